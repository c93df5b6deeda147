"""What the driver watchdog (``rotoruq.evaluation._watchdog``) costs and what it catches.

- ``per_evaluation``: wall and CPU time (this process and its children) of one
  ``run_process_tree`` call running ``python -S -c pass``, with the watchdog and without it
  (the path taken where ``prctl`` is missing), medians of interleaved repeats; the watchdog's
  cost is the difference.
- ``escapes``: a driver that starts a grandchild which calls ``setsid()``, execs a program
  with an empty environment that ignores SIGTERM, and whose parent exits at once; the
  processes of the tree still alive right after ``run_process_tree`` returns, with and
  without the watchdog.

    python benchmarks/driver_watchdog.py [--quick] > benchmarks/results/driver_watchdog.json
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)

from rotoruq.evaluation import process_tree
from rotoruq.evaluation.process_tree import is_running, run_process_tree

ESCAPER = r'''
import os, sys, time
if os.fork() == 0:
    if os.fork() == 0:  # setsid, then a new program with an empty environment (no token)
        os.setsid()
        open(sys.argv[1], "a").write(f"{os.getpid()}\n")
        os.execve(sys.executable, [sys.executable, "-S", "-c", "import signal, time; "
                  "signal.signal(signal.SIGTERM, signal.SIG_IGN); time.sleep(60)"], {})
    os._exit(0)  # its parent exits at once: it is nobody's descendant but init's
time.sleep(0.3)
'''


def one(argv: list[str], tmp: Path, watchdog: bool) -> tuple[float, float]:
    """(wall, CPU of this process and its children) of one run_process_tree call."""
    saved = process_tree._PRCTL
    if not watchdog:
        process_tree._PRCTL = None
    try:
        t0, c0 = time.perf_counter(), _cpu()
        run_process_tree(argv, cwd=tmp, stdout_path=tmp / "o", stderr_path=tmp / "e")
        return time.perf_counter() - t0, _cpu() - c0
    finally:
        process_tree._PRCTL = saved


def _cpu() -> float:
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    repeats = 10 if args.quick else 40
    out: dict = {"repeats": repeats, "cpus": os.cpu_count()}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        argv = [sys.executable, "-S", "-c", "pass"]
        runs: dict[str, list[tuple[float, float]]] = {"watchdog": [], "direct": []}
        for _ in range(repeats):
            for kind in runs:
                runs[kind].append(one(argv, tmp, kind == "watchdog"))
        med = {k: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v))
               for k, v in runs.items()}
        out["per_evaluation"] = {
            "wall_s": {k: round(v[0], 4) for k, v in med.items()},
            "cpu_s": {k: round(v[1], 4) for k, v in med.items()},
            "watchdog_extra_wall_s": round(med["watchdog"][0] - med["direct"][0], 4),
            "watchdog_extra_cpu_s": round(med["watchdog"][1] - med["direct"][1], 4),
        }
        (tmp / "esc.py").write_text(ESCAPER)
        escapes = {}
        for kind in ("watchdog", "direct"):
            pids = tmp / f"{kind}.pids"
            one([sys.executable, "-S", str(tmp / "esc.py"), str(pids)], tmp, kind == "watchdog")
            found = [int(x) for x in pids.read_text().split()]
            escapes[kind] = {"escaped_grandchildren": len(found),
                             "alive_after_return": sum(is_running(p) for p in found)}
            for p in found:
                if is_running(p):
                    os.kill(p, 9)
        out["escapes"] = escapes
    out["provenance"] = provenance()
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
