"""Names, paths and text that come from someone else's study file or results folder.

A study file names its study, its steps and the files it reads and writes; a results folder
may come out of an archive. Nothing in them may write outside the results folder, follow a
symlink planted there, or put escape codes on the user's terminal:

- :func:`check_name`: a study or step name usable as one file name (no ``/``, ``\\``,
  ``..`` or control characters);
- :func:`check_relative` / :func:`inside`: a relative path without ``..`` that stays inside
  its folder once resolved (symlinks included);
- :func:`real_dir`, :func:`no_symlink`, :func:`open_nofollow`, :func:`read_nofollow`: files
  and folders of a results folder, never through a symlink;
- :class:`SafeFolder`: a tree of files (a report) written through folder descriptors opened
  with ``O_NOFOLLOW``, each file atomically: a symlink planted at any name after the run
  started is refused naming it, and a folder swapped after it was opened does not redirect
  the writes;
- :func:`write_file`: one file written atomically, never through a symlink at its name;
- :func:`terminal_text`: a string with its control characters shown as escapes (the one
  escaping of study-supplied text: :mod:`rotoruq.report.escape` builds on it).
"""

from __future__ import annotations

import errno
import os
import secrets
import shutil
import stat
import unicodedata
from pathlib import Path, PurePath
from typing import BinaryIO

from .errors import InputFileError, RotoruqError

__all__ = ["UnsafePathError", "ForeignFileError", "check_name", "name_problem",
           "check_relative", "inside", "no_symlink", "real_dir", "open_nofollow",
           "read_nofollow", "terminal_text", "is_control", "path_length_problem", "SafeFolder",
           "write_file"]

_DIR_FLAGS = os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC
_NEW_FILE = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC

# Unicode's bidirectional overrides and isolates reorder what a terminal shows (a name can
# hide or reverse the text after it); they are format characters, not control ones.
_BIDI = frozenset("\u061c\u200e\u200f\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")
# Controls, lone surrogates (no encoding writes them) and the separators that break a line.
_CONTROL_CATEGORIES = frozenset({"Cc", "Cs", "Zl", "Zp"})

#: Longest name accepted, in UTF-8 bytes: it must fit in one file name (255 on every common
#: file system) with the prefixes rotoruq adds (``.tmp-``, ``.old-``, suffixes).
MAX_NAME_BYTES = 200
#: Longest file name and path the kernel takes, in bytes (Linux ``NAME_MAX``, ``PATH_MAX``).
NAME_MAX = 255
PATH_MAX = 4096


class UnsafePathError(RotoruqError, ValueError):
    """A path that would leave its folder, or a symlink where rotoruq writes or reads."""


class ForeignFileError(RotoruqError, ValueError):
    """A file of a results folder that rotoruq did not write (tampered, foreign or
    corrupted): the message names it and says to remove it or re-run the step."""

    def __init__(self, path: str | os.PathLike, why: str = ""):
        self.path = str(path)
        self.why = why
        detail = f" ({why})" if why else ""
        super().__init__(f"not written by rotoruq: {terminal_text(self.path)}{detail}; "
                         "remove it or re-run the step")


def is_control(ch: str) -> bool:
    """Whether the character ``ch`` changes what a terminal or a page shows rather than being
    shown: C0/C1 controls and DEL (Unicode category Cc), lone surrogates (Cs), the line and
    paragraph separators (Zl, Zp) and the bidirectional overrides.

    Examples
    --------
    >>> [is_control(c) for c in "a\\x1b\\x7f\\u202e\\u2028\\u00e9"]
    [False, True, True, True, True, False]
    """
    return unicodedata.category(ch) in _CONTROL_CATEGORIES or ch in _BIDI


