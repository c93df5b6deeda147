"""rotoruq's multi-fidelity estimators, generalized ACV and MLBLUE beside PyApprox's and
MXMCPy's in the same run (issue 37).

Two standard problems with exact covariances (closed-form integrals):

* the monomial ladder x^5, x^4, x^3, x ~ U(0, 1), costs 1, 0.05, 0.01 (the ACV papers'; issue
  26's comparison);
* the tunable ensemble (Gorodetsky, Geraci, Eldred, Jakeman 2020, JCP 408, sec. 6; PyApprox's
  ``TunableModelEnsemble``): f_k = A_k (cos t_k x1^p_k + sin t_k x2^p_k), p = 5, 3, 1,
  A = sqrt(11), sqrt(7), sqrt(3), t = pi/2, pi/3, pi/6, x ~ U(-1, 1)^2, costs 1, 0.01, 0.001.

At the same main-phase budget (``--budget`` high-fidelity runs) each tool allocates with the
exact covariance and reports the optimal estimator variance it predicts (PyApprox 2.0: GMF,
GRD, GIS searched over recursion trees, MLBLUE; MXMCPy 1.0: every algorithm it offers, an
algorithm that fails recorded with its error). The tools are compared at the whole runs each
would spend (PyApprox's fitted estimator's covariance; ``variance_continuous`` keeps the
continuous optimum its ACV search reports, which no whole-run allocation reaches).
rotoruq's estimators then run ``--seeds`` times at their allocation, each seed with a fresh
``--pilot``-point pilot that sets the weights: the empirical variance of the estimates against
the predicted one (the mean over the seeds of the bootstrap-corrected ``mean_se**2``, and of the
plug-in one). A last row repeats ACV-MF with a 20-point pilot, where the plug-in prediction is
optimistic. A variance from 200 draws is itself uncertain by ~10 % (more with heavy tails): each
ratio carries chi-square and bootstrap intervals, and the seeds go on to ``--check-seeds`` for a
second, tighter check.

A peer that is not installed stops the benchmark with an install hint.

Run: python benchmarks/multifidelity_peers.py [--seeds 200]
    > benchmarks/results/multifidelity_peers.json
``--summary benchmarks/results/multifidelity_peers.json`` prints the docs' paragraph.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)

import rotoruq as rq
from rotoruq.methods.acv import ESTIMATORS, GENERALIZED, allocate, estimator_variance
from rotoruq.methods.mf_choice import choose_estimator
from rotoruq.methods.mlblue import mlblue_allocate, mlblue_variance

ROTORUQ = (*ESTIMATORS, *GENERALIZED, "mlblue")


def _ladder() -> dict:
    powers = (5, 4, 3)
    cov = np.array([[1 / (a + b + 1) - 1 / ((a + 1) * (b + 1)) for b in powers]
                    for a in powers])
    models = [rq.FunctionModel(lambda x, p=p: x[:, 0] ** p, ["x"], ["y"]) for p in powers]
    return {"name": "monomial ladder", "space": rq.ParameterSpace({"x": rq.Uniform(0, 1)}),
            "models": models, "cov": cov, "mean": 1 / 6, "costs": [1.0, 0.05, 0.01]}


def _tunable() -> dict:
    p = (5, 3, 1)
    A = np.sqrt([11.0, 7.0, 3.0])
    t = (np.pi / 2, np.pi / 3, np.pi / 6)
    c = np.array([[a * np.cos(th), a * np.sin(th)] for a, th in zip(A, t, strict=True)])

    def moment(k: int) -> float:  # E[x^k], x ~ U(-1, 1)
        return 0.0 if k % 2 else 1.0 / (k + 1)

    # the odd powers have mean 0: cov_ij = (c_i1 c_j1 + c_i2 c_j2) E[x^(p_i + p_j)]
    cov = np.array([[(c[i] @ c[j]) * moment(p[i] + p[j]) for j in range(3)] for i in range(3)])
    models = [rq.FunctionModel(lambda x, k=k: c[k, 0] * x[:, 0] ** p[k] + c[k, 1] * x[:, 1]
                               ** p[k], ["x1", "x2"], ["y"]) for k in range(3)]
    space = rq.ParameterSpace({"x1": rq.Uniform(-1, 1), "x2": rq.Uniform(-1, 1)})
    return {"name": "tunable ensemble", "space": space, "models": models, "cov": cov,
            "mean": 0.0, "costs": [1.0, 0.01, 0.001]}


def _peers_or_exit():
    try:
        import mxmc  # noqa: F401
        import pyapprox  # noqa: F401
    except ImportError as exc:
        raise SystemExit(f"benchmarks/multifidelity_peers.py: {exc.name} is not installed: "
                         "pip install pyapprox mxmcpy (not in the CI extras)") from exc


def run_pyapprox(cov: np.ndarray, costs, budget: float, families=("gmf", "grd", "gis", "mlblue")
                 ) -> dict:
    from pyapprox.statest.acv.search import ACVSearch
    from pyapprox.statest.acv.strategies import TreeDepthRecursionStrategy
    from pyapprox.statest.acv.variants import GISEstimator, GMFEstimator, GRDEstimator
    from pyapprox.statest.groupacv.search import GroupACVSearch
    from pyapprox.statest.statistics import MultiOutputMean
    from pyapprox.util.backends.numpy import NumpyBkd

    bkd = NumpyBkd()
    stat = MultiOutputMean(1, bkd)
    stat.set_pilot_quantities(cov)
    w = np.asarray(costs, dtype=float)
    out = {}
    for name, cls in (("gmf", GMFEstimator), ("grd", GRDEstimator), ("gis", GISEstimator)):
        if name not in families:
            continue
        t0 = time.perf_counter()
        res = ACVSearch(stat, w, estimator_classes=[cls],
                        recursion_strategy=TreeDepthRecursionStrategy(len(w) - 1)
                        ).search(budget, allow_failures=True)
        # the objective of one statistic of one output is the log of its estimator variance
        # at the continuous optimum; the fitted estimator's covariance is at its whole runs
        out[name] = {"variance": float(res.best.covariance()[0, 0]),
                     "variance_continuous": float(np.exp(res.allocation.objective_value[0])),
                     "n_samples": [int(n) for n in res.best.nsamples_per_model()],
                     "cost": float(res.best.actual_cost()),
                     "seconds": time.perf_counter() - t0}
    if "mlblue" not in families:
        return out
    t0 = time.perf_counter()
    g = GroupACVSearch(stat, w).search(budget)
    out["mlblue"] = {"variance": float(g.best.covariance()[0, 0]),
                     "variance_objective": float(np.exp(g.allocation.objective_value[0])),
                     "n_samples": [int(n) for n in g.best.nsamples_per_model()],
                     "cost": float(g.best.actual_cost()),
                     "seconds": time.perf_counter() - t0}
    return out


def run_mxmcpy(cov: np.ndarray, costs, budget: float) -> dict:
    import mxmc.optimizer as mo

    opt = mo.Optimizer(np.asarray(costs, dtype=float), cov)
    out = {}
    for alg in mo.ALGORITHM_MAP:
        try:
            r = opt.optimize(alg, budget)
            out[alg] = {"variance": float(r.variance), "cost": float(r.cost)}
        except Exception as exc:  # noqa: BLE001  (record which algorithms fail and why)
            out[alg] = {"error": f"{type(exc).__name__}: {str(exc).splitlines()[0]}"}
    return out


def scatter_check(e: np.ndarray, pred: np.ndarray, level: float = 0.95) -> dict:
    """How sure the predicted-over-empirical ratio is, from ``e`` (S,) estimates and ``pred``
    (S,) predicted variances over S seeds: the empirical variance's own standard error (a
    variance from S draws scatters by ~sqrt(2 / (S - 1)) relative, more with heavy tails),
    as a chi-square interval (normal estimates) and a bootstrap over the seeds (any
    distribution; estimates and predictions resampled together), and the excess kurtosis of
    the estimates that widens the first into the second."""
    from scipy import stats

    S = e.size
    v = float(e.var(ddof=1))
    ratio = float(pred.mean()) / v
    lo_q, hi_q = (1 - level) / 2, (1 + level) / 2
    chi = [ratio * float(stats.chi2.ppf(q, S - 1)) / (S - 1) for q in (lo_q, hi_q)]
    rng = np.random.default_rng(20260)
    idx = rng.integers(0, S, size=(4000, S))
    boot = pred[idx].mean(axis=1) / e[idx].var(axis=1, ddof=1)
    lo, hi = np.quantile(boot, [lo_q, hi_q])
    return {"predicted_over_empirical": ratio,
            "empirical_variance_relative_se": float(np.std(e[idx].var(axis=1, ddof=1)) / v),
            "ratio_interval_chi2": chi, "ratio_interval_bootstrap": [float(lo), float(hi)],
            "excess_kurtosis": float(stats.kurtosis(e)), "level": level,
            "within_15pct": bool(abs(ratio - 1.0) <= 0.15),
            "interval_meets_15pct_band": bool(lo <= 1.15 and hi >= 0.85)}


def run_rotoruq(prob: dict, budget: float, seeds: int, pilot: int, estimators=ROTORUQ,
                check_seeds: int = 0) -> dict:
    """Each estimator over seeds 0 .. seeds - 1 (the issue's comparison), and, when
    ``check_seeds`` is larger, on to it: the predicted-over-empirical check again over them
    all, its interval ~sqrt(check_seeds / seeds) times narrower."""
    total = max(seeds, check_seeds)
    cov, w = prob["cov"], np.asarray(prob["costs"], dtype=float)
    out = {}
    for est in estimators:
        t0 = time.perf_counter()
        if est == "mlblue":
            plan = mlblue_allocate(cov, w, budget)
            alloc: object = {g: n for g, n in plan.used_groups()}
            kw: dict = {}
            assert plan.group_fractions is not None
            gc = np.array([w[list(g)].sum() for g in plan.groups])
            v_cont = mlblue_variance(cov, plan.groups, plan.group_fractions * budget / gc)
        else:
            plan = allocate(cov, w, budget, estimator=est)
            if list(plan.models) != sorted(plan.models):
                raise SystemExit(f"{prob['name']}: {est} orders the models {plan.models}; the "
                                 "fixed allocation below assumes the given order")
            alloc = np.zeros(len(w), dtype=int)
            alloc[list(plan.models)] = plan.n_samples
            kw = {"recursion": plan.recursion} if est in GENERALIZED else {}
            sub = list(plan.models)
            v_cont = estimator_variance(est, budget / float(w[sub] @ plan.ratios) * plan.ratios,
                                        "mean", cov[np.ix_(sub, sub)], recursion=plan.recursion)
        t_alloc = time.perf_counter() - t0
        e, pred, plug = np.empty(total), np.empty(total), np.empty(total)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # the 20-point pilot's warning
            for s in range(total):
                r = rq.multifidelity_sample(prob["models"], prob["space"], None, estimator=est,
                                            allocation=alloc, costs=w, n_pilot=pilot,
                                            statistics=["mean"], seed=s, **kw)
                e[s], pred[s], plug[s] = r.mean[0], r.mean_se[0] ** 2, r.mean_se_plugin[0] ** 2
        long = {f"check_{total}_seeds": scatter_check(e, pred)} if total > seeds else {}
        e, pred, plug = e[:seeds], pred[:seeds], plug[:seeds]
        v_emp = float(e.var(ddof=1))
        out[est] = {
            "models": list(plan.models), "recursion": list(plan.recursion),
            "n_samples": [int(n) for n in plan.n_samples], "cost": float(plan.cost),
            "variance_exact_covariance": float(plan.variance),
            "variance_continuous": float(v_cont), "allocation_seconds": t_alloc,
            "empirical_variance": v_emp, "bias_in_se": float((e.mean() - prob["mean"])
                                                             / np.sqrt(v_emp / seeds)),
            "predicted_variance": float(pred.mean()), "plugin_variance": float(plug.mean()),
            "predicted_over_empirical": float(pred.mean() / v_emp),
            "plugin_over_empirical": float(plug.mean() / v_emp),
            "check": scatter_check(e, pred), **long}
    return out


def summary(out: dict) -> str:
    parts = []
    for name, p in out["problems"].items():
        ours = p["rotoruq"]
        best = min(ours, key=lambda e: ours[e]["variance_exact_covariance"])
        pa = p["pyapprox"]
        pbest = min(pa, key=lambda e: pa[e]["variance"])
        # PyApprox's MLBLUE reports its variance at whole points only
        pa_cont = {e: pa[e].get("variance_continuous", pa[e]["variance"]) for e in pa}
        pcont = min(pa_cont, key=lambda e: pa_cont[e])
        ocont = min(ours, key=lambda e: ours[e].get("variance_continuous", np.inf))
        mx = {k: v for k, v in p["mxmcpy"].items() if "variance" in v}
        mxbest = min(mx, key=lambda e: mx[e]["variance"]) if mx else None
        ratios = [ours[e]["predicted_over_empirical"] for e in ROTORUQ]
        long = f"check_{out.get('check_seeds', 0)}_seeds"
        longer = ""
        if all(long in ours[e] for e in ROTORUQ):
            lr = [ours[e][long]["predicted_over_empirical"] for e in ROTORUQ]
            lo = min(ours[e][long]["ratio_interval_bootstrap"][0] for e in ROTORUQ)
            hi = max(ours[e][long]["ratio_interval_bootstrap"][1] for e in ROTORUQ)
            longer = (f"; over {out['check_seeds']} seeds {min(lr):.2f}-{max(lr):.2f} "
                      f"(95 % bootstrap intervals within {lo:.2f}-{hi:.2f})")
        if "variance_continuous" not in ours[best]:  # saved before the whole-run comparison
            plug = [ours[e]["plugin_over_empirical"] for e in ROTORUQ]
            parts.append(
                f"{name}: rotoruq's best {best} {ours[best]['variance_exact_covariance']:.3g} "
                f"against PyApprox's best {pbest} {pa[pbest]['variance']:.3g}; 'auto' chose "
                f"{p['auto']}; over {out['seeds']} seeds the predicted variance is "
                f"{min(ratios):.2f}-{max(ratios):.2f} times the empirical one (plug-in "
                f"{min(plug):.2f}-{max(plug):.2f})")
            continue
        n_out = sum(not ours[e]["check"]["within_15pct"] for e in ROTORUQ)
        wide = [ours[e]["check"]["ratio_interval_bootstrap"] for e in ROTORUQ]
        parts.append(
            f"{name} (costs {', '.join(f'{c:g}' for c in p['costs'])}): rotoruq's best "
            f"{best} {ours[best]['variance_exact_covariance']:.4g} against PyApprox's best "
            f"{pbest} {pa[pbest]['variance']:.4g}, both at the whole runs each allocates "
            f"(continuous optima: rotoruq's {ocont} {ours[ocont]['variance_continuous']:.4g}, "
            f"PyApprox's {pcont} {pa_cont[pcont]:.4g})"
            + (f", MXMCPy's {mxbest} {mx[mxbest]['variance']:.4g}" if mxbest else "")
            + f" (MXMCPy: {len(mx)} of {len(p['mxmcpy'])} algorithms run); 'auto' chose "
            f"{p['auto']}; over {out['seeds']} seeds with a {out['pilot']}-point pilot the "
            f"predicted variance is {min(ratios):.2f}-{max(ratios):.2f} times the empirical one "
            f"over the 7 estimators ({n_out} outside 15 %, the empirical variance's own 95 % "
            f"bootstrap intervals as wide as {min(w[0] for w in wide):.2f}-"
            f"{max(w[1] for w in wide):.2f})" + longer)
    small = out["small_pilot"]
    return ("Multi-fidelity estimators beside PyApprox " + out["pyapprox_version"]
            + " and MXMCPy " + out["mxmcpy_version"] + f" (budget {out['budget']:g} "
            "high-fidelity runs, variance of the mean at the exact covariance): "
            + "; ".join(parts) + f". ACV-MF on the ladder with a 20-point pilot: predicted "
            f"{small['predicted_over_empirical']:.2f}x the empirical variance, plug-in "
            f"{small['plugin_over_empirical']:.2f}x.")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=200)
    ap.add_argument("--check-seeds", type=int, default=1000,
                    help="seeds of the longer predicted-over-empirical check (0: none)")
    ap.add_argument("--budget", type=float, default=100.0)
    ap.add_argument("--pilot", type=int, default=50)
    ap.add_argument("--workers", type=int, default=4)
    ap.add_argument("--summary", default=None)
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    _peers_or_exit()
    from importlib.metadata import version

    prov = provenance()
    out = {"provenance": prov, "seeds": args.seeds, "check_seeds": args.check_seeds,
           "budget": args.budget,
           "pilot": args.pilot, "pyapprox_version": version("pyapprox"),
           "mxmcpy_version": version("mxmcpy"), "problems": {}}
    # the parts are independent: each in a process of its own (PyApprox's GMF search alone
    # takes minutes), the results gathered in a fixed order
    tasks = {(i, part): (_part, i, part, args.budget, args.seeds, args.pilot, args.check_seeds)
             for i in range(2) for part in ("rotoruq", "mlblue", "gmf", "rest")}
    tasks[(0, "small")] = (_part, 0, "small", args.budget, args.seeds, 20, args.check_seeds)
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        futures = {k: pool.submit(*t) for k, t in tasks.items()}
        got = {k: f.result() for k, f in futures.items()}
    for i, prob in enumerate((_ladder(), _tunable())):
        out["problems"][prob["name"]] = {
            "costs": prob["costs"], "covariance": prob["cov"].tolist(),
            **got[(i, "rest")]["auto"],
            "rotoruq": {**got[(i, "rotoruq")], **got[(i, "mlblue")]},
            "pyapprox": {**got[(i, "gmf")], **got[(i, "rest")]["pyapprox"]},
            "mxmcpy": got[(i, "rest")]["mxmcpy"]}
    out["small_pilot"] = got[(0, "small")]["acvmf"]
    print(json.dumps(out, indent=1))


def _part(i: int, part: str, budget_hf: float, seeds: int, pilot: int, check_seeds: int
          ) -> dict:
    """One independent part of the run on problem ``i`` (0 the ladder, 1 the tunable one)."""
    prob = (_ladder, _tunable)[i]()
    budget = budget_hf * prob["costs"][0]
    if part in ("rotoruq", "mlblue"):  # MLBLUE's seeds cost as much as the six others'
        return run_rotoruq(prob, budget, seeds, pilot, check_seeds=check_seeds,
                           estimators=("mlblue",) if part == "mlblue" else ROTORUQ[:-1])
    if part == "small":
        return run_rotoruq(prob, budget, seeds, pilot, estimators=("acvmf",),
                           check_seeds=check_seeds)
    if part == "gmf":
        return run_pyapprox(prob["cov"], prob["costs"], budget, families=("gmf",))
    choice = choose_estimator(prob["cov"], prob["costs"], budget)
    return {"auto": {"auto": choice.estimator, "auto_reason": choice.reason},
            "pyapprox": run_pyapprox(prob["cov"], prob["costs"], budget,
                                     families=("grd", "gis", "mlblue")),
            "mxmcpy": run_mxmcpy(prob["cov"], prob["costs"], budget)}


if __name__ == "__main__":
    main()
