"""Run an external driver so that it can always be stopped, whole, and never floods memory.

:func:`run_process_tree` starts a command in a session of its own and waits for it with a
time limit. It is the one place where rotoruq runs a solver, and it guarantees:

- **The whole process tree ends.** On Linux the command runs under a watchdog
  (:mod:`rotoruq.evaluation._watchdog`, a small process of its own session) that is the
  *child subreaper* of the driver's tree: every process the driver starts stays below it,
  whatever it does (``setsid()``, double forks, an emptied environment). When the driver
  exits, when the run stops it or times out, and when the thread waiting for it dies (even by
  SIGKILL: the watchdog's parent-death signal), the watchdog SIGKILLs and reaps every
  descendant before it exits. As a second line, after the watchdog has exited (or when it
  was killed itself) every process the run left behind is killed with SIGKILL: the driver's
  process group, every descendant recorded while it ran (``/proc/<pid>/stat`` parent links,
  scanned at growing intervals: 10 ms doubling up to 2 s), and every process whose
  environment carries the run's random token (``ROTORUQ_DRIVER_TOKEN``). Processes are
  identified by (pid, start time), so a recycled pid is never signalled, and the watchdog
  itself is reaped only after its group has been killed, so its pid (the group id) cannot be
  reused in between. No cgroups or privileges are needed; elsewhere than Linux the command
  runs without watchdog and its process group alone is killed.
- **Bounded output.** stdout and stderr go through pipes drained by the waiting thread into
  two files: the first ``cap`` bytes, then a ``[rotoruq: N bytes omitted]`` line and the last
  ``FILE_TAIL`` bytes. Memory held per stream is the last ``FILE_TAIL`` bytes, whatever the
  driver writes.
- **Nothing outlives the run.** The watchdog gets a parent-death signal (``PR_SET_PDEATHSIG``,
  SIGTERM, upon which it kills the tree), the driver another (SIGKILL, should the watchdog
  itself be killed): if the process waiting for them dies, even by SIGKILL, so does the
  driver's whole tree. What no process can guarantee: a SIGKILL of the watchdog and of the
  run at once (``kill -9`` of both pids, the OOM killer taking both) leaves the driver's own
  children to init. Every
  running tree is listed, so that :func:`kill_active_trees` (called by a process-pool worker
  on SIGTERM or when :func:`watch_parent` sees the run's main process die) ends them all.
- **Stopped by the run that owns it.** A thread that runs the tasks of one client (a Dask
  worker's thread runs tasks of whatever run submitted them) marks its drivers with the run's
  id (:func:`owned_by`); ``kill_active_trees(owner=..., stop=True)``, sent to the workers by a
  run that is interrupted, ends that run's drivers only and starts none of its drivers
  afterwards, while the worker goes on serving other runs.
- **No busy waiting.** The thread sleeps in ``select`` on the output pipes and a pidfd of the
  driver (Linux >= 5.3), so a fast driver is seen to exit at once.
"""

from __future__ import annotations

import ctypes
import os
import select
import selectors
import signal
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

__all__ = ["DriverRun", "run_process_tree", "is_running", "kill_active_trees", "watch_parent",
           "set_parent_death_signal", "owned_by", "TOKEN_VAR", "FILE_TAIL"]

TOKEN_VAR = "ROTORUQ_DRIVER_TOKEN"
FILE_TAIL = 64 * 1024  # bytes of the end of each stream kept (file and memory)
_CHUNK = 64 * 1024
_PROC = Path("/proc")
_PR_SET_PDEATHSIG = 1
_WATCHDOG = str(Path(__file__).with_name("_watchdog.py"))
_STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP, signal.SIGINT)  # the watchdog's
_WATCHDOG_GRACE = 5.0  # seconds the watchdog gets to kill and reap the tree it holds
_ACTIVE: dict[int, _Tree] = {}  # running driver trees of this process, by driver pid
_ACTIVE_LOCK = threading.Lock()
_STOPPING = threading.Event()  # set by kill_active_trees(stop=True): no new driver starts
_OWNER = threading.local()  # .run: the run whose drivers this thread starts (owned_by)
_STOPPED_OWNERS: dict[str, None] = {}  # runs stopped in this process (oldest dropped first)
_MAX_STOPPED = 1024


