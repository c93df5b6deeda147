"""Multi-fidelity Sobol' indices: main and total indices of a high-fidelity model from few of its
pick-and-freeze runs and many runs of cheaper, correlated models.

Method (after Qian, Peherstorfer, O'Malley, Vesselinov, Willcox 2018, "Multifidelity Monte Carlo
estimation of variance and sensitivity indices", SIAM/ASA JUQ 6(2) 683-706). A *base sample* is
a row of the pick-and-freeze design of :func:`rotoruq.methods.sensitivity.pick_freeze_design`:
a point of A, a point of B and the d points A_B^i (A with input i taken from B); it costs d + 2
evaluations of a model. Three kinds of statistic of model k are estimated from a set z of base
samples (f_A, f_B, f_i its responses there, c_k a constant):

* the variance: the unbiased sample variance of the 2 |z| responses f_A, f_B;
* the main-effect numerator of input i, V_i = Var[E[y | x_i]]: the mean over z of
  ``(f_B - c_k) (f_i - f_A)`` (Saltelli et al. 2010; f_B and f_i share x_i);
* the total-effect numerator, E[Var[y | x_~i]]: the mean over z of ``(f_A - f_i)^2 / 2``
  (Jansen 1999; f_A and f_i share every input but x_i).

All three are unbiased for any constant c_k (here model k's pilot mean, which keeps the
Saltelli term's variance low without the O(1/N) bias that centring by the sample's own mean
brings). Each statistic Q of the high-fidelity model is then estimated by the control-variate
form of :mod:`rotoruq.methods.acv` on nested (MFMC, ACV-MF) or independent (ACV-IS) sets of base
samples,

    Q_hat = Q_0(z_0) + sum_k alpha_k (Q_k(z_k*) - Q_k(z_k)),

with its own optimal weights alpha (from the pilot's covariances of that statistic's per-sample
terms across the models), so every numerator and the variance are estimated without bias. The
indices are the ratios ``main_i = V_i_hat / V_hat`` and ``total_i = VT_i_hat / V_hat``. A ratio
of unbiased estimators is not unbiased: to second order its bias is
``(S Var[V_hat] - Cov[N_hat, V_hat]) / V^2`` (N the numerator, S the index), of the order of the
estimators' variance, O(1/N), while the standard error is O(1/sqrt(N)). Qian et al. apply the
control variates to the index estimates themselves, with the weights that are optimal for the
mean; here the numerators are combined and the ratio is taken last.

Standard errors of the indices are the delta method's
``sqrt(Var[N_hat] - 2 S Cov[N_hat, V_hat] + S^2 Var[V_hat]) / V``, with the estimator
covariances from the pilot's moments and the allocation (the covariance of a variance with a
mean-type statistic to first order: the variance of 2 |z| points moves, to first order, as the
mean over z of ``((f_A - mu)^2 + (f_B - mu)^2) / 2``).

Allocation: :func:`rotoruq.methods.acv.allocate` minimises the variance of one mean-type
statistic. Each per-sample term of the target response (the variance term above, each
input's main and total numerator term) gives a candidate allocation of the budget (in base
samples, each at d + 2 times a model's cost per evaluation); the one kept is the candidate that
minimises the sum of the predicted variances of the target response's 2 d indices.

The pilot (every model on the same ``n_pilot`` base samples) measures the costs and the
covariances; it is not reused in the estimate, so the weights do not depend on the points they
weight and the numerator and variance estimators are unbiased.

References: E. Qian et al., SIAM/ASA JUQ 6 (2018) 683-706; B. Peherstorfer, K. Willcox,
M. Gunzburger, SIAM J. Sci. Comput. 38 (2016) A3163-A3194; A. Gorodetsky et al., J. Comput.
Phys. 408 (2020) 109257.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from .._rng import SeedLike, as_seed_sequence
from ..errors import EvaluationError, ParameterError
from ..model import Model
from ..params import ParameterSpace
from .acv import (
    Allocation,
    SampleSets,
    allocate,
    estimator_covariance,
    optimal_weights,
    sample_sets,
)
from .multifidelity import _check_common, _correlation, _EnsembleRun, _sample_moments, _timed
from .sensitivity import _BASE_TERMS, _PER_INPUT, _row_terms, pick_freeze_design

__all__ = ["MultifidelitySobolResult", "multifidelity_sobol"]

# positions in _row_terms' per-input block (see rotoruq.methods.sensitivity)
_SALTELLI, _JANSEN = 3, 4


@dataclass(frozen=True, eq=False)
class MultifidelitySobolResult(_EnsembleRun):
    """Result of :func:`multifidelity_sobol`.

    Attributes
    ----------
    names_in, names_out : input (d) and response (m) names.
    estimator : "mfmc", "acvmf" or "acvis".
    target : the response whose index variances the allocation minimised.
    allocation_term : the per-sample term whose optimal allocation was kept ("variance",
        "main:NAME" or "total:NAME").
    models_used : indices (into ``models``) of the models the estimator uses, the
        high-fidelity model first, in the estimator's order.
    allocation : (K,) main-phase base samples of each given model (0 for one left out); each
        costs d + 2 evaluations.
    n_pilot : pilot base samples (every model on each; rows where a model failed on one of
        the d + 2 points are left out of the pilot statistics).
    costs : (K,) cost of one evaluation of each model (wall seconds per point measured in the
        pilot when not given).
    costs_measured : True when ``costs`` were measured.
    budget : cost given to the main phase (units of ``costs``).
    cost_pilot, cost_main : cost of the pilot and of the main phase (the pilot comes on top of
        ``budget``).
    wall_pilot, wall_main : (K,) seconds spent evaluating each model.
    correlation : (m, K) pilot correlation of each model's response with the high-fidelity
        model's.
    term_correlation : (m, 1 + 2 d, K) pilot correlation of each per-sample term (variance,
        main numerators of the d inputs, total numerators of the d inputs) with the
        high-fidelity model's same term: what the control variates exploit.
    main, total : (m, d) first-order and total-effect indices (ratios: O(1/N) bias, see the
        module docstring).
    main_se, total_se : (m, d) their standard errors (delta method, pilot moments).
    variance, variance_se : (m,) the response variance estimate (unbiased) and its standard
        error.
    weights : "variance", "main", "total" -> control-variate weights alpha, shaped
        (m, len(models_used) - 1), (m, d, len(models_used) - 1) and the same.
    n_equivalent_hf : "main", "total" -> (m, d) high-fidelity *evaluations* (base samples times
        d + 2) plain single-fidelity pick-and-freeze (the same estimators on the
        high-fidelity model alone) needs for the same standard error.
    speedup : "main", "total" -> (m, d) cost of those evaluations over the cost spent,
        ``cost_pilot + cost_main``.
    n_evaluations : evaluations of all models, pilot included.
    plan : the :class:`rotoruq.methods.acv.Allocation` in base samples.
    """

    allocation_term: str
    term_correlation: np.ndarray
    main: np.ndarray
    main_se: np.ndarray
    total: np.ndarray
    total_se: np.ndarray
    variance: np.ndarray
    variance_se: np.ndarray

    def table(self) -> list[dict]:
        """One dict per (response, input): indices, standard errors, equivalent HF runs."""
        rows = []
        for j, r in enumerate(self.names_out):
            for i, x in enumerate(self.names_in):
                row: dict = {"response": r, "input": x}
                for s in ("main", "total"):
                    row[s] = float(getattr(self, s)[j, i])
                    row[f"{s}_se"] = float(getattr(self, f"{s}_se")[j, i])
                    row[f"{s}_n_equivalent_hf"] = float(self.n_equivalent_hf[s][j, i])
                rows.append(row)
        return rows


@dataclass(frozen=True)
class _Moments:
    """Pilot moments of one response: per-sample terms (P = 1 + 2 d: variance, main_1..d,
    total_1..d) across the K models, and the responses' covariance and fourth moments."""

    terms: np.ndarray  # (P, K, P, K) covariance of the terms
    cov: np.ndarray  # (K, K) covariance of the responses (A and B points)
    m22: np.ndarray  # (K, K) E[d_k^2 d_l^2] of the centred responses
    variance: float  # the high-fidelity model's pilot variance
    numerators: np.ndarray  # (2 d,) its pilot main and total numerators


