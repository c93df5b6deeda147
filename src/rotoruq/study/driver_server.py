"""The driver server: ``rotoruq driver`` calls answered by processes that keep models loaded.

``python -m rotoruq.study.driver_server [--detach] [--workers N] [--idle MINUTES]`` (what
``rotoruq serve`` and the first driver call run) serves the Unix socket of
:func:`rotoruq.study.driver_client.socket_path` in the private folder of
:func:`~rotoruq.study.driver_client.server_dir`:

- **One server per user and installation.** The server holds an exclusive ``flock`` on
  ``<socket>.lock`` for its lifetime: a second one started meanwhile exits at once. It removes
  a socket file nobody listens on (a server killed with SIGKILL leaves one), binds the socket
  (mode 0600) before loading anything, so that the first callers wait in its queue rather
  than start servers of their own, then loads the rotor model and its compiled kernels once.
- **Parallel calls.** It forks ``--workers`` processes (default: the number of CPUs; give at
  least Dakota's ``evaluation_concurrency``) that share the loaded code and accept
  connections on the one socket: each answers one call at a time, in the caller's working
  folder and with its umask, so concurrent calls never share a working folder. A worker that
  dies is replaced.
- **The answer of the in-process driver.** A call runs :func:`rotoruq.study.cmd_driver.main`
  on the caller's words, with stderr captured and warnings shown as in a fresh process; the
  results file is written by the same code, and the exit status and stderr text go back to
  the caller. Models are kept per worker (at most ``MODELS``, least recently used dropped),
  keyed by the driver's whole option set (``--preset``, ``--set``, ``--map``,
  ``--outputs``, ...) and the parameters file's variable and response names: two different
  driver strings never share a model.
- **Same code or nothing.** A call whose installation identity (version, package folder,
  interpreter, digest of the package's files) differs from the server's is answered
  ``stale``: the caller runs in process and the server stops (the next call starts a fresh
  one). A peer of another user id (``SO_PEERCRED``) is hung up on.
- **Gone when unused.** The server stops after ``--idle`` minutes without a call (default
  10; 0: never), on SIGTERM/SIGINT, on ``rotoruq serve --stop``, and when its socket file is
  removed or replaced. Workers end with the server (they poll their parent), a busy one
  after its call.
"""

from __future__ import annotations

import argparse
import contextlib
import fcntl
import io
import mmap
import os
import select
import signal
import socket
import sys
import time
import traceback
import warnings
from collections import OrderedDict

from . import driver_client as client

__all__ = ["main", "MODELS", "DEFAULT_IDLE_MINUTES"]

#: models kept per worker (least recently used dropped)
MODELS = 32
DEFAULT_IDLE_MINUTES = 10.0
#: seconds a worker waits for a request's bytes once a caller has connected
REQUEST_TIMEOUT = 10.0
_SLOT = 16  # per worker in the shared counters: pid, calls served


class _Stop(Exception):
    """The master was asked to stop (signal)."""


def _log(message: str) -> None:
    print(f"{time.strftime('%Y-%m-%d %H:%M:%S')} rotoruq serve [{os.getpid()}]: {message}",
          file=sys.stderr, flush=True)


def _preload() -> None:
    """Import the driver and the rotor model and load the compiled kernels (one point)."""
    import numpy as np

    from ..model import evaluate
    from ..rotor.model import RotorModel
    from . import cmd_driver  # noqa: F401

    evaluate(RotorModel("gvpm", names_in=["collective_deg"], names_out=["thrust"]),
             np.array([[8.0]]))


class _Models:
    """``cmd_driver.make_model`` with the models kept, keyed by the whole option set."""

    def __init__(self, size: int = MODELS) -> None:
        self.size = size
        self.models: OrderedDict[tuple, object] = OrderedDict()

    def __call__(self, args: argparse.Namespace, names_in: list[str], names_out: list[str],
                 fixed: dict[str, float]):
        from .cmd_driver import make_model

        options = tuple(sorted((k, repr(v)) for k, v in vars(args).items()
                               if k not in ("params", "results")))
        key = (options, tuple(names_in), tuple(names_out), tuple(sorted(fixed.items())))
        model = self.models.get(key)
        if model is None:
            model = make_model(args, names_in, names_out, fixed)
            self.models[key] = model
            while len(self.models) > self.size:
                self.models.popitem(last=False)
        else:
            self.models.move_to_end(key)
        return model


