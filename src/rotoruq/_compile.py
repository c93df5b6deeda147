"""A notice before numba compiles a family of kernels that its on-disk cache does not hold.

The first run after an install compiles the rotor, chain and emulator kernels (tens of
seconds each on two cores) and says nothing meanwhile; :func:`notice_if_cold` logs one INFO
line per family and process before that happens, and nothing when the cache is warm.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from typing import Any

__all__ = ["is_cached", "notice_if_cold"]

_noticed: set[str] = set()  # families announced in this process
_checked: set[int] = set()  # ids of the dispatchers already looked up in the cache


def is_cached(dispatcher: Any) -> bool:
    """Whether numba's on-disk cache holds compiled code of ``dispatcher`` (a function
    decorated with ``numba.njit(cache=True)``) for its current source.

    Reads the cache's small index file (no compilation). True when that cannot be told (a
    numba without this cache layout): a notice is better missed than wrong.

    Parameters
    ----------
    dispatcher : numba dispatcher
        The compiled function.

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
        return bool(dispatcher._cache._cache_file._load_index())
    except Exception:  # noqa: BLE001 - a numba without this layout: say nothing
        return True


def notice_if_cold(family: str, dispatchers: Iterable[Any], logger: logging.Logger,
                   seconds: str = "10-60") -> bool:
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
    fresh = [d for d in dispatchers if id(d) not in _checked]
    if not fresh:
        return False
    _checked.update(id(d) for d in fresh)
    if all(is_cached(d) for d in fresh):
        return False
    _noticed.add(family)
    # "now": printed as it comes, before the compile, even where a step gathers messages
    logger.info("compiling %s (once per install, ~%s s) ...", family, seconds,
                extra={"now": True})
    return True
