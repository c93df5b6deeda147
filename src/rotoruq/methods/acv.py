"""Approximate-control-variate algebra: sample-set structures, estimator covariances and the
optimal allocation of a budget over a model ensemble.

An ensemble estimator of a statistic Q of model 0 (the high-fidelity model) is

    Q_hat = Q_0(z_0) + sum_k alpha_k (Q_k(z_k*) - Q_k(z_k)),   k = 1 .. K-1,

where ``Q_k(z)`` is the plain sample estimator (mean, or unbiased variance) of model k on the
sample set z. The estimators differ only in how the sets overlap (Gorodetsky, Geraci, Eldred,
Jakeman 2020, JCP 408):

* ``"mfmc"`` (Peherstorfer, Willcox, Gunzburger 2016): one nested stream, model k on its first
  n_k points, ``z_k* = z_{k-1}`` (the previous model's points), n_0 <= n_1 <= ...;
* ``"acvmf"``: one nested stream, ``z_k* = z_0`` for every k, ``z_k`` the first n_k points;
* ``"acvis"``: ``z_k* = z_0`` and ``z_k = z_0`` plus n_k - n_0 points of its own, independent of
  every other model's.

Every covariance follows from the set sizes and their overlaps: for sample means
``Cov[m_i(A), m_j(B)] = C_ij |A & B| / (|A| |B|)``; for unbiased sample variances (U-statistics
of degree 2 with kernel (y - y')^2 / 2) with a = |A|, b = |B|, c = |A & B|

    Cov[v_i(A), v_j(B)] = [c (c - 1) / 2 * z2 + c ((a - 1)(b - 1) - (c - 1)) * z1]
                          / [a (a - 1) b (b - 1) / 4],
    z1 = (M_ij - C_ii C_jj) / 4,   z2 = M_ij / 2 - C_ii C_jj / 2 + C_ij^2,

with ``M_ij = E[(y_i - mu_i)^2 (y_j - mu_j)^2]``. With the optimal weights
``alpha = -Cov[Delta]^+ Cov[Delta, Q_0]`` the estimator variance is
``Var[Q_0] - c^T Cov[Delta]^+ c``.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from ..errors import ParameterError

__all__ = ["ESTIMATORS", "Allocation", "SampleSets", "sample_sets", "estimator_covariance",
           "estimator_variance", "optimal_weights", "allocate", "fixed_allocation",
           "mfmc_ratios"]

ESTIMATORS = ("mfmc", "acvmf", "acvis")


@dataclass(frozen=True, eq=False)
class SampleSets:
    """Where each model's sample sets lie in one list of independent points.

    sets : (2K - 1, 2, 2) intervals [lo, hi) of point indices (two per set, the second may be
        empty): set 0 is z_0, set 2k - 1 is z_k* and set 2k is z_k (k = 1 .. K-1).
    model_of_set : (2K - 1,) which model each set is evaluated with.
    n_points : distinct points the design draws.
    """

    sets: np.ndarray
    model_of_set: np.ndarray
    n_points: float

    def size(self) -> np.ndarray:
        """(2K - 1,) number of points in each set."""
        return np.sum(self.sets[:, :, 1] - self.sets[:, :, 0], axis=1)

    def overlap(self) -> np.ndarray:
        """(2K - 1, 2K - 1) number of points each pair of sets shares."""
        lo = np.maximum(self.sets[:, None, :, None, 0], self.sets[None, :, None, :, 0])
        hi = np.minimum(self.sets[:, None, :, None, 1], self.sets[None, :, None, :, 1])
        return np.sum(np.maximum(hi - lo, 0.0), axis=(2, 3))

    def indices(self, s: int) -> np.ndarray:
        """Point indices (integers) of set ``s``."""
        return np.concatenate([np.arange(int(a), int(b)) for a, b in self.sets[s]])


def sample_sets(estimator: str, n_samples) -> SampleSets:
    """The sample sets of ``estimator`` for ``n_samples`` (K,) evaluations per model (model 0
    first); sizes may be real numbers (continuous relaxation for the allocation)."""
    n = np.asarray(n_samples, dtype=float)
    K = n.size
    sets = np.zeros((2 * K - 1, 2, 2))
    sets[0, 0] = (0.0, n[0])
    offset = n[0]
    for k in range(1, K):
        if estimator == "mfmc":
            sets[2 * k - 1, 0] = (0.0, n[k - 1])
            sets[2 * k, 0] = (0.0, n[k])
        elif estimator == "acvmf":
            sets[2 * k - 1, 0] = (0.0, n[0])
            sets[2 * k, 0] = (0.0, n[k])
        elif estimator == "acvis":
            sets[2 * k - 1, 0] = (0.0, n[0])
            sets[2 * k, 0] = (0.0, n[0])
            sets[2 * k, 1] = (offset, offset + n[k] - n[0])
            offset += n[k] - n[0]
        else:
            raise ParameterError(f"unknown estimator {estimator!r}; valid: {', '.join(ESTIMATORS)}")
    n_points = offset if estimator == "acvis" else float(n.max())
    model_of_set = np.array([0] + [k for k in range(1, K) for _ in (0, 1)], dtype=int)
    return SampleSets(sets=sets, model_of_set=model_of_set, n_points=n_points)


def estimator_covariance(sets: SampleSets, statistic: str, cov: np.ndarray,
                         m22: np.ndarray | None = None) -> np.ndarray:
    """Covariance (2K - 1, 2K - 1) of the plain sample estimators on every set.

    cov : (K, K) covariance of the models' outputs; m22 : (K, K) ``E[d_i^2 d_j^2]`` of the
    centred outputs (needed for ``statistic="variance"``).
    """
    mo = sets.model_of_set
    C = np.asarray(cov, dtype=float)[np.ix_(mo, mo)]
    a = sets.size()
    c = sets.overlap()
    if statistic == "mean":
        return C * c / np.outer(a, a)
    if statistic != "variance":
        raise ParameterError(f"unknown statistic {statistic!r}; valid: mean, variance")
    if m22 is None:
        raise ParameterError("the variance statistic needs the fourth moments m22")
    M = np.asarray(m22, dtype=float)[np.ix_(mo, mo)]
    var = np.diag(np.asarray(cov, dtype=float))[mo]
    vv = np.outer(var, var)
    z1 = (M - vv) / 4.0
    z2 = M / 2.0 - vv / 2.0 + C**2
    A, B = a[:, None], a[None, :]
    num = c * (c - 1.0) / 2.0 * z2 + c * ((A - 1.0) * (B - 1.0) - (c - 1.0)) * z1
    return num / (A * (A - 1.0) * B * (B - 1.0) / 4.0)


def _split(S: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Var[Q_0], Cov[Delta, Q_0] and Cov[Delta] from the set covariance, Delta_k = Q_k(z_k*) -
    Q_k(z_k) (set 2k - 1 minus set 2k)."""
    a, b = slice(1, None, 2), slice(2, None, 2)
    c = S[a, 0] - S[b, 0]
    CD = S[a, a] - S[a, b] - S[b, a] + S[b, b]
    return float(S[0, 0]), c, CD


