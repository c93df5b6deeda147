"""``rotoruq serve [--stop | --status] [--detach] [--workers N] [--idle MINUTES]``: the driver
server of ``rotoruq driver``'s warm path (see :mod:`rotoruq.study.driver_server`).

The first driver call starts a server by itself; this command starts one by hand (in the
foreground, or in the background with ``--detach``), tells whether one is running
(``--status``: exit status 0 when it is, 1 when not) and stops it (``--stop``).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

from . import driver_client as client

HELP = "keep the rotor model loaded for 'rotoruq driver' (started by the driver by itself)"

__all__ = ["HELP", "add_arguments", "run"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    what = parser.add_mutually_exclusive_group()
    what.add_argument("--stop", action="store_true", help="stop the running server")
    what.add_argument("--status", action="store_true",
                      help="print the running server's state (exit status 1: none runs)")
    parser.add_argument("--detach", action="store_true",
                        help="run in the background (log: the socket's .log file)")
    parser.add_argument("--workers", type=int, default=None, metavar="N",
                        help=f"worker processes, calls answered at once (default: "
                             f"${client.WORKERS_VAR}, else the number of CPUs)")
    parser.add_argument("--idle", type=float, default=None, metavar="MINUTES",
                        help=f"stop after MINUTES without a call (default: ${client.IDLE_VAR}, "
                             "else 10; 0: never)")


def _ask(path: str, kind: bytes) -> list[bytes] | None:
    answer = client.request(path, [kind, client.identity()], client.CONNECT_TIMEOUT)
    return answer or None


def status(folder: str | None = None) -> dict[str, str] | None:
    """The running server's state (``pid``, ``workers``, ``calls``, ...), else ``None``."""
    folder = folder or client.server_dir()
    answer = _ask(client.socket_path(folder), b"status")
    if not answer or answer[0] != b"status":
        return None
    return dict(line.split("=", 1) for line in answer[1].decode().splitlines())


def stop(folder: str | None = None, timeout: float = 35.0) -> int | None:
    """Stop the running server and wait until its socket is gone; its pid, else ``None``."""
    folder = folder or client.server_dir()
    path = client.socket_path(folder)
    answer = _ask(path, b"stop")
    if not answer or answer[0] not in (b"stopping", b"stale"):
        return None
    deadline = time.monotonic() + timeout
    while os.path.exists(path) and time.monotonic() < deadline:
        time.sleep(0.02)
    return int(answer[1]) if answer[0] == b"stopping" else 0


def run(args: argparse.Namespace) -> int:
    folder = client.server_dir()  # a folder that is not private: an error, said
    path = client.socket_path(folder)
    if args.status:
        state = status(folder)
        if state is None:
            print(f"no driver server on {path}")
            return 1
        print("".join(f"{k}: {v}\n" for k, v in state.items()), end="")
        return 0
    if args.stop:
        pid = stop(folder)
        print(f"stopped the driver server (pid {pid})" if pid else
              f"no driver server on {path}")
        return 0
    state = status(folder)
    if state is not None:
        print(f"a driver server runs already (pid {state['pid']}) on {path}")
        return 0
    if not args.detach:
        proc = subprocess.Popen(client.server_argv(workers=args.workers,
                                                   idle_minutes=args.idle, detach=False))
        try:
            return proc.wait()
        except KeyboardInterrupt:  # the server saw Ctrl-C too: it stops by itself
            return proc.wait()
    client.start_server(folder, workers=args.workers, idle_minutes=args.idle)
    deadline = time.monotonic() + client.START_TIMEOUT
    while time.monotonic() < deadline:
        state = status(folder)
        if state is not None:
            print(f"driver server started (pid {state['pid']}, {state['workers']} workers, "
                  f"idle timeout {state['idle_minutes']} min) on {path}")
            return 0
        time.sleep(0.05)
    print(f"rotoruq serve: error: no server answered on {path} within "
          f"{client.START_TIMEOUT:g} s (see {path[:-5]}.log)", file=sys.stderr)
    return 1
