"""What the ``rotoruq`` command prints besides its results: library warnings as one line each,
and a quiet exit when the reader of its output goes away (``rotoruq show --csv | head``)."""

from __future__ import annotations

import logging
import os
import sys
import warnings
from collections.abc import Callable
from typing import Any

#: The logger Python's warnings are sent to (the name ``logging.captureWarnings`` uses).
WARNINGS_LOGGER = "py.warnings"


class _WarningLines(logging.Handler):
    """``warning: <message>`` on the current ``sys.stderr``, each distinct message once."""

    def __init__(self) -> None:
        super().__init__()
        self.seen: set[str] = set()

    def emit(self, record: logging.LogRecord) -> None:
        line = " ".join(record.getMessage().split())
        if line in self.seen:
            return
        self.seen.add(line)
        try:
            print(f"warning: {line}", file=sys.stderr)
        except Exception:  # noqa: BLE001  # a closed stderr must not end the run
            self.handleError(record)


def _show_warning(message: Any, category: type[Warning], filename: str, lineno: int,
                  file: Any = None, line: str | None = None) -> None:
    # The message alone: the library's file and line mean nothing to the user of the CLI.
    logging.getLogger(WARNINGS_LOGGER).warning("%s", message)


def route_warnings(quiet: bool = False) -> None:
    """Send Python warnings (numpy, scipy, numba, ...) to the ``py.warnings`` logger, printed as
    one ``warning: <message>`` line each (a message repeated is printed once); none with
    ``quiet``.

    Parameters
    ----------
    quiet : bool
        Print no warnings (for a caller that wants errors only; the CLI's ``--quiet`` keeps
        warnings).

    Examples
    --------
    >>> saved = warnings.showwarning
    >>> route_warnings(quiet=True)
    >>> warnings.warn("not printed: quiet")
    >>> warnings.showwarning = saved
    """
    logger = logging.getLogger(WARNINGS_LOGGER)
    for h in [h for h in logger.handlers if isinstance(h, _WarningLines)]:
        logger.removeHandler(h)
    logger.addHandler(_WarningLines())
    logger.propagate = False
    logger.setLevel(logging.ERROR if quiet else logging.WARNING)
    warnings.showwarning = _show_warning


def pipe_safe(run: Callable[[Any], int | None]) -> Callable[[Any], int]:
    """Wrap a subcommand's ``run(args)``: when the reader of stdout has gone (a closed pipe),
    stop quietly with status 0 instead of printing "Broken pipe".

    Parameters
    ----------
    run : callable
        A subcommand's ``run(args) -> int``.

    Returns
    -------
    callable
        ``run`` that also flushes stdout, so a closed pipe is met here and not at exit.

    Examples
    --------
    >>> pipe_safe(lambda args: 3)(None)
    3
    """

    def wrapped(args: Any) -> int:
        try:
            code = int(run(args) or 0)
            sys.stdout.flush()
        except BrokenPipeError:
            if not stdout_reader_gone():
                raise  # another pipe broke (a worker, a driver): a real error
            _silence_stdout()
            return 0
        return code

    wrapped.__wrapped__ = run  # type: ignore[attr-defined]
    return wrapped


def stdout_reader_gone(fd: int | None = None) -> bool:
    """Whether stdout (or the file descriptor ``fd``) is a pipe whose reading end has been
    closed: ``poll`` reports an error condition on the writing end then.

    Parameters
    ----------
    fd : int, optional
        File descriptor to look at; default: ``sys.stdout``'s.

    Returns
    -------
    bool
        False for a terminal, a file, an open pipe or a stdout that is no file at all.

    Examples
    --------
    >>> r, w = os.pipe()
    >>> stdout_reader_gone(w)
    False
    >>> os.close(r)
    >>> stdout_reader_gone(w)
    True
    >>> os.close(w)
    """
    import select

    try:
        fd = sys.stdout.fileno() if fd is None else fd
        poller = select.poll()
        poller.register(fd, select.POLLOUT)
        return any(ev & select.POLLERR for _, ev in poller.poll(0))
    except (OSError, ValueError, AttributeError):
        return False


def _silence_stdout() -> None:
    """Point stdout at the null device: the interpreter flushes it once more at exit."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):  # stdout is no real file (a test's buffer)
        pass


class _StderrHandler(logging.StreamHandler):
    """Progress lines of the ``rotoruq`` loggers on the current ``sys.stderr``."""

    def __init__(self) -> None:
        super().__init__()
        self.setFormatter(logging.Formatter("%(message)s"))

    @property  # type: ignore[override]  # follow sys.stderr when a caller swaps it
    def stream(self):  # noqa: D102
        return sys.stderr

    @stream.setter
    def stream(self, value) -> None:
        pass


def configure_logging(quiet: bool = False, debug: bool = False, verbose: bool = False) -> None:
    """Send the library's log records (the ``rotoruq`` loggers) to stderr as plain lines:
    INFO and above by default (progress), WARNING and above with ``quiet`` (the CLI's
    ``--quiet`` hides progress only), DEBUG with ``verbose`` or ``debug``; Python warnings
    as one ``warning: ...`` line each, also with ``quiet``."""
    route_warnings(quiet=False)
    root = logging.getLogger("rotoruq")
    for h in [h for h in root.handlers if isinstance(h, _StderrHandler)]:
        root.removeHandler(h)
    root.addHandler(_StderrHandler())
    root.setLevel(logging.DEBUG if debug or verbose else logging.WARNING if quiet
                  else logging.INFO)


def printing_level() -> int | None:
    """The level from which the ``rotoruq`` loggers print to stderr after
    :func:`configure_logging` (None when it was not called in this process): what a worker
    process passes on so that it prints the same lines."""
    root = logging.getLogger("rotoruq")
    if not any(isinstance(h, _StderrHandler) for h in root.handlers):
        return None
    return root.level
