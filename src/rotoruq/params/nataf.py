"""Correlated parameters: the Nataf model (Gaussian copula).

A correlation ``R`` given in x-space (Pearson correlation of the parameters themselves) is
mapped to the equivalent correlation ``R0`` of the normal scores ``z_i = Phi^-1(F_i(x_i))``,
solved per pair by Gauss-Hermite quadrature; independent standard normals are then
``u = L^-1 z`` with ``L L^T = R0``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .._lazy import lazy_module
from ..errors import ParameterError
from .distributions import Distribution, Normal

if TYPE_CHECKING:
    from scipy import optimize
else:
    optimize = lazy_module("scipy.optimize")

__all__ = ["NatafModel", "nataf_correlation", "nataf_model"]


def _bivariate_corr(
    d1: Distribution, d2: Distribution, rho0: float, z: np.ndarray, w: np.ndarray
) -> float:
    """Correlation of (F1^-1(Phi(z1)), F2^-1(Phi(z2))) when corr(z1, z2) = rho0, by the
    quadrature nodes ``z`` (k, 2) and weights ``w`` (k,)."""
    z1 = z[:, 0]
    z2 = rho0 * z[:, 0] + math.sqrt(max(1.0 - rho0 * rho0, 0.0)) * z[:, 1]
    (m1, s1), (m2, s2) = d1.moments, d2.moments
    return float(np.sum(w * (d1.from_z(z1) - m1) * (d2.from_z(z2) - m2)) / (s1 * s2))


def nataf_correlation(
    distributions: Sequence[Distribution], correlation: Any, n_quad: int = 32
) -> np.ndarray:
    """Correlation matrix of the normal scores (Nataf) equivalent to an x-space correlation.

    For every pair the equation ``corr(x_i, x_j) = R_ij`` is solved for the normal-score
    correlation by Gauss-Hermite quadrature (``n_quad`` points per axis) and root finding.
    Pairs of normals keep ``R_ij``. Raises :class:`~rotoruq.errors.ParameterError` when a
    requested correlation cannot be reached with these marginals. Shape (d, d).

    Parameters
    ----------
    distributions : sequence of Distribution
        The d marginals.
    correlation : array_like of shape (d, d)
        The x-space (Pearson) correlation matrix.
    n_quad : int, optional
        Gauss-Hermite points per axis of the quadrature (default 32).

    Examples
    --------
    Two uniforms: the x-space correlation rho and the normal-score one rho0 are related by
    rho = (6 / pi) arcsin(rho0 / 2), so rho = 0.5 needs rho0 = 2 sin(pi / 12) = 0.5176:

    >>> from rotoruq.params import Uniform
    >>> r0 = nataf_correlation([Uniform(0, 1), Uniform(0, 1)], [[1.0, 0.5], [0.5, 1.0]])
    >>> r0.shape, round(float(r0[0, 1]), 4)
    ((2, 2), 0.5176)
    """
    r = np.array(correlation, dtype=float)
    t, wt = np.polynomial.hermite_e.hermegauss(n_quad)
    wt = wt / wt.sum()
    z = np.array(np.meshgrid(t, t, indexing="ij")).reshape(2, -1).T
    w = np.outer(wt, wt).ravel()
    r0 = np.eye(r.shape[0])
    dists = list(distributions)
    for i in range(r.shape[0]):
        for j in range(i + 1, r.shape[0]):
            rij = r[i, j]
            if rij == 0.0:
                continue
            di, dj = dists[i], dists[j]
            if isinstance(di, Normal) and isinstance(dj, Normal):
                r0[i, j] = r0[j, i] = rij
                continue
            lo = _bivariate_corr(di, dj, -0.9999, z, w)
            hi = _bivariate_corr(di, dj, 0.9999, z, w)
            if not (lo <= rij <= hi):
                raise ParameterError(
                    f"correlation {rij} between parameters {i} and {j} is not reachable with "
                    f"their marginals (range [{lo:.4f}, {hi:.4f}])"
                )
            val = optimize.brentq(
                lambda q, a=di, b=dj, t=rij: _bivariate_corr(a, b, q, z, w) - t,
                -0.9999,
                0.9999,
                xtol=1e-12,
            )
            r0[i, j] = r0[j, i] = val
    return r0


@dataclass(frozen=True, eq=False)
class NatafModel:
    """A validated correlation and its Nataf factor.

    Attributes
    ----------
    correlation : ndarray of shape (d, d) or None
        The x-space correlation, or None when the parameters are independent.
    nataf : ndarray of shape (d, d) or None
        The normal-score correlation R0, or None when independent.
    cholesky : ndarray of shape (d, d) or None
        The lower factor L of R0 (L L^T = R0), or None when independent.
    """

    correlation: np.ndarray | None
    nataf: np.ndarray | None
    cholesky: np.ndarray | None


def nataf_model(distributions: Sequence[Distribution], correlation: Any) -> NatafModel:
    """Check an x-space correlation matrix for these marginals and build its Nataf model.

    ``correlation`` None or the identity gives an independent model (all fields None). Raises
    :class:`~rotoruq.errors.ParameterError` when the matrix is not (d, d), finite, symmetric,
    of unit diagonal, positive definite, or not reachable with the marginals.

    Parameters
    ----------
    distributions : sequence of Distribution
        The d marginals.
    correlation : array_like of shape (d, d) or None
        The x-space (Pearson) correlation matrix; None: independent.

    Examples
    --------
    >>> import numpy as np
    >>> from rotoruq.params import Normal, Uniform
    >>> m = nataf_model([Normal(0, 1), Uniform(0, 1)], [[1.0, 0.3], [0.3, 1.0]])
    >>> m.nataf.shape, bool(np.allclose(m.cholesky @ m.cholesky.T, m.nataf))
    ((2, 2), True)
    >>> nataf_model([Normal(0, 1), Uniform(0, 1)], None).nataf is None
    True
    """
    if correlation is None:
        return NatafModel(None, None, None)
    d = len(distributions)
    try:
        r = np.array(correlation, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(
            f"correlation must be a ({d}, {d}) matrix of numbers, got {correlation!r}"
        ) from None
    if r.shape != (d, d):
        raise ParameterError(f"correlation must have shape ({d}, {d}), got {r.shape}")
    if not np.all(np.isfinite(r)) or not np.allclose(r, r.T, atol=1e-12):
        raise ParameterError("correlation matrix must be finite and symmetric")
    if not np.allclose(np.diag(r), 1.0) or np.any(np.abs(r) > 1.0):
        raise ParameterError("correlation matrix needs a unit diagonal and |r_ij| <= 1")
    if np.allclose(r, np.eye(d)):
        return NatafModel(None, None, None)
    try:
        np.linalg.cholesky(r)
    except np.linalg.LinAlgError:
        raise ParameterError("correlation matrix is not positive definite") from None
    r0 = nataf_correlation(distributions, r)
    try:
        chol = np.linalg.cholesky(r0)
    except np.linalg.LinAlgError:
        raise ParameterError(
            "the Nataf normal-score correlation is not positive definite for these "
            "marginals; reduce the correlations"
        ) from None
    return NatafModel(r, r0, chol)
