"""Efficient global optimization (EGO) of the minimum and maximum of every response over many
boxes at once, on one Gaussian process (Jones, Schonlau and Welch 1998; Dakota's
``global_evidence ego`` and ``global_interval_est ego``).

One GP is fitted over the bounding box of all the boxes, so an evaluation made for one box's
extreme also informs every other box it lies in or near. Each iteration maximises the expected
improvement (EI) of every (box, response, min/max) target inside its box and evaluates the
single point with the largest EI, scaled by the response's observed range; the search stops
when every target's scaled EI is below the tolerance.
"""

from __future__ import annotations

import itertools
import warnings
from dataclasses import dataclass

import numpy as np
from scipy import stats

from .._rng import SeedLike, as_generator
from ..errors import ParameterError
from ..params import unit_design

KERNEL = "matern52"
__all__ = ["BoxExtremes", "box_extremes", "expected_improvement"]


def expected_improvement(best, mean, var):
    """Expected improvement below ``best`` of a normal prediction (minimisation).

    Parameters
    ----------
    best : float or array, the best (lowest) value observed so far.
    mean, var : arrays of the same shape, the predicted mean and variance.

    Returns
    -------
    ei : array, ``(best - mean) Phi(z) + s phi(z)`` with ``z = (best - mean) / s``,
        ``max(best - mean, 0)`` where ``s = 0``.

    Examples
    --------
    >>> float(expected_improvement(0.0, np.array([0.0]), np.array([1.0]))[0])  # phi(0)
    0.3989422804014327
    """
    s = np.sqrt(np.maximum(np.asarray(var, dtype=float), 0.0))
    imp = np.asarray(best, dtype=float) - np.asarray(mean, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(s > 0, imp / np.where(s > 0, s, 1.0), 0.0)
    return np.where(s > 0, imp * stats.norm.cdf(z) + s * stats.norm.pdf(z), np.maximum(imp, 0.0))


@dataclass(frozen=True, eq=False)
class BoxExtremes:
    """Result of :func:`box_extremes`.

    Attributes
    ----------
    minimum, maximum : (c, m) lowest and highest evaluated response in every box (model
        values, not GP predictions).
    argmin, argmax : (c, m, d) the points where they were evaluated.
    x, y : (n, d), (n, m) every evaluation made.
    max_expected_improvement : (c, m, 2) the last scaled EI of each target (min, max).
    n_evaluations : int; n_iterations : GP refits; converged : every scaled EI below the
        tolerance.
    """

    minimum: np.ndarray
    maximum: np.ndarray
    argmin: np.ndarray
    argmax: np.ndarray
    x: np.ndarray
    y: np.ndarray
    max_expected_improvement: np.ndarray
    n_evaluations: int
    n_iterations: int
    converged: bool


def _snap(z, lo, hi):
    """Points within 1e-9 box-widths of a bound put exactly on it (extremes of monotone
    responses lie on corners; a point 1e-16 inside would not reach a level there)."""
    tol = 1e-9 * (hi - lo)
    z = np.where(np.abs(z - lo) <= tol, lo, z)
    return np.where(np.abs(z - hi) <= tol, hi, z)


def _in_boxes(x, lo, hi):
    """(c, n) mask: point n lies in box c (bounds included)."""
    return np.all((x[None, :, :] >= lo[:, None, :]) & (x[None, :, :] <= hi[:, None, :]), axis=2)


def box_extremes(
    f,
    lower,
    upper,
    *,
    n_initial: int | None = None,
    tolerance: float = 1e-6,
    max_evaluations: int = 200,
    n_candidates: int = 256,
    seed: SeedLike = None,
) -> BoxExtremes:
    """Minimum and maximum of every response of ``f`` in each of c boxes by EGO on one GP.

    Parameters
    ----------
    f : callable, (n, d) points -> (n, m) responses (non-finite rows are dropped).
    lower, upper : (c, d) box bounds (input units).
    n_initial : size of the initial Latin hypercube over the bounding box of all boxes;
        default ``(d + 1)(d + 2) / 2`` as Dakota's EGO.
    tolerance : stop when every target's expected improvement, divided by the response's
        observed range, is below it.
    max_evaluations : evaluation budget (initial design included); a ``RuntimeWarning`` when
        it ends the search before the tolerance is met.
    n_candidates : random candidate points per box where the EI is screened (the box's
        corners and centre are added) before the best is polished by L-BFGS-B.
    seed : int or Generator (initial design, candidates and GP starts).

    Returns
    -------
    BoxExtremes

    Examples
    --------
    >>> r = box_extremes(lambda x: (x[:, :1] - 0.3) ** 2, [[0.0], [1.0]], [[1.0], [2.0]],
    ...                  seed=1)
    >>> bool(abs(r.minimum[0, 0]) < 1e-6), round(float(r.maximum[1, 0]), 12)
    (True, 2.89)
    """
    from scipy.optimize import minimize

    from .surrogate import GaussianProcess

    lo = np.atleast_2d(np.asarray(lower, dtype=float))
    hi = np.atleast_2d(np.asarray(upper, dtype=float))
    if lo.shape != hi.shape or lo.ndim != 2 or not np.all(hi > lo):
        raise ParameterError(f"box bounds must be (c, d) arrays with upper > lower; got shapes "
                             f"{lo.shape}, {hi.shape}")
    if not tolerance > 0 or int(max_evaluations) < 2 or int(n_candidates) < 1:
        raise ParameterError(f"tolerance must be > 0, max_evaluations >= 2 and n_candidates >= 1;"
                             f" got {tolerance!r}, {max_evaluations!r}, {n_candidates!r}")
    n_box, d = lo.shape
    n0 = (d + 1) * (d + 2) // 2 if n_initial is None else int(n_initial)
    if n0 < 2:
        raise ParameterError(f"n_initial must be >= 2, got {n_initial!r}")
    ss = np.random.SeedSequence(int(as_generator(seed).integers(2**63)))
    s_design, s_cand, s_gp = ss.spawn(3)
    blo, bhi = lo.min(0), hi.max(0)
    x = blo + unit_design(n0, d, design="lhs", seed=as_generator(s_design)) * (bhi - blo)
    y = np.atleast_2d(np.asarray(f(x), dtype=float))
    if y.shape[0] != n0:
        y = y.T
    m = y.shape[1]
    corners = np.array(list(itertools.product([0.0, 1.0], repeat=d))) if d <= 10 else np.empty(
        (0, d))
    unit = np.vstack([as_generator(s_cand).random((int(n_candidates), d)), corners,
                      np.full((1, d), 0.5)])
    cand = _snap(lo[:, None, :] + unit[None, :, :] * (hi - lo)[:, None, :], lo[:, None, :],
                 hi[:, None, :])  # (c, q, d)
    gp_rng = as_generator(s_gp)
    ei_last = np.full((n_box, m, 2), np.inf)
    n_iter, converged = 0, False
    ell = None
    while True:
        ok = np.all(np.isfinite(y), axis=1)
        xs, ys = x[ok], y[ok]
        scale = np.ptp(ys, axis=0) if ys.shape[0] else np.ones(m)
        scale = np.where(scale > 0, scale, 1.0)
        if ys.shape[0] < 2 or x.shape[0] >= int(max_evaluations):
            break
        # refits start from the previous length-scales (one new point barely moves them)
        gp = GaussianProcess(trend="constant", kernel=KERNEL, n_restarts=1 if ell is None else 0,
                             length_scales=ell, seed=gp_rng).fit(xs, ys)
        ell = gp.length_scales
        n_iter += 1
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mu, var = gp.predict(cand.reshape(-1, d), warn_distance=np.inf)
        mu, var = mu.reshape(n_box, -1, m), var.reshape(n_box, -1, m)
        inside = _in_boxes(xs, lo, hi)
        bounds = [list(zip(lo[c], hi[c], strict=True)) for c in range(n_box)]
        best = np.empty((n_box, m, 2))
        for c, k, j in itertools.product(range(n_box), range(m), range(2)):
            sgn = 1.0 - 2.0 * j
            obs = sgn * ys[inside[c], k]
            best[c, k, j] = obs.min() if obs.size else (sgn * mu[c, :, k]).min()
            ei_last[c, k, j] = expected_improvement(best[c, k, j], sgn * mu[c, :, k],
                                                    var[c, :, k]).max() / scale[k]
        c, k, j = (int(v) for v in np.unravel_index(int(np.argmax(ei_last)), ei_last.shape))
        if ei_last[c, k, j] >= tolerance:
            sgn, b = 1.0 - 2.0 * j, best[c, k, j]

            def neg_ei(z, gp=gp, k=k, sgn=sgn, b=b):
                mz, vz = gp.predict(z[None, :], warn_distance=np.inf)
                return -float(expected_improvement(b, sgn * mz[0, k], vz[0, k]))

            ei = expected_improvement(b, sgn * mu[c, :, k], var[c, :, k])
            i = int(np.argmax(ei))
            r = minimize(neg_ei, cand[c, i], method="L-BFGS-B", bounds=bounds[c],
                         options={"maxiter": 50})
            z = np.clip(r.x if -r.fun > ei[i] else cand[c, i], lo[c], hi[c])
            new = [_snap(z, lo[c], hi[c])]
        else:
            # exploitation: evaluate each target's GP-mean optimum where the mean predicts any
            # improvement (a hundredth of the tolerance) at a point not yet evaluated: the EI
            # finds the basin, this polishes the extreme within it (as a local search would)
            new = []
            for c, k, j in itertools.product(range(n_box), range(m), range(2)):
                sgn = 1.0 - 2.0 * j

                def fm(z, gp=gp, k=k, sgn=sgn):
                    mz, gz = gp.predict(z[None, :], return_var=False, return_grad=True,
                                        warn_distance=np.inf)
                    return sgn * float(mz[0, k]), sgn * gz[0, k]

                i = int(np.argmin(sgn * mu[c, :, k]))
                r = minimize(fm, cand[c, i], jac=True, method="L-BFGS-B", bounds=bounds[c],
                             options={"maxiter": 100})
                z = _snap(np.clip(r.x, lo[c], hi[c]), lo[c], hi[c])
                known = np.vstack([xs, *new]) if new else xs
                far = np.min(np.max(np.abs(known - z) / (bhi - blo), axis=1)) > 1e-6
                gain = best[c, k, j] - r.fun > 0.01 * tolerance * scale[k]
                if far and (gain or not inside[c].any()):
                    new.append(z)
            if not new:
                converged = True
                break
        xn = np.array(new)
        if x.shape[0] + xn.shape[0] > int(max_evaluations):
            break
        yn = np.atleast_2d(np.asarray(f(xn), dtype=float)).reshape(xn.shape[0], m)
        x, y = np.vstack([x, xn]), np.vstack([y, yn])
    if not converged:
        warnings.warn(
            f"EGO stopped at max_evaluations = {max_evaluations} with a scaled expected "
            f"improvement of {np.max(ei_last):.3g} > tolerance {tolerance:g}: the box extremes "
            "may not be the true ones (raise max_evaluations)", RuntimeWarning, stacklevel=2)
    ok = np.all(np.isfinite(y), axis=1)
    xs, ys = x[ok], y[ok]
    inside = _in_boxes(xs, lo, hi)
    cmin, cmax = np.full((n_box, m), np.nan), np.full((n_box, m), np.nan)
    amin, amax = np.full((n_box, m, d), np.nan), np.full((n_box, m, d), np.nan)
    for c in range(n_box):
        if inside[c].any():
            yi, xi = ys[inside[c]], xs[inside[c]]
            imin, imax = yi.argmin(0), yi.argmax(0)
            cmin[c], cmax[c] = yi[imin, np.arange(m)], yi[imax, np.arange(m)]
            amin[c], amax[c] = xi[imin], xi[imax]
    return BoxExtremes(minimum=cmin, maximum=cmax, argmin=amin, argmax=amax, x=x, y=y,
                       max_expected_improvement=ei_last, n_evaluations=int(x.shape[0]),
                       n_iterations=n_iter, converged=converged)
