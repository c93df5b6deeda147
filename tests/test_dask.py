"""External evaluations through a real Dask scheduler and two worker processes on loopback."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from rotoruq.evaluation.evaluator import Evaluator
from rotoruq.evaluation.executors import DaskExecutor
from rotoruq.evaluation.external import ExternalModel
from rotoruq.evaluation.store import Store
from rotoruq.model import FunctionModel

# Writes f = 3 a and records the pid of the process that ran it (the Dask worker).
DRIVER = r'''
import os, sys, time
params, results = sys.argv[1], sys.argv[2]
lines = open(params).read().splitlines()
a = float(lines[1].split()[0])
time.sleep(0.15)
if a == 5.0:
    sys.stderr.write("solver diverged\n")
    sys.exit(2)
pid = os.getppid()
try:  # on Linux the driver's parent is its watchdog, whose parent is the worker
    if b"_watchdog" in open(f"/proc/{pid}/cmdline", "rb").read():
        pid = int(open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()[1])
except OSError:
    pass
open(results, "w").write(f"{3 * a!r} f\n{pid} worker_pid\n")
'''


@pytest.fixture(scope="module")
def cluster():
    # imported here, not at the module's top: every pytest worker collects this file
    distributed = pytest.importorskip("distributed")
    cl = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None)
    yield cl
    cl.close()


def test_external_batch_on_two_workers(cluster, tmp_path):
    assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
    driver = tmp_path / "driver.py"
    driver.write_text(DRIVER)
    m = ExternalModel([sys.executable, "-S", str(driver)], ["a"], ["f", "worker_pid"],
                      workdir=tmp_path / "work")
    ex = DaskExecutor(cluster.scheduler_address)
    try:
        assert ex.n_workers == 2
        x = np.arange(1.0, 11.0)[:, None]
        with Evaluator(m, store=tmp_path / "d.db", executor=ex, study="dask") as ev:
            out = ev.evaluate(x)
        ok = np.flatnonzero(x[:, 0] != 5.0)
        np.testing.assert_array_equal(out.values[ok, 0], 3 * x[ok, 0])
        assert set(out.failures) == {4} and "solver diverged" in out.failures[4]
        worker_pids = {int(p) for p in out.values[ok, 1]}
        assert len(worker_pids) == 2  # both workers ran evaluations
        recs = Store(tmp_path / "d.db").records(study="dask")
        assert len(recs) == 10
        failed = [r for r in recs if r.status == "failed"]
        assert len(failed) == 1 and "solver diverged" in failed[0].stderr
        # a second pass through Dask reuses everything that succeeded
        with Evaluator(m, store=tmp_path / "d.db", executor=ex, study="dask") as ev:
            again = ev.evaluate(x)
            assert ev.last_stats.n_reused == 9 and ev.last_stats.n_evaluations == 1
        np.testing.assert_array_equal(again.values[ok], out.values[ok])
    finally:
        ex.close()


def test_vectorized_model_chunks_on_dask(cluster):
    m = FunctionModel(lambda x: np.c_[x[:, 0] ** 2, x.sum(axis=1)], ["a", "b"], ["f", "g"])
    x = np.random.default_rng(2).normal(size=(50, 2))
    with DaskExecutor(cluster.scheduler_address) as ex:
        out = Evaluator(m, executor=ex, chunk_size=8).evaluate(x)
    np.testing.assert_array_equal(out.values, m(x))


@pytest.mark.slow  # ~30 CPU-s (six study runs, the Dask workers); the two above stay fast
def test_study_file_runs_on_dask_by_changing_only_the_executor(cluster, tmp_path):
    """A user's path: the same study file through `rotoruq run`, serial, with processes and on
    the Dask scheduler (the [executor] table is all that changes): bitwise equal results, for
    an external solver and for the rotor model."""
    import subprocess

    from _inproc import rotoruq
    from test_trust import CLI, external_study, outputs

    rotor = """
[study]
name = "rotor"
seed = 2

[model]
preset = "gvpm"
responses = ["thrust", "torque"]
fixed = { height_over_radius = 2.0 }

[parameters.k_pitch_link]
distribution = "uniform"
lower = 10.0
upper = 20.0

[parameters.collective_deg]
distribution = "normal"
mean = 5.4
std = 0.3

{executor}

[[steps]]
name = "lhs"
type = "sampling"
n_samples = 40
"""
    executors = {
        "serial": '[executor]\nkind = "serial"',
        "processes": '[executor]\nkind = "processes"\nworkers = 2',
        "dask": f'[executor]\nkind = "dask"\nscheduler = "{cluster.scheduler_address}"',
    }
    results: dict[str, dict[str, np.ndarray]] = {"ext": {}, "rotor": {}}
    for name, table in executors.items():
        folder = tmp_path / name
        ext = external_study(folder, n=10, executor=name)
        text = ext.read_text()
        if name == "dask":
            text = text.replace('kind = "dask"',
                                f'kind = "dask"\nscheduler = "{cluster.scheduler_address}"')
        ext.write_text(text)
        (folder / "rotor.toml").write_text(rotor.replace("{executor}", table))
        for kind, study in (("ext", ext), ("rotor", folder / "rotor.toml")):
            out = folder / f"out_{kind}"
            args = ["run", str(study), "--out", str(out), "--no-report"]
            if name == "dask":  # a fresh process: its Dask client leaves none behind here
                proc = subprocess.run([*CLI, *args], capture_output=True, text=True,
                                      timeout=300)
            else:  # the CLI's entry point in this process (tests/_inproc.py)
                proc = rotoruq(*args)
            assert proc.returncode == 0, proc.stderr
            results[kind][name] = outputs(out)
    for kind, by_exec in results.items():
        assert np.isfinite(by_exec["serial"]).all(), kind
        for name in ("processes", "dask"):
            np.testing.assert_array_equal(by_exec[name], by_exec["serial"], err_msg=kind)
