"""Same seed, same bits at any thread count (issue 35): each bundled study, and a calibration
with a 300-point GP emulator and its variance in the likelihood (the case that broke: LAPACK's
Cholesky, triangular inverse and LU solve give other last bits on two OpenBLAS threads), run
through ``rotoruq run`` in fresh processes with 1, 2 and 4 threads (``NUMBA_NUM_THREADS``,
``OMP_NUM_THREADS``, ``OPENBLAS_NUM_THREADS``, ``MKL_NUM_THREADS`` set before the process
starts); every saved array (``steps/*/*.npy``) of a run is compared bit for bit with the
1-thread run's.

Prints JSON: per study, the arrays compared, those that differ (with the largest absolute
difference) and the wall time of each run. Run: python benchmarks/thread_determinism.py
[--out benchmarks/results/thread_determinism.json] [--full] [--threads 1 2 4]
[--studies quick validation ...]. ``--quick`` runs (the default) are what CI runs;
``--full`` runs the studies at their own sizes. ``--summary FILE`` prints the docs' paragraph
from a saved JSON.
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

# the calibration that differed between 1 and 2 BLAS threads before issue 35 (max chain
# difference 0.099 here): a 300-point GP emulator with its variance in the likelihood
GP_STUDY = """\
[study]
name = "gp300"
seed = 7

[model]
function = "text_book"
responses = ["f", "c1", "c2"]

[parameters.a]
distribution = "uniform"
lower = 0.0
upper = 2.0

[parameters.b]
distribution = "uniform"
lower = 0.0
upper = 2.0

[parameters.c]
distribution = "uniform"
lower = 0.0
upper = 2.0

[data.obs]
f = [0.3]
c1 = [0.5]
c2 = [0.8]

