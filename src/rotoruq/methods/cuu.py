"""Calibration under uncertainty (CUU): the nested model of thesis figure 2.2.

An *inner* UQ method turns the input distributions into response statistics ``s(theta)``
(mean and/or standard deviation per response); an *outer* least-squares solver
(:func:`rotoruq.methods.least_squares.least_squares`, NL2SOL-style by default) moves the
calibrated input statistics ``theta`` (input means and/or standard deviations) until the
response statistics match their targets. Residuals are weighted by ``weighting``:
``"relative"`` (default) ``(s_k(theta) - t_k) / |t_k|`` (or ``s_k - t_k`` for a zero target), so
thrust in N and torque in N m weigh alike; ``"absolute"`` the plain differences ``s_k - t_k``,
as Dakota's nested model with ``calibration_terms`` computes them. The two agree when the
targets can all be met; they differ when there are more targets than calibrated statistics
(the least-squares compromise weighs the responses differently).

Inner methods
-------------
``"mean_value"`` (default, as in the thesis): first-order mean value statistics
``mean = g(mu)``, ``std^2 = sum_ij dg/dx_i dg/dx_j sigma_i sigma_j R_ij`` from
:func:`rotoruq.methods.reliability.mean_value_from_gradient`. When only standard deviations are
calibrated the gradient at the (fixed) means never changes: the model is evaluated once (2d+1
points with central differences, or one point and its analytic gradient) and the outer loop
runs on closed-form statistics with an analytic outer Jacobian. When means move, the inner
gradients of all points of an outer finite-difference Jacobian are evaluated in one model batch,
and points that share their means share one gradient.

``"sampling"``: sample statistics (std with ddof = 1) of a Latin hypercube (``design``) with
common random numbers: one design in (0, 1)^d is drawn once from ``seed`` and mapped through the
current distributions, so the statistics are smooth in ``theta`` and finite differences are
meaningful. All points of a Jacobian (``(p + 1) * n_samples`` rows) go to the model in one
batch.

``"pce"``: mean and standard deviation from the coefficients of a polynomial chaos expansion
(:func:`rotoruq.methods.pce.polynomial_chaos`, quadrature by default, ``order`` 2): exact for
responses that are polynomials of that order in the germs, deterministic in ``theta``.

A callable ``inner(model, space) -> object with .mean and .std (m,)`` is also accepted (e.g. a
user's own UQ method); it is called once per outer point.

Each inner method is a small class (:class:`MeanValueInner`, :class:`SamplingInner`,
:class:`PCEInner`, :class:`CallableInner`) with one interface: ``bind`` (once per calibration),
``statistics`` (input moments of K outer points -> response mean and std) and
``outer_jacobian`` (a closed-form outer Jacobian, or None for finite differences).

Parameterization of calibrated statistics
-----------------------------------------
* ``Normal`` and ``LogNormal``: the mean and the std are their defining parameters.
* ``Uniform``: its std is derived from its bounds, ``(upper - lower) / sqrt(12)``. Calibrating
  the std scales the half-width about the midpoint (``half-width = sqrt(3) std``); calibrating
  the mean moves the midpoint at constant width.
* Other distributions have no independent mean/std parameters; asking for them raises
  :class:`~rotoruq.errors.ParameterError` that says how the distribution is parameterized.

Identifiability
---------------
Targets only fix as many combinations of the calibrated statistics as there are targets, and a
statistic whose effect on the targets is negligible is not determined by them (thesis table
3.10: the flap-hinge stiffness next to the lift slopes). The result reports the singular values
of the outer Jacobian scaled column-wise by the statistic values (rows are already relative to
the targets) and flags the problem when the smallest is below ``identifiability_tolerance``
times the largest or when there are more calibrated statistics than targets.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._rng import SeedLike
from ..errors import EvaluationError, ParameterError
from ..model import (
    FD_STEP,
    FixedInputs,
    GradientOption,
    Model,
    align_inputs,
    check_gradient_option,
    model_gradient,
)
from ..params import LogNormal, Normal, ParameterSpace, Uniform, unit_design
from ._common import eval_space
from .least_squares import LeastSquaresResult, least_squares, solver_options
from .reliability import mean_value_from_gradient

__all__ = ["CUUResult", "CUUCheck", "calibrate_under_uncertainty", "check_cuu", "INNERS",
           "WEIGHTINGS",
           "MeanValueInner", "SamplingInner", "PCEInner", "CallableInner"]

_STATS = ("mean", "std")
#: residual weightings of the outer least squares
WEIGHTINGS = ("relative", "absolute")
_SQRT3 = math.sqrt(3.0)


@dataclass(frozen=True, eq=False)
class CUUResult:
    """Outcome of :func:`calibrate_under_uncertainty`.

    Attributes
    ----------
    names_in : tuple of str
        Names of the p calibrated statistics, ``"<input>.<mean|std>"``, in the order of
        ``x``.
    names_out : tuple of str
        The model's responses.
    x : ndarray of shape (p,)
        Calibrated statistic values, in the inputs' units.
    x0 : ndarray of shape (p,)
        The starting values.
    calibrated : dict
        Input -> {"mean": ..., "std": ...} of every input with a calibrated statistic (both
        moments, calibrated or not).
    space : ParameterSpace
        The space with the calibrated distributions.
    initial_space : ParameterSpace
        The space that was given.
    fixed : dict of str to float
        Deterministic inputs held fixed.
    targets : dict
        Response -> {statistic: target}.
    statistics_before, statistics_after : dict
        Response -> {"mean": ..., "std": ...} of every response from the inner method at
        ``x0`` and at ``x``.
    least_squares : LeastSquaresResult
        The outer least squares (its residuals weighted by ``weighting``).
    singular_values : ndarray of shape (min(n_targets, p),)
        Singular values of the scaled outer Jacobian.
    condition_number : float
        Largest / smallest singular value (inf when rank deficient).
    identifiable : bool
        False when the diagnostic flags the calibration.
    diagnostic : str
        Explanation of the identifiability verdict.
    inner : str
        Name of the inner method.
    optimizer : str
        The outer solver (``"nl2sol"``, ``"trf"`` or ``"lm"``).
    weighting : str
        ``"relative"`` or ``"absolute"`` residuals of the outer least squares.
    n_evaluations : int
        Model evaluations (points) of the whole nested study.
    converged : bool
        Whether the outer solver converged.
    message : str
        The outer solver's stopping reason.
    """

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    x: np.ndarray
    x0: np.ndarray
    calibrated: dict
    space: ParameterSpace
    initial_space: ParameterSpace
    fixed: dict
    targets: dict
    statistics_before: dict
    statistics_after: dict
    least_squares: LeastSquaresResult
    singular_values: np.ndarray
    condition_number: float
    identifiable: bool
    diagnostic: str
    inner: str
    optimizer: str
    weighting: str
    n_evaluations: int
    converged: bool
    message: str


@dataclass(frozen=True, eq=False)
class CUUCheck:
    """Forward sampling check of a CUU result (:func:`check_cuu`).

    Attributes
    ----------
    sampling : the :class:`~rotoruq.methods.sampling.SamplingResult` of the calibrated space.
    achieved : mapping response -> {statistic: sampled value} for every target.
    targets : mapping response -> {statistic: target}.
    relative_error : mapping response -> {statistic: (achieved - target) / abs(target)}.
    """

    sampling: object
    achieved: dict
    targets: dict
    relative_error: dict


def _with_moments(dist, mean: float, std: float):
    if isinstance(dist, Normal):
        return Normal(mean, std)
    if isinstance(dist, LogNormal):
        return LogNormal(mean, std)
    if isinstance(dist, Uniform):
        return Uniform(mean - _SQRT3 * std, mean + _SQRT3 * std)
    raise AssertionError(dist)  # guarded by _check_calibratable


def _check_calibratable(name: str, stat: str, dist) -> None:
    if isinstance(dist, Normal | LogNormal | Uniform):
        return
    params = {k: v for k, v in dist.describe().items() if k != "kind"}
    shown = ", ".join(f"{k}={v!r}" for k, v in params.items())
    raise ParameterError(
        f"cannot calibrate the {stat} of {name!r}: a {type(dist).__name__} is parameterized by "
        f"({shown}), not by an independent mean and std (its mean {dist.mean:.6g} and std "
        f"{dist.std:.6g} are derived). CUU calibrates the mean/std of Normal and LogNormal "
        "inputs, and of Uniform inputs as midpoint and half-width (half-width = sqrt(3) std); "
        "use one of those distributions for this input"
    )


def _parse_calibrate(calibrate, space: ParameterSpace, fixed: Mapping) -> list[tuple[int, str]]:
    if not isinstance(calibrate, Mapping) or not calibrate:
        raise ParameterError(
            "calibrate must be a non-empty mapping input -> 'mean' | 'std' | ['mean', 'std']"
        )
    out = []
    for name, stats_ in calibrate.items():
        stats_ = [stats_] if isinstance(stats_, str) else list(stats_)
        if name not in space.names:
            if name in fixed:
                raise ParameterError(
                    f"{name!r} is held fixed at {fixed[name]!r}: a deterministic input has no "
                    "mean or std to calibrate; give it a distribution in the space instead"
                )
            raise ParameterError(
                f"cannot calibrate {name!r}: not a parameter of the space "
                f"({', '.join(space.names)})"
            )
        for stat in stats_:
            if stat not in _STATS:
                raise ParameterError(
                    f"calibrate[{name!r}]: unknown statistic {stat!r}; valid: mean, std"
                )
            _check_calibratable(name, stat, space[name])
            out.append((space.index(name), stat))
    if len(set(out)) != len(out):
        raise ParameterError("a calibrated statistic is listed twice")
    return out


def _parse_targets(targets, names_out: Sequence[str]) -> list[tuple[int, str, float]]:
    if not isinstance(targets, Mapping) or not targets:
        raise ParameterError(
            "targets must be a non-empty mapping response -> {'mean': value, 'std': value}"
        )
    out = []
    for resp, spec in targets.items():
        if resp not in names_out:
            raise ParameterError(
                f"target for unknown response {resp!r}; the model's responses are "
                f"{list(names_out)}"
            )
        if not isinstance(spec, Mapping) or not spec:
            raise ParameterError(
                f"targets[{resp!r}] must be a mapping like {{'std': 11.45}}, got {spec!r}"
            )
        for stat, value in spec.items():
            if stat not in _STATS:
                raise ParameterError(
                    f"targets[{resp!r}]: unknown statistic {stat!r}; valid: mean, std"
                )
            value = float(value)
            if not np.isfinite(value):
                raise ParameterError(f"target {stat} of {resp!r} must be finite, got {value}")
            if stat == "std" and value <= 0:
                raise ParameterError(f"target std of {resp!r} must be > 0, got {value}")
            out.append((list(names_out).index(resp), stat, value))
    return out


class _Problem:
    """Maps outer variables theta (K, p) to input moments and, through the inner method, to
    weighted residuals of the targeted response statistics."""

    def __init__(self, model: Model, space: ParameterSpace, calibrated: list[tuple[int, str]],
                 targets: list[tuple[int, str, float]], weighting: str = "relative") -> None:
        self.model = model
        self.space = space
        self.calibrated = calibrated
        self.targets = targets
        self.mu0 = space.mean
        self.sd0 = space.std
        self.corr = space.correlation_matrix
        self.m = len(model.names_out)
        self.n_eval = 0
        self.means_move = any(s == "mean" for _, s in calibrated)
        t = np.array([v for _, _, v in targets])
        self.scale = (np.where(t != 0, np.abs(t), 1.0) if weighting == "relative"
                      else np.ones_like(t))
        self.target = t

    def moments(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Input means and stds (K, d) at outer points theta (K, p)."""
        k = theta.shape[0]
        mu = np.repeat(self.mu0[None, :], k, axis=0)
        sd = np.repeat(self.sd0[None, :], k, axis=0)
        for j, (i, stat) in enumerate(self.calibrated):
            (mu if stat == "mean" else sd)[:, i] = theta[:, j]
        return mu, sd

    def space_at(self, mu: np.ndarray, sd: np.ndarray) -> ParameterSpace:
        dists = {}
        for i, _ in self.calibrated:
            name = self.space.names[i]
            dists[name] = _with_moments(self.space.distributions[i], mu[i], sd[i])
        return self.space.replace(**dists)


