"""One run per results folder.

``with results_lock(out):`` holds an exclusive ``flock`` on ``out/.rotoruq.lock`` for the
length of a run. A second run on the same folder refuses at once with
:class:`ResultsLockedError`, naming the PID, host and start time of the run that holds it.
The kernel releases the lock when its process dies, however it dies (SIGKILL included), so
a lock left by a killed run is simply taken over by the next run; the file's stale contents
are reported in ``ResultsLock.taken_over``.

Advisory locks need a file system that honours them (local disks do; some network file
systems do not).
"""

from __future__ import annotations

import fcntl
import json
import os
import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from ..errors import RotoruqError

__all__ = ["ResultsLockedError", "ResultsLock", "results_lock", "LOCK_NAME"]

LOCK_NAME = ".rotoruq.lock"


@dataclass(frozen=True)
class ResultsLock:
    """A held lock: its file, and the holder found in it when this run took it over
    (``None`` when the folder was free)."""

    path: Path
    taken_over: dict | None


# locks this process holds (flock is per open file: a second open in one process would
# conflict with the first), so nested use (`rotoruq run` around run_study) re-enters
_HELD: dict[Path, ResultsLock] = {}


class ResultsLockedError(RotoruqError, RuntimeError):
    """Another run holds the results folder."""


def _read(fd: int) -> dict | None:
    os.lseek(fd, 0, os.SEEK_SET)
    raw = os.read(fd, 4096)
    try:
        doc = json.loads(raw.decode())
    except (UnicodeDecodeError, ValueError):
        return None
    return doc if isinstance(doc, dict) else None


@contextmanager
def results_lock(folder: str | os.PathLike, command: str = "run") -> Iterator[ResultsLock]:
    """Hold the results folder ``folder`` for one run (a context manager yielding a
    :class:`ResultsLock`); raises :class:`ResultsLockedError` when another run holds it."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = (folder / LOCK_NAME).resolve()
    if path in _HELD:
        yield _HELD[path]
        return
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read(fd) or {}
            since = holder.get("since")
            when = (time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(since))
                    if isinstance(since, (int, float)) else "an unknown time")
            raise ResultsLockedError(
                f"results folder {str(folder)!r} is in use by another rotoruq "
                f"{holder.get('command', 'run')} (PID {holder.get('pid', '?')} on host "
                f"{holder.get('host', '?')}, since {when}); wait for it to finish, or choose "
                "another output folder (--out)") from None
        stale = _read(fd)
        me = {"pid": os.getpid(), "host": socket.gethostname(), "since": time.time(),
              "command": command}
        os.ftruncate(fd, 0)
        os.lseek(fd, 0, os.SEEK_SET)
        os.write(fd, json.dumps(me).encode())
        os.fsync(fd)
        _HELD[path] = ResultsLock(path, stale)
        try:
            yield _HELD[path]
        finally:
            del _HELD[path]
            os.ftruncate(fd, 0)
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)