[[steps]]
name = "bayes"
type = "bayes_calibration"
emulator = "gp"
n_emulator_samples = 300
emulator_variance = true
noise_std = 0.05
n_samples = 400
burn_in = 100
"""

#: the bundled studies that run without MBDyn (forward_flight without its MBDyn step, which
#: the runs here skip), and those that need it (tests/test_reproducible_studies.py replays
#: their MBDyn runs from the first run's store)
STUDIES = ("quick", "validation", "experiment", "heldout", "multifidelity_rotor",
           "forward_flight")
MBDYN_STUDIES = ("mbdyn_rigid", "mbdyn_elastic", "mbdyn_multifidelity")
THREAD_VARIABLES = ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                    "MKL_NUM_THREADS")


def run_at(study: str | Path, threads: int, out: Path, *, quick: bool = True,
           timeout: float = 3600.0, env: dict[str, str] | None = None) -> float:
    """Run ``study`` (a file or a bundled study's name) through ``rotoruq run`` in a fresh
    process with ``threads`` threads for numba and BLAS (in ``env``, default this process's
    environment); returns its wall time [s]. Raises RuntimeError with the run's stderr if it
    fails."""
    env = {**(os.environ if env is None else env), **{k: str(threads)
                                                      for k in THREAD_VARIABLES}}
    cmd = [sys.executable, "-m", "rotoruq.study.cli", "-q", "run", str(study), "--out",
           str(out), "--no-report", *(["--quick"] if quick else [])]
    t0 = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} at {threads} threads failed "
                           f"({done.returncode}):\n{done.stderr[-3000:]}")
    return time.perf_counter() - t0


def differing(a: Path, b: Path) -> tuple[int, dict[str, float]]:
    """Compare every saved array of results folder ``a`` with ``b``'s bit for bit: (number of
    arrays compared, {array path: largest absolute difference (inf: shape or dtype differ,
    nan: not numbers)} for those that differ)."""
    files = sorted(p.relative_to(a) for p in (a / "steps").rglob("*.npy"))
    other = sorted(p.relative_to(b) for p in (b / "steps").rglob("*.npy"))
    out: dict[str, float] = {str(p): float("inf") for p in set(files) ^ set(other)}
    for rel in sorted(set(files) & set(other)):
        x, y = np.load(a / rel, allow_pickle=False), np.load(b / rel, allow_pickle=False)
        if x.shape != y.shape or x.dtype != y.dtype:
            out[str(rel)] = float("inf")
        elif x.tobytes() != y.tobytes():
            out[str(rel)] = (float(np.nanmax(np.abs(x - y))) if x.dtype.kind == "f"
                             else float("nan"))
    return len(files), out


def measure(study: str | Path, threads: tuple[int, ...], root: Path, *, quick: bool) -> dict:
    """Run ``study`` at each thread count and compare each run with the first's arrays. A
    step that needs MBDyn (``needs = ["mbdyn"]``) is skipped: no MBDyn is found."""
    name = Path(study).stem if str(study).endswith(".toml") else str(study)
    env = {k: v for k, v in os.environ.items() if k != "MBDYN"}
    env["MBDYN_PREFIX"] = str(root / "no-mbdyn")
    runs, seconds = {}, {}
    for t in threads:
        runs[t] = root / f"{name}-{t}"
        seconds[str(t)] = round(run_at(study, t, runs[t], quick=quick, env=env), 2)
    first = threads[0]
    compared, diffs = 0, {}
    for t in threads[1:]:
        n, d = differing(runs[first], runs[t])
        compared = max(compared, n)
        if d:
            diffs[f"{first} vs {t}"] = d
    return {"arrays": compared, "identical": not diffs, "differing": diffs,
            "seconds": seconds}


def summary(out: dict) -> str:
    """The docs' paragraph: per study, the arrays compared and whether every thread count gave
    the same bits, with the runs' wall times."""
    parts = []
    for name, r in out["studies"].items():
        secs = " / ".join(f"{r['seconds'][str(t)]:.0f} s" for t in out["threads"])
        verdict = "all bit for bit equal" if r["identical"] else (
            "DIFFER: " + "; ".join(f"{k}: {len(v)} arrays" for k, v in r["differing"].items()))
        parts.append(f"{name}: {r['arrays']} arrays, {verdict} ({secs})")
    threads = ", ".join(map(str, out["threads"]))
    size = "--quick sizes (gp300 at its own)" if out["quick"] else "their own sizes"
    missing = [s for s in ("gp300", *STUDIES) if s not in out["studies"]]
    left = (f" Not in this run (CI checks them at 1 and 2 threads): {', '.join(missing)}."
            if missing else "")
    return (f"From `benchmarks/results/thread_determinism.json` (threads {threads} for numba "
            f"and BLAS, studies at {size}; wall times at each thread count on a shared "
            f"2-core machine): {'; '.join(parts)}. All identical: {out['all_identical']}."
            + left)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path)
    ap.add_argument("--full", action="store_true", help="the studies at their own sizes")
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2, 4])
    ap.add_argument("--studies", nargs="+", default=["gp300", *STUDIES])
    ap.add_argument("--summary", help="print the docs' paragraph from this JSON file and exit")
    args = ap.parse_args()
    from _summary import print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)

    if print_saved_summary(args.summary, summary):
        return
    from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)

    result: dict = {"threads": args.threads, "quick": not args.full, "studies": {}}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for s in args.studies:
            study: str | Path = s
            if s == "gp300":
                study = root / "gp300.toml"
                study.write_text(GP_STUDY)
            result["studies"][s] = measure(study, tuple(args.threads), root,  # gp300: CI size
                                           quick=not args.full and s != "gp300")
            print(s, json.dumps(result["studies"][s]), file=sys.stderr, flush=True)
    result["all_identical"] = all(v["identical"] for v in result["studies"].values())
    result["provenance"] = provenance(modules=["rotoruq.study.runner",
                                               "rotoruq.methods.surrogate"])
    text = json.dumps(result, indent=1)
    if args.out:
        args.out.write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
