"""Executors: run a batch of independent tasks and yield each result as it completes.

All executors share one interface::

    with ProcessExecutor() as ex:
        for out in ex.run(fn, tasks):      # out: TaskOutcome(index, value, error, wall_time)
            ...

``run`` is a generator: results arrive in completion order, tagged with the task index; an
exception inside a task becomes ``TaskOutcome.error`` (text with the traceback) and never
stops the other tasks. Closing the generator early (``break``, an exception in the consumer)
cancels the tasks that have not started (a process pool is stopped at once: its running
drivers are killed and no queued task starts).

A fault of the machinery rather than of the task (a pool worker killed, a lost Dask worker, a
cancelled or forgotten future, a broken connection) never becomes an outcome: the task is run
again on a fresh pool or another worker, and when that is not possible ``run`` raises
:class:`~rotoruq.errors.InfrastructureError` after the outcomes it could deliver.

- :class:`SerialExecutor` runs in the calling process.
- :class:`ProcessExecutor` uses a local :class:`concurrent.futures.ProcessPoolExecutor`
  (default: one worker per core). The function is serialized with cloudpickle when it is
  available, so lambdas and closures work.
- :class:`DaskExecutor` submits to a ``dask.distributed`` scheduler (``address`` such as
  ``"tcp://host:8786"``) or to a :class:`~distributed.LocalCluster` it starts itself.
"""

from __future__ import annotations

import concurrent.futures as cf
import logging
import os
import pickle
import signal
import threading
import time
import traceback
import uuid
from abc import ABC, abstractmethod
from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass
from typing import Any

from ..errors import InfrastructureError, ParameterError

log = logging.getLogger(__name__)

__all__ = [
    "TaskOutcome",
    "Executor",
    "SerialExecutor",
    "ProcessExecutor",
    "DaskExecutor",
    "make_executor",
]


@dataclass(frozen=True, eq=False)
class TaskOutcome:
    """Result of one task: ``value`` when it returned, ``error`` (text) when it raised."""

    index: int
    value: Any = None
    error: str | None = None
    wall_time: float = 0.0

    @property
    def ok(self) -> bool:
        return self.error is None


def _dumps(fn) -> bytes:
    try:
        import cloudpickle
    except ImportError:  # pragma: no cover - cloudpickle ships with dask
        return pickle.dumps(fn)
    return cloudpickle.dumps(fn)


_FN_CACHE: dict[int, Callable] = {}


def _call(payload: bytes, task) -> tuple[Any, str | None, float]:
    """Run one task in a worker: unpickle the function (cached), time it, catch errors."""
    key = hash(payload)
    fn = _FN_CACHE.get(key)
    if fn is None:
        try:
            fn = pickle.loads(payload)
        except Exception as exc:  # the task's fault (its function cannot load here)
            return None, f"could not load the task in the worker: {type(exc).__name__}: {exc}", 0.0
        if len(_FN_CACHE) > 8:
            _FN_CACHE.clear()
        _FN_CACHE[key] = fn
    return _timed(fn, task)


def _call_owned(run: str, payload: bytes, task) -> tuple[Any, str | None, float]:
    """:func:`_call` on a Dask worker, the drivers it starts marked as the run ``run``'s (so
    that the run, interrupted, can end them: :func:`_stop_run`)."""
    from .process_tree import owned_by

    with owned_by(run):
        return _call(payload, task)


def _stop_run(run: str) -> int:
    """On a Dask worker (``Client.run``): kill the run ``run``'s drivers and start none of
    its drivers afterwards; the number of driver trees killed."""
    from .process_tree import kill_active_trees

    return kill_active_trees(owner=run, stop=True)


def _timed(fn, task) -> tuple[Any, str | None, float]:
    t0 = time.perf_counter()
    try:
        value = fn(task)
    except Exception as exc:  # a failed task is data, not a crash of the batch
        tb = traceback.format_exc(limit=8)
        return None, f"{type(exc).__name__}: {exc}\n{tb}", time.perf_counter() - t0
    return value, None, time.perf_counter() - t0


