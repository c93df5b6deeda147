"""CPU seconds of the GP emulator fits inside the chapters of `rotoruq reproduce`, two source
trees alternating, and whether their saved results are the same bits (issue 34).

Each run is one chapter in a fresh Python process with ``PYTHONPATH`` at one tree's ``src``
(imports and numba cache loads included; run each tree once beforehand so that its numba
cache is warm). The chapter's CPU seconds are the child process's user + system time; the
GP fits' are the CPU seconds it spent inside ``GaussianProcess.fit`` (every emulator fit of
the chapter: each Bayes step's emulator, the held-out chapter's discrepancy emulators).
The trees run in turn (before, after; the next round after, before), so a change of load
hits both alike; CPU time, not wall time, because the machine may be shared: the load
(``/proc/loadavg``) is recorded before each run and still inflates CPU seconds
(shared caches and cores).

``same_bits`` compares the two trees' outputs of each chapter file by file under
``steps/``: every array (``.npy``), table (``.csv``) and chain file byte for byte, and each
``result.json`` without the entries that name the code (its version, identity and files'
hashes, the fingerprint and checksum derived from them) and the seconds a step took.

    python benchmarks/gp_fit_chapters.py --before /tmp/gp-before/src \
        --json benchmarks/results/gp_fit_chapters.json
    python benchmarks/gp_fit_chapters.py --summary benchmarks/results/gp_fit_chapters.json

(``git worktree add /tmp/gp-before <commit>`` makes the tree to compare against.)
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
from pathlib import Path

from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_and_save, print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)

CHAPTERS = ("validation", "experiment", "heldout")
HERE = Path(__file__).resolve().parent
#: result.json entries that depend on the code or the clock, not on the numbers
CODE_KEYS = {("checksum",), ("fingerprint",), ("meta", "seconds"), ("meta", "code_version"),
             ("meta", "identity"), ("meta", "code_files")}


def _cpu(who: int) -> float:
    ru = resource.getrusage(who)
    return ru.ru_utime + ru.ru_stime


def child(chapter: str, out: str) -> None:
    """Run one chapter in this process; print the GP fits' CPU seconds as JSON."""
    import numpy as np

    from rotoruq.methods import surrogate
    from rotoruq.study.cmd_reproduce import _chapter

    fits: list[dict] = []
    fit = surrogate.GaussianProcess._fit

    def timed_fit(self, X, Y):
        c0 = time.process_time()
        try:
            return fit(self, X, Y)
        finally:
            fits.append({"n_d_m": [*np.shape(X)[:2], *np.shape(Y)[1:2]],
                         "cpu_seconds": round(time.process_time() - c0, 3)})

    surrogate.GaussianProcess._fit = timed_fit
    _chapter(chapter, Path(out), False)
    print(json.dumps({"fits": fits}))


def run_chapter(chapter: str, src: str, out: Path) -> dict:
    """One chapter with the code of ``src`` in a fresh process."""
    env = dict(os.environ, PYTHONPATH=src)
    load = Path("/proc/loadavg").read_text().split()[:3] if Path("/proc/loadavg").exists() \
        else []
    c0, t0 = _cpu(resource.RUSAGE_CHILDREN), time.perf_counter()
    done = subprocess.run([sys.executable, __file__, "--child", chapter, str(out)], env=env,
                          capture_output=True, text=True, cwd=HERE.parent)
    wall, cpu = time.perf_counter() - t0, _cpu(resource.RUSAGE_CHILDREN) - c0
    if done.returncode != 0:
        raise RuntimeError(f"{chapter} with {src} failed:\n{done.stderr[-3000:]}")
    fits = json.loads(done.stdout.strip().splitlines()[-1])["fits"]
    return {"cpu_seconds": round(cpu, 2), "wall_seconds": round(wall, 2),
            "gp_fit_cpu_seconds": round(sum(f["cpu_seconds"] for f in fits), 3),
            "fits": fits, "load_before": load}


def _strip(doc: dict) -> dict:
    doc = json.loads(json.dumps(doc))
    for path in CODE_KEYS:
        node = doc
        for key in path[:-1]:
            node = node.get(key, {})
        node.pop(path[-1], None)
    return doc


def compare(a: Path, b: Path) -> dict:
    """Files under ``steps/`` of two outputs of one chapter: how many match, which differ."""
    files = sorted({p.relative_to(root) for root in (a, b) for p in root.rglob("*")
                    if p.is_file() and "steps" in p.relative_to(root).parts})
    differ = []
    for rel in files:
        pa, pb = a / rel, b / rel
        if not (pa.is_file() and pb.is_file()):
            differ.append(str(rel))
        elif rel.name == "result.json":
            if _strip(json.loads(pa.read_text())) != _strip(json.loads(pb.read_text())):
                differ.append(str(rel))
        elif pa.read_bytes() != pb.read_bytes():
            differ.append(str(rel))
    return {"files": len(files), "differ": differ}


