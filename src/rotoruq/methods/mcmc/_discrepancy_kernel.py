"""Compiled (numba) marginal log likelihood of a GP discrepancy, per posterior point.

Each point has its own amplitude and length-scale, so each needs its own ``n_c x n_c``
Cholesky factor; with a handful of configurations numpy's batched linear algebra spends most of
a Markov chain step in call overhead, hence this loop.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ... import _numba_cache  # noqa: F401  (the cache keyed by what the kernels compile in)

_LOG_2PI = math.log(2.0 * math.pi)
SQUARED_EXPONENTIAL, MATERN52 = 0, 1


@nb.njit(cache=True, nogil=True)
def gp_marginal_loglik(resid: np.ndarray, xs: np.ndarray, var_mean: np.ndarray,
                       log_amp: np.ndarray, log_ell: np.ndarray, kernel: int, jitter: float,
                       var_point: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    """out[i] = sum_r log N(resid[i, r]; 0, K(a_ir, l_ir) + diag(var_mean[r] + var_point[i, r])
    + jitter I).

    resid : (k, m, n_c); xs : (n_c,); var_mean : (m, n_c); log_amp, log_ell : (k, m);
    kernel : SQUARED_EXPONENTIAL or MATERN52; var_point : (k, m, n_c) a variance of each
    point's own (an emulator's Kriging variance), or (0, 0, 0): none. A non-finite input or a
    matrix that is not positive definite gives -inf.
    """
    per_point = var_point.shape[0] > 0
    k, m, nc = resid.shape
    C = np.empty((nc, nc))
    w = np.empty(nc)
    s5 = math.sqrt(5.0)
    for i in range(k):
        tot = 0.0
        for r in range(m):
            a2 = math.exp(2.0 * log_amp[i, r])
            ell = math.exp(log_ell[i, r])
            for p in range(nc):
                for q in range(p + 1):
                    t = abs(xs[p] - xs[q]) / ell
                    if kernel == SQUARED_EXPONENTIAL:
                        c = a2 * math.exp(-0.5 * t * t)
                    else:
                        c = a2 * (1.0 + s5 * t + 5.0 * t * t / 3.0) * math.exp(-s5 * t)
                    C[p, q] = c
                if per_point:
                    C[p, p] += var_mean[r, p] + var_point[i, r, p] + jitter
                else:
                    C[p, p] += var_mean[r, p] + jitter
            logdet = 0.0
            quad = 0.0
            ok = True
            for p in range(nc):  # Cholesky, lower triangle in place, with the forward solve
                s = C[p, p]
                for q in range(p):
                    s -= C[p, q] * C[p, q]
                if not s > 0.0:
                    ok = False
                    break
                d = math.sqrt(s)
                C[p, p] = d
                logdet += 2.0 * math.log(d)
                for u in range(p + 1, nc):
                    v = 0.0
                    for q in range(p):
                        v += C[u, q] * C[p, q]
                    # C[u, p] still holds the covariance entry: lower triangle is filled
                    C[u, p] = (C[u, p] - v) / d
                v = resid[i, r, p]
                for q in range(p):
                    v -= C[p, q] * w[q]
                w[p] = v / d
                quad += w[p] * w[p]
            if not ok or not math.isfinite(quad):
                tot = -math.inf
                break
            tot += -0.5 * (quad + logdet + nc * _LOG_2PI)
        out[i] = tot