class Executor(ABC):
    """Runs ``fn(task)`` for each task and yields :class:`TaskOutcome` as they complete."""

    #: number of tasks that can run at the same time (used to size chunks)
    n_workers: int = 1

    @abstractmethod
    def run(self, fn: Callable[[Any], Any], tasks: Sequence[Any]) -> Generator[TaskOutcome]:
        """Yield one outcome per task, in completion order.

        A task's exception is its outcome's ``error`` (the text and a short traceback), not
        an exception of the batch.

        Parameters
        ----------
        fn : callable
            Called as ``fn(task)``; must be picklable for an executor with worker processes.
        tasks : sequence
            The tasks; each outcome carries its task's index in this sequence.

        Yields
        ------
        TaskOutcome
            The task's index, value or error, and wall time.
        """

    def close(self) -> None:
        """Release workers (a closed executor may be used again; it restarts them)."""
        return None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class SerialExecutor(Executor):
    """Run tasks one after the other in this process."""

    n_workers = 1

    def run(self, fn: Callable[[Any], Any], tasks: Sequence[Any]) -> Generator[TaskOutcome]:
        for i, task in enumerate(tasks):
            value, error, wall = _timed(fn, task)
            yield TaskOutcome(i, value, error, wall)

    def __repr__(self) -> str:
        return "SerialExecutor()"


def _signal_text(code: int | None) -> str:
    if code is None:
        return "still running"
    if code < 0:
        try:
            return f"killed by signal {-code} ({signal.Signals(-code).name})"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}"


def _worker_init(parent: int) -> None:
    """Set up a process-pool worker: it and its drivers end with the run's main process
    (``parent``) and with SIGTERM; Ctrl-C is the main process's to handle."""
    from .process_tree import kill_active_trees, watch_parent

    def on_term(signum, frame):
        kill_active_trees(stop=True)
        os._exit(128 + signum)

    signal.signal(signal.SIGTERM, on_term)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    watch_parent(parent, exit_code=128 + signal.SIGKILL)


