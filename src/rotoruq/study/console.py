"""What the ``rotoruq`` command prints besides its results: library warnings as one line each,
and a quiet exit when the reader of its output goes away (``rotoruq show --csv | head``)."""

from __future__ import annotations

import logging
import os
import shutil
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from .._progress import LOGGER as PROGRESS_LOGGER
from .._progress import PhaseState

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
            with _BAR_LOCK:  # no bar drawn between its clearing and this line
                clear_bar()
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
    _only_handler(WARNINGS_LOGGER, _WarningLines(), logging.ERROR if quiet else logging.WARNING,
                  propagate=False)
    warnings.showwarning = _show_warning


def _only_handler(name: str, handler: logging.Handler, level: int,
                  propagate: bool = True) -> None:
    """Logger ``name`` with ``handler`` in place of any earlier one of its class (configuring
    twice prints each line once), at ``level``."""
    logger = logging.getLogger(name)
    for h in [h for h in logger.handlers if isinstance(h, type(handler))]:
        logger.removeHandler(h)
    logger.addHandler(handler)
    logger.propagate = propagate
    logger.setLevel(level)


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

    def emit(self, record: logging.LogRecord) -> None:
        with _BAR_LOCK:  # no bar drawn between its clearing and this line
            clear_bar()
            super().emit(record)

    @property  # type: ignore[override]  # follow sys.stderr when a caller swaps it
    def stream(self):  # noqa: D102
        return sys.stderr

    @stream.setter
    def stream(self, value) -> None:
        pass


class _ProgressBar(logging.Handler):
    """The phases of :mod:`rotoruq._progress` under way, as one bar line redrawn in place on
    ``sys.stderr`` when it is a terminal (nothing in a pipe: the step's status line says it
    there). A finished phase leaves the line; a printed line clears it first."""

    def __init__(self) -> None:
        super().__init__()
        self.phases: dict[str, PhaseState] = {}
        self.drawn = False
        self.last = -float("inf")
        # a phase shorter than this [s] is not worth a flash of a bar
        self.after = float(os.environ.get("ROTORUQ_BAR_AFTER", "0.5"))

    @property
    def draws_on_terminal(self) -> bool:
        """Whether stderr is a terminal (read by :func:`rotoruq._progress.bar_on_terminal`)."""
        isatty = getattr(sys.stderr, "isatty", None)
        return bool(isatty and isatty())

    def emit(self, record: logging.LogRecord) -> None:
        state = getattr(record, "progress", None)
        if state is None or not self.draws_on_terminal:
            return
        with _BAR_LOCK:
            if state.finished:
                self.phases.pop(state.name, None)
            else:
                self.phases[state.name] = state
            now = time.perf_counter()
            if self.phases and now - self.last < 0.2:
                return
            self.last = now
            shown = [p for p in self.phases.values() if p.elapsed >= self.after]
            try:
                if not shown:
                    self._clear()
                    return
                from ..evaluation.progress import bar_line  # on a terminal only: not light

                width = max(shutil.get_terminal_size().columns - 1, 20)
                text = " | ".join(p.text() if p.total is None else
                                  bar_line(p.name, p.done, p.total, p.elapsed, width=16)
                                  for p in shown)
                sys.stderr.write("\r" + text[:width] + "\033[K")
                sys.stderr.flush()
                self.drawn = True
            except Exception:  # noqa: BLE001  # a closed stderr must not end the run
                self.handleError(record)

    def _clear(self) -> None:
        if self.drawn:
            sys.stderr.write("\r\033[K")
            sys.stderr.flush()
            self.drawn = False
            self.last = -float("inf")


_BAR_LOCK = threading.RLock()


def clear_bar() -> None:
    """Take the progress bar off the terminal's current line before a line is printed (it is
    drawn again at the next progress record)."""
    with _BAR_LOCK:
        for h in logging.getLogger(PROGRESS_LOGGER).handlers:
            if isinstance(h, _ProgressBar):
                try:
                    h._clear()
                except (OSError, ValueError):  # a closed stderr
                    pass


