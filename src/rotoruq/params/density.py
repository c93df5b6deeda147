"""A marginal density estimated from samples, kept inside a support: what a sequential
calibration's next stage takes as its prior from the previous stage's chain (issue 35), so a
uniform-shaped posterior stays uniform-shaped and no prior mass leaves the box the first prior
allowed.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .._lazy import lazy_module
from ..errors import ParameterError
from .distributions import HistogramBin

if TYPE_CHECKING:
    from scipy import special
else:
    special = lazy_module("scipy.special")

__all__ = ["kernel_density"]

# the samples are first binned on a grid this many times finer than the density's bins: the
# kernel sum then costs (fine bins x bins), not (samples x bins), and moves each sample by at
# most half a fine bin (1/16 of a density bin)
_FINE = 8
# the kernel's reach in bandwidths beyond the outermost sample (its mass beyond: 3e-5)
_REACH = 4.0


def kernel_density(samples, support: tuple[float, float] = (-math.inf, math.inf), *,
                   n_bins: int = 256) -> HistogramBin:
    """Gaussian kernel density of one variable's samples, reflected at the finite bounds of
    ``support`` and tabulated as a piecewise-uniform :class:`HistogramBin`.

    The bandwidth is Silverman's rule, ``h = 0.9 min(std, IQR / 1.34) n^(-1/5)``. Each bin
    holds the kernel mass the samples put into it (exact Gaussian CDF differences); at a
    finite bound of ``support`` the samples are mirrored (Silverman 1986, sec. 2.10), so a
    density that is flat up to the bound stays flat there instead of leaking half its kernel
    mass out of the support. The bins span the samples widened by 4 h, cut at the support:
    the result has no mass outside ``support``.

    Parameters
    ----------
    samples : array_like of shape (n,)
        Draws of the variable, in its units (n >= 2; non-finite ones are dropped, at least two
        distinct values must remain).
    support : tuple of float, optional
        (lower, upper) bounds the variable cannot leave, in its units (infinite: none);
        default the real line. Every sample must lie inside it.
    n_bins : int, optional
        Number of equal bins of the tabulated density (>= 8); default 256.

    Returns
    -------
    HistogramBin
        The density, ``n_bins`` equal bins inside ``support``.

    Raises
    ------
    ParameterError
        Fewer than two distinct finite samples, samples outside ``support``, or ``n_bins`` < 8.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.random.default_rng(0).uniform(0.0, 1.0, 20_000)
    >>> d = kernel_density(x, (0.0, 1.0))
    >>> d.bounds
    (0.0, 1.0)
    >>> round(float(d.pdf(0.01)), 1), round(float(d.pdf(0.5)), 1)
    (1.0, 1.0)
    """
    x = np.asarray(samples, dtype=float).ravel()
    x = x[np.isfinite(x)]
    lo_s, hi_s = (float(support[0]), float(support[1]))
    if n_bins < 8:
        raise ParameterError(f"kernel_density: n_bins must be >= 8, got {n_bins}")
    if x.size < 2 or x.min() == x.max():
        raise ParameterError(f"kernel_density: at least two distinct finite samples are "
                             f"needed, got {x.size} finite of which "
                             f"{np.unique(x).size} distinct")
    if x.min() < lo_s or x.max() > hi_s:
        raise ParameterError(f"kernel_density: samples span [{x.min():g}, {x.max():g}], "
                             f"outside the support [{lo_s:g}, {hi_s:g}]")
    q75, q25 = np.percentile(x, [75.0, 25.0])
    spread = min(float(np.std(x)), float(q75 - q25) / 1.34) or float(np.std(x))
    h = 0.9 * spread * x.size ** -0.2
    lo = max(lo_s, float(x.min()) - _REACH * h)
    hi = min(hi_s, float(x.max()) + _REACH * h)
    edges = np.linspace(lo, hi, n_bins + 1)
    counts, fine = np.histogram(x, bins=_FINE * n_bins, range=(lo, hi))
    keep = counts > 0
    centers = 0.5 * (fine[:-1] + fine[1:])[keep]
    weights = counts[keep].astype(float)
    points, w = [centers], [weights]
    for bound in (lo_s, hi_s):
        if math.isfinite(bound):  # mirrored samples within the kernel's reach of the bound
            near = np.abs(centers - bound) < _REACH * h
            points.append(2.0 * bound - centers[near])
            w.append(weights[near])
    c, wt = np.concatenate(points), np.concatenate(w)
    # a plain sum, not a BLAS product: the same bits whatever the thread count
    cdf = (special.ndtr((edges[:, None] - c[None, :]) / h) * wt).sum(axis=1)
    mass = np.maximum(np.diff(cdf), 0.0)
    return HistogramBin(abscissas=edges, counts=mass)
