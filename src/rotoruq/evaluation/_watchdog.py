"""The watchdog between rotoruq and one driver: the driver's whole process tree ends with it.

Run as a script (``python -I -S _watchdog.py PARENT STATUS_FD COMMAND...``, standard library
only, so it starts in milliseconds) by :func:`rotoruq.evaluation.process_tree.run_process_tree`
in a session of its own. It makes itself the *child subreaper* of everything below it
(``prctl(PR_SET_CHILD_SUBREAPER)``): a process of the driver's tree whose parent ends is
re-parented to the watchdog, not to init, whatever it does (``setsid()``, double forks, an
emptied environment), so the watchdog's descendants are exactly the tree. It then forks the
driver (in a process group of its own, so that a driver killing its own group does not kill
the watchdog) and waits. When the driver exits, when the watchdog gets SIGTERM, SIGHUP or
SIGINT (the run stops, times out, or kills it), and when the thread that started it ends
(``PR_SET_PDEATHSIG``, SIGTERM: the run or its worker died, even by SIGKILL), it SIGKILLs every
descendant and reaps them until it has no child left, writes ``done <n>`` (the processes other
than the driver it killed) or ``exec <errno>`` (the command could not be started) to
``STATUS_FD`` and exits with the driver's status (dying by the driver's signal when the driver
died by one).

What it cannot do: a SIGKILL of the watchdog itself (``kill -9`` of its pid, the OOM killer)
ends it without cleanup. The driver then still dies (its parent-death signal is SIGKILL), and
rotoruq's own scan of the tree, while the run is alive, kills the rest.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys

_PR_SET_PDEATHSIG = 1
_PR_SET_CHILD_SUBREAPER = 36
_STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP, signal.SIGINT)


class _Stop(BaseException):
    """A stop signal arrived while the driver ran."""


_cleaning = False


def _on_stop(signum, frame):
    if not _cleaning:
        raise _Stop


def _descendants(me: int) -> list[int]:
    """Live (not zombie) processes below ``me``, from ``/proc/<pid>/stat`` parent links."""
    children: dict[int, list[int]] = {}
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/stat", "rb") as f:
                data = f.read()
        except OSError:
            continue
        fields = data[data.rfind(b")") + 2:].split()
        if len(fields) > 1 and fields[0] not in (b"Z", b"X"):
            children.setdefault(int(fields[1]), []).append(int(name))
    found: list[int] = []
    todo = [me]
    while todo:
        for c in children.get(todo.pop(), ()):
            found.append(c)
            todo.append(c)
    return found


def _kill_tree(me: int, driver: int | None) -> tuple[int, int | None]:
    """SIGKILL every descendant and reap every child until none is left; returns how many
    processes other than the driver were killed and the driver's wait status (None when it
    had been reaped before)."""
    killed: set[int] = set()
    status = None
    while True:
        for pid in _descendants(me):
            try:
                os.kill(pid, signal.SIGKILL)
                killed.add(pid)
            except ProcessLookupError:
                pass
        try:
            pid, st = os.waitpid(-1, 0)
        except ChildProcessError:
            break
        if pid == driver:
            status = st
    killed.discard(driver)
    return len(killed), status


def _start(argv: list[str], me: int, prctl) -> tuple[int | None, int]:
    """Fork and exec the driver; (its pid, 0), or (None, errno) when exec failed."""
    r, w = os.pipe2(os.O_CLOEXEC)
    pid = os.fork()
    if pid == 0:
        try:
            os.close(r)
            # what Popen's restore_signals does: Python ignores SIGPIPE and SIGXFSZ
            for s in (*_STOP_SIGNALS, signal.SIGPIPE, signal.SIGXFSZ):
                signal.signal(s, signal.SIG_DFL)
            signal.pthread_sigmask(signal.SIG_SETMASK, ())
            os.setpgid(0, 0)
            prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
            if os.getppid() != me:
                os._exit(1)
            os.execvp(argv[0], argv)
        except OSError as exc:
            os.write(w, str(exc.errno).encode())
        finally:
            os._exit(127)
    os.close(w)
    try:
        err = os.read(r, 32)
    finally:
        os.close(r)
    return (None, int(err)) if err else (pid, 0)


def main(args: list[str]) -> None:
    global _cleaning
    parent, status_fd, argv = int(args[0]), int(args[1]), args[2:]
    os.set_inheritable(status_fd, False)  # the driver's tree cannot write to it
    for s in _STOP_SIGNALS:
        signal.signal(s, _on_stop)
    prctl = ctypes.CDLL(None, use_errno=True).prctl
    prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    if os.getppid() != parent:  # the run ended before the line above
        os._exit(1)
    prctl(_PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)
    me = os.getpid()
    driver = None
    status = None
    stopped = False
    report = "done"
    try:
        # started with the stop signals blocked (a stop sent before the handlers were set
        # is pending): from here on it raises _Stop
        signal.pthread_sigmask(signal.SIG_UNBLOCK, _STOP_SIGNALS)
        driver, errno_ = _start(argv, me, prctl)
        if driver is None:
            report = f"exec {errno_}"
        else:
            status = os.waitpid(driver, 0)[1]
    except _Stop:
        stopped = True
    finally:
        _cleaning = True
        n, last = _kill_tree(me, driver)
    if report == "done":
        report = f"done {n}"
    try:
        os.write(status_fd, report.encode())
    except OSError:
        pass
    status = last if status is None else status
    if stopped or (status is not None and os.WIFSIGNALED(status)):
        # the driver's signal, SIGKILL when it was stopped: what its waiter would have seen
        sig = int(signal.SIGKILL) if stopped or status is None else os.WTERMSIG(status)
        for number in {*map(int, _STOP_SIGNALS), sig} - {signal.SIGKILL, signal.SIGSTOP}:
            signal.signal(number, signal.SIG_DFL)
        os.kill(me, sig)
        os._exit(1)
    os._exit(127 if status is None else os.waitstatus_to_exitcode(status))


if __name__ == "__main__":
    main(sys.argv[1:])
