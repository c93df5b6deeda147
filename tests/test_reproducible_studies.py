"""Every bundled study, run twice into fresh folders through the CLI, once with 1 and once
with 2 threads for numba and BLAS (the second with its independent steps in two processes,
``--jobs 2``), saves bitwise the same arrays and the same tables (issue 21's first acceptance
test: the same seed gives the same posterior, the same forward checks, the same everything;
issue 35: at any thread count; issue 34: at any job count).

The MBDyn studies' second run starts in a folder holding a copy of the first run's
evaluation store: MBDyn is an external one-threaded process whose answers the store keys by
everything that changes them, so the second run replays them (no MBDyn process starts,
counted by an ``MBDYN`` that records each start) and only our side runs again at 2 threads:
the samplers, estimators, emulators and tables. ``mbdyn_multifidelity``'s first run is
``test_multifidelity_study.py::test_mbdyn_study_runs_through_the_cli``'s, which calls
:func:`assert_replays_bitwise` on it."""

from __future__ import annotations

import os
import shlex
import sqlite3
import subprocess
import sys
from contextlib import closing
from pathlib import Path

import numpy as np
import pytest

from rotoruq.methods.mcmc.export import read_chains
from test_mbdyn import MBDYN, env_with_mbdyn, needs_mbdyn

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from thread_determinism import THREAD_VARIABLES  # noqa: E402

STUDIES = Path(__file__).resolve().parents[1] / "src" / "rotoruq" / "studies"
CLI = [sys.executable, "-m", "rotoruq.study.cli"]
# the MBDyn studies: their second run replays the first's MBDyn runs from a copy of its store
# (test_mbdyn_study_repeats_bitwise_replaying_its_runs below; mbdyn_multifidelity's first run
# is test_multifidelity_study.py's)
BUNDLED = [p.stem for p in sorted(STUDIES.glob("*.toml")) if not p.stem.startswith("mbdyn")]
MBDYN_STUDIES = ["mbdyn_rigid", "mbdyn_elastic"]
STORE = "evaluations.sqlite"


def _run(study: str, out: Path, threads: int, jobs: int = 1,
         env: dict[str, str] | None = None) -> None:
    if env is None:
        env = env_with_mbdyn() if study.startswith("mbdyn") else dict(os.environ)
    else:
        env = dict(env)
    if not study.startswith("mbdyn"):
        # a study's MBDyn step (`needs = ["mbdyn"]`) is skipped: its runs are the MBDyn
        # studies' here (minutes on 2 cores), and tests/test_mbdyn_forward.py runs it
        env.pop("MBDYN", None)
        env["MBDYN_PREFIX"] = str(out.parent / "no-mbdyn")
    env.update({k: str(threads) for k in THREAD_VARIABLES})
    proc = subprocess.run([*CLI, "run", study, "--quick", "--no-report", "--out", str(out),
                           "--jobs", str(jobs)],
                          capture_output=True, text=True, env=env, timeout=1800)
    assert proc.returncode == 0, proc.stderr[-3000:]


def _saved(out: Path) -> dict[str, Path]:
    """Every array and table a run saved, by path relative to its folder (the store of model
    evaluations and the run's timing log are not results)."""
    steps = out / "steps"
    return {str(p.relative_to(out)): p for p in sorted(steps.rglob("*"))
            if p.suffix in (".npy", ".csv", ".nc", ".npz") or p.name == "result.json"}


def _numbers(path: Path) -> dict:
    """What a ``result.json`` holds of the step's numbers: its record's plain fields, the
    scalars outside the record and the distributions handed on (not its timing, paths or
    checksum, which differ between two runs into two folders)."""
    import json

    doc = json.loads(path.read_text())
    return {"record": (doc.get("meta") or {}).get("record"),
            "scalars": {k: v for k, v in doc.get("scalars", {}).items()
                        if not k.endswith(("seconds", "_per_second"))},
            "distributions": doc.get("distributions")}


