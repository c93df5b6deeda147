"""MBDyn driven by rotoruq: extractor, driver, parity with the built-in rotor, a study through
the CLI killed and resumed.

Tests marked ``mbdyn`` run the real solver. They find it like a user does (``$MBDYN``, then
``mbdyn`` on PATH, then the build tool's default prefix ``~/.cache/mbdyn``) and are skipped,
with the reason in the test summary, only when no MBDyn executable exists (CI builds it with
``shared/tools/build-mbdyn`` first).
"""

from __future__ import annotations

import math
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rotoruq.errors import ParameterError
from rotoruq.evaluation.dakota_files import read_results, write_parameters
from rotoruq.evaluation.external import ExternalModel
from rotoruq.evaluation.templates import fill_template, template_fields
from rotoruq.mbdyn import (
    CaseSettings,
    MBDynError,
    MBDynNotFoundError,
    find_mbdyn,
    hub_loads,
    rigid_equivalent,
    run_case,
    template_values,
)
from rotoruq.mbdyn.case import template_text
from rotoruq.results import load_step
from rotoruq.rotor.model import RotorModel
from rotoruq.rotor.presets import get_preset
from rotoruq.study.schema import load_study

CLI = [sys.executable, "-m", "rotoruq.study.cli"]
DRIVER = [sys.executable, "-m", "rotoruq.mbdyn.driver"]
STUDIES = Path(__file__).resolve().parents[1] / "src" / "rotoruq" / "studies"


def _mbdyn_or_none() -> str | None:
    try:
        return str(find_mbdyn(build_prefix=True))
    except MBDynNotFoundError:
        return None


MBDYN = _mbdyn_or_none()


def needs_mbdyn(test):
    """Mark a test ``mbdyn``; skip it, saying why, when no MBDyn executable exists."""
    test = pytest.mark.skipif(MBDYN is None, reason="MBDyn not available: build it with "
                              "shared/tools/build-mbdyn and set MBDYN (CI does both)")(test)
    return pytest.mark.mbdyn(test)


def env_with_mbdyn(**extra) -> dict[str, str]:
    """Environment of a user who set MBDYN; ``python`` is the interpreter running the tests."""
    path = os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "")])
    return {**os.environ, "MBDYN": MBDYN or "", "PATH": path, **extra}


# ------------------------------------------------------------------------------------------
# extractor on rotor output files written here (no solver needed)


def write_rot(path: Path, n: int, fx=0.0, fy=0.0, fz=10.0, mx=0.0, my=0.0, mz=-1.0,
              conv=1, drift=0.0, flip=0.0) -> Path:
    """A ``.rot`` file of n steps in MBDyn's column layout; ``drift`` adds a linear trend,
    ``flip`` a relative step-to-step alternation."""
    rows = []
    for i in range(n):
        k = 1.0 + drift * i / n + flip * (-1) ** i
        rows.append([100, fx, fy, fz * k, mx, my, mz * k, 2.0, 0, 0, 0, 0.01, 0, 0, conv, 2])
    path.write_text("".join(" ".join(repr(float(v)) for v in r) + "\n" for r in rows))
    return path


def test_extractor_sign_conventions_and_coefficients(tmp_path):
    rot = write_rot(tmp_path / "a.rot", 8 * 10, mx=3.0, my=-2.0, fz=50.0, mz=-1.5)
    omega, rho, R = 200.0, 1.2, 0.5
    h = hub_loads(rot, omega=omega, rho=rho, radius=R, steps_per_rev=10, revolutions=8)
    area, vt = math.pi * R**2, omega * R
    assert (h.thrust, h.torque, h.roll, h.pitch) == (50.0, 1.5, -3.0, -2.0)
    assert h.power == pytest.approx(1.5 * omega, rel=1e-15)
    assert h.ct == pytest.approx(50.0 / (rho * area * vt**2), rel=1e-15)
    assert h.cq == pytest.approx(1.5 / (rho * area * vt**2 * R), rel=1e-15)
    assert h.periodicity == 0.0 and h.steps == 80


def test_extractor_reads_hub_joint_reaction(tmp_path):
    """With the airframe-hub joint's output, loads are minus its reaction (blade inertia
    included); the rotor file still supplies the inflow convergence flag."""
    rot = write_rot(tmp_path / "a.rot", 80, fz=50.0, mz=-1.5, mx=9.0, my=9.0)
    jnt = tmp_path / "a.jnt"
    # local frame (turning with the hub) first, then the airframe frame the loads come from
    jnt.write_text("".join("3 7. 7. -7. 7. 7. 7. 0. 0. -49.0 -2.5 4.0 1.4 3.\n"
                           for _ in range(80)))
    h = hub_loads(rot, omega=200.0, rho=1.2, radius=0.5, steps_per_rev=10, revolutions=8,
                  joint=jnt)
    np.testing.assert_allclose([h.thrust, h.torque, h.roll, h.pitch], [49.0, 1.4, -2.5, -4.0],
                               rtol=1e-14)
    jnt.write_text(jnt.read_text() * 2)
    with pytest.raises(MBDynError, match="expected the airframe-hub joint alone"):
        hub_loads(rot, omega=200.0, rho=1.2, radius=0.5, steps_per_rev=10, revolutions=8,
                  joint=jnt)


