"""Wall time of `rotoruq reproduce` per chapter (target: the whole study in < 10 minutes on
2 cores). Prints JSON: seconds per chapter and for the report, total, and whether the total
is within the target.

    python benchmarks/reproduce_time.py            # full study
    python benchmarks/reproduce_time.py --quick    # the reduced CI version
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
import traceback

TARGET_SECONDS = 600.0


def main() -> None:
    from rotoruq.report.html import write_report
    from rotoruq.study.cmd_reproduce import CHAPTERS, studies_dir
    from rotoruq.study.runner import run_study

    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default=None, help="keep the results here (default: temporary)")
    ap.add_argument("--chapters", nargs="+", default=list(CHAPTERS), choices=list(CHAPTERS))
    args = ap.parse_args()
    out_root = args.out or tempfile.mkdtemp(prefix="rotoruq-reproduce-")
    result: dict = {"quick": args.quick, "cpus": os.cpu_count(), "seconds": {}, "errors": {}}
    t_all = time.perf_counter()
    for name in args.chapters:
        t0 = time.perf_counter()
        try:
            run_study(studies_dir() / CHAPTERS[name], out=os.path.join(out_root, name),
                      quick=args.quick)
        except Exception as exc:  # noqa: BLE001 - report the failure, time the rest
            result["errors"][name] = f"{type(exc).__name__}: {exc}"
            traceback.print_exc()
        result["seconds"][name] = round(time.perf_counter() - t0, 2)
    t0 = time.perf_counter()
    dirs = [os.path.join(out_root, n) for n in args.chapters
            if os.path.isfile(os.path.join(out_root, n, "study.json"))]
    write_report(dirs, os.path.join(out_root, "report"))
    result["seconds"]["report"] = round(time.perf_counter() - t0, 2)
    total = time.perf_counter() - t_all
    result["total_seconds"] = round(total, 2)
    result["target_seconds"] = TARGET_SECONDS
    result["within_target"] = total < TARGET_SECONDS and not result["errors"]
    result["out"] = out_root
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
