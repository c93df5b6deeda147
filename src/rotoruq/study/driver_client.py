"""The warm path of ``rotoruq driver``: hand the call to a running driver server.

Dakota runs ``rotoruq driver ... params.in results.out`` once per evaluation; in a fresh
process each call pays the imports and the loading of the rotor's compiled kernels (about
0.8 s of CPU) for well under a millisecond of physics. A per-user server
(:mod:`rotoruq.study.driver_server`, ``rotoruq serve``) keeps the models loaded; this module
is what a driver call runs first. It imports the standard library's smallest modules only
(``_socket``, not ``socket``), so a served call costs little more than the interpreter's
start-up.

:func:`call` connects to the server's Unix socket, sends the driver's words, its working
folder and umask, and the identity of this installation (version, package folder,
interpreter, a digest of the size and modification time of every file of the package); the
server answers with the exit status and the text the in-process driver would have printed on
stderr, after writing exactly the results file it would have written. Anything short of that
answer - the warm path switched off, no server and none could be started, a socket folder
that is not private, a server of other code (it stops itself), a server that dies or stays
silent - returns ``None``, and the caller runs the driver in process: the warm path never
fails an evaluation.

The socket lives in a private folder: ``$ROTORUQ_SERVER_DIR``, else
``$XDG_RUNTIME_DIR/rotoruq``, else ``$TMPDIR/rotoruq-<uid>`` (``/tmp`` without ``TMPDIR``),
created with mode 0700; a folder not owned by the user or open to group or others is refused.
Both ends check the peer's user id (``SO_PEERCRED``).

Environment: ``ROTORUQ_DRIVER_SERVER=0`` switches the warm path off (checked by the
command line before this module is imported); ``ROTORUQ_DRIVER_TIMEOUT`` (seconds, default
300) bounds the wait for an answer; ``ROTORUQ_SERVER_IDLE`` (minutes, default 10) and
``ROTORUQ_SERVER_WORKERS`` (default: the number of CPUs) configure a server the driver
starts. A driver run by rotoruq's own external-model runner (``ROTORUQ_DRIVER_TOKEN`` set)
uses a running server but starts none: that runner ends every process a driver leaves behind.
"""

from __future__ import annotations

import _socket  # the C module: ``socket`` imports enum, selectors & co (10 ms of CPU)
import os
import stat
import sys
import time
import zlib

from .. import __version__

__all__ = ["call", "request", "start_server", "server_argv", "server_dir", "socket_path",
           "check_folder", "identity", "code_digest", "pack", "unpack", "SWITCH", "DIR_VAR"]

#: ``ROTORUQ_DRIVER_SERVER=0``: every driver call runs in process.
SWITCH = "ROTORUQ_DRIVER_SERVER"
#: the folder of the socket (default: see the module).
DIR_VAR = "ROTORUQ_SERVER_DIR"
TIMEOUT_VAR = "ROTORUQ_DRIVER_TIMEOUT"
IDLE_VAR = "ROTORUQ_SERVER_IDLE"
WORKERS_VAR = "ROTORUQ_SERVER_WORKERS"
#: set by rotoruq's process-tree runner, which kills what a driver leaves behind
TOKEN_VAR = "ROTORUQ_DRIVER_TOKEN"

PROTOCOL = b"rotoruq-driver-server/1"
#: the package folder this module was imported from (the server must run the same files)
PACKAGE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: seconds to wait for a starting server's socket to accept connections
START_TIMEOUT = 10.0
CONNECT_TIMEOUT = 2.0
DEFAULT_CALL_TIMEOUT = 300.0
_MAX_MESSAGE = 1 << 26


def server_dir(create: bool = True) -> str:
    """The private folder of the socket, created (mode 0700) when missing and ``create``.

    Raises
    ------
    PermissionError
        The folder is not a directory owned by this user with no group or other permissions.
    """
    d = os.environ.get(DIR_VAR)
    if not d:
        runtime = os.environ.get("XDG_RUNTIME_DIR")
        if runtime and os.path.isdir(runtime):
            d = os.path.join(runtime, "rotoruq")
        else:
            d = os.path.join(os.environ.get("TMPDIR") or "/tmp", f"rotoruq-{os.getuid()}")
    d = os.path.abspath(d)
    if create:
        try:
            os.makedirs(d, mode=0o700)
        except FileExistsError:
            pass
    check_folder(d)
    return d


