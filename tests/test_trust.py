"""Results a user can trust, tested the way a user works: study files and ``rotoruq run``,
nothing injected (the first test and the signal tests run it as a fresh process; the others
through its entry point in the test's process, ``tests/_inproc.py``: a fresh interpreter per run
adds ~2 CPU-s and nothing of what is checked, and a cache kept in memory between runs could
only make a stale result more likely, never hide one).

- change anything a result depends on (a fixed input, the preset, the airfoil table, a template,
  the driver script) and re-run into the same folder: the results equal a fresh folder's;
- an external-solver study runs from a study file (templates, fixed inputs, failure policy);
- two runs on one folder: the second refuses, no point runs twice;
- a half-saved step is recomputed, never trusted;
- SIGKILL at random moments, resumed each time: bitwise equal to an uninterrupted run, no
  evaluation lost, at most one re-run per worker per kill.
"""

from __future__ import annotations

import json
import os
import random
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from _inproc import rotoruq
from rotoruq.results import load_step

ROOT = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "rotoruq.study.cli"]

# A solver behind Dakota's file contract: reads the input file rotoruq filled from the template,
# writes the results file, logs every execution it finishes (one line, the value of a).
DRIVER = r'''
import os, sys, time
params, results = sys.argv[1], sys.argv[2]
vals = {}
for line in open("input.txt"):
    k, v = line.split("=")
    vals[k.strip()] = float(v)
time.sleep(float(os.environ.get("DRIVER_SLEEP", "0")))
gate = os.environ.get("DRIVER_GATE")
while gate and not os.path.exists(gate):
    time.sleep(0.02)
a, b, c = vals["a"], vals["b"], vals["c"]
if a > float(os.environ.get("DRIVER_FAIL_ABOVE", "inf")):
    sys.exit(3)
SCALE = 2.0
open(results, "w").write(f"{SCALE * a + 3 * b + c!r} y1\n{a - b!r} y2\n")
log = os.environ.get("DRIVER_LOG")
if log:
    with open(log, "a") as f:
        f.write(f"{a!r}\n")
'''

TEMPLATE = "a = {a}\nb = {b}\nc = {c}\n"


def external_study(folder: Path, *, n: int = 8, executor: str = "serial", failure: str = "",
                   c: float = 1.0) -> Path:
    text = f"""
        [study]
        name = "ext"
        seed = 3

        [model]
        command = [{json.dumps(sys.executable)}, "-S", "driver.py", "{{params}}", "{{results}}"]
        templates = ["input.txt"]
        responses = ["y1", "y2"]
        fixed = {{ c = {c} }}
        {failure}

        [parameters.a]
        distribution = "uniform"
        lower = 0.0
        upper = 1.0

        [parameters.b]
        distribution = "normal"
        mean = 2.0
        std = 0.5

        [executor]
        kind = "{executor}"

        [[steps]]
        name = "lhs"
        type = "sampling"
        n_samples = {n}
        """
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "driver.py").write_text(DRIVER)
    (folder / "input.txt").write_text(TEMPLATE)
    path = folder / "study.toml"
    path.write_text(textwrap.dedent(text))
    return path


def cli(*args, env=None, check=True, timeout=300):
    proc = subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env={**os.environ, **(env or {})})
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


def run_here(*args, env=None, check=True):
    """``cli`` through the CLI's entry point in this process (``tests/_inproc.py``)."""
    proc = rotoruq(*args, env=env)
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


def outputs(out: Path, step: str = "lhs") -> np.ndarray:
    return load_step(out / "steps" / step).arrays["outputs"]


def test_external_study_runs_from_a_study_file(tmp_path):
    study = external_study(tmp_path / "s", c=1.5)
    cli("run", study, "--out", tmp_path / "out", "--no-report")
    res = load_step(tmp_path / "out" / "steps" / "lhs")
    x, y = res.arrays["inputs"], res.arrays["outputs"]
    assert x.shape == (8, 2) and res.columns("inputs") == ["a", "b"]
    np.testing.assert_allclose(y[:, 0], 2 * x[:, 0] + 3 * x[:, 1] + 1.5, rtol=1e-15)
    np.testing.assert_allclose(y[:, 1], x[:, 0] - x[:, 1], rtol=1e-15)


@pytest.mark.parametrize("failure,expect_rc", [
    ('failure = "continue"', 0),
    ('failure = "recover"\n        recover = [-1.0, -2.0]', 0),
    ('failure = "abort"', 1),
])
def test_external_study_failure_policy(tmp_path, failure, expect_rc):
    study = external_study(tmp_path / "s", failure=failure)
    proc = run_here("run", study, "--out", tmp_path / "out", "--no-report",
                    env={"DRIVER_FAIL_ABOVE": "0.5"}, check=False)
    assert proc.returncode == expect_rc, proc.stderr
    assert "Traceback" not in proc.stderr
    if expect_rc:
        assert "error" in proc.stderr
        return
    res = load_step(tmp_path / "out" / "steps" / "lhs")
    a = res.arrays["inputs"][:, 0]
    y = res.arrays["outputs"]
    bad = a > 0.5
    assert bad.any() and (~bad).any()
    if "recover" in failure:
        np.testing.assert_array_equal(y[bad], np.tile([-1.0, -2.0], (bad.sum(), 1)))
    else:
        assert np.isnan(y[bad]).all()
    assert np.isfinite(y[~bad]).all()