class InnerMethod:
    """The interface of a CUU inner method (one instance per calibration).

    ``bind(problem, seed)`` once before the outer loop; ``statistics(mu, sd)`` maps input
    means and stds (K, d) to response means and stds (K, m), adding its model evaluations to
    ``problem.n_eval`` (NaN rows where the model failed); ``outer_jacobian()`` returns a
    closed-form outer Jacobian ``theta (K, p) -> (K, n_targets, p)`` or None.
    """

    name = "inner"

    def bind(self, problem: _Problem, seed: SeedLike) -> None:
        self.problem = problem

    def statistics(self, mu: np.ndarray, sd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def outer_jacobian(self) -> Callable[[np.ndarray], np.ndarray] | None:
        return None


class MeanValueInner(InnerMethod):
    """First-order mean value statistics (thesis eqs. 2.4-2.5) from the model's gradient at
    the input means: ``gradient`` and ``fd_step`` as in :func:`rotoruq.model.model_gradient`.
    Gradients are cached per mean vector; those of all points of an outer Jacobian are
    evaluated in one model batch."""

    name = "mean_value"

    def __init__(self, gradient: GradientOption = "auto", fd_step: float = FD_STEP) -> None:
        self.gradient = gradient
        self.fd_step = fd_step

    def bind(self, problem: _Problem, seed: SeedLike) -> None:
        super().bind(problem, seed)
        check_gradient_option(self.gradient, problem.model)
        self._cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def _at_means(self, mus: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Values (U, m) and gradients (U, m, d) at distinct mean vectors, one model batch."""
        pr = self.problem
        todo = [u for u, mu in enumerate(mus) if mu.tobytes() not in self._cache]
        if todo:
            at = model_gradient(pr.model, mus[todo], gradient=self.gradient,
                                fd_step=self.fd_step, scale=pr.sd0, names_in=pr.space.names)
            pr.n_eval += at.n_evaluations
            for u, g0, gr in zip(todo, at.values, at.gradient, strict=True):
                self._cache[mus[u].tobytes()] = (g0, gr)
        g0 = np.array([self._cache[mu.tobytes()][0] for mu in mus])
        grad = np.array([self._cache[mu.tobytes()][1] for mu in mus])
        return g0, grad

    def statistics(self, mu: np.ndarray, sd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pr = self.problem
        uniq, inv = np.unique(mu, axis=0, return_inverse=True)
        g0, grad = self._at_means(uniq)
        mean = np.empty((len(mu), pr.m))
        std = np.empty((len(mu), pr.m))
        for k in range(len(mu)):
            u = inv.ravel()[k]
            if not (np.all(np.isfinite(g0[u])) and np.all(np.isfinite(grad[u]))):
                mean[k] = std[k] = np.nan
                continue
            mv = mean_value_from_gradient(g0[u], grad[u], sd[k], pr.corr)
            mean[k], std[k] = mv.mean, mv.std
        return mean, std

    def outer_jacobian(self) -> Callable[[np.ndarray], np.ndarray] | None:
        """Closed form when only stds are calibrated (the gradient at the means is fixed)."""
        pr = self.problem
        if pr.means_move:
            return None
        grad = self._at_means(pr.mu0[None, :])[1][0]
        sd_idx = np.array([i for i, _ in pr.calibrated])

        def jac(theta: np.ndarray) -> np.ndarray:
            theta = np.atleast_2d(theta)
            _, sd = pr.moments(theta)
            out = np.zeros((len(theta), len(pr.targets), len(pr.calibrated)))
            for k in range(len(theta)):
                sg = grad * sd[k][None, :]  # (m, d)
                rsg = sg @ pr.corr.T
                var = np.einsum("md,md->m", sg, rsg)
                std = np.sqrt(np.maximum(var, 0.0))
                # d std / d sigma_i = g_i (R s g)_i / std
                dstd = grad * rsg / np.where(std > 0, std, np.inf)[:, None]  # (m, d)
                for row, (r, stat, _) in enumerate(pr.targets):
                    if stat == "std":
                        out[k, row] = dstd[r, sd_idx] / pr.scale[row]
            return out

        return jac


class SamplingInner(InnerMethod):
    """Sample mean and std (ddof = 1) of ``n_samples`` points of one ``design`` in (0, 1)^d,
    drawn once from the seed and mapped through each outer point's distributions (common
    random numbers); all outer points of a call go to the model in one batch."""

    name = "sampling"

    def __init__(self, n_samples: int = 200, design: str = "lhs") -> None:
        if int(n_samples) < 2:
            raise ParameterError(f"inner sampling needs n_samples >= 2, got {n_samples}")
        self.n_samples = int(n_samples)
        self.design = design

    def bind(self, problem: _Problem, seed: SeedLike) -> None:
        super().bind(problem, seed)
        self.unit = unit_design(self.n_samples, problem.space.dim, design=self.design,
                                seed=seed)

    def statistics(self, mu: np.ndarray, sd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        from .sampling import unit_to_space

        pr = self.problem
        n = self.n_samples
        X = np.concatenate(
            [unit_to_space(pr.space_at(mu[k], sd[k]), self.unit) for k in range(len(mu))]
        )
        Y = eval_space(pr.model, pr.space, X).values.reshape(len(mu), n, pr.m)
        pr.n_eval += len(X)
        ok = np.all(np.isfinite(Y), axis=2)  # (K, n)
        mean = np.full((len(mu), pr.m), np.nan)
        std = np.full((len(mu), pr.m), np.nan)
        for k in range(len(mu)):
            if ok[k].sum() >= 2:
                mean[k] = Y[k, ok[k]].mean(axis=0)
                std[k] = Y[k, ok[k]].std(axis=0, ddof=1)
        return mean, std


class CallableInner(InnerMethod):
    """A user's ``inner(model, space)`` returning ``.mean`` and ``.std`` (m,) (or
    ``.statistics.mean/std``), called once per outer point."""

    def __init__(self, func: Callable) -> None:
        self.func = func
        self.name = getattr(func, "__name__", "callable")

    def statistics(self, mu: np.ndarray, sd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pr = self.problem
        mean = np.empty((len(mu), pr.m))
        std = np.empty((len(mu), pr.m))
        for k in range(len(mu)):
            res = self.run(pr.space_at(mu[k], sd[k]))
            src = getattr(res, "statistics", res)
            mean[k] = np.asarray(src.mean, dtype=float)
            std[k] = np.asarray(src.std, dtype=float)
            pr.n_eval += int(getattr(res, "n_evaluations", 0))
        return mean, std

    def run(self, space: ParameterSpace) -> Any:
        return self.func(self.problem.model, space)


class PCEInner(CallableInner):
    """Mean and std from the coefficients of a polynomial chaos expansion (eqs. 2.18-2.19) of
    total order ``order``, one expansion per outer point: ``estimator`` "quadrature" or
    "sparse_grid" (deterministic in theta, so the outer finite differences are meaningful);
    ``quadrature_points`` and ``basis`` as in :func:`rotoruq.methods.pce.polynomial_chaos`."""

    name = "pce"

    def __init__(self, order: int = 2, estimator: str = "quadrature",
                 quadrature_points: int | None = None, basis: str = "askey") -> None:
        if estimator == "regression":
            raise ParameterError("inner 'pce' takes estimator 'quadrature' or 'sparse_grid' "
                                 "(deterministic in theta, so the outer finite differences "
                                 "are meaningful), not 'regression'")
        self.order = int(order)
        self.options: dict[str, Any] = {"estimator": estimator,
                                        "quadrature_points": quadrature_points, "basis": basis}

    def run(self, space: ParameterSpace) -> Any:
        from .pce import polynomial_chaos

        return polynomial_chaos(self.problem.model, space, self.order, **self.options)


#: inner method name -> class (keyword options of the class are the ``inner_options``)
INNERS: dict[str, type[InnerMethod]] = {
    "mean_value": MeanValueInner, "sampling": SamplingInner, "pce": PCEInner,
}


def _make_inner(inner, inner_options: Mapping | None, gradient, fd_step: float) -> InnerMethod:
    if callable(inner):
        if inner_options:
            raise ParameterError("inner_options apply to a named inner method, not a callable")
        return CallableInner(inner)
    name = str(inner).lower()
    if name not in INNERS:
        raise ParameterError(f"unknown inner method {inner!r}; valid: "
                             f"{', '.join(map(repr, INNERS))} or a callable")
    opts = dict(inner_options or {})
    if name == "mean_value":
        opts = {"gradient": gradient, "fd_step": fd_step, **opts}
    import inspect

    valid = [p for p in inspect.signature(INNERS[name].__init__).parameters if p != "self"]
    unknown = sorted(set(opts) - set(valid))
    if unknown:
        raise ParameterError(f"unknown {name} inner options {unknown}; valid: {valid}")
    return INNERS[name](**opts)


def _nested_dict(pairs) -> dict:
    out: dict = {}
    for a, b, v in pairs:
        out.setdefault(a, {})[b] = float(v)
    return out


def _identifiability(J, x, labels, n_targets, tol):
    scale = np.where(x != 0, np.abs(x), 1.0)
    Js = J * scale[None, :]
    sv = np.linalg.svd(Js, compute_uv=False)
    p = len(labels)
    smax = sv[0] if sv.size else 0.0
    smin = sv[-1] if (sv.size == p) else 0.0
    cond = smax / smin if smin > 0 else np.inf
    col = np.linalg.norm(Js, axis=0)
    weak = [labels[j] for j in range(p) if col[j] < tol * max(col.max(), 1e-300)]
    if p > n_targets:
        return sv, cond, False, (
            f"{p} calibrated statistics but only {n_targets} targets: infinitely many "
            "combinations match the targets equally well and the values found depend on the "
            "start. Calibrate at most as many statistics as targets, or "
            "add targets"
            + (f"; {', '.join(weak)} barely affect the targets" if weak else "")
        )
    if smax == 0 or smin < tol * smax:
        if smax > 0 and smin > 0:
            _, _, vt = np.linalg.svd(Js)
            worst = labels[int(np.argmax(np.abs(vt[-1])))]
        else:
            worst = weak[0] if weak else labels[-1]
        extra = f" ({', '.join(weak)} barely affect the targets)" if weak else ""
        return sv, cond, False, (
            f"practically unidentifiable: the scaled outer Jacobian has condition number "
            f"{cond:.3g} (> 1/{tol:g}); the targets hardly depend on {worst}{extra}, so its "
            "calibrated value is not determined by the data. Calibrate variables of comparable "
            "sensitivity together or hold the weak one fixed"
        )
    return sv, cond, True, (
        f"identifiable: scaled outer Jacobian condition number {cond:.3g}"
    )


def _outer_bounds(space: ParameterSpace, calibrated, labels, x0, bounds):
    """Bounds (lower, upper) of the calibrated statistics: defaults and the user's."""
    lo = np.full(len(x0), -np.inf)
    hi = np.full(len(x0), np.inf)
    for j, (i, s) in enumerate(calibrated):
        if s == "std":
            lo[j] = 1e-6 * x0[j]
        elif isinstance(space.distributions[i], LogNormal):
            lo[j] = 1e-6 * abs(x0[j])
    for key, (b_lo, b_hi) in dict(bounds or {}).items():
        label = key if isinstance(key, str) else ".".join(key)
        if label not in labels:
            raise ParameterError(f"bounds for {label!r}, which is not calibrated; have {labels}")
        j = labels.index(label)
        lo[j], hi[j] = max(lo[j], float(b_lo)), float(b_hi)
    if np.any(x0 < lo) or np.any(x0 > hi):
        raise ParameterError(f"starting statistics {x0} lie outside the bounds {lo}, {hi}")
    return lo, hi