def test_extractor_failures_name_the_cause(tmp_path):
    kw = dict(omega=200.0, rho=1.2, radius=0.5, steps_per_rev=10, revolutions=8)
    with pytest.raises(MBDynError, match="wrote no rotor output"):
        hub_loads(tmp_path / "missing.rot", **kw)
    (tmp_path / "empty.rot").write_text("")
    with pytest.raises(MBDynError, match="empty rotor output"):
        hub_loads(tmp_path / "empty.rot", **kw)
    with pytest.raises(MBDynError, match=r"stopped early: .* 55 time steps of 80"):
        hub_loads(write_rot(tmp_path / "short.rot", 55), **kw)
    with pytest.raises(MBDynError, match="periodic steady state"):
        hub_loads(write_rot(tmp_path / "drift.rot", 80, drift=0.5), **kw)
    with pytest.raises(MBDynError, match="alternate between time steps"):
        hub_loads(write_rot(tmp_path / "flip.rot", 80, flip=0.3), **kw)
    with pytest.raises(MBDynError, match="induced velocity iteration did not converge"):
        hub_loads(write_rot(tmp_path / "noconv.rot", 80, conv=0), **kw)
    bad = write_rot(tmp_path / "bad.rot", 80)
    bad.write_text(bad.read_text() + "100 nan-ish\n")
    with pytest.raises(MBDynError, match=r"bad.rot, line 81"):
        hub_loads(bad, **kw)


