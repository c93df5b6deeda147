"""The MBDyn multi-fidelity savings checked by repetition (issue 37).

``benchmarks/multifidelity_mbdyn.py`` predicts the savings from one pilot. Here the whole
estimate (a fresh pilot and main phase each time) is repeated ``--repeats`` times on MBDyn's
elastic GVPM rotor with the built-in rotor as the cheap model (the 'narrow' case: collective
and C_La(0.3) uncertain), at a reduced budget, and the scatter of the estimates is set
against plain Monte Carlo on the elastic rotor at the same cost (pilot included): its variance
``sigma^2 / n`` with ``sigma^2`` from every elastic run of the repetitions (pooled pilots, an
unbiased estimate), ``n`` the elastic runs the same cost buys. Measured saving: that variance
over the empirical variance of the multi-fidelity means; predicted: the mean over the
repetitions of each estimate's own ``speedup`` (bootstrap-corrected standard errors).

The costs are fixed (``--cost-ratio``, the built-in rotor's run over the elastic one's, 1.2e-4
as ``multifidelity_mbdyn.json`` measured) so that every repetition allocates alike. MBDyn is
CPU-heavy: run it under ``nice``; about (pilot + budget) elastic runs of ~4 s per repetition.

Run: nice -n 10 python benchmarks/multifidelity_mbdyn_repeat.py [--repeats 20]
    > benchmarks/results/multifidelity_mbdyn_repeat.json
``--quick``: 2 repetitions at a 7-point pilot and 3 elastic runs (the test's configuration).
"""

from __future__ import annotations

import argparse
import json
import resource
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_and_save, print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)
from multifidelity_mbdyn import FIXED, RESPONSES, SPACE, MBDynModel, locate_mbdyn  # noqa: E402
from scipy import stats

import rotoruq as rq
from rotoruq.rotor.model import RotorModel


def _against(predicted: float, band: list[float]) -> str:
    """Where the predicted saving lies against the measured one's interval."""
    if predicted < band[0]:
        return (f" (below the interval: the prediction is conservative by "
                f"{band[0] / predicted:.2g}x at least)")
    if predicted > band[1]:
        return (f" (above the interval: the prediction is optimistic by "
                f"{predicted / band[1]:.2g}x at least)")
    return " (inside the interval)"


def summary(out: dict) -> str:
    band = out.get("measured_saving_interval_95", {})
    parts = [f"{r}: measured {out['measured_saving'][r]:.3g}x"
             + (f" (95 % interval {band[r][0]:.3g}-{band[r][1]:.3g}x)" if r in band else "")
             + f", predicted {out['predicted_saving'][r]:.3g}x"
             + (_against(out["predicted_saving"][r], band[r]) if r in band else "")
             for r in out["responses"]]
    cpu = (f"; {out['cpu_seconds'] / 60:.0f} CPU minutes in all" if "cpu_seconds" in out
           else "")
    return (f"MBDyn multi-fidelity ({out['estimator']}, adapt={out['adapt']}) repeated "
            + (f"{out['repeats']} times" if out.get("repeats_done", out["repeats"])
               == out["repeats"] else f"{out['repeats_done']} of {out['repeats']} planned times")
            + f" ({out['pilot']}-point pilot, {out['budget']:g} elastic runs "
            f"of budget, {out['elastic_runs']} elastic runs in all{cpu}): savings of the mean "
            "over plain Monte Carlo on the elastic rotor at the same cost, "
            + "; ".join(parts) + ".")


def one_repetition(r: int, args: argparse.Namespace, mbdyn: Path, tmp: str) -> dict:
    """Repetition ``r`` (seed r): a fresh pilot and main phase; what it estimated and spent,
    and its CPU seconds (this process's and MBDyn's, the children's)."""
    cpu0, kids0 = time.process_time(), resource.getrusage(resource.RUSAGE_CHILDREN)
    builtin = RotorModel("gvpm", names_in=list(SPACE.names), names_out=list(RESPONSES),
                         fixed=FIXED)
    elastic = MBDynModel("elastic", args.elastic_revolutions, mbdyn, Path(tmp) / str(r))
    res = rq.multifidelity_sample([elastic, builtin], SPACE, args.budget,
                                  budget_unit="hf_runs", estimator=args.estimator,
                                  n_pilot=args.pilot, adapt=args.adapt,
                                  costs=[1.0, args.cost_ratio], statistics=["mean"], seed=r)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return {"seed": r, "mean": res.mean, "speedup": res.speedup["mean"],
            "spent": res.cost_pilot + res.cost_main, "hf": res.pilot_outputs[:, 0, :],
            "elastic_runs": elastic.count, "failures": len(elastic.failures),
            "n_samples": [int(n) for n in res.allocation],
            "cpu_seconds": time.process_time() - cpu0 + (kids.ru_utime + kids.ru_stime)
            - (kids0.ru_utime + kids0.ru_stime)}


