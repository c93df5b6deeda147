"""Compiled mean and variance of a fitted Gaussian process at one point or a small batch (numba).

A Markov chain on an emulator asks for the GP mean at one or two points per step; numpy's call
overhead (a dozen array operations per call) costs more than the arithmetic then. These kernels
compute ``y_o = y_mean_o + y_std_o (sum_i alpha_oi r(h_oi) + g(x)^T beta_o)`` with direct loops
(no distance matrix, no temporaries beyond one row of n), one output at a time, and, when
asked, the Kriging variance from the same correlations ``r`` (:func:`gp_mean_var_into`).
The scaled training points are stored input by input (outputs, inputs, points): the squared
distances to all n points build up one input at a time in loops over contiguous memory that
the compiler vectorizes, each distance summed over the inputs in the same order as a
point-by-point loop would (the same bits). The correlations are then one loop of
:func:`~rotoruq.methods._vexp.exp1` (arithmetic alone, vectorized; ``math.exp``, a call into
the C library per point, was most of an evaluation) and the weighted sum runs in eight
running sums of a fixed order (:func:`_dot8`): the mean is the same bits on every machine and
thread count, about twice as fast as with ``math.exp`` and one running sum
(``benchmarks/emulator_eval.py``).

The GP is handed over as a :class:`CompiledGP` (built by
:meth:`rotoruq.methods.surrogate.GaussianProcess.compiled`); the kernels take its
:attr:`CompiledGP.mean_pack` and :attr:`CompiledGP.var_pack` tuples (numba takes tuples of
arrays, not dataclasses).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from .. import _numba_cache  # noqa: F401  (the cache keyed by what the kernels compile in)
from .._compile import compiling
from ._vexp import exp1

log = logging.getLogger(__name__)

__all__ = ["KERNEL_IDS", "CompiledGP", "basis_terms", "gp_pack", "gp_mean_into",
           "gp_mean_batch", "gp_mean_var_into", "gp_mean_var_batch"]

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
    training points (packed as Xe (m, d, n), the points times output o's inverse
    length-scales, contiguous over points); inv_ell : (m, d) inverse length-scales in scaled
    units; alpha : (m, n) weights (``sigma^2`` folded in); beta : (m, p) trend
    coefficients; y_mean, y_std : (m,) response standardization.
    """
    ie = np.ascontiguousarray(inv_ell, dtype=float)
    Xe = np.ascontiguousarray(np.asarray(Xs, float).T[None] * ie[:, :, None])  # (m, d, n)
    bi, bj = basis_terms(trend, Xe.shape[1])
    beta = np.asarray(beta, dtype=float).reshape(ie.shape[0], bi.size)
    f = np.ascontiguousarray
    return (f(lo, dtype=float), f(span, dtype=float), Xe, ie, f(alpha, dtype=float), f(beta),
            bi, bj, np.int64(KERNEL_IDS[kernel]), f(y_mean, dtype=float),
            f(y_std, dtype=float))


@dataclass(frozen=True, eq=False)
class CompiledGP:
    """A fitted GP's arrays for the compiled kernels, one leading axis per response (m).

    Mean: lo, span : (d,) training box (inputs scaled ``(x - lo) / span``); Xe : (m, d, n)
    scaled training points times the inverse length-scales, contiguous over the points;
    inv_ell : (m, d) inverse length-scales (scaled units); alpha : (m, n) kriging weights
    (``sigma^2`` folded in); beta : (m, p) trend coefficients; basis_i, basis_j : (p,)
    trend terms (:func:`basis_terms`); kernel_id : :data:`KERNEL_IDS`; y_mean, y_std : (m,) response
    standardization.

    Variance (empty with ``has_variance`` False): with ``r`` (n,) the correlations to the
    training points and ``g`` (p,) the trend basis at x, the Kriging variance of response o
    (response units squared, including the trend's uncertainty) is
    ``var_scale_o (v0_o - |chol_inv_o r|^2 + |trend_chol_inv_o (minv_f_o^T r - g)|^2)``;
    chol_inv : (m, n, n) inverse lower Cholesky factor of the training covariance (the
    cross-covariance factor folded in), minv_f : (m, n, p) ``M^-1 F`` (same factor),
    trend_chol_inv : (m, p, p) inverse Cholesky factor of ``F^T M^-1 F``; v0, var_scale : (m,).
    One variance costs ``n^2 / 2`` multiply-adds per response (the mean ``n d``).
    """

    lo: np.ndarray
    span: np.ndarray
    Xe: np.ndarray
    inv_ell: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    basis_i: np.ndarray
    basis_j: np.ndarray
    kernel_id: np.int64
    y_mean: np.ndarray
    y_std: np.ndarray
    chol_inv: np.ndarray
    minv_f: np.ndarray
    trend_chol_inv: np.ndarray
    v0: np.ndarray
    var_scale: np.ndarray

    @property
    def n_outputs(self) -> int:
        return int(self.Xe.shape[0])

    @property
    def has_variance(self) -> bool:
        return self.chol_inv.shape[1] == self.Xe.shape[2]

    @property
    def mean_pack(self) -> tuple:
        """The mean's arrays as the tuple the kernels take."""
        return (self.lo, self.span, self.Xe, self.inv_ell, self.alpha, self.beta, self.basis_i,
                self.basis_j, self.kernel_id, self.y_mean, self.y_std)

    @property
    def var_pack(self) -> tuple:
        """The variance's arrays as the tuple the kernels take."""
        return (self.chol_inv, self.minv_f, self.trend_chol_inv, self.v0, self.var_scale)