def _rerun_equals_fresh(tmp_path, study: Path, change, tag: str, cli=run_here):
    """Run into ``same``, apply ``change``, run again into ``same`` and into a fresh folder."""
    same = tmp_path / f"same_{tag}"
    cli("run", study, "--out", same, "--no-report")
    before = outputs(same)
    change()
    cli("run", study, "--out", same, "--no-report")
    cli("run", study, "--out", tmp_path / f"fresh_{tag}", "--no-report")
    after, fresh = outputs(same), outputs(tmp_path / f"fresh_{tag}")
    np.testing.assert_array_equal(after, fresh)
    assert not np.array_equal(before, after, equal_nan=True)


@pytest.mark.parametrize("what", ["driver", "template", "fixed"])
def test_external_changes_are_never_served_stale(tmp_path, what):
    folder = tmp_path / "s"
    study = external_study(folder)

    def change():
        if what == "driver":
            p = folder / "driver.py"
            p.write_text(p.read_text().replace("SCALE = 2.0", "SCALE = 5.0"))
        elif what == "template":
            (folder / "input.txt").write_text(TEMPLATE.replace("b = {b}", "b = {b:.1f}"))
        else:
            external_study(folder, c=4.0)

    _rerun_equals_fresh(tmp_path, study, change, what)


ROTOR_STUDY = """
[study]
name = "rotor"
seed = 5

[model]
preset = "{preset}"
responses = ["thrust"]
fixed = {{ collective_deg = {collective}, height_over_radius = {h} }}
{options}

[parameters.k_pitch_link]
distribution = "uniform"
lower = 10.0
upper = 20.0

[[steps]]
name = "lhs"
type = "sampling"
n_samples = 6
"""


@pytest.mark.parametrize("what", ["collective", "preset", "airfoil", "height"])
def test_rotor_changes_are_never_served_stale(tmp_path, what):
    path = tmp_path / "study.toml"
    table = tmp_path / "naca0012.c81"
    from rotoruq.rotor.airfoil import read_bundled
    from rotoruq.rotor.c81 import write_c81

    write_c81(read_bundled("naca0012"), table)
    kw = {"preset": "gvpm", "collective": 5.0, "h": 2.0,
          "options": f'preset_options = {{ airfoil = "{table}" }}'}
    path.write_text(ROTOR_STUDY.format(**kw))
    if what == "preset":
        # k_pitch_link is a gvpm input; the bo105 has one too (its pitch link)
        kw["preset"], kw["options"] = "bo105", ""
    elif what == "collective":
        kw["collective"] = 8.0
    elif what == "height":
        kw["h"] = 4.0

    def change():
        if what == "airfoil":
            from dataclasses import replace

            from rotoruq.rotor.c81 import read_c81

            t = read_c81(table)
            write_c81(replace(t, cl=replace(t.cl, values=t.cl.values * 1.1)), table)
        else:
            path.write_text(ROTOR_STUDY.format(**kw))

    _rerun_equals_fresh(tmp_path, path, change, what)


