"""Infrastructure faults are never results: killed pool workers, lost Dask workers, orphans.

Every test uses real processes (a process pool, a Dask scheduler and worker processes on
loopback, drivers run by an ExternalModel) and kills them with real signals; every wait is
bounded.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from rotoruq.errors import InfrastructureError
from rotoruq.evaluation.evaluator import Evaluator
from rotoruq.evaluation.executors import ProcessExecutor
from rotoruq.evaluation.process_tree import _stat, is_running
from rotoruq.evaluation.store import Store
from rotoruq.model import FunctionModel

SRC = str(Path(__file__).resolve().parents[1] / "src")


def _wait_for(cond, timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.02)


def slow_square(x):
    marks = Path(os.environ["ROTORUQ_TEST_MARKS"])
    (marks / f"{os.getpid()}-{time.monotonic_ns()}").write_text("")
    time.sleep(0.15)
    return np.c_[np.sin(x[:, 0]) * x[:, 1], x[:, 0] ** 2 + x[:, 1]]


def suicide(x):
    os.kill(os.getpid(), signal.SIGKILL)


@pytest.fixture
def marks(tmp_path, monkeypatch):
    d = tmp_path / "marks"
    d.mkdir()
    monkeypatch.setenv("ROTORUQ_TEST_MARKS", str(d))
    return d


def test_killed_pool_worker_is_replaced_and_the_batch_is_bitwise_complete(tmp_path, marks,
                                                                          caplog):
    x = np.random.default_rng(3).uniform(-1, 1, size=(24, 2))
    m = FunctionModel(slow_square, ["a", "b"], ["f", "g"])
    ref = Evaluator(m, chunk_size=2).evaluate(x)
    for f in marks.iterdir():
        f.unlink()
    ex = ProcessExecutor(2)
    killed = []

    def kill_one():
        _wait_for(lambda: len(list(marks.iterdir())) >= 3, 30, "three chunks started")
        pid = ex.worker_pids()[0]
        os.kill(pid, signal.SIGKILL)
        killed.append(pid)

    try:
        with Evaluator(m, store=tmp_path / "e.db", executor=ex, chunk_size=2) as ev:
            t = threading.Thread(target=kill_one)
            t.start()
            out = ev.evaluate(x)
            t.join(10)
        assert killed and not is_running(killed[0])
        np.testing.assert_array_equal(out.values, ref.values)
        assert out.failures == {}
        # said, not replaced in silence (the CLI's run of it: tests/test_terminal.py)
        said = [r.getMessage() for r in caplog.records
                if r.name == "rotoruq.evaluation.executors"]
        assert len(said) == 1 and said[0].startswith(
            f"a process-pool worker died (PID {killed[0]}, killed by signal 9 (SIGKILL)")
        st = Store(tmp_path / "e.db")
        assert st.count() == 24 and st.count(status="failed") == 0
        assert {tuple(r.inputs) for r in st.records()} == {tuple(r) for r in x}
    finally:
        ex.close()


def test_a_pool_that_keeps_dying_raises_and_stores_nothing_for_the_lost_points(tmp_path):
    m = FunctionModel(suicide, ["a"], ["f"])
    ex = ProcessExecutor(2, restarts=1)
    t0 = time.monotonic()
    with Evaluator(m, store=tmp_path / "e.db", executor=ex, chunk_size=1) as ev:
        with pytest.raises(InfrastructureError) as info:
            ev.evaluate(np.arange(4.0)[:, None])
    msg = str(info.value)
    assert "process-pool worker died" in msg and "signal 9 (SIGKILL)" in msg
    assert "4 of 4 task(s) were not run" in msg and "\n" not in msg
    assert Store(tmp_path / "e.db").count() == 0
    assert time.monotonic() - t0 < 30
    assert ex.worker_pids() == []


DRIVER = r'''
import os, sys, time
params, results = sys.argv[1], sys.argv[2]
a = float(open(params).read().splitlines()[1].split()[0])
time.sleep(float(os.environ.get("ROTORUQ_TEST_SLEEP", "0.3")))
open(results, "w").write(f"{3 * a + 0.1!r} f\n")
'''


def _dask_worker(address: str, nthreads: int = 1, **extra: str) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": SRC, **extra}  # the drivers run with the worker's env
    return subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address,
                             "--no-nanny", "--nthreads", str(nthreads), "--host", "127.0.0.1",
                             "--no-dashboard"], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)


@pytest.mark.slow
def test_losing_the_only_dask_worker_raises_and_resume_finishes_bitwise(tmp_path):
    distributed = pytest.importorskip("distributed")
    from rotoruq.evaluation.executors import DaskExecutor
    from rotoruq.evaluation.external import ExternalModel

    driver = tmp_path / "driver.py"
    driver.write_text(DRIVER)
    m = ExternalModel([sys.executable, "-S", str(driver)], ["a"], ["f"],
                      workdir=tmp_path / "work", failure_policy="retry:2")
    x = np.arange(1.0, 17.0)[:, None]
    db = tmp_path / "e.db"
    cluster = distributed.LocalCluster(n_workers=0, host="127.0.0.1", dashboard_address=None)
    workers = [_dask_worker(cluster.scheduler_address)]
    try:
        ex = DaskExecutor(cluster.scheduler_address, worker_timeout=2.0)
        _wait_for(lambda: len(ex.client.scheduler_info()["workers"]) == 1, 60, "a worker")

        def kill_worker():
            _wait_for(lambda: db.exists() and Store(db).count() >= 3, 60, "three results")
            workers[0].kill()

        killer = threading.Thread(target=kill_worker)
        killer.start()
        t0 = time.monotonic()
        with Evaluator(m, store=db, executor=ex) as ev, pytest.raises(InfrastructureError) as e:
            ev.evaluate(x)
        killer.join(10)
        msg = str(e.value)
        assert "all Dask workers lost at " + cluster.scheduler_address in msg
        assert "resume with `rotoruq run` when workers are back" in msg and "\n" not in msg
        assert time.monotonic() - t0 < 60
        st = Store(db)
        n_saved = st.count()
        assert n_saved < 16 and st.count(status="failed") == 0  # results in flight are lost

        workers.append(_dask_worker(cluster.scheduler_address))
        _wait_for(lambda: len(ex.client.scheduler_info()["workers"]) == 1, 60, "a new worker")
        with Evaluator(m, store=db, executor=ex) as ev:
            out = ev.evaluate(x)
            assert ev.last_stats.n_reused == n_saved
            assert ev.last_stats.n_evaluations == 16 - n_saved
        np.testing.assert_array_equal(out.values[:, 0], 3 * x[:, 0] + 0.1)
        assert out.failures == {} and st.count(status="failed") == 0 and st.count() == 16
        ex.close()
    finally:
        for w in workers:
            w.kill()
            w.wait(10)
        cluster.close()


# A run with a process pool whose drivers record themselves (pid, parent pid, point) and then
# sleep: 0.1 s for a <= 2, else 30 s.
RUN = textwrap.dedent('''
    import signal, sys
    import numpy as np
    from rotoruq.evaluation.evaluator import Evaluator
    from rotoruq.evaluation.external import ExternalModel

    def on_term(signum, frame):
        raise KeyboardInterrupt
    signal.signal(signal.SIGTERM, on_term)
    tmp = sys.argv[1]
    m = ExternalModel([sys.executable, "-S", tmp + "/driver.py"], ["a"], ["f"],
                      workdir=tmp + "/work")
    ev = Evaluator(m, store=tmp + "/e.db", executor="processes:2")
    try:
        ev.evaluate(np.arange(1.0, 7.0)[:, None])
    except KeyboardInterrupt:
        print("terminated", flush=True)
    finally:
        ev.close()
''')

SLEEPER = r'''
import os, sys, time
params, results = sys.argv[1], sys.argv[2]
a = float(open(params).read().splitlines()[1].split()[0])
marks = os.path.join(os.path.dirname(os.path.abspath(__file__)), "marks")
with open(os.path.join(marks, f"{os.getpid()}"), "w") as f:
    f.write(f"{os.getppid()} {a}")
time.sleep(0.1 if a <= 2 else 30)
open(results, "w").write(f"{2 * a!r} f\n")
'''


def _start_run(tmp_path) -> tuple[subprocess.Popen, Path]:
    marks = tmp_path / "marks"
    marks.mkdir()
    (tmp_path / "driver.py").write_text(SLEEPER)
    proc = subprocess.Popen([sys.executable, "-c", RUN, str(tmp_path)],
                            env={**os.environ, "PYTHONPATH": SRC}, start_new_session=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return proc, marks


def _drivers(marks: Path) -> dict[int, tuple[int, float]]:
    out = {}
    for f in marks.iterdir():
        text = f.read_text().split()
        if len(text) == 2:
            out[int(f.name)] = (int(text[0]), float(text[1]))
    return out


def _slow_running(marks: Path) -> int:
    return sum(1 for pid, (_, a) in _drivers(marks).items() if a > 2 and is_running(pid))


@pytest.mark.parametrize("whole_group", [False, True], ids=["parent", "process-group"])
def test_sigkill_of_the_run_leaves_no_worker_or_driver(tmp_path, whole_group):
    proc, marks = _start_run(tmp_path)
    try:
        _wait_for(lambda: _slow_running(marks) == 2, 60, "two 30 s drivers running")
        drivers = _drivers(marks)
        # the running drivers' parents are their watchdogs, whose parents are the workers
        watchdogs = {ppid for pid, (ppid, a) in drivers.items() if a > 2 and is_running(pid)}
        workers = {_stat(w)[1] for w in watchdogs}
        assert len(workers) == 2 and proc.pid not in workers
        if whole_group:
            os.killpg(proc.pid, signal.SIGKILL)
        else:
            proc.kill()
        proc.wait(10)
        time.sleep(2.0)
        alive = [p for p in [*drivers, *watchdogs, *workers] if is_running(p)]
        assert alive == [], f"still running 2 s after SIGKILL: {alive}"
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate(timeout=10)


def test_sigterm_starts_no_queued_driver_and_keeps_finished_results(tmp_path):
    proc, marks = _start_run(tmp_path)
    try:
        _wait_for(lambda: _slow_running(marks) == 2, 60, "two 30 s drivers running")
        assert Store(tmp_path / "e.db").count(status="ok") == 2
        drivers = _drivers(marks)
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=15)
        assert time.monotonic() - t0 < 5, "SIGTERM waited for the running drivers"
        assert out.strip() == "terminated", err
        time.sleep(0.5)
        assert _drivers(marks) == drivers  # points 5 and 6 never started
        assert sorted(a for _, a in drivers.values()) == [1.0, 2.0, 3.0, 4.0]
        assert not any(is_running(p) for p in drivers)
        st = Store(tmp_path / "e.db")
        assert st.count() == 2 and st.count(status="ok") == 2
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)


def _pids_running(word: str) -> list[int]:
    """Processes whose command line holds ``word``."""
    found = []
    for d in os.listdir("/proc"):
        try:
            if d.isdigit() and word.encode() in Path(f"/proc/{d}/cmdline").read_bytes():
                found.append(int(d))
        except OSError:  # ended meanwhile
            continue
    return found


def _driver_workers(cli_pid: int) -> list[int]:
    """Pool workers of the CLI running driver.py (the parents of the drivers' watchdogs)."""
    found = set()
    for pid in _pids_running("driver.py"):  # only those whose grandparent is the CLI
        st = _stat(pid)
        if st is not None and st[1] != cli_pid:
            parent = _stat(st[1])
            if parent is not None and parent[1] == cli_pid:
                found.add(st[1])
    return sorted(found)


@pytest.mark.slow
def test_cli_run_survives_a_sigkilled_pool_worker_bitwise(tmp_path):
    """`rotoruq run` with process workers: one worker SIGKILLed mid-step (as the OOM killer
    does) -> the step completes, bitwise equal to an uninterrupted run, no failure stored."""
    from test_trust import CLI, external_study, outputs

    study = external_study(tmp_path / "s", n=12, executor="processes")
    env = {**os.environ, "PYTHONPATH": SRC, "DRIVER_SLEEP": "0.3"}
    ref = subprocess.run([*CLI, "run", str(study), "--out", str(tmp_path / "ref"),
                          "--no-report"], env=env, capture_output=True, text=True, timeout=300)
    assert ref.returncode == 0, ref.stderr
    log = tmp_path / "log"
    proc = subprocess.Popen([*CLI, "run", str(study), "--out", str(tmp_path / "out"),
                             "--no-report"], env={**env, "DRIVER_LOG": str(log)},
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        # the workers seen while a driver runs: read again later, the list can be empty
        # between one evaluation's driver and the next (a 0.3 s driver)
        seen: list[int] = []

        def ready() -> bool:
            if not (log.exists() and len(log.read_text().split()) >= 2):
                return False
            seen[:] = _driver_workers(proc.pid)
            return bool(seen)

        _wait_for(ready, 120, "two finished evaluations")
        victim = seen[0]
        os.kill(victim, signal.SIGKILL)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, err
    assert "Traceback" not in err
    np.testing.assert_array_equal(outputs(tmp_path / "out"), outputs(tmp_path / "ref"))
    st = Store(tmp_path / "out" / "evaluations.sqlite")
    assert st.count(status="failed") == 0 and st.count() == 12


@pytest.mark.parametrize("whole_group", [False, True], ids=["cli", "process-group"])
def test_sigkill_of_the_cli_frees_the_folder_at_once(tmp_path, whole_group):
    """kill -9 of `rotoruq run` (or of its whole process group) with 30 s drivers running on
    process workers: 2 s later no worker or driver is left, and the next run starts at once
    (nothing holds the results folder's lock) and finishes."""
    from test_trust import CLI, external_study, outputs

    study = external_study(tmp_path / "s", n=6, executor="processes")
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": SRC}
    proc = subprocess.Popen([*CLI, "run", str(study), "--out", str(out), "--no-report"],
                            env={**env, "DRIVER_SLEEP": "30"}, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        _wait_for(lambda: len(_driver_workers(proc.pid)) == 2, 120, "two drivers running")
        workers = _driver_workers(proc.pid)
        if whole_group:
            os.killpg(proc.pid, signal.SIGKILL)
        else:
            proc.kill()
        proc.wait(10)
        time.sleep(2.0)
        left = [pid for pid in _pids_running(str(tmp_path)) if is_running(pid)]
        assert left == [] and not any(is_running(w) for w in workers)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    t0 = time.monotonic()
    again = subprocess.run([*CLI, "run", str(study), "--out", str(out), "--no-report"],
                           env=env, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    assert "locked" not in again.stderr.lower() and time.monotonic() - t0 < 120
    assert np.isfinite(outputs(out)).all()


def _dask_study(distributed, folder: Path, n: int):
    """A scheduler on loopback without workers, and test_trust's external study (``n``
    points, ``failure = "retry"``) on it."""
    from test_trust import external_study

    cluster = distributed.LocalCluster(n_workers=0, host="127.0.0.1", dashboard_address=None)
    study = external_study(folder, n=n, executor="dask", failure='failure = "retry"')
    study.write_text(study.read_text().replace(
        'kind = "dask"', f'kind = "dask"\nscheduler = "{cluster.scheduler_address}"'))
    return cluster, study


@pytest.mark.slow
def test_cli_run_losing_the_only_dask_worker_saves_no_step_and_resumes_bitwise(tmp_path):
    """`rotoruq run` on a real scheduler with one worker process: the worker SIGKILLed
    mid-step -> exit 1 with the one-line message, no saved step, no failed evaluation; with a
    new worker the same command finishes, bitwise equal to an uninterrupted run."""
    distributed = pytest.importorskip("distributed")
    from test_trust import CLI, outputs

    cluster, study = _dask_study(distributed, tmp_path / "s", n=12)
    address = cluster.scheduler_address
    env = {**os.environ, "PYTHONPATH": SRC, "ROTORUQ_DASK_WORKER_TIMEOUT": "2"}
    out, log = tmp_path / "out", tmp_path / "log"
    workers = [_dask_worker(address, DRIVER_SLEEP="0.3", DRIVER_LOG=str(log))]
    try:
        proc = subprocess.Popen([*CLI, "run", str(study), "--out", str(out), "--no-report"],
                                env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
        try:
            _wait_for(lambda: proc.poll() is not None
                      or (log.exists() and len(log.read_text().split()) >= 3), 120,
                      "three evaluations")
            assert proc.poll() is None, proc.communicate()
            workers[0].kill()
            _, err = proc.communicate(timeout=120)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
        assert proc.returncode == 1, err
        (line,) = [ln for ln in err.splitlines() if "error" in ln]
        assert "all Dask workers lost at " + address in line and "Traceback" not in err
        assert not (out / "steps" / "lhs" / "result.json").exists()
        st = Store(out / "evaluations.sqlite")
        n_saved = st.count()
        assert n_saved < 12 and st.count(status="failed") == 0  # results in flight are lost

        workers.append(_dask_worker(address))
        for folder in (out, tmp_path / "ref"):
            proc2 = subprocess.run([*CLI, "run", str(study), "--out", str(folder),
                                    "--no-report"], env=env, capture_output=True, text=True,
                                   timeout=300)
            assert proc2.returncode == 0, proc2.stderr
        assert st.count() == 12 and st.count(status="failed") == 0
        np.testing.assert_array_equal(outputs(out), outputs(tmp_path / "ref"))
    finally:
        for w in workers:
            w.kill()
            w.wait(10)
        cluster.close()


# A run on a process pool whose store cannot grow past a file-size limit.
FULL = textwrap.dedent('''
    import resource, sys
    import numpy as np
    from rotoruq.errors import StoreError
    from rotoruq.evaluation.evaluator import Evaluator
    from rotoruq.model import FunctionModel

    def f(x):
        return np.c_[x[:, 0] * 2.0, x[:, 1] ** 2]

    ev = Evaluator(FunctionModel(f, ["a", "b"], ["f", "g"]), store=sys.argv[1],
                   executor="processes:2", chunk_size=50)
    resource.setrlimit(resource.RLIMIT_FSIZE, (200_000, 200_000))  # SIGXFSZ: Python ignores it
    try:
        ev.evaluate(np.random.default_rng(0).normal(size=(20_000, 2)))
    except StoreError as exc:
        print(exc)
''')


def test_store_fault_on_a_process_pool_is_one_line_and_no_pool_traceback(tmp_path):
    path = tmp_path / "e.db"
    proc = subprocess.run([sys.executable, "-c", FULL, str(path)], capture_output=True,
                          text=True, timeout=120, env={**os.environ, "PYTHONPATH": SRC})
    assert proc.returncode == 0, proc.stderr
    (line,) = proc.stdout.splitlines()
    assert line.startswith(f"{path}: ") and "free disk space" in line
    assert proc.stderr == ""  # no concurrent.futures traceback at exit
    st = Store(path)
    assert 0 < st.count() < 20_000 and st.count(status="failed") == 0


def test_dask_internal_allexit_is_not_printed_but_other_loop_errors_are(caplog):
    """distributed's own AllExit, left on the client's loop by a gather whose worker died,
    never reaches the user's terminal; any other unretrieved task exception still does."""
    distributed = pytest.importorskip("distributed")
    from distributed.client import AllExit

    from rotoruq.evaluation.executors import DaskExecutor

    cluster = distributed.LocalCluster(n_workers=0, host="127.0.0.1", dashboard_address=None)
    ex = DaskExecutor(cluster.scheduler_address)
    try:
        loop = ex.client.loop.asyncio_loop
        caplog.clear()
        with caplog.at_level("ERROR", logger="asyncio"):
            loop.call_exception_handler({"message": "Task exception was never retrieved",
                                         "exception": AllExit()})
            assert not [r for r in caplog.records if r.name == "asyncio"]
            loop.call_exception_handler({"message": "Task exception was never retrieved",
                                         "exception": ValueError("ours")})
            assert [r.getMessage() for r in caplog.records if r.name == "asyncio"] == [
                "Task exception was never retrieved"]
    finally:
        ex.close()
        cluster.close()


# Ctrl-C while the client waits in distributed's sync() with the loop busy: the loop runs the
# queued cancel before the call's future exists (distributed's bug); then a callback of ours
# fails, which must still be reported.
SYNC_INTERRUPTED = r'''
import signal, sys, threading, time
import distributed
from distributed.utils import sync
cluster = distributed.LocalCluster(n_workers=0, host="127.0.0.1", dashboard_address=None)
if sys.argv[1] == "rotoruq":
    from rotoruq.evaluation.executors import DaskExecutor
    client = DaskExecutor(cluster.scheduler_address).client
else:
    client = distributed.Client(cluster.scheduler_address)
# a test run started in the background inherits SIGINT ignored, and Python keeps it so
signal.signal(signal.SIGINT, signal.default_int_handler)
client.loop.add_callback(time.sleep, 1.0)
threading.Timer(0.3, signal.pthread_kill, (threading.get_ident(), signal.SIGINT)).start()
async def nothing():
    return 1
try:
    sync(client.loop, nothing)
except KeyboardInterrupt:
    print("interrupted", flush=True)
time.sleep(1.5)
client.loop.add_callback(lambda: 1 / 0)
time.sleep(0.5)
client.close()
cluster.close()
'''


@pytest.mark.parametrize("client", ["distributed", "rotoruq"])
def test_an_interrupted_dask_wait_prints_no_distributed_traceback(client):
    """The NameError traceback distributed's ``sync`` leaves when Ctrl-C lands before its call
    started (seen by the Ctrl-C test below) is not printed by the executor's client; a plain
    ``distributed.Client`` prints it (so the check can fail), and a callback error of any other
    kind is still printed by both."""
    pytest.importorskip("distributed")
    proc = subprocess.run([sys.executable, "-c", SYNC_INTERRUPTED, client], capture_output=True,
                          text=True, timeout=120, env={**os.environ, "PYTHONPATH": SRC})
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == "interrupted\n"
    assert "ZeroDivisionError" in proc.stderr
    bug = "NameError: cannot access free variable 'future'"
    if client == "distributed":
        if bug not in proc.stderr:
            pytest.skip("this distributed's sync() has no cancel bug")
    else:
        assert bug not in proc.stderr and proc.stderr.count("Traceback") == 1, proc.stderr


# The driver of test_trust's external study, run on Dask workers: it records itself (pid -> a)
# and takes 30 s for a > 0.5 (4 of the 8 LHS points), 0.05 s for the others.
SLOW_HALF = r'''
import os, sys, time
vals = {k.strip(): float(v) for k, v in (ln.split("=") for ln in open("input.txt"))}
a = vals["a"]
with open(os.path.join(os.environ["DRIVER_MARKS"], str(os.getpid())), "w") as f:
    f.write(repr(a))
time.sleep(30 if a > 0.5 else 0.05)
open(sys.argv[2], "w").write(f"{2 * a!r} y1\n{a!r} y2\n")
'''


@pytest.mark.parametrize("sig", [signal.SIGTERM, pytest.param(signal.SIGINT,
                                                                 marks=pytest.mark.slow)],
                         ids=["SIGTERM", "Ctrl-C"])
def test_signal_to_a_dask_run_ends_its_drivers_on_the_workers(tmp_path, sig):
    """SIGTERM (or Ctrl-C) of `rotoruq run` on a Dask cluster of two worker processes whose
    threads run 30 s drivers: the CLI exits within 5 s, the 4 results it has are stored and
    nothing else, and 2 s later no driver of the run is left on the workers, which keep
    serving (they are the cluster's, not the run's); a driver killed under `retry` is not
    started again."""
    distributed = pytest.importorskip("distributed")
    from test_trust import CLI

    cluster, study = _dask_study(distributed, tmp_path / "s", n=8)
    address = cluster.scheduler_address
    (tmp_path / "s" / "driver.py").write_text(SLOW_HALF)
    marks = tmp_path / "marks"
    marks.mkdir()
    out = tmp_path / "out"
    workers = [_dask_worker(address, 4, DRIVER_MARKS=str(marks)) for _ in range(2)]

    def drivers() -> dict[int, float]:
        return {int(f.name): float(t) for f in marks.iterdir() if (t := f.read_text())}

    try:
        _wait_for(lambda: len(cluster.scheduler.workers) == 2, 60, "two workers")
        # a terminal's Ctrl-C reaches a foreground CLI whose SIGINT is the default; a test run
        # started in the background (`cmd &` in a script) would hand down SIGINT ignored, and
        # Python keeps an ignored SIGINT ignored
        proc = subprocess.Popen([*CLI, "run", str(study), "--out", str(out), "--no-report"],
                                env={**os.environ, "PYTHONPATH": SRC},
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        try:
            store = out / "evaluations.sqlite"
            _wait_for(lambda: proc.poll() is not None or (
                store.exists() and Store(store).count() == 4
                and sum(a > 0.5 and is_running(p) for p, a in drivers().items()) == 4),
                120, "4 results stored and 4 slow drivers running")
            assert proc.poll() is None, proc.communicate()
            running = drivers()
            t0 = time.monotonic()
            proc.send_signal(sig)
            _, err = proc.communicate(timeout=30)
            took = time.monotonic() - t0
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
        assert took < 5, f"the run took {took:.1f} s to end"
        assert proc.returncode == (143 if sig == signal.SIGTERM else 130), err
        assert ("terminated" if sig == signal.SIGTERM else "interrupted") in err
        assert "Traceback" not in err
        time.sleep(2.0)
        assert [p for p in drivers() if is_running(p)] == []
        assert drivers() == running  # no driver started after the signal (no retry either)
        st = Store(store)
        assert st.count() == 4 and st.count(status="ok") == 4
        assert sorted(r.inputs[0] for r in st.records()) == sorted(
            a for a in running.values() if a <= 0.5)
        assert all(w.poll() is None for w in workers)
        assert len(cluster.scheduler.workers) == 2 and not cluster.scheduler.tasks
    finally:
        for w in workers:
            w.kill()
            w.wait(10)
        cluster.close()


def test_stopping_one_run_leaves_the_drivers_of_another_in_the_same_process(tmp_path):
    """What a Dask worker does for an interrupted run: its drivers are killed and none of
    them starts again, while another run's driver in the same process goes on."""
    from rotoruq.evaluation import process_tree
    from rotoruq.evaluation.process_tree import kill_active_trees, owned_by, run_process_tree

    runs: dict[str, object] = {}

    def drive(owner: str) -> None:
        with owned_by(owner):
            try:
                runs[owner] = run_process_tree(
                    [sys.executable, "-S", "-c", "import time; time.sleep(30)", str(tmp_path)],
                    cwd=tmp_path, stdout_path=tmp_path / f"{owner}.out",
                    stderr_path=tmp_path / f"{owner}.err")
            except InterruptedError as exc:
                runs[owner] = exc

    threads = {o: threading.Thread(target=drive, args=(o,)) for o in ("a", "b")}
    for t in threads.values():
        t.start()
    _wait_for(lambda: len(_pids_running(str(tmp_path))) >= 2, 10, "two drivers")
    # a driver is listed just after it starts: on a busy machine its thread may not be there yet
    _wait_for(lambda: len(process_tree._ACTIVE) >= 2, 10, "two listed driver trees")
    try:
        assert kill_active_trees(owner="a", stop=True) == 1
        threads["a"].join(5)
        assert runs["a"].returncode == -signal.SIGKILL and not threads["a"].is_alive()
        again = threading.Thread(target=drive, args=("a",))
        again.start()
        again.join(5)
        assert isinstance(runs["a"], InterruptedError) and "'a' is stopping" in str(runs["a"])
        assert threads["b"].is_alive() and "b" not in runs
    finally:
        kill_active_trees(owner="b")
        threads["b"].join(5)
    assert runs["b"].returncode == -signal.SIGKILL


@pytest.mark.slow  # a cold compile started, ~10 s
def test_sigterm_during_a_rotor_compile_ends_the_run_at_once(tmp_path):
    """`rotoruq run` of a rotor study on a cold numba cache, SIGTERM while the rotor kernels
    compile on the rotor's thread pool: the run says it was terminated and ends (exit 143)
    within seconds. Found in use: it printed "terminated" and then waited for the compile
    (minutes), because the interpreter joined the pool's threads at exit."""
    study = tmp_path / "s.toml"
    study.write_text(textwrap.dedent("""
        [study]
        name = "cold"
        seed = 1

        [model]
        preset = "gvpm"
        responses = ["thrust"]

        [parameters.cd0_m03]
        distribution = "uniform"
        lower = 0.008
        upper = 0.014

        [[steps]]
        name = "lhs"
        type = "sampling"
        n_samples = 64
        """))
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"), "NUMBA_NUM_THREADS": "2",
           "PYTHONPATH": SRC}
    proc = subprocess.Popen([sys.executable, "-m", "rotoruq", "run", str(study), "--out",
                             str(tmp_path / "out")], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(iter(proc.stderr.readline, "")),
                              daemon=True)
    reader.start()
    try:
        _wait_for(lambda: any(ln.startswith("compiling rotor kernels") for ln in lines), 120,
                  "the rotor compile's notice")
        time.sleep(2.0)  # the batch spread over the pool's two threads, compiling there
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        proc.wait(60)
        assert time.monotonic() - t0 < 10, "SIGTERM waited for the rotor's threads"
        reader.join(10)
        assert proc.returncode == 143, lines
        assert any("terminated" in ln for ln in lines), lines
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)
