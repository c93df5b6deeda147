"""Restricted pairing of a Latin hypercube (Iman and Conover 1982), as Dakota's LHS does.

Each column of a Latin hypercube is stratified on its own; pairing the columns at random
leaves spurious sample correlations of order 1/sqrt(n) between independent inputs. The
restricted pairing re-orders every column (so each stratum is still hit exactly once) to give
the rank structure of a matrix of the design's normal scores whose correlation has been driven
to the target: the normal-score correlation of the sample then sits near the target (identity
for independent inputs, the Nataf correlation R0 for correlated ones).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .._lazy import lazy_module
from ..errors import ParameterError

if TYPE_CHECKING:
    from scipy import special
else:
    special = lazy_module("scipy.special")

__all__ = ["PAIRINGS", "restricted_pairing"]

PAIRINGS = ("restricted", "random")
"""Column pairings of a Latin hypercube: Iman-Conover (``"restricted"``) or ``"random"``."""

_SWEEPS = 100
_CANDIDATES = 256


def _ranks(a: np.ndarray) -> np.ndarray:
    """Ranks 0..n-1 of each column (ties broken by position), shape of ``a``."""
    at = np.ascontiguousarray(a.T)  # row-wise sorts: column-wise ones are cache-bound
    r = np.empty(at.shape, dtype=np.intp)
    np.put_along_axis(r, np.argsort(at, axis=1, kind="stable"), np.arange(at.shape[1])[None, :],
                      axis=1)
    return r.T


def restricted_pairing(
    q: np.ndarray, rng: np.random.Generator, target: np.ndarray | None = None
) -> np.ndarray:
    """Re-order the columns of a design so its normal-score correlation is near ``target``.

    Parameters
    ----------
    q : array (n, d)
        A design in (0, 1)^d, e.g. a Latin hypercube; every column keeps its values (and so its
        stratification), only their order changes.
    rng : numpy Generator
        Draws the initial random permutations of the scores.
    target : array (d, d), optional
        Positive-definite correlation matrix of the normal scores Phi^-1(q) to reach (default
        the identity: independent inputs).

    Returns
    -------
    array (n, d)
        The re-paired design. With ``n <= d`` the score correlation matrix is singular and no
        pairing can reach the target: the columns stay paired at random (as for ``n = 1``)
        and a non-identity target is imposed on their normal scores through its Cholesky
        factor instead (the design is then not stratified per column).

    Notes
    -----
    Iman and Conover (1982): a score matrix S whose columns are random permutations of the
    design's normal scores is transformed to S' = S Q^-T P^T with Q Q^T = corr(S) and
    P P^T = target, so corr(S') = target exactly; each column of the design takes the ranks of
    the matching column of S'. Taking ranks leaves the rank correlations ~0.03 off at n = 500,
    so pairs of entries are then swapped within columns while that brings both the score
    (Pearson) and rank (Spearman, goal (6/pi) arcsin(R0/2)) correlations nearer the target,
    for at most 100 sweeps over the columns (fewer beyond 9 inputs: at most ~900 column
    steps in all) or until both are within 0.5/n.

    Examples
    --------
    >>> import numpy as np
    >>> from rotoruq.params import unit_design
    >>> rng = np.random.default_rng(0)
    >>> q = restricted_pairing(unit_design(500, 9, pairing="random", seed=1), rng)
    >>> z = np.argsort(np.argsort(q, axis=0), axis=0)
    >>> bool(np.abs(np.corrcoef(z.T) - np.eye(9)).max() < 0.02)
    True
    """
    q = np.asarray(q, dtype=float)
    if q.ndim != 2:
        raise ParameterError(f"a design must have shape (n, d), got {q.shape}")
    n, d = q.shape
    p_target = np.eye(d)
    if target is not None:
        target = np.asarray(target, dtype=float)
        if target.shape != (d, d):
            raise ParameterError(f"target correlation must have shape ({d}, {d}), got "
                                 f"{target.shape}")
        try:
            p_target = np.linalg.cholesky(target)
        except np.linalg.LinAlgError:
            raise ParameterError("target correlation must be positive definite") from None
    if n <= d or d < 2:
        if target is None or d < 2:
            return q.copy()
        # no pairing reaches the target: correlate the normal scores instead (the design is
        # then stratified in u-space, not per column, as a randomly paired one mapped by Nataf)
        z = special.ndtri(np.clip(q, 1e-16, 1.0 - 1e-16)) @ p_target.T
        return np.clip(special.ndtr(z), 1e-300, 1.0 - 1e-16)
    goal = p_target @ p_target.T
    qs = np.sort(q, axis=0)
    # the normal scores of the design's own values (centred per column): what the Nataf
    # correlation refers to, tails included
    zs = special.ndtri(np.clip(qs, 1e-300, 1.0 - 1e-16))
    zs = zs - zs.mean(axis=0)
    s = np.column_stack([zs[rng.permutation(n), j] for j in range(d)])
    try:
        qf = np.linalg.cholesky(np.corrcoef(s, rowvar=False))
        # S' = S Q^-T P^T has correlation P P^T exactly; the columns take its ranks
        ranks = _ranks(np.linalg.solve(qf, s.T).T @ p_target.T)
    except np.linalg.LinAlgError:  # a column of equal values: nothing to control
        ranks = _ranks(s)
    ranks = _swap_polish(ranks, zs, rng, goal, 6.0 / np.pi * np.arcsin(goal / 2.0))
    return np.take_along_axis(np.ascontiguousarray(qs.T), np.ascontiguousarray(ranks.T),
                              axis=1).T.copy()


def _swap_polish(
    ranks: np.ndarray, zs: np.ndarray, rng: np.random.Generator, goal_scores: np.ndarray,
    goal_ranks: np.ndarray,
) -> np.ndarray:
    """Swap pairs of entries within columns while that brings both the normal-score
    (Pearson) and the rank (Spearman) correlations nearer their goals.

    ``zs`` (n, d) holds each column's sorted, centred normal scores. Iman-Conover on normal
    scores leaves their correlation within ~0.005 of the goal but the rank correlation ~0.03
    away at n = 500; controlling ranks instead swaps the two. Each step tries ``_CANDIDATES``
    random swaps in one column, evaluates the change of that column's correlations in O(d)
    each, and keeps the best if it lowers the summed squared error of both matrices.
    """
    n, d = ranks.shape
    ranks = ranks.copy()
    lin = np.arange(n) - (n - 1) / 2.0
    a = (lin / np.linalg.norm(lin))[ranks]
    v = np.take_along_axis(zs / np.linalg.norm(zs, axis=0), ranks, axis=0)
    ca, cv = a.T @ a, v.T @ v
    tol = 0.5 / n
    # at most ~900 column steps: many inputs get fewer sweeps (each step costs O(d))
    for _ in range(min(_SWEEPS, max(10, 900 // d))):
        if max(np.abs(ca - goal_ranks).max(), np.abs(cv - goal_scores).max()) <= tol:
            break
        improved = False
        for j in range(d):
            ia = rng.integers(n, size=_CANDIDATES)
            ib = rng.integers(n, size=_CANDIDATES)
            da = (a[ib, j] - a[ia, j])[:, None] * (a[ia] - a[ib])
            dv = (v[ib, j] - v[ia, j])[:, None] * (v[ia] - v[ib])
            da[:, j] = dv[:, j] = 0.0
            ea, ev = ca[j] - goal_ranks[j], cv[j] - goal_scores[j]
            ea[j] = ev[j] = 0.0
            gain = ((ea + da) ** 2 - ea**2).sum(axis=1) + ((ev + dv) ** 2 - ev**2).sum(axis=1)
            k = int(np.argmin(gain))
            if gain[k] >= 0.0:
                continue
            i1, i2 = ia[k], ib[k]
            for arr in (ranks, a, v):
                arr[[i1, i2], j] = arr[[i2, i1], j]
            for c, delta in ((ca, da[k]), (cv, dv[k])):
                c[j] += delta
                c[:, j] = c[j]
                c[j, j] = 1.0
            improved = True
        if not improved:
            break
    return ranks
