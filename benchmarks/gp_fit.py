"""GP fit time and holdout error: rotoruq GaussianProcess vs scikit-learn GaussianProcessRegressor.

Two problems with 500 LHS training points and 2000 random holdout points:
  * 4-D: a smooth rotor-like response on [0, 1]^4;
  * 9-D: the Borehole function (8 inputs, Morris et al. 1993) plus one inert input.

Held equal in the like-for-like row ("rotoruq_constant" vs "sklearn"): the training and holdout
points, the kernel family (anisotropic squared exponential / RBF), a constant mean (ordinary
Kriging's GLS constant vs scikit-learn's normalize_y), inputs scaled to the unit box, and
3 optimizer starts (n_restarts = 2 on both sides) each run on ALL training points
(``screen_points=None``: no subset screening). Not equal: scikit-learn draws its extra starts
log-uniformly in the bounds, we draw them in [0.05, 3] (unit-box length-scales); scikit-learn
optimizes sigma^2 with the length-scales, we concentrate it out.
BLAS threads: rotoruq limits itself to one thread for n <= 2000 (part of what is measured);
scikit-learn is timed with the default threads ("sklearn") and with one ("sklearn_1thread").
Further rows: the study's reduced-quadratic trend and the full quadratic trend (REML by default)
with the library defaults (subset screening of the starts).
Times are medians over ``--repeats`` runs (spread: min and max).

Prints JSON. Run: python benchmarks/gp_fit.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import time
import warnings

import numpy as np
from scipy.stats import qmc

from rotoruq.methods.surrogate import GaussianProcess

BOREHOLE_LO = np.array([0.05, 100, 63070, 990, 63.1, 700, 1120, 9855, 0.0])
BOREHOLE_HI = np.array([0.15, 50000, 115600, 1110, 116, 820, 1680, 12045, 1.0])


def borehole(x: np.ndarray) -> np.ndarray:
    """Water flow rate through a borehole (m^3/yr); column 8 is inert."""
    rw, r, tu, hu, tl, hl, L, kw = (x[:, j] for j in range(8))
    lnr = np.log(r / rw)
    return 2 * np.pi * tu * (hu - hl) / (lnr * (1 + 2 * L * tu / (lnr * rw**2 * kw) + tu / tl))


def smooth4(x: np.ndarray) -> np.ndarray:
    return (np.sin(2 * x[:, 0]) * np.exp(0.5 * x[:, 1]) + x[:, 2] ** 2 + 0.5 * x[:, 0] * x[:, 3]
            + np.cos(3 * x[:, 3]))


def problem(name, seed=0):
    rng = np.random.default_rng(seed)
    if name == "borehole9":
        lo, hi, f = BOREHOLE_LO, BOREHOLE_HI, borehole
    else:
        lo, hi, f = np.zeros(4), np.ones(4), smooth4
    d = lo.size
    xtr = lo + (hi - lo) * qmc.LatinHypercube(d=d, seed=rng).random(500)
    xte = lo + (hi - lo) * rng.random((2000, d))
    return xtr, f(xtr), xte, f(xte)


def _timed(repeats, fit, *args):
    times, err = [], None
    for _ in range(repeats):
        t, err = fit(*args)
        times.append(t)
    return {"fit_s": float(np.median(times)), "fit_s_min": float(min(times)),
            "fit_s_max": float(max(times)), "holdout_nrmse": err}


def fit_ours(xtr, ytr, xte, yte, seed, trend, screen_points=150):
    t0 = time.perf_counter()
    gp = GaussianProcess(trend=trend, kernel="sqexp", n_restarts=2, seed=seed,
                         screen_points=screen_points).fit(xtr, ytr)
    fit = time.perf_counter() - t0
    pred = gp.predict(xte, return_var=False)[:, 0]
    return fit, float(np.sqrt(np.mean((pred - yte) ** 2)) / yte.std())


def fit_sklearn(xtr, ytr, xte, yte, seed, threads=None):
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF
    from sklearn.gaussian_process.kernels import ConstantKernel as C
    from threadpoolctl import threadpool_limits

    lo, span = xtr.min(0), xtr.max(0) - xtr.min(0)
    d = xtr.shape[1]
    kernel = C(1.0, (1e-3, 1e3)) * RBF(np.full(d, 0.5), (1e-3, 1e2))
    t0 = time.perf_counter()
    gpr = GaussianProcessRegressor(kernel, alpha=1e-10, normalize_y=True, n_restarts_optimizer=2,
                                   random_state=seed)
    with warnings.catch_warnings(), threadpool_limits(limits=threads, user_api="blas"):
        warnings.simplefilter("ignore")
        gpr.fit((xtr - lo) / span, ytr)
    fit = time.perf_counter() - t0
    pred = gpr.predict((xte - lo) / span)
    return fit, float(np.sqrt(np.mean((pred - yte) ** 2)) / yte.std())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    r = args.repeats
    out = {"n_train": 500, "n_holdout": 2000, "repeats": r, "error": "holdout RMSE / std"}
    for name in ("smooth4", "borehole9"):
        data = problem(name)
        row = {
            "dim": data[0].shape[1],
            "rotoruq_constant": _timed(r, fit_ours, *data, 0, "constant", None),
            "sklearn": _timed(r, fit_sklearn, *data, 0),
            "sklearn_1thread": _timed(r, fit_sklearn, *data, 0, 1),
            "rotoruq_reduced_quadratic": _timed(r, fit_ours, *data, 0, "reduced_quadratic"),
            "rotoruq_quadratic": _timed(r, fit_ours, *data, 0, "quadratic"),
        }
        c, sk = row["rotoruq_constant"], row["sklearn"]
        row["like_for_like"] = {
            "fit_time_ratio_sklearn_over_ours": sk["fit_s"] / c["fit_s"],
            "fit_time_ratio_sklearn_1thread_over_ours": row["sklearn_1thread"]["fit_s"]
            / c["fit_s"],
            "error_ratio_ours_over_sklearn": c["holdout_nrmse"] / sk["holdout_nrmse"],
        }
        row["quadratic_error_over_reduced"] = (row["rotoruq_quadratic"]["holdout_nrmse"]
                                               / row["rotoruq_reduced_quadratic"]["holdout_nrmse"])
        out[name] = row
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
