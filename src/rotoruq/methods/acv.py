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

__all__ = ["ESTIMATORS", "GENERALIZED", "check_ensemble", "Allocation", "SampleSets",
           "sample_sets", "set_sizes",
           "default_recursion", "recursion_indices", "estimator_covariance",
           "estimator_variance", "optimal_weights", "weighted_variance",
           "weights_stack", "weighted_variance_stack", "allocate", "fixed_allocation",
           "mfmc_ratios"]

ESTIMATORS = ("mfmc", "acvmf", "acvis")
#: The generalized ACV families of Bomarito et al. 2022, any recursion index.
GENERALIZED = ("gmf", "grd", "gis")


@dataclass(frozen=True, eq=False)
class SampleSets:
    """Where each model's sample sets lie in one list of independent points.

    sets : (2K - 1, J, 2) intervals [lo, hi) of point indices (a set is the union of its J
        intervals, some empty): set 0 is z_0, set 2k - 1 is z_k* and set 2k is z_k
        (k = 1 .. K-1).
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
        """Point indices (integers, ascending) of set ``s``."""
        return np.unique(np.concatenate([np.arange(int(a), int(b)) for a, b in self.sets[s]]))

    def model_points(self, k: int) -> np.ndarray:
        """Point indices (integers, ascending) model ``k`` runs on: the union of its sets."""
        return np.unique(np.concatenate([self.indices(int(s))
                                         for s in np.flatnonzero(self.model_of_set == k)]))


def default_recursion(estimator: str, K: int) -> tuple[int, ...]:
    """The recursion index of a named estimator: MFMC's chain ``(0, 1, .., K-2)``, else every
    model's control variate on model 0, ``(0, .., 0)``."""
    return tuple(range(K - 1)) if estimator == "mfmc" else (0,) * (K - 1)


def _family(estimator: str, recursion, K: int) -> tuple[str, tuple[int, ...]]:
    """(family, recursion index) of an estimator: mfmc and acvmf are GMF, acvis is GIS."""
    if estimator not in (*ESTIMATORS, *GENERALIZED):
        raise ParameterError(f"unknown estimator {estimator!r}; valid: "
                             f"{', '.join((*ESTIMATORS, *GENERALIZED))}")
    family = {"mfmc": "gmf", "acvmf": "gmf", "acvis": "gis"}.get(estimator, estimator)
    gamma = default_recursion(estimator, K) if recursion is None else tuple(
        int(g) for g in recursion)
    if len(gamma) != K - 1 or any(not 0 <= g < k for k, g in enumerate(gamma, start=1)):
        raise ParameterError(f"recursion index must give each of models 1..{K - 1} a parent "
                             f"listed before it (0 <= gamma_k < k), got {list(gamma)}")
    if estimator in ESTIMATORS and gamma != default_recursion(estimator, K):
        raise ParameterError(f"estimator {estimator!r} has the recursion index "
                             f"{list(default_recursion(estimator, K))}; for another use "
                             f"'gmf', 'grd' or 'gis'")
    return family, gamma


def set_sizes(estimator: str, n_samples, recursion=None) -> np.ndarray:
    """(K,) sizes |z_k| of the sets from the evaluations per model ``n_samples`` (K,): equal
    for GMF and GIS; for GRD model k runs on z_{gamma_k} and its own disjoint z_k, so
    ``|z_k| = n_k - |z_{gamma_k}|``."""
    n = np.asarray(n_samples, dtype=float)
    family, gamma = _family(estimator, recursion, n.size)
    if family != "grd":
        return n.copy()
    N = n.copy()
    for k, p in enumerate(gamma, start=1):
        N[k] = n[k] - N[p]
    return N