def terminal_text(text: object, *, lines: bool = False) -> str:
    """``str(text)`` with every control character (see :func:`is_control`) shown as an
    escape (``\\x1b``, ``\\u202e``): the result holds no control character.
    Newlines and tabs are escaped too (one study string stays on one line) unless
    ``lines`` is true (a message of several lines).

    Parameters
    ----------
    text : object
        A study-supplied string (a name, a description, a path, an error message).
    lines : bool
        Keep ``\\n`` and ``\\t`` as they are.

    Returns
    -------
    str
        Printable text.

    Examples
    --------
    >>> terminal_text("x\\x1b]0;owned\\x07y")
    'x\\\\x1b]0;owned\\\\x07y'
    >>> terminal_text("plain name, é")
    'plain name, é'
    >>> print(terminal_text("two\\nlines\\a", lines=True))
    two
    lines\\x07
    """
    s = str(text)
    # str.isprintable is False for every control character (Cc, Cs, Zl, Zp; the bidi
    # overrides are format characters, Cf): a printable string is returned in one C call
    # (a report escapes thousands of strings)
    if s.isprintable():
        return s
    keep = "\n\t" if lines else ""
    if not any(is_control(c) and c not in keep for c in s):
        return s
    out = []
    for c in s:
        if is_control(c) and c not in keep:
            o = ord(c)
            out.append(f"\\x{o:02x}" if o < 0x100 else f"\\u{o:04x}")
        else:
            out.append(c)
    return "".join(out)


def name_problem(name: object) -> str | None:
    """What makes ``name`` unusable as a study or step name (as one file name), or ``None``
    when it is fine.

    Examples
    --------
    >>> name_problem("bayes_1"), name_problem("up..x"), name_problem("a\\x1bb")
    (None, "'..'", 'a control character (\\\\x1b)')
    """
    if not isinstance(name, str):
        return f"a {type(name).__name__}, not text"
    if not name.strip():
        return "nothing but white space" if name else "an empty name"
    for c in name:
        if is_control(c):
            return f"a control character ({terminal_text(c)})"
    if "/" in name or "\\" in name:
        return "a path separator"
    if ".." in name:
        return "'..'"
    if name.startswith("."):
        return "a leading '.' (hidden file)"
    if len(name.encode("utf-8")) > MAX_NAME_BYTES:
        return f"more than {MAX_NAME_BYTES} bytes"
    return None


def check_name(name: object, *, what: str = "name", path: str | os.PathLike | None = None,
               line: int | None = None) -> str:
    """``name`` when it can name one file: text without ``/``, ``\\``, ``..``, control
    characters or a leading ``.``, not blank, at most :data:`MAX_NAME_BYTES` bytes.

    Parameters
    ----------
    name : object
        The name read from a study file (a study or step name).
    what : str
        What it names, for the message (``"the study name"``).
    path, line : file and 1-based line it was read from, for the message (optional).

    Returns
    -------
    str
        ``name`` unchanged.

    Raises
    ------
    InputFileError
        Naming the file and line, what is expected, and the name (control characters
        escaped).

    Examples
    --------
    >>> check_name("quick")
    'quick'
    >>> check_name("../../escaped", what="the study name", path="s.toml", line=2)
    Traceback (most recent call last):
    ...
    rotoruq.errors.InputFileError: s.toml, line 2: expected the study name without '/', \
'\\', '..', control characters or a leading '.' (found a path separator), found '../../escaped'
    """
    why = name_problem(name)
    if why is not None:
        raise InputFileError(path, line, f"{what} without '/', '\\', '..', control "
                             f"characters or a leading '.' (found {why})",
                             name if isinstance(name, str) else repr(name))
    assert isinstance(name, str)
    return name


def check_relative(value: object, *, what: str = "path",
                   path: str | os.PathLike | None = None, line: int | None = None) -> Path:
    """``value`` as a relative path that cannot climb out of its folder: not absolute (nor
    ``~``), no ``..`` component, no control character, not empty.

    Parameters
    ----------
    value : object
        The path as written in a study file.
    what : str
        What it is, for the message (``"[store] path"``).
    path, line : file and 1-based line it was read from, for the message (optional).

    Returns
    -------
    pathlib.Path
        The relative path.

    Raises
    ------
    InputFileError
        Naming the file, line and the path.

    Examples
    --------
    >>> check_relative("work/runs")
    PosixPath('work/runs')
    >>> check_relative("/tmp/elsewhere", what="[store] path")
    Traceback (most recent call last):
    ...
    rotoruq.errors.InputFileError: <string>: expected [store] path relative to its folder, \
without '..' (an absolute path), found '/tmp/elsewhere'
    """
    why = None
    text = os.fspath(value) if isinstance(value, str | os.PathLike) else None
    if not isinstance(text, str):
        why = f"a {type(value).__name__}"
    else:
        if not text.strip():
            why = "an empty path"
        elif any(is_control(c) for c in text):
            why = "a control character"
        elif PurePath(text).is_absolute() or text.startswith("~") or text.startswith("\\"):
            why = "an absolute path"
        elif ".." in PurePath(text).parts or ".." in text.split("\\"):
            why = "a '..' component"
    if why is not None:
        raise InputFileError(path, line, f"{what} relative to its folder, without '..' ({why})",
                             text if isinstance(text, str) else repr(value))
    assert text is not None
    return Path(text)


