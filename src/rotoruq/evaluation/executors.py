"""Executors: run a batch of independent tasks and yield each result as it completes.

All executors share one interface::

    with ProcessExecutor() as ex:
        for out in ex.run(fn, tasks):      # out: TaskOutcome(index, value, error, wall_time)
            ...

``run`` is a generator: results arrive in completion order, tagged with the task index; an
exception inside a task becomes ``TaskOutcome.error`` (text with the traceback) and never
stops the other tasks. Closing the generator early (``break``, an exception in the consumer)
cancels the tasks that have not started.

- :class:`SerialExecutor` runs in the calling process.
- :class:`ProcessExecutor` uses a local :class:`concurrent.futures.ProcessPoolExecutor`
  (default: one worker per core). The function is serialized with cloudpickle when it is
  available, so lambdas and closures work.
- :class:`DaskExecutor` submits to a ``dask.distributed`` scheduler (``address`` such as
  ``"tcp://host:8786"``) or to a :class:`~distributed.LocalCluster` it starts itself.
"""

from __future__ import annotations

import concurrent.futures as cf
import os
import pickle
import time
import traceback
from abc import ABC, abstractmethod
from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass
from typing import Any

from ..errors import ParameterError

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
        fn = pickle.loads(payload)
        if len(_FN_CACHE) > 8:
            _FN_CACHE.clear()
        _FN_CACHE[key] = fn
    return _timed(fn, task)


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
        """Yield one outcome per task, in completion order."""

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


class ProcessExecutor(Executor):
    """Local process pool.

    Parameters
    ----------
    max_workers : number of worker processes (default: ``os.cpu_count()``).
    mp_context : multiprocessing context name ("fork", "spawn", "forkserver") or None for
        Python's default.

    The pool is started on first use and kept until :meth:`close`, so repeated batches do
    not pay the start-up cost again. A worker that dies (killed, out of memory) turns its task
    and the unfinished ones into errors; the next batch gets a fresh pool.
    """

    def __init__(self, max_workers: int | None = None, *, mp_context: str | None = None):
        self.n_workers = int(max_workers or os.cpu_count() or 1)
        if self.n_workers < 1:
            raise ParameterError(f"max_workers must be >= 1, got {max_workers}")
        self.mp_context = mp_context
        self._pool: cf.ProcessPoolExecutor | None = None

    def _get_pool(self) -> cf.ProcessPoolExecutor:
        if self._pool is None:
            import multiprocessing as mp

            ctx = mp.get_context(self.mp_context) if self.mp_context else None
            self._pool = cf.ProcessPoolExecutor(self.n_workers, mp_context=ctx)
        return self._pool

    def run(self, fn: Callable[[Any], Any], tasks: Sequence[Any]) -> Generator[TaskOutcome]:
        payload = _dumps(fn)
        pool = self._get_pool()
        futures = {pool.submit(_call, payload, t): i for i, t in enumerate(tasks)}
        broken = False
        try:
            for fut in cf.as_completed(futures):
                i = futures[fut]
                try:
                    value, error, wall = fut.result()
                except Exception as exc:  # worker died or the task could not be pickled
                    if isinstance(exc, cf.process.BrokenProcessPool):
                        broken = True
                    value, error, wall = None, f"{type(exc).__name__}: {exc}", 0.0
                yield TaskOutcome(i, value, error, wall)
        finally:
            for fut in futures:
                fut.cancel()
            if broken:
                self.close()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def __getstate__(self):
        return {"n_workers": self.n_workers, "mp_context": self.mp_context, "_pool": None}

    def __repr__(self) -> str:
        return f"ProcessExecutor(max_workers={self.n_workers})"


class DaskExecutor(Executor):
    """Dask distributed.

    Parameters
    ----------
    address : scheduler address (``"tcp://host:8786"``); None starts a LocalCluster.
    client : an existing ``distributed.Client`` to use instead (not closed by :meth:`close`).
    n_workers, threads_per_worker : size of the LocalCluster when one is started.

    External-solver tasks release the GIL while they wait for the subprocess, so threads are
    fine for them; vectorized Python models are better served by one thread per worker.
    """

    def __init__(
        self, address: str | None = None, *, client: Any = None, n_workers: int | None = None,
        threads_per_worker: int = 1,
    ):
        self.address = address
        self._n_local = n_workers
        self._threads = threads_per_worker
        self._client = client
        self._own_client = client is None
        self._cluster: Any = None

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
        return self._client

    @property
    def n_workers(self) -> int:  # type: ignore[override]
        info = self.client.scheduler_info()
        n = sum(w.get("nthreads", 1) for w in info.get("workers", {}).values())
        return max(1, n)

    def run(self, fn: Callable[[Any], Any], tasks: Sequence[Any]) -> Generator[TaskOutcome]:
        from distributed import as_completed

        client = self.client
        payload = client.scatter(_dumps(fn), broadcast=True, hash=False)
        futures = {client.submit(_call, payload, t, pure=False): i for i, t in enumerate(tasks)}
        try:
            for fut in as_completed(list(futures)):
                i = futures[fut]
                try:
                    value, error, wall = fut.result()
                except Exception as exc:  # worker lost, task could not be deserialized, ...
                    value, error, wall = None, f"{type(exc).__name__}: {exc}", 0.0
                yield TaskOutcome(i, value, error, wall)
        finally:
            client.cancel([f for f in futures if not f.done()])

    def close(self) -> None:
        if self._client is not None and self._own_client:
            self._client.close()
            self._client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    def __repr__(self) -> str:
        return f"DaskExecutor(address={self.address!r})"


def make_executor(spec: str | Executor | None, **kwargs: Any) -> Executor:
    """An Executor from a name ("serial", "processes", "dask") or an existing Executor.

    ``"processes:4"`` sets the number of workers; ``"dask:tcp://host:8786"`` a scheduler.
    """
    if isinstance(spec, Executor):
        return spec
    if spec is None or spec == "serial":
        return SerialExecutor()
    if not isinstance(spec, str):
        raise ParameterError(f"executor must be a name or an Executor, got {spec!r}")
    name, _, arg = spec.partition(":")
    if name == "processes":
        return ProcessExecutor(int(arg) if arg else kwargs.get("max_workers"))
    if name == "dask":
        return DaskExecutor(arg or kwargs.get("address"))
    raise ParameterError(f"unknown executor {spec!r}; use 'serial', 'processes[:N]', "
                     "'dask[:tcp://host:port]' or an Executor instance")
