"""Executors and the Evaluator over internal (vectorized) models; the progress bar."""

from __future__ import annotations

import io
import os
import time

import numpy as np
import pytest

from rotoruq.evaluation.evaluator import Evaluator, as_evaluator
from rotoruq.evaluation.executors import (
    ProcessExecutor,
    SerialExecutor,
    TaskOutcome,
    make_executor,
)
from rotoruq.evaluation.progress import Progress, format_duration
from rotoruq.model import FunctionModel, evaluate, has_gradient


def square_or_raise(t):
    if t == 3:
        raise ValueError("three is bad")
    return t * t


def sleepy(t):
    time.sleep(t)
    return os.getpid()


@pytest.fixture(scope="module")
def pool():
    ex = ProcessExecutor(2)
    yield ex
    ex.close()


@pytest.mark.parametrize("which", ["serial", "processes"])
def test_errors_are_per_task(which, pool):
    ex = SerialExecutor() if which == "serial" else pool
    outs = sorted(ex.run(square_or_raise, range(6)), key=lambda o: o.index)
    assert [o.value for o in outs] == [0, 1, 4, None, 16, 25]
    assert outs[3].error.startswith("ValueError: three is bad")
    assert all(isinstance(o, TaskOutcome) and o.wall_time >= 0 for o in outs)


def test_process_results_arrive_as_completed_in_parallel(pool):
    t0 = time.perf_counter()
    outs = list(pool.run(sleepy, [0.6, 0.0, 0.0, 0.0]))
    assert outs[-1].index == 0  # the slow task finishes last
    assert len({o.value for o in outs}) == 2  # both workers took part
    assert time.perf_counter() - t0 < 0.6 + 1.5


def test_lambdas_and_closures_run_in_processes(pool):
    k = 7
    outs = list(pool.run(lambda t: t + k, [1, 2]))
    assert sorted(o.value for o in outs) == [8, 9]


def test_closing_the_generator_cancels_pending(tmp_path):
    marks = tmp_path

    def task(i):
        (marks / f"t{i}").write_text("")
        return i

    gen = SerialExecutor().run(task, range(10))
    next(gen)
    gen.close()
    assert len(list(marks.iterdir())) == 1


def test_make_executor():
    assert isinstance(make_executor("serial"), SerialExecutor)
    ex = make_executor("processes:3")
    assert isinstance(ex, ProcessExecutor) and ex.n_workers == 3
    assert make_executor(ex) is ex
    with pytest.raises(ValueError, match="unknown executor"):
        make_executor("threads")


def vec(x):
    return np.c_[np.sin(x[:, 0]) * x[:, 1], np.where(x[:, 0] > 2.5, np.nan, x[:, 0] ** 2)]


@pytest.mark.parametrize("executor", ["serial", "processes"])
@pytest.mark.parametrize("chunk", [None, 1, 7])
def test_evaluator_matches_direct_evaluation(executor, chunk, pool, tmp_path):
    x = np.random.default_rng(5).uniform(0, 3, size=(23, 2))
    x[5] = x[2]  # a duplicate row
    m = FunctionModel(vec, ["u", "v"], ["f", "g"])
    ref = evaluate(m, x)
    ev = Evaluator(m, store=tmp_path / "e.db", executor=pool if executor == "processes"
                   else "serial", chunk_size=chunk)
    out = ev.evaluate(x)
    np.testing.assert_array_equal(out.values, ref.values)
    assert out.failures == ref.failures
    assert ev.last_stats.n_evaluations == 22 and ev.last_stats.n_duplicates == 1
    assert ev.store.count() == 22
    assert ev.store.count(status="failed") == len({tuple(r) for r in x[x[:, 0] > 2.5]})


def test_model_that_raises_fails_only_its_chunk(tmp_path):
    def f(x):
        if np.any(x[:, 0] < 0):
            raise RuntimeError("negative input")
        return x[:, 0] * 2

    m = FunctionModel(f, ["a"], ["f"])
    ev = Evaluator(m, store=tmp_path / "e.db", chunk_size=2)
    out = ev.evaluate(np.array([[1.0], [2.0], [-1.0], [3.0], [4.0]]))
    np.testing.assert_array_equal(out.values[[0, 1, 4], 0], [2.0, 4.0, 8.0])
    assert set(out.failures) == {2, 3}  # the chunk holding the bad point
    assert "negative input" in out.failures[2]
    assert "negative input" in ev.store.records(status="failed")[0].error


