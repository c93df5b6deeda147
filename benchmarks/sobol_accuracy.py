"""Accuracy of main and total Sobol' indices: rotoruq against SALib and scipy, many seeds.

Functions: Ishigami (a = 7, b = 0.1; the function the default estimator was first chosen on),
the 8-D Sobol' G function with a = (0, 1, 4.5, 9, 99, 99, 99, 99) (its small-total rule was
chosen after looking at it) and a 6-D G function with a = (0, 0.5, 3, 9, 20, 99), run on nothing
before this benchmark. Exact indices are closed-form for all three.

Held equal: N base samples and N (d + 2) model evaluations for every library; rotoruq and
scipy.stats.sobol_indices draw the very same scrambled Sobol' design from the same seed (a
paired comparison); SALib draws its own (SALib.sample.sobol, scrambled, no second order).

Per seed the error is the largest absolute error over all main AND total indices (the issue's
figure). Reported per N over all seeds: mean (with its standard error), median, 90th percentile
and maximum; the mean of the main-only and total-only largest errors; and the paired mean
difference rotoruq - scipy with its standard error. ``ours_vs_best`` divides our mean by the
best peer's (<= 1: no worse).

Why a 3-seed median and a 100-seed mean disagreed (issue 13): the largest error per seed is
heavy-tailed (its 90th percentile is about twice its median), so a median over 3 seeds swings
by a factor of 2 between seed triples; ``three_seed_medians`` shows the spread of that statistic
over consecutive seed triples for ours and SALib at N = 1024 on Ishigami. The old benchmark
also averaged the main and total errors separately, a smaller figure than the per-seed maximum
over both.

Bootstrap cost (issue 12): seconds of ``sobol_from_design`` without and with the default
bootstrap (100 resamples) at N = 4096 on Ishigami outputs, and of SALib's ``analyze`` with its
default 100 resamples on the same number of outputs (medians of 5 runs).

Run: python benchmarks/sobol_accuracy.py [--seeds 100]
"""

from __future__ import annotations

import argparse
import json
import time
import warnings

import numpy as np
from scipy import stats

import rotoruq as rq
from rotoruq.methods.sensitivity import ESTIMATORS, sobol_from_design, sobol_indices

A, B = 7.0, 0.1
NS = (256, 1024, 4096)


def ishigami(x):
    return np.sin(x[:, 0]) + A * np.sin(x[:, 1]) ** 2 + B * x[:, 2] ** 4 * np.sin(x[:, 0])


def ishigami_exact():
    v = A**2 / 8 + B * np.pi**4 / 5 + B**2 * np.pi**8 / 18 + 0.5
    v1 = 0.5 * (1 + B * np.pi**4 / 5) ** 2
    v2 = A**2 / 8
    v13 = 8 * B**2 * np.pi**8 / 225
    return np.array([v1, v2, 0.0]) / v, np.array([v1 + v13, v2, v13]) / v


def g_function(a):
    a = np.asarray(a, dtype=float)

    def f(x):
        return np.prod((np.abs(4 * x - 2) + a) / (1 + a), axis=1)

    vi = 1 / (3 * (1 + a) ** 2)
    v = np.prod(1 + vi) - 1
    return f, (vi / v, vi * np.prod(1 + vi) / (1 + vi) / v)


G8 = g_function([0, 1, 4.5, 9, 99, 99, 99, 99])
G6 = g_function([0, 0.5, 3, 9, 20, 99])
PROBLEMS = {
    "ishigami": (ishigami, [(-np.pi, np.pi)] * 3, ishigami_exact()),
    "g8": (G8[0], [(0.0, 1.0)] * 8, G8[1]),
    "g6_untuned": (G6[0], [(0.0, 1.0)] * 6, G6[1]),
}


def run_ours(f, bounds, n, seed, estimator):
    space = rq.ParameterSpace({f"x{i}": rq.Uniform(lo, hi) for i, (lo, hi) in enumerate(bounds)})
    model = rq.FunctionModel(f, space.names, ["y"])
    r = sobol_indices(model, space, n, estimator=estimator, seed=seed, n_bootstrap=0)
    return r.main[0], r.total[0]


def run_salib(f, bounds, n, seed):
    from SALib.analyze import sobol as sa
    from SALib.sample import sobol as ss

    d = len(bounds)
    problem = {"num_vars": d, "names": [f"x{i}" for i in range(d)], "bounds": bounds}
    x = ss.sample(problem, n, calc_second_order=False, scramble=True, seed=seed)
    r = sa.analyze(problem, f(x), calc_second_order=False, num_resamples=2, seed=seed)
    return np.asarray(r["S1"]), np.asarray(r["ST"])


