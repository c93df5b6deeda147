"""A small progress bar on stderr: count, percentage, rate and ETA.

It stays silent when the stream is not a terminal, and appears only once a run has lasted
``delay`` seconds (2 s by default), so short batches and logs/CI output stay clean.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

from .._progress import format_duration

__all__ = ["Progress", "bar_line", "format_duration"]


def bar_line(label: str, done: int, total: int, elapsed: float, width: int = 24) -> str:
    """One progress bar as text: label, bar, count, percentage, rate, elapsed time and ETA.

    Parameters
    ----------
    label : str
        What is counted (``"evaluations"``, ``"4 chains"``).
    done, total : int
        Units done and to do.
    elapsed : float
        Seconds since the start (wall).
    width : int, optional
        Characters of the bar itself.

    Returns
    -------
    str
        The line, without carriage return or newline.

    Examples
    --------
    >>> bar_line("evaluations", 30, 120, 15.0, width=8)
    'evaluations [##......] 30/120  25% 2/s elapsed 0:15 ETA 0:45'
    """
    rate = done / elapsed if elapsed > 0 else 0.0
    frac = done / total if total else 1.0
    fill = int(round(frac * width))
    eta = (total - done) / rate if rate > 0 else float("nan")
    return (f"{label} [{'#' * fill}{'.' * (width - fill)}] {done}/{total} "
            f"{100 * frac:3.0f}% {rate:.3g}/s elapsed {format_duration(elapsed)} "
            f"ETA {format_duration(eta)}")


class Progress:
    """Progress of ``total`` tasks.

    Parameters
    ----------
    total : number of tasks.
    label : text in front of the bar.
    stream : where to draw (default stderr).
    enabled : True/False to force; None draws only when ``stream.isatty()``.
    delay : seconds before the bar first appears.
    interval : minimum seconds between redraws.
    """

    def __init__(
        self, total: int, *, label: str = "evaluations", stream: TextIO | None = None,
        enabled: bool | None = None, delay: float = 2.0, interval: float = 0.2,
    ):
        self.total = int(total)
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        if enabled is None:
            isatty = getattr(self.stream, "isatty", None)
            enabled = bool(isatty and isatty())
        self.enabled = enabled
        self.delay = delay
        self.interval = interval
        self.done = 0
        self.start = time.perf_counter()
        self._last = -float("inf")
        self._drawn = False

    def line(self) -> str:
        """The current progress text (without carriage return)."""
        return bar_line(self.label, self.done, self.total, time.perf_counter() - self.start)

    def update(self, n: int = 1) -> None:
        """Record ``n`` more finished tasks and redraw if due."""
        self.done += n
        if not self.enabled:
            return
        now = time.perf_counter()
        if now - self.start < self.delay or now - self._last < self.interval:
            return
        self._last = now
        self.stream.write("\r" + self.line() + "\033[K")
        self.stream.flush()
        self._drawn = True

    def close(self) -> None:
        """Finish the line if anything was drawn."""
        if self._drawn:
            self.stream.write("\r" + self.line() + "\033[K\n")
            self.stream.flush()
            self._drawn = False

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
