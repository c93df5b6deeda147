"""A notice before numba compiles a family of kernels that its on-disk cache does not hold.

The first run after an install compiles the rotor, chain and emulator kernels (tens of
seconds each on two cores) and says nothing meanwhile; :func:`notice_if_cold` logs one INFO
line per family and process before that happens, and nothing when the cache is warm;
:func:`compiling` also keeps a progress phase open while the compile runs, so a step's status
line says "compiling rotor kernels" instead of a count that does not move.

Processes that start together with a cold cache (``rotoruq reproduce``'s chapters, ``rotoruq
run --jobs``'s steps) would each compile the same kernels: :func:`compiling` holds an
exclusive lock per family (:func:`compile_lock`, a file in numba's cache folder) while the
first call compiles, so one process compiles and the others wait and then load its code
from the cache. It also keeps numba's cache index, which numba reads, changes and rewrites
unlocked, from being written by two processes at once.
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Any

from ._progress import Phase

__all__ = ["compile_lock", "compiling", "is_cached", "notice_if_cold"]

#: A test on a cached signature's argument type names (see :func:`is_cached`).
Variant = Callable[[tuple[str, ...]], bool]

#: Seconds a process waits for another one's compile before it compiles itself; None: as
#: long as the other holds the lock (it is released when that process ends, however it
#: ends; a compile takes many minutes on a loaded machine).
LOCK_WAIT: float | None = None

_noticed: set[str] = set()  # families announced in this process
_checked: set[tuple[str, int]] = set()  # (family, dispatcher id) already looked up


def is_cached(dispatcher: Any, variant: Variant | None = None) -> bool:
    """Whether numba's on-disk cache holds compiled code of ``dispatcher`` (a function
    decorated with ``numba.njit(cache=True)``) for its current source.

    Reads the cache's small index file (no compilation). True when that cannot be told (a
    numba without this cache layout): a notice is better missed than wrong.

    Parameters
    ----------
    dispatcher : numba dispatcher
        The compiled function.
    variant : callable, optional
        Which specialisation counts: called with the names of a cached signature's argument
        types (``("array(float64, 2d, C)", ..., "none")``), true for the one about to be
        called. None: any cached specialisation counts. A kernel compiled once per argument
        type (the rotor's hover and forward-flight builds) is cold for the one its cache
        does not hold, although the other one is there.

    Returns
    -------
    bool
        True when its first call loads compiled code instead of compiling.

    Examples
    --------
    >>> is_cached(len)  # not a numba function: cannot be told
    True
    """
    try:
        index = dispatcher._cache._cache_file._load_index()
        if variant is None:
            return bool(index)
        return any(variant(tuple(str(t) for t in key[0])) for key in index)
    except Exception:  # noqa: BLE001 - a numba without this layout: say nothing
        return True


def notice_if_cold(family: str, dispatchers: Iterable[Any], logger: logging.Logger,
                   seconds: str = "10-60", variant: Variant | None = None) -> bool:
    """Log once per process, at INFO, that the kernels of ``family`` are being compiled,
    when one of ``dispatchers`` is not in numba's cache.

    Call it where the dispatchers are about to be called, with those only: a kernel that a
    process never calls is never cached, and naming it would announce a compile on every
    run. A family may be checked from several call sites (each with its own kernels); it is
    announced at most once.

    Parameters
    ----------
    family : str
        What is compiled, for the line (``"rotor kernels"``).
    dispatchers : iterable
        The entry points of the family (their callees compile with them).
    logger : logging.Logger
        Where the line goes.
    seconds : str, optional
        The usual compile time on two cores, for the line.
    variant : callable, optional
        The specialisation about to be called (see :func:`is_cached`); a family per
        specialisation.

    Returns
    -------
    bool
        True when the line was logged.

    Examples
    --------
    >>> notice_if_cold("demo kernels", [len], logging.getLogger("demo"))
    False
    """
    if family in _noticed:
        return False
    fresh = [d for d in dispatchers if (family, id(d)) not in _checked]
    if not fresh:
        return False
    _checked.update((family, id(d)) for d in fresh)
    if all(is_cached(d, variant) for d in fresh):
        return False
    _noticed.add(family)
    # "now": printed as it comes, before the compile, even where a step gathers messages
    logger.info("compiling %s (once per install, ~%s s) ...", family, seconds,
                extra={"now": True})
    return True


@contextlib.contextmanager
def compiling(family: str, dispatchers: Iterable[Any], logger: logging.Logger,
              seconds: str = "10-60", variant: Variant | None = None,
              lock: str | None = None) -> Iterator[bool]:
    """Around the first call of ``dispatchers``: :func:`notice_if_cold`, and while the body
    runs, when it logged, an uncounted progress phase ``"compiling <family>"`` (the step's
    status line and the terminal's bar name it) and :func:`compile_lock` of ``lock``
    (default: ``family``; the specialisations of one dispatcher share one lock, as they
    share numba's cache index).

    Yields
    ------
    bool
        Whether a compile was announced.

    Examples
    --------
    >>> with compiling("demo kernels", [len], logging.getLogger("demo")) as cold:
    ...     len("abc")
    3
    >>> cold
    False
    """
    dispatchers = list(dispatchers)
    if not notice_if_cold(family, dispatchers, logger, seconds, variant):
        yield False
        return
    with Phase(f"compiling {family}", None), compile_lock(lock or family, dispatchers,
                                                          logger):
        yield True


def _lock_path(family: str, dispatchers: Iterable[Any]) -> str | None:
    """The lock file of ``family``: in numba's cache folder of its first dispatcher."""
    for d in dispatchers:
        folder = getattr(getattr(d, "_cache", None), "_cache_path", None)
        if isinstance(folder, str) and os.path.isdir(folder):
            return os.path.join(folder, "rotoruq-compile-" + re.sub(r"\W+", "-", family)
                                + ".lock")
    return None


@contextlib.contextmanager
def compile_lock(family: str, dispatchers: Iterable[Any], logger: logging.Logger,
                 wait: float | None = LOCK_WAIT) -> Iterator[bool]:
    """Hold the exclusive lock of ``family``'s compile (across processes) while the body
    runs: a process that finds it held logs that it waits, and its body runs once the other
    process is done (its kernels then load from numba's cache instead of compiling).

    An advisory ``flock`` on ``rotoruq-compile-<family>.lock`` in numba's cache folder of the
    first of ``dispatchers``; released when the body ends, also by an error or by the
    process's end. No lock (the body runs at once) where there is no such folder or no
    ``fcntl`` (Windows), and after ``wait`` seconds (None, the default: no limit) with a
    warning.

    Yields
    ------
    bool
        Whether the lock is held.

    Examples
    --------
    >>> with compile_lock("demo kernels", [len], logging.getLogger("demo")) as held:
    ...     held  # a builtin has no numba cache folder: nothing to lock
    False
    """
    try:
        import fcntl
    except ImportError:  # Windows: the processes may compile at once
        yield False
        return
    path = _lock_path(family, dispatchers)
    fd = -1
    if path is not None:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o666)
        except OSError:  # a read-only cache folder: numba does not cache there either
            fd = -1
    if fd < 0:
        yield False
        return
    try:
        held = _acquire(fd, fcntl, family, logger, wait)
        yield held
    finally:
        os.close(fd)  # releases the lock


def _acquire(fd: int, fcntl: Any, family: str, logger: logging.Logger,
             wait: float | None) -> bool:
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return True
    except BlockingIOError:
        pass
    logger.info("another process is compiling the %s: waiting for it, then loading them "
                "from the cache ...", family, extra={"now": True})
    t0 = time.monotonic()
    while wait is None or time.monotonic() - t0 < wait:
        time.sleep(0.1)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return True
        except BlockingIOError:
            continue
    logger.warning("the %s: another process has held their compile lock for %.0f s; "
                   "compiling them here", family, time.monotonic() - t0)
    return False