def optimal_weights(S: np.ndarray) -> tuple[np.ndarray, float]:
    """Control-variate weights alpha (K - 1,) minimising the variance, and that variance."""
    v0, c, CD = _split(S)
    if c.size == 0:
        return np.zeros(0), v0
    try:
        alpha = -np.linalg.solve(CD, c)
        if not np.all(np.isfinite(alpha)):
            raise np.linalg.LinAlgError
    except np.linalg.LinAlgError:  # a Delta identically zero (z_k* = z_k)
        alpha = -np.linalg.pinv(CD, rcond=1e-12, hermitian=True) @ c
    return alpha, float(v0 + alpha @ c)


def estimator_variance(estimator: str, n_samples, statistic: str, cov: np.ndarray,
                       m22: np.ndarray | None = None) -> float:
    """Variance of the optimally weighted ensemble estimator with ``n_samples`` (K,)."""
    S = estimator_covariance(sample_sets(estimator, n_samples), statistic, cov, m22)
    return optimal_weights(S)[1]


@dataclass(frozen=True, eq=False)
class Allocation:
    """How a budget is spent over the models (see :func:`allocate`).

    models : indices (into the given ensemble) of the models used, model 0 first, in the order
        the estimator uses them.
    ratios : (len(models),) continuous optimum r_k = n_k / n_0 (r_0 = 1).
    n_samples : (len(models),) integer evaluations per model used.
    cost : cost of ``n_samples`` (<= budget).
    variance : predicted variance of the target's mean estimator at ``n_samples``.
    """

    estimator: str
    models: tuple[int, ...]
    ratios: np.ndarray
    n_samples: np.ndarray
    cost: float
    variance: float