def compile_gp(lo, span, Xs, inv_ell, alpha, beta, trend, kernel, y_mean, y_std,
               variance=None) -> CompiledGP:
    """A :class:`CompiledGP` from a fit's arrays (see :func:`gp_pack` for the mean's);
    ``variance`` is None or the tuple (chol_inv, minv_f, trend_chol_inv, v0, var_scale)."""
    mp = gp_pack(lo, span, Xs, inv_ell, alpha, beta, trend, kernel, y_mean, y_std)
    m = mp[2].shape[0]
    p = mp[6].shape[0]
    if variance is None:
        variance = (np.zeros((m, 0, 0)), np.zeros((m, 0, p)), np.zeros((m, p, p)),
                    np.zeros(m), np.zeros(m))
    f = np.ascontiguousarray
    return CompiledGP(*mp, *(f(a, dtype=float) for a in variance))


@nb.njit(cache=True, nogil=True, inline="always")
def _corr_into(h, kernel) -> None:
    """h (n,): squared scaled distances in, correlations out, one loop per kernel of
    arithmetic alone (:func:`~rotoruq.methods._vexp.exp1`), which the compiler vectorizes:
    the exponentials were most of an emulator's evaluation as calls into the C library."""
    n = h.shape[0]
    if kernel == 0:
        for i in range(n):
            h[i] = exp1(-0.5 * h[i])
    elif kernel == 1:
        for i in range(n):
            s = _SQRT3 * math.sqrt(h[i])
            h[i] = (1.0 + s) * exp1(-s)
    else:
        for i in range(n):
            s = _SQRT5 * math.sqrt(h[i])
            h[i] = (1.0 + s + s * s / 3.0) * exp1(-s)


@nb.njit(cache=True, nogil=True, inline="always")
def _dot8(a, b, n) -> float:
    """sum_i a[i] b[i] (i < n) in eight running sums, element i into sum i mod 8, added
    pairwise at the end: a fixed order (the same bits on every machine, no reassociation
    left to the compiler), which the compiler can still put into vector registers."""
    s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = 0.0
    m = n - n % 8
    for i in range(0, m, 8):
        s0 += a[i] * b[i]
        s1 += a[i + 1] * b[i + 1]
        s2 += a[i + 2] * b[i + 2]
        s3 += a[i + 3] * b[i + 3]
        s4 += a[i + 4] * b[i + 4]
        s5 += a[i + 5] * b[i + 5]
        s6 += a[i + 6] * b[i + 6]
        s7 += a[i + 7] * b[i + 7]
    for i in range(m, n):
        s0 += a[i] * b[i]
    return ((s0 + s4) + (s1 + s5)) + ((s2 + s6) + (s3 + s7))


@nb.njit(cache=True, nogil=True, inline="always")
def _sq_distances(xs, Xe, ie, o, h) -> None:
    """h (n,) = |xs * ie[o] - Xe[o, :, i]|^2 for every training point i, built up one input
    at a time (each sum in input order, as a loop over the inputs per point would)."""
    n = h.shape[0]
    for i in range(n):
        h[i] = 0.0
    for a in range(xs.shape[0]):
        xa = xs[a] * ie[o, a]
        row = Xe[o, a]
        for i in range(n):
            u = xa - row[i]
            h[i] += u * u


# gp_mean_into, _tri_sumsq and gp_mean_var_into are called only from compiled code: no
# CPython wrapper (see mcmc._kernels._inner); they cannot be called from Python.
@nb.njit(cache=True, nogil=True, no_cpython_wrapper=True)
def gp_mean_into(theta, pack, xs, h, out) -> None:
    """GP mean at one point theta (d,) into out (m,); work arrays xs (d,) and h (n,). On
    return ``xs`` holds the point scaled to the training box (0..1 inside it)."""
    lo, span, Xe, ie, alpha, beta, bi, bj, kernel, y_mean, y_std = pack
    m, d, n = Xe.shape
    for a in range(d):
        xs[a] = (theta[a] - lo[a]) / span[a]
    for o in range(m):
        _sq_distances(xs, Xe, ie, o, h)
        _corr_into(h, kernel)
        acc = _dot8(alpha[o], h, n)
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
    xs = np.empty(X.shape[1])
    h = np.empty(pack[2].shape[2])
    for k in range(X.shape[0]):
        gp_mean_into(X[k], pack, xs, h, out[k])


