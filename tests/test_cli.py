"""The command line a new user meets in the first hour, each behaviour through ``rotoruq`` in a
subprocess: the compile notice, library warnings as one line each, ``--quiet``, ``--version``,
quiet pipes, the run summary, ``evaluate``'s exit status and fixed inputs, and units in tables
and figure axes; failures a user sees (exit code 3 with the first failure's message, ``--only``
on a fresh folder, data files checked when the study is read, bundled study names, global
flags after the subcommand, ``python -m rotoruq``, exported decks' names and driver line).
(``reproduce`` prints the same summary: tests/test_report.py's slow
``test_reproduce_quick`` runs it.)"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest

from rotoruq import __version__
from rotoruq.errors import ParameterError
from rotoruq.rotor.model import COMPILE_NOTICE, RotorModel, kernels_cached

CLI = [sys.executable, "-m", "rotoruq.study.cli"]

TINY = """\
[study]
name = "tiny"
seed = 3

[model]
preset = "gvpm"
responses = ["thrust", "roll"]
fixed = { collective_deg = 5.0 }

[parameters.k_pitch_link]
distribution = "normal"
mean = 15.0
std = 0.75
label = "K_p"

[[steps]]
name = "lhs"
type = "sampling"
n_samples = 40
"""


def cli(*args, env=None, timeout=300) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=env)


@pytest.fixture(scope="module")
def warm():
    """The rotor kernels compiled and cached (what every later process loads)."""
    RotorModel("gvpm").evaluate([[5.0, -1.0, -1.0]])
    assert kernels_cached()


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory, warm):
    d = tmp_path_factory.mktemp("tiny")
    (d / "tiny.toml").write_text(TINY)
    proc = cli("run", d / "tiny.toml", "--out", d / "out", "--no-report")
    assert proc.returncode == 0, proc.stderr[-3000:]
    return d, proc


def test_version():
    proc = cli("--version")
    assert proc.returncode == 0 and proc.stdout.strip() == f"rotoruq {__version__}"


def test_compile_notice_on_a_cold_cache_only(tmp_path, warm):
    # An empty numba cache folder is a cold cache: the notice comes before the compile starts
    # (the process is ended once it has said so, not left to compile for a minute).
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    proc = subprocess.Popen([*CLI, "evaluate", "--set", "collective_deg=5"], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stderr is not None
        first = proc.stderr.readline()  # blocks until the notice, or the end of a compile
        assert first.strip() == COMPILE_NOTICE
    finally:
        proc.kill()
        proc.wait()
    # on the worktree's warm cache the same command says not a word about compiling:
    # test_evaluate_prints_the_preset_inputs_it_used's run checks it


def test_evaluate_prints_the_preset_inputs_it_used(warm):
    proc = cli("evaluate", "--set", "collective_deg=5", "k_pitch_link=15")
    assert proc.returncode == 0, proc.stderr
    assert "compiling" not in proc.stderr  # the cache is warm (`warm`): no compile notice
    fixed = proc.stdout.splitlines()[0]
    assert fixed.startswith("fixed inputs (preset gvpm): ")
    values = dict(w.split("=") for w in fixed.split(": ", 1)[1].split())
    model = RotorModel("gvpm")
    assert float(values["lateral_deg"]) == model.defaults()["lateral_deg"] == -1.0
    assert float(values["longitudinal_deg"]) == model.defaults()["longitudinal_deg"] == -1.0
    assert "collective_deg" not in values and "k_pitch_link" not in values
    # the table below it holds the model's own numbers at the point, each column with its unit
    header, row = proc.stdout.splitlines()[1:3]
    got = dict(zip(re.split(r"\s{2,}", header.strip()), map(float, row.split()), strict=True))
    assert list(got) == ["collective_deg [deg]", "k_pitch_link [N]", "thrust [N]",
                         "torque [N m]", "roll [N m]", "pitch [N m]", "power [W]", "ct [-]",
                         "cq [-]"]
    expect = RotorModel("gvpm", names_in=["collective_deg", "k_pitch_link"],
                        names_out=["thrust"])([[5.0, 15.0]])[0, 0]
    assert got["thrust [N]"] == pytest.approx(expect, rel=1e-5)  # printed to 6 digits


def test_evaluate_fails_when_every_point_failed(warm):
    # 95 deg of collective (+ the preset's 1 + 1 deg cyclic) is no rotor operating state
    proc = cli("evaluate", "--json", "--set", "collective_deg=95,96")
    assert proc.returncode == 1
    rows = json.loads(proc.stdout)  # strict JSON: null, not NaN
    assert [r["thrust"] for r in rows] == [None, None]
    assert all("exceeds 90 deg" in r["failure"] for r in rows)
    assert "rotoruq evaluate: error: all 2 evaluations failed" in proc.stderr
    assert "fixed inputs (preset gvpm)" in proc.stderr  # stdout stays JSON


def test_evaluate_with_no_response_named_is_a_usage_error(rotoruq_main):
    # found by test_fuzz_study: `--responses` with no names reached numpy's concatenate
    code, _, err = rotoruq_main("evaluate", "--responses")
    assert code == 2
    assert "argument --responses: expected at least one argument" in err
    assert "internal error" not in err
    with pytest.raises(ParameterError, match="names_out is empty: name at least one response; "
                                             "valid: thrust, torque"):
        RotorModel("gvpm", names_out=[])


def test_run_summary_and_quiet(tiny_run, tmp_path):
    d, proc = tiny_run
    assert "summary of tiny (1 steps):" in proc.stdout
    assert "40 evaluations" in proc.stdout and "0 failed evaluation(s)" in proc.stdout
    again = cli("--quiet", "run", d / "tiny.toml", "--out", d / "out", "--no-report")
    assert again.returncode == 0
    assert again.stdout == "" and again.stderr == ""


def test_show_csv_into_a_closed_pipe_is_quiet(tiny_run):
    d, _ = tiny_run
    # the reader is gone before the first byte is written: what `| head` does to a long
    # output (Python ignores SIGPIPE, so the write raises BrokenPipeError)
    r, w = os.pipe()
    os.close(r)
    try:
        proc = subprocess.run([*CLI, "show", str(d / "out"), "--csv"], stdout=w,
                              stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(w)
    assert proc.returncode == 0
    assert proc.stderr == ""


def test_library_warnings_are_one_line_each(tmp_path):
    # numpy warns from its own file; the CLI's logging setup prints the message alone, once
    code = ("import sys, numpy as np\n"
            "from rotoruq.study.cli import main\n"
            f"main(sys.argv[1:] + ['report', {str(tmp_path)!r}])\n"
            "np.mean([]); np.mean([])\n")
    loud = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    lines = loud.stderr.splitlines()
    # (numpy 2.3.0 ends the message with a full stop, later versions do not)
    assert sum(ln.startswith("warning: Mean of empty slice") for ln in lines) == 1, loud.stderr
    assert not any(".py:" in ln or "numpy" in ln for ln in lines), loud.stderr
    quiet = subprocess.run([sys.executable, "-c", code, "--quiet"], capture_output=True,
                           text=True, timeout=120)
    # --quiet hides progress only: warnings and errors are still said
    assert sum(ln.startswith("warning: Mean of empty slice")
               for ln in quiet.stderr.splitlines()) == 1, quiet.stderr
    assert "rotoruq report: error:" in quiet.stderr


def test_summary_units_in_tables(tiny_run):
    d, _ = tiny_run
    proc = cli("show", d / "out", "lhs", "--json")
    assert proc.returncode == 0, proc.stderr
    tables = json.loads(proc.stdout)
    tables = tables if isinstance(tables, list) else tables.get("tables", tables)
    labels = [row[0] for t in _tables(tables) for row in t["rows"]]
    assert "thrust [N]" in labels and "roll [N m]" in labels and "K_p [N]" in labels


def _tables(obj):
    """Every ``{"title", "columns", "rows"}`` in ``show --json``'s output."""
    if isinstance(obj, dict):
        if {"columns", "rows"} <= set(obj):
            yield obj
        else:
            for v in obj.values():
                yield from _tables(v)
    elif isinstance(obj, list):
        for v in obj:
            yield from _tables(v)


