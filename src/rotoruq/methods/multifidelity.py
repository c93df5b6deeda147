"""Multi-fidelity forward UQ: the mean and variance of a high-fidelity model's responses from
few of its runs and many runs of cheaper, correlated models.

:func:`multifidelity_sample` runs a pilot (every model on the same ``n_pilot`` random points) to
measure each model's cost and the correlations between the models, allocates the budget
(:func:`rotoruq.methods.acv.allocate`: multifidelity Monte Carlo, Peherstorfer, Willcox,
Gunzburger 2016, SIAM J. Sci. Comput. 38(5); approximate control variates ACV-MF / ACV-IS,
Gorodetsky, Geraci, Eldred, Jakeman 2020, J. Comput. Phys. 408), then evaluates the models on
fresh, independent random points and combines the plain sample estimators with the optimal
control-variate weights. The pilot is not reused in the estimate, so the weights are
independent of the points they weight and the estimators are unbiased.

``adapt="linear"`` first adapts each low-fidelity model to the high-fidelity one on the pilot:
``LF_k'(x) = c_0 + c_1 LF_k(x) + c_x . z(x)`` (z the inputs standardised on the pilot), least
squares per response. The adapted model is a deterministic function of x fixed before the main
phase, so the estimators stay unbiased (the adaptation of Peherstorfer 2019, "Multifidelity
Monte Carlo estimation with adaptive low-fidelity models", SIAM/ASA JUQ 7(2), with a linear
map). It pays where the two models weigh the inputs differently: a low-fidelity model whose
error is mostly linear in the inputs becomes far more correlated, and the variance estimator,
which needs the squared deviations to correlate, gains most. The correlations that set the
allocation, the weights and the standard errors are computed from leave-one-out adapted
values on the pilot, so the fit's optimism does not enter them. Where that leave-one-out
correlation is no better than the model's own (a small pilot, a response the cheap model gets
nearly right with an error not linear in the inputs), the model is kept as evaluated for that
response: a choice made on the pilot alone, so unbiasedness holds.
"""

from __future__ import annotations

import logging
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from .._rng import SeedLike, as_seed_sequence
from ..errors import EvaluationError, ParameterError
from ..model import Model
from ..params import ParameterSpace
from ._common import eval_space
from .acv import (
    ESTIMATORS,
    GENERALIZED,
    Allocation,
    SampleSets,
    allocate,
    estimator_covariance,
    fixed_allocation,
    optimal_weights,
    sample_sets,
    weighted_variance_stack,
    weights_stack,
)
from .mf_choice import EstimatorChoice, choose_estimator
from .mf_pilot import bootstrap_variance, pilot_too_small
from .mlblue import (
    GroupAllocation,
    mlblue_allocate,
    mlblue_estimate,
    mlblue_fixed_allocation,
    mlblue_psi,
    mlblue_weighted_variance,
)

log = logging.getLogger(__name__)

__all__ = ["MultifidelityResult", "LinearAdaptation", "multifidelity_sample", "STATISTICS",
           "BUDGET_UNITS", "ADAPTATIONS", "MF_ESTIMATORS"]

STATISTICS = ("mean", "variance")
BUDGET_UNITS = ("cost", "hf_runs")
ADAPTATIONS = ("none", "linear")
#: The estimators of :func:`multifidelity_sample`: the ACV family, its generalized families
#: (Bomarito et al. 2022), MLBLUE (mean only) and "auto" (:mod:`rotoruq.methods.mf_choice`).
MF_ESTIMATORS = (*ESTIMATORS, *GENERALIZED, "mlblue", "auto")