def test_evaluator_is_a_model():
    m = FunctionModel(lambda x: x[:, 0] * x[:, 1], ["a", "b"], ["f"],
                      gradient=lambda x: x[:, ::-1])
    ev = as_evaluator(m)
    assert as_evaluator(ev) is ev
    assert ev.names_in == ("a", "b") and has_gradient(ev)
    x = np.array([[2.0, 3.0]])
    np.testing.assert_array_equal(ev(x), [[6.0]])
    np.testing.assert_array_equal(ev.gradient(x), [[[3.0, 2.0]]])
    assert not has_gradient(Evaluator(FunctionModel(np.sin, ["a"], ["f"])))
    with pytest.raises(ValueError, match="shape"):
        ev.evaluate(np.ones((2, 3)))


class FakeTTY(io.StringIO):
    def isatty(self):
        return True


def test_progress_silent_off_terminal_and_drawn_on_one():
    quiet = io.StringIO()
    p = Progress(10, stream=quiet, delay=0.0, interval=0.0)
    for _ in range(10):
        p.update()
    p.close()
    assert quiet.getvalue() == ""
    tty = FakeTTY()
    p = Progress(10, stream=tty, delay=0.0, interval=0.0)
    p.start -= 5.0  # as if 5 s had passed
    p.update(4)
    text = tty.getvalue()
    assert "4/10" in text and "40%" in text and "/s" in text and "ETA 0:0" in text
    p.close()
    assert tty.getvalue().endswith("\n")
    late = FakeTTY()
    p = Progress(10, stream=late, delay=60.0)
    p.update(3)
    p.close()
    assert late.getvalue() == ""  # short runs draw nothing
    assert format_duration(3725) == "1:02:05" and format_duration(65) == "1:05"


def test_executor_fault_options(monkeypatch):
    from rotoruq.evaluation.executors import DaskExecutor

    ex = make_executor("processes:2", restarts=5)
    assert isinstance(ex, ProcessExecutor) and ex.restarts == 5
    with pytest.raises(ValueError, match="restarts"):
        ProcessExecutor(2, restarts=-1)
    monkeypatch.setenv("ROTORUQ_DASK_WORKER_TIMEOUT", "7.5")
    assert DaskExecutor("tcp://127.0.0.1:1").worker_timeout == 7.5  # no connection made
    d = make_executor("dask:tcp://127.0.0.1:1", worker_timeout=3, resubmits=1)
    assert (d.worker_timeout, d.resubmits) == (3.0, 1)
    monkeypatch.setenv("ROTORUQ_DASK_WORKER_TIMEOUT", "soon")
    with pytest.raises(ValueError, match="ROTORUQ_DASK_WORKER_TIMEOUT must be a number"):
        DaskExecutor("tcp://127.0.0.1:1")


def test_pool_left_early_starts_no_queued_task(tmp_path):
    """Closing run() early (an exception in the consumer) stops the pool at once: the running
    tasks end, the queued ones never start, the next batch gets a fresh pool."""
    marks = tmp_path

    def task(i):
        (marks / f"t{i}").write_text("")
        time.sleep(0.3 if i < 2 else 30)
        return i

    ex = ProcessExecutor(2)
    try:
        gen = ex.run(task, range(8))
        first = next(gen)
        t0 = time.perf_counter()
        gen.close()
        assert time.perf_counter() - t0 < 5  # did not wait for the 30 s tasks
        time.sleep(0.5)
        started = {p.name for p in marks.iterdir()}
        assert first.index in (0, 1) and started <= {"t0", "t1", "t2", "t3"}
        t1 = time.perf_counter()
        assert sorted(o.value for o in ex.run(lambda i: i * i, [2, 3])) == [4, 9]
        assert time.perf_counter() - t1 < 10  # no 30 s task holds a worker
    finally:
        ex.close()
