"""Accuracy of main and total Sobol' indices: rotoruq against SALib and scipy, many seeds.

Functions (exact indices in closed form for all), in three groups, as honesty requires:

* looked at while the default estimator was designed: Ishigami (a = 7, b = 0.1), the 8-D
  Sobol' G function a = (0, 1, 4.5, 9, 99, 99, 99, 99), a 6-D G function
  a = (0, 0.5, 3, 9, 20, 99), Ishigami with a = 5, b = 0.5 (where the first rule lost at
  N = 256 and its threshold was raised from 0.1 to 0.2), a 7-D G function
  a = (0.2, 0.8, 2, 6, 30, 60, 99) and a 5-D G function with a = 1 everywhere;
* run for the first time with the final estimator (``fresh``): Ishigami with a = 3, b = 0.3
  and a 10-D G function a = (0, 0.1, 0.3, 1, 3, 10, 30, 99, 99, 99).

Held equal: N base samples and N (d + 2) model evaluations for every side. Two comparisons:

* ``paired``: SALib's and scipy's estimator (the same formula in both libraries: Saltelli 2010
  main, Jansen total, variance of A and B) computed on OUR design and outputs, seed by seed:
  the estimator alone is compared, the design noise cancels, so the standard error is small;
* ``libraries``: SALib (``SALib.sample.sobol`` + ``SALib.analyze.sobol``) and
  ``scipy.stats.sobol_indices`` run end to end on their own scrambled Sobol' designs from the
  same integer seed; unpaired, so its standard error is larger.

Per seed the error is the largest absolute error over all main AND total indices. Reported per
N over all seeds: mean (with its standard error), median, 90th percentile and maximum.
``ratio`` = our mean / the peer's mean with its standard error (paired: from the per-seed
differences; libraries: delta method on the two independent means). <= 1: no worse.

Why a 3-seed median and a 100-seed mean disagreed (issue 13): the largest error per seed is
heavy-tailed (its 90th percentile is about twice its median), so a median over 3 seeds swings
by a factor of 2 between seed triples; ``three_seed_medians`` shows the spread of that statistic
over consecutive seed triples for ours and SALib at N = 1024 on Ishigami.

Interval cost (issue 12): seconds of ``sobol_from_design`` without intervals, with the default
100-draw parametric bootstrap of the term means, and with a classical 100-resample row
bootstrap (resampling counts and one matrix product, what rotoruq did before), at N = 4096 on
Ishigami outputs, and SALib's ``analyze`` with its default 100 resamples on the same outputs
(``--repeats`` interleaved runs, process CPU time, one BLAS thread for every side; the
ratios are medians of the per-run ratios).

Run: python benchmarks/sobol_accuracy.py [--seeds 300] > benchmarks/results/sobol_accuracy.json
``--summary benchmarks/results/sobol_accuracy.json`` prints README's paragraph.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)
from scipy import stats

import rotoruq as rq
from rotoruq.methods.sensitivity import (
    ESTIMATORS,
    _indices,
    _row_terms,
    pick_freeze_design,
    sobol_from_design,
)

NS = (256, 1024, 4096)


def ishigami(a, b):
    def f(x):
        return np.sin(x[:, 0]) + a * np.sin(x[:, 1]) ** 2 + b * x[:, 2] ** 4 * np.sin(x[:, 0])

    v = a**2 / 8 + b * np.pi**4 / 5 + b**2 * np.pi**8 / 18 + 0.5
    v1 = 0.5 * (1 + b * np.pi**4 / 5) ** 2
    v2 = a**2 / 8
    v13 = 8 * b**2 * np.pi**8 / 225
    exact = np.array([v1, v2, 0.0]) / v, np.array([v1 + v13, v2, v13]) / v
    return f, [(-np.pi, np.pi)] * 3, exact


def g_function(a):
    a = np.asarray(a, dtype=float)

    def f(x):
        return np.prod((np.abs(4 * x - 2) + a) / (1 + a), axis=1)

    vi = 1 / (3 * (1 + a) ** 2)
    v = np.prod(1 + vi) - 1
    return f, [(0.0, 1.0)] * a.size, (vi / v, vi * np.prod(1 + vi) / (1 + vi) / v)


PROBLEMS = {
    "ishigami": ("looked_at", ishigami(7.0, 0.1)),
    "g8": ("looked_at", g_function([0, 1, 4.5, 9, 99, 99, 99, 99])),
    "g6": ("looked_at", g_function([0, 0.5, 3, 9, 20, 99])),
    "ishigami_a5_b05": ("looked_at", ishigami(5.0, 0.5)),
    "g7": ("looked_at", g_function([0.2, 0.8, 2, 6, 30, 60, 99])),
    "g5_equal": ("looked_at", g_function([1, 1, 1, 1, 1])),
    "ishigami_a3_b03": ("fresh", ishigami(3.0, 0.3)),
    "g10": ("fresh", g_function([0, 0.1, 0.3, 1, 3, 10, 30, 99, 99, 99])),
}


def space_of(bounds):
    return rq.ParameterSpace({f"x{i}": rq.Uniform(lo, hi) for i, (lo, hi) in enumerate(bounds)})


def peer_estimator(y, d):
    """SALib.analyze.sobol first_order / total_order (= scipy's saltelli_2010) on outputs y."""
    b = y.reshape(d + 2, -1)
    b = b - b.mean()
    fa, fb, fi = b[0], b[1], b[2:]
    var = np.var(np.concatenate([fa, fb]))
    return np.mean(fb * (fi - fa), axis=1) / var, 0.5 * np.mean((fa - fi) ** 2, axis=1) / var


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


def error_stats(err):
    e = np.asarray(err)
    return {"mean": float(e.mean()), "mean_se": float(e.std(ddof=1) / np.sqrt(e.size)),
            "median": float(np.median(e)), "p90": float(np.quantile(e, 0.9)),
            "max": float(e.max())}


def paired_ratio(ours, peer):
    r = ours.mean() / peer.mean()
    se = np.std(ours - r * peer, ddof=1) / np.sqrt(ours.size) / peer.mean()
    return {"ratio": round(float(r), 4), "se": round(float(se), 4)}


def unpaired_ratio(ours, peer):
    r = ours.mean() / peer.mean()
    rel = np.hypot(ours.std(ddof=1) / ours.mean(), peer.std(ddof=1) / peer.mean())
    return {"ratio": round(float(r), 4), "se": round(float(r * rel / np.sqrt(ours.size)), 4)}


def accuracy(seeds):
    out, per_seed = {}, {}
    for pname, (group, (f, bounds, (s_ex, t_ex))) in PROBLEMS.items():
        d = len(bounds)
        space = space_of(bounds)
        out[pname] = {"group": group, "dim": d}
        for n in NS:
            errs = {k: [] for k in (*ESTIMATORS, "peer_estimator", "salib", "scipy")}

            def add(key, s, t, s_ex=s_ex, t_ex=t_ex, errs=errs):
                errs[key].append(max(np.abs(s - s_ex).max(), np.abs(t - t_ex).max()))

            for seed in range(seeds):
                y = f(pick_freeze_design(space, n, seed=seed))
                for est in ESTIMATORS:
                    r = sobol_from_design(y, d, estimator=est, n_bootstrap=0)
                    add(est, r.main[0], r.total[0])
                add("peer_estimator", *peer_estimator(y, d))
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    add("salib", *run_salib(f, bounds, n, seed))
                    add("scipy", *run_scipy(f, bounds, n, seed))
            e = {k: np.array(v) for k, v in errs.items()}
            best = "salib" if e["salib"].mean() <= e["scipy"].mean() else "scipy"
            out[pname][str(n)] = {
                "errors": {k: error_stats(v) for k, v in e.items()},
                "paired_ours_vs_peer_estimator": paired_ratio(e["hybrid"], e["peer_estimator"]),
                "ours_vs_best_library": {"best": best,
                                         **unpaired_ratio(e["hybrid"], e[best])},
            }
            per_seed[(pname, n)] = (e["hybrid"], e["salib"])
    return out, per_seed


def three_seed_medians(per_seed):
    ours, salib = per_seed[("ishigami", 1024)]
    k = ours.size // 3
    mo = np.median(ours[: 3 * k].reshape(k, 3), axis=1)
    ms = np.median(salib[: 3 * k].reshape(k, 3), axis=1)
    return {"triples": k, "ours_min_max": [float(mo.min()), float(mo.max())],
            "salib_min_max": [float(ms.min()), float(ms.max())],
            "fraction_of_triples_ours_worse": float(np.mean(mo > ms))}


def row_bootstrap(y, d, b=100, seed=0):
    """The classical bootstrap: b resamples of the N base rows (multiplicities, one product)."""
    n = y.shape[0] // (d + 2)
    blocks = y.reshape(d + 2, n)
    c = blocks.mean()
    terms = _row_terms(blocks[0] - c, blocks[1] - c, blocks[2:] - c)
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, n, size=(b, n)) + (n * np.arange(b))[:, None]
    w = np.bincount(idx.ravel(), minlength=b * n).reshape(b, n).astype(float)
    s, t, _ = _indices(w @ terms / n, n, d, "hybrid")
    return np.nanquantile(s, [0.025, 0.975], axis=0), np.nanquantile(t, [0.025, 0.975], axis=0)