def test_find_mbdyn_says_what_it_tried(tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.setenv("MBDYN", str(tmp_path / "nowhere" / "mbdyn"))
    with pytest.raises(MBDynNotFoundError, match=r"MBDYN=.*nowhere.*PATH"):
        find_mbdyn()
    exe = tmp_path / "mbdyn"
    exe.write_text("#!/bin/sh\n")
    exe.chmod(0o755)
    assert find_mbdyn() == exe  # MBDYN is broken: PATH is next
    assert find_mbdyn(exe) == exe
    # an explicit path that is not MBDyn is an error, never a fallback to MBDYN or PATH
    with pytest.raises(MBDynNotFoundError, match=r"--mbdyn=.*elsewhere.* not an executable"):
        find_mbdyn(tmp_path / "elsewhere")
    # the build tool's prefix comes last, and only when asked for
    exe.unlink()
    built = tmp_path / "prefix" / "bin" / "mbdyn"
    built.parent.mkdir(parents=True)
    built.write_text("#!/bin/sh\n")
    built.chmod(0o755)
    monkeypatch.setenv("MBDYN_PREFIX", str(tmp_path / "prefix"))
    with pytest.raises(MBDynNotFoundError, match=r"PATH \(not found\)\. Install"):
        find_mbdyn()
    assert find_mbdyn(build_prefix=True) == built


def test_template_fields_are_all_provided():
    text, path = template_text("rigid")
    vals = template_values(get_preset("gvpm"), {"height_over_radius": math.inf},
                           CaseSettings())
    filled = fill_template(text, vals, path=path)
    assert "set: real H_GROUND = 485000.0;" in filled  # 1e6 R: out of ground effect
    assert set(template_fields(text)) <= set(vals)


def test_inputs_the_template_ignores_are_refused(tmp_path):
    with pytest.raises(ParameterError, match=r"does not use the inputs \['k_pitch_link'\]"):
        run_case(tmp_path, get_preset("gvpm"), {"k_pitch_link": 12.0})
    with pytest.raises(ParameterError, match="did you mean .collective_deg.*not rotor inputs"):
        run_case(tmp_path, get_preset("gvpm"), {"collective": 5.0})
    with pytest.raises(ParameterError, match="height_over_radius must be > 0.25"):
        run_case(tmp_path, get_preset("gvpm"), {"height_over_radius": 0.2})
    with pytest.raises(ParameterError, match="neither a bundled template"):
        run_case(tmp_path, get_preset("gvpm"), {}, template=tmp_path / "nope.mbd")


def test_driver_without_mbdyn_fails_clearly(tmp_path):
    write_parameters(tmp_path / "params.in", {"collective_deg": 5.0}, ["thrust"])
    env = {k: v for k, v in os.environ.items() if k != "MBDYN"}
    env["PATH"] = str(tmp_path)
    env["MBDYN_PREFIX"] = str(tmp_path / "no-build")
    proc = subprocess.run([*DRIVER, "params.in", "results.out"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1
    assert "MBDyn executable not found" in proc.stderr and "MBDYN" in proc.stderr
    assert "no-build" in proc.stderr  # the build tool's install was tried too
    assert read_results(tmp_path / "results.out").failed


@needs_mbdyn
def test_driver_finds_the_build_tools_mbdyn_without_mbdyn_or_path(tmp_path):
    """As the benchmarks and scripts do (``find_mbdyn(build_prefix=True)``): neither
    ``$MBDYN`` nor PATH, only ``$MBDYN_PREFIX/bin/mbdyn``."""
    assert MBDYN is not None
    prefix = Path(MBDYN).resolve().parent.parent
    if not (prefix / "bin" / "mbdyn").is_file():
        pytest.skip(f"MBDyn at {MBDYN} is not in a build prefix's bin/")
    write_parameters(tmp_path / "params.in", {"collective_deg": 5.0}, ["thrust"])
    env = {k: v for k, v in os.environ.items() if k != "MBDYN"}
    env["PATH"] = str(tmp_path)
    env["MBDYN_PREFIX"] = str(prefix)
    proc = subprocess.run([*DRIVER, "--revolutions", "20", "params.in", "results.out"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert not read_results(tmp_path / "results.out").failed


@pytest.mark.parametrize("name", ["mbdyn_rigid", "mbdyn_elastic"])
def test_bundled_studies_parse(name):
    study = load_study(STUDIES / f"{name}.toml")
    assert study.model.kind == "external"
    assert "rotoruq.mbdyn.driver" in study.model.external.command
    assert [s.type for s in study.steps] == ["sampling", "sensitivity"]


# ------------------------------------------------------------------------------------------
# the real solver


@needs_mbdyn
def test_parity_with_builtin_rotor_through_external_model(tmp_path):
    """One MBDyn case per point through ExternalModel and the driver, against the built-in
    rotor on the same physics (:func:`rigid_equivalent`). Same c81 table and stations: thrust
    within 0.01 %; torque within 1 % (MBDyn interpolates the rewritten CD linearly between
    table angles where the built-in model evaluates the quadratic fit: measured 0.1-0.2 %)."""
    names = ["collective_deg", "height_over_radius", "cla_m03"]
    model = ExternalModel([*DRIVER, "--revolutions", "8", "--mbdyn", MBDYN],
                          names, ["thrust", "torque", "power"], workdir=tmp_path)
    x = np.array([[5.4, 4.0, 0.108], [3.0, 1.0, 0.100], [8.0, 1e6, 0.115]])
    batch = model.evaluate(x)
    assert not batch.failures, batch.failures
    builtin = RotorModel(rigid_equivalent(get_preset("gvpm")), names_in=names,
                         names_out=["thrust", "torque", "power"])(x)
    np.testing.assert_allclose(batch.values[:, 0], builtin[:, 0], rtol=1e-4)
    np.testing.assert_allclose(batch.values[:, 1:], builtin[:, 1:], rtol=1e-2)


@pytest.mark.slow
@needs_mbdyn
def test_elastic_rotor_cyclic_moments_are_odd_in_the_command(tmp_path):
    """The elastic GVPM (beams, feathering hinge, pitch-link rod, swashplate) in hover: +1 and
    -1 deg of lateral cyclic give the same thrust and opposite hub moments (exact symmetry of
    the model, checked to 1e-6 relative), and the moment is not negligible (> 0.5 N m per deg;
    the built-in model gives 1.6)."""
    p = get_preset("gvpm")
    settings = CaseSettings(revolutions=6, average=1, tolerance=1e-2)
    base = {"collective_deg": 5.0, "k_pitch_link": 15.0, "ei_flap": 7.0, "longitudinal_deg": 0.0}
    up, down = (run_case(tmp_path / str(s), p, {**base, "lateral_deg": s}, template="elastic",
                         settings=settings, mbdyn=MBDYN) for s in (1.0, -1.0))
    assert up.thrust == pytest.approx(down.thrust, rel=1e-6)
    np.testing.assert_allclose([up.roll, up.pitch], [-down.roll, -down.pitch], rtol=1e-6)
    assert math.hypot(up.roll, up.pitch) > 0.5
    with pytest.raises(ParameterError, match=r"does not use the inputs \['k_flap'\]"):
        run_case(tmp_path / "x", p.replace(flap_model="hinge"), {"k_flap": 50.0},
                 template="elastic", mbdyn=MBDYN)


@needs_mbdyn
def test_not_periodic_and_mbdyn_errors_are_failures(tmp_path):
    p = get_preset("gvpm")
    # two revolutions: the inflow is still settling when the windows are compared
    with pytest.raises(MBDynError, match="periodic steady state"):
        run_case(tmp_path / "a", p, {"collective_deg": 5.0},
                 settings=CaseSettings(revolutions=2, average=1, tolerance=1e-12), mbdyn=MBDYN)
    bad = tmp_path / "bad.mbd"
    bad.write_text(template_text("rigid")[0].replace("max iterations: 20;",
                                                    "max iterations: twenty;"))
    with pytest.raises(MBDynError, match="MBDyn exited with status"):
        run_case(tmp_path / "b", p, {"collective_deg": 5.0}, template=bad, mbdyn=MBDYN)
    # the same through the driver: FAIL in the results file, the reason on stderr
    write_parameters(tmp_path / "params.in", {"collective_deg": 5.0}, ["thrust"])
    proc = subprocess.run([*DRIVER, "--template", str(bad), "params.in", "results.out"],
                          cwd=tmp_path, env=env_with_mbdyn(), capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 1 and "MBDyn exited with status" in proc.stderr
    assert read_results(tmp_path / "results.out").failed


def small_study(folder: Path, n: int) -> Path:
    """The bundled study, smaller: an LHS of n points, 10 revolutions per run."""
    text = (STUDIES / "mbdyn_rigid.toml").read_text()
    text = text.replace('"--revolutions", "40"', '"--revolutions", "10"')
    text = text.replace("n_samples = 20", f"n_samples = {n}")
    head, _, _ = text.partition('[[steps]]\nname = "sensitivity"')
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "mbdyn.toml"
    path.write_text(head)
    return path


def stored(out: Path) -> int:
    db = out / "evaluations.sqlite"
    if not db.exists():
        return 0
    try:
        with sqlite3.connect(db, timeout=5) as con:
            return con.execute("SELECT COUNT(*) FROM evaluations WHERE status = 'ok'"
                               ).fetchone()[0]
    except sqlite3.OperationalError:  # created but not yet initialised
        return 0


@pytest.mark.slow
@needs_mbdyn
def test_study_through_cli_killed_and_resumed(tmp_path):
    n = 6
    study = small_study(tmp_path / "s", n)
    env = env_with_mbdyn()
    ref = subprocess.run([*CLI, "run", str(study), "--out", str(tmp_path / "ref"),
                          "--no-report"], env=env, capture_output=True, text=True, timeout=600)
    assert ref.returncode == 0, ref.stderr
    reference = load_step(tmp_path / "ref" / "steps" / "lhs").arrays["outputs"]
    assert reference.shape == (n, 3) and np.all(np.isfinite(reference))

    out = tmp_path / "out"
    proc = subprocess.Popen([*CLI, "run", str(study), "--out", str(out), "--no-report"],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            start_new_session=True)
    deadline = time.monotonic() + 300
    while stored(out) < 2 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert proc.poll() is None, "the run finished before it could be killed"
    os.killpg(proc.pid, signal.SIGKILL)  # the run, its workers and their MBDyn processes
    proc.wait()
    done_at_kill = stored(out)
    assert 2 <= done_at_kill < n

    res = subprocess.run([*CLI, "run", str(study), "--out", str(out), "--no-report"], env=env,
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    np.testing.assert_array_equal(load_step(out / "steps" / "lhs").arrays["outputs"], reference)
    assert stored(out) == n  # every evaluation stored once: none lost, none repeated


@pytest.mark.slow
@needs_mbdyn
def test_study_runs_on_dask_by_changing_only_the_executor(tmp_path, monkeypatch):
    """The MBDyn study on a real Dask scheduler with two worker processes on loopback (only
    [executor] changes): the same numbers as with local processes."""
    distributed = pytest.importorskip("distributed")
    env = env_with_mbdyn()
    for key in ("MBDYN", "PATH"):  # the workers' environment, as a user's cluster would have
        monkeypatch.setenv(key, env[key])
    study = small_study(tmp_path / "s", 4)
    procs = subprocess.run([*CLI, "run", str(study), "--out", str(tmp_path / "p"),
                            "--no-report"], env=env, capture_output=True, text=True, timeout=600)
    assert procs.returncode == 0, procs.stderr
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        text = study.read_text().replace(
            'kind = "processes"', f'kind = "dask"\nscheduler = "{cluster.scheduler_address}"')
        dask_study = tmp_path / "s" / "dask.toml"
        dask_study.write_text(text)
        res = subprocess.run([*CLI, "run", str(dask_study), "--out", str(tmp_path / "d"),
                              "--no-report"], env=env, capture_output=True, text=True,
                             timeout=600)
    assert res.returncode == 0, res.stderr
    expected = load_step(tmp_path / "p" / "steps" / "lhs").arrays["outputs"]
    assert expected.shape == (4, 3) and np.all(np.isfinite(expected))
    np.testing.assert_array_equal(load_step(tmp_path / "d" / "steps" / "lhs").arrays["outputs"],
                                  expected)