@dataclass(frozen=True, eq=False)
class LinearAdaptation:
    """Low-fidelity models adapted to the high-fidelity one on the pilot (module doc).

    Attributes
    ----------
    coef : (K, m, d + 2) per model and response: intercept, slope on the model's own response,
        slopes on the standardised inputs (``[0, 1, 0, ...]``, the model as evaluated, where
        ``adapted`` is False); NaN in row 0 (the high-fidelity model).
    center, scale : (d,) the pilot's input means and standard deviations (z = (x - center) /
        scale; scale 1 where an input is constant on the pilot).
    r2_loo : (K, m) leave-one-out R^2 of the high-fidelity response by the linear fit.
    adapted : (K, m) True where the fit is used: its leave-one-out correlation with the
        high-fidelity response beats the model's own correlation on the pilot (a fit to few
        points can correlate worse than the model it adapts); False in row 0.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.linspace(0, 1, 8)[:, None]
    >>> Y = np.stack([3 * x[:, 0] + x[:, 0] ** 2, x[:, 0] ** 2], axis=1)[:, :, None]
    >>> ad, loo = LinearAdaptation.fit(x, Y)
    >>> bool(np.allclose(ad.apply(1, x, Y[:, 1]), Y[:, 0]))
    True
    """

    coef: np.ndarray
    center: np.ndarray
    scale: np.ndarray
    r2_loo: np.ndarray
    adapted: np.ndarray

    @classmethod
    def fit(cls, x: np.ndarray, Y: np.ndarray) -> tuple[LinearAdaptation, np.ndarray]:
        """Least squares on pilot points ``x`` with every model's values ``Y``.

        Parameters
        ----------
        x : ndarray of shape (n, d)
            The pilot points, in the inputs' units.
        Y : ndarray of shape (n, K, m)
            Every model's responses at them, the high-fidelity model first.

        Returns
        -------
        tuple of (LinearAdaptation, ndarray)
            The adaptation, and ``Y`` with each low-fidelity model replaced by its
            leave-one-out adapted values where the fit is used (``adapted``; the
            high-fidelity column and the models kept as evaluated unchanged).
        """
        n, K, m = Y.shape
        center = x.mean(axis=0)
        scale = x.std(axis=0)
        scale = np.where(scale > 0, scale, 1.0)
        z = (x - center) / scale
        coef = np.full((K, m, x.shape[1] + 2), np.nan)
        r2 = np.full((K, m), np.nan)
        loo = Y.copy()
        for k in range(1, K):
            for j in range(m):
                A = np.column_stack([np.ones(n), Y[:, k, j], z])
                pinv = np.linalg.pinv(A)
                coef[k, j] = pinv @ Y[:, 0, j]
                h = np.einsum("ij,ji->i", A, pinv)
                resid = Y[:, 0, j] - A @ coef[k, j]
                with np.errstate(divide="ignore", invalid="ignore"):
                    e_loo = np.where(h < 1 - 1e-10, resid / (1 - h), 0.0)
                loo[:, k, j] = Y[:, 0, j] - e_loo
                ss = np.sum((Y[:, 0, j] - Y[:, 0, j].mean()) ** 2)
                r2[k, j] = 1.0 - np.sum(e_loo**2) / ss if ss > 0 else np.nan
        # the control variate's weight rescales either: compare |correlation| (a model that
        # is constant on the pilot has NaN and is adapted)
        fit, own = (np.abs(_correlation(_sample_moments(v)[0])).T for v in (loo, Y))
        adapted = ~(fit <= own)
        adapted[0] = False
        loo = np.where(adapted[None], loo, Y)
        identity = np.zeros(x.shape[1] + 2)
        identity[1] = 1.0
        coef[1:][~adapted[1:]] = identity
        return cls(coef, center, scale, r2, adapted), loo

    def apply(self, k: int, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Model ``k``'s adapted values at points ``x``, shape (n, m).

        Parameters
        ----------
        k : int
            The model's index in the ensemble (0 is the high-fidelity model, never adapted).
        x : ndarray of shape (n, d)
            The points, in the inputs' units.
        y : ndarray of shape (n, m)
            Model ``k``'s responses at them.
        """
        y = np.asarray(y, dtype=float).reshape(len(x), -1)
        z = (np.asarray(x, dtype=float) - self.center) / self.scale
        c = self.coef[k]
        return c[:, 0] + y * c[:, 1] + z @ c[:, 2:].T


@dataclass(frozen=True, eq=False)
class _EnsembleRun:
    """The fields every multi-fidelity result shares (documented on each result)."""

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    estimator: str
    target: str
    models_used: tuple[int, ...]
    allocation: np.ndarray
    n_pilot: int
    costs: np.ndarray
    costs_measured: bool
    budget: float
    cost_pilot: float
    cost_main: float
    wall_pilot: np.ndarray
    wall_main: np.ndarray
    correlation: np.ndarray
    weights: dict = field(default_factory=dict, kw_only=True)
    n_equivalent_hf: dict = field(default_factory=dict, kw_only=True)
    speedup: dict = field(default_factory=dict, kw_only=True)
    n_evaluations: int = field(default=0, kw_only=True)
    plan: Allocation | None = field(default=None, repr=False, kw_only=True)


@dataclass(frozen=True, eq=False)
class MultifidelityResult(_EnsembleRun):
    """Result of :func:`multifidelity_sample`.

    Attributes
    ----------
    names_in, names_out : input (d) and response (m) names.
    estimator : "mfmc", "acvmf", "acvis", "gmf", "grd", "gis" or "mlblue" (the one "auto"
        chose, see ``choice``).
    statistics : the statistics estimated ("mean", "variance").
    target : the response whose mean-estimator variance the allocation minimised.
    models_used : indices (into ``models``) of the models the estimator uses, the
        high-fidelity model first, in the estimator's order (models the allocation found
        useless are left out).
    allocation : (K,) main-phase evaluations of each given model (0 for one left out).
    n_pilot : pilot points (every model evaluated on each; rows where a model failed are
        left out of the pilot statistics).
    costs : (K,) cost of one evaluation of each model: wall seconds per point measured in the
        pilot (batched evaluation, driver included) when not given.
    costs_measured : True when ``costs`` were measured.
    budget : cost given to the main phase (units of ``costs``, whatever ``budget_unit``).
    cost_pilot, cost_main : cost of the pilot and of the main phase, ``costs`` times the
        evaluations (the pilot comes on top of ``budget``).
    wall_pilot, wall_main : (K,) seconds spent evaluating each model.
    correlation : (m, K) pilot correlation of each model with the high-fidelity model.
    mean, variance : (m,) estimates (NaN for a statistic not asked for); the multi-fidelity
        variance estimate is unbiased and may, rarely, come out negative.
    mean_se, variance_se : (m,) their standard errors predicted from the pilot moments and
        the allocation, with the pilot's uncertainty accounted for by the bootstrap
        (``pilot_bootstrap`` resamples, :mod:`rotoruq.methods.mf_pilot`; the plug-in without).
    mean_se_plugin, variance_se_plugin : (m,) the plug-in standard errors (weights and
        variance from the pilot's covariance as if it were exact; optimistic).
    adapt : "none" or "linear".
    adaptation : the :class:`LinearAdaptation` (None without).
    correlation_unadapted : (m, K) pilot correlation of each model as evaluated (equal to
        ``correlation`` without adaptation; with it, ``correlation`` is the adapted models',
        leave-one-out).
    weights : statistic -> (m, len(models_used) - 1) control-variate weights alpha_k (the
        estimate is Q_0(z_0) + sum_k alpha_k (Q_k(z_k*) - Q_k(z_k))); for "mlblue",
        "mean" -> (m, len(models_used)) the first row of Psi^{-1} (the weights of the
        models' C_S^{-1}-weighted group sums, :mod:`rotoruq.methods.mlblue`).
    n_equivalent_hf : statistic -> (m,) high-fidelity runs plain Monte Carlo needs for the same
        estimator variance.
    speedup : statistic -> (m,) cost of those runs over ``cost_pilot + cost_main``.
    n_evaluations : evaluations of all models, pilot included.
    pilot_inputs : (n_pilot, d) the pilot's points.
    pilot_outputs : (n_pilot, K, m) every model's responses there (NaN where one failed).
    plan : the allocation as planned (``rotoruq.methods.acv.Allocation``: the models used,
        their continuous ratios, integer evaluations, cost, predicted variance and recursion
        index; for "mlblue" a ``rotoruq.methods.mlblue.GroupAllocation``, with the points per
        group).
    choice : for ``estimator="auto"``, the :class:`~rotoruq.methods.mf_choice.EstimatorChoice`
        (every candidate's predicted variance and the reason); None otherwise.
    """

    statistics: tuple[str, ...]
    mean: np.ndarray
    mean_se: np.ndarray
    variance: np.ndarray
    variance_se: np.ndarray
    pilot_inputs: np.ndarray | None = field(default=None, repr=False)
    pilot_outputs: np.ndarray | None = field(default=None, repr=False)
    adapt: str = "none"
    adaptation: LinearAdaptation | None = field(default=None, repr=False)
    correlation_unadapted: np.ndarray | None = field(default=None, repr=False)
    mean_se_plugin: np.ndarray | None = field(default=None, repr=False)
    variance_se_plugin: np.ndarray | None = field(default=None, repr=False)
    choice: EstimatorChoice | None = field(default=None, repr=False)

    @property
    def std(self) -> np.ndarray:
        """(m,) square root of the variance estimate (NaN where it is negative)."""
        with np.errstate(invalid="ignore"):
            return np.sqrt(self.variance)

    def table(self) -> list[dict]:
        """One dict per response: estimates, standard errors, equivalent HF runs."""
        rows = []
        for j, name in enumerate(self.names_out):
            row: dict = {"response": name}
            for s in self.statistics:
                est = self.mean if s == "mean" else self.variance
                se = self.mean_se if s == "mean" else self.variance_se
                row[s] = float(est[j])
                row[f"{s}_se"] = float(se[j])
                row[f"{s}_n_equivalent_hf"] = float(self.n_equivalent_hf[s][j])
            rows.append(row)
        return rows


def _check_models(models: Sequence[Model], space: ParameterSpace) -> tuple[str, ...]:
    if isinstance(models, str) or not isinstance(models, Sequence) or len(models) < 1:
        raise ParameterError("models must be a sequence of Models, the high-fidelity one first, "
                             f"got {models!r}")
    names_out = tuple(models[0].names_out)
    for k, mod in enumerate(models):
        for attr in ("names_in", "names_out"):
            if not hasattr(mod, attr) or not callable(mod):
                raise ParameterError(f"models[{k}] is not a Model (names_in, names_out, "
                                     f"__call__): {mod!r}")
        if set(mod.names_in) != set(space.names):
            raise ParameterError(f"models[{k}] has inputs {list(mod.names_in)}; every model "
                                 f"must take the space's parameters {list(space.names)}")
        if tuple(mod.names_out) != names_out:
            raise ParameterError(f"models[{k}] has responses {list(mod.names_out)}; every model "
                                 f"must return the high-fidelity model's {list(names_out)}")
    return names_out


def _check_common(models: Sequence[Model], space: ParameterSpace, estimator: str,
                  budget_unit: str, target: str | None, n_pilot, costs, pilot_unit: str = "",
                  estimators: tuple[str, ...] = ESTIMATORS
                  ) -> tuple[tuple[str, ...], int, np.ndarray | None]:
    """The checks :func:`multifidelity_sample` and ``multifidelity_sobol`` share: the
    responses, the target's index and the given costs (None when measured)."""
    if estimator not in estimators:
        raise ParameterError(f"unknown estimator {estimator!r}; valid: {', '.join(estimators)}")
    if budget_unit not in BUDGET_UNITS:
        raise ParameterError(f"budget_unit must be one of {BUDGET_UNITS}, got {budget_unit!r}")
    names_out = _check_models(models, space)
    target = names_out[0] if target is None else target
    if target not in names_out:
        raise ParameterError(f"target {target!r} is not a response; valid: {list(names_out)}")
    if isinstance(n_pilot, bool) or not isinstance(n_pilot, int | np.integer) or n_pilot < 4:
        raise ParameterError(f"n_pilot must be an integer >= 4{pilot_unit}, got {n_pilot!r}")
    w_given = None
    if costs is not None:
        w_given = np.asarray(costs, dtype=float)
        K = len(models)
        if w_given.shape != (K,) or not np.all(np.isfinite(w_given)) or np.any(w_given <= 0):
            raise ParameterError(f"costs must be {K} positive numbers (one per model), "
                                 f"got {costs!r}")
    return names_out, names_out.index(target), w_given


def _timed(model: Model, space: ParameterSpace, x: np.ndarray
           ) -> tuple[np.ndarray, dict, float]:
    """Values, failures and the model's seconds for the batch ``x``.

    The first point runs on its own, untimed, when there are three or more: what a model
    does once (loading compiled kernels, starting workers) is not a per-run cost and would
    otherwise fall on whichever model the pilot runs first; the time of the others is scaled
    to the whole batch. Points a store served count with the seconds they took when they
    were run (``last_stats.stored_wall_time`` of an evaluator), not the lookup's."""
    n = len(x)
    head = 1 if n >= 3 else 0
    if head:
        first = eval_space(model, space, x[:head])
    t0 = time.perf_counter()
    batch = eval_space(model, space, x[head:])
    wall = time.perf_counter() - t0
    stats = getattr(model, "last_stats", None)
    if stats is not None and getattr(stats, "n_samples", None) == n - head:
        wall += float(getattr(stats, "stored_wall_time", 0.0) or 0.0)
    if not head:
        return batch.values, batch.failures, wall
    values = np.vstack([first.values, batch.values])
    failures = {**first.failures, **{i + head: why for i, why in batch.failures.items()}}
    return values, failures, wall * n / (n - head)


def _correlation(cov: np.ndarray) -> np.ndarray:
    """(m, K, K) covariances -> (m, K) correlation of each model with model 0."""
    sd = np.sqrt(np.einsum("jkk->jk", cov))
    with np.errstate(invalid="ignore", divide="ignore"):
        return cov[:, 0, :] / (sd[:, :1] * sd)


def _sample_moments(Y: np.ndarray, population: bool = False
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Y (n, K, m) -> covariance (m, K, K) and E[d_i^2 d_j^2] (m, K, K) of the centred values
    (the covariance unbiased, or with ``population`` the empirical distribution's)."""
    d = Y - Y.mean(axis=0)
    n = Y.shape[0]
    cov = np.einsum("nkj,nlj->jkl", d, d) / (n if population else n - 1)
    d2 = d**2
    m22 = np.einsum("nkj,nlj->jkl", d2, d2) / n
    return cov, m22


def _plain_variance_runs(var_est: float, sigma2: float, mu4: float) -> float:
    """n with Var[s^2_n] = mu4 / n - (n - 3) sigma^4 / (n (n - 1)) = var_est (larger root)."""
    a, b, c = var_est, -(var_est + mu4 - sigma2**2), mu4 - 3.0 * sigma2**2
    disc = b * b - 4.0 * a * c
    return float((-b + np.sqrt(max(disc, 0.0))) / (2.0 * a))


def multifidelity_sample(
    models: Sequence[Model],
    space: ParameterSpace,
    budget: float | None,
    *,
    budget_unit: str = "cost",
    estimator: str = "mfmc",
    n_pilot: int = 50,
    costs: Sequence[float] | None = None,
    statistics: Sequence[str] | None = None,
    target: str | None = None,
    select: bool = True,
    allocation: Sequence[int] | Mapping[tuple[int, ...], int] | None = None,
    adapt: str = "none",
    recursion: Sequence[int] | None = None,
    pilot_bootstrap: int = 100,
    seed: SeedLike = None,
) -> MultifidelityResult:
    """Mean and variance of ``models[0]``'s responses using cheaper correlated models.

    Parameters
    ----------
    models : sequence of K Models, the high-fidelity one first; all take ``space``'s inputs
        and return the same responses. Each is evaluated in batches through
        :func:`rotoruq.model.evaluate`.
    space : ParameterSpace of the inputs (points drawn by plain random sampling: the
        estimators' variances assume independent points).
    budget : cost of the main phase, in the units of ``costs`` (seconds when measured); the
        pilot's ``n_pilot * sum(costs)`` comes on top. None when ``allocation`` is given.
    budget_unit : "cost" (``budget`` in the units of ``costs``) or "hf_runs" (in evaluations
        of the high-fidelity model: ``budget * costs[0]``).
    estimator : "mfmc" (multifidelity Monte Carlo, closed-form allocation), "acvmf" or "acvis"
        (approximate control variates, allocation by numerical optimisation), or "mlblue"
        (multilevel best linear unbiased estimator, Schaden, Ullmann 2020, SIAM/ASA JUQ 8(2);
        allocation over groups of models as in Croci, Willcox, Wright 2023; the mean only:
        :mod:`rotoruq.methods.mlblue`). At the optimal allocation MLBLUE's predicted variance
        is at most the ACV estimators'; it needs one high-fidelity run, not two. "gmf",
        "grd", "gis": the generalized ACV families of Bomarito et al. 2022 (J. Comput. Phys.
        451), the allocation searched over model subsets and recursion indices (each model's
        control variate on a parent model; :func:`rotoruq.methods.acv.sample_sets`). "auto":
        every one of these allocated on the pilot, the smallest predicted variance of the
        target's mean kept (MLBLUE only when ``statistics=["mean"]``); ``choice`` says which
        and why, and the module's logger says it at INFO.
    n_pilot : points of the pilot, every model on each (>= 4): it measures the costs and the
        covariances that set the allocation, the weights and the standard errors.
    costs : (K,) cost of one evaluation of each model; None measures wall seconds per point
        in the pilot (the allocation then depends on the machine's timing: pass the result's
        ``costs`` back to reproduce a run bitwise).
    statistics : any of "mean", "variance" (default both; "mean" alone for "mlblue", which
        estimates no variance).
    target : the response whose mean estimator the allocation optimises (default the first).
    select : let the allocation leave out low-fidelity models that do not pay (see
        :func:`rotoruq.methods.acv.allocate`); "mlblue" always considers every group of
        models and leaves out those given no points.
    allocation : (K,) main-phase evaluations per model (0 leaves a model out) instead of the
        optimised allocation (e.g. another tool's, to compare at equal samples); the pilot
        then sets only the weights and the standard errors. For "mlblue" a mapping
        ``{group: points}`` (a group a tuple of model indices).
    adapt : "none" or "linear": adapt each low-fidelity model on the pilot by a linear map of
        its response and the inputs (module doc); needs ``n_pilot >= d + 5``.
    recursion : (number of models with evaluations - 1,) with ``allocation`` and "gmf",
        "grd" or "gis": each model's parent, its position among those models (``gamma_k <
        k``).
    pilot_bootstrap : resamples of the pilot for the standard errors' correction for the
        pilot's uncertainty (:mod:`rotoruq.methods.mf_pilot`); 0 reports the plug-in. A
        pilot smaller than ``11 (K - 1) + 2`` points warns (the rule there).
    seed : int, SeedSequence, Generator or None. The same seed (and costs) gives bitwise the
        same result.

    Returns
    -------
    MultifidelityResult

    Raises
    ------
    ParameterError for inconsistent models, an unknown estimator or statistic, a budget too
    small for two high-fidelity runs; EvaluationError when a model fails in the main phase.

    Examples
    --------
    >>> import numpy as np, rotoruq as rq
    >>> space = rq.ParameterSpace({"x": rq.Uniform(0, 1)})
    >>> hf = rq.FunctionModel(lambda x: x[:, 0] ** 5, ["x"])
    >>> lf = rq.FunctionModel(lambda x: x[:, 0] ** 4, ["x"])
    >>> res = rq.multifidelity_sample([hf, lf], space, 100.0, costs=[1.0, 0.01],
    ...                               n_pilot=100, seed=1)
    >>> res.allocation.tolist(), bool(abs(res.mean[0] - 1 / 6) < 4 * res.mean_se[0])
    ([51, 4900], True)
    """
    if statistics is None:
        statistics = ("mean",) if estimator == "mlblue" else STATISTICS
    if isinstance(pilot_bootstrap, bool) or not isinstance(pilot_bootstrap, int | np.integer) \
            or pilot_bootstrap < 0:
        raise ParameterError(f"pilot_bootstrap must be a non-negative integer, got "
                             f"{pilot_bootstrap!r}")
    stats_asked = tuple(statistics)
    bad = [s for s in stats_asked if s not in STATISTICS]
    if bad or not stats_asked:
        raise ParameterError(f"statistics must be a non-empty subset of {STATISTICS}, "
                             f"got {list(statistics)}")
    names_out, jt, w_given = _check_common(models, space, estimator, budget_unit, target,
                                           n_pilot, costs, estimators=MF_ESTIMATORS)
    if estimator == "mlblue" and "variance" in stats_asked:
        raise ParameterError("estimator 'mlblue' estimates the mean only: statistics=['mean'] "
                             "(the variance by mfmc, acvmf or acvis)")
    target = names_out[jt]
    K, m = len(models), len(names_out)
    if adapt not in ADAPTATIONS:
        raise ParameterError(f"adapt must be one of {ADAPTATIONS}, got {adapt!r}")
    if adapt == "linear" and n_pilot < space.dim + 5:
        raise ParameterError(f"adapt='linear' fits {space.dim + 2} coefficients per model on "
                             f"the pilot: n_pilot must be >= {space.dim + 5} (d + 5), got "
                             f"{n_pilot}")
    if (budget is None) == (allocation is None):
        raise ParameterError("give either a budget or an allocation (evaluations per model)")
    if estimator == "auto" and budget is None:
        raise ParameterError("estimator 'auto' chooses by the predicted variance at a budget: "
                             "give a budget, not an allocation")
    if recursion is not None and (estimator not in GENERALIZED or allocation is None):
        raise ParameterError("recursion goes with an allocation and estimator 'gmf', 'grd' or "
                             "'gis' (with a budget the allocation searches the recursion)")
    ss = as_seed_sequence(seed)
    s_pilot, s_main, s_boot = ss.spawn(3)

    # pilot: every model on the same points
    xp = space.draw(int(n_pilot), design="random", seed=np.random.default_rng(s_pilot))
    Yp = np.empty((int(n_pilot), K, m))
    wall_pilot = np.zeros(K)
    ok = np.ones(int(n_pilot), dtype=bool)
    for k, mod in enumerate(models):
        Yp[:, k, :], fails, wall_pilot[k] = _timed(mod, space, xp)
        ok &= np.all(np.isfinite(Yp[:, k, :]), axis=1)
        if fails:
            ok[list(fails)] = False
    if ok.sum() < 4:
        raise EvaluationError(f"pilot: only {int(ok.sum())} of {n_pilot} points succeeded on "
                              "every model; at least 4 are needed")
    if not ok.all():
        warnings.warn(f"multifidelity pilot: {int((~ok).sum())} of {n_pilot} points failed on "
                      "some model and are left out of the pilot statistics", RuntimeWarning,
                      stacklevel=2)
    w = w_given if w_given is not None else wall_pilot / n_pilot
    small = pilot_too_small(int(ok.sum()), K)
    if small:
        warnings.warn(small, RuntimeWarning, stacklevel=2)
    cov, m22 = _sample_moments(Yp[ok])
    correlation_unadapted = _correlation(cov)
    adaptation = None
    if adapt == "linear":
        if ok.sum() < space.dim + 5:
            raise EvaluationError(f"pilot: {int(ok.sum())} points succeeded on every model; "
                                  f"adapt='linear' needs {space.dim + 5}")
        adaptation, Y_loo = LinearAdaptation.fit(xp[ok], Yp[ok])
        cov, m22 = _sample_moments(Y_loo)
    Y_fit = Y_loo if adaptation is not None else Yp[ok]
    correlation = _correlation(cov)
    boot = (int(pilot_bootstrap), np.random.default_rng(s_boot))

    plan: Allocation
    choice = None
    if estimator == "auto":
        assert budget is not None  # checked above: 'auto' needs a budget
        if budget_unit == "hf_runs":
            budget = float(budget) * float(w[0])
        choice = choose_estimator(cov[jt], w, float(budget), statistics=stats_asked,
                                  select=select)
        log.info("%s", choice.reason)
        estimator = choice.estimator
        budget_unit = "cost"
    if estimator == "mlblue":
        if budget is None:
            if not isinstance(allocation, Mapping):
                raise ParameterError("estimator 'mlblue': allocation must be a mapping "
                                     f"{{group: points}}, got {allocation!r}")
            gplan = mlblue_fixed_allocation(cov[jt], w, allocation)
        else:
            if budget_unit == "hf_runs":
                budget = float(budget) * float(w[0])
            gplan = (choice.plan if choice is not None  # type: ignore[assignment]
                     else mlblue_allocate(cov[jt], w, float(budget)))
        return _mlblue_main(models, space, gplan, s_main, names_out, target, stats_asked,
                            cov, w, xp, Yp, wall_pilot, int(n_pilot), costs is None, budget,
                            correlation, correlation_unadapted, adapt, adaptation, Y_fit, boot,
                            choice)
    if choice is not None:
        plan = choice.plan
    elif budget is None:
        plan = fixed_allocation(cov[jt], w, np.asarray(allocation), estimator=estimator,
                                recursion=recursion)
    else:
        if budget_unit == "hf_runs":
            budget = float(budget) * float(w[0])
        plan = allocate(cov[jt], w, float(budget), estimator=estimator, select=select)
    used = list(plan.models)
    sets = sample_sets(estimator, plan.n_samples, plan.recursion)

    # main phase: fresh points, each model on its largest set
    xm = space.draw(int(round(sets.n_points)), design="random",
                    seed=np.random.default_rng(s_main))
    wall_main = np.zeros(K)
    values: list[np.ndarray] = []
    for pos, k in enumerate(used):
        idx = sets.model_points(pos)
        y, wall_main[k] = _run_main(models, k, space, xm[idx], adaptation)
        full = np.full((xm.shape[0], m), np.nan)
        full[idx] = y
        values.append(full)

    spent = np.zeros(K, dtype=int)
    spent[used] = plan.n_samples
    nan = np.full(m, np.nan)
    est = {"mean": nan.copy(), "variance": nan.copy()}
    se = {"mean": nan.copy(), "variance": nan.copy()}
    se_plug = {"mean": nan.copy(), "variance": nan.copy()}
    weights, n_eq, speedup = {}, {}, {}
    cost_pilot = float(n_pilot * w.sum())
    cost_main = float(w[used] @ plan.n_samples)
    sub = np.ix_(used, used)
    for s in stats_asked:
        alphas = np.zeros((m, len(used) - 1))
        n_eq[s] = np.full(m, np.nan)
        for j in range(m):
            S = estimator_covariance(sets, s, cov[j][sub], m22[j][sub])
            alpha = optimal_weights(S)[0]
            plug, var = _acv_bootstrap(sets, s, Y_fit[:, used, j], boot)
            se_plug[s][j] = np.sqrt(plug)
            alphas[j] = alpha
            q = []
            for si, k in enumerate(sets.model_of_set):
                v = values[k][sets.indices(si), j]
                q.append(v.mean() if s == "mean" else v.var(ddof=1))
            delta = np.array([q[2 * i - 1] - q[2 * i] for i in range(1, len(used))])
            est[s][j] = q[0] + float(alpha @ delta)
            se[s][j] = np.sqrt(max(var, 0.0))
            sigma2 = cov[j, 0, 0]
            n_eq[s][j] = (sigma2 / var if s == "mean"
                          else _plain_variance_runs(var, sigma2, m22[j, 0, 0]))
        weights[s] = alphas
        speedup[s] = n_eq[s] * w[0] / (cost_pilot + cost_main)
    return MultifidelityResult(
        names_in=tuple(space.names), names_out=names_out, estimator=estimator,
        statistics=stats_asked, target=target, models_used=tuple(used), allocation=spent,
        n_pilot=int(n_pilot), costs=w, costs_measured=costs is None,
        budget=plan.cost if budget is None else float(budget),
        cost_pilot=cost_pilot, cost_main=cost_main, wall_pilot=wall_pilot, wall_main=wall_main,
        correlation=correlation, mean=est["mean"], mean_se=se["mean"],
        variance=est["variance"], variance_se=se["variance"], weights=weights,
        n_equivalent_hf=n_eq, speedup=speedup,
        n_evaluations=int(n_pilot) * K + int(plan.n_samples.sum()), plan=plan,
        pilot_inputs=xp, pilot_outputs=Yp, adapt=adapt, adaptation=adaptation,
        correlation_unadapted=correlation_unadapted, mean_se_plugin=se_plug["mean"],
        variance_se_plugin=se_plug["variance"], choice=choice)


def _run_main(models, k: int, space: ParameterSpace, x: np.ndarray,
              adaptation: LinearAdaptation | None) -> tuple[np.ndarray, float]:
    """Model ``k``'s main-phase values at ``x`` (adapted where asked) and its seconds; every
    point must succeed."""
    y, fails, wall = _timed(models[k], space, x)
    if fails:
        first = next(iter(fails.items()))
        raise EvaluationError(
            f"multifidelity_sample: models[{k}] failed on {len(fails)} of {len(x)} points "
            f"(first: point {first[0]}: {first[1]}); the estimators need every point")
    if adaptation is not None and k > 0:
        y = adaptation.apply(k, x, y)
    return np.asarray(y, dtype=float).reshape(len(x), -1), wall


def _acv_bootstrap(sets: SampleSets, statistic: str, Y: np.ndarray,
                   boot: tuple[int, np.random.Generator]) -> tuple[float, float]:
    """Plug-in and bootstrap-corrected variance of an ACV estimator on ``sets`` whose weights
    come from the pilot ``Y`` (n, K) of one response."""

    def moments(Ys, population=False):
        c, m = _sample_moments(Ys.transpose(1, 2, 0), population)
        return estimator_covariance(sets, statistic, c, m)

    def variance(W, Ys, population):
        S = moments(Ys, population)
        return weighted_variance_stack(np.broadcast_to(S, (len(W), *S.shape[1:])), W)

    return bootstrap_variance(Y, lambda Ys: weights_stack(moments(Ys)), variance,
                              boot[0] if Y.shape[1] > 1 else 0, boot[1])


def _mlblue_main(models, space, plan: GroupAllocation, s_main, names_out, target, stats_asked,
                 cov, w, xp, Yp, wall_pilot, n_pilot: int, costs_measured: bool, budget,
                 correlation, correlation_unadapted, adapt, adaptation, Y_fit, boot,
                 choice) -> MultifidelityResult:
    """The main phase of :func:`multifidelity_sample` with ``estimator="mlblue"``: each group
    with points gets a block of fresh independent points, every model runs once on the union
    of its groups' blocks."""
    K, m = len(models), len(names_out)
    assert plan.group_samples is not None
    groups = plan.groups
    gm = np.asarray(plan.group_samples, dtype=int)
    start = np.concatenate([[0], np.cumsum(gm)])
    xm = space.draw(int(start[-1]), design="random", seed=np.random.default_rng(s_main))
    wall_main = np.zeros(K)
    values = np.full((xm.shape[0], K, m), np.nan)
    for k in plan.models:
        idx = np.concatenate([np.arange(start[i], start[i + 1])
                              for i, g in enumerate(groups) if k in g and gm[i]])
        values[idx, k, :], wall_main[k] = _run_main(models, k, space, xm[idx], adaptation)
    spent = np.zeros(K, dtype=int)
    spent[list(plan.models)] = plan.n_samples
    nan = np.full(m, np.nan)
    mean, mean_se, se_plug = nan.copy(), nan.copy(), nan.copy()
    n_eq = np.full(m, np.nan)
    used = list(plan.models)
    alphas = np.zeros((m, len(used)))
    for j in range(m):
        sums = [values[start[i]:start[i + 1], list(g), j].sum(axis=0)
                for i, g in enumerate(groups)]
        mean[j] = mlblue_estimate(cov[j], groups, sums, gm)[0]
        def covs(Ys, population=False):
            return _sample_moments(Ys.transpose(1, 2, 0), population)[0]

        def variance(Cu, Ys, population):
            C = np.broadcast_to(covs(Ys, population), Cu.shape)
            return np.array([mlblue_weighted_variance(c, cu, groups, gm)
                             for c, cu in zip(C, Cu, strict=True)])

        plug, var = bootstrap_variance(Y_fit[:, :, j], covs, variance,
                                       boot[0] if len(used) > 1 else 0, boot[1])
        se_plug[j] = np.sqrt(plug)
        alphas[j] = np.linalg.pinv(mlblue_psi(cov[j], groups, gm)[np.ix_(used, used)],
                                   hermitian=True)[0]
        mean_se[j] = np.sqrt(max(var, 0.0))
        n_eq[j] = cov[j, 0, 0] / var
    cost_pilot = float(n_pilot * w.sum())
    cost_main = float(w @ spent)
    speedup = n_eq * w[0] / (cost_pilot + cost_main)
    return MultifidelityResult(
        names_in=tuple(space.names), names_out=names_out, estimator="mlblue",
        statistics=stats_asked, target=target, models_used=tuple(used), allocation=spent,
        n_pilot=n_pilot, costs=w, costs_measured=costs_measured,
        budget=plan.cost if budget is None else float(budget),
        cost_pilot=cost_pilot, cost_main=cost_main, wall_pilot=wall_pilot, wall_main=wall_main,
        correlation=correlation, mean=mean, mean_se=mean_se, variance=nan.copy(),
        variance_se=nan.copy(), weights={"mean": alphas}, n_equivalent_hf={"mean": n_eq},
        speedup={"mean": speedup}, n_evaluations=n_pilot * K + int(spent.sum()), plan=plan,
        pilot_inputs=xp, pilot_outputs=Yp, adapt=adapt, adaptation=adaptation,
        correlation_unadapted=correlation_unadapted, mean_se_plugin=se_plug,
        variance_se_plugin=nan.copy(), choice=choice)
