"""One run per results folder.

``with results_lock(out):`` holds an exclusive ``flock`` on ``out/.rotoruq.lock`` for the
length of a run. A second run on the same folder refuses at once with
:class:`ResultsLockedError`, naming the PID, host and start time of the run that holds it.
The kernel releases the lock when its process dies, however it dies (SIGKILL included), so
a lock left by a killed run is simply taken over by the next run; the file's stale contents
are reported in ``ResultsLock.taken_over``.

Advisory locks need a file system that honours them (local disks do; some network file
systems do not).

The lock file is opened without following a symlink and never truncated unless it is a
lock rotoruq wrote (a regular file with one link, empty or holding a lock record): a results
folder from an archive with ``.rotoruq.lock`` linked to another file leaves that file intact.
Taking the lock also checks the folder (:func:`check_results_folder`): the entries rotoruq
writes (``steps/``, ``report/``, ``work/``, ``study.json``, the store...) must be real files
and folders, not symlinks planted to redirect the run's writes.
"""

from __future__ import annotations

import fcntl
import json
import os
import socket
import stat
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from ..errors import RotoruqError
from ..safety import ForeignFileError, no_symlink, open_nofollow, real_dir

__all__ = ["ResultsLockedError", "ResultsLock", "results_lock", "LOCK_NAME",
           "check_results_folder", "RESULTS_DIRS", "RESULTS_FILES"]

LOCK_NAME = ".rotoruq.lock"

#: Folders of a results folder that rotoruq writes into: real folders, never symlinks.
RESULTS_DIRS = ("steps", "report", "work")
#: Files of a results folder that rotoruq writes (the default store and SQLite's companions
#: included): never symlinks.
RESULTS_FILES = (LOCK_NAME, "study.json", "study.toml", "evaluations.sqlite",
                 "evaluations.sqlite-journal", "evaluations.sqlite-wal",
                 "evaluations.sqlite-shm")


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


def check_results_folder(folder: str | os.PathLike) -> Path:
    """``folder`` when what rotoruq writes in it is real: the folders
    :data:`RESULTS_DIRS` and every step folder under ``steps/`` are real folders, the files
    :data:`RESULTS_FILES` are not symlinks. Raises :class:`~rotoruq.safety.UnsafePathError`
    naming the first symlink found (a missing entry is fine).

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as d:
    ...     _ = check_results_folder(d)
    """
    folder = Path(folder)
    for name in RESULTS_FILES:
        no_symlink(folder / name)
    for name in RESULTS_DIRS:
        if (folder / name).is_symlink() or (folder / name).exists():
            real_dir(folder / name)
    steps = folder / "steps"
    if steps.is_dir():
        for entry in sorted(steps.iterdir()):
            if entry.is_symlink() or entry.is_dir():
                real_dir(entry)
    return folder


def _open_lock(path: Path) -> int:
    """The lock file, opened read-write without following a symlink, created (umask) when
    missing; a file that is not rotoruq's lock (a hard link to another file, or foreign
    contents) is refused before anything is written to it."""
    fd = open_nofollow(path, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise ForeignFileError(path, "not a regular file")
        if st.st_nlink != 1:
            raise ForeignFileError(path, f"a file with {st.st_nlink} hard links")
        if st.st_size and _read(fd) is None:
            raise ForeignFileError(path, "not a rotoruq lock record")
    except BaseException:
        os.close(fd)
        raise
    return fd


@contextmanager
def results_lock(folder: str | os.PathLike, command: str = "run") -> Iterator[ResultsLock]:
    """Hold the results folder ``folder`` for one run (a context manager yielding a
    :class:`ResultsLock`); raises :class:`ResultsLockedError` when another run holds it."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder.resolve() / LOCK_NAME
    if path in _HELD:
        yield _HELD[path]
        return
    fd = _open_lock(path)
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
        check_results_folder(folder)  # under the lock: no other run changes it meanwhile
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