def test_fixed_inputs_line_matches_the_model():
    # the line's numbers are the preset's (and nothing given with --set)
    from rotoruq.study.cmd_evaluate import fixed_inputs_line

    model = RotorModel("gvpm", names_in=["collective_deg"])
    line = fixed_inputs_line(model)
    values = {k: float(v) for k, v in (w.split("=") for w in line.split(": ", 1)[1].split())}
    defaults = model.defaults()
    assert set(values) == set(defaults) - {"collective_deg"}
    for k, v in values.items():
        assert v == pytest.approx(defaults[k], rel=1e-5)
    assert np.isfinite(list(values.values())).all()


def test_report_axes_and_tables_carry_units(tmp_path):
    """``rotoruq report`` of a saved calibration over a lift slope [1/deg] and K_p [N]: the
    densities read [deg] and [1/N] (never [1/1/deg]), K_p is in N as the README defines it,
    and each figure is written as SVG beside its PNG."""
    from rotoruq.results import StepResult, save_step

    study = tmp_path / "cal"
    study.mkdir()
    (study / "study.json").write_text(json.dumps({"name": "cal", "steps": ["bayes"],
                                                  "model": {"preset": "gvpm"}}))
    rng = np.random.default_rng(1)
    chain = np.column_stack([rng.normal(0.108, 5e-3, 2000), rng.normal(15.0, 0.7, 2000)])
    save_step(StepResult("bayes", "bayes_calibration", {}, {"chain": chain},
                         meta={"columns": {"chain": ["cla_m03", "k_pitch_link"]}}), study)
    proc = cli("report", study, "--out", tmp_path / "rep")
    assert proc.returncode == 0, proc.stderr
    page = (tmp_path / "rep" / "index.html").read_text()
    ylabels = [lab for raw in re.findall(r"data-ylabels='([^']*)'", page)
               for lab in json.loads(raw.replace("&quot;", '"'))]
    xlabels = [lab for raw in re.findall(r"data-xlabels='([^']*)'", page)
               for lab in json.loads(raw.replace("&quot;", '"'))]
    assert "density [deg]" in ylabels and "density [1/N]" in ylabels
    assert not any("1/1/" in lab for lab in ylabels)
    assert "k_pitch_link [N]" in xlabels and "cla_m03 [1/deg]" in xlabels
    figures = tmp_path / "rep" / "figures"
    pngs = sorted(p.stem for p in figures.glob("*.png"))
    assert pngs and pngs == sorted(p.stem for p in figures.glob("*.svg"))