def gp_mean_batch(X: np.ndarray, pack: tuple) -> np.ndarray:
    """GP mean at points X (k, d) -> (k, m), one point at a time (results do not depend on
    the batch a point is evaluated in)."""
    X = np.ascontiguousarray(X, dtype=float)
    out = np.empty((X.shape[0], pack[2].shape[0]))
    # the notice where the kernel is called: a process that never calls one (a chain on the
    # emulator calls neither: its own kernels inline the GP) never caches it, and checking
    # it up front announced a compile on every warm run
    with compiling("emulator kernels", [_mean_rows], log):
        _mean_rows(X, pack, out)
    return out


@nb.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"}, no_cpython_wrapper=True)
def _tri_sumsq(Li, r, n) -> float:
    """|Li r|^2 for a lower-triangular Li (n, n): the n^2/2 multiply-adds of the variance.
    Reassociation lets the compiler vectorize the row sums (the result is still a function
    of the inputs alone, the same on every call)."""
    s = 0.0
    for i in range(n):
        t = 0.0
        row = Li[i]
        for j in range(i + 1):
            t += row[j] * r[j]
        s += t * t
    return s


@nb.njit(cache=True, nogil=True, no_cpython_wrapper=True)
def gp_mean_var_into(theta, pack, vpack, xs, r, g, u, out, var) -> None:
    """GP mean (m,) into ``out`` and Kriging variance (m,) into ``var`` at one point theta
    (d,). Work arrays: xs (d,), r (n,), g, u (p,). On return ``xs`` holds the scaled
    point. The variance is ``v0 - |L^-1 r|^2 + |C^-1 (M^-1 F)^T r - g|^2`` (times the
    scale), clipped at 0 like :meth:`GaussianProcess.predict`."""
    lo, span, Xe, ie, alpha, beta, bi, bj, kernel, y_mean, y_std = pack
    Li, MF, Ci, v0, vscale = vpack
    m, d, n = Xe.shape
    p = bi.shape[0]
    for a in range(d):
        xs[a] = (theta[a] - lo[a]) / span[a]
    for q in range(p):
        f = 1.0
        if bi[q] >= 0:
            f *= xs[bi[q]] - 0.5
        if bj[q] >= 0:
            f *= xs[bj[q]] - 0.5
        g[q] = f
    for o in range(m):
        _sq_distances(xs, Xe, ie, o, r)
        _corr_into(r, kernel)
        acc = _dot8(alpha[o], r, n)
        for q in range(p):
            acc += beta[o, q] * g[q]
        out[o] = y_mean[o] + y_std[o] * acc
        # |L^-1 r|^2: row i of the triangular inverse touches r[0..i]
        s = _tri_sumsq(Li[o], r, n)
        for q in range(p):
            t = -g[q]
            for i in range(n):
                t += MF[o, i, q] * r[i]
            u[q] = t
        w2 = 0.0
        for q in range(p):
            t = 0.0
            for k in range(q + 1):
                t += Ci[o, q, k] * u[k]
            w2 += t * t
        var[o] = max(v0[o] - s + w2, 0.0) * vscale[o]


@nb.njit(cache=True, nogil=True)
def _mean_var_rows(X, pack, vpack, out, var) -> None:
    xs = np.empty(X.shape[1])
    r = np.empty(pack[2].shape[2])
    p = pack[6].shape[0]
    g = np.empty(p)
    u = np.empty(p)
    for k in range(X.shape[0]):
        gp_mean_var_into(X[k], pack, vpack, xs, r, g, u, out[k], var[k])


def gp_mean_var_batch(X: np.ndarray, gp: CompiledGP) -> tuple[np.ndarray, np.ndarray]:
    """GP mean and Kriging variance at points X (k, d) -> (k, m), (k, m), one point at a
    time; ``gp`` must carry its variance arrays (:attr:`CompiledGP.has_variance`)."""
    if not gp.has_variance:
        raise ValueError("this CompiledGP was built without its variance arrays")
    X = np.ascontiguousarray(X, dtype=float)
    out = np.empty((X.shape[0], gp.n_outputs))
    var = np.empty_like(out)
    with compiling("emulator kernels", [_mean_var_rows], log):
        _mean_var_rows(X, gp.mean_pack, gp.var_pack, out, var)
    return out, var
