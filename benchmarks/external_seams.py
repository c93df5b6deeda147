"""External drivers at the seams: timeout of an escaping process tree, output flood, hostile
results files, per-evaluation cost of the safety machinery. Prints JSON; every number is a
ratio measured in this run (or a count / size), never an absolute time to compare across runs.

- ``timeout``: a driver that hangs after starting a grandchild that left its process group
  (``setsid``); ``return_over_timeout`` = time for ``run_one`` to return / ``timeout``;
  ``processes_left`` = driver and grandchild still alive afterwards.
- ``output_flood``: a driver writing ``--flood-mib`` MiB to stdout; growth of this process's
  peak memory (VmHWM) as a fraction of the output, and the size of the kept file.
- ``hostile_results``: parse time per byte of a results file holding a 20,000-digit token,
  over the parse time per byte of an ordinary one (linear parsers: about 1 or below).
- ``per_evaluation``: ``ExternalModel.run_one`` (work directory, parameters file, process tree
  watch, capped output, results check) over a bare ``subprocess.run`` of the same driver.

    python benchmarks/external_seams.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from rotoruq.evaluation.dakota_files import format_results, parse_results, write_parameters
from rotoruq.evaluation.external import ExternalModel
from rotoruq.evaluation.process_tree import is_running

DRIVER = r'''
import os, subprocess, sys, time
params, results = sys.argv[1], sys.argv[2]
lines = open(params).read().splitlines()
mode = float(lines[1].split()[0])
if mode == 1.0:  # hang, with a grandchild that escaped the process group
    gc = ("import os, sys, time; os.setsid(); "
          "open(sys.argv[1], 'w').write(str(os.getpid())); time.sleep(600)")
    subprocess.Popen([sys.executable, "-S", "-c", gc, os.environ["GC_PID"]])
    time.sleep(600)
if mode == 2.0:  # flood stdout
    block = b"y" * (1 << 20)
    for _ in range(int(os.environ["FLOOD_MIB"])):
        sys.stdout.buffer.write(block)
open(results, "w").write(f"{mode!r} f\n")
'''


def hwm_kib() -> int:
    line = next(s for s in open("/proc/self/status") if s.startswith("VmHWM"))
    return int(line.split()[1])


def best(fn, repeat: int) -> float:
    out = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out = min(out, time.perf_counter() - t0)
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--flood-mib", type=int, default=200)
    args = ap.parse_args()
    n = 10 if args.quick else 30
    out: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        drv = tmp / "driver.py"
        drv.write_text(DRIVER)
        os.environ["GC_PID"] = str(tmp / "gc.pid")
        os.environ["FLOOD_MIB"] = str(args.flood_mib)
        m = ExternalModel([sys.executable, "-S", str(drv)], ["mode"], ["f"],
                          workdir=tmp / "work", timeout=1.0, keep_workdirs=True)

        t0 = time.perf_counter()
        r = m.run_one(np.array([1.0]))
        wall = time.perf_counter() - t0
        pids = [int((tmp / "gc.pid").read_text())]
        out["timeout"] = {"timeout_s": 1.0, "return_over_timeout": round(wall / m.timeout, 3),
                          "status": r.status, "processes_left": sum(is_running(p) for p in pids)}

        before = hwm_kib()
        r = m.run_one(np.array([2.0]))
        grown = (hwm_kib() - before) / 1024
        kept = (Path(r.workdir) / "rotoruq.stdout").stat().st_size / 2**20
        out["output_flood"] = {"output_mib": args.flood_mib, "status": r.status,
                               "peak_memory_growth_mib": round(grown, 1),
                               "growth_over_output": round(grown / args.flood_mib, 4),
                               "kept_file_mib": round(kept, 2)}

        normal = format_results([1.2345678901234567, -2.5e-8], ["f", "g"]) * 200
        hostile = "1" * 20_000 + " f\n" + "2" * 20_000 + "x g\n"
        per_byte = {}
        for name, text in (("normal", normal), ("hostile", hostile)):
            def parse(text=text):
                try:
                    parse_results(text)
                except Exception:
                    pass
            per_byte[name] = best(parse, 20) / len(text)
        out["hostile_results"] = {"bytes": len(hostile),
                                  "per_byte_cost_over_normal": round(per_byte["hostile"] /
                                                                     per_byte["normal"], 3)}

        m_fast = ExternalModel([sys.executable, "-S", str(drv)], ["mode"], ["f"],
                               workdir=tmp / "work2")
        params = tmp / "p.in"
        write_parameters(params, {"mode": 0.0}, ["f"])

        def bare():
            for _ in range(n):
                subprocess.run([sys.executable, "-S", str(drv), str(params), str(tmp / "r.out")],
                               check=True, capture_output=True)

        def ours():
            for _ in range(n):
                assert m_fast.run_one(np.array([0.0])).status == "ok"

        t_bare, t_ours = best(bare, 3) / n, best(ours, 3) / n
        out["per_evaluation"] = {"evaluations": n,
                                 "run_one_over_bare_subprocess": round(t_ours / t_bare, 3)}
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