def test_density_units_and_the_coefficient_of_variation():
    from rotoruq.render.figures import per_unit
    from rotoruq.render.tables import CV_MIN_MEAN_OVER_STD, cv_or_none

    assert [per_unit(u) for u in ("1/deg", "1/deg^2", "N", "N m", "-", "1/(N m)")] == [
        "deg", "deg^2", "1/N", "1/(N m)", "-", "N m"]
    # the CV is std / |mean| where the mean is clear of zero, and not given where it is not
    # (the 656 and 1930: a mean at 1.5e-3 and 5e-4 of the std)
    assert cv_or_none(-25.0, 0.5) == 0.02
    assert cv_or_none(1.0, 656.0) is None and cv_or_none(1.0, 1930.0) is None
    assert cv_or_none(CV_MIN_MEAN_OVER_STD * 2.0, 2.0) == pytest.approx(
        1 / CV_MIN_MEAN_OVER_STD)
    assert cv_or_none(0.0, 0.0) is None and cv_or_none(float("nan"), 1.0) is None


def test_a_broken_pipe_that_is_not_stdout_is_an_error():
    # a worker's or a driver's pipe breaking is no reader going away: it must not pass as a
    # quiet success
    from rotoruq.study.console import pipe_safe

    def run(args):
        r, w = os.pipe()
        os.close(r)
        try:
            os.write(w, b"to a worker that died")
        finally:
            os.close(w)
        return 0

    with pytest.raises(BrokenPipeError):
        pipe_safe(run)(None)


# --- failures a user sees, and the command line (issue 36) -------------------------------

def _study(d, text: str, name: str = "s.toml"):
    (d / name).write_text(text)
    return d / name