def summary(result: dict) -> str:
    """The docs' sentence for a saved run."""
    parts = []
    for name, ch in result["chapters"].items():
        b, a = ch["before"], ch["after"]
        parts.append(f"{name} GP fits {b['gp_fit_cpu_seconds']:.2f} -> "
                     f"{a['gp_fit_cpu_seconds']:.2f} CPU-s (chapter {b['cpu_seconds']:.1f} -> "
                     f"{a['cpu_seconds']:.1f})")
    t = result["total"]
    same = "the same bits" if result["same_bits"] else "DIFFERENT results"
    files = sum(c["compare"][0]["files"] for c in result["chapters"].values())
    commits = result.get("commits", {})
    return (f"`python benchmarks/gp_fit_chapters.py` (before = {commits.get('before')}, after = "
            f"{commits.get('after')}; medians of {result['rounds']} alternating round(s), "
            f"load {result['load']}): " + "; ".join(parts)
            + f"; in all GP fits {t['before_gp_fit_cpu_seconds']:.2f} -> "
            f"{t['after_gp_fit_cpu_seconds']:.2f} CPU-s, chapters {t['before_cpu_seconds']:.1f}"
            f" -> {t['after_cpu_seconds']:.1f} CPU-s; {same} in all {files} saved files.")


def _commit(src: str) -> str | None:
    """The commit checked out in the git tree holding ``src`` (None outside git), with
    ``+changes`` when its files differ from it."""
    def git(*a: str) -> str:
        return subprocess.run(["git", "-C", src, *a], capture_output=True, text=True).stdout
    head = git("rev-parse", "--short", "HEAD").strip()
    if not head:
        return None
    return head + ("+changes" if git("status", "--porcelain", "--untracked-files=no").strip()
                   else "")


def _median(xs: list[float]) -> float:
    s = sorted(xs)
    return round(0.5 * (s[(len(s) - 1) // 2] + s[len(s) // 2]), 3)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", help="src folder of the code to compare against")
    ap.add_argument("--after", default=str(HERE.parent / "src"),
                    help="src folder of the code measured (default: this repository's)")
    ap.add_argument("--chapters", nargs="+", default=list(CHAPTERS), choices=CHAPTERS)
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--json", default=None, help="also write the JSON to this file")
    ap.add_argument("--summary", default=None, metavar="JSON",
                    help="print the docs' sentence for a saved run and exit")
    ap.add_argument("--child", nargs=2, metavar=("CHAPTER", "OUT"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    if args.child:
        child(*args.child)
        return
    if not args.before:
        ap.error("--before SRC is required")
    trees = {"before": str(Path(args.before).resolve()), "after": str(Path(args.after).resolve())}
    commits = {w: _commit(src) for w, src in trees.items()}
    result: dict = {"trees": trees, "commits": commits, "rounds": args.rounds,
                    "cpus": os.cpu_count(), "chapters": {}}
    runs: dict = {c: {"before": [], "after": []} for c in args.chapters}
    same = True
    with tempfile.TemporaryDirectory(prefix="rotoruq-gpfit-") as tmp:
        for r in range(args.rounds):
            for chapter in args.chapters:
                order = ("before", "after") if r % 2 == 0 else ("after", "before")
                outs = {}
                for which in order:
                    outs[which] = Path(tmp, f"{which}{r}")
                    runs[chapter][which].append(run_chapter(chapter, trees[which],
                                                            outs[which]))
                cmp = compare(outs["before"] / chapter, outs["after"] / chapter)
                runs[chapter].setdefault("compare", []).append(cmp)
                same = same and not cmp["differ"]
    for chapter, rr in runs.items():
        ch = {}
        for which in ("before", "after"):
            ch[which] = {k: _median([x[k] for x in rr[which]])
                         for k in ("cpu_seconds", "wall_seconds", "gp_fit_cpu_seconds")}
            ch[which]["runs"] = rr[which]
        ch["compare"] = rr["compare"]
        result["chapters"][chapter] = ch
    result["total"] = {f"{w}_{k}": round(sum(c[w][k] for c in result["chapters"].values()), 3)
                       for w in ("before", "after") for k in ("cpu_seconds",
                                                              "gp_fit_cpu_seconds")}
    result["same_bits"] = same
    result["provenance"] = provenance(modules=["rotoruq.methods.surrogate"])
    result["load"] = result["provenance"].get("load")
    print_and_save(result, args.json)


if __name__ == "__main__":
    main()