def run_scipy(f, bounds, n, seed):
    dists = [stats.uniform(loc=lo, scale=hi - lo) for lo, hi in bounds]
    r = stats.sobol_indices(func=lambda xt: f(xt.T), n=n, dists=dists,
                            rng=np.random.default_rng(seed))
    return np.asarray(r.first_order), np.asarray(r.total_order)


def summary(err, err_main, err_total):
    e = np.asarray(err)
    return {
        "mean": float(e.mean()), "mean_se": float(e.std(ddof=1) / np.sqrt(e.size)),
        "median": float(np.median(e)), "p90": float(np.quantile(e, 0.9)),
        "max": float(e.max()), "main_only_mean": float(np.mean(err_main)),
        "total_only_mean": float(np.mean(err_total)),
    }


def accuracy(seeds):
    runners = {f"rotoruq_{e}": (lambda f, b, n, s, e=e: run_ours(f, b, n, s, e))
               for e in ESTIMATORS}
    runners["salib"] = run_salib
    runners["scipy"] = run_scipy
    out, per_seed = {}, {}
    for pname, (f, bounds, (s_ex, t_ex)) in PROBLEMS.items():
        out[pname] = {}
        for n in NS:
            errs = {k: ([], [], []) for k in runners}
            for seed in range(seeds):
                for name, run in runners.items():
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        s, st = run(f, bounds, n, seed)
                    em, et = np.abs(s - s_ex).max(), np.abs(st - t_ex).max()
                    errs[name][0].append(max(em, et))
                    errs[name][1].append(em)
                    errs[name][2].append(et)
            row = {k: summary(*v) for k, v in errs.items()}
            ours = np.array(errs["rotoruq_hybrid"][0])
            diff = ours - np.array(errs["scipy"][0])
            row["paired_ours_minus_scipy"] = {
                "mean": float(diff.mean()), "se": float(diff.std(ddof=1) / np.sqrt(diff.size))}
            best = min(row["salib"]["mean"], row["scipy"]["mean"])
            row["ours_vs_best"] = row["rotoruq_hybrid"]["mean"] / best
            out[pname][str(n)] = row
            per_seed[(pname, n)] = (ours, np.array(errs["salib"][0]))
    return out, per_seed


def three_seed_medians(per_seed):
    ours, salib = per_seed[("ishigami", 1024)]
    k = ours.size // 3
    mo = np.median(ours[: 3 * k].reshape(k, 3), axis=1)
    ms = np.median(salib[: 3 * k].reshape(k, 3), axis=1)
    return {"triples": k, "ours_min_max": [float(mo.min()), float(mo.max())],
            "salib_min_max": [float(ms.min()), float(ms.max())],
            "fraction_of_triples_ours_worse": float(np.mean(mo > ms))}


def bootstrap_cost(repeats=5, n=4096):
    f, bounds = PROBLEMS["ishigami"][0], PROBLEMS["ishigami"][1]
    space = rq.ParameterSpace({f"x{i}": rq.Uniform(lo, hi) for i, (lo, hi) in enumerate(bounds)})
    from rotoruq.methods.sensitivity import pick_freeze_design

    y = f(pick_freeze_design(space, n, seed=0))

    def med(fn):
        ts = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn()
            ts.append(time.perf_counter() - t0)
        return float(np.median(ts))

    t0 = med(lambda: sobol_from_design(y, 3, n_bootstrap=0, seed=0))
    t1 = med(lambda: sobol_from_design(y, 3, seed=0))
    from SALib.analyze import sobol as sa

    problem = {"num_vars": 3, "names": ["x0", "x1", "x2"], "bounds": bounds}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ts = med(lambda: sa.analyze(problem, y, calc_second_order=False, seed=0))
    return {"n": n, "analysis_without_bootstrap_s": t0, "analysis_with_default_bootstrap_s": t1,
            "bootstrap_over_analysis": (t1 - t0) / t0 if t0 > 0 else None,
            "salib_analyze_default_s": ts, "ours_with_bootstrap_over_salib": t1 / ts}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=100)
    args = ap.parse_args()
    t0 = time.perf_counter()
    acc, per_seed = accuracy(args.seeds)
    out = {
        "seeds": args.seeds,
        "default": "rotoruq_hybrid",
        "metric": "per seed: max abs error over all main and total indices",
        "results": acc,
        "ours_vs_best_per_function_and_n": {
            p: {n: round(r["ours_vs_best"], 3) for n, r in rows.items()}
            for p, rows in acc.items()},
        "three_seed_medians_ishigami_1024": three_seed_medians(per_seed),
        "bootstrap_cost": bootstrap_cost(),
    }
    out["seconds"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
