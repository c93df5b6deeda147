"""Multilevel best linear unbiased estimator (MLBLUE) of the high-fidelity mean.

Schaden, Ullmann 2020, "On multilevel best linear unbiased estimators", SIAM/ASA JUQ 8(2),
601-635; the allocation as in Croci, Willcox, Wright 2023, "Multi-output multilevel best
linear unbiased estimators via semidefinite programming" (here solved as the equivalent smooth
convex problem by SLSQP instead of the SDP).

K models, model 0 the high-fidelity one. A *group* S is a nonempty subset of the models,
evaluated together on m_S points of its own (independent of every other group's); one of its
points costs ``c_S = sum_{k in S} w_k``. With ``C_S`` the covariance block of the group's
models, ``R_S`` the restriction to them and ``Y_S`` the sums of the group's outputs over its
points, the estimator of the vector of every model's mean is

    mu_hat = Psi^{-1} sum_S R_S^T C_S^{-1} Y_S,   Psi = sum_S m_S R_S^T C_S^{-1} R_S,

unbiased whatever ``C`` is (E[Y_S] = m_S R_S mu) and, with the true ``C``, the best linear
unbiased estimator from these samples; its covariance is ``Psi^{-1}``, the HF mean's variance
``e_0^T Psi^{-1} e_0``. Every estimator of the ACV family (MFMC, ACV-MF, ACV-IS) is a linear
unbiased estimator on samples that groups of this kind can hold, so at the optimal allocation
MLBLUE's variance is at most theirs (exactly so with the true covariance; with a pilot's it is
what the pilot predicts).

The allocation minimises ``e_0^T Psi(m)^{-1} e_0`` over m_S >= 0 with ``sum_S m_S c_S <=
budget`` (convex in m), then rounds to integers within the budget. Models of no group with
points are left out (their rows and columns of Psi are empty).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from ..errors import ParameterError
from .acv import Allocation, check_ensemble

__all__ = ["GroupAllocation", "mlblue_groups", "mlblue_psi", "mlblue_variance",
           "mlblue_allocate", "mlblue_fixed_allocation", "mlblue_estimate",
           "mlblue_weighted_variance"]


@dataclass(frozen=True, eq=False)
class GroupAllocation(Allocation):
    """An :class:`~rotoruq.methods.acv.Allocation` of MLBLUE: besides the per-model fields
    (``models`` the models with points, ``n_samples`` their evaluations, the sum over the
    groups holding each), the groups and their points.

    groups : every group considered (tuples of model indices, ascending).
    group_samples : (len(groups),) integer points per group.
    group_fractions : (len(groups),) share of the budget each group got at the continuous
        optimum.
    """

    groups: tuple[tuple[int, ...], ...] = ()
    group_samples: np.ndarray | None = None
    group_fractions: np.ndarray | None = None

    def used_groups(self) -> list[tuple[tuple[int, ...], int]]:
        """``(group, points)`` for each group with points."""
        assert self.group_samples is not None
        return [(g, int(n)) for g, n in zip(self.groups, self.group_samples, strict=True) if n]


def mlblue_groups(K: int, contain: Sequence[int] = ()) -> tuple[tuple[int, ...], ...]:
    """Every nonempty subset of ``range(K)`` (containing all of ``contain``), smallest first.

    Examples
    --------
    >>> mlblue_groups(3)
    ((0,), (1,), (2,), (0, 1), (0, 2), (1, 2), (0, 1, 2))
    >>> mlblue_groups(3, contain=[0])
    ((0,), (0, 1), (0, 2), (0, 1, 2))
    """
    need = set(int(k) for k in contain)
    return tuple(g for size in range(1, K + 1) for g in itertools.combinations(range(K), size)
                 if need <= set(g))


def _blocks(cov: np.ndarray, groups) -> list[np.ndarray]:
    """R_S^T C_S^{-1} R_S, (K, K) each."""
    K = cov.shape[0]
    out = []
    for g in groups:
        B = np.zeros((K, K))
        idx = np.ix_(g, g)
        try:
            B[idx] = np.linalg.inv(cov[idx])
        except np.linalg.LinAlgError:
            B[idx] = np.linalg.pinv(cov[idx], hermitian=True)
        out.append(B)
    return out


def mlblue_psi(cov: np.ndarray, groups, m) -> np.ndarray:
    """Psi = sum_S m_S R_S^T C_S^{-1} R_S, (K, K), for the covariance ``cov`` (K, K), the
    groups (tuples of model indices) and ``m`` (len(groups),) points per group (real numbers
    allowed): the arguments of :func:`mlblue_variance`.

    Examples
    --------
    >>> mlblue_psi(np.array([[2.0]]), [(0,)], [8]).tolist()
    [[4.0]]
    """
    cov = np.asarray(cov, dtype=float)
    return np.einsum("s,skl->kl", np.asarray(m, dtype=float), np.array(_blocks(cov, groups)))


def _used(groups, m) -> list[int]:
    return sorted({k for g, n in zip(groups, m, strict=True) if n > 0 for k in g})


def mlblue_variance(cov: np.ndarray, groups, m) -> float:
    """Variance ``e_0^T Psi^{-1} e_0`` of MLBLUE's model-0 mean with ``m`` points per group
    (models of no group with points left out); inf when no group with points holds model 0.

    Parameters
    ----------
    cov : ndarray of shape (K, K)
        Covariance of the models' outputs.
    groups : sequence of tuples of int
        The groups (model indices).
    m : array_like of shape (len(groups),)
        Points per group.

    Examples
    --------
    >>> float(mlblue_variance(np.array([[2.0]]), [(0,)], [8]))
    0.25
    """
    used = _used(groups, m)
    if not used or used[0] != 0:
        return float("inf")
    P = mlblue_psi(cov, groups, m)[np.ix_(used, used)]
    try:
        return float(np.linalg.solve(P, np.eye(len(used))[0])[0])
    except np.linalg.LinAlgError:
        return float("inf")


def _continuous(cov: np.ndarray, gc: np.ndarray, groups,
                fixed: dict[int, float] | None = None) -> tuple[np.ndarray, float]:
    """Budget shares x (sum 1) minimising the HF-mean variance at budget 1, and that variance.

    m_S = x_S / c_S; f(x) = e0^T Psi^{-1} e0, grad_S = -v_S^T C_S^{-1} v_S / c_S with
    v = Psi^{-1} e0. Psi stays invertible in the interior (every singleton has a floor).
    ``fixed`` {group index: share} holds those groups' shares where they are."""
    blocks = np.array(_blocks(cov, groups))
    G = len(groups)
    scale = cov[0, 0] * gc[0] if gc[0] > 0 else 1.0  # plain MC's variance at budget 1
    e0 = np.zeros(cov.shape[0])
    e0[0] = 1.0
    floor = 1e-10

    def f_and_grad(x):
        P = np.einsum("s,skl->kl", np.maximum(x, floor) / gc, blocks)
        try:
            v = np.linalg.solve(P, e0)
        except np.linalg.LinAlgError:
            return 1e30, np.zeros(G)
        val = float(v[0]) / scale
        grad = -np.einsum("k,skl,l->s", v, blocks, v) / gc / scale
        return val, grad

    fixed = fixed or {}
    bounds = [(fixed[i], fixed[i]) if i in fixed else (0.0, 1.0) for i in range(G)]
    free = [i for i in range(G) if i not in fixed]
    rest = 1.0 - sum(fixed.values())
    starts = [np.full(G, 1.0 / G)]
    x_mc = np.full(G, 1e-3 / G)
    x_mc[groups.index((0,))] = 1.0
    starts.append(x_mc / x_mc.sum())
    for x0 in starts:  # feasible for the fixed shares: the free ones share what is left
        x0[list(fixed)] = list(fixed.values())
        x0[free] *= rest / x0[free].sum()
    best = None
    for x0 in starts:
        res = optimize.minimize(f_and_grad, x0, jac=True, method="SLSQP", bounds=bounds,
                                constraints=[{"type": "eq", "fun": lambda x: x.sum() - 1.0,
                                              "jac": lambda x: np.ones(G)}],
                                options={"maxiter": 500, "ftol": 1e-14})
        x = np.clip(res.x, 0.0, None)
        x[free] *= rest / x[free].sum()
        val = f_and_grad(x)[0]
        if best is None or val < best[1]:
            best = (x, val)
    assert best is not None
    return best[0], best[1] * scale


