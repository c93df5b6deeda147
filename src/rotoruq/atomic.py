"""Crash-safe file writes: a reader sees the old file or the new one, never half of one.

Each write goes to a temporary file in the same folder, is flushed to disk (``fsync``) and
renamed over the target; the folder is then synced so the rename itself survives a crash.
Files and folders are created with the user's umask (``tempfile.mkstemp``/``mkdtemp`` would
make them private, 0600/0700, unlike every other file of a results folder), and the temporary
name is opened with ``O_EXCL | O_NOFOLLOW``: a link planted under that name is never followed.

:class:`SafeFolder` writes a tree of files (a report) through folder descriptors opened with
``O_NOFOLLOW``: a symlink planted at any folder or file name after the run started is refused
with a one-line error naming it, and a folder swapped after it was opened does not redirect
the writes (they go to the folder that was opened).
"""

from __future__ import annotations

import errno
import os
import secrets
import stat
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

from .safety import UnsafePathError, terminal_text

__all__ = ["atomic_write", "write_bytes", "write_text", "fsync_dir", "make_temp_dir",
           "SafeFolder"]

_DIR_FLAGS = os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC
_NEW_FILE = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC


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


def _planted(name: str, dir_fd: int | None, shown: Path) -> UnsafePathError | None:
    """The error for a symlink (or, where a folder is expected, a file) at ``name``."""
    try:
        st = os.lstat(name, dir_fd=dir_fd)
    except FileNotFoundError:
        return None
    if stat.S_ISLNK(st.st_mode):
        return UnsafePathError(
            f"symlink planted at {terminal_text(shown)} (-> "
            f"{terminal_text(os.readlink(name, dir_fd=dir_fd))}) while rotoruq writes there; "
            "rotoruq never writes through a symlink: remove it and run again")
    return None


class SafeFolder:
    """A folder opened without following a symlink, to create files and folders in.

    Every folder below it is opened the same way and every file is written atomically (a
    temporary name opened with ``O_EXCL | O_NOFOLLOW``, then renamed), all through folder
    descriptors: a symlink planted at a name, at any time, raises
    :class:`~rotoruq.safety.UnsafePathError` naming it, and nothing is written through it.

    Parameters
    ----------
    path : str or path-like
        The folder; created (with its parents, the user's umask) when missing. Its parents
        may be symlinks (the user's choice); the folder itself may not.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as d, SafeFolder(Path(d) / "report") as out:
    ...     with out.folder("tables") as tables:
    ...         _ = tables.write("a.csv", b"x,y\n")
    ...     (Path(d) / "report" / "tables" / "a.csv").read_bytes()
    b'x,y\n'
    """

    def __init__(self, path: str | os.PathLike, *, _parent: SafeFolder | None = None):
        self.path = Path(path)
        if _parent is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            where, name = None, str(self.path)
        else:
            where, name = _parent.fd, self.path.name
        try:
            os.mkdir(name, 0o777, dir_fd=where)
        except FileExistsError:
            pass
        try:
            self.fd = os.open(name, _DIR_FLAGS, dir_fd=where)
        except OSError as exc:
            if exc.errno in (errno.ELOOP, errno.ENOTDIR):
                planted = _planted(name, where, self.path)
                if planted is not None:
                    raise planted from None
                raise UnsafePathError(f"{terminal_text(self.path)}: expected a folder, found "
                                      "a file; remove it") from None
            raise

    def folder(self, name: str) -> SafeFolder:
        """The folder ``name`` in this one, created when missing (a context manager)."""
        return SafeFolder(self.path / name, _parent=self)

    def write(self, name: str, data: bytes, *, sync: bool = False) -> Path:
        """Write ``data`` to the file ``name`` of this folder atomically (with ``sync``, on
        disk before the rename); returns its path."""
        shown = self.path / name
        for _ in range(100):
            tmp = f".{name}.{secrets.token_hex(6)}.tmp"
            try:
                fd = os.open(tmp, _NEW_FILE, 0o666, dir_fd=self.fd)
                break
            except FileExistsError:
                continue
        else:
            raise FileExistsError(f"no free temporary name .{name}.*.tmp in {self.path}")
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
                fh.flush()
                if sync:
                    os.fsync(fh.fileno())
            planted = _planted(name, self.fd, shown)
            if planted is not None:
                raise planted
            os.replace(tmp, name, src_dir_fd=self.fd, dst_dir_fd=self.fd)
        except BaseException as exc:
            try:
                os.unlink(tmp, dir_fd=self.fd)
            except FileNotFoundError:
                pass
            if isinstance(exc, OSError) and not isinstance(exc, UnsafePathError):
                raise OSError(exc.errno, exc.strerror, str(shown)) from None
            raise
        if sync:
            os.fsync(self.fd)
        return shown

    def close(self) -> None:
        """Close the folder's descriptor."""
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1

    def __enter__(self) -> SafeFolder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