def check_folder(path: str) -> None:
    """Refuse a socket folder that another user could enter or own (see :func:`server_dir`)."""
    st = os.lstat(path)
    if not stat.S_ISDIR(st.st_mode):
        raise PermissionError(f"the driver server's folder {path} is not a directory (a "
                              "symbolic link or a file is refused)")
    if st.st_uid != os.getuid():
        raise PermissionError(f"the driver server's folder {path} is owned by user id "
                              f"{st.st_uid}, not by you ({os.getuid()}); set {DIR_VAR} to a "
                              "folder of your own")
    if st.st_mode & 0o077:
        raise PermissionError(f"the driver server's folder {path} has mode "
                              f"{stat.S_IMODE(st.st_mode):04o}: group or others may enter it "
                              f"(chmod 700 {path}, or set {DIR_VAR} to a private folder)")


def socket_path(folder: str) -> str:
    """The socket of this installation (package folder and interpreter) in ``folder``."""
    key = zlib.crc32(f"{PACKAGE}\0{sys.executable}".encode(errors="surrogateescape"))
    return os.path.join(folder, f"driver-{key:08x}.sock")


def code_digest(root: str = PACKAGE) -> str:
    """A digest of the path, size and modification time of every file under ``root``
    (``__pycache__`` left out): it changes when any source or data file does."""
    entries = []
    todo = [root]
    while todo:
        folder = todo.pop()
        with os.scandir(folder) as it:
            for e in it:
                if e.name == "__pycache__" or e.name.startswith("."):
                    continue
                if e.is_dir(follow_symlinks=False):
                    todo.append(e.path)
                else:
                    st = e.stat()
                    entries.append(f"{e.path}\0{st.st_size}\0{st.st_mtime_ns}")
    data = "\n".join(sorted(entries)).encode(errors="surrogateescape")
    return f"{zlib.crc32(data):08x}{zlib.adler32(data):08x}"


def identity() -> bytes:
    """What a server must share with this client to answer for it: version, package folder,
    interpreter and :func:`code_digest`."""
    return "\0".join((__version__, PACKAGE, sys.executable, sys.version, code_digest())).encode(
        errors="surrogateescape")


def pack(fields: list[bytes]) -> bytes:
    """One message: its length, then each field's length and bytes (4-byte big-endian)."""
    body = b"".join(len(f).to_bytes(4, "big") + f for f in fields)
    return len(body).to_bytes(4, "big") + body


def unpack(body: bytes) -> list[bytes]:
    """The fields of a message body (without its leading length)."""
    out, k = [], 0
    while k < len(body):
        n = int.from_bytes(body[k:k + 4], "big")
        if k + 4 + n > len(body):
            raise ValueError("truncated message")
        out.append(body[k + 4:k + 4 + n])
        k += 4 + n
    return out


def _recv_exact(sock, n: int) -> bytes:
    chunks, got = [], 0
    while got < n:
        chunk = sock.recv(min(n - got, 1 << 20))
        if not chunk:
            raise ConnectionError("the driver server closed the connection")
        chunks.append(chunk)
        got += len(chunk)
    return b"".join(chunks)


def receive(sock) -> list[bytes]:
    """One message from ``sock`` (raises ``ConnectionError`` on a short read)."""
    n = int.from_bytes(_recv_exact(sock, 4), "big")
    if n > _MAX_MESSAGE:
        raise ValueError(f"message of {n} bytes")
    return unpack(_recv_exact(sock, n))


def peer_uid(sock) -> int:
    """The user id of the process at the other end of a Unix socket (Linux ``SO_PEERCRED``)."""
    creds = sock.getsockopt(_socket.SOL_SOCKET, _socket.SO_PEERCRED, 12)
    return int.from_bytes(creds[4:8], sys.byteorder)