def test_second_run_on_one_folder_refuses(tmp_path):
    study = external_study(tmp_path / "s", n=6)
    log, gate = tmp_path / "driver.log", tmp_path / "gate"
    # the first run's driver waits at the gate: the first run holds the folder meanwhile
    env = {**os.environ, "DRIVER_GATE": str(gate), "DRIVER_LOG": str(log)}
    out = tmp_path / "out"
    first = subprocess.Popen([*CLI, "run", str(study), "--out", str(out), "--no-report"],
                             env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        lock = out / ".rotoruq.lock"
        deadline = time.time() + 120
        while time.time() < deadline:
            text = lock.read_text() if lock.is_file() else ""
            if text and json.loads(text).get("pid") == first.pid:
                break
            time.sleep(0.05)
        second = cli("run", study, "--out", out, "--no-report", env=env, check=False)
        assert second.returncode == 1, second.stderr
        assert "in use by another rotoruq run" in second.stderr
        assert f"PID {first.pid}" in second.stderr
        assert "Traceback" not in second.stderr
    finally:
        gate.touch()
        _, err = first.communicate(timeout=300)
    assert first.returncode == 0, err
    runs = Counter(log.read_text().split())
    assert len(runs) == 6 and max(runs.values()) == 1


def test_half_saved_step_is_recomputed(tmp_path):
    study = external_study(tmp_path / "s")
    out = tmp_path / "out"
    run_here("run", study, "--out", out, "--no-report")
    good = outputs(out)
    step = out / "steps" / "lhs"
    # a save cut short: arrays missing, then a truncated result.json
    (step / "outputs.npy").unlink()
    proc = run_here("run", study, "--out", out, "--no-report")
    assert "incomplete" in proc.stderr
    np.testing.assert_array_equal(outputs(out), good)
    text = (step / "result.json").read_text()
    (step / "result.json").write_text(text[: len(text) // 2])
    proc = run_here("run", study, "--out", out, "--no-report")
    assert "incomplete" in proc.stderr
    np.testing.assert_array_equal(outputs(out), good)


@pytest.mark.slow
def test_sigkill_at_random_moments_resumes_bitwise(tmp_path):
    n = 60  # enough work left after each resume for ten kills, however fast the runs start
    study = external_study(tmp_path / "s", n=n, executor="processes")
    ref_log, log = tmp_path / "ref.log", tmp_path / "kill.log"
    base_env = {"DRIVER_SLEEP": "0.05"}
    cli("run", study, "--out", tmp_path / "ref", "--no-report",
        env={**base_env, "DRIVER_LOG": str(ref_log)})
    reference = outputs(tmp_path / "ref")
    out = tmp_path / "out"
    env = {**os.environ, **base_env, "DRIVER_LOG": str(log)}
    rng = random.Random(11)
    kills = 0
    for _ in range(30):
        proc = subprocess.Popen([*CLI, "run", str(study), "--out", str(out), "--no-report"],
                                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                start_new_session=True)
        # kill at a random moment after this run has finished an evaluation of its own (a fixed
        # delay killed nothing once the runs started faster)
        seen = log.stat().st_size if log.exists() else 0
        deadline = time.monotonic() + 60
        while (proc.poll() is None and time.monotonic() < deadline
               and (log.stat().st_size if log.exists() else 0) == seen):
            time.sleep(0.01)
        time.sleep(rng.uniform(0.0, 0.15))
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)  # the run and its workers, as a crash would
            proc.wait()
            kills += 1
        else:
            proc.communicate()
        if kills >= 10:
            break
    assert kills >= 10
    cli("run", study, "--out", out, "--no-report", env={**base_env, "DRIVER_LOG": str(log)})
    np.testing.assert_array_equal(outputs(out), reference)
    runs = Counter(log.read_text().split())
    assert len(runs) == n  # none lost
    workers = os.cpu_count() or 1
    assert sum(runs.values()) - n <= kills * workers


@pytest.mark.slow
def test_rotor_study_killed_and_resumed_is_bitwise_equal(tmp_path):
    """Resumed rotor evaluations run in other batch compositions than an uninterrupted run:
    the rotor's answers must not depend on which points share a batch."""
    path = tmp_path / "study.toml"
    path.write_text(ROTOR_STUDY.format(preset="gvpm", collective=5.4, h=3.0, options="")
                    .replace("n_samples = 6", "n_samples = 20000")
                    .replace("[[steps]]", '[parameters.cla_m03]\ndistribution = "normal"\n'
                             'mean = 0.108\nstd = 0.005\n\n[[steps]]'))
    t0 = time.monotonic()
    cli("run", path, "--out", tmp_path / "ref", "--no-report")
    duration = time.monotonic() - t0  # kill moments scale with it: the kernel's speed varies
    reference = outputs(tmp_path / "ref")
    out = tmp_path / "out"
    rng = random.Random(3)
    kills, scale = 0, 1.0
    for _ in range(10):
        if kills == 4:
            break
        proc = subprocess.Popen([*CLI, "run", str(path), "--out", str(out), "--no-report"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                start_new_session=True)
        time.sleep(rng.uniform(0.4, 0.8) * duration * scale)
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            kills += 1
        elif kills == 0:
            # it finished before the kill (the reference run met a busier machine): start
            # again from nothing, killing sooner
            shutil.rmtree(out, ignore_errors=True)
            scale /= 2
        proc.wait()
    cli("run", path, "--out", out, "--no-report")
    assert kills >= 1
    np.testing.assert_array_equal(outputs(out), reference)


def test_sigterm_ends_the_run_and_its_drivers(tmp_path):
    """SIGTERM to `rotoruq run` (a scheduler's time limit): a clean exit, no driver left."""
    study = external_study(tmp_path / "s", n=4)
    gate = tmp_path / "never"  # the drivers wait here until ended
    out = tmp_path / "out"
    env = {**os.environ, "DRIVER_GATE": str(gate)}
    proc = subprocess.Popen([*CLI, "run", str(study), "--out", str(out), "--no-report"],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    drivers: list[int] = []
    while time.time() < deadline and not drivers:
        drivers = [int(p.name) for p in Path("/proc").iterdir() if p.name.isdigit()
                   and _cmdline(p).endswith(f"{tmp_path}/s/driver.py params.in results.out")]
        time.sleep(0.05)
    assert drivers, "no driver started"
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert "terminated" in err and "Traceback" not in err
    time.sleep(0.2)
    assert not [d for d in drivers if Path(f"/proc/{d}").exists()
                and "Z" not in Path(f"/proc/{d}/stat").read_text().split()[2]]


def _cmdline(p: Path) -> str:
    try:
        return (p / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
    except OSError:
        return ""