def _load_prctl():
    if not sys.platform.startswith("linux"):
        return None
    try:
        return ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):  # pragma: no cover - a libc without prctl
        return None


_PRCTL = _load_prctl()  # looked up before any fork: the child only calls it


def set_parent_death_signal(sig: int = signal.SIGKILL) -> bool:
    """Ask the kernel to send ``sig`` to this process when the thread that started it ends
    (Linux ``prctl(PR_SET_PDEATHSIG)``); False where that is not available.

    Examples
    --------
    >>> set_parent_death_signal(0)  # clears it again
    True
    """
    if _PRCTL is None:
        return False
    return _PRCTL(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0


def _driver_preexec(parent: int):
    def preexec() -> None:
        # runs in the forked child before exec: the driver dies with the thread waiting for
        # it (and at once if that already happened between fork and prctl), and gets the
        # default SIGINT back (a process-pool worker ignores it)
        set_parent_death_signal(signal.SIGKILL)
        if os.getppid() != parent:
            os._exit(1)
        signal.signal(signal.SIGINT, signal.SIG_DFL)

    return preexec


@contextmanager
def owned_by(run: str) -> Iterator[None]:
    """Mark the drivers this thread starts meanwhile as the run ``run``'s, so that
    ``kill_active_trees(owner=run)`` ends them (and only them).

    Examples
    --------
    >>> with owned_by("run-1"):
    ...     kill_active_trees(owner="run-1", stop=True)  # none running; none may start now
    0
    >>> with owned_by("run-1"):
    ...     run_process_tree(["true"], cwd=".", stdout_path=os.devnull,
    ...                      stderr_path=os.devnull)
    Traceback (most recent call last):
    ...
    InterruptedError: run 'run-1' is stopping: no driver of it is started
    """
    before = getattr(_OWNER, "run", None)
    _OWNER.run = run
    try:
        yield
    finally:
        _OWNER.run = before


def kill_active_trees(*, stop: bool = False, owner: str | None = None) -> int:
    """SIGKILL every driver tree this process is running (drivers, their groups and
    descendants), or with ``owner`` those started under ``owned_by(owner)``; returns how
    many trees there were. With ``stop``, no driver (of ``owner``) starts in this process
    afterwards (:func:`run_process_tree` raises ``InterruptedError``).

    Examples
    --------
    >>> kill_active_trees()  # no driver running
    0
    """
    with _ACTIVE_LOCK:
        if stop and owner is None:
            _STOPPING.set()
        elif stop and owner is not None:
            _STOPPED_OWNERS[owner] = None
            while len(_STOPPED_OWNERS) > _MAX_STOPPED:
                del _STOPPED_OWNERS[next(iter(_STOPPED_OWNERS))]
        trees = [t for t in _ACTIVE.values() if owner is None or t.owner == owner]
    for tree in trees:
        tree.kill_all()
    return len(trees)


def _refuse_if_stopping(owner: str | None) -> None:
    """``InterruptedError`` when this process, or the run ``owner``, is stopping."""
    if _STOPPING.is_set():
        raise InterruptedError("the run is stopping: no driver is started")
    if owner is not None and owner in _STOPPED_OWNERS:
        raise InterruptedError(f"run {owner!r} is stopping: no driver of it is started")


def _wait_for_exit(pid: int, poll: float = 0.2) -> None:
    """Block until process ``pid`` (not necessarily a child) has ended."""
    try:
        fd = os.pidfd_open(pid)
    except (AttributeError, OSError):
        fd = None
    if fd is not None:
        try:
            select.select([fd], [], [])
        finally:
            os.close(fd)
        return
    while is_running(pid) or (not _PROC.is_dir() and _exists(pid)):  # no pidfd: poll
        time.sleep(poll)


def _exists(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass
    return True


def watch_parent(pid: int, exit_code: int = 1) -> threading.Thread:
    """Start a daemon thread that, when process ``pid`` ends (even by SIGKILL), kills this
    process's driver trees and exits with ``exit_code``; for the workers of a run, so that
    neither they nor their drivers outlive it.

    Examples
    --------
    >>> t = watch_parent(os.getpid())  # watches itself: never fires
    >>> t.daemon
    True
    """
    def watch() -> None:
        _wait_for_exit(pid)
        kill_active_trees(stop=True)
        os._exit(exit_code)

    t = threading.Thread(target=watch, name=f"rotoruq-watch-{pid}", daemon=True)
    t.start()
    return t


@dataclass(frozen=True, eq=False)
class DriverRun:
    """What happened to one driver process.

    returncode : exit status (negative: killed by that signal).
    timed_out : the time limit was reached and the tree was killed.
    stdout, stderr : the last bytes written to each stream (at most ``FILE_TAIL``).
    stdout_bytes, stderr_bytes : bytes written in total to each stream.
    leftovers : processes other than the driver that were still alive when it ended and were
        killed (descendants, escaped grandchildren).
    wall_time : seconds from start to the end of the cleanup.
    """

    returncode: int
    timed_out: bool
    stdout: bytes
    stderr: bytes
    stdout_bytes: int
    stderr_bytes: int
    leftovers: int
    wall_time: float


class _Capture:
    """Drain one pipe into a file: the first ``cap`` bytes, then the last ``FILE_TAIL``."""

    def __init__(self, fd: int, file, cap: int):
        self.fd = fd
        self.file = file
        self.cap = cap
        self.written = 0  # bytes of the head written to the file
        self.total = 0
        self.tail = bytearray()
        self.open = True

    def read(self) -> bool:
        """Read what the pipe holds; False at end of file."""
        data = os.read(self.fd, _CHUNK)
        if not data:
            return False
        self.total += len(data)
        room = self.cap - self.written
        if room > 0:
            self.file.write(data[:room])
            self.written += min(room, len(data))
        self.tail += data
        if len(self.tail) > FILE_TAIL:
            del self.tail[: len(self.tail) - FILE_TAIL]
        return True

    def close_pipe(self) -> None:
        if self.open:
            os.close(self.fd)
            self.open = False

    def finish(self) -> bytes:
        """Close the pipe, complete the file (omission line and tail); returns the tail."""
        self.close_pipe()
        start = self.total - len(self.tail)  # stream offset of the tail's first byte
        if self.total > self.written:
            skip = max(0, self.written - start)  # tail bytes already in the head
            omitted = start + skip - self.written
            if omitted:
                self.file.write(f"\n[rotoruq: {omitted} bytes omitted]\n".encode())
            self.file.write(self.tail[skip:])
        self.file.close()
        return bytes(self.tail)


def _read(path: str, size: int = 4096) -> bytes | None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None
    try:
        return os.read(fd, size)
    except OSError:
        return None
    finally:
        os.close(fd)


def _stat(pid: int) -> tuple[str, int, int, int, int] | None:
    """(state, ppid, pgid, session, start time) of a process, None if gone."""
    data = _read(f"/proc/{pid}/stat")
    if data is None:
        return None
    f = data[data.rfind(b")") + 2 :].split()
    try:
        return f[0].decode(), int(f[1]), int(f[2]), int(f[3]), int(f[19])
    except (IndexError, ValueError):
        return None


def is_running(pid: int) -> bool:
    """True while process ``pid`` exists and is not a zombie (Linux ``/proc``)."""
    st = _stat(pid)
    return st is not None and st[0] not in ("Z", "X")


def _pids() -> list[int]:
    try:
        return [int(d) for d in os.listdir(_PROC) if d.isdigit()]
    except OSError:
        return []


class _Tree:
    """The processes of one driver run, recorded as (pid -> start time)."""

    def __init__(self, root: int, token: str, owner: str | None = None,
                 watchdog: bool = False):
        self.root = root
        self.owner = owner
        self.watchdog = watchdog
        self.needle = f"{TOKEN_VAR}={token}".encode()
        self.known: dict[int, int] = {}
        self.me = os.getpid()

    def _scan(self, with_env: bool) -> dict[int, int]:
        """Live processes of the run: descendants of the driver, members of its session or
        group, and (``with_env``) holders of the token."""
        table = {}
        for pid in _pids():
            st = _stat(pid)
            if st is not None and st[0] not in ("Z", "X"):
                table[pid] = st
        children: dict[int, list[int]] = {}
        for pid, st in table.items():
            children.setdefault(st[1], []).append(pid)
        found = {}
        todo = [self.root]
        while todo:
            p = todo.pop()
            for c in children.get(p, ()):
                if c not in found:
                    found[c] = table[c][4]
                    todo.append(c)
        for pid, st in table.items():
            if st[2] == self.root or st[3] == self.root:
                found[pid] = st[4]
            elif with_env and pid not in found:
                env = _read(f"/proc/{pid}/environ", 1 << 21)
                if env is not None and self.needle in env:
                    found[pid] = st[4]
        if self.root in table:
            found[self.root] = table[self.root][4]
        found.pop(self.me, None)
        return found

    def record(self) -> None:
        self.known.update(self._scan(with_env=False))

    def kill_all(self) -> int:
        """SIGKILL the driver's group and every process of the run (several rounds, so that
        children forked meanwhile are caught too); returns how many processes other than the
        driver were killed."""
        if self.watchdog:  # it kills and reaps the tree it holds, then exits
            try:
                os.kill(self.root, signal.SIGTERM)
            except ProcessLookupError:
                pass
            end = time.monotonic() + _WATCHDOG_GRACE
            while is_running(self.root) and time.monotonic() < end:
                time.sleep(0.002)
        killed: set[int] = set()
        for rnd in range(50):
            try:
                os.killpg(self.root, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
            targets = self._scan(with_env=True) if _PROC.is_dir() else {}
            for pid, start in self.known.items():
                st = _stat(pid)
                if st is not None and st[4] == start and st[0] not in ("Z", "X"):
                    targets[pid] = start
            targets.pop(self.me, None)
            if not targets:
                break
            for pid, start in targets.items():
                st = _stat(pid)
                if st is None or st[4] != start:  # gone, or the pid was recycled
                    continue
                try:
                    os.kill(pid, signal.SIGKILL)
                    killed.add(pid)
                except (ProcessLookupError, PermissionError):
                    pass
            time.sleep(0.002 * (rnd + 1))
        killed.discard(self.root)
        return len(killed)


def _exited(pid: int) -> bool:
    """True once the child has exited; it stays a zombie (not reaped) so its pid, which is
    also its process group id, cannot be reused before the group is killed."""
    try:
        return os.waitid(os.P_PID, pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is not None
    except ChildProcessError:
        return True


def run_process_tree(
    argv: Sequence[str],
    *,
    cwd: str | os.PathLike | int,
    env: Mapping[str, str] | None = None,
    timeout: float | None = None,
    stdout_path: str | os.PathLike | int,
    stderr_path: str | os.PathLike | int,
    cap: int = 10 * 2**20,
) -> DriverRun:
    """Run ``argv`` (no shell) in ``cwd`` in a new session; wait at most ``timeout`` seconds.

    Parameters
    ----------
    argv : the command and its arguments.
    cwd : working directory: a path, or an open folder descriptor (the driver starts in the
        folder it holds, whatever its name leads to by then; the descriptor is passed on).
    env : the environment (default: this process's), to which ``ROTORUQ_DRIVER_TOKEN`` is
        added.
    timeout : seconds, or None for no limit.
    stdout_path, stderr_path : files receiving the first ``cap`` bytes and the last
        ``FILE_TAIL`` bytes of each stream: paths, or open file descriptors that this call
        takes over (and closes).
    cap : bytes of the head of each stream written to its file.

    Raises
    ------
    OSError
        When the command cannot be started (no such file, not executable).
    """
    owner = getattr(_OWNER, "run", None)
    _refuse_if_stopping(owner)
    t0 = time.perf_counter()
    token = uuid.uuid4().hex
    # the token goes first: found early in /proc/<pid>/environ, and it replaces the token of
    # an enclosing run (a rotoruq study run as a driver)
    env = {TOKEN_VAR: token, **{k: v for k, v in (os.environ if env is None else env).items()
                                if k != TOKEN_VAR}}
    files = []
    pipes = []
    watchdog = _PRCTL is not None
    pass_fds: tuple[int, ...]
    try:  # everything that can fail is done before the driver starts
        files = [open(stdout_path, "wb"), open(stderr_path, "wb")]  # noqa: SIM115
        extra: tuple[int, ...] = ()
        if isinstance(cwd, int):  # the folder the descriptor holds, never a swapped name
            extra, cwd = (cwd,), f"/proc/self/fd/{cwd}"
        pipes = [os.pipe(), os.pipe(), os.pipe()]  # stdout, stderr, the watchdog's report
        if watchdog:
            command = [sys.executable, "-I", "-S", _WATCHDOG, str(os.getpid()),
                       str(pipes[2][1]), *argv]
            pass_fds, preexec = (pipes[2][1], *extra), None
        else:
            command, pass_fds, preexec = list(argv), extra, _driver_preexec(os.getpid())
        # the watchdog starts with its stop signals blocked (it unblocks them once it can
        # act on them): a stop sent while it starts is never lost
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, _STOP_SIGNALS) if watchdog else None
        try:
            proc = subprocess.Popen(command, cwd=cwd, env=env, stdin=subprocess.DEVNULL,
                                    stdout=pipes[0][1], stderr=pipes[1][1], shell=False,
                                    close_fds=True, start_new_session=True,
                                    pass_fds=pass_fds, preexec_fn=preexec)
        finally:
            if mask is not None:
                signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    except BaseException:
        for fd in (fd for pair in pipes for fd in pair):
            os.close(fd)
        for f in files:
            f.close()
        raise
    for _, w in pipes:
        os.close(w)
    caps = [_Capture(pipes[0][0], files[0], cap), _Capture(pipes[1][0], files[1], cap)]
    tree = _Tree(proc.pid, token, owner, watchdog)
    with _ACTIVE_LOCK:
        _ACTIVE[proc.pid] = tree
        stopping = _STOPPING.is_set() or (owner is not None and owner in _STOPPED_OWNERS)
    if stopping:  # the stop came while it was starting
        tree.kill_all()
    sel = selectors.DefaultSelector()
    for c in caps:
        sel.register(c.fd, selectors.EVENT_READ, c)
    try:
        pidfd = os.pidfd_open(proc.pid)
        sel.register(pidfd, selectors.EVENT_READ, None)
    except (AttributeError, OSError):
        pidfd = None
    deadline = None if timeout is None else time.monotonic() + timeout
    timed_out = False
    leftovers = 0
    try:
        interval = 0.01
        next_scan = time.monotonic() + interval
        while not _exited(proc.pid):
            now = time.monotonic()
            if deadline is not None and now >= deadline:
                timed_out = True
                break
            if now >= next_scan:
                tree.record()
                interval = min(2 * interval, 2.0)
                next_scan = now + interval
            wait = next_scan - now
            if deadline is not None:
                wait = min(wait, deadline - now)
            if pidfd is None:
                wait = min(wait, 0.05)
            _pump(sel, max(wait, 0.0))
    finally:
        # also on KeyboardInterrupt or a cancelled task: nothing of the run survives it
        try:
            if pidfd is not None:
                sel.unregister(pidfd)
            leftovers = tree.kill_all()
            proc.wait()
            with _ACTIVE_LOCK:
                _ACTIVE.pop(proc.pid, None)
            end = time.monotonic() + 2.0
            while any(c.open for c in caps) and time.monotonic() < end:
                _pump(sel, 0.05)
        finally:
            sel.close()
            if pidfd is not None:
                os.close(pidfd)
            tails = [c.finish() for c in caps]
            report = _read_report(pipes[2][0])
    if report.startswith("exec "):
        code = int(report.split()[1])
        raise OSError(code, os.strerror(code), argv[0])
    if report.startswith("done "):
        leftovers += int(report.split()[1])
    return DriverRun(proc.returncode, timed_out, tails[0], tails[1], caps[0].total,
                     caps[1].total, leftovers, time.perf_counter() - t0)


def _read_report(fd: int) -> str:
    """What the watchdog wrote to its report pipe (empty without watchdog, or when it was
    killed before writing); closes the pipe."""
    try:
        os.set_blocking(fd, False)
        return os.read(fd, 64).decode("ascii", "replace")
    except (BlockingIOError, OSError):
        return ""
    finally:
        os.close(fd)


def _pump(sel: selectors.BaseSelector, wait: float) -> None:
    """Wait up to ``wait`` seconds for output or the driver's exit; drain what is readable."""
    if not sel.get_map():
        time.sleep(wait)
        return
    for key, _ in sel.select(wait):
        cap = key.data
        if cap is None:  # the pidfd: the driver exited
            continue
        if not cap.read():
            sel.unregister(key.fd)
            cap.close_pipe()
