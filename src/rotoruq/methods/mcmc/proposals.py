"""Log priors evaluated fast, and the initial proposal covariance (thesis eqs. 2.25-2.27).

The chains work in scaled coordinates ``z = (theta - center) / scale`` (scale = prior std), so
that the adaptive Metropolis epsilon (1e-8) is relative and proposals are well conditioned
whatever the units of the parameters (a stiffness of 1.5e4 N/m next to a drag coefficient of
0.01).
"""

from __future__ import annotations

import numpy as np

from ...params import HistogramBin, Normal, ParameterSpace, Uniform
from ._kernels import logprior_rows

__all__ = ["LogPrior", "hessian_covariance", "prior_scales"]


class LogPrior:
    """Joint log density of a ParameterSpace, vectorized. Uniform, normal and histogram
    (piecewise-constant, e.g. a kernel density a sequential calibration's next stage takes as
    its prior) marginals are evaluated in compiled code (:func:`._kernels.logprior_point`;
    scipy's frozen-distribution call overhead would dominate a Markov chain step), other
    marginals by their ``logpdf``. Points outside the support get -inf.

    ``pack`` holds the arrays of the compiled part; ``compiled`` is True when every marginal
    is uniform, normal or a histogram (the whole prior is then the compiled part). A
    histogram's compiled log density is a table of its own ``logpdf`` at its bins' left edges
    looked up by bisection of its edges (numpy's ``searchsorted``): bitwise its ``logpdf``,
    added after the normal terms in parameter order as the Python route adds it. With another
    marginal beside, the histograms stay on the Python route with it (the same sum, in the
    same order, as before).

    Examples
    --------
    >>> import numpy as np
    >>> from rotoruq.params import HistogramBin, Normal
    >>> space = ParameterSpace({"a": Normal(0.0, 1.0),
    ...                         "b": HistogramBin(abscissas=[0.0, 1.0, 3.0], counts=[1.0, 1.0])})
    >>> lp = LogPrior(space)
    >>> theta = np.array([[0.5, 2.0], [0.5, 3.5]])
    >>> lp.compiled, bool(np.isclose(lp(theta)[0], -0.5 * np.log(2 * np.pi) - 0.125
    ...                                                  + np.log(0.25)))
    (True, True)
    >>> float(lp(theta)[1])
    -inf
    """

    def __init__(self, space: ParameterSpace):
        self.space = space
        b = space.bounds
        self.lo, self.hi = b[:, 0].copy(), b[:, 1].copy()
        const = 0.0
        idx, mu, sig = [], [], []
        pieces: list[tuple[int, HistogramBin]] = []
        self._other = []
        for j, dist in enumerate(space.distributions):
            if isinstance(dist, Uniform):
                const -= np.log(dist.upper - dist.lower)
            elif isinstance(dist, Normal):
                idx.append(j)
                mu.append(dist.mean)
                sig.append(dist.std)
                const -= np.log(dist.std * np.sqrt(2.0 * np.pi))
            elif type(dist) is HistogramBin:
                pieces.append((j, dist))
            else:
                self._other.append((j, dist))
        if self._other:  # the Python route adds every other marginal in parameter order
            self._other = sorted([*self._other, *pieces], key=lambda jd: jd[0])
            pieces = []
        self.compiled = not self._other
        self.pack = (self.lo, self.hi, float(const), np.array(idx, dtype=np.int64),
                     np.array(mu, dtype=float), np.array(sig, dtype=float),
                     *_piecewise_pack(pieces))
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


def _piecewise_pack(pieces: list[tuple[int, HistogramBin]]) -> tuple[np.ndarray, ...]:
    """Parameter index (r,), edge offsets (r + 1,), concatenated edges and concatenated log
    densities of the histogram marginals, for :func:`._kernels.logprior_point`."""
    edges = [np.asarray(dist.abscissas, dtype=float) for _, dist in pieces]
    # each bin's value of the marginal's own logpdf (constant over the bin; a bin's left
    # edge is in the bin, as numpy's searchsorted(side="right") places it)
    logd = [np.asarray(dist.logpdf(e[:-1]), dtype=float)
            for e, (_, dist) in zip(edges, pieces, strict=True)]
    off = np.concatenate([[0], np.cumsum([e.size for e in edges])]).astype(np.int64)
    return (np.array([j for j, _ in pieces], dtype=np.int64), off,
            np.concatenate([np.zeros(0), *edges]), np.concatenate([np.zeros(0), *logd]))


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
