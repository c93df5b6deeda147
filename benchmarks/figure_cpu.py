"""CPU seconds of the report's figures and of `rotoruq report` of unchanged results (issue 34:
the rebuild <= 2 s), for this source tree and, with ``--before SRC``, another one (e.g. the
main branch's ``src``), alternated in the same run on the same saved results.

Per tree and repeat, each in a process of its own with ``PYTHONPATH`` at the tree:

- ``draw``: every figure of the studies drawn into an empty figure cache by one process
  (``rotoruq.study.cmd_report.prerender``, as `rotoruq reproduce` draws a chapter's figures),
  CPU-s of the process, imports included;
- ``rebuild``: `rotoruq report` of the same, unchanged results as a user types it, after a
  first report that wrote the page and took every figure from that cache: CPU-s (user +
  system) and wall seconds of the command, and the heavy modules it imported
  (``python -X importtime``, a separate run).

Wall seconds on a loaded machine are not meaningful: compare CPU-s, and read the load
average the JSON records.

    python benchmarks/figure_cpu.py --results /tmp/quick --before /work/main/src \\
        --repeats 2 --json benchmarks/results/figure_cpu.json
    python benchmarks/figure_cpu.py --summary benchmarks/results/figure_cpu.json

``--results``: a folder holding saved studies (``rotoruq reproduce --quick --out DIR``
writes one; the full ``rotoruq reproduce --out DIR`` too: the JSON's ``quick`` says which);
without it the quick reproduction is run first into a temporary folder.

    python benchmarks/figure_cpu.py --results /tmp/full --before /work/main/src \\
        --repeats 1 --json benchmarks/results/figure_cpu_full.json
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_and_save, print_saved_summary  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: Modules a report of unchanged results has no use for.
HEAVY = ("scipy.stats", "scipy.optimize", "numba", "matplotlib")
TARGET_SECONDS = 2.0

_DRAW = """
import sys
from rotoruq.study.cmd_report import prerender
print(sum(prerender(d, sys.argv[1]) for d in sys.argv[2:]))
"""


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _run(tree: str, args: list[str]) -> tuple[float, float, subprocess.CompletedProcess]:
    """(CPU-s, wall s, the process) of ``python args`` with rotoruq from ``tree``."""
    env = dict(os.environ, PYTHONPATH=tree)
    c0, t0 = _children_cpu(), time.perf_counter()
    proc = subprocess.run([sys.executable, *args], env=env, capture_output=True, text=True,
                          check=False)
    wall, cpu = time.perf_counter() - t0, _children_cpu() - c0
    if proc.returncode != 0:
        raise RuntimeError(f"{args[:3]} with {tree} failed:\n{proc.stderr[-2000:]}")
    return cpu, wall, proc


def once(tree: str, dirs: list[str], work: Path, rebuilds: int) -> dict:
    """One measurement of ``tree``: the figures drawn, then `rotoruq report` rebuilt."""
    out = work / "report"
    shutil.rmtree(out, ignore_errors=True)
    cpu, wall, proc = _run(tree, ["-c", _DRAW, str(out), *dirs])
    result = {"draw_cpu": cpu, "draw_wall": wall, "jobs": int(proc.stdout.split()[-1])}
    report = ["-m", "rotoruq", "report", *dirs, "--out", str(out), "-q"]
    _run(tree, report)  # the page written, every figure from the cache
    result["figures"] = len(list((out / "figures").glob("*.png")))
    runs = [_run(tree, report)[:2] for _ in range(rebuilds)]
    result["rebuild_cpu"] = float(np.median([c for c, _ in runs]))
    result["rebuild_wall"] = float(np.median([w for _, w in runs]))
    err = _run(tree, ["-X", "importtime", *report])[2].stderr
    names = set(re.findall(r"^import time:\s+\d+ \|\s+\d+ \| +(\S+)$", err, re.M))
    # a package by itself or any of its submodules (importtime may not list the package)
    result["rebuild_heavy_imports"] = [h for h in HEAVY if any(
        n == h or n.startswith(h + ".") for n in names)]
    return result


def summary(result: dict) -> str:
    """The docs' paragraph for a saved result."""
    trees = result["trees"]
    after = trees["this"]

    def cpu(t: dict, k: str) -> str:
        return f"{t[k]:.2f} ({t['range'][k][0]:.2f}-{t['range'][k][1]:.2f})"

    text = (f"{result['repeats']} alternated runs, medians (range), {result['cpus']} cores, "
            f"load {result['load_average_1min']:.1f} (CPU-s are comparable under load, "
            f"wall seconds are not): the {after['figures']} figures of the "
            f"{'quick' if result.get('quick', True) else 'full'} "
            f"reproduction ({after['jobs']} figure jobs) drawn in one process in "
            f"{cpu(after, 'draw_cpu')} CPU-s; `rotoruq report` of the unchanged results "
            f"rebuilt in {cpu(after, 'rebuild_cpu')} CPU-s "
            f"({after['rebuild_wall']:.2f} s wall), importing "
            f"{', '.join(after['rebuild_heavy_imports']) or 'none of ' + ', '.join(HEAVY)}.")
    if "before" in trees:
        b = trees["before"]
        text += (f" Before ({result['before_label']}): figures {cpu(b, 'draw_cpu')} CPU-s, "
                 f"rebuild {cpu(b, 'rebuild_cpu')} CPU-s ({b['rebuild_wall']:.2f} s wall), "
                 f"importing {', '.join(b['rebuild_heavy_imports']) or 'none of them'}.")
    return text


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--summary", default=None, metavar="JSON",
                    help="print the docs' paragraph for a saved result and exit")
    ap.add_argument("--results", default=None,
                    help="folder of saved studies (default: a fresh quick reproduction)")
    ap.add_argument("--before", default=None, metavar="SRC",
                    help="another source tree's src folder, measured alternately")
    ap.add_argument("--before-label", default="main",
                    help="the other tree's name in the JSON and the summary")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--rebuilds", type=int, default=3,
                    help="`rotoruq report` runs per measurement (their median)")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    this = str(ROOT / "src")
    work = Path(tempfile.mkdtemp(prefix="rotoruq-figure-cpu-"))
    results = args.results
    if results is None:
        results = str(work / "quick")
        _run(this, ["-m", "rotoruq", "reproduce", "all", "--quick", "--out", results, "-q"])
    dirs = sorted(str(p.parent) for p in Path(results).glob("*/study.json"))
    trees = {"this": this} | ({"before": args.before} if args.before else {})
    load0 = os.getloadavg()[0]
    runs: dict[str, list[dict]] = {k: [] for k in trees}
    for _ in range(args.repeats):
        for name, tree in trees.items():
            runs[name].append(once(tree, dirs, work / name, args.rebuilds))
    quick = all(json.loads((Path(d) / "study.json").read_text(encoding="utf-8")).get("quick")
                for d in dirs)
    out: dict = {"quick": quick, "cpus": os.cpu_count(), "repeats": args.repeats,
                 "rebuilds": args.rebuilds, "studies": [Path(d).name for d in dirs],
                 "load_average_1min": round(max(load0, os.getloadavg()[0]), 2),
                 "target_rebuild_seconds": TARGET_SECONDS, "trees": {}}
    if args.before:
        out["before_label"] = args.before_label
    keys = ("draw_cpu", "draw_wall", "rebuild_cpu", "rebuild_wall")
    for name, rs in runs.items():
        t: dict = {k: round(float(np.median([r[k] for r in rs])), 3) for k in keys}
        t["range"] = {k: [round(min(r[k] for r in rs), 3), round(max(r[k] for r in rs), 3)]
                      for k in keys}
        t["runs"] = rs
        for k in ("jobs", "figures", "rebuild_heavy_imports"):
            t[k] = rs[-1][k]
        out["trees"][name] = t
    out["rebuild_cpu_within_target"] = out["trees"]["this"]["rebuild_cpu"] <= TARGET_SECONDS
    out["provenance"] = provenance(modules=["rotoruq.study.cli", "rotoruq.study.cmd_report",
                                            "rotoruq.report.html", "rotoruq.render.figures"])
    shutil.rmtree(work, ignore_errors=True)
    print_and_save(out, args.json)


if __name__ == "__main__":
    main()