def inside(root: str | os.PathLike, value: object, *, what: str = "path",
           path: str | os.PathLike | None = None, line: int | None = None) -> Path:
    """``root / value`` after checking that it stays inside ``root``: ``value`` passes
    :func:`check_relative`, and its resolved form (symlinks followed, as far as they exist)
    lies under the resolved ``root``.

    Parameters
    ----------
    root : path-like
        The folder it must stay in (the results folder, the study file's folder).
    value : object
        The relative path from the study file.
    what, path, line : as for :func:`check_relative`.

    Returns
    -------
    pathlib.Path
        ``Path(root) / value`` (not resolved: messages keep the user's spelling).

    Raises
    ------
    InputFileError
        When ``value`` is absolute, has ``..`` or a control character, or leads out of
        ``root`` through a symlink.

    Examples
    --------
    >>> inside("out", "evaluations.sqlite")
    PosixPath('out/evaluations.sqlite')
    """
    rel = check_relative(value, what=what, path=path, line=line)
    joined = Path(root) / rel
    base = Path(root).resolve()
    target = joined.resolve()
    if target != base and base not in target.parents:
        raise InputFileError(path, line, f"{what} inside {terminal_text(root)} (it leads to "
                             f"{terminal_text(target)} through a symlink)",
                             str(value))
    return joined


def path_length_problem(p: str | os.PathLike) -> str | None:
    """Why no file can be named ``p`` (a name longer than ``NAME_MAX`` bytes, the whole path
    longer than ``PATH_MAX``), or None; for a command-line argument, refused as a usage
    error before the file system answers ``File name too long``.

    Examples
    --------
    >>> path_length_problem("results/r.out") is None
    True
    >>> path_length_problem("x" * 300)
    'a file name of 300 bytes (at most 255)'
    """
    raw = os.fsencode(p)
    if len(raw) >= PATH_MAX:
        return f"a path of {len(raw)} bytes (at most {PATH_MAX - 1})"
    longest = max(raw.split(b"/"), key=len)
    if len(longest) > NAME_MAX:
        return f"a file name of {len(longest)} bytes (at most {NAME_MAX})"
    return None


def no_symlink(p: str | os.PathLike) -> Path:
    """``p`` when it is not a symlink (it may be missing); :class:`UnsafePathError` naming
    it otherwise.

    Examples
    --------
    >>> no_symlink("no/such/file")
    PosixPath('no/such/file')
    """
    p = Path(p)
    if p.is_symlink():
        raise UnsafePathError(
            f"symlink in a results folder: {terminal_text(p)} -> "
            f"{terminal_text(os.readlink(p))}; rotoruq reads and writes only real files and "
            "folders there (a folder unpacked from an archive may carry links): remove it")
    return p


def real_dir(p: str | os.PathLike, *, create: bool = False) -> Path:
    """``p`` when it is a real folder (not a symlink to one); with ``create``, a missing
    one is made with the user's umask. :class:`UnsafePathError` naming it otherwise.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as d:
    ...     real_dir(Path(d) / "steps", create=True).is_dir()
    True
    """
    p = no_symlink(p)
    try:
        st = os.lstat(p)
    except FileNotFoundError:
        if not create:
            raise
        try:
            os.mkdir(p, 0o777)
        except FileExistsError:
            pass
        st = os.lstat(no_symlink(p))
    if not stat.S_ISDIR(st.st_mode):
        raise UnsafePathError(f"{terminal_text(p)}: expected a folder written by rotoruq, "
                              "found a file; remove it")
    return p


