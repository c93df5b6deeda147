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
    """Where a phase is: ``done`` of ``total`` units after ``elapsed`` seconds (wall)."""

    name: str
    done: int
    total: int
    elapsed: float

    @property
    def finished(self) -> bool:
        """Whether every unit is done."""
        return self.done >= self.total


def bar_on_terminal() -> bool:
    """Whether a handler draws the progress records as a bar on a terminal (then the step's
    periodic status line and an evaluator's own bar stay silent)."""
    return any(getattr(h, "draws_on_terminal", False) for h in _log.handlers)


class Phase:
    """Report ``done`` of ``total`` units of the phase ``name``: a record at the start, at most
    one every ``interval`` seconds (wall), and one when it is finished or left. Thread-safe
    (replications finishing on a thread pool).

    Examples
    --------
    >>> with Phase("chains", 3) as phase:
    ...     for _ in range(3):
    ...         phase.advance()
    >>> phase.done
    3
    """

    def __init__(self, name: str, total: int, interval: float = 0.25) -> None:
        self.name = name
        self.total = max(int(total), 0)
        self.done = 0
        self.interval = interval
        self._t0 = time.perf_counter()
        self._last = -float("inf")
        self._lock = threading.Lock()
        self._closed = False
        self._emit(force=True)

    def advance(self, n: int = 1) -> None:
        """Count ``n`` more units done."""
        with self._lock:
            self.done = min(self.done + int(n), self.total)
            self._emit(force=False)

    def close(self) -> None:
        """The phase is over (finished, or left by an error): a last record, marked done."""
        with self._lock:
            if not self._closed:
                self._closed = True
                self.done = self.total
                self._emit(force=True)

    def _emit(self, force: bool) -> None:
        if not _log.isEnabledFor(logging.INFO):
            return
        now = time.perf_counter()
        if not force and now - self._last < self.interval and self.done < self.total:
            return
        self._last = now
        state = PhaseState(self.name, self.done, self.total, now - self._t0)
        _log.info("%s: %d/%d", self.name, self.done, self.total, extra={"progress": state})

    def __enter__(self) -> Phase:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