def _plan(cov, w, groups, m, fractions) -> GroupAllocation:
    m = np.asarray(m, dtype=int)
    used = _used(groups, m)
    per_model = np.array([sum(int(n) for g, n in zip(groups, m, strict=True) if k in g)
                          for k in used], dtype=int)
    return GroupAllocation(
        estimator="mlblue", models=tuple(used), ratios=per_model / max(per_model[0], 1),
        n_samples=per_model, cost=float(w[used] @ per_model),
        variance=mlblue_variance(cov, groups, m), groups=tuple(groups), group_samples=m,
        group_fractions=fractions)


def _rounded(gc: np.ndarray, budget: float, m_cont: np.ndarray, with0: list[int]
             ) -> np.ndarray:
    """Whole points per group from a continuous allocation: the floors, then what they left
    spent by largest remainder."""
    m = np.floor(m_cont + 1e-9).astype(int)
    if not any(m[i] for i in with0):  # the HF mean needs a point of a group holding model 0
        i = max(with0, key=lambda i: (m_cont[i], -gc[i]))
        m[i] = 1
        for j in np.argsort(-gc):  # give back what the budget cannot hold, dearest first
            while float(gc @ m) > budget * (1 + 1e-12) and m[j] > (1 if j == i else 0):
                m[j] -= 1
    # largest remainder: spend what the floors left, one more point where most was cut off
    for j in np.argsort(-(m_cont - m)):
        if m_cont[j] - m[j] > 1e-9 and float(gc @ m) + gc[j] <= budget * (1 + 1e-12):
            m[j] += 1
    return m