def test_a_run_whose_evaluations_all_fail_exits_3_and_says_why_even_quiet(tmp_path, warm):
    # 95 deg of collective is no rotor state: every evaluation fails; --quiet after the
    # subcommand keeps the warning and the reason, hides the progress and the summary
    study = _study(tmp_path, TINY.replace("collective_deg = 5.0", "collective_deg = 95.0")
                   .replace("n_samples = 40", "n_samples = 8"))
    proc = cli("run", study, "--out", tmp_path / "out", "--no-report", "--quiet")
    assert proc.returncode == 3, proc.stderr
    assert proc.stdout == ""
    assert "rotoruq run: error: step 'lhs': none of its 8 evaluations succeeded; first " \
           "failure: blade pitch command" in proc.stderr
    assert "exceeds 90 deg" in proc.stderr and "exit code 3" in proc.stderr
    assert "warning: sample (lhs): 8 of 8 evaluations failed" in proc.stderr
    assert "running" not in proc.stderr  # no progress chatter
    # the saved failures say the same when reused, and the summary gives the first reason
    again = cli("run", study, "--out", tmp_path / "out", "--no-report")
    assert again.returncode == 3
    assert "x first failed evaluation: blade pitch command" in again.stdout
    assert "none of its 8 evaluations succeeded" in again.stderr


PARTIAL = """\
[study]
name = "part"
seed = 3
{extra}
[model]
preset = "gvpm"
responses = ["thrust"]

[parameters.collective_deg]
distribution = "uniform"
lower = 4.0
upper = 94.0

[[steps]]
name = "lhs"
type = "sampling"
n_samples = 10
"""


@pytest.mark.slow  # ~12 CPU-s; exit 3 stays fast in the test above
def test_a_failure_share_above_the_threshold_exits_3(tmp_path, warm):
    # 8 of the 10 collectives from 4 to 94 deg fail (deep stall, > 90 deg)
    study = _study(tmp_path, PARTIAL.format(extra=""))
    proc = cli("run", study, "--out", tmp_path / "out", "--no-report")
    assert proc.returncode == 3, proc.stderr
    assert "step 'lhs': 8 of 10 evaluations failed (80%, above the 50% allowed by " \
           "max_failed_share); first failure: " in proc.stderr
    assert cli("run", study, "--out", tmp_path / "out", "--no-report",
               "--max-failed-share", "0.9").returncode == 0
    assert cli("run", study, "--out", tmp_path / "out", "--no-report",
               "--max-failed-share", "2").returncode == 2  # a share is 0 to 1
    lenient = _study(tmp_path, PARTIAL.format(extra="max_failed_share = 0.85\n"), "l.toml")
    assert cli("run", lenient, "--out", tmp_path / "out", "--no-report").returncode == 0
    wrong = _study(tmp_path, PARTIAL.format(extra="max_failed_share = 50\n"), "w.toml")
    bad = cli("run", wrong, "--out", tmp_path / "out2")
    assert bad.returncode == 1 and "w.toml, line 4: expected a share" in bad.stderr


@pytest.mark.slow  # ~11 CPU-s: several runs in fresh processes
def test_only_runs_what_it_names_and_skips_the_rest(tmp_path, warm):
    study = _study(tmp_path, TINY.replace("n_samples = 40", "n_samples = 6") + """
[[steps]]
name = "sobol"
type = "sensitivity"
n_samples = 8
""")
    out = tmp_path / "fresh"
    proc = cli("run", study, "--only", "lhs", "--out", out)
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in (out / "steps").iterdir()) == ["lhs"]
    assert (out / "report" / "index.html").is_file()
    assert "sobol                skipped (not in --only, no saved result)" in proc.stdout
    # a name that is no step: the steps, and the closest
    typo = cli("run", study, "--only", "sobl", "--out", out)
    assert typo.returncode == 1
    assert "--only sobl: no such step" in typo.stderr and "did you mean 'sobol'?" in typo.stderr
    # the named step runs, the saved one is reused
    both = cli("run", study, "--only", "sobol", "--out", out, "--no-report")
    assert both.returncode == 0, both.stderr
    assert "lhs: reused" in both.stderr and "sobol: running" in both.stderr


