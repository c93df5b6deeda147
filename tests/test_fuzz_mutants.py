"""Seeded structural fuzzing of the bundled study files (issue 36): mutants of their parsed
documents (tests/_study_mutants.py: values of another type, values nested in arrays or tables,
huge, tiny, NaN, infinite or negative numbers, keys removed, added or renamed) go through
the study loader and, when it accepts them, through what a run and an export build from them
before any evaluation: the model at the parameters' medians (one evaluation of a built-in
rotor) and the Dakota decks. Every rejection must be a :class:`~rotoruq.errors.RotoruqError`
whose message names the file; any other exception is a traceback the user would see.
A sample goes through ``rotoruq dakota export`` in a subprocess (the user's path). The
in-suite run is 500 mutants and 3 CLI calls (each a fresh interpreter: about 2 s on a quiet
machine, 9 s on a loaded one); the slow run 5,000 and 40. Mutants that load run their
first step through the CLI's entry point in the test's process (3 in the suite, 30 in the
slow run)."""

from __future__ import annotations

import os
import subprocess
import sys
import traceback
from pathlib import Path

import numpy as np
import pytest

from _inproc import rotoruq
from _study_mutants import bundled, mutants, to_toml
from rotoruq.errors import RotoruqError
from rotoruq.study.schema import load_study

SEED = 20261202
SRC = str(Path(__file__).resolve().parents[1] / "src")
CLI = [sys.executable, "-m", "rotoruq.study.cli"]


def _build(study) -> None:
    """What a run and an export build before any evaluation."""
    from rotoruq.study.deck import study_to_decks
    from rotoruq.study.runner import build_model

    study_to_decks(study, quick=True)
    spec = study.model
    if spec.preset is None:
        return
    names = [p.name for p in study.parameters]
    model = build_model(study, names, list(spec.responses), dict(spec.fixed))
    x = np.array([[float(p.distribution.ppf(0.5)) for p in study.parameters]])
    model(x)


def judge(text: str, path: Path) -> str | None:
    """None when the mutant loads (and builds) or is refused with a RotoruqError naming
    ``path``; else what went wrong, with the traceback's last frame."""
    path.write_text(text, encoding="utf-8")
    try:
        study = load_study(path)
        _build(study)
    except RotoruqError as exc:
        if path.name not in str(exc):
            return f"{type(exc).__name__} without the file's name: {exc}"
        return None
    except Exception as exc:  # noqa: BLE001 - the point: nothing else may escape
        frame = traceback.extract_tb(exc.__traceback__)[-1]
        return (f"{type(exc).__name__}: {str(exc)[:200]} "
                f"({Path(frame.filename).name}:{frame.lineno})")
    return None


def _run(tmp_path: Path, n: int) -> None:
    failures = []
    for i, (name, text) in enumerate(mutants(SEED, n)):
        why = judge(text, tmp_path / f"mutant{i}.toml")
        if why is not None:
            failures.append(f"mutant {i} of {name}: {why}")
    assert failures == [], f"{len(failures)} of {n} mutants:\n" + "\n".join(failures[:20])


def test_the_writer_round_trips_every_bundled_study():
    import tomllib

    for name, doc in bundled().items():
        assert tomllib.loads(to_toml(doc)) == doc, name


def test_the_mutants_are_the_same_for_the_same_seed_and_mostly_refused():
    a, b = mutants(SEED, 50), mutants(SEED, 50)
    assert a == b and mutants(SEED + 1, 50) != a
    assert len({text for _, text in a}) > 45


def test_500_mutants_load_or_are_refused_naming_the_file(tmp_path):
    _run(tmp_path, 500)


@pytest.mark.slow
@pytest.mark.extended  # ~6-12 min; the 500 above run in every suite
def test_5000_mutants_load_or_are_refused_naming_the_file(tmp_path):
    _run(tmp_path, 5000)