def _whole_points(cov: np.ndarray, gc: np.ndarray, groups, budget: float, x: np.ndarray,
                  with0: list[int]) -> np.ndarray:
    """Integer points per group near the continuous optimum's shares ``x``.

    The groups holding model 0 are the dear ones, a few dozen points each at common budgets:
    their floors leave up to a high-fidelity run unspent (about 1 % of the variance at 100
    runs). So each used one is set to its floor or its ceiling (up to 16 combinations), the
    cheap groups re-optimised with what that leaves, and the combination with the smallest
    variance at whole points kept (the plain rounding among the candidates)."""
    m_cont = x * budget / gc
    cands = [_rounded(gc, budget, m_cont, with0)]
    dear = sorted((i for i in with0 if m_cont[i] > 1e-6), key=lambda i: -m_cont[i])[:4]
    for ups in itertools.product((0, 1), repeat=len(dear)):
        counts = {i: float(np.floor(m_cont[i] + 1e-9) + u) for i, u in zip(dear, ups,
                                                                          strict=True)}
        fixed = {i: c * gc[i] / budget for i, c in counts.items()}
        fixed.update({i: 0.0 for i in with0 if i not in counts})
        if sum(fixed.values()) >= 1.0 or not any(counts.values()):
            continue
        xf, _ = _continuous(cov, gc, groups, fixed)
        m = _rounded(gc, budget, xf * budget / gc, with0)
        m[list(counts)] = [int(c) for c in counts.values()]
        if float(gc @ m) <= budget * (1 + 1e-12):
            cands.append(m)
    var = [mlblue_variance(cov, groups, m) for m in cands]
    return cands[int(np.argmin(var))]


def mlblue_allocate(cov: np.ndarray, costs, budget: float, *,
                    groups: Sequence[tuple[int, ...]] | None = None) -> GroupAllocation:
    """Points per group minimising the variance of MLBLUE's model-0 mean within ``budget``.

    Parameters
    ----------
    cov : ndarray of shape (K, K)
        Covariance of the models' outputs, model 0 the high-fidelity one.
    costs : array_like of shape (K,)
        Cost of one evaluation of each model.
    budget : float
        Total cost of the evaluations, in the units of ``costs``.
    groups : sequence of tuples of int, optional
        The groups to consider (default every nonempty subset, :func:`mlblue_groups`); one
        must be ``(0,)`` or contain model 0.

    Returns
    -------
    GroupAllocation

    Raises
    ------
    ParameterError
        When the budget does not buy one point of the cheapest group holding model 0.

    Examples
    --------
    >>> cov = np.array([[1.0, 0.9], [0.9, 1.0]])
    >>> plan = mlblue_allocate(cov, [1.0, 0.01], 100.0)
    >>> bool(plan.variance < 1.0 / 100), plan.cost <= 100.0
    (True, True)
    """
    cov, w = check_ensemble(cov, costs)
    K = w.size
    groups = mlblue_groups(K) if groups is None else tuple(tuple(sorted(set(g))) for g in groups)
    if (0,) not in groups:  # the optimiser's second start; a harmless extra group
        groups = ((0,), *groups)
    gc = np.array([float(w[list(g)].sum()) for g in groups])
    with0 = [i for i, g in enumerate(groups) if 0 in g]
    c_min = float(gc[with0].min())
    if not (np.isfinite(budget) and budget >= c_min):
        raise ParameterError(f"budget {budget:g} does not buy one high-fidelity evaluation "
                             f"(cost {c_min:g}): MLBLUE needs at least that")
    x, _ = _continuous(cov, gc, groups)
    m = _whole_points(cov, gc, groups, budget, x, with0)
    if mlblue_variance(cov, groups, m) == float("inf"):  # pragma: no cover - guarded above
        raise ParameterError("MLBLUE allocation left Psi singular")
    return _plan(cov, w, groups, m, x)


