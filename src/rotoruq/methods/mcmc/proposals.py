"""Log priors evaluated fast, and the initial proposal covariance (thesis eqs. 2.25-2.27).

The chains work in scaled coordinates ``z = (theta - center) / scale`` (scale = prior std), so
that the adaptive Metropolis epsilon (1e-8) is relative and proposals are well conditioned
whatever the units of the parameters (a stiffness of 1.5e4 N/m next to a drag coefficient of
0.01).
"""

from __future__ import annotations

import numpy as np

from ...params import Normal, ParameterSpace, Uniform
from ._kernels import logprior_rows

__all__ = ["LogPrior", "hessian_covariance", "prior_scales"]


class LogPrior:
    """Joint log density of a ParameterSpace, vectorized. Uniform and normal marginals are
    evaluated in compiled code (:func:`._kernels.logprior_point`; scipy's frozen-distribution
    call overhead would dominate a Markov chain step), other marginals by their ``logpdf``.
    Points outside the support get -inf.

    ``pack`` holds the arrays of the compiled part; ``compiled`` is True when every marginal
    is uniform or normal (the whole prior is then the compiled part).
    """

    def __init__(self, space: ParameterSpace):
        self.space = space
        b = space.bounds
        self.lo, self.hi = b[:, 0].copy(), b[:, 1].copy()
        const = 0.0
        idx, mu, sig = [], [], []
        self._other = []
        for j, dist in enumerate(space.distributions):
            if isinstance(dist, Uniform):
                const -= np.log(dist.upper - dist.lower)
            elif isinstance(dist, Normal):
                idx.append(j)
                mu.append(dist.mean)
                sig.append(dist.std)
                const -= np.log(dist.std * np.sqrt(2.0 * np.pi))
            else:
                self._other.append((j, dist))
        self.compiled = not self._other
        self.pack = (self.lo, self.hi, float(const), np.array(idx, dtype=np.int64),
                     np.array(mu, dtype=float), np.array(sig, dtype=float))

    def inside(self, theta: np.ndarray) -> np.ndarray:
        """Boolean mask (k,) of points in the (closed) support."""
        return np.all((theta >= self.lo) & (theta <= self.hi), axis=1)

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        """log prior (k,) of points (k, d); -inf outside the support."""
        theta = np.ascontiguousarray(np.atleast_2d(theta), dtype=float)
        out = np.empty(theta.shape[0])
        logprior_rows(theta, self.pack, out)
        if self._other:
            with np.errstate(invalid="ignore"):
                for j, dist in self._other:
                    out += dist.logpdf(theta[:, j])
            out[np.isnan(out)] = -np.inf
        return out


def prior_scales(space: ParameterSpace) -> tuple[np.ndarray, np.ndarray]:
    """Center and scale (prior mean and std) of each parameter, shapes (d,), (d,)."""
    center, scale = space.mean.astype(float), space.std.astype(float)
    bad = ~np.isfinite(scale) | (scale <= 0)
    scale[bad] = 1.0
    center[~np.isfinite(center)] = 0.0
    return center, scale


def hessian_covariance(jac: np.ndarray, precision: np.ndarray, prior_var: np.ndarray,
                       scale: np.ndarray) -> np.ndarray:
    """Inverse of the Gauss-Newton Hessian of the negative log posterior, in scaled coordinates.

    ``H = J^T P J + diag(1 / prior_var)`` (eqs. 2.25-2.27; the prior term is exact for normal
    priors and is Dakota's choice for the others, where it also regularizes directions the data
    do not inform). ``jac`` is (m, d) in parameter units, ``precision`` is (m, m); returns the
    (d, d) covariance of ``z = theta / scale``.
    """
    Js = jac * scale[None, :]
    H = Js.T @ precision @ Js + np.diag(scale**2 / prior_var)
    H = 0.5 * (H + H.T)
    w, V = np.linalg.eigh(H)
    w = np.maximum(w, w.max() * 1e-12)
    return (V / w) @ V.T
