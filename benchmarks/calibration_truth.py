"""Calibration that tells the truth: simulation-based calibration per case, and the speed.

SBC (Talts et al. 2018, :func:`rotoruq.simulation_based_calibration`) of calibrate_bayes on the
3-parameter, 4-output nonlinear model of tests/test_sbc.py (uniform priors on [-1, 1], noise
std 0.05, one experiment per replication, 3,000-step DRAM chains of which 1,000 burn-in, ranks
among 99 draws thinned by the chain's ESS). Cases:

* ``no_emulator``: the chains call the model;
* ``adequate_emulator``: a 50-point GP built once from the prior;
* ``sparse_mean_only``: a 12-point GP, likelihood on its mean only (the thesis's way);
* ``sparse_with_variance``: the same GP with its predictive variance in the likelihood (when
  calibrate_bayes has ``emulator_variance``);
* ``sparse_refined``: the same with adaptive refinement (when calibrate_bayes has ``refine``):
  the runs added and the final error-to-noise ratio of one representative calibration are
  reported from its BayesResult.

Per case: chi-square p-value of the ranks per parameter, 50 / 90 % coverage and their binomial
standard errors, z-score spread, the verdict and its reason, the wall time. Then the single-chain
ESS per second against pymcmcstat DRAM in the same run (the measurement of
benchmarks/mcmc_efficiency.py, ``one_chain``; target >= 3x).

Prints JSON (and writes it with --out). ``--quick``: 40 replications and one speed repeat of
20,000 steps (a smoke run; its p-values have little power). Run:
python benchmarks/calibration_truth.py
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
import time
import warnings

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)

import rotoruq as rq
from rotoruq.methods import mcmc
from rotoruq.methods.mcmc import ChainOptions, EmulatorOptions, NoiseModel, calibrate_bayes

NOISE = 0.05
PRIOR = rq.ParameterSpace({n: rq.Uniform(-1.0, 1.0) for n in "abc"})


class Nonlinear:
    """3 inputs, 4 smooth nonlinear responses (a plain batched Model)."""

    names_in = ("a", "b", "c")
    names_out = ("y1", "y2", "y3", "y4")

    def __call__(self, x):
        a, b, c = np.asarray(x, dtype=float).T
        return np.column_stack([np.sin(a) + b * c, np.exp(0.5 * a) - c, a * b + 0.3 * c**2,
                                b + 0.5 * np.sin(2 * c)])


def _cases() -> dict[str, dict | None]:
    """Case name -> extra keywords of simulation_based_calibration (None: not available)."""
    kw = set(inspect.signature(calibrate_bayes).parameters)
    records = getattr(mcmc, "EmulatorOptions", None)  # the emulator's options since 0.2
    if records is not None:
        kw |= {f.name for f in dataclasses.fields(records)}
    has_var, has_refine = "emulator_variance" in kw, "refine" in kw
    config = getattr(mcmc, "RefineConfig", None)
    refine = config() if config is not None else True
    mean_only = {"emulator_variance": False} if has_var else {}
    return {
        "no_emulator": {},
        "adequate_emulator": {"emulator": 50},
        "sparse_mean_only": {"emulator": 12, **mean_only},
        "sparse_with_variance": {"emulator": 12, "emulator_variance": True} if has_var else None,
        "sparse_refined": ({"emulator": 12, "emulator_variance": True, "refine": refine}
                           if has_var and has_refine else None),
    }


def _refinement_record(opts: dict, seed: int) -> dict:
    """Runs added and error-to-noise ratio of one calibration with these options (whatever
    fields of BayesResult name them)."""
    X = PRIOR.draw(opts["n_emulator_samples"], seed=seed)
    gp = rq.GaussianProcess(seed=seed).fit(X, Nonlinear()(X))
    theta = PRIOR.draw(1, design="random", seed=seed + 1)
    data = Nonlinear()(theta) + NOISE * np.random.default_rng(seed + 2).standard_normal((1, 4))
    rest = {k: v for k, v in opts.items() if k not in ("emulator", "n_emulator_samples")}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = calibrate_bayes(Nonlinear(), data, PRIOR, emulator=EmulatorOptions(gp, **rest),
                              noise=NoiseModel(noise_std=NOISE),
                              chains=ChainOptions(n_samples=2000, burn_in=1000), seed=seed)
    out = {}
    for f in dataclasses.fields(res):
        if any(w in f.name for w in ("refine", "ratio", "added")):
            v = getattr(res, f.name)
            out[f.name] = v.tolist() if isinstance(v, np.ndarray) else v
    return out


def sbc_case(opts: dict, n_replications: int, seed: int) -> dict:
    opts = dict(opts)
    if "emulator" in opts:
        opts["n_emulator_samples"] = opts["emulator"]
        opts["emulator"] = rq.GaussianProcess(seed=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = rq.simulation_based_calibration(Nonlinear(), PRIOR, noise_std=NOISE,
                                            n_replications=n_replications, seed=seed, **opts)
    out = {"p_value": r.p_value.tolist(), "coverage_50": r.coverage_50.tolist(),
           "coverage_90": r.coverage_90.tolist(), "coverage_50_se": r.coverage_50_se,
           "coverage_90_se": r.coverage_90_se, "z_score_std": r.z_score_std.tolist(),
           "ess_median": float(np.median(r.ess)), "n_autocorrelated": r.n_autocorrelated,
           "within_issue_bounds": bool(np.all(r.p_value > 0.01) and np.all(
               (r.coverage_90 >= 0.85) & (r.coverage_90 <= 0.95))),
           "passed": r.passed, "reason": r.reason, "seconds": r.seconds}
    if "refine" in opts:
        out["refinement"] = _refinement_record(opts, seed)
    return out


def speed(budget: int, seed: int, repeats: int) -> dict:
    """Single-chain ESS/s of rotoruq DRAM against pymcmcstat DRAM (mcmc_efficiency.py)."""
    from mcmc_efficiency import make_problem, one_chain

    model, space, data = make_problem(0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        # load compiled kernels
        calibrate_bayes(model, data, space, chains=ChainOptions(n_samples=300), seed=0)
        return one_chain(model, space, data, budget, seed, repeats)


def summary(out: dict) -> str:
    """The README's sentence for this benchmark, from its JSON (``--summary FILE``)."""
    parts = []
    for name, c in out["cases"].items():
        if c is None:
            continue
        parts.append(f"{name.replace('_', ' ')}: p {min(c['p_value']):.3g} (smallest), 90 % "
                     f"coverage {min(c['coverage_90']):.3f}-{max(c['coverage_90']):.3f}, "
                     f"{'pass' if c['within_issue_bounds'] else 'FAIL'}")
    s = out["speed"].get("ratio_ess_per_s")
    speed_text = (f"One DRAM chain vs pymcmcstat: {s['median']:.1f}x ESS/s "
                  f"({s['min']:.1f}-{s['max']:.1f}, target 3x)." if s else
                  f"Speed not measured: {out['speed'].get('skipped')}.")
    return (f"SBC, {out['n_replications']} replications, 3 parameters, 4 outputs: "
            + "; ".join(parts) + ". " + speed_text)


