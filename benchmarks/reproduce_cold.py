"""A newcomer's first `rotoruq reproduce`: wall and CPU seconds of ``rotoruq reproduce``
with an empty numba cache (issue 34: within 60 s on two quiet cores), and what it compiled.

Runs ``rotoruq reproduce [--quick] --json`` in a fresh process with ``NUMBA_CACHE_DIR`` at an
empty folder and records its wall time, its CPU seconds (itself and every process it
started: the chapters' pool, the figure workers), the seconds it printed per chapter and
for the report, the machine's load before and after, and its compile notices: how many
processes announced a compile of each kernel family and how many of them waited for another
process's compile instead (``rotoruq._compile.compile_lock``). CPU seconds are what to compare
on a shared machine; the wall time is only meaningful at a load below the core count.

    python benchmarks/reproduce_cold.py --quick --json benchmarks/results/reproduce_cold_quick.json
    python benchmarks/reproduce_cold.py --summary benchmarks/results/reproduce_cold_quick.json
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time

from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_and_save, print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)

COMPILING = re.compile(r"^compiling (?P<family>.+?) \(once per install")
WAITING = re.compile(r"^another process is compiling the (?P<family>.+?): waiting")


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def measure(quick: bool, out: str) -> dict:
    """One cold ``rotoruq reproduce`` into ``out`` (a fresh folder)."""
    cache = tempfile.mkdtemp(prefix="rotoruq-numba-cold-")
    env = {**os.environ, "NUMBA_CACHE_DIR": cache}
    cmd = [sys.executable, "-m", "rotoruq.study.cli", "reproduce", "--out", out, "--json",
           *(["--quick"] if quick else [])]
    load0 = os.getloadavg()
    t0, c0 = time.perf_counter(), _children_cpu()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, _children_cpu() - c0
    compiled: dict[str, int] = {}
    waited: dict[str, int] = {}
    for line in proc.stderr.splitlines():
        if m := COMPILING.match(line.strip()):
            compiled[m["family"]] = compiled.get(m["family"], 0) + 1
        elif m := WAITING.match(line.strip()):
            waited[m["family"]] = waited.get(m["family"], 0) + 1
    seconds = {}
    if proc.returncode == 0:
        seconds = json.loads(proc.stdout)["seconds"]
    return {"quick": quick, "cold_numba_cache": True, "cpus": os.cpu_count(),
            "exit": proc.returncode, "wall_seconds": round(wall, 2),
            "cpu_seconds": round(cpu, 2), "load_before": [round(x, 2) for x in load0],
            "load_after": [round(x, 2) for x in os.getloadavg()],
            "seconds": {k: round(v, 2) for k, v in seconds.items()},
            "announced": compiled, "waited": waited,
            "stderr_tail": proc.stderr[-2000:] if proc.returncode else ""}


def summary(result: dict) -> str:
    """The docs' sentence for a saved result."""
    fams = ", ".join(f"{f} announced by {n} process{'es' if n > 1 else ''}"
                     + (f" ({result['waited'][f]} waited for the other's compile)"
                        if result["waited"].get(f) else "")
                     for f, n in sorted(result["announced"].items()))
    sec = result["seconds"]
    return (f"`python benchmarks/reproduce_cold.py{' --quick' if result['quick'] else ''}` "
            f"(an empty numba cache, {result['cpus']} cores, load "
            f"{result['load_before'][0]:.1f} before, {result['load_after'][0]:.1f} after): "
            f"{result['cpu_seconds']:.1f} CPU-s, {result['wall_seconds']:.1f} s wall "
            f"(chapters until {sec.get('wall', float('nan')):.1f} s, report "
            f"{sec.get('report', float('nan')):.1f} s); {fams}.")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--summary", default=None, metavar="JSON",
                    help="print the docs' sentence for a saved result and exit")
    ap.add_argument("--quick", action="store_true", help="the reduced study")
    ap.add_argument("--out", default=None, help="keep the results here (default: temporary)")
    ap.add_argument("--json", default=None, help="also write the JSON to this file")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    out = args.out or tempfile.mkdtemp(prefix="rotoruq-reproduce-cold-")
    result = measure(args.quick, out)
    import rotoruq

    result["rotoruq"] = os.path.dirname(rotoruq.__file__)  # the code measured
    result["provenance"] = provenance(modules=["rotoruq.study.cli", "rotoruq._compile"])
    print_and_save(result, args.json)


if __name__ == "__main__":
    main()
