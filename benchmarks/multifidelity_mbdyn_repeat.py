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
import tempfile
import time
from pathlib import Path

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)
from multifidelity_mbdyn import FIXED, RESPONSES, SPACE, MBDynModel, locate_mbdyn  # noqa: E402

import rotoruq as rq
from rotoruq.rotor.model import RotorModel


def summary(out: dict) -> str:
    parts = [f"{r}: measured {out['measured_saving'][r]:.3g}x, predicted "
             f"{out['predicted_saving'][r]:.3g}x" for r in out["responses"]]
    return (f"MBDyn multi-fidelity ({out['estimator']}, adapt={out['adapt']}) repeated "
            f"{out['repeats']} times ({out['pilot']}-point pilot, {out['budget']:g} elastic runs "
            f"of budget, {out['elastic_runs']} elastic runs in all): savings of the mean over "
            "plain Monte Carlo on the elastic rotor at the same cost, " + "; ".join(parts) + ".")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--pilot", type=int, default=8)
    ap.add_argument("--budget", type=float, default=6.0, help="main phase, in elastic runs")
    ap.add_argument("--estimator", default="mfmc")
    ap.add_argument("--adapt", default="linear", choices=("none", "linear"))
    ap.add_argument("--cost-ratio", type=float, default=1.2e-4)
    ap.add_argument("--elastic-revolutions", type=int, default=8)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--summary", metavar="JSON")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    if args.quick:
        args.repeats, args.pilot, args.budget = 2, 7, 3.0
    prov = provenance()
    mbdyn = locate_mbdyn()
    builtin = RotorModel("gvpm", names_in=list(SPACE.names), names_out=list(RESPONSES),
                         fixed=FIXED)
    costs = [1.0, args.cost_ratio]
    means, speedups, hf_values, spent = [], [], [], []
    runs = 0
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.repeats):
            elastic = MBDynModel("elastic", args.elastic_revolutions, mbdyn, Path(tmp) / str(r))
            res = rq.multifidelity_sample([elastic, builtin], SPACE, args.budget,
                                          budget_unit="hf_runs", estimator=args.estimator,
                                          n_pilot=args.pilot, adapt=args.adapt, costs=costs,
                                          statistics=["mean"], seed=r)
            means.append(res.mean)
            speedups.append(res.speedup["mean"])
            spent.append(res.cost_pilot + res.cost_main)
            hf_values.append(res.pilot_outputs[:, 0, :])
            runs += elastic.count
    means, pooled = np.array(means), np.vstack(hf_values)
    sigma2 = np.nanvar(pooled, axis=0, ddof=1)
    n_equal = float(np.mean(spent)) / costs[0]  # elastic runs the same cost buys
    v_mc = sigma2 / n_equal
    v_mf = means.var(axis=0, ddof=1)
    out = {"provenance": prov, "repeats": args.repeats, "pilot": args.pilot,
           "budget": args.budget, "estimator": args.estimator, "adapt": args.adapt,
           "costs": costs, "responses": list(RESPONSES), "wall_seconds": time.perf_counter() - t0,
           "elastic_runs": runs,
           "mean_of_means": dict(zip(RESPONSES, means.mean(axis=0).tolist(), strict=True)),
           "empirical_variance": dict(zip(RESPONSES, v_mf.tolist(), strict=True)),
           "plain_mc_variance": dict(zip(RESPONSES, v_mc.tolist(), strict=True)),
           "measured_saving": dict(zip(RESPONSES, (v_mc / v_mf).tolist(), strict=True)),
           "predicted_saving": dict(zip(RESPONSES, np.mean(speedups, axis=0).tolist(),
                                        strict=True))}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
