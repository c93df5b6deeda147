"""The command line a new user meets in the first hour, each behaviour through ``rotoruq`` in a
subprocess: the compile notice, library warnings as one line each, ``--quiet``, ``--version``,
quiet pipes, the run summary, ``evaluate``'s exit status and fixed inputs, and units in tables
and figure axes. (``reproduce`` prints the same summary: tests/test_report.py's slow
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
    # the worktree's cache is warm: not a word about compiling
    warm_run = cli("evaluate", "--set", "collective_deg=5")
    assert warm_run.returncode == 0, warm_run.stderr
    assert "compiling" not in warm_run.stderr


def test_evaluate_prints_the_preset_inputs_it_used(warm):
    proc = cli("evaluate", "--set", "collective_deg=5", "k_pitch_link=15")
    assert proc.returncode == 0, proc.stderr
    fixed = proc.stdout.splitlines()[0]
    assert fixed.startswith("fixed inputs (preset gvpm): ")
    values = dict(w.split("=") for w in fixed.split(": ", 1)[1].split())
    model = RotorModel("gvpm")
    assert float(values["lateral_deg"]) == model.defaults()["lateral_deg"] == -1.0
    assert float(values["longitudinal_deg"]) == model.defaults()["longitudinal_deg"] == -1.0
    assert "collective_deg" not in values and "k_pitch_link" not in values
    # the table below it holds the model's own numbers at the point
    header, row = proc.stdout.splitlines()[1:3]
    got = dict(zip(header.split(), map(float, row.split()), strict=True))
    expect = RotorModel("gvpm", names_in=["collective_deg", "k_pitch_link"],
                        names_out=["thrust"])([[5.0, 15.0]])[0, 0]
    assert got["thrust"] == pytest.approx(expect, rel=1e-5)  # printed to 6 digits


def test_evaluate_fails_when_every_point_failed(warm):
    # 95 deg of collective (+ the preset's 1 + 1 deg cyclic) is no rotor operating state
    proc = cli("evaluate", "--json", "--set", "collective_deg=95,96")
    assert proc.returncode == 1
    rows = json.loads(proc.stdout)  # strict JSON: null, not NaN
    assert [r["thrust"] for r in rows] == [None, None]
    assert all("exceeds 90 deg" in r["failure"] for r in rows)
    assert "rotoruq evaluate: error: all 2 evaluations failed" in proc.stderr
    assert "fixed inputs (preset gvpm)" in proc.stderr  # stdout stays JSON


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
    assert "warning:" not in quiet.stderr, quiet.stderr
    # the error itself is still said with --quiet
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