def _terms(blocks: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Per-sample terms (n, 1 + 2 d) from one model's responses ``blocks`` (d + 2, n): the
    variance's first-order term, then the Saltelli and Jansen numerator terms."""
    b = blocks - centre
    t = _row_terms(b[0], b[1], b[2:])
    per = t[:, _BASE_TERMS:].reshape(t.shape[0], -1, _PER_INPUT)
    return np.column_stack([0.5 * (t[:, 2] + t[:, 3]), per[:, :, _SALTELLI],
                            0.5 * per[:, :, _JANSEN]])


def _coefficients(alpha: np.ndarray) -> np.ndarray:
    """Weights (2K - 1,) of the set statistics in Q_0 + sum_k alpha_k (Q_k* - Q_k)."""
    a = np.zeros(2 * alpha.size + 1)
    a[0] = 1.0
    a[1::2], a[2::2] = alpha, -alpha
    return a


def _doubled(sets: SampleSets) -> SampleSets:
    """The sets of A and B points of ``sets``' base samples (two points per base sample)."""
    return SampleSets(sets=2.0 * sets.sets, model_of_set=sets.model_of_set,
                      n_points=2.0 * sets.n_points)


def _predict(sets: SampleSets, mom: _Moments, sub: list[int], variance: float,
             numerators: np.ndarray) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Weights per statistic, the statistics' estimator variances (1 + 2 d,) and the indices'
    predicted variances (2 d,) for the models ``sub`` on ``sets``."""
    P = mom.terms.shape[0]
    ix = np.ix_(sub, sub)
    s_var = estimator_covariance(_doubled(sets), "variance", mom.cov[ix], mom.m22[ix])
    alpha_v, var_v = optimal_weights(s_var)
    a_v = _coefficients(alpha_v)
    alphas, var_stat = [alpha_v], np.empty(P)
    var_stat[0] = var_v
    var_index = np.empty(P - 1)
    for p in range(1, P):
        s_pp = estimator_covariance(sets, "mean", mom.terms[p, :, p, :][ix])
        alpha, var_n = optimal_weights(s_pp)
        a_p = _coefficients(alpha)
        cross = estimator_covariance(sets, "mean", mom.terms[p, :, 0, :][ix])
        cov_nv = float(a_p @ cross @ a_v)
        s = numerators[p - 1] / variance
        alphas.append(alpha)
        var_stat[p] = var_n
        var_index[p - 1] = (var_n - 2.0 * s * cov_nv + s * s * var_v) / variance**2
    return alphas, var_stat, var_index


def _plain_base_samples(mom: _Moments, p: int, variance: float, numerator: float,
                        target_var: float) -> float:
    """Base samples plain pick-and-freeze on the high-fidelity model alone needs for the
    index variance ``target_var`` (statistic p = 1 .. 2 d), by the same formulas as
    :func:`_predict` with one model."""
    s = numerator / variance
    c_nn, c_nv = mom.terms[p, 0, p, 0], mom.terms[p, 0, 0, 0]

    def gap(log_n: float) -> float:
        n = np.exp(log_n)
        var_v = estimator_covariance(_doubled(sample_sets("mfmc", [n])), "variance",
                                     mom.cov[:1, :1], mom.m22[:1, :1])[0, 0]
        var = (c_nn / n - 2.0 * s * c_nv / n + s * s * var_v) / variance**2
        return float(np.log(var / target_var))

    lo, hi = np.log(2.0), np.log(1e15)
    if not (np.isfinite(target_var) and target_var > 0) or gap(hi) > 0:
        return np.nan
    if gap(lo) < 0:
        return 2.0
    return float(np.exp(optimize.brentq(gap, lo, hi, xtol=1e-10)))


def multifidelity_sobol(
    models: Sequence[Model],
    space: ParameterSpace,
    budget: float,
    *,
    budget_unit: str = "cost",
    estimator: str = "mfmc",
    n_pilot: int = 50,
    costs: Sequence[float] | None = None,
    target: str | None = None,
    select: bool = True,
    seed: SeedLike = None,
) -> MultifidelitySobolResult:
    """Main and total Sobol' indices of ``models[0]``'s responses using cheaper correlated models.

    Parameters
    ----------
    models : sequence of K Models, the high-fidelity one first; all take ``space``'s inputs and
        return the same responses.
    space : ParameterSpace of the d inputs (independent; base samples drawn at random: the
        estimators' variances assume independent base samples).
    budget : cost of the main phase, in the units of ``costs`` (seconds when measured); the
        pilot's ``n_pilot (d + 2) sum(costs)`` comes on top.
    budget_unit : "cost" or "hf_runs" (``budget`` in evaluations of the high-fidelity model:
        ``budget * costs[0]``; at least 2 (d + 2), two base samples).
    estimator : "mfmc" (multifidelity Monte Carlo, nested sets), "acvmf" or "acvis"
        (approximate control variates).
    n_pilot : pilot base samples, every model on each (>= 4; each costs d + 2 evaluations of
        every model). They set the costs, the weights, the allocation and the standard errors.
    costs : (K,) cost of one evaluation of each model; None measures wall seconds per point in
        the pilot (pass the result's ``costs`` back to reproduce a run bitwise).
    target : the response whose index variances the allocation minimises (default the first).
    select : let the allocation leave out low-fidelity models that do not pay.
    seed : int, SeedSequence, Generator or None. The same seed (and costs) gives bitwise the
        same result.

    Returns
    -------
    MultifidelitySobolResult
        ``main``, ``total`` (m, d) with ``main_se``, ``total_se``; ``allocation`` in base
        samples per model; ``n_equivalent_hf`` the high-fidelity evaluations plain
        pick-and-freeze needs for the same standard errors.

    Raises
    ------
    ParameterError for models with different inputs or responses, an unknown estimator or
    budget unit, a budget too small for two high-fidelity base samples, bad costs;
    EvaluationError when a model fails in the main phase.

    Examples
    --------
    y = a + 2 b (main = total = 1/5, 4/5), the cheap model a + 2 b + 0.3 a b:

    >>> import numpy as np, rotoruq as rq
    >>> space = rq.ParameterSpace({"a": rq.Uniform(-1, 1), "b": rq.Uniform(-1, 1)})
    >>> hf = rq.FunctionModel(lambda x: x[:, 0] + 2 * x[:, 1], ["a", "b"])
    >>> lf = rq.FunctionModel(lambda x: x[:, 0] + 2 * x[:, 1] + 0.3 * x[:, 0] * x[:, 1],
    ...                       ["a", "b"])
    >>> res = rq.multifidelity_sobol([hf, lf], space, 200, budget_unit="hf_runs",
    ...                              costs=[1.0, 0.01], n_pilot=50, seed=2)
    >>> res.main.shape, res.allocation.tolist()          # base samples per model
    ((1, 2), [33, 1700])
    >>> bool(np.all(np.abs(res.total - [0.2, 0.8]) < 4 * res.total_se))
    True
    """
    names_out, jt, w_given = _check_common(models, space, estimator, budget_unit, target,
                                           n_pilot, costs, " (base samples)")
    target = names_out[jt]
    K, m, d = len(models), len(names_out), space.dim
    if isinstance(budget, bool) or not isinstance(budget, int | float | np.number) \
            or not np.isfinite(budget) or budget <= 0:
        raise ParameterError(f"budget must be a positive number, got {budget!r}")
    if w_given is not None:
        if budget_unit == "cost" and budget < 2 * (d + 2) * w_given[0]:
            raise ParameterError(
                f"budget {budget:g} is below two high-fidelity base samples, 2 (d + 2) = "
                f"{2 * (d + 2)} evaluations at cost {w_given[0]:g}: at least "
                f"{2 * (d + 2) * w_given[0]:g} is needed")
    if budget_unit == "hf_runs" and budget < 2 * (d + 2):
        raise ParameterError(
            f"budget {budget:g} high-fidelity runs is below two base samples: a base sample "
            f"costs d + 2 = {d + 2} runs, so at least {2 * (d + 2)} are needed")
    ss = as_seed_sequence(seed)
    s_pilot, s_main = ss.spawn(2)

    # pilot: every model on the same base samples
    n_p = int(n_pilot)
    xp = pick_freeze_design(space, n_p, design="random", seed=np.random.default_rng(s_pilot))
    Yp = np.empty((d + 2, n_p, K, m))
    wall_pilot = np.zeros(K)
    ok = np.ones(n_p, dtype=bool)
    for k, mod in enumerate(models):
        y, fails, wall_pilot[k] = _timed(mod, space, xp)
        y = y.reshape(d + 2, n_p, m).copy()
        for i in fails:
            y[i // n_p, i % n_p] = np.nan
        Yp[:, :, k, :] = y
        ok &= np.all(np.isfinite(y), axis=(0, 2))
    if ok.sum() < 4:
        raise EvaluationError(f"pilot: only {int(ok.sum())} of {n_p} base samples succeeded on "
                              "every model (all d + 2 points); at least 4 are needed")
    if not ok.all():
        warnings.warn(f"multifidelity_sobol pilot: {int((~ok).sum())} of {n_p} base samples "
                      "failed on some model and are left out of the pilot statistics",
                      RuntimeWarning, stacklevel=2)
    w = w_given if w_given is not None else wall_pilot / (n_p * (d + 2))
    budget_cost = float(budget) * float(w[0]) if budget_unit == "hf_runs" else float(budget)
    if budget_cost < 2 * (d + 2) * w[0]:
        raise ParameterError(
            f"budget {budget_cost:g} is below two high-fidelity base samples, 2 (d + 2) = "
            f"{2 * (d + 2)} evaluations at the measured cost {w[0]:g}: at least "
            f"{2 * (d + 2) * w[0]:g} is needed")
    Yp = Yp[:, ok]
    ab = Yp[:2].reshape(-1, K, m)  # the A and B points: independent, distributed as y
    centre = ab.mean(axis=0)  # (K, m)
    cov_y, m22_y = _sample_moments(ab)
    moments, term_corr = [], np.empty((m, 2 * d + 1, K))
    for j in range(m):
        T = np.stack([_terms(Yp[:, :, k, j], centre[k, j]) for k in range(K)], axis=1)
        flat = T.reshape(T.shape[0], -1)  # (n, K P): model-major
        c = np.atleast_2d(np.cov(flat, rowvar=False))
        c4 = c.reshape(K, 2 * d + 1, K, 2 * d + 1).transpose(1, 0, 3, 2)  # (P, K, P, K)
        sd = np.sqrt(np.einsum("pkpk->pk", c4))
        with np.errstate(invalid="ignore", divide="ignore"):
            term_corr[j] = np.einsum("pkp->pk", c4[:, :, :, 0]) / (sd[:, :1] * sd)
        hf_terms = T[:, 0, :].mean(axis=0)
        moments.append(_Moments(terms=c4, cov=cov_y[j], m22=m22_y[j],
                                variance=float(cov_y[j, 0, 0]), numerators=hf_terms[1:]))
    correlation = _correlation(cov_y)

    # allocation: each term's optimum is a candidate; keep the one with the least index variance
    w_base = (d + 2) * w
    term_names = ["variance", *(f"main:{x}" for x in space.names),
                  *(f"total:{x}" for x in space.names)]
    mt = moments[jt]
    best: tuple[float, str, Allocation] | None = None
    errors = []
    seen: set[tuple] = set()
    for p, name in enumerate(term_names):
        try:  # a low-fidelity term exactly proportional to the HF one has rho = 1
            with np.errstate(divide="ignore", invalid="ignore"):
                plan_p = allocate(mt.terms[p, :, p, :], w_base, budget_cost,
                                  estimator=estimator, select=select)
        except (ParameterError, ValueError, OverflowError) as exc:  # e.g. an inert input's
            errors.append(f"{name}: {exc}")  # total term does not vary
            continue
        if not np.isfinite(plan_p.variance):
            continue
        key = (plan_p.models, tuple(plan_p.n_samples.tolist()))
        if key in seen:
            continue
        seen.add(key)
        crit = float(np.sum(_predict(sample_sets(estimator, plan_p.n_samples), mt,
                                     list(plan_p.models), mt.variance, mt.numerators)[2]))
        if best is None or crit < best[0]:
            best = (crit, name, plan_p)
    if best is None:
        raise ParameterError("no allocation: " + "; ".join(errors))
    _, allocation_term, plan = best
    used = list(plan.models)
    sets = sample_sets(estimator, plan.n_samples)

    # main phase: fresh base samples, each model on its largest set
    n_main = int(round(sets.n_points))
    xm = pick_freeze_design(space, n_main, design="random", seed=np.random.default_rng(s_main))
    blocks = np.arange((d + 2) * n_main).reshape(d + 2, n_main)
    wall_main = np.zeros(K)
    values: dict[int, np.ndarray] = {}
    for pos, k in enumerate(used):
        idx = sets.indices(2 * pos if pos else 0)
        y, fails, wall_main[k] = _timed(models[k], space, xm[blocks[:, idx].ravel()])
        if fails:
            first = next(iter(fails.items()))
            raise EvaluationError(
                f"multifidelity_sobol: models[{k}] failed on {len(fails)} of {y.shape[0]} "
                f"points (first: point {first[0]}: {first[1]}); the estimators need every point")
        full = np.full((d + 2, n_main, m), np.nan)
        full[:, idx] = y.reshape(d + 2, idx.size, m)
        values[k] = full

    spent = np.zeros(K, dtype=int)
    spent[used] = plan.n_samples
    cost_pilot = float(n_p * w_base.sum())
    cost_main = float(w_base[used] @ plan.n_samples)
    main, total = np.full((m, d), np.nan), np.full((m, d), np.nan)
    main_se, total_se = np.full((m, d), np.nan), np.full((m, d), np.nan)
    variance, variance_se = np.full(m, np.nan), np.full(m, np.nan)
    n_lf = len(used) - 1
    w_var, w_main, w_tot = np.zeros((m, n_lf)), np.zeros((m, d, n_lf)), np.zeros((m, d, n_lf))
    n_eq = {"main": np.full((m, d), np.nan), "total": np.full((m, d), np.nan)}
    for j in range(m):
        stats_q = []  # per set: (1 + 2 d,) statistics of its model
        for s, pos in enumerate(sets.model_of_set):
            k, rows = used[pos], sets.indices(s)
            b = values[k][:, rows, j]
            t = _terms(b, centre[k, j])
            stats_q.append(np.concatenate([[np.var(b[:2], ddof=1)], t[:, 1:].mean(axis=0)]))
        Q = np.array(stats_q)  # (2K - 1, 1 + 2 d)
        alphas, _, _ = _predict(sets, moments[j], used, moments[j].variance,
                                moments[j].numerators)
        est = np.array([_coefficients(a) @ Q[:, p] for p, a in enumerate(alphas)])
        v = est[0]
        # standard errors at the estimates (the weights depend on the pilot only)
        with np.errstate(invalid="ignore", divide="ignore"):
            _, var_stat, var_index = _predict(sets, moments[j], used, v, est[1:])
            idx_est = est[1:] / v if v > 0 else np.full(2 * d, np.nan)
        variance[j], variance_se[j] = v, np.sqrt(max(var_stat[0], 0.0))
        main[j], total[j] = idx_est[:d], idx_est[d:]
        se = np.sqrt(np.maximum(var_index, 0.0)) if v > 0 else np.full(2 * d, np.nan)
        main_se[j], total_se[j] = se[:d], se[d:]
        w_var[j] = alphas[0]
        w_main[j] = np.array(alphas[1:d + 1]).reshape(d, n_lf)
        w_tot[j] = np.array(alphas[d + 1:]).reshape(d, n_lf)
        if v > 0:
            for p in range(1, 2 * d + 1):
                n_base = _plain_base_samples(moments[j], p, v, est[p], float(var_index[p - 1]))
                n_eq["main" if p <= d else "total"][j, (p - 1) % d] = n_base * (d + 2)
    spend = cost_pilot + cost_main
    return MultifidelitySobolResult(
        names_in=tuple(space.names), names_out=names_out, estimator=estimator, target=target,
        allocation_term=allocation_term, models_used=tuple(used), allocation=spent,
        n_pilot=n_p, costs=w, costs_measured=costs is None, budget=budget_cost,
        cost_pilot=cost_pilot, cost_main=cost_main, wall_pilot=wall_pilot, wall_main=wall_main,
        correlation=correlation, term_correlation=term_corr, main=main, main_se=main_se,
        total=total, total_se=total_se, variance=variance, variance_se=variance_se,
        weights={"variance": w_var, "main": w_main, "total": w_tot},
        n_equivalent_hf=n_eq,
        speedup={s: n_eq[s] * w[0] / spend for s in ("main", "total")},
        n_evaluations=(d + 2) * (n_p * K + int(plan.n_samples.sum())), plan=plan)
