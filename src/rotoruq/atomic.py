"""Crash-safe file writes: a reader sees the old file or the new one, never half of one.

Each write goes to a temporary file in the same folder, is flushed to disk (``fsync``) and
renamed over the target; the folder is then synced so the rename itself survives a crash.
Files and folders are created with the user's umask (``tempfile.mkstemp``/``mkdtemp`` would
make them private, 0600/0700, unlike every other file of a results folder), and the temporary
name is opened with ``O_EXCL | O_NOFOLLOW``: a link planted under that name is never followed.
"""

from __future__ import annotations

import os
import secrets
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

__all__ = ["atomic_write", "write_bytes", "write_text", "fsync_dir", "make_temp_dir"]


def fsync_dir(folder: str | os.PathLike) -> None:
    """Flush a folder's entries (renames, new files) to disk."""
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _temp_file(folder: Path, prefix: str, suffix: str) -> tuple[int, Path]:
    """A new file with a random name in ``folder``, mode 0666 less the umask."""
    flags = os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC
    for _ in range(100):
        tmp = folder / f"{prefix}{secrets.token_hex(6)}{suffix}"
        try:
            return os.open(tmp, flags, 0o666), tmp
        except FileExistsError:
            continue
    raise FileExistsError(f"no free temporary name {prefix}*{suffix} in {folder}")


def make_temp_dir(folder: str | os.PathLike, prefix: str) -> Path:
    """A new folder with a random name in ``folder``, mode 0777 less the umask (like
    ``tempfile.mkdtemp``, which makes it 0700)."""
    for _ in range(100):
        tmp = Path(folder) / f"{prefix}{secrets.token_hex(6)}"
        try:
            os.mkdir(tmp, 0o777)
            return tmp
        except FileExistsError:
            continue
    raise FileExistsError(f"no free temporary name {prefix}* in {folder}")


def atomic_write(path: str | os.PathLike, write: Callable[[BinaryIO], object]) -> Path:
    """Call ``write(fh)`` on a temporary binary file, then put it at ``path`` atomically.
    The new file's mode is 0666 less the umask; a symlink at ``path`` is replaced, never
    followed (``rename`` does not follow its target)."""
    path = Path(path)
    fd, tmp = _temp_file(path.parent, f".{path.name}.", ".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    fsync_dir(path.parent)
    return path


def write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Atomically write ``data`` to ``path``."""
    return atomic_write(path, lambda fh: fh.write(data))


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Atomically write ``text`` (UTF-8) to ``path``."""
    return write_bytes(path, text.encode("utf-8"))