def sample_sets(estimator: str, n_samples, recursion=None) -> SampleSets:
    """The sample sets of ``estimator`` for ``n_samples`` (K,) evaluations per model (model 0
    first); sizes may be real numbers (continuous relaxation for the allocation).

    ``recursion`` (K - 1,) is the parent ``gamma_k < k`` of each model k >= 1 (Bomarito et
    al. 2022; default the named estimator's, :func:`default_recursion`): ``z_k* =
    z_{gamma_k}``, and ``z_k`` is, for "gmf", the first n_k points of one nested stream
    (``n_k >= n_{gamma_k}``); for "gis", ``z_{gamma_k}`` plus ``n_k - n_{gamma_k}`` points of
    its own; for "grd", points of its own only (model k runs on both sets).
    """
    n = np.asarray(n_samples, dtype=float)
    K = n.size
    family, gamma = _family(estimator, recursion, K)
    N = set_sizes(estimator, n, gamma)
    z: list[list[tuple[float, float]]] = [[(0.0, N[0])]]
    offset = float(N[0]) if family != "gmf" else float(N.max())
    sets = np.zeros((2 * K - 1, K, 2))
    sets[0, 0] = z[0][0]
    for k, p in enumerate(gamma, start=1):
        if family == "gmf":
            zk = [(0.0, N[k])]
        elif family == "gis":
            zk = [*z[p], (offset, offset + N[k] - N[p])]
            offset += N[k] - N[p]
        else:
            zk = [(offset, offset + N[k])]
            offset += N[k]
        z.append(zk)
        sets[2 * k - 1, :len(z[p])] = z[p]
        sets[2 * k, :len(zk)] = zk
    model_of_set = np.array([0] + [k for k in range(1, K) for _ in (0, 1)], dtype=int)
    return SampleSets(sets=sets, model_of_set=model_of_set, n_points=offset)


def estimator_covariance(sets: SampleSets, statistic: str, cov: np.ndarray,
                         m22: np.ndarray | None = None) -> np.ndarray:
    """Covariance (..., 2K - 1, 2K - 1) of the plain sample estimators on every set.

    cov : (..., K, K) covariance of the models' outputs (leading axes: a stack of them);
    m22 : (..., K, K) ``E[d_i^2 d_j^2]`` of the centred outputs (needed for
    ``statistic="variance"``).
    """
    mo = sets.model_of_set
    pick = (..., mo[:, None], mo[None, :])
    C = np.asarray(cov, dtype=float)[pick]
    a = sets.size()
    c = sets.overlap()
    if statistic == "mean":
        return C * c / np.outer(a, a)
    if statistic != "variance":
        raise ParameterError(f"unknown statistic {statistic!r}; valid: mean, variance")
    if m22 is None:
        raise ParameterError("the variance statistic needs the fourth moments m22")
    M = np.asarray(m22, dtype=float)[pick]
    var = np.diagonal(np.asarray(cov, dtype=float), axis1=-2, axis2=-1)[..., mo]
    vv = var[..., :, None] * var[..., None, :]
    z1 = (M - vv) / 4.0
    z2 = M / 2.0 - vv / 2.0 + C**2
    A, B = a[:, None], a[None, :]
    num = c * (c - 1.0) / 2.0 * z2 + c * ((A - 1.0) * (B - 1.0) - (c - 1.0)) * z1
    return num / (A * (A - 1.0) * B * (B - 1.0) / 4.0)