def mfmc_ratios(rho: np.ndarray, costs: np.ndarray) -> np.ndarray | None:
    """Peherstorfer et al. (2016) thm. 3.4 optimal ratios r_k (r_0 = 1) for models ordered by
    decreasing |rho| (rho[0] = 1), or None when the ordering or the cost condition fails."""
    r2 = np.append(np.asarray(rho, dtype=float) ** 2, 0.0)
    w = np.asarray(costs, dtype=float)
    if np.any(np.diff(r2) >= 0):  # |rho| strictly decreasing, the last one above 0
        return None
    for k in range(1, w.size):  # w_{k-1} / w_k > (rho_{k-1}^2 - rho_k^2) / (rho_k^2 - rho_{k+1}^2)
        if not w[k - 1] / w[k] > (r2[k - 1] - r2[k]) / (r2[k] - r2[k + 1]):
            return None
    return np.sqrt(w[0] * (r2[:-1] - r2[1:]) / (w * (1.0 - r2[1])))


def _integer(estimator: str, n: np.ndarray) -> np.ndarray:
    out = np.floor(n + 1e-9).astype(int)
    for k in range(1, out.size):
        low = out[k - 1] if estimator == "mfmc" else out[0]
        out[k] = max(out[k], low)
    return out


def _continuous(estimator: str, cov: np.ndarray, w: np.ndarray, budget: float,
                start: np.ndarray | None) -> tuple[np.ndarray, float]:
    """Optimal ratios (K,) over the continuous relaxation, r_k = 1 + exp(t_k) (mfmc: increasing,
    r_k = r_{k-1} + exp(t_k)), and the variance there."""
    K = w.size

    def ratios(t):
        step = np.exp(np.clip(t, -30.0, 30.0))
        return np.concatenate([[1.0], np.cumsum(step) + 1.0 if estimator == "mfmc"
                               else 1.0 + step])

    def objective(t):
        r = ratios(t)
        n0 = budget / float(w @ r)
        return np.log(estimator_variance(estimator, n0 * r, "mean", cov))

    # equal ratios are a kink of the nested estimators' variance (min(r_i, r_j)), where the
    # simplex stalls: start from nearly equal small and large ratios, and from MFMC's
    spread = 0.01 * np.arange(K - 1)
    starts = [np.log(np.maximum(np.diff(start) if estimator == "mfmc" else start[1:] - 1.0,
                                1e-6))] if start is not None else []
    starts += [np.log(3.0) + spread, np.log(100.0) + spread]
    best = None
    for t0 in starts:
        res = optimize.minimize(objective, t0, method="Nelder-Mead",
                                options={"xatol": 1e-4, "fatol": 1e-10, "maxfev": 300 * K})
        if best is None or res.fun < best.fun:
            best = res
    assert best is not None
    res = optimize.minimize(objective, best.x, method="Nelder-Mead",  # restart: a fresh simplex
                            options={"xatol": 1e-5, "fatol": 1e-12, "maxfev": 300 * K})
    best = res if res.fun < best.fun else best
    return ratios(best.x), float(np.exp(best.fun))


def fixed_allocation(cov: np.ndarray, costs, n_samples, *, estimator: str = "mfmc"
                     ) -> Allocation:
    """An :class:`Allocation` for given evaluations per model (K,), 0 leaving a model out;
    checks the estimator's structure (n_0 >= 2; mfmc: non-decreasing in the order given,
    acv: every n_k >= n_0)."""
    if estimator not in ESTIMATORS:
        raise ParameterError(f"unknown estimator {estimator!r}; valid: {', '.join(ESTIMATORS)}")
    n_all = np.asarray(n_samples)
    w = np.asarray(costs, dtype=float)
    if n_all.shape != w.shape or not np.issubdtype(n_all.dtype, np.integer) or np.any(n_all < 0):
        raise ParameterError(f"allocation must be {w.size} non-negative integers (evaluations "
                             f"per model, 0 to leave one out), got {n_samples!r}")
    models = tuple(int(k) for k in np.flatnonzero(n_all))
    if not models or models[0] != 0 or n_all[0] < 2:
        raise ParameterError(f"allocation must give the high-fidelity model at least 2 "
                             f"evaluations, got {n_all.tolist()}")
    n = n_all[list(models)].astype(int)
    low = np.maximum.accumulate(n) if estimator == "mfmc" else np.full(n.size, n[0])
    if np.any(n < low):
        rule = ("non-decreasing from model to model" if estimator == "mfmc"
                else "at least the high-fidelity model's for every other model")
        raise ParameterError(f"allocation {n_all.tolist()} does not fit {estimator}: the "
                             f"evaluations must be {rule}")
    sub = np.asarray(cov, dtype=float)[np.ix_(models, models)]
    return Allocation(estimator=estimator, models=models, ratios=n / n[0], n_samples=n,
                      cost=float(w[list(models)] @ n),
                      variance=estimator_variance(estimator, n, "mean", sub))