def calibrate_under_uncertainty(
    model: Model,
    space: ParameterSpace,
    *,
    calibrate: Mapping[str, str | Sequence[str]],
    targets: Mapping[str, Mapping[str, float]],
    inner: str | Callable = "mean_value",
    inner_options: Mapping | None = None,
    fixed: Mapping[str, float] | None = None,
    bounds: Mapping | None = None,
    optimizer: str = "nl2sol",
    weighting: str = "relative",
    gradient: GradientOption = "auto",
    fd_step: float = FD_STEP,
    identifiability_tolerance: float = 1e-3,
    seed: SeedLike = None,
    **outer_options: Any,
) -> CUUResult:
    """Calibrate input statistics so that response statistics match targets (nested model).

    Parameters
    ----------
    model : Model; its inputs are the space's parameters plus the ``fixed`` inputs.
    space : ParameterSpace with the starting distributions (their means/stds are the start).
    calibrate : mapping input -> "mean", "std" or ["mean", "std"], e.g.
        ``{"cla_m03": "std", "coll": ["mean", "std"]}``.
    targets : mapping response -> {"mean": value, "std": value}, e.g.
        ``{"thrust": {"std": 11.45}, "torque": {"mean": -2360.9, "std": 2.1}}``.
    inner : "mean_value" (default), "sampling", "pce" (see :data:`INNERS`), or a callable
        ``inner(model, space)`` returning an object with ``.mean`` and ``.std`` arrays (m,)
        (or ``.statistics.mean/std``).
    inner_options : keyword options of the named inner method: "sampling": ``n_samples``
        (per outer point, default 200) and ``design`` ("lhs"); "pce": ``order`` (default 2),
        ``estimator`` ("quadrature", default, or "sparse_grid"), ``quadrature_points`` and
        ``basis`` of :func:`rotoruq.methods.pce.polynomial_chaos`.
    fixed : deterministic inputs not in the space, held at the given values.
    bounds : mapping ``"input.stat"`` (or ``(input, stat)``) -> (lower, upper) for calibrated
        statistics. Defaults: stds in ``[1e-6 std0, inf)``; means of lognormals ``> 0``.
    optimizer : outer solver, "nl2sol" (default), "trf" or "lm".
    weighting : residuals of the outer least squares: "relative" (default) to the targets,
        ``(s - t) / |t|``, or "absolute", ``s - t`` as Dakota's nested model. They give the
        same answer when every target can be met, different compromises otherwise.
    gradient : how the mean-value inner method gets the model's gradient: "auto",
        "analytic", "finite_difference" or a callable (see
        :func:`rotoruq.model.model_gradient`).
    fd_step : relative finite-difference step of the inner gradient and of the outer Jacobian
        (default :data:`rotoruq.model.FD_STEP`).
    identifiability_tolerance : flag when the smallest scaled singular value is below this fraction
        of the largest.
    seed : seed of the inner sampling design (common random numbers across outer iterations).
    **outer_options : passed to :func:`least_squares`: ``convergence`` (a
        :class:`~rotoruq.methods.least_squares.Convergence`), ``initial_radius``,
        ``confidence``; the fields of the Convergence may be given flat here
        (``max_iterations``, ``max_function_evaluations``, ``tolerance`` (Dakota default
        1e-4), ..., as a study file's ``cuu`` step gives them).

    Returns
    -------
    CUUResult

    Examples
    --------
    y = 2 a with a ~ N(1, 0.5): the mean value method is exact for a linear model, so targets
    mean 4 and std 0.2 of y give a ~ N(2, 0.1):

    >>> import numpy as np
    >>> import rotoruq as rq
    >>> model = rq.FunctionModel(lambda x: 2.0 * x, ["a"], ["y"])
    >>> space = rq.ParameterSpace({"a": rq.Normal(1.0, 0.5)})
    >>> cuu = rq.calibrate_under_uncertainty(model, space, calibrate={"a": ["mean", "std"]},
    ...                                      targets={"y": {"mean": 4.0, "std": 0.2}})
    >>> np.round([cuu.space.parameters["a"].mean, cuu.space.parameters["a"].std], 6).tolist()
    [2.0, 0.1]

    Residual weighting: relative (default) against absolute, as Dakota's nested model:

    >>> from rotoruq import FunctionModel, Normal, ParameterSpace
    >>> m = FunctionModel(lambda x: np.column_stack([x[:, 0], 2 * x[:, 0]]), ["a"], ["y", "z"])
    >>> space = ParameterSpace({"a": Normal(1.0, 0.1)})
    >>> t = {"y": {"std": 0.1}, "z": {"std": 1.0}}
    >>> rel = calibrate_under_uncertainty(m, space, calibrate={"a": "std"}, targets=t)
    >>> ab = calibrate_under_uncertainty(m, space, calibrate={"a": "std"}, targets=t,
    ...                                  weighting="absolute")
    >>> # closed forms: sum(a/t) / sum(a^2/t^2) = 12/104 and sum(a t) / sum(a^2) = 2.1/5
    >>> round(float(rel.x[0]), 4), round(float(ab.x[0]), 4)
    (0.1154, 0.42)
    """
    if weighting not in WEIGHTINGS:
        raise ParameterError(f"weighting must be one of {', '.join(map(repr, WEIGHTINGS))} "
                             f"(relative to the targets, or plain differences as Dakota), "
                             f"got {weighting!r}")
    fixed = dict(fixed or {})
    if not isinstance(space, ParameterSpace):
        raise ParameterError(f"space must be a ParameterSpace, got {type(space).__name__}")
    view = FixedInputs(model, fixed) if fixed else model
    align_inputs(view, space.names)  # raises a clear error when names disagree
    calibrated = _parse_calibrate(calibrate, space, fixed)
    tgt = _parse_targets(targets, tuple(model.names_out))
    method = _make_inner(inner, inner_options, gradient, fd_step)
    prob = _Problem(view, space, calibrated, tgt, weighting)
    method.bind(prob, seed)

    def statistics(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return method.statistics(*prob.moments(np.atleast_2d(theta)))

    def residual(theta: np.ndarray) -> np.ndarray:
        mean, std = statistics(theta)
        s = np.column_stack([(mean if stat == "mean" else std)[:, r] for r, stat, _ in tgt])
        return (s - prob.target[None, :]) / prob.scale[None, :]

    labels = tuple(f"{space.names[i]}.{s}" for i, s in calibrated)
    x0 = np.array([(space.mean if s == "mean" else space.std)[i] for i, s in calibrated])
    lo, hi = _outer_bounds(space, calibrated, labels, x0, bounds)
    mean0, std0 = statistics(x0[None, :])
    if not np.all(np.isfinite(residual(x0[None, :]))):
        raise EvaluationError("the inner method returned NaN statistics at the starting point")
    jac = method.outer_jacobian()
    ls = least_squares(residual, x0, gradient=jac if jac is not None else "finite_difference",
                       bounds=(lo, hi), optimizer=optimizer, fd_step=fd_step,
                       **solver_options("calibrate_under_uncertainty", outer_options))
    mean1, std1 = statistics(ls.x[None, :])
    mu, sd = prob.moments(ls.x[None, :])
    sv, cond, ok, diag = _identifiability(ls.jacobian, ls.x, labels, len(tgt),
                                          identifiability_tolerance)
    names_out = tuple(model.names_out)
    return CUUResult(
        names_in=labels, names_out=names_out, x=ls.x, x0=x0,
        calibrated={space.names[i]: {"mean": float(mu[0, i]), "std": float(sd[0, i])}
                    for i, _ in calibrated},
        space=prob.space_at(mu[0], sd[0]), initial_space=space, fixed=fixed,
        targets=_nested_dict((names_out[r], s, v) for r, s, v in tgt),
        statistics_before=_response_statistics(names_out, mean0[0], std0[0]),
        statistics_after=_response_statistics(names_out, mean1[0], std1[0]),
        least_squares=ls, singular_values=sv, condition_number=float(cond), identifiable=ok,
        diagnostic=diag, inner=method.name, optimizer=ls.optimizer, weighting=weighting,
        n_evaluations=prob.n_eval,
        converged=ls.converged, message=ls.message,
    )


def _response_statistics(names_out, mean: np.ndarray, std: np.ndarray) -> dict:
    return {n: {"mean": float(mean[k]), "std": float(std[k])} for k, n in enumerate(names_out)}


def check_cuu(result: CUUResult, model: Model, n_samples: int = 300, *, design: str = "lhs",
              seed: SeedLike = None) -> CUUCheck:
    """Forward-propagate the calibrated distributions with ``n_samples`` points of ``design``
    (one model batch) and compare the sampled response statistics with the CUU targets (the
    thesis confirms each CUU with 300-500 LHS samples).

    Parameters
    ----------
    result : CUUResult
        The calibration to check.
    model : Model
        The calibrated model (the inputs held fixed in ``result`` are held fixed again).
    n_samples : int, optional
        Sample size (default 300).
    design : str, optional
        ``"lhs"`` (default), ``"random"``, ``"sobol"`` or ``"halton"``.
    seed : int, SeedSequence, Generator or None, optional
        Random source of the sample.

    Returns
    -------
    CUUCheck
        The sampled statistics and their relative errors against the targets.

    Examples
    --------
    The calibration of :func:`calibrate_under_uncertainty`'s example, checked by 2,000 LHS
    points: the sampled mean and std of y meet the targets 4 and 0.2:

    >>> import numpy as np
    >>> import rotoruq as rq
    >>> model = rq.FunctionModel(lambda x: 2.0 * x, ["a"], ["y"])
    >>> cuu = rq.calibrate_under_uncertainty(model, rq.ParameterSpace({"a": rq.Normal(1.0, 0.5)}),
    ...                                      calibrate={"a": ["mean", "std"]},
    ...                                      targets={"y": {"mean": 4.0, "std": 0.2}})
    >>> check = rq.check_cuu(cuu, model, 2000, seed=1)
    >>> {k: round(float(v), 2) for k, v in check.achieved["y"].items()}
    {'mean': 4.0, 'std': 0.2}
    """
    from .sampling import sample

    view = FixedInputs(model, result.fixed) if result.fixed else model
    s = sample(view, result.space, n_samples, design=design, seed=seed)
    names_out = tuple(model.names_out)
    achieved: dict = {}
    rel: dict = {}
    for resp, spec in result.targets.items():
        k = names_out.index(resp)
        for stat, target in spec.items():
            v = float((s.statistics.mean if stat == "mean" else s.statistics.std)[k])
            achieved.setdefault(resp, {})[stat] = v
            rel.setdefault(resp, {})[stat] = (v - target) / (abs(target) if target else 1.0)
    return CUUCheck(sampling=s, achieved=achieved, targets=result.targets, relative_error=rel)
