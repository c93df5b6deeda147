"""Wall time of `rotoruq reproduce` per chapter (target, issue 12: the whole study and its
report in < 30 s on 2 cores, each figure drawn once). Prints JSON: seconds per chapter (run
at once, ``--jobs``), for the report, total, the rebuild of an unchanged report (figures from
the cache; also ``rebuild_cli``: ``rotoruq report`` in a process of its own, wall and CPU), the
report phase had the figures not been drawn as each chapter ended (``report_fresh``: the same
report into a fresh folder, wall and CPU, beside reproduce's ``report`` and ``report_cpu``),
the number of figures, and whether the total is within the target.
Run it once first so the numba caches are warm; compare versions by alternating runs.

    python benchmarks/reproduce_time.py --repeats 3 --json benchmarks/results/reproduce_time.json

    python benchmarks/reproduce_time.py            # full study
    python benchmarks/reproduce_time.py --quick    # the reduced CI version
    python benchmarks/reproduce_time.py --summary benchmarks/results/reproduce_time.json
                                                   # README's sentence from a saved run

After the runs, the report of the last run is drawn again ``--report-repeats`` times with one
process and with a figure worker (``write_report(workers=1)`` against ``workers=2``,
alternated, into fresh folders): the same results, figures and tables on both sides, so the
ratio is what the second process buys on this machine.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
import traceback

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_and_save, print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)

TARGET_SECONDS = 30.0


def run_once(out_root: str, chapters: list[str], quick: bool, jobs: int | None) -> dict:
    """One reproduction into the empty folder ``out_root`` as ``rotoruq reproduce`` runs it
    (the chapters at once on ``jobs`` processes): seconds per chapter, until the last chapter
    ended (``wall``), for the report, in all (``total``), and for the report rebuilt from
    the same results (``rebuild``: its figures from the cache)."""
    from rotoruq.study.cmd_report import write
    from rotoruq.study.cmd_reproduce import reproduce

    result: dict = {"seconds": {}, "errors": {}}
    t_all = time.perf_counter()
    try:
        if chapters == ["all"] or len(chapters) > 1:
            got = reproduce("all", out_root, quick, jobs)
        else:
            got = reproduce(chapters[0], out_root, quick, jobs)
        result["seconds"] = {k: round(v, 2) for k, v in got["seconds"].items()}
    except Exception as exc:  # noqa: BLE001 - report the failure
        result["errors"]["reproduce"] = f"{type(exc).__name__}: {exc}"
        traceback.print_exc()
    result["seconds"]["total"] = round(time.perf_counter() - t_all, 2)
    dirs = [os.path.join(out_root, n) for n in sorted(os.listdir(out_root))
            if os.path.isfile(os.path.join(out_root, n, "study.json"))]
    result["dirs"] = dirs   # the studies the report was written from (not in the JSON)
    result["figures"] = len([f for f in os.listdir(os.path.join(out_root, "report", "figures"))
                             if f.endswith(".png")]) if dirs else 0
    if dirs:  # `rotoruq report` of the same results, as a user rebuilds it
        t0 = time.perf_counter()
        write(dirs, os.path.join(out_root, "report"))
        result["seconds"]["rebuild"] = round(time.perf_counter() - t0, 2)
        # the same in a process of its own, as a user types it (imports included)
        t0, c0 = time.perf_counter(), _children_cpu()
        subprocess.run([sys.executable, "-m", "rotoruq.study.cli", "report", *dirs, "--out",
                        os.path.join(out_root, "report"), "-q"], check=True)
        result["seconds"]["rebuild_cli"] = round(time.perf_counter() - t0, 2)
        result["seconds"]["rebuild_cli_cpu"] = round(_children_cpu() - c0, 2)
        # the report phase had reproduce not drawn the figures as each chapter ended: the
        # same report into a fresh folder (every figure drawn, with its figure worker), in
        # this process as reproduce writes it
        t0, c0 = time.perf_counter(), _cpu()
        write(dirs, os.path.join(out_root, "report_fresh"))
        result["seconds"]["report_fresh"] = round(time.perf_counter() - t0, 2)
        result["seconds"]["report_fresh_cpu"] = round(_cpu() - c0, 2)
    return result


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime + _children_cpu()


def report_workers(dirs: list[str], repeats: int) -> dict:
    """Seconds to write the report of ``dirs`` with 1 and 2 drawing processes, alternated."""
    from rotoruq.report.html import write_report

    times: dict[int, list[float]] = {1: [], 2: []}
    for _ in range(repeats):
        for workers in (1, 2):
            with tempfile.TemporaryDirectory() as out:
                t0 = time.perf_counter()
                write_report(dirs, os.path.join(out, "report"), workers=workers)
                times[workers].append(time.perf_counter() - t0)
    med = {w: float(np.median(t)) for w, t in times.items()}
    return {"repeats": repeats, "seconds_1_process": times[1], "seconds_2_processes": times[2],
            "median_1_process": med[1], "median_2_processes": med[2],
            "speedup": med[1] / med[2]}


def summary(result: dict) -> str:
    """README's sentence for a saved result."""
    sec, rng = result["seconds"], result["range"]

    def stage(s: str) -> str:
        return f"{sec[s]:.1f} ({rng[s][0]:.1f}-{rng[s][1]:.1f}) s"

    chapters = ", ".join(f"{s} {stage(s)}" for s in sec
                         if s not in ("report", "total", "wall") and not s.startswith(
                             ("figures", "rebuild", "report_")))
    verdict = "within" if result["within_target"] else "NOT within"
    par = (f" (at once on {result['jobs']} processes: the last ended after {stage('wall')})"
           if "wall" in sec and result.get("jobs", 1) > 1 else "")
    if "figures_after_chapters" in sec:  # each chapter's figures drawn as it ended
        par += (", its figures drawn meanwhile (waited "
                f"{stage('figures_after_chapters')} after the last chapter)")
    text = (f"{result['repeats']} runs, medians, range in brackets, {result['cpus']} cores, "
            f"load {result['load_average_1min']:.1f}: {chapters}{par}, report "
            f"{stage('report')} with {result['figures']} figures, total {stage('total')}: "
            f"{verdict} the {result['target_seconds']:.0f} s target.")
    if "report_fresh" in sec:
        text += (f" Had the figures not been drawn ahead, the report would have taken "
                 f"{stage('report_fresh')} ({sec['report_fresh_cpu']:.1f} CPU-s against "
                 f"{sec['report_cpu']:.1f}).")
    if "rebuild" in sec:
        text += f" The report of unchanged results rebuilt in {stage('rebuild')}"
        text += (f" ({stage('rebuild_cli')} as `rotoruq report` in a process of its own, "
                 f"{sec['rebuild_cli_cpu']:.1f} CPU-s)." if "rebuild_cli" in sec else ".")
    if w := result.get("report_workers"):
        text += (f" The report alone, {w['repeats']} alternated runs: "
                 f"{w['median_1_process']:.2f} s drawing in one process, "
                 f"{w['median_2_processes']:.2f} s with a figure worker "
                 f"({w['speedup']:.2f}x).")
    return text


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
    ap.add_argument("--jobs", type=int, default=None,
                    help="chapters at once (reproduce --jobs; default one per core)")
    ap.add_argument("--report-repeats", type=int, default=3,
                    help="redraw the last report with 1 and 2 processes this many times each "
                         "(0: skip)")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    out_root = args.out or tempfile.mkdtemp(prefix="rotoruq-reproduce-")
    runs = [run_once(os.path.join(out_root, f"run{k + 1}") if args.repeats > 1 else out_root,
                     args.chapters, args.quick, args.jobs) for k in range(args.repeats)]
    stages = list(runs[0]["seconds"])
    result: dict = {
        "quick": args.quick, "cpus": os.cpu_count(), "repeats": args.repeats,
        "jobs": min(args.jobs or os.cpu_count() or 1, len(args.chapters)),
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
    if args.report_repeats > 0 and runs[-1]["dirs"]:
        result["report_workers"] = report_workers(runs[-1]["dirs"], args.report_repeats)
    result["provenance"] = provenance(modules=["rotoruq.study.cli"])
    print_and_save(result, args.json)


if __name__ == "__main__":
    main()