def open_nofollow(p: str | os.PathLike, flags: int = os.O_RDONLY, mode: int = 0o666) -> int:
    """``os.open(p, flags | O_NOFOLLOW | O_CLOEXEC, mode)``: a symlink at ``p`` raises
    :class:`UnsafePathError` naming it instead of being followed. ``mode`` is filtered by
    the umask, as for any new file.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as d:
    ...     fd = open_nofollow(Path(d) / "f", os.O_WRONLY | os.O_CREAT)
    ...     os.close(fd)
    """
    try:
        return os.open(p, flags | os.O_NOFOLLOW | os.O_CLOEXEC, mode)
    except OSError as exc:
        if exc.errno == errno.ELOOP or (exc.errno == errno.ENOTDIR and Path(p).is_symlink()):
            no_symlink(p)
        raise


def read_nofollow(p: str | os.PathLike) -> bytes:
    """The bytes of the regular file ``p``, opened without following a symlink
    (:class:`UnsafePathError`); a folder or device there is :class:`ForeignFileError`.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as d:
    ...     _ = (Path(d) / "a.txt").write_text("x")
    ...     read_nofollow(Path(d) / "a.txt")
    b'x'
    """
    fd = open_nofollow(p, os.O_RDONLY | os.O_NONBLOCK)
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise ForeignFileError(p, "not a regular file")
        chunks = []
        while chunk := os.read(fd, 1 << 20):
            chunks.append(chunk)
        return b"".join(chunks)
    finally:
        os.close(fd)