def allocate(cov: np.ndarray, costs, budget: float, *, estimator: str = "mfmc",
             select: bool = True) -> Allocation:
    """Spend ``budget`` over an ensemble to minimise the variance of model 0's mean estimator.

    Parameters
    ----------
    cov : (K, K) covariance of the models' outputs (model 0 the high-fidelity one).
    costs : (K,) cost of one evaluation of each model (any unit; ``budget`` in the same).
    budget : total cost of the evaluations to allocate.
    estimator : "mfmc" (closed form, thm. 3.4 of Peherstorfer et al. 2016, models ordered by
        decreasing correlation with model 0), "acvmf" or "acvis" (numerical optimisation of the
        estimator variance over the ratios r_k = n_k / n_0 >= 1, n_0 = budget / (w . r)).
    select : try every subset of the low-fidelity models and keep the best (Peherstorfer et
        al., algorithm 1); else use them all (mfmc: those satisfying its conditions, in order).

    Returns
    -------
    Allocation
    """
    if estimator not in ESTIMATORS:
        raise ParameterError(f"unknown estimator {estimator!r}; valid: {', '.join(ESTIMATORS)}")
    cov = np.asarray(cov, dtype=float)
    w = np.asarray(costs, dtype=float)
    K = w.size
    if cov.shape != (K, K):
        raise ParameterError(f"cov must be ({K}, {K}) for {K} costs, got {cov.shape}")
    if not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise ParameterError(f"costs must be positive and finite, got {w.tolist()}")
    if not (np.isfinite(budget) and budget > 0):
        raise ParameterError(f"budget must be positive, got {budget}")
    sd = np.sqrt(np.diag(cov))
    if np.any(sd <= 0):
        raise ParameterError("every model's output must vary over the pilot (a zero variance "
                             f"was found: std {sd.tolist()})")
    rho = cov[0] / (sd[0] * sd)
    order = [0] + sorted(range(1, K), key=lambda k: (-abs(rho[k]), k))
    subsets = ([tuple(s) for m in range(K) for s in itertools.combinations(order[1:], m)]
               if select else [tuple(order[1:])])
    best: tuple[float, tuple[int, ...], np.ndarray] | None = None
    for lf in subsets:
        idx = [0, *lf]
        sub_cov, sub_w = cov[np.ix_(idx, idx)], w[idx]
        if len(idx) == 1:
            r = np.ones(1)
        elif estimator == "mfmc":
            r_or_none = mfmc_ratios(rho[idx], sub_w)
            if r_or_none is None:
                continue
            r = r_or_none
        else:
            start = mfmc_ratios(rho[idx], sub_w)
            r = _continuous(estimator, sub_cov, sub_w, budget, start)[0]
        n0 = budget / float(sub_w @ r)
        var = estimator_variance(estimator, n0 * r, "mean", sub_cov)
        if best is None or var < best[0] * (1.0 - 1e-9):
            best = (var, tuple(idx), r)
    assert best is not None  # the HF model alone is always admissible
    _, models, r = best
    sub_cov, sub_w = cov[np.ix_(models, models)], w[list(models)]
    n_cont = budget / float(sub_w @ r) * r
    if n_cont[0] < 2.0 and len(models) > 1:
        # the optimum wants fewer than the 2 high-fidelity runs a variance needs (a very good
        # low-fidelity model): take 2 and spread what is left in the optimum's proportions
        low = 2.0 * sub_w[0] + 2.0 * float(sub_w[1:].sum())
        if budget >= low:
            lf = n_cont[1:] * (budget - 2.0 * sub_w[0]) / float(sub_w[1:] @ n_cont[1:])
            n_cont = np.concatenate([[2.0], np.maximum(lf, 2.0)])
    n = _integer(estimator, n_cont)
    while float(sub_w @ n) > budget * (1 + 1e-12) and n[-1] > n[0]:
        n[-1] -= 1  # rounding the floors up to 2 may overspend: trim the cheapest set
    if n[0] < 2 or float(sub_w @ n) > budget * (1 + 1e-12):
        raise ParameterError(
            f"budget {budget:g} buys {int(n_cont[0])} high-fidelity evaluation(s) with the "
            f"{estimator} allocation (costs {w[list(models)].tolist()}); at least 2 are "
            f"needed: raise the budget above {2 * float(sub_w @ r):g}")
    return Allocation(estimator=estimator, models=models, ratios=r, n_samples=n,
                      cost=float(sub_w @ n),
                      variance=estimator_variance(estimator, n, "mean", sub_cov))