def test_only_a_step_whose_source_is_missing_says_what_to_add(tmp_path, rotoruq_main):
    # `cal` calibrates on `lhs`'s samples: --only cal in a fresh folder cannot run it
    study = _study(tmp_path, TINY.replace("n_samples = 40", "n_samples = 6") + """
[[steps]]
name = "cal"
type = "least_squares"
data = "lhs.samples"
responses = ["thrust"]
""")
    code, _, err = rotoruq_main("run", study, "--only", "cal", "--out", tmp_path / "o")
    assert code == 1, err
    assert "step 'lhs' has no saved result, and 'cal' (in --only) takes from it: add it, " \
           "--only lhs cal" in err
    assert not (tmp_path / "o" / "steps" / "lhs").exists()


DATA_STUDY = TINY.replace("n_samples = 40", "n_samples = 6") + """
[data.measured]
file = "m.csv"
{extra}
[[steps]]
name = "fwd"
type = "forward_check"
data = "measured"
responses = ["thrust"]
n_samples = 6
sweep = { collective_deg = [5.0] }
"""
CSV = "# measured\ncollective_deg,thrust,roll\n5.0,25.7,-0.04\n5.0,{v},-0.03\n6.0,27.1,-0.05\n"


@pytest.mark.parametrize("value, expected", [
    ("nan", "m.csv, line 4: expected a number in column 'thrust' that is finite (nan and inf "
            "are refused: set allow_nonfinite = true in [data.measured]"),
    ("-inf", "m.csv, line 4: expected a number in column 'thrust' that is finite"),
    ("1e400", "m.csv, line 4: expected a number in column 'thrust' within float range"),
    ("1" * 20000, "m.csv, line 4: expected a number in column 'thrust' of at most 100 "
                  "characters, found '11111111111111111111... (20000 characters)'"),
])
def test_measured_numbers_are_checked_when_the_study_is_read(tmp_path, value, expected,
                                                            rotoruq_main):
    # in this process: the same check through a fresh process is the next tests' (a missing
    # column, an empty select)
    (tmp_path / "m.csv").write_text(CSV.format(v=value))
    study = _study(tmp_path, DATA_STUDY.replace("{extra}", ""))
    code, _, err = rotoruq_main("run", study, "--out", tmp_path / "out")
    assert code == 1
    assert expected in err, err
    assert not (tmp_path / "out" / "steps").exists()  # before any step ran


def test_nonfinite_data_allowed_explicitly(tmp_path, warm, rotoruq_main):
    (tmp_path / "m.csv").write_text(CSV.format(v="nan"))
    study = _study(tmp_path, DATA_STUDY.replace("{extra}", "allow_nonfinite = true\n"))
    proc = cli("run", study, "--out", tmp_path / "out", "--no-report", "--only", "fwd")
    assert proc.returncode == 0, proc.stderr
    shown = cli("show", tmp_path / "out", "fwd", "--json")
    assert shown.returncode == 0, shown.stderr
    # the nan row is left out: one repeat of 25.7 at 5 deg
    assert "25.7" in shown.stdout
    # inline columns: the same rule
    inline = _study(tmp_path, DATA_STUDY.replace('file = "m.csv"', "thrust = [25.7, nan]\n"
                                                 "collective_deg = [5.0, 5.0]")
                    .replace("{extra}", ""), "i.toml")
    code, _, err = rotoruq_main("run", inline, "--out", tmp_path / "o2")
    assert code == 1
    assert "i.toml, line 22: expected finite numbers in column 'thrust'" in err


