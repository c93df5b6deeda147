"""CPU seconds of each chapter of `rotoruq reproduce` and of each of its steps (issue 34).

CPU time, not wall time: it measures the work on a shared machine, where the wall time of the
same run varies with the load. Each chapter runs in a fresh Python process (imports, numba
cache loads and compilation included), one after the other; the process's user + system CPU
seconds over all its threads are the chapter's, each step's are the CPU seconds the process
spent inside it, and ``self_check_cpu_seconds`` the part of a Bayes step spent in its
self-check (simulation-based calibration). ``--cold`` points ``NUMBA_CACHE_DIR`` at one empty
folder for the whole run: the first chapter compiles every kernel it uses, a later one only
those not compiled before (the chapters of a newcomer's first ``rotoruq reproduce`` share one
cache).

    python benchmarks/reproduce_cpu.py --json benchmarks/results/reproduce_cpu.json
    python benchmarks/reproduce_cpu.py --cold --json benchmarks/results/reproduce_cpu_cold.json
    python benchmarks/reproduce_cpu.py --chapters validation --quick
    python benchmarks/reproduce_cpu.py --summary benchmarks/results/reproduce_cpu_cold_quick.json
                                                   # the docs' sentence from a saved run
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_and_save, print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)

CHAPTERS = ("validation", "experiment", "heldout")


def _cpu(who: int) -> float:
    ru = resource.getrusage(who)
    return ru.ru_utime + ru.ru_stime


def child(chapter: str, out: str, quick: bool) -> None:
    """Run one chapter in this process; print its step CPU seconds as JSON on the last line."""
    from pathlib import Path

    from rotoruq.methods.mcmc import bayes
    from rotoruq.study import runner
    from rotoruq.study.cmd_reproduce import _chapter

    steps: dict[str, float] = {}
    checks: dict[str, float] = {}
    current = [""]
    run_step, self_check = runner.run_step, bayes._self_check

    def timed(fn, ctx, *args):
        c0 = _cpu(resource.RUSAGE_SELF)
        current[0] = ctx.name
        try:
            return run_step(fn, ctx, *args)
        finally:
            steps[ctx.name] = round(_cpu(resource.RUSAGE_SELF) - c0, 2)

    def timed_check(*args, **kwargs):
        c0 = _cpu(resource.RUSAGE_SELF)
        try:
            return self_check(*args, **kwargs)
        finally:
            checks[current[0]] = round(_cpu(resource.RUSAGE_SELF) - c0, 2)

    # the benchmark's probes: the runner calls run_step once per step, calibrate_bayes
    # _self_check once per self-check (both looked up in their module at each call)
    runner.run_step, bayes._self_check = timed, timed_check
    _chapter(chapter, Path(out), quick)
    print(json.dumps({"steps": steps, "checks": checks,
                      "cpu": round(_cpu(resource.RUSAGE_SELF), 2)}))


def run_chapter(chapter: str, out: str, quick: bool, env: dict) -> dict:
    """One chapter in a fresh process: its CPU seconds, wall seconds and per-step CPU."""
    c0, t0 = _cpu(resource.RUSAGE_CHILDREN), time.perf_counter()
    done = subprocess.run([sys.executable, __file__, "--child", chapter, out]
                          + (["--quick"] if quick else []),
                          env=env, capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, _cpu(resource.RUSAGE_CHILDREN) - c0
    if done.returncode != 0:
        return {"error": done.stderr[-2000:]}
    got = json.loads(done.stdout.strip().splitlines()[-1])
    return {"cpu_seconds": round(cpu, 2), "wall_seconds": round(wall, 2),
            "steps_cpu_seconds": got["steps"], "self_check_cpu_seconds": got["checks"]}


def summary(result: dict) -> str:
    """The docs' sentence for a saved run: CPU seconds per chapter, its heaviest step and
    self-check, and the total."""
    parts = []
    for name, ch in result["chapters"].items():
        if "cpu_seconds" not in ch:
            parts.append(f"{name} failed")
            continue
        steps = ch["steps_cpu_seconds"]
        top = max(steps, key=steps.get)
        checks = sum(ch.get("self_check_cpu_seconds", {}).values())
        parts.append(f"{name} {ch['cpu_seconds']:.1f} CPU-s (heaviest step {top} "
                     f"{steps[top]:.1f}" + (f"; self-checks {checks:.1f}" if checks else "")
                     + ")")
    how = "an empty numba cache shared by the chapters" if result["cold_numba_cache"] else \
        "numba's cache warm"
    scope = "the --quick study" if result["quick"] else "the full study"
    return (f"`python benchmarks/reproduce_cpu.py{' --cold' if result['cold_numba_cache'] else ''}"
            f"{' --quick' if result['quick'] else ''}` ({scope}, {how}, each chapter in a fresh "
            f"process, load {result['provenance']['load'][0]}): " + "; ".join(parts)
            + f"; {result['cpu_seconds']:.1f} CPU-s in all.")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--chapters", nargs="+", default=list(CHAPTERS), choices=CHAPTERS)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--cold", action="store_true",
                    help="start from an empty numba cache (everything compiled once)")
    ap.add_argument("--json", default=None, help="also write the JSON to this file")
    ap.add_argument("--summary", default=None, metavar="JSON",
                    help="print the docs' sentence for a saved run and exit")
    ap.add_argument("--child", nargs=2, metavar=("CHAPTER", "OUT"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    if args.child:
        child(args.child[0], args.child[1], args.quick)
        return
    result: dict = {"quick": args.quick, "cold_numba_cache": args.cold, "cpus": os.cpu_count(),
                    "chapters": {}}
    with tempfile.TemporaryDirectory(prefix="rotoruq-cpu-") as tmp:
        env = dict(os.environ)
        if args.cold:
            env["NUMBA_CACHE_DIR"] = os.path.join(tmp, "numba")
        for chapter in args.chapters:
            result["chapters"][chapter] = run_chapter(chapter, os.path.join(tmp, "out"),
                                                      args.quick, env)
    result["cpu_seconds"] = round(sum(c.get("cpu_seconds", 0.0)
                                      for c in result["chapters"].values()), 2)
    result["provenance"] = provenance(modules=["rotoruq.study.cmd_reproduce"])
    print_and_save(result, args.json)


if __name__ == "__main__":
    main()
