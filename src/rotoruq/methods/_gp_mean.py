"""Compiled mean of a fitted Gaussian process at one point or a small batch (numba).

A Markov chain on an emulator asks for the GP mean at one or two points per step; numpy's call
overhead (a dozen array operations per call) costs more than the arithmetic then. These kernels
compute ``y_o = y_mean_o + y_std_o (sum_i alpha_oi r(h_oi) + g(x)^T beta_o)`` with a direct loop
over the training points (no distance matrix, no temporaries), one output at a time.

The GP is handed over as a *pack*: a tuple of arrays built once after fitting by
:func:`gp_pack` (see :meth:`rotoruq.methods.surrogate.GaussianProcess._build_fast`).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

__all__ = ["KERNEL_IDS", "basis_terms", "gp_pack", "gp_mean_into", "gp_mean_batch"]

KERNEL_IDS = {"sqexp": 0, "matern32": 1, "matern52": 2}
_SQRT3 = math.sqrt(3.0)
_SQRT5 = math.sqrt(5.0)


def basis_terms(trend: str | None, d: int) -> tuple[np.ndarray, np.ndarray]:
    """Trend basis as factor index pairs (p,), (p,): term ``= u_i u_j`` with ``u = x_s - 0.5``
    and index -1 meaning a factor of 1 (same column order as ``surrogate._basis``)."""
    if trend is None:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    bi, bj = [-1], [-1]
    if trend in ("linear", "reduced_quadratic", "quadratic"):
        bi += list(range(d))
        bj += [-1] * d
    if trend == "reduced_quadratic":
        bi += list(range(d))
        bj += list(range(d))
    if trend == "quadratic":
        i, j = np.triu_indices(d)
        bi += i.tolist()
        bj += j.tolist()
    return np.array(bi, np.int64), np.array(bj, np.int64)


def gp_pack(lo, span, Xs, inv_ell, alpha, beta, trend, kernel, y_mean, y_std) -> tuple:
    """Arrays of a fitted GP for the kernels.

    lo, span : (d,) training box (inputs are scaled ``(x - lo) / span``); Xs : (n, d) scaled
    training points; inv_ell : (m, d) inverse length-scales in scaled units; alpha : (m, n)
    weights (``sigma^2`` folded in); beta : (m, p) trend coefficients; y_mean, y_std : (m,)
    response standardization.
    """
    ie = np.ascontiguousarray(inv_ell, dtype=float)
    Xe = np.ascontiguousarray(np.asarray(Xs, float)[None] * ie[:, None, :])  # (m, n, d)
    bi, bj = basis_terms(trend, Xe.shape[2])
    beta = np.asarray(beta, dtype=float).reshape(ie.shape[0], bi.size)
    f = np.ascontiguousarray
    return (f(lo, dtype=float), f(span, dtype=float), Xe, ie, f(alpha, dtype=float), f(beta),
            bi, bj, np.int64(KERNEL_IDS[kernel]), f(y_mean, dtype=float),
            f(y_std, dtype=float))


@nb.njit(cache=True, nogil=True)
def _corr(h2: float, kernel: int) -> float:
    if kernel == 0:
        return math.exp(-0.5 * h2)
    if kernel == 1:
        s = _SQRT3 * math.sqrt(h2)
        return (1.0 + s) * math.exp(-s)
    s = _SQRT5 * math.sqrt(h2)
    return (1.0 + s + s * s / 3.0) * math.exp(-s)


@nb.njit(cache=True, nogil=True)
def gp_mean_into(theta, pack, xs, xe, out) -> None:
    """GP mean at one point theta (d,) into out (m,); xs, xe : (d,) work arrays. On return
    ``xs`` holds the point scaled to the training box (0..1 inside it)."""
    lo, span, Xe, ie, alpha, beta, bi, bj, kernel, y_mean, y_std = pack
    m, n, d = Xe.shape
    for a in range(d):
        xs[a] = (theta[a] - lo[a]) / span[a]
    for o in range(m):
        for a in range(d):
            xe[a] = xs[a] * ie[o, a]
        acc = 0.0
        for i in range(n):
            h2 = 0.0
            for a in range(d):
                u = xe[a] - Xe[o, i, a]
                h2 += u * u
            acc += alpha[o, i] * _corr(h2, kernel)
        for q in range(bi.shape[0]):
            f = beta[o, q]
            if bi[q] >= 0:
                f *= xs[bi[q]] - 0.5
            if bj[q] >= 0:
                f *= xs[bj[q]] - 0.5
            acc += f
        out[o] = y_mean[o] + y_std[o] * acc


@nb.njit(cache=True, nogil=True)
def _mean_rows(X, pack, out) -> None:
    d = X.shape[1]
    xs = np.empty(d)
    xe = np.empty(d)
    for k in range(X.shape[0]):
        gp_mean_into(X[k], pack, xs, xe, out[k])


def gp_mean_batch(X: np.ndarray, pack: tuple) -> np.ndarray:
    """GP mean at points X (k, d) -> (k, m), one point at a time (results do not depend on
    the batch a point is evaluated in)."""
    X = np.ascontiguousarray(X, dtype=float)
    out = np.empty((X.shape[0], pack[2].shape[0]))
    _mean_rows(X, pack, out)
    return out