def mlblue_fixed_allocation(cov: np.ndarray, costs,
                            group_samples: Mapping[tuple[int, ...], int]) -> GroupAllocation:
    """A :class:`GroupAllocation` for given points per group ``{group: points}``.

    Parameters
    ----------
    cov : ndarray of shape (K, K)
        Covariance of the models' outputs.
    costs : array_like of shape (K,)
        Cost of one evaluation of each model.
    group_samples : mapping of tuple of int to int
        Points per group; at least one group holding model 0 needs one.
    """
    cov, w = check_ensemble(cov, costs)
    K = w.size
    groups, m = [], []
    for g, n in group_samples.items():
        gg = tuple(sorted(set(int(k) for k in g)))
        if not gg or gg[0] < 0 or gg[-1] >= K or gg in groups:
            raise ParameterError(f"group {tuple(g)!r} is not a new nonempty subset of the "
                                 f"{K} models")
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
            raise ParameterError(f"group {gg}: points must be a non-negative integer, got {n!r}")
        groups.append(gg)
        m.append(int(n))
    if not any(n and 0 in g for g, n in zip(groups, m, strict=True)):
        raise ParameterError("MLBLUE needs at least one point of a group holding the "
                             "high-fidelity model (0)")
    return _plan(cov, w, tuple(groups), m, None)


def mlblue_weighted_variance(cov: np.ndarray, cov_used: np.ndarray, groups, m) -> float:
    """Variance of MLBLUE's model-0 mean built with the covariance ``cov_used`` (a pilot's)
    when the models' true covariance is ``cov``: ``v^T M v`` with ``v`` the first row of
    ``Psi(cov_used)^{-1}`` and ``M = sum_S m_S R_S^T Cu_S^{-1} C_S Cu_S^{-1} R_S`` (the
    group sums have covariance ``m_S C_S``); :func:`mlblue_variance` when they agree.

    Parameters
    ----------
    cov, cov_used : ndarray of shape (K, K)
        The true covariance and the one the estimator's weights come from.
    groups : sequence of tuples of int
        The groups.
    m : array_like of shape (len(groups),)
        Points per group.

    Examples
    --------
    >>> cov = np.array([[1.0, 0.9], [0.9, 1.0]])
    >>> g, m = [(0,), (0, 1), (1,)], [0, 10, 90]
    >>> bool(np.isclose(mlblue_weighted_variance(cov, cov, g, m), mlblue_variance(cov, g, m)))
    True
    """
    used = _used(groups, m)
    B = np.array(_blocks(np.asarray(cov_used, dtype=float), groups))
    mm = np.asarray(m, dtype=float)
    P = np.einsum("s,skl->kl", mm, B)[np.ix_(used, used)]
    M = np.einsum("s,skl,lq,sqr->kr", mm, B, np.asarray(cov, dtype=float), B)[np.ix_(used, used)]
    v = np.linalg.pinv(P, hermitian=True)[0]
    return float(v @ M @ v)


def mlblue_estimate(cov: np.ndarray, groups, sums: Sequence[np.ndarray], m
                    ) -> tuple[float, float]:
    """MLBLUE's model-0 mean and its predicted variance.

    Parameters
    ----------
    cov : ndarray of shape (K, K)
        Covariance of the models' outputs (the pilot's, or the exact one).
    groups : sequence of tuples of int
        The groups.
    sums : sequence of ndarray
        Per group, the sums of its models' outputs over its points (shape (len(group),);
        anything for a group without points).
    m : array_like of shape (len(groups),)
        Points per group.

    Examples
    --------
    >>> y = np.array([1.0, 2.0, 4.0])
    >>> mean, var = mlblue_estimate(np.array([[3.0]]), [(0,)], [np.array([y.sum()])], [3])
    >>> round(mean, 12), round(var, 12)
    (2.333333333333, 1.0)
    """
    cov = np.asarray(cov, dtype=float)
    used = _used(groups, m)
    if not used or used[0] != 0:
        raise ParameterError("MLBLUE needs a point of a group holding model 0")
    pos = {k: i for i, k in enumerate(used)}
    n = len(used)
    P = np.zeros((n, n))
    rhs = np.zeros(n)
    for g, s, mg in zip(groups, sums, m, strict=True):
        if not mg:
            continue
        ix = [pos[k] for k in g]
        Ci = np.linalg.pinv(cov[np.ix_(g, g)], hermitian=True)
        P[np.ix_(ix, ix)] += mg * Ci
        rhs[ix] += Ci @ np.asarray(s, dtype=float)
    Pinv = np.linalg.pinv(P, hermitian=True)
    return float(Pinv[0] @ rhs), float(Pinv[0, 0])