def configure_logging(quiet: bool = False, debug: bool = False, verbose: bool = False) -> None:
    """Send the library's log records (the ``rotoruq`` loggers) to stderr as plain lines:
    INFO and above by default (progress), WARNING and above with ``quiet`` (the CLI's
    ``--quiet`` hides progress only), DEBUG with ``verbose`` or ``debug``; Python warnings
    as one ``warning: ...`` line each, also with ``quiet``. The progress of long phases
    (:mod:`rotoruq._progress`) is a bar on a terminal and no line (none with ``quiet``)."""
    route_warnings(quiet=False)
    _only_handler("rotoruq", _StderrHandler(), logging.DEBUG if debug or verbose
                  else logging.WARNING if quiet else logging.INFO)
    _only_handler(PROGRESS_LOGGER, _ProgressBar(), logging.WARNING if quiet else logging.INFO,
                  propagate=False)


#: The loggers whose INFO messages a step gathers (:func:`gathered_messages`).
METHODS_LOGGER = "rotoruq.methods"


class GatheredMessages(logging.Handler):
    """The INFO messages of the methods during one step, each kind (its format string) once
    with how often it came: a step's self-check repeats its calibration's messages once per
    replication. Warnings, errors and messages marked ``now`` (the compile notice) pass on
    at once."""

    def __init__(self) -> None:
        super().__init__()
        self.kinds: dict[tuple[str, str], list] = {}  # (logger, format) -> [first text, count]

    def emit(self, record: logging.LogRecord) -> None:
        if record.levelno >= logging.WARNING or getattr(record, "now", False):
            logging.getLogger("rotoruq").handle(record)
            return
        kind = self.kinds.setdefault((record.name, str(record.msg)), [None, 0])
        if kind[0] is None:
            kind[0] = " ".join(record.getMessage().split())
        kind[1] += 1

    def lines(self) -> list[str]:
        """One line per kind, in the order they first came: the first message, and how many
        more of its kind followed."""
        return [text if n == 1 else f"{text} (and {n - 1} more like it)"
                for text, n in self.kinds.values()]


@contextmanager
def gathered_messages() -> Iterator[GatheredMessages]:
    """Within the block, gather the methods' INFO messages (the ``rotoruq.methods`` loggers)
    instead of printing them one by one; read them from the handler afterwards. Nothing is
    gathered when those loggers print debug messages (``--verbose``: each as it comes) or
    no INFO at all (``--quiet``).

    Yields
    ------
    GatheredMessages
        The handler; its :meth:`~GatheredMessages.lines` after the block.

    Examples
    --------
    >>> log = logging.getLogger("rotoruq.methods.demo")
    >>> logging.getLogger("rotoruq").setLevel(logging.INFO)
    >>> with gathered_messages() as got:
    ...     for k in range(3):
    ...         log.info("chain %d done", k)
    >>> got.lines()
    ['chain 0 done (and 2 more like it)']
    >>> logging.getLogger("rotoruq").setLevel(logging.NOTSET)
    """
    methods = logging.getLogger(METHODS_LOGGER)
    handler = GatheredMessages()
    if methods.isEnabledFor(logging.DEBUG) or not methods.isEnabledFor(logging.INFO):
        yield handler
        return
    propagate = methods.propagate
    methods.addHandler(handler)
    methods.propagate = False
    try:
        yield handler
    finally:
        methods.removeHandler(handler)
        methods.propagate = propagate


def printing_level() -> int | None:
    """The level from which the ``rotoruq`` loggers print to stderr after
    :func:`configure_logging` (None when it was not called in this process): what a worker
    process passes on so that it prints the same lines."""
    root = logging.getLogger("rotoruq")
    if not any(isinstance(h, _StderrHandler) for h in root.handlers):
        return None
    return root.level