def _planted(name: str, dir_fd: int | None, shown: Path, doing: str = "writes"
             ) -> UnsafePathError | None:
    """The error for a symlink (or, where a folder is expected, a file) at ``name``."""
    try:
        st = os.lstat(name, dir_fd=dir_fd)
    except FileNotFoundError:
        return None
    if stat.S_ISLNK(st.st_mode):
        return UnsafePathError(
            f"symlink planted at {terminal_text(shown)} (-> "
            f"{terminal_text(os.readlink(name, dir_fd=dir_fd))}) while rotoruq {doing} there; "
            f"rotoruq never {doing} through a symlink: remove it and run again")
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
    new : bool
        The folder must be made by this call (:class:`FileExistsError` otherwise).
    create : bool
        Make the folder (and its parents) when missing (default); False: it must exist.
    follow : bool
        The folder itself may be a symlink (one the user made before the run started: a
        work folder linked to a scratch disk); everything below it is still held by
        descriptors.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as d, SafeFolder(Path(d) / "report") as out:
    ...     with out.folder("tables") as tables:
    ...         _ = tables.write("a.csv", b"x,y\\n")
    ...     (Path(d) / "report" / "tables" / "a.csv").read_bytes()
    b'x,y\\n'
    """

    fd: int  # the folder's descriptor, -1 once closed

    def __init__(self, path: str | os.PathLike, *, new: bool = False, create: bool = True,
                 follow: bool = False, _parent: SafeFolder | None = None):
        self.path = Path(path)
        if _parent is None:
            if create:
                self.path.parent.mkdir(parents=True, exist_ok=True)
            where, name = None, str(self.path)
        else:
            where, name = _parent.fd, self.path.name
        flags = _DIR_FLAGS & ~os.O_NOFOLLOW if follow and _parent is None else _DIR_FLAGS
        if create or new:
            try:
                os.mkdir(name, 0o777, dir_fd=where)
            except FileExistsError:
                if new:
                    planted = _planted(name, where, self.path)
                    if planted is not None:
                        raise planted from None
                    raise
        try:
            self.fd = os.open(name, flags, dir_fd=where)
        except OSError as exc:
            if exc.errno in (errno.ELOOP, errno.ENOTDIR):
                planted = _planted(name, where, self.path)
                if planted is not None:
                    raise planted from None
                raise UnsafePathError(f"{terminal_text(self.path)}: expected a folder, found "
                                      "a file; remove it") from None
            raise

    def folder(self, name: str, *, new: bool = False, create: bool = True) -> SafeFolder:
        """The folder ``name`` in this one (a context manager), created when missing
        (``create``); with ``new``, made by this call: a name taken is
        :class:`FileExistsError`, by a symlink :class:`UnsafePathError` naming it."""
        return SafeFolder(self.path / name, new=new, create=create, _parent=self)

    def create(self, name: str, mode: int = 0o666) -> int:
        """A descriptor of the new file ``name`` (opened ``O_EXCL | O_NOFOLLOW``, for a
        stream written as it comes): a symlink or a file already at ``name`` is refused,
        naming it (:class:`UnsafePathError` or :class:`FileExistsError`)."""
        try:
            return os.open(name, _NEW_FILE, mode, dir_fd=self.fd)
        except FileExistsError:
            planted = _planted(name, self.fd, self.path / name)
            if planted is not None:
                raise planted from None
            raise FileExistsError(errno.EEXIST, "a file is already there",
                                  str(self.path / name)) from None
        except OSError as exc:
            raise OSError(exc.errno, exc.strerror, str(self.path / name)) from None

    def symlink(self, name: str, target: str | os.PathLike) -> Path:
        """Make the symbolic link ``name`` -> ``target`` in this folder (the caller's link:
        the user listed it); a name already taken is :class:`FileExistsError`."""
        try:
            os.symlink(target, name, dir_fd=self.fd)
        except OSError as exc:
            raise OSError(exc.errno, exc.strerror, str(self.path / name)) from None
        return self.path / name

    def read(self, name: str, limit: int | None = None) -> bytes:
        """The bytes of the regular file ``name`` of this folder, never through a symlink
        (:class:`UnsafePathError` naming it); at most ``limit`` bytes when given. A missing
        file is :class:`FileNotFoundError`, a folder or device :class:`ForeignFileError`."""
        shown = self.path / name
        try:
            fd = os.open(name, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW | os.O_CLOEXEC,
                         dir_fd=self.fd)
        except OSError as exc:
            if exc.errno == errno.ELOOP:
                planted = _planted(name, self.fd, shown, "reads")
                if planted is not None:
                    raise planted from None
            raise OSError(exc.errno, exc.strerror, str(shown)) from None
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                raise ForeignFileError(shown, "not a regular file")
            chunks, got = [], 0
            while (limit is None or got < limit) and (
                    chunk := os.read(fd, 1 << 20 if limit is None else min(1 << 20, limit - got))):
                chunks.append(chunk)
                got += len(chunk)
            return b"".join(chunks)
        finally:
            os.close(fd)

    def lstat(self, name: str) -> os.stat_result | None:
        """``os.lstat`` of ``name`` in this folder (a link is not followed); None when
        missing."""
        try:
            return os.lstat(name, dir_fd=self.fd)
        except FileNotFoundError:
            return None

    def remove_tree(self, name: str) -> None:
        """Remove the folder ``name`` of this one and everything in it (links are removed,
        never followed: ``shutil.rmtree`` through this folder's descriptor); a symlink at
        ``name`` itself is :class:`UnsafePathError`; a missing one is nothing to do."""
        planted = _planted(name, self.fd, self.path / name)
        if planted is not None:
            raise planted
        try:
            shutil.rmtree(name, dir_fd=self.fd)
        except FileNotFoundError:
            pass

    def cwd_path(self) -> str:
        """A path to this very folder for a child process's working directory
        (``/proc/self/fd/<fd>``, with the descriptor passed to the child): the child starts
        in the folder this descriptor holds, even if its name was swapped for a link."""
        return f"/proc/self/fd/{self.fd}"

    def write(self, name: str, data: bytes | BinaryIO, *, sync: bool = False,
              mode: int | None = None) -> Path:
        """Write ``data`` (bytes, or a binary file read to its end) to the file ``name`` of
        this folder atomically (with ``sync``, on disk before the rename); ``mode``: the
        file's permission bits exactly (default 0666 less the umask). Returns its path."""
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
                if isinstance(data, bytes | bytearray | memoryview):
                    fh.write(data)
                else:
                    shutil.copyfileobj(data, fh)
                fh.flush()
                if mode is not None:
                    os.fchmod(fh.fileno(), mode)
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


def write_file(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (a new temporary name opened ``O_EXCL |
    O_NOFOLLOW`` in its folder, then renamed): a symlink planted at ``path`` is refused with
    :class:`UnsafePathError` naming it, never written through. The folder itself is the
    caller's and may be reached through links. For a file a driver or a results folder
    writes where someone else may have planted a link (no ``fsync``: see
    :mod:`rotoruq.atomic` for crash safety).

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as d:
    ...     write_file(Path(d) / "results.out", b"1.5 f\\n").read_bytes()
    b'1.5 f\\n'
    """
    p = Path(path)
    with SafeFolder(p.parent, create=False, follow=True) as folder:
        return folder.write(p.name, data)
