"""Progress of a long phase (emulator fit, Markov chains, self-check replications, evaluation
batches) as log records of the ``rotoruq.progress`` logger, so that any layer can report it
and only the command line decides how it is shown: a bar on a terminal, the step's periodic
status line in a pipe or CI log (:mod:`rotoruq.study.console`, :func:`rotoruq.steps.base.
run_step`). Without a handler nothing is printed (the records are INFO, below logging's
default level). The numbers a method computes never depend on it.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass

#: The logger the progress records go to; the CLI does not print them as lines.
LOGGER = "rotoruq.progress"

_log = logging.getLogger(LOGGER)


@dataclass(frozen=True)
class PhaseState:
    """Where a phase is: ``done`` of ``total`` units after ``elapsed`` seconds (wall);
    ``total`` None for a phase that is not counted (a compile: under way until closed)."""

    name: str
    done: int
    total: int | None
    elapsed: float
    closed: bool = False

    @property
    def finished(self) -> bool:
        """Whether every unit is done (an uncounted phase: whether it was closed)."""
        return self.closed if self.total is None else self.done >= self.total

    def text(self) -> str:
        """``"4 chains 3000/7200 (42 %)"``; an uncounted phase: its name and elapsed time.

        Examples
        --------
        >>> PhaseState("4 chains", 3000, 7200, 12.0).text()
        '4 chains 3000/7200 (42 %)'
        >>> PhaseState("compiling rotor kernels", 0, None, 45.0).text()
        'compiling rotor kernels, 0:45'
        """
        if self.total is None:
            return f"{self.name}, {format_duration(self.elapsed)}"
        pct = 100 * self.done / self.total if self.total else 100.0
        return f"{self.name} {self.done}/{self.total} ({pct:.0f} %)"


def format_duration(seconds: float) -> str:
    """``h:mm:ss`` (or ``m:ss`` under an hour)."""
    if seconds != seconds or seconds == float("inf"):
        return "?"
    s = int(round(seconds))
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


def bar_on_terminal() -> bool:
    """Whether a handler draws the progress records as a bar on a terminal (then the step's
    periodic status line and an evaluator's own bar stay silent)."""
    return any(getattr(h, "draws_on_terminal", False) for h in _log.handlers)


class Phase:
    """Report ``done`` of ``total`` units of the phase ``name``: a record at the start, at most
    one every ``interval`` seconds (wall), and one when it is finished or left. Thread-safe
    (replications finishing on a thread pool). ``total`` None: a phase that is not counted
    (a compile), under way until it is closed; while it is open and someone listens, a record
    every ``tick`` seconds carries its elapsed time (nothing else would: it never advances).

    Examples
    --------
    >>> with Phase("chains", 3) as phase:
    ...     for _ in range(3):
    ...         phase.advance()
    >>> phase.done
    3
    """

    def __init__(self, name: str, total: int | None, interval: float = 0.25,
                 tick: float = 1.0) -> None:
        self.name = name
        self.total = None if total is None else max(int(total), 0)
        self.done = 0
        self.interval = interval
        self._t0 = time.perf_counter()
        self._last = -float("inf")
        self._lock = threading.Lock()
        self._closed = False
        self._stop = threading.Event()
        self._emit(force=True)
        if self.total is None and _log.isEnabledFor(logging.INFO):
            threading.Thread(target=self._tick, args=(tick,), name=f"phase-{name}",
                             daemon=True).start()

    def _tick(self, tick: float) -> None:
        while not self._stop.wait(tick):
            with self._lock:
                if self._closed:
                    return
                self._emit(force=True)

    def advance(self, n: int = 1) -> None:
        """Count ``n`` more units done."""
        with self._lock:
            self.done = self.done + int(n) if self.total is None else min(
                self.done + int(n), self.total)
            self._emit(force=False)

    def close(self) -> None:
        """The phase is over (finished, or left by an error): a last record, marked done."""
        with self._lock:
            if not self._closed:
                self._closed = True
                self._stop.set()
                self.done = self.done if self.total is None else self.total
                self._emit(force=True)

    def _emit(self, force: bool) -> None:
        if not _log.isEnabledFor(logging.INFO):
            return
        now = time.perf_counter()
        state = PhaseState(self.name, self.done, self.total, now - self._t0, self._closed)
        if not force and now - self._last < self.interval and not state.finished:
            return
        self._last = now
        _log.info("%s", state.text(), extra={"progress": state})

    def __enter__(self) -> Phase:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