def connect(path: str, timeout: float = CONNECT_TIMEOUT):
    """A connected socket to the server at ``path`` run by this user, else ``None``."""
    sock = _socket.socket(_socket.AF_UNIX, _socket.SOCK_STREAM)
    try:
        sock.settimeout(timeout)
        sock.connect(path)
        if peer_uid(sock) != os.getuid():
            raise PermissionError(f"{path} is served by another user")
    except OSError:
        sock.close()
        return None
    return sock


def request(path: str, fields: list[bytes], timeout: float) -> list[bytes] | None:
    """Send one request to the server at ``path``; its answer, ``None`` when no server
    accepts the connection, ``[]`` when the server gave no complete answer within ``timeout``
    seconds (it died, or hangs)."""
    sock = connect(path)
    if sock is None:
        return None
    try:
        sock.settimeout(timeout)
        sock.sendall(pack([PROTOCOL, *fields]))
        return receive(sock)
    except (OSError, ValueError):
        return []
    finally:
        sock.close()


def server_argv(*, workers: int | None = None, idle_minutes: float | None = None,
                detach: bool = True) -> list[str]:
    """The command that runs a server of this installation (``-P``: the caller's working
    folder is not put on ``sys.path``)."""
    argv = [sys.executable, "-P", "-m", "rotoruq.study.driver_server"]
    if detach:
        argv.append("--detach")
    if workers is not None:
        argv += ["--workers", str(int(workers))]
    if idle_minutes is not None:
        argv += ["--idle", repr(float(idle_minutes))]
    return argv


def start_server(folder: str, *, workers: int | None = None,
                 idle_minutes: float | None = None) -> int:
    """Start a server for this installation in the background, in a session of its own (it
    detaches itself: the launcher forks it and exits); the launcher's exit status."""
    argv = server_argv(workers=workers, idle_minutes=idle_minutes)
    env = {k: v for k, v in os.environ.items() if k != TOKEN_VAR}
    env[DIR_VAR] = folder
    null = os.open(os.devnull, os.O_RDWR)
    try:
        pid = os.posix_spawn(sys.executable, argv, env, setsid=True,
                             file_actions=[(os.POSIX_SPAWN_DUP2, null, 0),
                                           (os.POSIX_SPAWN_DUP2, null, 1),
                                           (os.POSIX_SPAWN_DUP2, null, 2)])
    finally:
        os.close(null)
    # reap the launcher (no zombie left in a long-lived caller)
    return os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])


def _float_env(name: str, default: float) -> float:
    try:
        return float(os.environ.get(name, default))
    except ValueError:
        return default


def call(words: list[str]) -> int | None:
    """Run one driver call (``words``: the driver's command line) on the warm path.

    Returns
    -------
    int or None
        The driver's exit status, its results file written and its messages printed on
        stderr by the server; ``None`` when the call was not served (run it in process).
    """
    try:
        folder = server_dir()
        path = socket_path(folder)
        umask = os.umask(0o077)
        os.umask(umask)
        fields = [b"call", identity(), os.getcwdb(), str(umask).encode(),
                  (sys.stderr.encoding or "utf-8").encode(), *(os.fsencode(w) for w in words)]
    except (OSError, ValueError):
        return None
    timeout = _float_env(TIMEOUT_VAR, DEFAULT_CALL_TIMEOUT)
    answer = request(path, fields, timeout)
    if answer is None and not os.environ.get(TOKEN_VAR):
        # no server (or a socket file nobody listens on): start one, wait for its socket
        try:
            start_server(folder)
        except OSError:
            return None
        deadline = time.monotonic() + START_TIMEOUT
        while answer is None and time.monotonic() < deadline:
            time.sleep(0.02)
            answer = request(path, fields, timeout)
    if not answer or answer[0] != b"ok" or len(answer) != 3:
        return None
    if answer[2]:
        sys.stderr.flush()
        sys.stderr.buffer.write(answer[2])
        sys.stderr.flush()
    return int(answer[1])