def test_a_missing_column_or_an_empty_select_is_said_before_any_step_runs(tmp_path):
    (tmp_path / "m.csv").write_text(CSV.format(v="25.9").replace("thrust", "thrst"))
    study = _study(tmp_path, DATA_STUDY.replace("{extra}", ""))
    proc = cli("run", study, "--out", tmp_path / "out")
    assert proc.returncode == 1
    line = study.read_text().splitlines().index('data = "measured"') + 1
    assert (f"s.toml, line {line}: expected data 'measured' (m.csv) to have the columns step 'fwd' "
            "(forward_check) reads: thrust, collective_deg; it has collective_deg, thrst, roll, "
            "found 'no column thrust'") in proc.stderr, proc.stderr
    assert not (tmp_path / "out" / "steps").exists()
    (tmp_path / "m.csv").write_text(CSV.format(v="25.9"))
    study = _study(tmp_path, DATA_STUDY.replace("{extra}", "select = { collective_deg = 7.0 }\n"))
    proc = cli("run", study, "--out", tmp_path / "out")
    assert proc.returncode == 1
    assert ("expected a selection matching at least one row of m.csv (collective_deg has 5, "
            "6), found 'collective_deg = 7'") in proc.stderr, proc.stderr


def test_bundled_names_help_and_did_you_mean(tmp_path, rotoruq_main):
    from rotoruq.study.cmd_run import bundled_studies

    names = bundled_studies()
    assert {"quick", "validation", "experiment", "heldout"} <= set(names) and len(names) >= 8
    code, out, _ = rotoruq_main("run", "--help")
    help_text = " ".join(out.split())
    assert code == 0 and all(n in help_text for n in names), help_text
    code, _, err = rotoruq_main("run", "quik")
    assert code == 1
    assert "(did you mean 'quick'?)" in err and "mbdyn_rigid" in err


def test_global_flags_before_or_after_the_subcommand_and_python_m(tmp_path, rotoruq_main):
    d = tmp_path / "nothing"
    d.mkdir()
    # the parser's part in this process (the command line the process gets is the same list)
    for args in (["--quiet", "report", d], ["report", d, "--quiet"], ["report", d, "-q"],
                 ["report", d, "--verbose"], ["-v", "report", d]):
        code, _, err = rotoruq_main(*args)
        assert code == 1 and "rotoruq report: error:" in err, args
    code, _, err = rotoruq_main("report", d, "-q", "-v")
    assert code == 2 and "--quiet and --verbose" in err
    # in a process of its own: a global flag before the subcommand
    proc = cli("--quiet", "report", d)
    assert proc.returncode == 1 and "rotoruq report: error:" in proc.stderr
    # python -m rotoruq is the same command
    mod = subprocess.run([sys.executable, "-m", "rotoruq", "--version"], capture_output=True,
                         text=True, timeout=120)
    assert mod.returncode == 0 and mod.stdout.strip() == f"rotoruq {__version__}"
    # and it stays light: the driver's words are found after the global flags
    from rotoruq.study.cli import _driver_argv

    assert _driver_argv(["-q", "--debug", "driver", "p", "r"]) == ["p", "r"]


def test_exported_decks_are_named_step_in_with_a_portable_driver(tmp_path, rotoruq_main,
                                                                  monkeypatch):
    study = _study(tmp_path, TINY + """
[[steps]]
name = "sobol"
type = "sensitivity"
n_samples = 8
""")
    proc = subprocess.run([*CLI, "dakota", "export", study, "--out", "decks"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in (tmp_path / "decks").iterdir()) == ["lhs.in", "sobol.in"]
    deck = (tmp_path / "decks" / "lhs.in").read_text()
    venv_bin = os.path.dirname(sys.executable)
    here = venv_bin + os.pathsep + os.environ.get("PATH", "")
    # the driver line as the PATH decides, in this process (the export above ran in its own)
    monkeypatch.chdir(tmp_path)
    for path, line, note in ((here, "analysis_drivers = 'rotoruq driver --preset gvpm",
                              "# driver: 'rotoruq' as found on PATH"),
                             ("/usr/bin:/bin", f"analysis_drivers = '{venv_bin}/rotoruq driver",
                              "# driver: this installation's rotoruq by absolute path")):
        if not os.path.isfile(os.path.join(venv_bin, "rotoruq")):
            pytest.skip("no rotoruq console script beside this Python")
        monkeypatch.setenv("PATH", path)
        code, _, err = rotoruq_main("dakota", "export", study, "-o", "d.in", "--step", "lhs")
        assert code == 0, err
        deck = (tmp_path / "d.in").read_text()
        assert line in deck and deck.startswith(note), deck[:400]
