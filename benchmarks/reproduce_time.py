"""Wall time of `rotoruq reproduce` per chapter (target, issue 12: the whole study and its
report in < 30 s on 2 cores, each figure drawn once). Prints JSON: seconds per chapter and
for the report, total, the number of figures, and whether the total is within the target.
Run it once first so the numba caches are warm; compare versions by alternating runs.

    python benchmarks/reproduce_time.py --repeats 3 --json benchmarks/results/reproduce_time.json

    python benchmarks/reproduce_time.py            # full study
    python benchmarks/reproduce_time.py --quick    # the reduced CI version
    python benchmarks/reproduce_time.py --summary benchmarks/results/reproduce_time.json
                                                   # README's sentence from a saved run
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
import traceback

import numpy as np
from _summary import print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)

TARGET_SECONDS = 30.0


def run_once(out_root: str, chapters: list[str], quick: bool) -> dict:
    """One reproduction into the empty folder ``out_root``: seconds per chapter and report."""
    from rotoruq.report.html import write_report
    from rotoruq.study.cmd_reproduce import CHAPTERS, studies_dir
    from rotoruq.study.runner import run_study

    result: dict = {"seconds": {}, "errors": {}}
    t_all = time.perf_counter()
    for name in chapters:
        t0 = time.perf_counter()
        try:
            run_study(studies_dir() / CHAPTERS[name], out=os.path.join(out_root, name),
                      quick=quick)
        except Exception as exc:  # noqa: BLE001 - report the failure, time the rest
            result["errors"][name] = f"{type(exc).__name__}: {exc}"
            traceback.print_exc()
        result["seconds"][name] = round(time.perf_counter() - t0, 2)
    t0 = time.perf_counter()
    dirs = [os.path.join(out_root, n) for n in chapters
            if os.path.isfile(os.path.join(out_root, n, "study.json"))]
    write_report(dirs, os.path.join(out_root, "report"))
    result["seconds"]["report"] = round(time.perf_counter() - t0, 2)
    result["figures"] = len(os.listdir(os.path.join(out_root, "report", "figures")))
    result["seconds"]["total"] = round(time.perf_counter() - t_all, 2)
    return result


def summary(result: dict) -> str:
    """README's sentence for a saved result."""
    sec, rng = result["seconds"], result["range"]

    def stage(s: str) -> str:
        return f"{sec[s]:.1f} ({rng[s][0]:.1f}-{rng[s][1]:.1f}) s"

    chapters = ", ".join(f"{s} {stage(s)}" for s in sec if s not in ("report", "total"))
    verdict = "within" if result["within_target"] else "NOT within"
    return (f"{result['repeats']} runs, medians, range in brackets, {result['cpus']} cores, "
            f"load {result['load_average_1min']:.1f}: {chapters}, report {stage('report')} with "
            f"{result['figures']} figures, total {stage('total')}: {verdict} the "
            f"{result['target_seconds']:.0f} s target.")


def main() -> None:
    from rotoruq.study.cmd_reproduce import CHAPTERS

    ap = argparse.ArgumentParser()
    ap.add_argument("--summary", default=None, metavar="JSON",
                    help="print README's sentence for a saved result and exit")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default=None, help="keep the results here (default: temporary)")
    ap.add_argument("--chapters", nargs="+", default=list(CHAPTERS), choices=list(CHAPTERS))
    ap.add_argument("--repeats", type=int, default=1,
                    help="fresh reproductions in a row (medians and ranges are printed)")
    ap.add_argument("--json", default=None, help="also write the JSON to this file")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    out_root = args.out or tempfile.mkdtemp(prefix="rotoruq-reproduce-")
    runs = [run_once(os.path.join(out_root, f"run{k + 1}") if args.repeats > 1 else out_root,
                     args.chapters, args.quick) for k in range(args.repeats)]
    stages = list(runs[0]["seconds"])
    result: dict = {
        "quick": args.quick, "cpus": os.cpu_count(), "repeats": args.repeats,
        "load_average_1min": round(os.getloadavg()[0], 2),
        "seconds": {s: float(np.median([r["seconds"][s] for r in runs])) for s in stages},
        "range": {s: [min(r["seconds"][s] for r in runs), max(r["seconds"][s] for r in runs)]
                  for s in stages},
        "figures": runs[-1]["figures"],
        "errors": {k: v for r in runs for k, v in r["errors"].items()},
    }
    result["total_seconds"] = result["seconds"]["total"]
    result["target_seconds"] = TARGET_SECONDS
    result["within_target"] = result["total_seconds"] < TARGET_SECONDS and not result["errors"]
    result["out"] = out_root
    text = json.dumps(result, indent=1)
    print(text)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")


if __name__ == "__main__":
    main()
