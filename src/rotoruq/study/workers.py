"""The start method of the worker processes that run chapters (``rotoruq reproduce``) and
steps (``rotoruq run --jobs``): forked by a fork server that imported their modules once.

A spawned worker imports numpy, scipy, numba, matplotlib and rotoruq again, about 2 CPU-s
per process before it computes anything (issue 34). A fork server is a fresh process, started
from the interpreter (not forked from the caller, so it holds none of the caller's BLAS or
numba thread locks), that imports the ``preload`` modules and then forks each worker from
itself while single-threaded: the imports are paid once per pool, not once per worker.
"""

from __future__ import annotations

import multiprocessing
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from multiprocessing.context import BaseContext

__all__ = ["start_method", "worker_context"]


def start_method() -> str:
    """``"forkserver"`` where Python has it and forking is safe, else ``"spawn"``.

    macOS lists a fork server but its system libraries (Accelerate, the Objective-C runtime)
    are not safe in a forked child, which is why Python spawns there by default.
    """
    if sys.platform != "darwin" and "forkserver" in multiprocessing.get_all_start_methods():
        return "forkserver"
    return "spawn"


@contextmanager
def worker_context(preload: Sequence[str]) -> Iterator[BaseContext]:
    """A multiprocessing context for a pool used inside the block: a fork server that
    imports ``preload`` (module names; one that is not installed is skipped) before it forks
    the workers, or spawn (:func:`start_method`).

    A fork server is one per Python process (the standard library's): when this block
    starts it, the block stops it at its end, after the pool's workers have ended, so that
    no process outlives the run, its CPU seconds and its workers' count in this process's
    children (``RUSAGE_CHILDREN``), and the next pool starts from this process's environment
    as it is then (``NUMBA_CACHE_DIR``, ...). A fork server already running (started by the
    caller) is used as it is, with the modules it preloaded, and left running. (The
    preload list is the standard library's, one per process, and restored at the end.)

    Parameters
    ----------
    preload : module names the workers import in any case (the tasks' modules and what
        they import). Not ``__main__``: each worker imports the caller's script as spawn
        does, once it has the caller's ``sys.path`` (the fork server of Python 3.11 to 3.13
        is not given it).
    """
    method = start_method()
    ctx = multiprocessing.get_context(method)
    if method != "forkserver":
        yield ctx
        return
    from multiprocessing import forkserver

    # the standard library has no public way to ask whether its fork server runs or to stop
    # it (3.11 to 3.13 hold these names); without them the server is left running
    server = getattr(forkserver, "_forkserver", None)
    ours = getattr(server, "_forkserver_pid", 0) is None and hasattr(server, "_stop")
    before = getattr(server, "_preload_modules", ["__main__"])
    ctx.set_forkserver_preload(list(preload))
    if ours:
        # started now, not at the pool's first task: it imports while the caller goes on
        # (reproduce checks numba's cache, importing numba, before it submits a chapter)
        forkserver.ensure_running()
    try:
        yield ctx
    finally:
        ctx.set_forkserver_preload(before)
        if ours and server._forkserver_pid is not None:  # type: ignore[union-attr]
            server._stop()  # type: ignore[union-attr]
