"""Accuracy of main and total Sobol' indices on the Ishigami function (a = 7, b = 0.1).

For N = 256, 1024, 4096 base samples (N (d + 2) = 5N model evaluations for every library) and
several seeds, prints JSON with the mean over seeds of the max absolute error of the main and
total indices for rotoruq (default estimator, and each alternative), SALib
(``SALib.sample.sobol`` + ``SALib.analyze.sobol``, no second order) and
``scipy.stats.sobol_indices``. With the same seed rotoruq and scipy draw the very same
scrambled Sobol' design (paired comparison); SALib draws its own. ``*_se`` are standard errors
of the seed averages. ``ours_vs_best`` is our error divided by the best baseline's
(<= 1 means no worse).

Run: python benchmarks/sobol_accuracy.py [--seeds 30]
"""

from __future__ import annotations

import argparse
import json
import time
import warnings

import numpy as np
from scipy import stats

import rotoruq as rq
from rotoruq.methods.sensitivity import ESTIMATORS, sobol_indices

A, B = 7.0, 0.1


def ishigami(x):
    return np.sin(x[:, 0]) + A * np.sin(x[:, 1]) ** 2 + B * x[:, 2] ** 4 * np.sin(x[:, 0])


def exact():
    v = A**2 / 8 + B * np.pi**4 / 5 + B**2 * np.pi**8 / 18 + 0.5
    v1 = 0.5 * (1 + B * np.pi**4 / 5) ** 2
    v2 = A**2 / 8
    v13 = 8 * B**2 * np.pi**8 / 225
    return np.array([v1, v2, 0.0]) / v, np.array([v1 + v13, v2, v13]) / v


class Counter:
    def __init__(self, f):
        self.f, self.n = f, 0

    count_axis = 0  # scipy passes points as columns (d, n)

    def __call__(self, x):
        self.n += x.shape[self.count_axis]
        return self.f(x)


def run_ours(n, seed, estimator):
    space = rq.ParameterSpace({k: rq.Uniform(-np.pi, np.pi) for k in ("x1", "x2", "x3")})
    f = Counter(ishigami)
    model = rq.FunctionModel(f, space.names, ["y"])
    r = sobol_indices(model, space, n, estimator=estimator, seed=seed, n_bootstrap=0)
    return r.main[0], r.total[0], f.n


def run_salib(n, seed):
    from SALib.analyze import sobol as sa
    from SALib.sample import sobol as ss

    problem = {"num_vars": 3, "names": ["x1", "x2", "x3"], "bounds": [[-np.pi, np.pi]] * 3}
    x = ss.sample(problem, n, calc_second_order=False, scramble=True, seed=seed)
    f = Counter(ishigami)
    y = f(x)
    r = sa.analyze(problem, y, calc_second_order=False, num_resamples=2, seed=seed)
    return np.asarray(r["S1"]), np.asarray(r["ST"]), f.n


def run_scipy(n, seed):
    f = Counter(lambda xt: ishigami(xt.T))
    f.count_axis = 1
    dists = [stats.uniform(loc=-np.pi, scale=2 * np.pi)] * 3
    r = stats.sobol_indices(func=f, n=n, dists=dists, rng=np.random.default_rng(seed))
    return np.asarray(r.first_order), np.asarray(r.total_order), f.n


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=100)
    args = ap.parse_args()
    s_ex, st_ex = exact()
    runners = {f"rotoruq_{e}": (lambda n, s, e=e: run_ours(n, s, e)) for e in ESTIMATORS}
    runners["salib"] = run_salib
    runners["scipy"] = run_scipy
    out = {
        "function": "ishigami(a=7, b=0.1)",
        "seeds": args.seeds,
        "default": "rotoruq_hybrid",
        "results": {},
    }
    t0 = time.perf_counter()
    for n in (256, 1024, 4096):
        row = {}
        for name, run in runners.items():
            e_main, e_tot, evals = [], [], set()
            for seed in range(args.seeds):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    s, st, k = run(n, seed)
                e_main.append(np.max(np.abs(s - s_ex)))
                e_tot.append(np.max(np.abs(st - st_ex)))
                evals.add(k)
            row[name] = {
                "main_max_abs_err": float(np.mean(e_main)),
                "total_max_abs_err": float(np.mean(e_tot)),
                "main_se": float(np.std(e_main) / np.sqrt(len(e_main))),
                "total_se": float(np.std(e_tot) / np.sqrt(len(e_tot))),
                "evaluations": sorted(evals),
            }
        best_main = min(row[b]["main_max_abs_err"] for b in ("salib", "scipy"))
        best_tot = min(row[b]["total_max_abs_err"] for b in ("salib", "scipy"))
        ours = row[out["default"]]
        row["ours_vs_best"] = {
            "main": ours["main_max_abs_err"] / best_main,
            "total": ours["total_max_abs_err"] / best_tot,
        }
        out["results"][str(n)] = row
    out["seconds"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