#: Cases the issue requires to be calibrated; ``sparse_mean_only`` must fail (the test can
#: fail). ``sparse_with_variance`` is reported, not a target: measured, the 12-point GP's own
#: variance raises coverage but does not calibrate the posterior (see tests/test_sbc.py).
MUST_PASS = ("no_emulator", "adequate_emulator", "sparse_refined")


def _speed_or_why(args) -> dict:
    """The speed comparison, or why it was not measured (pymcmcstat is in the bench extra)."""
    import importlib.util

    if importlib.util.find_spec("pymcmcstat") is None:
        return {"skipped": "pymcmcstat is not installed (pip install -e '.[bench]')"}
    return speed(args.budget, args.seed, args.repeats)


def meets_targets(out: dict) -> bool:
    cases = out["cases"]
    return bool("ratio_ess_per_s" in out["speed"]
                and out["speed"]["ratio_ess_per_s"]["median"] >= 3.0
                and all(cases[n] is not None and cases[n]["within_issue_bounds"]
                        for n in MUST_PASS)
                and not cases["sparse_mean_only"]["within_issue_bounds"])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--replications", type=int, default=200)
    ap.add_argument("--budget", type=int, default=100_000, help="steps of the speed chains")
    ap.add_argument("--repeats", type=int, default=3, help="speed repeats")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--quick", action="store_true", help="40 replications, one short repeat")
    ap.add_argument("--out", help="also write the JSON here")
    ap.add_argument("--summary", metavar="JSON", help="print the README sentence of a saved run")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    if args.quick:
        args.replications, args.budget, args.repeats = 40, 20_000, 1
    t0 = time.perf_counter()
    cases = {name: None if opts is None else sbc_case(opts, args.replications, args.seed)
             for name, opts in _cases().items()}
    out = {"problem": "3 parameters (uniform on [-1, 1]), 4 nonlinear outputs, noise std "
                      f"{NOISE}, one experiment; DRAM 3,000 steps (1,000 burn-in), L = 99",
           "n_replications": args.replications, "seed": args.seed, "cases": cases,
           "sbc_seconds": time.perf_counter() - t0,
           "speed": _speed_or_why(args)}
    out["meets_targets"] = meets_targets(out)
    out["provenance"] = provenance()
    text = json.dumps(out, indent=1)
    print(text)
    if args.out:
        with open(args.out, "w") as fh:
            fh.write(text + "\n")


if __name__ == "__main__":
    main()