def interval_cost(repeats, n=4096):
    from SALib.analyze import sobol as sa
    from threadpoolctl import threadpool_limits

    f, bounds, _ = PROBLEMS["ishigami"][1]
    y = f(pick_freeze_design(space_of(bounds), n, seed=0))
    problem = {"num_vars": 3, "names": ["x0", "x1", "x2"], "bounds": bounds}
    sides = {
        "analysis_without_intervals": lambda: sobol_from_design(y, 3, n_bootstrap=0, seed=0),
        "analysis_with_default_intervals": lambda: sobol_from_design(y, 3, seed=0),
        "analysis_with_100_row_resamples": lambda: (sobol_from_design(y, 3, n_bootstrap=0),
                                                    row_bootstrap(y, 3)),
        "salib_analyze_default": lambda: sa.analyze(problem, y, calc_second_order=False,
                                                    seed=0),
    }
    times = {k: [] for k in sides}
    with threadpool_limits(limits=1, user_api="blas"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(repeats):  # interleaved, CPU time: other jobs on the machine cancel
            for k, fn in sides.items():
                t0 = time.process_time()
                fn()
                times[k].append(time.process_time() - t0)
    t = {k: np.array(v) for k, v in times.items()}
    base = t["analysis_without_intervals"]

    def over(k):
        return float(np.median((t[k] - base) / base))

    return {"n": n, "repeats": repeats, "blas_threads": 1, "clock": "process CPU time",
            **{f"{k}_s": float(np.median(v)) for k, v in t.items()},
            "intervals_over_analysis": over("analysis_with_default_intervals"),
            "row_bootstrap_over_analysis": over("analysis_with_100_row_resamples"),
            "ours_with_intervals_over_salib": float(np.median(
                t["analysis_with_default_intervals"] / t["salib_analyze_default"]))}


def summary(out: dict) -> str:
    """README's paragraph, from the JSON of one run."""
    def fmt(r):
        return f"{r['ratio']:.3f} ± {r['se']:.3f}"

    parts = []
    for p, rows in out["ratio_table"].items():
        group = out["results"][p]["group"]
        paired = " / ".join(fmt(rows[n]["paired"]) for n in rows)
        libs = " / ".join(fmt(rows[n]["libraries"]) for n in rows)
        parts.append(f"{p} ({group}): paired {paired}; libraries {libs}")
    worst = max((r["paired"]["ratio"], p, n) for p, rows in out["ratio_table"].items()
                for n, r in rows.items())
    t = out["three_seed_medians_ishigami_1024"]
    c = out["interval_cost"]
    return (
        f"From `benchmarks/results/sobol_accuracy.json` ({out['seeds']} seeds; our mean "
        f"largest error over the peers' at N = {' / '.join(map(str, NS))}, ± one standard "
        "error; paired = the peers' estimator on our design and outputs, libraries = SALib or "
        "scipy end to end on their own designs, whichever is better): "
        + "; ".join(parts)
        + f". Largest paired ratio: {worst[0]:.3f} ({worst[1]}, N = {worst[2]}). A median over "
        f"3 seeds (the figure issue 13 quoted) is not a measurement: over {t['triples']} "
        f"disjoint seed triples at Ishigami N = 1024 it ranges {t['ours_min_max'][0]:.4f}-"
        f"{t['ours_min_max'][1]:.4f} for ours and {t['salib_min_max'][0]:.4f}-"
        f"{t['salib_min_max'][1]:.4f} for SALib. Interval cost at N = {c['n']} (CPU time, "
        f"one BLAS thread): the default 100-draw intervals add {c['intervals_over_analysis']:.2f}"
        f"x the analysis ({c['analysis_without_intervals_s'] * 1e3:.2f} ms); 100 row "
        f"resamples added {c['row_bootstrap_over_analysis']:.1f}x; our analysis with intervals "
        f"takes {c['ours_with_intervals_over_salib']:.3f}x SALib's default `analyze`."
    )


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=300)
    ap.add_argument("--repeats", type=int, default=21)
    ap.add_argument("--summary", help="print README's paragraph from this JSON file and exit")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    t0 = time.perf_counter()
    acc, per_seed = accuracy(args.seeds)
    out = {
        "seeds": args.seeds,
        "default": "hybrid",
        "metric": "per seed: max abs error over all main and total indices",
        "ratio_table": {
            p: {n: {"paired": r["paired_ours_vs_peer_estimator"],
                    "libraries": r["ours_vs_best_library"]}
                for n, r in rows.items() if n.isdigit()}
            for p, rows in acc.items()},
        "results": acc,
        "three_seed_medians_ishigami_1024": three_seed_medians(per_seed),
        "interval_cost": interval_cost(args.repeats),
    }
    out["seconds"] = round(time.perf_counter() - t0, 1)
    out["provenance"] = provenance()
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
