"""CPU per evaluation of the compiled GP emulator (the chains' log posterior calls it at every
step), this tree against an earlier commit's ``methods/_gp_mean.py`` in the same process
(issue 34: the correlations by rotoruq's own vectorized exponential, ``methods/_vexp.py``,
and the weighted sum in eight running sums, instead of ``math.exp`` per point and one
running sum).

The earlier commit's module is read with ``git show`` and loaded beside this tree's; both
evaluate the same GP arrays at the same points (the emulator designs of the chapters: 500
training points, 4 or 9 inputs, 2 responses, mean only; 300 points and 4 responses with the
Kriging variance), alternated, CPU seconds by ``time.process_time``. The answers differ in
the last bits (another exponential, another summation order): the JSON records the largest
difference relative to the sum of the absolute terms, the condition of the weighted sum.

    python benchmarks/emulator_eval.py --before c26cd7c --json benchmarks/results/emulator_eval.json
    python benchmarks/emulator_eval.py --summary benchmarks/results/emulator_eval.json
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba as nb
import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_and_save, print_saved_summary  # noqa: E402

from rotoruq.methods._vexp import exp1

ROOT = Path(__file__).resolve().parents[1]
REL = "src/rotoruq/methods/_gp_mean.py"


def _old_module(commit: str, folder: str):
    """``methods/_gp_mean.py`` as of ``commit``, loaded inside its package."""
    src = subprocess.run(["git", "show", f"{commit}:{REL}"], cwd=ROOT, check=True,
                         capture_output=True, text=True).stdout
    path = os.path.join(folder, "_gp_mean_before.py")
    Path(path).write_text(src)
    name = "rotoruq.methods._gp_mean_before"
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


@nb.njit(cache=False)
def _libm_exp(x, out, reps):
    for _ in range(reps):
        for i in range(x.shape[0]):
            out[i] = math.exp(x[i])


@nb.njit(cache=False)
def _own_exp(x, out, reps):
    for _ in range(reps):
        for i in range(x.shape[0]):
            out[i] = exp1(x[i])


def _gp(mod, rng, n: int, d: int, m: int, variance: bool):
    """A GP's arrays for ``mod`` (both modules take the same): weights of both signs and a
    spread of magnitudes, as a near-interpolating fit has."""
    Xs = rng.random((n, d))
    inv_ell = rng.uniform(1.0, 4.0, (m, d))
    alpha = rng.standard_normal((m, n)) * 10.0 ** rng.uniform(0, 3, (m, n))
    bi, _ = mod.basis_terms("reduced_quadratic", d)
    beta = rng.standard_normal((m, bi.size))
    if not variance:
        return mod.gp_pack(np.zeros(d), np.ones(d), Xs, inv_ell, alpha, beta,
                           "reduced_quadratic", "sqexp", np.zeros(m), np.ones(m))
    p = bi.size
    L = np.tril(rng.standard_normal((m, n, n)) * 0.01) + np.eye(n)
    var = (L, rng.standard_normal((m, n, p)) * 0.01,
           np.tril(rng.standard_normal((m, p, p)) * 0.01) + np.eye(p), np.ones(m), np.ones(m))
    return mod.compile_gp(np.zeros(d), np.ones(d), Xs, inv_ell, alpha, beta,
                          "reduced_quadratic", "sqexp", np.zeros(m), np.ones(m), variance=var)


def _time(f, repeats: int) -> tuple[float, object]:
    out = f()  # compiled and warm
    t = time.process_time()
    for _ in range(repeats):
        out = f()
    return (time.process_time() - t) / repeats, out


def measure(commit: str, repeats: int) -> dict:
    from rotoruq.methods import _gp_mean as new

    rng = np.random.default_rng(0)
    pieces: dict[str, dict] = {}
    x = -0.5 * rng.uniform(0.0, 3.0, 512) ** 2
    out = np.empty_like(x)
    reps = 20_000
    t_old = _time(lambda: _libm_exp(x, out, reps), repeats)[0]
    t_new = _time(lambda: _own_exp(x, out, reps), repeats)[0]
    pieces["exp of 512 squared-exponential arguments"] = {
        "before_ns_per_value": round(t_old / (reps * x.size) * 1e9, 3),
        "after_ns_per_value": round(t_new / (reps * x.size) * 1e9, 3)}
    with tempfile.TemporaryDirectory() as tmp:
        old = _old_module(commit, tmp)
        cases = {"mean, 500 points, 4 inputs, 2 responses (experiment stage 1)": (500, 4, 2, False),
                 "mean, 500 points, 9 inputs, 2 responses (experiment stage 2)": (500, 9, 2, False),
                 "mean and variance, 300 points, 4 inputs, 4 responses (held-out)":
                     (300, 4, 4, True)}
        for label, (n, d, m, variance) in cases.items():
            seed = int(rng.integers(2**31))
            packs = [_gp(mod, np.random.default_rng(seed), n, d, m, variance)
                     for mod in (old, new)]
            X = np.random.default_rng(seed + 1).random((4000, d)) * 1.2 - 0.1
            if variance:
                calls = [lambda mod=mod, g=g, X=X: mod.gp_mean_var_batch(X, g)[0]
                         for mod, g in zip((old, new), packs, strict=True)]
            else:
                calls = [lambda mod=mod, g=g, X=X: mod.gp_mean_batch(X, g)
                         for mod, g in zip((old, new), packs, strict=True)]
            t = [0.0, 0.0]
            got = [None, None]
            for _ in range(repeats):  # alternated
                for k in (0, 1):
                    dt, got[k] = _time(calls[k], 1)
                    t[k] += dt
            a, b = np.asarray(got[0]), np.asarray(got[1])
            g = packs[1]
            pack = g.mean_pack if variance else g
            scale = np.abs(pack[4]).sum(1)  # sum |alpha|: the weighted sum's condition
            pieces[label] = {
                "before_us_per_eval": round(t[0] / repeats / X.shape[0] * 1e6, 3),
                "after_us_per_eval": round(t[1] / repeats / X.shape[0] * 1e6, 3),
                "ratio": round(t[0] / t[1], 2),
                "largest_difference_per_sum_abs_weights": float(np.max(np.abs(a - b) / scale)),
            }
    return {"before": commit, "pieces": pieces, "repeats": repeats}


def summary(result: dict) -> str:
    p = result["pieces"]
    e = p.pop("exp of 512 squared-exponential arguments")
    load = result.get("provenance", {}).get("load", ["?"])[0]
    cases = "; ".join(
        f"{k}: {v['before_us_per_eval']:.2f} -> {v['after_us_per_eval']:.2f} us "
        f"({v['ratio']}x, largest difference {v['largest_difference_per_sum_abs_weights']:.1e}"
        " of the sum of |terms|)" for k, v in p.items())
    return (f"`python benchmarks/emulator_eval.py --before {result['before']}` (CPU, "
            f"alternated in one process, load {load}): the exponential "
            f"{e['before_ns_per_value']:.2f} -> {e['after_ns_per_value']:.2f} ns a value; "
            f"an evaluation, {cases}. With the variance, its n^2/2 multiply-adds a response "
            "take most of the time.")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", default="c26cd7c", help="the earlier commit")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", help="also write the JSON here")
    ap.add_argument("--summary", help="print the summary of a saved JSON and exit")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    result = measure(args.before, args.repeats)
    result["provenance"] = provenance(__file__)
    print_and_save(result, args.json)


if __name__ == "__main__":
    main()