def result(reps: list[dict], args: argparse.Namespace, prov: dict, costs: list[float],
           t0: float) -> dict:
    """The JSON of the repetitions done so far (``repeats_done`` of ``repeats``)."""
    means = np.array([rep["mean"] for rep in reps])
    pooled = np.vstack([rep["hf"] for rep in reps])
    sigma2 = np.nanvar(pooled, axis=0, ddof=1)
    spent = [rep["spent"] for rep in reps]
    n_equal = float(np.mean(spent)) / costs[0]  # elastic runs the same cost buys
    v_mc = sigma2 / n_equal
    v_mf = means.var(axis=0, ddof=1)
    # the measured saving's own uncertainty: v_mf from R repetitions (chi-square, R - 1
    # degrees of freedom) and sigma^2 from the pooled pilots (N - 1)
    R, N = len(reps), len(pooled)
    lo = v_mc / v_mf * stats.chi2.ppf(0.025, R - 1) / (R - 1)
    hi = v_mc / v_mf * stats.chi2.ppf(0.975, R - 1) / (R - 1)
    out = {"provenance": prov, "repeats": args.repeats, "repeats_done": len(reps),
           "pilot": args.pilot,
           "budget": args.budget, "estimator": args.estimator, "adapt": args.adapt,
           "costs": costs, "elastic_revolutions": args.elastic_revolutions,
           "responses": list(RESPONSES), "wall_seconds": time.perf_counter() - t0,
           "cpu_seconds": float(sum(rep["cpu_seconds"] for rep in reps)),
           "cpu_seconds_per_repetition": [rep["cpu_seconds"] for rep in reps],
           "elastic_runs": int(sum(rep["elastic_runs"] for rep in reps)),
           "elastic_failures": int(sum(rep["failures"] for rep in reps)),
           "n_samples_per_repetition": [rep["n_samples"] for rep in reps],
           "pooled_pilot_runs": N,
           "mean_of_means": dict(zip(RESPONSES, means.mean(axis=0).tolist(), strict=True)),
           "empirical_variance": dict(zip(RESPONSES, v_mf.tolist(), strict=True)),
           "plain_mc_variance": dict(zip(RESPONSES, v_mc.tolist(), strict=True)),
           "measured_saving": dict(zip(RESPONSES, (v_mc / v_mf).tolist(), strict=True)),
           "measured_saving_interval_95": {
               r: [float(a), float(b)] for r, a, b in zip(RESPONSES, lo, hi, strict=True)},
           "predicted_saving": dict(zip(RESPONSES, np.mean([rep["speedup"] for rep in reps],
                                                           axis=0).tolist(), strict=True))}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--pilot", type=int, default=8)
    ap.add_argument("--budget", type=float, default=6.0, help="main phase, in elastic runs")
    ap.add_argument("--estimator", default="mfmc")
    ap.add_argument("--adapt", default="linear", choices=("none", "linear"))
    ap.add_argument("--cost-ratio", type=float, default=1.2e-4)
    ap.add_argument("--elastic-revolutions", type=int, default=8)
    ap.add_argument("--workers", type=int, default=1,
                    help="repetitions run side by side (each its own process)")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--summary", metavar="JSON")
    ap.add_argument("--json", metavar="PATH",
                    help="also write the JSON there, rewritten as each repetition finishes")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    if args.quick:
        args.repeats, args.pilot, args.budget = 2, 7, 3.0
    prov = provenance()
    mbdyn = locate_mbdyn()
    costs = [1.0, args.cost_ratio]
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        reps: list[dict] = []
        with ProcessPoolExecutor(max_workers=args.workers) as pool:
            futures = [pool.submit(one_repetition, r, args, mbdyn, tmp)
                       for r in range(args.repeats)]
            for f in as_completed(futures):
                reps.append(f.result())
                if args.json and 2 <= len(reps) < args.repeats:  # what is done so far
                    with open(args.json, "w", encoding="utf-8") as fh:
                        json.dump(result(reps, args, prov, costs, t0), fh, indent=1)
        reps.sort(key=lambda rep: rep["seed"])
    print_and_save(result(reps, args, prov, costs, t0), args.json)


if __name__ == "__main__":
    main()