class Server:
    """The master process: the socket, the workers, the idle clock."""

    def __init__(self, folder: str, path: str, listener: socket.socket, *, workers: int,
                 idle_minutes: float, ident: bytes) -> None:
        self.folder, self.path, self.listener = folder, path, listener
        st = os.stat(path)
        self.inode = (st.st_dev, st.st_ino)
        self.n_workers, self.idle = workers, 60.0 * idle_minutes
        self.ident = ident
        self.pid = os.getpid()
        self.started = time.time()
        self.counters = mmap.mmap(-1, _SLOT * workers)  # shared with the forked workers
        self.activity_r, self.activity_w = os.pipe()
        self.workers: dict[int, int] = {}  # pid -> slot
        self.lock_fd = -1

    # -- master

    def run(self) -> None:
        def stop(signum, frame):
            raise _Stop()

        for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
            signal.signal(sig, stop)
        last = time.monotonic()
        try:
            for slot in range(self.n_workers):
                self._fork(slot)
            _log(f"serving {self.path} with {self.n_workers} workers, idle timeout "
                 f"{self.idle / 60:g} min")
            while True:
                if select.select([self.activity_r], [], [], 1.0)[0]:
                    os.read(self.activity_r, 4096)
                    last = time.monotonic()
                self._reap()
                if self.idle and time.monotonic() - last > self.idle:
                    _log("idle: stopping")
                    break
                if not self._socket_is_ours():
                    _log(f"{self.path} was removed or replaced: stopping")
                    break
        except _Stop:
            _log("asked to stop")
        finally:
            for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
                signal.signal(sig, signal.SIG_IGN)
            self._shutdown()

    def _socket_is_ours(self) -> bool:
        try:
            st = os.stat(self.path)
        except OSError:
            return False
        return (st.st_dev, st.st_ino) == self.inode

    def _fork(self, slot: int) -> None:
        pid = os.fork()
        if pid == 0:  # the worker
            code = 0
            try:
                _Worker(self, slot).serve()
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else 0
            except BaseException:  # noqa: BLE001  # a worker never returns into the master
                traceback.print_exc()
                code = 1
            finally:
                sys.stderr.flush()
                os._exit(code)
        self.workers[pid] = slot

    def _reap(self) -> None:
        while self.workers:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                return
            if pid == 0:
                return
            slot = self.workers.pop(pid, None)
            if slot is not None:
                _log(f"worker {pid} ended ({os.waitstatus_to_exitcode(status)}): replaced")
                self._fork(slot)

    def _shutdown(self) -> None:
        with contextlib.suppress(OSError):
            self.listener.close()
        if self._socket_is_ours():
            with contextlib.suppress(OSError):
                os.unlink(self.path)
        if self.lock_fd >= 0:  # a new server may start now (busy workers finish meanwhile)
            os.close(self.lock_fd)
            self.lock_fd = -1
        for pid in self.workers:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGTERM)
        deadline = time.monotonic() + 30.0  # a busy worker finishes its call first
        while self.workers and time.monotonic() < deadline:
            try:
                pid, _ = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                break
            if pid:
                self.workers.pop(pid, None)
            else:
                time.sleep(0.01)
        for pid in self.workers:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
        _log("stopped")

    def status_text(self, worker: _Worker) -> str:
        pids, calls = [], 0
        for slot in range(self.n_workers):
            base = slot * _SLOT
            pids.append(int.from_bytes(self.counters[base:base + 8], "little"))
            calls += int.from_bytes(self.counters[base + 8:base + 16], "little")
        version, package, executable = self.ident.split(b"\0")[:3]
        lines = {"pid": self.pid, "worker_pids": ",".join(str(p) for p in pids if p),
                 "workers": self.n_workers, "calls": calls,
                 "idle_minutes": f"{self.idle / 60:g}",
                 "uptime_s": f"{time.time() - self.started:.0f}",
                 "rotoruq": version.decode(errors="replace"),
                 "package": package.decode(errors="replace"),
                 "python": executable.decode(errors="replace"),
                 "socket": self.path, "models_in_this_worker": len(worker.models.models)}
        return "".join(f"{k}={v}\n" for k, v in lines.items())


