"""GP fit time and holdout error: rotoruq GaussianProcess vs scikit-learn GaussianProcessRegressor.

Two problems with 500 LHS training points and 2000 random holdout points:
  * 4-D: a smooth rotor-like response on [0, 1]^4;
  * 9-D: the Borehole function (8 inputs, Morris et al. 1993) plus one inert input.
Both fit one anisotropic squared-exponential GP by maximum likelihood from the same number
of starts (n_restarts = 2, i.e. 3 starts). scikit-learn: ConstantKernel * RBF(anisotropic)
with normalize_y and a small fixed alpha, inputs scaled to the unit box as ours are.
"rotoruq" is the reference study's configuration (universal Kriging, reduced quadratic trend);
"rotoruq_constant_trend" is ordinary Kriging, like for like with scikit-learn's constant mean.

Prints JSON. Run: python benchmarks/gp_fit.py
"""

from __future__ import annotations

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


def fit_ours(xtr, ytr, xte, yte, seed, trend="reduced_quadratic"):
    t0 = time.perf_counter()
    gp = GaussianProcess(trend=trend, kernel="sqexp", n_restarts=2, seed=seed).fit(xtr, ytr)
    fit = time.perf_counter() - t0
    pred = gp.predict(xte, return_var=False)[:, 0]
    return fit, float(np.sqrt(np.mean((pred - yte) ** 2)))


def fit_sklearn(xtr, ytr, xte, yte, seed):
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF
    from sklearn.gaussian_process.kernels import ConstantKernel as C

    lo, span = xtr.min(0), xtr.max(0) - xtr.min(0)
    d = xtr.shape[1]
    kernel = C(1.0, (1e-3, 1e3)) * RBF(np.full(d, 0.5), (1e-3, 1e2))
    t0 = time.perf_counter()
    gpr = GaussianProcessRegressor(kernel, alpha=1e-10, normalize_y=True, n_restarts_optimizer=2,
                                   random_state=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gpr.fit((xtr - lo) / span, ytr)
    fit = time.perf_counter() - t0
    pred = gpr.predict((xte - lo) / span)
    return fit, float(np.sqrt(np.mean((pred - yte) ** 2)))


def main():
    out = {}
    for name in ("smooth4", "borehole9"):
        xtr, ytr, xte, yte = problem(name)
        ours_t, ours_e = fit_ours(xtr, ytr, xte, yte, 0)
        c_t, c_e = fit_ours(xtr, ytr, xte, yte, 0, trend="constant")
        sk_t, sk_e = fit_sklearn(xtr, ytr, xte, yte, 0)
        out[name] = {
            "n_train": 500, "dim": xtr.shape[1], "response_std": float(yte.std()),
            "rotoruq": {"fit_s": ours_t, "holdout_rmse": ours_e, "trend": "reduced_quadratic"},
            "rotoruq_constant_trend": {"fit_s": c_t, "holdout_rmse": c_e},
            "sklearn": {"fit_s": sk_t, "holdout_rmse": sk_e},
            "fit_time_ratio_sklearn_over_ours": sk_t / ours_t,
            "rmse_ratio_ours_over_sklearn": ours_e / sk_e,
            "meets_target": bool(ours_t < sk_t and ours_e <= sk_e),
        }
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