def _differences(a: Path, b: Path) -> list[str]:
    fa, fb = _saved(a), _saved(b)
    diff = [f"{k}: saved by one run only" for k in sorted(set(fa) ^ set(fb))]
    for key in sorted(set(fa) & set(fb)):
        pa, pb = fa[key], fb[key]
        if pa.suffix == ".npy":
            x, y = np.load(pa, allow_pickle=False), np.load(pb, allow_pickle=False)
            if x.shape != y.shape or x.tobytes() != y.tobytes():
                where = (np.nanmax(np.abs(x - y)) if x.shape == y.shape
                         and x.dtype.kind == "f" else "shape/dtype")
                diff.append(f"{key}: arrays differ (max |diff| {where})")
        elif pa.suffix in (".npz", ".nc"):
            # the archive's own bytes carry a write time; its arrays must not differ
            x, y = read_chains(pa), read_chains(pb)
            if x.names != y.names or x.chains.tobytes() != y.chains.tobytes():
                diff.append(f"{key}: exported chains differ")
        elif pa.name == "result.json":
            if _numbers(pa) != _numbers(pb):
                diff.append(f"{key}: the record, scalars or distributions differ")
        elif key.endswith("scalars.csv"):
            # wall and CPU times are measurements of the run, not results
            rows = [[ln for ln in p.read_text().splitlines()
                     if not ln.split(",")[0].endswith(("seconds", "_per_second"))]
                    for p in (pa, pb)]
            if rows[0] != rows[1]:
                bad = [ra.split(",")[0] for ra, rb in zip(*rows, strict=False) if ra != rb]
                diff.append(f"{key}: rows differ: {bad[:8]}")
        elif pa.read_bytes() != pb.read_bytes():
            diff.append(f"{key}: files differ")
    return diff


def counting_mbdyn(folder: Path) -> tuple[dict[str, str], Path]:
    """The environment of a user whose ``MBDYN`` is a script that appends a line to a log
    each time it starts, then runs the real solver; returns (environment, log path)."""
    assert MBDYN is not None
    starts = folder / "mbdyn-starts.log"
    script = folder / "mbdyn-counting"
    script.write_text(f"#!/bin/sh\necho $$ >> {shlex.quote(str(starts))}\n"
                      f"exec {shlex.quote(MBDYN)} \"$@\"\n")
    script.chmod(0o755)
    return env_with_mbdyn(MBDYN=str(script)), starts


def mbdyn_starts(log: Path) -> int:
    """MBDyn processes started so far with :func:`counting_mbdyn`'s environment."""
    return len(log.read_text().splitlines()) if log.exists() else 0


def stored_rows(out: Path) -> int:
    """Rows (evaluations, failed ones included) in a results folder's store."""
    with closing(sqlite3.connect(out / STORE)) as con:
        return int(con.execute("SELECT COUNT(*) FROM evaluations").fetchone()[0])


def assert_replays_bitwise(study: str, first: Path, second: Path, env: dict[str, str],
                           starts: Path) -> None:
    """Run ``study`` again into ``second`` at 2 threads and ``--jobs 2``, starting from a
    copy of ``first``'s evaluation store (nothing else of it), with ``env`` (a
    :func:`counting_mbdyn` environment logging to ``starts``); assert that no MBDyn process
    started, the store gained no row, and every saved array and table equals ``first``'s bit
    for bit."""
    second.mkdir(parents=True)
    # SQLite's own backup: the copy holds every committed row, whatever the journal mode
    with closing(sqlite3.connect(first / STORE)) as src, \
            closing(sqlite3.connect(second / STORE)) as dst:
        src.backup(dst)
    rows, before = stored_rows(second), mbdyn_starts(starts)
    assert rows > 0, "the first run stored no evaluation"
    _run(study, second, threads=2, jobs=2, env=env)
    assert mbdyn_starts(starts) - before == 0, "the second run started MBDyn"
    assert stored_rows(second) == rows, "the second run stored new evaluations"
    assert _saved(first), "the run saved no arrays"
    assert _differences(first, second) == []


@pytest.mark.slow
@pytest.mark.parametrize("study", BUNDLED)
def test_bundled_study_repeats_bitwise_at_1_and_2_threads(study, tmp_path):
    """Same seed, same bits, at any thread count (issue 35, item 4) and job count (issue
    34): the two runs of every bundled study differ in their numba and BLAS threads (1, then
    2) and in the processes their independent steps run on (1, then 2), nothing else."""
    _run(study, tmp_path / "a", threads=1)
    _run(study, tmp_path / "b", threads=2, jobs=2)
    assert _saved(tmp_path / "a"), "the run saved no arrays"
    assert _differences(tmp_path / "a", tmp_path / "b") == []


@pytest.mark.slow
@needs_mbdyn
@pytest.mark.parametrize("study", MBDYN_STUDIES)
def test_mbdyn_study_repeats_bitwise_replaying_its_runs(study, tmp_path):
    """An MBDyn study at 1 thread, then at 2 threads and ``--jobs 2`` replaying its MBDyn
    runs from a copy of the first run's store: every MBDyn run of the first started the
    counted solver once, the second started none, and both saved the same bits."""
    env, starts = counting_mbdyn(tmp_path)
    _run(study, tmp_path / "a", threads=1, env=env)
    assert mbdyn_starts(starts) == stored_rows(tmp_path / "a") > 0
    assert_replays_bitwise(study, tmp_path / "a", tmp_path / "b", env, starts)