class _Worker:
    """One forked process answering calls, one at a time."""

    def __init__(self, server: Server, slot: int) -> None:
        self.server, self.slot = server, slot
        self.models = _Models()
        self.busy = False
        self.stopping = False
        self.calls = 0

    def _on_term(self, signum, frame):
        if not self.busy:
            raise SystemExit(0)
        self.stopping = True

    def serve(self) -> None:
        srv = self.server
        os.close(srv.activity_r)
        if srv.lock_fd >= 0:
            os.close(srv.lock_fd)  # the master alone holds the server's lock
        signal.signal(signal.SIGTERM, self._on_term)
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
        base = self.slot * _SLOT
        srv.counters[base:base + 16] = os.getpid().to_bytes(8, "little") + bytes(8)
        srv.listener.settimeout(1.0)
        os.chdir(srv.folder)
        while not self.stopping and os.getppid() == srv.pid:
            try:
                conn, _ = srv.listener.accept()
            except TimeoutError:
                continue
            self.busy = True
            try:
                self._answer(conn)
            except Exception:  # noqa: BLE001  # log it, keep serving
                _log("error answering a call:\n" + traceback.format_exc())
            finally:
                conn.close()
                self.busy = False
                os.chdir(srv.folder)

    def _answer(self, conn: socket.socket) -> None:
        srv = self.server
        if client.peer_uid(conn) != os.getuid():
            _log("a process of another user connected: hung up")
            return
        conn.settimeout(REQUEST_TIMEOUT)
        fields = client.receive(conn)
        os.write(srv.activity_w, b".")
        if len(fields) < 3 or fields[0] != client.PROTOCOL:
            reply = [b"stale", b"protocol"]
        elif fields[2] != srv.ident:
            reply = [b"stale", b"another rotoruq installation or code"]
        elif fields[1] == b"status":
            reply = [b"status", srv.status_text(self).encode()]
        elif fields[1] == b"stop":
            reply = [b"stopping", str(srv.pid).encode()]
        elif fields[1] == b"call" and len(fields) >= 6:
            reply = self._call(fields[3], int(fields[4]), fields[5].decode(),
                               [os.fsdecode(w) for w in fields[6:]])
        else:
            reply = [b"bypass", b"unknown request"]
        conn.settimeout(REQUEST_TIMEOUT)
        with contextlib.suppress(OSError):
            conn.sendall(client.pack(reply))
        if reply[0] in (b"stale", b"stopping"):
            _log(f"stopping: {reply[0].decode()} {reply[1].decode(errors='replace')}")
            os.kill(srv.pid, signal.SIGTERM)
        os.write(srv.activity_w, b".")

    def _call(self, cwd: bytes, umask: int, encoding: str, words: list[str]) -> list[bytes]:
        from .cmd_driver import main as driver_main

        try:
            os.chdir(cwd)
        except OSError as exc:
            return [b"bypass", str(exc).encode(errors="replace")]
        previous = os.umask(umask)
        err = io.StringIO()
        try:
            # a fresh process shows each warning once: so does every call
            with warnings.catch_warnings(), contextlib.redirect_stderr(err):
                status = driver_main(words, make_model=self.models)
        except Exception:  # noqa: BLE001  # a bug: the caller runs in process, and says it
            _log("the driver raised:\n" + traceback.format_exc())
            return [b"bypass", b"the driver raised"]
        finally:
            os.umask(previous)
        self.calls += 1
        base = self.slot * _SLOT + 8
        self.server.counters[base:base + 8] = self.calls.to_bytes(8, "little")
        return [b"ok", str(int(status)).encode(),
                err.getvalue().encode(encoding, errors="backslashreplace")]


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m rotoruq.study.driver_server",
                                description=__doc__.splitlines()[0])
    p.add_argument("--detach", action="store_true",
                   help="fork, return at once, log to the socket's .log file")
    p.add_argument("--workers", type=int, default=None,
                   help=f"worker processes (default: ${client.WORKERS_VAR}, else the CPUs)")
    p.add_argument("--idle", type=float, default=None, metavar="MINUTES",
                   help=f"stop after MINUTES without a call (default: ${client.IDLE_VAR}, else "
                        f"{DEFAULT_IDLE_MINUTES:g}; 0: never)")
    return p


def _env_number(name: str, default: float) -> float:
    try:
        return float(os.environ[name])
    except (KeyError, ValueError):
        return default


def _lock(path: str, wait: float = 40.0) -> int | None:
    """The server's lock on ``<socket>.lock``, else ``None`` when another server holds it and
    serves (its socket exists). A server that is stopping has removed its socket already: wait
    for it to let go (at most ``wait`` seconds)."""
    fd = os.open(path + ".lock", os.O_RDWR | os.O_CREAT, 0o600)
    deadline = time.monotonic() + wait
    while True:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return fd
        except BlockingIOError:
            if os.path.exists(path) or time.monotonic() > deadline:
                os.close(fd)
                return None
            time.sleep(0.05)


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    workers = max(1, int(args.workers if args.workers is not None
                         else _env_number(client.WORKERS_VAR, os.cpu_count() or 1)))
    idle = max(0.0, args.idle if args.idle is not None
               else _env_number(client.IDLE_VAR, DEFAULT_IDLE_MINUTES))
    if args.detach:
        # a caller's open descriptors (Dakota's pipes) must not be held by the server
        os.closerange(3, 1 << 16)
        if os.fork():
            os._exit(0)
    try:
        folder = client.server_dir()
    except OSError as exc:
        print(f"rotoruq serve: error: {exc}", file=sys.stderr)
        return 1
    path = client.socket_path(folder)
    lock_fd = _lock(path)
    if lock_fd is None:
        if not args.detach:
            print(f"rotoruq serve: a server is running already on {path}", file=sys.stderr)
        return 0
    if args.detach:
        log = os.open(path[: -len(".sock")] + ".log", os.O_WRONLY | os.O_CREAT | os.O_TRUNC,
                      0o600)
        os.dup2(log, 1)
        os.dup2(log, 2)
        os.close(log)
    ident = client.identity()  # the files as they are now, before they are imported
    with contextlib.suppress(FileNotFoundError):
        os.unlink(path)  # nobody listens on it: we hold the lock
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    old = os.umask(0o177)
    try:
        listener.bind(path)
    except OSError as exc:
        _log(f"cannot listen on {path}: {exc}")
        return 1
    finally:
        os.umask(old)
    listener.listen(128)  # callers wait here while the model loads
    try:
        _preload()
    except Exception:  # noqa: BLE001  # each call will say what is wrong, in process
        _log("loading the rotor model failed:\n" + traceback.format_exc())
    server = Server(folder, path, listener, workers=workers, idle_minutes=idle, ident=ident)
    server.lock_fd = lock_fd
    server.run()
    return 0


if __name__ == "__main__":
    sys.exit(main())
