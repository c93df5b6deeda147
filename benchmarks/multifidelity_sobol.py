"""Multi-fidelity Sobol' indices against plain pick-and-freeze at equal cost (issue 26).

Two ladders, each over ``--seeds`` seeds, ``rq.multifidelity_sobol`` against
``rq.sobol_indices(estimator="saltelli2010", design="random")`` on the high-fidelity model alone
with the same total cost (the multi-fidelity pilot included):

* **Ishigami** (Qian et al. 2018, sec. 5.1): sin x1 + a sin^2 x2 + b x3^4 sin x1 with
  (a, b) = (5, 0.1), the cheap models sin x1 + 0.95 a sin^2 x2 + b x3^4 sin x1 and
  sin x1 + 0.6 a sin^2 x2 + 9 b x3^2 sin x1, x ~ U(-pi, pi)^3, costs 1, 0.05, 0.001; exact
  indices in closed form. Estimators "mfmc", "acvmf", "acvis".
* **Rotor**: the built-in GVPM rotor in hover at its default grid (10 stations, 36 azimuth
  steps) as the high-fidelity model, the same rotor on a 3-station, 6-step grid as the cheap
  one (``studies/multifidelity_rotor.toml``'s pair), thrust and power over collective, the
  lift slope and the drag of the Mach 0.3 airfoil section and the pitch-link stiffness; costs
  the study's (seconds per point, measured once); the reference indices from plain
  pick-and-freeze with ``--rotor-reference`` base samples (scrambled Sobol', hybrid estimator).

Per index: the mean of the estimates and its error against the exact (reference) value, the
empirical standard deviation over the seeds against the root-mean-square of the predicted
standard errors, and the empirical variances of both methods; their ratio (the measured cost
saving) beside the predicted one (``speedup``: the plain HF runs for the same standard error
over the cost spent).

Run: python benchmarks/multifidelity_sobol.py > benchmarks/results/multifidelity_sobol.json
``--quick``: a few seeds (a smoke run). ``--summary JSON`` prints the docs' paragraph.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)

import rotoruq as rq

A, B = 5.0, 0.1
ISHIGAMI_COSTS = (1.0, 0.05, 0.001)
ROTOR_COSTS = (3.2e-4, 1.0e-4)  # studies/multifidelity_rotor.toml
ROTOR_FIXED = {"height_over_radius": 4.0}


def ishigami_exact() -> tuple[np.ndarray, np.ndarray]:
    """Main and total indices (3,) of sin x1 + a sin^2 x2 + b x3^4 sin x1 (Ishigami, Homma)."""
    v1 = 0.5 * (1.0 + B * np.pi**4 / 5.0) ** 2
    v2 = A**2 / 8.0
    v13 = B**2 * np.pi**8 * (1.0 / 18.0 - 1.0 / 50.0)
    v = v1 + v2 + v13
    return np.array([v1, v2, 0.0]) / v, np.array([v1 + v13, v2, v13]) / v


def ishigami_ladder():
    space = rq.ParameterSpace({f"x{i}": rq.Uniform(-np.pi, np.pi) for i in (1, 2, 3)})

    def model(a: float, b4: float, b2: float):
        def f(x):
            return (np.sin(x[:, 0]) * (1.0 + b4 * x[:, 2] ** 4 + b2 * x[:, 2] ** 2)
                    + a * np.sin(x[:, 1]) ** 2)
        return rq.FunctionModel(f, space.names, ["y"])

    models = [model(A, B, 0.0), model(0.95 * A, B, 0.0), model(0.6 * A, 0.0, 9.0 * B)]
    return models, space


def rotor_ladder():
    space = rq.ParameterSpace({
        "collective_deg": rq.Uniform(4.5, 6.5),
        "cla_m03": rq.Normal(0.1080, 5.4e-3),
        "cd0_m03": rq.Normal(0.0077, 3.85e-4),
        "k_pitch_link": rq.Normal(15.0, 0.75),
    })
    kw = dict(names_in=space.names, names_out=["thrust", "power"], fixed=ROTOR_FIXED)
    hf = rq.RotorModel("gvpm", **kw)
    lf = rq.RotorModel("gvpm", n_stations=3, n_azimuth=6, **kw)
    return [hf, lf], space


def _stats(est: np.ndarray, exact: np.ndarray) -> dict:
    return {"mean": est.mean(axis=0).tolist(), "error_of_mean": (est.mean(axis=0) - exact).tolist(),
            "std": est.std(axis=0, ddof=1).tolist(),
            "mse": ((est - exact) ** 2).mean(axis=0).tolist()}


def compare(models, space, exact: dict, *, estimator: str, budget: float, n_pilot: int,
            costs, seeds: int) -> dict:
    """``seeds`` multi-fidelity runs and as many plain runs at the same total cost."""
    t0 = time.perf_counter()
    runs = [rq.multifidelity_sobol(models, space, budget, budget_unit="hf_runs", costs=costs,
                                   n_pilot=n_pilot, estimator=estimator, seed=s)
            for s in range(seeds)]
    wall_mf = time.perf_counter() - t0
    spent = float(np.mean([r.cost_pilot + r.cost_main for r in runs]))
    n_plain = int(spent / (costs[0] * (space.dim + 2)))
    t0 = time.perf_counter()
    plain = [rq.sobol_indices(models[0], space, n_plain, estimator="saltelli2010",
                              design="random", n_bootstrap=0, seed=10_000 + s)
             for s in range(seeds)]
    wall_plain = time.perf_counter() - t0
    out: dict = {"estimator": estimator, "seeds": seeds, "budget_hf_runs": budget,
                 "n_pilot": n_pilot, "costs": list(costs),
                 "cost_spent_in_hf_runs": spent / costs[0],
                 "plain_base_samples": n_plain,
                 "mean_allocation_base_samples": np.mean([r.allocation for r in runs],
                                                         axis=0).tolist(),
                 "allocation_terms": sorted({r.allocation_term for r in runs}),
                 "wall_seconds": {"multifidelity": wall_mf, "plain": wall_plain},
                 "responses": {}}
    for j, name in enumerate(runs[0].names_out):
        per: dict = {}
        for s in ("main", "total"):
            ex = np.asarray(exact[name][s])
            mf = np.array([getattr(r, s)[j] for r in runs])
            pl = np.array([getattr(p, s)[j] for p in plain])
            se = np.array([getattr(r, f"{s}_se")[j] for r in runs])
            var_mf, var_pl = mf.var(axis=0, ddof=1), pl.var(axis=0, ddof=1)
            per[s] = {
                "exact": ex.tolist(),
                "multifidelity": _stats(mf, ex) | {"rms_predicted_se": np.sqrt(
                    np.mean(se**2, axis=0)).tolist()},
                "plain": _stats(pl, ex),
                "variance_ratio_measured": (var_pl / var_mf).tolist(),
                "speedup_predicted": np.mean([r.speedup[s][j] for r in runs],
                                             axis=0).tolist(),
                "n_equivalent_hf_predicted": np.mean([r.n_equivalent_hf[s][j] for r in runs],
                                                     axis=0).tolist()}
        out["responses"][name] = per
    return out


def ishigami(seeds: int, budget: float, n_pilot: int, estimators) -> dict:
    models, space = ishigami_ladder()
    main, total = ishigami_exact()
    exact = {"y": {"main": main, "total": total}}
    return {"names_in": list(space.names),
            "runs": [compare(models, space, exact, estimator=e, budget=budget, n_pilot=n_pilot,
                             costs=ISHIGAMI_COSTS, seeds=seeds) for e in estimators]}


def rotor(seeds: int, budget: float, n_pilot: int, n_reference: int) -> dict:
    models, space = rotor_ladder()
    t0 = time.perf_counter()
    ref = rq.sobol_indices(models[0], space, n_reference, seed=26, n_bootstrap=200)
    wall_ref = time.perf_counter() - t0
    exact = {r: {"main": ref.main[j], "total": ref.total[j]} for j, r in enumerate(ref.names_out)}
    measured = rq.multifidelity_sobol(models, space, budget, budget_unit="hf_runs",
                                      n_pilot=n_pilot, seed=0)
    return {"names_in": list(space.names),
            "reference": {"n_samples": n_reference, "estimator": ref.estimator,
                          "wall_seconds": wall_ref,
                          "main": ref.main.tolist(), "total": ref.total.tolist(),
                          "main_ci": ref.main_ci.tolist(), "total_ci": ref.total_ci.tolist()},
            "costs_measured_once": measured.costs.tolist(),
            "term_correlation": measured.term_correlation.tolist(),
            "runs": [compare(models, space, exact, estimator="mfmc", budget=budget,
                             n_pilot=n_pilot, costs=ROTOR_COSTS, seeds=seeds)]}


def _range(values) -> str:
    v = np.asarray(values, dtype=float).ravel()
    return f"{v.min():.0f}-{v.max():.0f}" if v.max() >= 10 else f"{v.min():.1f}-{v.max():.1f}"


def _calibration(out: dict) -> tuple[np.ndarray, np.ndarray]:
    """Over every run and index: the mean's error in its sampling errors, and the spread over
    the seeds over the root-mean-square predicted standard error."""
    z, ratio = [], []
    for part in ("ishigami", "rotor"):
        for run in out.get(part, {}).get("runs", []):
            for per in run["responses"].values():
                for s in ("main", "total"):
                    mf = per[s]["multifidelity"]
                    sd, se = np.array(mf["std"]), np.array(mf["rms_predicted_se"])
                    keep = se > 1e-9 * max(1.0, float(se.max()))  # an index exactly 0
                    z.extend(np.array(mf["error_of_mean"])[keep] / sd[keep]
                             * np.sqrt(run["seeds"]))
                    ratio.extend(sd[keep] / se[keep])
    return np.abs(np.array(z)), np.array(ratio)


def summary(out: dict) -> str:
    ish = out["ishigami"]
    parts = []
    for run in ish["runs"]:
        y = run["responses"]["y"]
        ratios = y["main"]["variance_ratio_measured"] + y["total"]["variance_ratio_measured"]
        pred = y["main"]["speedup_predicted"] + y["total"]["speedup_predicted"]
        parts.append(f"{run['estimator']} {_range(ratios)}x (predicted {_range(pred)}x)")
    r0 = ish["runs"][0]
    text = (f"Multi-fidelity Sobol' indices on the Ishigami ladder (costs "
            f"{', '.join(f'{c:g}' for c in r0['costs'])}; {r0['budget_hf_runs']:g} "
            f"high-fidelity runs of budget plus a {r0['n_pilot']}-base-sample pilot; "
            f"{r0['seeds']} seeds): the variance of the six main and total indices is smaller "
            f"than plain pick-and-freeze's at the same cost by " + "; ".join(parts) + ".")
    if "rotor" in out:
        run = out["rotor"]["runs"][0]
        bits = []
        for resp, per in run["responses"].items():
            ratios = [*per["main"]["variance_ratio_measured"],
                      *per["total"]["variance_ratio_measured"]]
            pred = [*per["main"]["speedup_predicted"], *per["total"]["speedup_predicted"]]
            bits.append(f"{resp} {_range(ratios)}x (predicted {_range(pred)}x)")
        text += (f" The GVPM rotor with its 3-station, 6-step copy as the cheap model (cost "
                 f"ratio {run['costs'][0] / run['costs'][1]:.1f}, {run['seeds']} seeds): "
                 + ", ".join(bits) + ".")
    z, ratio = _calibration(out)
    text += (f" Over every estimator and index, the mean estimate is within {z.max():.1f} of its "
             f"sampling errors of the exact (reference) index, and the spread over the seeds is "
             f"{ratio.min():.2f}-{ratio.max():.2f} times the predicted standard error.")
    return text


def main() -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--budget", type=float, default=250.0, help="Ishigami, HF runs")
    ap.add_argument("--pilot", type=int, default=40)
    ap.add_argument("--rotor-seeds", type=int, default=40)
    ap.add_argument("--rotor-budget", type=float, default=600.0)
    ap.add_argument("--rotor-pilot", type=int, default=30)
    ap.add_argument("--rotor-reference", type=int, default=8192)
    ap.add_argument("--no-rotor", action="store_true")
    ap.add_argument("--quick", action="store_true", help="a few seeds, a smoke run")
    ap.add_argument("--summary", metavar="JSON", help="print the docs' paragraph for a saved run")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return {}
    if args.quick:
        args.seeds, args.rotor_seeds, args.rotor_reference = 4, 3, 256
    out: dict = {"benchmark": "multifidelity_sobol",
                 "ishigami": ishigami(args.seeds, args.budget, args.pilot,
                                      ("mfmc", "acvmf", "acvis"))}
    if not args.no_rotor:
        out["rotor"] = rotor(args.rotor_seeds, args.rotor_budget, args.rotor_pilot,
                             args.rotor_reference)
    out["provenance"] = provenance()
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