class ProcessExecutor(Executor):
    """Local process pool.

    The pool is started on first use and kept until :meth:`close`, so repeated batches do
    not pay the start-up cost again. A worker that dies (killed, out of memory) is an
    infrastructure fault, not a result: the pool is replaced and the tasks it had not finished
    are run again (their results do not depend on the worker); after ``restarts`` replacements
    :meth:`run` raises :class:`~rotoruq.errors.InfrastructureError`. Workers and their
    drivers end with the process that started them (even when it is SIGKILLed), and when
    :meth:`run` is left early (an exception, Ctrl-C, SIGTERM) the workers are stopped at once:
    queued tasks never start and running drivers are killed.

    Parameters
    ----------
    max_workers : number of worker processes (default: ``os.cpu_count()``).
    mp_context : multiprocessing context name ("fork", "spawn", "forkserver") or None for
        Python's default.
    restarts : how many times a broken pool is replaced in one :meth:`run` before giving up.
    """

    def __init__(self, max_workers: int | None = None, *, mp_context: str | None = None,
                 restarts: int = 2):
        self.n_workers = int(max_workers or os.cpu_count() or 1)
        if self.n_workers < 1:
            raise ParameterError(f"max_workers must be >= 1, got {max_workers}")
        if restarts < 0:
            raise ParameterError(f"restarts must be >= 0, got {restarts}")
        self.mp_context = mp_context
        self.restarts = int(restarts)
        self._pool: cf.ProcessPoolExecutor | None = None

    def _get_pool(self) -> cf.ProcessPoolExecutor:
        if self._pool is None:
            import multiprocessing as mp

            ctx = mp.get_context(self.mp_context) if self.mp_context else None
            self._pool = cf.ProcessPoolExecutor(self.n_workers, mp_context=ctx,
                                                initializer=_worker_init,
                                                initargs=(os.getpid(),))
        return self._pool

    def worker_pids(self) -> list[int]:
        """Process ids of the pool's live workers (empty before the first batch)."""
        pool = self._pool
        procs = dict(getattr(pool, "_processes", None) or {}) if pool is not None else {}
        return [pid for pid, p in procs.items() if p.exitcode is None]

    def run(self, fn: Callable[[Any], Any], tasks: Sequence[Any]) -> Generator[TaskOutcome]:
        payload = _dumps(fn)
        todo = list(range(len(tasks)))
        breaks: list[str] = []
        finished = False
        try:
            while todo:
                pool = self._get_pool()
                procs = dict(getattr(pool, "_processes", None) or {})
                futures = {pool.submit(_call, payload, tasks[i]): i for i in todo}
                procs.update(getattr(pool, "_processes", None) or {})
                lost: list[int] = []
                for fut in cf.as_completed(futures):
                    i = futures[fut]
                    try:
                        value, error, wall = fut.result()
                    except cf.process.BrokenProcessPool:
                        lost.append(i)
                        continue
                    except Exception as exc:  # the task or its result could not be pickled
                        value, error, wall = None, f"{type(exc).__name__}: {exc}", 0.0
                    yield TaskOutcome(i, value, error, wall)
                if not lost:
                    break
                breaks.append(self._death_note(procs))
                self._discard_pool()
                todo = sorted(lost)
                if len(breaks) <= self.restarts:
                    log.warning("a process-pool worker died (%s: the out-of-memory killer, a "
                                "kill or a crash in native code); the pool is replaced and its "
                                "%d unfinished task(s) run again (replacement %d of at most %d)",
                                breaks[-1], len(todo), len(breaks), self.restarts)
                if len(breaks) > self.restarts:
                    raise InfrastructureError(
                        f"a process-pool worker died {len(breaks)} time(s) (last: {breaks[-1]}; "
                        "the out-of-memory killer, a kill or a crash in native code); "
                        f"{len(todo)} of {len(tasks)} task(s) were not run and nothing is "
                        "stored for them; finished evaluations are saved: run the same command "
                        "again to resume")
            finished = True
        finally:
            if not finished:  # left early: no queued task may start, running ones end now
                self._discard_pool()

    @staticmethod
    def _death_note(procs: dict) -> str:
        codes: dict = {}
        # the pool terminates the survivors (SIGTERM) once one worker died: name the other
        # (a worker that handles SIGTERM, stopping its drivers first, exits with 128 + 15)
        terminated = (None, -signal.SIGTERM, 128 + signal.SIGTERM)
        # on a loaded machine the dead worker's exit may be read a moment late (the pool's own
        # thread may be reaping it while the survivors' SIGTERM exits are already known): wait
        # up to a few seconds in all for the exit that is not the pool's SIGTERM
        deadline = time.monotonic() + 5.0
        while True:
            for pid, p in procs.items():
                p.join(timeout=max(0.0, min(1.0, deadline - time.monotonic())))
                codes[pid] = p.exitcode
            if (any(c not in terminated for c in codes.values())
                    or all(c is not None for c in codes.values())
                    or time.monotonic() >= deadline):
                break
            time.sleep(0.05)
        dead = [(pid, c) for pid, c in codes.items() if c not in terminated]
        if not dead:
            dead = [(pid, c) for pid, c in codes.items() if c is not None]
        if not dead:
            return "worker process ended"
        pid, code = dead[0]
        return f"PID {pid}, {_signal_text(code)}"

    def _discard_pool(self) -> None:
        """Stop the pool without waiting for its tasks: workers get SIGTERM (they kill their
        drivers and exit), then SIGKILL if they are still there a moment later."""
        pool, self._pool = self._pool, None
        if pool is None:
            return
        procs = list((getattr(pool, "_processes", None) or {}).values())
        for p in procs:
            if p.exitcode is None:
                p.terminate()
        for p in procs:
            p.join(timeout=2.0)
            if p.exitcode is None:
                p.kill()
                p.join(timeout=2.0)
        pool.shutdown(wait=True, cancel_futures=True)

    def close(self) -> None:
        """Shut the pool down (the next :meth:`run` starts a new one)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def __getstate__(self):
        return {"n_workers": self.n_workers, "mp_context": self.mp_context,
                "restarts": self.restarts, "_pool": None}

    def __repr__(self) -> str:
        return f"ProcessExecutor(max_workers={self.n_workers})"


class DaskExecutor(Executor):
    """Dask distributed.

    External-solver tasks release the GIL while they wait for the subprocess, so threads are
    fine for them; vectorized Python models are better served by one thread per worker.

    A task's own failure comes back as :attr:`TaskOutcome.error`. A lost worker, a cancelled
    or forgotten future or a broken connection is not a result: the task is submitted again
    (Dask runs it on another worker); when no worker is left for ``worker_timeout`` seconds,
    or a task was lost ``resubmits + 1`` times, :meth:`run` raises
    :class:`~rotoruq.errors.InfrastructureError` and nothing is reported for the lost tasks.

    When :meth:`run` is left early (Ctrl-C, SIGTERM, an error), the tasks that finished are
    delivered first if the interruption came while it waited, then its futures are cancelled
    and every worker kills the drivers of this run (only this run's: a worker may serve
    others) and starts none of them afterwards; all within ``STOP_SECONDS`` even when the
    scheduler does not answer.

    Parameters
    ----------
    address : scheduler address (``"tcp://host:8786"``); None starts a LocalCluster.
    client : an existing ``distributed.Client`` to use instead (not closed by :meth:`close`).
    n_workers, threads_per_worker : size of the LocalCluster when one is started.
    resubmits : how many times a task lost to the infrastructure is submitted again.
    worker_timeout : seconds to wait for a worker when the scheduler has none left, before
        :meth:`run` raises :class:`~rotoruq.errors.InfrastructureError` (default: the
        ``ROTORUQ_DASK_WORKER_TIMEOUT`` environment variable, else 30).
    """

    #: seconds that leaving :meth:`run` early may spend on fetching finished results and on
    #: stopping the workers' drivers, each
    STOP_SECONDS = 2.0

    def __init__(
        self, address: str | None = None, *, client: Any = None, n_workers: int | None = None,
        threads_per_worker: int = 1, resubmits: int = 3, worker_timeout: float | None = None,
    ):
        self.address = address
        self._n_local = n_workers
        self._threads = threads_per_worker
        self._client = client
        self._own_client = client is None
        self._cluster: Any = None
        if worker_timeout is None:
            env = os.environ.get("ROTORUQ_DASK_WORKER_TIMEOUT", "30")
            try:
                worker_timeout = float(env)
            except ValueError:
                raise ParameterError("ROTORUQ_DASK_WORKER_TIMEOUT must be a number of seconds, "
                                     f"got {env!r}") from None
        if not worker_timeout >= 0 or resubmits < 0:
            raise ParameterError(f"worker_timeout and resubmits must be >= 0, got "
                                 f"{worker_timeout} and {resubmits}")
        self.resubmits = int(resubmits)
        self.worker_timeout = float(worker_timeout)

    @property
    def client(self) -> Any:
        """The ``distributed.Client`` (started on first use; a local cluster without an
        address)."""
        if self._client is None:
            try:
                from distributed import Client, LocalCluster
            except ImportError as exc:  # pragma: no cover
                raise ImportError("the Dask executor needs dask[distributed]: "
                                  "pip install 'rotoruq[dask]'") from exc
            if self.address is not None:
                self._client = Client(self.address)
            else:
                self._cluster = LocalCluster(
                    n_workers=self._n_local or os.cpu_count() or 1,
                    threads_per_worker=self._threads, processes=True,
                    dashboard_address=None)
                self._client = Client(self._cluster)
            _quiet_internal_exits(self._client)
        return self._client

    @property
    def n_workers(self) -> int:  # type: ignore[override]
        """Worker threads the scheduler has now (at least 1), to size the chunks."""
        info = self.client.scheduler_info()
        n = sum(w.get("nthreads", 1) for w in info.get("workers", {}).values())
        return max(1, n)

    def _n_live(self) -> int:
        try:
            return len(self.client.scheduler_info().get("workers", {}))
        except Exception:  # the scheduler cannot be reached: no workers as far as we know
            return 0

    def _where(self) -> str:
        return self.address or (self._cluster.scheduler_address if self._cluster else "?")

    def run(self, fn: Callable[[Any], Any], tasks: Sequence[Any]) -> Generator[TaskOutcome]:
        from distributed import wait

        client = self.client
        blob = _dumps(fn)
        run = uuid.uuid4().hex
        lost_count = [0] * len(tasks)
        futures: dict[Any, int] = {}

        def submit(indices: list[int]) -> None:
            # the function travels inside each task's graph, not scattered: scattered data
            # dies with the worker holding it and takes every waiting task with it
            for i in indices:
                futures[client.submit(_call_owned, run, blob, tasks[i], pure=False)] = i

        submit(list(range(len(tasks))))
        no_worker_since: float | None = None
        last_error = ""
        try:
            while futures:
                try:
                    done, _ = wait(list(futures), timeout=0.5, return_when="FIRST_COMPLETED")
                except TimeoutError:
                    done = set()
                except Exception as exc:  # connection to the scheduler lost
                    done, last_error = set(), f"{type(exc).__name__}: {exc}"
                again: list[int] = []
                got = False
                for fut in done:
                    i = futures.pop(fut)
                    try:
                        if fut.status == "cancelled":
                            raise cf.CancelledError(f"task {fut.key} was cancelled")
                        value, error, wall = fut.result(timeout=2.0)
                    except TimeoutError:
                        # finished, then its worker died before the result was fetched: the
                        # task waits to run again; keep waiting for it
                        futures[fut] = i
                        continue
                    except Exception as exc:  # lost worker, data or connection
                        last_error = f"{type(exc).__name__}: {exc}".splitlines()[0]
                        lost_count[i] += 1
                        if lost_count[i] > self.resubmits:
                            raise InfrastructureError(
                                f"a task was lost on the Dask cluster at {self._where()} "
                                f"{lost_count[i]} times ({last_error}); finished evaluations "
                                "are saved: run the same command again to resume") from None
                        again.append(i)
                        continue
                    got = True
                    yield TaskOutcome(i, value, error, wall)
                if again:
                    submit(again)
                if not got:
                    if self._n_live():
                        no_worker_since = None
                    elif no_worker_since is None:
                        no_worker_since = time.monotonic()
                    elif time.monotonic() - no_worker_since > self.worker_timeout:
                        raise InfrastructureError(
                            f"all Dask workers lost at {self._where()} (none came back within "
                            f"{self.worker_timeout:g} s; {len(futures)} of {len(tasks)} task(s) "
                            "not run); finished evaluations are saved: resume with "
                            "`rotoruq run` when workers are back"
                            + (f" (last error: {last_error})" if last_error else ""))
        except KeyboardInterrupt:  # Ctrl-C, SIGTERM while waiting: what finished counts
            yield from self._finished(futures)
            raise
        finally:
            if futures:
                self._stop(run, [f for f in futures if not f.done()])

    def _finished(self, futures: dict[Any, int]) -> Generator[TaskOutcome]:
        """The outcomes of the futures that are finished, fetched within ``STOP_SECONDS``
        (removed from ``futures``)."""
        end = time.monotonic() + self.STOP_SECONDS
        for fut, i in list(futures.items()):
            left = end - time.monotonic()
            if fut.status != "finished" or left <= 0:
                continue
            try:
                value, error, wall = fut.result(timeout=left)
            except Exception:  # lost meanwhile: it is simply not delivered
                continue
            del futures[fut]
            yield TaskOutcome(i, value, error, wall)

    def _stop(self, run: str, futures: list[Any]) -> None:
        """Cancel ``futures`` and have every worker kill the run's drivers, without waiting
        more than ``STOP_SECONDS`` for an answer (a signal to the run does not wait for a
        scheduler that is gone)."""
        client = self.client

        def stop() -> None:
            try:
                client.cancel(futures)
                client.run(_stop_run, run, on_error="ignore")
            except Exception:  # the scheduler or a worker is gone: nothing left to stop there
                pass

        t = threading.Thread(target=stop, name="rotoruq-dask-stop", daemon=True)
        t.start()
        t.join(self.STOP_SECONDS)

    def close(self) -> None:
        """Close the client and the local cluster this executor started (a client given to
        it stays open)."""
        if self._client is not None and self._own_client:
            self._client.close()
            self._client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    def __repr__(self) -> str:
        return f"DaskExecutor(address={self.address!r})"


class _SyncCancelBug(logging.Filter):
    """Drop tornado's report of distributed's ``sync()`` cancel bug, and nothing else.

    Ctrl-C (or SIGTERM) that lands while the client waits in ``distributed.utils.sync``
    before the loop has started the call queues ``cancel``, which reads the call's future
    before it exists: tornado logs ``NameError: cannot access free variable 'future'`` with a
    traceback from ``distributed/utils.py`` (distributed 2026.8 and earlier). The interrupt is
    already handled and reported by the CLI in one line; any other callback error still shows.
    """

    def filter(self, record: logging.LogRecord) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        if not isinstance(exc, NameError) or exc.__traceback__ is None:
            return True
        last = traceback.extract_tb(exc.__traceback__)[-1]
        return not (last.name == "cancel"
                    and last.filename.replace(os.sep, "/").endswith("distributed/utils.py"))


_SYNC_CANCEL_BUG = _SyncCancelBug()


def _quiet_internal_exits(client: Any) -> None:
    """Keep distributed's internal exits off the user's terminal.

    ``Future.result(timeout=)`` on a worker that dies leaves a gather task behind on the
    client's event loop; it ends with ``distributed.client.AllExit`` (distributed's own
    early-exit signal, never an error of ours) and asyncio prints "Task exception was never
    retrieved" with a traceback when it is collected. The executor has already reported the
    loss in one line; every other loop error still goes to the previous handler. The same
    holds for the NameError of distributed's ``sync`` when it is interrupted
    (:class:`_SyncCancelBug`).
    """
    logging.getLogger("tornado.application").addFilter(_SYNC_CANCEL_BUG)  # a set: idempotent
    loop = getattr(getattr(client, "loop", None), "asyncio_loop", None)
    if loop is None:  # pragma: no cover - distributed without a tornado IOLoop
        return
    previous = loop.get_exception_handler()

    def handler(lp: Any, context: dict[str, Any]) -> None:
        if type(context.get("exception")).__name__ == "AllExit":
            return
        if previous is not None:
            previous(lp, context)
        else:
            lp.default_exception_handler(context)

    loop.set_exception_handler(handler)


def make_executor(spec: str | Executor | None, **kwargs: Any) -> Executor:
    """An Executor from a name ("serial", "processes", "dask") or an existing Executor.

    ``"processes:4"`` sets the number of workers; ``"dask:tcp://host:8786"`` a scheduler.

    Parameters
    ----------
    spec : str, Executor or None
        ``"serial"`` (or None), ``"processes[:N]"``, ``"dask[:ADDRESS]"``, or an Executor
        (returned as it is).
    **kwargs
        ``max_workers``, ``restarts`` (processes); ``address``, ``resubmits``,
        ``worker_timeout`` (dask); the others are ignored.
    """
    if isinstance(spec, Executor):
        return spec
    if spec is None or spec == "serial":
        return SerialExecutor()
    if not isinstance(spec, str):
        raise ParameterError(f"executor must be a name or an Executor, got {spec!r}")
    name, _, arg = spec.partition(":")
    if name == "processes":
        return ProcessExecutor(int(arg) if arg else kwargs.get("max_workers"),
                               **{k: kwargs[k] for k in ("restarts",) if k in kwargs})
    if name == "dask":
        return DaskExecutor(arg or kwargs.get("address"),
                            **{k: kwargs[k] for k in ("resubmits", "worker_timeout")
                               if k in kwargs})
    raise ParameterError(f"unknown executor {spec!r}; use 'serial', 'processes[:N]', "
                     "'dask[:tcp://host:port]' or an Executor instance")