def _split(S: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Var[Q_0], Cov[Delta, Q_0] and Cov[Delta] from the set covariance (..., 2K - 1, 2K - 1),
    Delta_k = Q_k(z_k*) - Q_k(z_k) (set 2k - 1 minus set 2k)."""
    a, b = slice(1, None, 2), slice(2, None, 2)
    c = S[..., a, 0] - S[..., b, 0]
    CD = S[..., a, a] - S[..., a, b] - S[..., b, a] + S[..., b, b]
    return S[..., 0, 0], c, CD


def weights_stack(S: np.ndarray) -> np.ndarray:
    """Optimal weights (B, K - 1) for a stack of set covariances (B, 2K - 1, 2K - 1) (the
    pseudo-inverse where a Delta is identically zero)."""
    _, c, CD = _split(S)
    return -np.einsum("bkl,bl->bk", np.linalg.pinv(CD, rcond=1e-12, hermitian=True), c)


def weighted_variance_stack(S: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(B,) variances of estimators with weights ``alpha`` (B, K - 1) on the set covariances
    ``S`` (B, 2K - 1, 2K - 1) (:func:`weighted_variance` for each)."""
    v0, c, CD = _split(S)
    return v0 + 2.0 * np.einsum("bk,bk->b", alpha, c) + np.einsum("bk,bkl,bl->b", alpha, CD,
                                                                   alpha)


def optimal_weights(S: np.ndarray) -> tuple[np.ndarray, float]:
    """Control-variate weights alpha (K - 1,) minimising the variance, and that variance."""
    v0, c, CD = _split(S)
    if c.size == 0:
        return np.zeros(0), float(v0)
    try:
        alpha = -np.linalg.solve(CD, c)
        if not np.all(np.isfinite(alpha)):
            raise np.linalg.LinAlgError
    except np.linalg.LinAlgError:  # a Delta identically zero (z_k* = z_k)
        alpha = -np.linalg.pinv(CD, rcond=1e-12, hermitian=True) @ c
    return alpha, float(v0 + alpha @ c)


def weighted_variance(S: np.ndarray, alpha: np.ndarray) -> float:
    """Variance of the estimator with weights ``alpha`` (K - 1,) when its sets' estimators
    have the covariance ``S`` (2K - 1, 2K - 1): ``Var[Q_0] + 2 alpha . c + alpha^T Cov[Delta]
    alpha`` (at the optimal weights, what :func:`optimal_weights` returns).

    Examples
    --------
    >>> S = estimator_covariance(sample_sets("acvmf", [10, 100]), "mean",
    ...                          np.array([[1.0, 0.9], [0.9, 1.0]]))
    >>> alpha, v = optimal_weights(S)
    >>> bool(np.isclose(weighted_variance(S, alpha), v)), weighted_variance(S, 0 * alpha)
    (True, 0.1)
    """
    a = np.asarray(alpha, dtype=float)
    return float(weighted_variance_stack(S[None], a[None])[0])


def estimator_variance(estimator: str, n_samples, statistic: str, cov: np.ndarray,
                       m22: np.ndarray | None = None, recursion=None) -> float:
    """Variance of the optimally weighted ensemble estimator with ``n_samples`` (K,)."""
    S = estimator_covariance(sample_sets(estimator, n_samples, recursion), statistic, cov, m22)
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
    recursion : the recursion index (len(models) - 1,): the position in ``models`` of each
        model's parent (empty for MLBLUE).
    """

    estimator: str
    models: tuple[int, ...]
    ratios: np.ndarray
    n_samples: np.ndarray
    cost: float
    variance: float
    recursion: tuple[int, ...] = ()


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


def recursion_indices(K: int) -> list[tuple[int, ...]]:
    """Every recursion index over K models listed by decreasing correlation with model 0
    whose parents come before their children, ``gamma_k < k``: (K - 1)! trees rooted at model
    0, from ACV-MF's ``(0, .., 0)`` to MFMC's chain ``(0, 1, .., K - 2)`` (Bomarito et al.
    2022 search every tree; a model's control variate on a less correlated one is left out
    here, which keeps the search to 24 trees for 5 models instead of 125).

    Examples
    --------
    >>> recursion_indices(3)
    [(0, 0), (0, 1)]
    """
    return list(itertools.product(*(range(k) for k in range(1, K))))


def _own_floor(family: str) -> int:
    """Fewest points of its own a GRD set needs (two: a sample variance)."""
    return 2 if family == "grd" else 0


def _lower(family: str, gamma, n: np.ndarray) -> np.ndarray:
    """(K,) fewest evaluations each model may have given its parent's (n_0: 2)."""
    N = set_sizes(family, n, gamma)
    low = np.full(n.size, 2.0)
    for k, p in enumerate(gamma, start=1):
        low[k] = N[p] + _own_floor(family) if family == "grd" else n[p]
    return low


def _integer(estimator: str, n: np.ndarray, recursion=None) -> np.ndarray:
    family, gamma = _family(estimator, recursion, n.size)
    out = np.floor(n + 1e-9).astype(int)
    N = out.copy()
    for k, p in enumerate(gamma, start=1):
        low = N[p] + _own_floor(family) if family == "grd" else out[p]
        out[k] = max(out[k], low)
        N[k] = out[k] - N[p] if family == "grd" else out[k]
    return out


def _ratios(family: str, gamma, t: np.ndarray) -> np.ndarray:
    """Evaluations per model for n_0 = 1 from free variables t (K - 1,): a model's set grows
    on its parent's by exp(t_k) (GMF, GIS), or is exp(t_k) of its own (GRD)."""
    step = np.exp(np.clip(t, -30.0, 30.0))
    r = np.ones(len(gamma) + 1)
    N = np.ones(len(gamma) + 1)
    for k, p in enumerate(gamma, start=1):
        r[k] = (N[p] if family == "grd" else r[p]) + step[k - 1]
        N[k] = step[k - 1] if family == "grd" else r[k]
    return r


def _continuous(estimator: str, cov: np.ndarray, w: np.ndarray, budget: float,
                start: np.ndarray | None, recursion=None, *, effort: int = 300
                ) -> tuple[np.ndarray, float]:
    """Optimal ratios (K,) over the continuous relaxation (:func:`_ratios`), and the variance
    there; ``effort`` evaluations of the variance per free variable and start."""
    K = w.size
    family, gamma = _family(estimator, recursion, K)

    def objective(t):
        r = _ratios(family, gamma, t)
        n0 = budget / float(w @ r)
        return np.log(estimator_variance(estimator, n0 * r, "mean", cov, recursion=gamma))

    # equal ratios are a kink of the nested estimators' variance (min(r_i, r_j)), where the
    # simplex stalls: start from nearly equal small and large ratios, and from MFMC's
    spread = 0.01 * np.arange(K - 1)
    starts = []
    if start is not None:
        own = set_sizes(family, start, gamma) if family == "grd" else None
        steps = [own[k] if own is not None else start[k] - start[p]
                 for k, p in enumerate(gamma, start=1)]
        starts.append(np.log(np.maximum(steps, 1e-6)))
    starts += [np.log(3.0) + spread, np.log(100.0) + spread]
    best = None
    for t0 in starts[:1] if effort < 300 else starts:
        res = optimize.minimize(objective, t0, method="Nelder-Mead",
                                options={"xatol": 1e-4, "fatol": 1e-10, "maxfev": effort * K})
        if best is None or res.fun < best.fun:
            best = res
    assert best is not None
    if effort >= 300:
        res = optimize.minimize(objective, best.x, method="Nelder-Mead",  # a fresh simplex
                                options={"xatol": 1e-5, "fatol": 1e-12, "maxfev": effort * K})
        best = res if res.fun < best.fun else best
    return _ratios(family, gamma, best.x), float(np.exp(best.fun))


def _rounded(estimator: str, n_cont: np.ndarray, w: np.ndarray, budget: float, gamma
             ) -> np.ndarray:
    """Whole runs from a continuous allocation (K,): the floors, raised to what each model's
    parent requires, then trimmed to the budget."""
    family = _family(estimator, gamma, n_cont.size)[0]
    n = _integer(estimator, n_cont, gamma)
    parents = set(gamma)
    while float(w @ n) > budget * (1 + 1e-12):
        # rounding the floors up may overspend: trim a model no other one leans on, the one
        # spending most, while it keeps what its parent requires
        slack = [k for k in range(1, n.size)
                 if k not in parents and n[k] > _lower(family, gamma, n)[k]]
        if not slack:
            break
        n[max(slack, key=lambda k: (w[k] * n[k], k))] -= 1
    return n


def _whole_runs(estimator: str, cov: np.ndarray, w: np.ndarray, budget: float, r: np.ndarray,
                gamma) -> np.ndarray:
    """The integer allocation (K,) for the continuous optimum's ratios ``r`` (K,).

    Flooring every count leaves up to one high-fidelity run's cost unspent, 1 % of the
    variance at 100 runs (the loss PyApprox's reported continuous optimum does not carry). So
    the high-fidelity count is fixed at each whole number next to the optimum's, the
    low-fidelity models' shape re-optimised with the budget that count leaves, and the
    candidate with the smallest variance at its whole runs kept (the plain floors among
    them)."""
    K = w.size
    n_cont = budget / float(w @ r) * r
    if n_cont[0] < 2.0 and K > 1:
        # the optimum wants fewer than the 2 high-fidelity runs a variance needs (a very good
        # low-fidelity model): take 2 and spread what is left in the optimum's proportions
        low = 2.0 * w[0] + 2.0 * float(w[1:].sum())
        if budget >= low:
            lf = n_cont[1:] * (budget - 2.0 * w[0]) / float(w[1:] @ n_cont[1:])
            n_cont = np.concatenate([[2.0], np.maximum(lf, 2.0)])
    cands = [_rounded(estimator, n_cont, w, budget, gamma)]
    family = _family(estimator, gamma, K)[0]
    if K > 1:
        # n(n0, lam) = n0 a + lam (r(t) - a) is linear in the high-fidelity count n0 and the
        # low-fidelity steps' scale lam (:func:`_ratios`): fix n0, spend the rest through lam
        a = _ratios(family, gamma, np.full(K - 1, -np.inf))
        steps = [(set_sizes(family, r, gamma)[k] if family == "grd" else r[k] - r[p])
                 for k, p in enumerate(gamma, start=1)]
        t_opt = np.log(np.maximum(steps, 1e-12))

        def counts(n0: float, t: np.ndarray) -> np.ndarray | None:
            shape = _ratios(family, gamma, t) - a
            lam = (budget - n0 * float(w @ a)) / float(w @ shape)
            return n0 * a + lam * shape if lam > 0 else None

        for n0 in {int(np.floor(n_cont[0] + 1e-9)), int(np.floor(n_cont[0] + 1e-9)) + 1}:
            if n0 < 2 or counts(n0, t_opt) is None:
                continue

            def objective(t, n0=n0):
                n = counts(n0, t)
                return np.inf if n is None else np.log(
                    estimator_variance(estimator, n, "mean", cov, recursion=gamma))

            res = optimize.minimize(objective, t_opt, method="Nelder-Mead",
                                    options={"xatol": 1e-5, "fatol": 1e-12,
                                             "maxfev": 100 * K})
            t = res.x if res.fun < objective(t_opt) else t_opt
            n = counts(n0, t)
            if n is not None:
                cands.append(_rounded(estimator, n, w, budget, gamma))
    ok = [n for n in cands
          if n[0] >= 2 and float(w @ n) <= budget * (1 + 1e-12)
          and np.all(n >= _lower(family, gamma, n))]
    if not ok:
        return cands[0]
    var = [estimator_variance(estimator, n, "mean", cov, recursion=gamma) for n in ok]
    return ok[int(np.argmin(var))]


def fixed_allocation(cov: np.ndarray, costs, n_samples, *, estimator: str = "mfmc",
                     recursion=None) -> Allocation:
    """An :class:`Allocation` for given evaluations per model (K,), 0 leaving a model out;
    checks the estimator's structure (n_0 >= 2; every model at least its parent's
    evaluations: mfmc non-decreasing in the order given, acv at least n_0; grd two more
    than its parent's set). ``recursion`` (for "gmf", "grd", "gis") indexes the models
    left in, in their order."""
    if estimator not in (*ESTIMATORS, *GENERALIZED):
        raise ParameterError(f"unknown estimator {estimator!r}; valid: "
                             f"{', '.join((*ESTIMATORS, *GENERALIZED))}")
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
    family, gamma = _family(estimator, recursion, n.size)
    if np.any(n < _lower(family, gamma, n)):
        rule = {"mfmc": "non-decreasing from model to model",
                "acvmf": "at least the high-fidelity model's for every other model",
                "acvis": "at least the high-fidelity model's for every other model"}.get(
                    estimator, f"at least the parent's (recursion {list(gamma)})"
                    + (" plus 2 of the model's own" if family == "grd" else ""))
        raise ParameterError(f"allocation {n_all.tolist()} does not fit {estimator}: the "
                             f"evaluations must be {rule}")
    sub = np.asarray(cov, dtype=float)[np.ix_(models, models)]
    return Allocation(estimator=estimator, models=models, ratios=n / n[0], n_samples=n,
                      cost=float(w[list(models)] @ n),
                      variance=estimator_variance(estimator, n, "mean", sub, recursion=gamma),
                      recursion=gamma)


def check_ensemble(cov, costs) -> tuple[np.ndarray, np.ndarray]:
    """``cov`` (K, K) and ``costs`` (K,) as float arrays, checked: matching shapes, costs
    positive and finite, every model's variance positive and finite.

    Examples
    --------
    >>> check_ensemble([[1.0]], [0.0])
    Traceback (most recent call last):
    ...
    rotoruq.errors.ParameterError: costs must be positive and finite, got [0.0]
    """
    cov = np.asarray(cov, dtype=float)
    w = np.asarray(costs, dtype=float)
    K = w.size
    if cov.shape != (K, K):
        raise ParameterError(f"cov must be ({K}, {K}) for {K} costs, got {cov.shape}")
    if not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise ParameterError(f"costs must be positive and finite, got {w.tolist()}")
    if np.any(np.diag(cov) <= 0) or not np.all(np.isfinite(cov)):
        raise ParameterError("every model's output must vary over the pilot (variances "
                             f"{np.diag(cov).tolist()})")
    return cov, w


def _candidates(estimator: str, rho: np.ndarray, select: bool, recursion
                ) -> list[tuple[tuple[int, ...], tuple[int, ...]]]:
    """(models, recursion index) pairs the allocation tries."""
    K = rho.size
    order = [0] + sorted(range(1, K), key=lambda k: (-abs(rho[k]), k))
    subsets = ([tuple(s) for m in range(K) for s in itertools.combinations(order[1:], m)]
               if select and recursion is None else [tuple(order[1:])])
    if recursion is not None:
        return [(tuple(range(K)), _family(estimator, recursion, K)[1])]
    out = []
    for lf in subsets:
        idx = (0, *lf)
        if estimator in ESTIMATORS or len(idx) == 1:
            out.append((idx, default_recursion(estimator, len(idx))))
        else:
            out += [(idx, g) for g in recursion_indices(len(idx))]
    return out


def allocate(cov: np.ndarray, costs, budget: float, *, estimator: str = "mfmc",
             select: bool = True, recursion=None) -> Allocation:
    """Spend ``budget`` over an ensemble to minimise the variance of model 0's mean estimator.

    Parameters
    ----------
    cov : (K, K) covariance of the models' outputs (model 0 the high-fidelity one).
    costs : (K,) cost of one evaluation of each model (any unit; ``budget`` in the same).
    budget : total cost of the evaluations to allocate.
    estimator : "mfmc" (closed form, thm. 3.4 of Peherstorfer et al. 2016, models ordered by
        decreasing correlation with model 0), "acvmf" or "acvis" (numerical optimisation of the
        estimator variance over the ratios r_k = n_k / n_0 >= 1, n_0 = budget / (w . r)), or a
        generalized family "gmf", "grd", "gis" (Bomarito et al. 2022): the ratios optimised
        for every recursion index (:func:`recursion_indices`), the best kept.
    select : try every subset of the low-fidelity models and keep the best (Peherstorfer et
        al., algorithm 1); else use them all (mfmc: those satisfying its conditions, in order).
    recursion : (K - 1,) the recursion index of a generalized family over every model in the
        order given (no search).

    Returns
    -------
    Allocation
    """
    cov, w = check_ensemble(cov, costs)
    if not (np.isfinite(budget) and budget > 0):
        raise ParameterError(f"budget must be positive, got {budget}")
    sd = np.sqrt(np.diag(cov))
    rho = cov[0] / (sd[0] * sd)
    if estimator not in (*ESTIMATORS, *GENERALIZED):
        raise ParameterError(f"unknown estimator {estimator!r}; valid: "
                             f"{', '.join((*ESTIMATORS, *GENERALIZED))}")
    cands = _candidates(estimator, rho, select, recursion)
    # many structures: screen each with a short optimisation, then refine the best few
    effort = 300 if estimator in ESTIMATORS or len(cands) <= 4 else 60
    scored: list[tuple[float, tuple[int, ...], tuple[int, ...], np.ndarray]] = []
    for idx, gamma in cands:
        sub_cov, sub_w = cov[np.ix_(idx, idx)], w[list(idx)]
        if len(idx) == 1:
            r = np.ones(1)
        elif estimator == "mfmc":
            r_or_none = mfmc_ratios(rho[list(idx)], sub_w)
            if r_or_none is None:
                continue
            r = r_or_none
        else:
            start = mfmc_ratios(rho[list(idx)], sub_w) if gamma == default_recursion(
                "mfmc", len(idx)) or estimator in ESTIMATORS else None
            r = _continuous(estimator, sub_cov, sub_w, budget, start, gamma, effort=effort)[0]
        n0 = budget / float(sub_w @ r)
        var = estimator_variance(estimator, n0 * r, "mean", sub_cov, recursion=gamma)
        scored.append((var, idx, gamma, r))
    if effort < 300:
        # the best few, and the named estimators' structures (a short search must not lose
        # to ACV-MF, MFMC or ACV-IS, which GMF and GIS contain)
        scored.sort(key=lambda s: s[0])
        named = {default_recursion(e, len(s[1])) for e in ("mfmc", "acvmf") for s in scored}
        for i, (_, idx, gamma, r) in enumerate(scored):
            if len(idx) == 1 or (i >= 6 and gamma not in named):
                continue
            sub_cov, sub_w = cov[np.ix_(idx, idx)], w[list(idx)]
            r = _continuous(estimator, sub_cov, sub_w, budget, r, gamma)[0]
            n0 = budget / float(sub_w @ r)
            scored[i] = (estimator_variance(estimator, n0 * r, "mean", sub_cov,
                                            recursion=gamma), idx, gamma, r)
    best = None
    for s in scored:  # the first of equals: fewer models, then the candidates' order
        if best is None or s[0] < best[0] * (1.0 - 1e-9):
            best = s
    assert best is not None  # the HF model alone is always admissible
    _, models, gamma, r = best
    sub_cov, sub_w = cov[np.ix_(models, models)], w[list(models)]
    n_cont = budget / float(sub_w @ r) * r
    n = _whole_runs(estimator, sub_cov, sub_w, budget, r, gamma)
    if n[0] < 2 or float(sub_w @ n) > budget * (1 + 1e-12):
        raise ParameterError(
            f"budget {budget:g} buys {int(n_cont[0])} high-fidelity evaluation(s) with the "
            f"{estimator} allocation (costs {w[list(models)].tolist()}); at least 2 are "
            f"needed: raise the budget above {2 * float(sub_w @ r):g}")
    return Allocation(estimator=estimator, models=models, ratios=r, n_samples=n,
                      cost=float(sub_w @ n),
                      variance=estimator_variance(estimator, n, "mean", sub_cov,
                                                  recursion=gamma),
                      recursion=gamma)