def _cli(tmp_path: Path, seed: int, n: int) -> None:
    env = {**os.environ, "PYTHONPATH": SRC}
    for i, (name, text) in enumerate(mutants(seed, n)):
        study = tmp_path / f"cli{i}.toml"
        study.write_text(text, encoding="utf-8")
        proc = subprocess.run([*CLI, "dakota", "export", str(study), "-o",
                               str(tmp_path / f"decks{i}")], capture_output=True, text=True,
                              env=env, timeout=300)
        where = f"mutant {i} of {name}"
        assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr, \
            f"{where}: {proc.stderr}"
        if proc.returncode != 0:
            (line,) = [ln for ln in proc.stderr.splitlines() if "error" in ln]
            assert proc.returncode == 1 and line.startswith(
                "rotoruq dakota: error: ") and study.name in line, f"{where}: {proc.stderr}"


def test_a_sample_of_mutants_through_the_cli_is_refused_in_one_line(tmp_path):
    _cli(tmp_path, SEED + 7, 3)


@pytest.mark.slow
@pytest.mark.extended  # 40 CLI runs, ~5 min
def test_a_larger_sample_through_the_cli(tmp_path):
    _cli(tmp_path, SEED + 8, 40)


def test_a_step_naming_a_removed_parameter_is_refused_naming_file_and_line(tmp_path):
    """Found by the 5,000-mutant run: experiment.toml without [parameters.cla_m02], which a
    step still lists, made `rotoruq dakota export` end in a KeyError traceback."""
    doc = bundled()["experiment.toml"]
    del doc["parameters"]["cla_m02"]
    study = tmp_path / "study.toml"
    study.write_text(to_toml(doc), encoding="utf-8")
    proc = subprocess.run([*CLI, "dakota", "export", str(study), "-o", str(tmp_path / "d")],
                          capture_output=True, text=True, timeout=300,
                          env={**os.environ, "PYTHONPATH": SRC})
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    (line,) = [ln for ln in proc.stderr.splitlines() if "error" in ln]
    assert f"{study}, line " in line and "found 'cla_m02'" in line


def _first_steps(tmp_path: Path, seed: int, n: int) -> list[tuple[int, str, Path, str]]:
    """The first ``n`` mutants (of the seeded stream) that load, with their first step: mbdyn
    studies left out (MBDyn's runs are their own tests)."""
    picked = []
    for i, (name, text) in enumerate(mutants(seed, 100 * n)):
        if name.startswith("mbdyn"):
            continue
        path = tmp_path / f"run{i}.toml"
        path.write_text(text, encoding="utf-8")
        try:
            study = load_study(path)
        except RotoruqError:
            continue
        if study.steps:
            picked.append((i, name, path, study.steps[0].name))
        if len(picked) == n:
            break
    return picked


def _run_first_steps(tmp_path: Path, seed: int, n: int) -> None:
    """Mutants that load RUN their first step (``rotoruq run --quick --only``, through the
    CLI's entry point in this process, ``tests/_inproc.py``: an exception that escapes it
    fails the test as a traceback would show): no traceback, no internal error; a failure
    is one line."""
    picked = _first_steps(tmp_path, seed, n)
    assert len(picked) == n
    for i, name, study, step in picked:
        proc = rotoruq("run", study, "--quick", "--only", step, "--out", tmp_path / f"out{i}",
                       "--no-report", "--quiet")
        where = f"mutant {i} of {name} (step {step!r})"
        assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr, \
            f"{where}: {proc.stderr}"
        if proc.returncode != 0:
            errors = [ln for ln in proc.stderr.splitlines() if "error" in ln]
            assert errors and errors[0].startswith("rotoruq run: error: "), \
                f"{where}: {proc.stderr}"


def test_a_sample_of_mutants_runs_its_first_step_through_the_cli(tmp_path):
    _run_first_steps(tmp_path, SEED + 11, 3)


@pytest.mark.slow
@pytest.mark.extended  # 30 CLI runs of a first step, minutes
def test_a_larger_sample_runs_its_first_step_through_the_cli(tmp_path):
    _run_first_steps(tmp_path, SEED + 12, 30)
