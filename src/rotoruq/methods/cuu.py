"""Calibration under uncertainty (CUU): the nested model of thesis figure 2.2.

An *inner* UQ method turns the input distributions into response statistics ``s(theta)``
(mean and/or standard deviation per response); an *outer* least-squares solver
(:func:`rotoruq.methods.least_squares.least_squares`, NL2SOL-style by default) moves the
calibrated input statistics ``theta`` (input means and/or standard deviations) until the
response statistics match their targets. Residuals are relative: ``(s_k(theta) - t_k) / |t_k|``
(or ``s_k - t_k`` for a zero target), so thrust in N and torque in N m weigh alike.

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

``"lhs"``: Latin hypercube statistics (sample std, ddof = 1) with common random numbers: one
design in (0, 1)^d is drawn once from ``seed`` and mapped through the current distributions, so
the statistics are smooth in ``theta`` and finite differences are meaningful. All points of a
Jacobian (``(p + 1) * n`` rows) go to the model in one batch.

``"pce"``: mean and standard deviation from the coefficients of a polynomial chaos expansion
(:func:`rotoruq.methods.pce.polynomial_chaos`, quadrature by default, ``order`` 2): exact for
responses that are polynomials of that order in the germs, deterministic in ``theta``.

A callable ``inner(model, space) -> object with .mean and .std (m,)`` is also accepted (e.g. a
user's own UQ method); it is called once per outer point.

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
the targets) and flags the problem when the smallest is below ``identifiability_tol`` times the
largest or when there are more calibrated statistics than targets.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from .._rng import SeedLike
from ..errors import ParameterError
from ..model import align_inputs, evaluate, has_gradient
from ..params import LogNormal, Normal, ParameterSpace, Uniform, unit_design
from ._common import analytic_gradient, eval_space, fd_steps
from .least_squares import LeastSquaresResult, least_squares
from .reliability import mean_value_from_gradient

__all__ = ["CUUResult", "CUUCheck", "calibrate_under_uncertainty", "check_cuu"]

_STATS = ("mean", "std")
_SQRT3 = math.sqrt(3.0)


@dataclass(frozen=True)
class CUUResult:
    """Outcome of :func:`calibrate_under_uncertainty`.

    Attributes
    ----------
    labels : names of the calibrated statistics, ``"<input>.<mean|std>"``, in the order of
        ``x``.
    x : (p,) calibrated statistic values; ``x0`` the starting ones.
    calibrated : mapping input -> {"mean": ..., "std": ...} of every input with a calibrated
        statistic (both moments, calibrated or not).
    space : the ParameterSpace with the calibrated distributions; ``initial_space`` the given
        one.
    fixed : deterministic inputs held fixed.
    targets : mapping response -> {statistic: target}.
    statistics_before, statistics_after : mapping response -> {"mean": ..., "std": ...} of
        every response from the inner method at ``x0`` and at ``x``.
    least_squares : the outer :class:`LeastSquaresResult` (its residuals are relative).
    singular_values : (min(n_targets, p),) singular values of the scaled outer Jacobian.
    condition_number : largest / smallest singular value (inf when rank deficient).
    identifiable : False when the diagnostic flags the calibration.
    diagnostic : explanation of the identifiability verdict.
    inner : name of the inner method.
    n_model_evaluations : model evaluations (points) of the whole nested study.
    success, message : from the outer solver.
    """

    labels: tuple[str, ...]
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
    n_model_evaluations: int
    success: bool
    message: str
    names_out: tuple[str, ...] = field(default=(), repr=False)


@dataclass(frozen=True)
class CUUCheck:
    """Forward sampling check of a CUU result (:func:`check_cuu`).

    Attributes
    ----------
    sampling : the :class:`~rotoruq.methods.sampling.SamplingResult` of the calibrated space.
    achieved : mapping response -> {statistic: sampled value} for every target.
    targets : mapping response -> {statistic: target}.
    relative_error : mapping response -> {statistic: (achieved - target) / |target|}.
    """

    sampling: object
    achieved: dict
    targets: dict
    relative_error: dict


class _FixedInputs:
    """A Model view with some inputs held at fixed values (their columns are filled in)."""

    def __init__(self, model, fixed: Mapping[str, float]):
        self.model = model
        self.fixed = {k: float(v) for k, v in fixed.items()}
        self.names_in = tuple(n for n in model.names_in if n not in self.fixed)
        self.names_out = tuple(model.names_out)
        names = tuple(model.names_in)
        self._free = np.array([names.index(n) for n in self.names_in], dtype=int)
        self._fix = np.array([names.index(n) for n in self.fixed], dtype=int)
        self._vals = np.array(list(self.fixed.values()))
        if has_gradient(model):
            self.gradient = self._gradient

    def _full(self, x):
        x = np.atleast_2d(np.asarray(x, dtype=float))
        full = np.empty((x.shape[0], len(self.model.names_in)))
        full[:, self._free] = x
        full[:, self._fix] = self._vals
        return full

    def __call__(self, x):
        return evaluate(self.model, self._full(x)).values

    def evaluate(self, x):
        return evaluate(self.model, self._full(x))

    def _gradient(self, x):
        g = np.asarray(self.model.gradient(self._full(x)), dtype=float)
        if g.ndim == 2:
            g = g[:, None, :]
        return g[:, :, self._free]


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


_PCE_OPTIONS = {"order", "method", "quadrature_points", "basis"}


class _Problem:
    """Maps outer variables theta (K, p) to input moments and response statistics."""

    def __init__(self, model, space, calibrated, targets, inner, inner_options, seed):
        self.model = model
        self.space = space
        self.calibrated = calibrated
        self.targets = targets
        self.inner = inner
        self.opts = dict(inner_options or {})
        self.mu0 = space.mean
        self.sd0 = space.std
        self.corr = space.correlation_matrix
        self.m = len(model.names_out)
        self.n_eval = 0
        self.means_move = any(s == "mean" for _, s in calibrated)
        self._cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
        t = np.array([v for _, _, v in targets])
        self.scale = np.where(t != 0, np.abs(t), 1.0)
        self.target = t
        if inner == "lhs":
            n = int(self.opts.get("n", 200))
            if n < 2:
                raise ParameterError(f"inner LHS needs n >= 2 samples, got {n}")
            self.unit = unit_design(n, space.dim, design="lhs", seed=seed)
        elif inner == "mean_value":
            unknown = set(self.opts) - {"gradient", "fd_step"}
            if unknown:
                raise ParameterError(f"unknown mean_value inner options {sorted(unknown)}")
        elif inner == "pce":
            unknown = set(self.opts) - _PCE_OPTIONS
            if unknown:
                raise ParameterError(f"unknown pce inner options {sorted(unknown)}; valid: "
                                     f"{sorted(_PCE_OPTIONS)}")
            if str(self.opts.get("method", "quadrature")) == "regression":
                raise ParameterError("inner 'pce' takes method 'quadrature' or 'sparse_grid' "
                                     "(deterministic in theta, so the outer finite differences "
                                     "are meaningful), not 'regression'")

    def moments(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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

    # --- inner methods: (K, p) -> mean (K, m), std (K, m) -------------------------------------
    def statistics(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        theta = np.atleast_2d(theta)
        mu, sd = self.moments(theta)
        if self.inner == "mean_value":
            return self._mean_value(mu, sd)
        if self.inner == "lhs":
            return self._lhs(mu, sd)
        if self.inner == "pce":
            return self._pce(mu, sd)
        return self._callable(mu, sd)

    def _gradients(self, mus: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Values (U, m) and gradients (U, m, d) at distinct mean vectors, one model batch."""
        out_g0 = np.empty((len(mus), self.m))
        out_gr = np.empty((len(mus), self.m, self.space.dim))
        todo = [u for u, mu in enumerate(mus) if mu.tobytes() not in self._cache]
        if todo:
            X = mus[todo]
            mode = self.opts.get("gradient", "auto")
            fd_step = float(self.opts.get("fd_step", 1e-6))
            if mode not in ("auto", "analytic", "fd"):
                raise ParameterError(f"gradient must be 'auto', 'analytic' or 'fd', got {mode!r}")
            d = self.space.dim
            if mode == "analytic" or (mode == "auto" and has_gradient(self.model)):
                vals = eval_space(self.model, self.space, X).values
                grads = analytic_gradient(self.model, self.space, X)
                self.n_eval += len(X)
            else:
                idx = np.arange(d)
                pts, hs = [], []
                for x0 in X:
                    h = fd_steps(x0, self.sd0, fd_step)
                    p = np.repeat(x0[None, :], 2 * d + 1, axis=0)
                    p[1 + idx, idx] += h
                    p[1 + d + idx, idx] -= h
                    pts.append(p)
                    hs.append(h)
                v = eval_space(self.model, self.space, np.concatenate(pts)).values
                self.n_eval += len(X) * (2 * d + 1)
                v = v.reshape(len(X), 2 * d + 1, self.m)
                vals = v[:, 0]
                grads = np.transpose(v[:, 1 : d + 1] - v[:, d + 1 :], (0, 2, 1)) / (
                    2.0 * np.array(hs)[:, None, :]
                )
            for u, g0, gr in zip(todo, vals, grads, strict=True):
                self._cache[mus[u].tobytes()] = (g0, gr)
        for u, mu in enumerate(mus):
            out_g0[u], out_gr[u] = self._cache[mu.tobytes()]
        return out_g0, out_gr

    def _mean_value(self, mu, sd):
        uniq, inv = np.unique(mu, axis=0, return_inverse=True)
        g0, grad = self._gradients(uniq)
        mean = np.empty((len(mu), self.m))
        std = np.empty((len(mu), self.m))
        for k in range(len(mu)):
            u = inv.ravel()[k]
            if not (np.all(np.isfinite(g0[u])) and np.all(np.isfinite(grad[u]))):
                mean[k] = std[k] = np.nan
                continue
            mv = mean_value_from_gradient(g0[u], grad[u], sd[k], self.corr)
            mean[k], std[k] = mv.mean, mv.std
        return mean, std

    def _lhs(self, mu, sd):
        from .sampling import unit_to_space

        n = self.unit.shape[0]
        X = np.concatenate(
            [unit_to_space(self.space_at(mu[k], sd[k]), self.unit) for k in range(len(mu))]
        )
        Y = eval_space(self.model, self.space, X).values.reshape(len(mu), n, self.m)
        self.n_eval += len(X)
        ok = np.all(np.isfinite(Y), axis=2)  # (K, n)
        mean = np.full((len(mu), self.m), np.nan)
        std = np.full((len(mu), self.m), np.nan)
        for k in range(len(mu)):
            if ok[k].sum() >= 2:
                mean[k] = Y[k, ok[k]].mean(axis=0)
                std[k] = Y[k, ok[k]].std(axis=0, ddof=1)
        return mean, std

    def _pce(self, mu, sd):
        """Mean and std from the coefficients of a polynomial chaos expansion (quadrature or
        sparse grid, eqs. 2.18-2.19), one expansion per outer point."""
        from .pce import polynomial_chaos

        opts = dict(self.opts)
        order = int(opts.pop("order", 2))
        mean = np.empty((len(mu), self.m))
        std = np.empty((len(mu), self.m))
        for k in range(len(mu)):
            res = polynomial_chaos(self.model, self.space_at(mu[k], sd[k]), order, **opts)
            mean[k], std[k] = res.mean, res.std
            self.n_eval += int(res.n_evaluations)
        return mean, std

    def _callable(self, mu, sd):
        mean = np.empty((len(mu), self.m))
        std = np.empty((len(mu), self.m))
        for k in range(len(mu)):
            res = self.inner(self.model, self.space_at(mu[k], sd[k]))
            src = getattr(res, "statistics", res)
            mean[k] = np.asarray(src.mean, dtype=float)
            std[k] = np.asarray(src.std, dtype=float)
            self.n_eval += int(getattr(res, "n_evaluations", 0))
        return mean, std

    # --- outer least squares ----------------------------------------------------------------
    def residual(self, theta: np.ndarray) -> np.ndarray:
        mean, std = self.statistics(theta)
        cols = [
            (mean if stat == "mean" else std)[:, r] for r, stat, _ in self.targets
        ]
        s = np.column_stack(cols)
        return (s - self.target[None, :]) / self.scale[None, :]

    def analytic_jacobian(self):
        """Outer Jacobian for mean-value inners with fixed means (only stds calibrated)."""
        if self.inner != "mean_value" or self.means_move:
            return None
        g0, grad = self._gradients(self.mu0[None, :])
        grad = grad[0]
        sd_idx = np.array([i for i, _ in self.calibrated])

        def jac(theta):
            theta = np.atleast_2d(theta)
            _, sd = self.moments(theta)
            out = np.zeros((len(theta), len(self.targets), len(self.calibrated)))
            for k in range(len(theta)):
                sg = grad * sd[k][None, :]  # (m, d)
                rsg = sg @ self.corr.T
                var = np.einsum("md,md->m", sg, rsg)
                std = np.sqrt(np.maximum(var, 0.0))
                # d std / d sigma_i = g_i (R s g)_i / std
                dstd = grad * rsg / np.where(std > 0, std, np.inf)[:, None]  # (m, d)
                for row, (r, stat, _) in enumerate(self.targets):
                    if stat == "std":
                        out[k, row] = dstd[r, sd_idx] / self.scale[row]
            return out

        return jac


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
            "start (thesis table 3.10). Calibrate at most as many statistics as targets, or "
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
            "sensitivity together (thesis section 3.5) or hold the weak one fixed"
        )
    return sv, cond, True, (
        f"identifiable: scaled outer Jacobian condition number {cond:.3g}"
    )


def calibrate_under_uncertainty(
    model,
    space: ParameterSpace,
    *,
    calibrate: Mapping[str, str | Sequence[str]],
    targets: Mapping[str, Mapping[str, float]],
    inner: str | Callable = "mean_value",
    inner_options: Mapping | None = None,
    fixed: Mapping[str, float] | None = None,
    bounds: Mapping | None = None,
    method: str = "nl2sol",
    identifiability_tol: float = 1e-3,
    seed: SeedLike = None,
    **outer_options,
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
    inner : "mean_value" (default), "lhs", "pce", or a callable ``inner(model, space)`` returning an
        object with ``.mean`` and ``.std`` arrays (m,) (or ``.statistics.mean/std``).
    inner_options : for "mean_value": ``gradient`` ("auto", "analytic", "fd") and ``fd_step``
        (relative central-difference step, default 1e-6); for "lhs": ``n`` (samples per outer
        point, default 200); for "pce": ``order`` (default 2), ``method`` ("quadrature",
        default, or "sparse_grid"), ``quadrature_points`` and ``basis`` of
        :func:`rotoruq.methods.pce.polynomial_chaos`.
    fixed : deterministic inputs not in the space, held at the given values.
    bounds : mapping ``"input.stat"`` (or ``(input, stat)``) -> (lower, upper) for calibrated
        statistics. Defaults: stds in ``[1e-6 std0, inf)``; means of lognormals ``> 0``.
    method : outer solver, "nl2sol" (default), "trf" or "lm".
    identifiability_tol : flag when the smallest scaled singular value is below this fraction
        of the largest.
    seed : seed of the inner LHS design (common random numbers across outer iterations).
    **outer_options : passed to :func:`least_squares` (max_iterations,
        max_function_evaluations, convergence_tolerance (Dakota default 1e-4), fd_step
        (default 1e-6 here), ...).

    Returns
    -------
    CUUResult
    """
    fixed = dict(fixed or {})
    if not isinstance(space, ParameterSpace):
        raise ParameterError(f"space must be a ParameterSpace, got {type(space).__name__}")
    view = _FixedInputs(model, fixed) if fixed else model
    unknown_fixed = [n for n in fixed if n not in tuple(model.names_in)]
    if unknown_fixed:
        raise ParameterError(
            f"fixed inputs that the model does not have: {unknown_fixed}; model inputs are "
            f"{list(model.names_in)}"
        )
    align_inputs(view, space.names)  # raises a clear error when names disagree
    calibrated = _parse_calibrate(calibrate, space, fixed)
    tgt = _parse_targets(targets, tuple(model.names_out))
    if callable(inner):
        inner_name = getattr(inner, "__name__", "callable")
    else:
        inner_name = str(inner).lower()
        if inner_name not in ("mean_value", "lhs", "pce"):
            raise ParameterError(
                f"unknown inner method {inner!r}; valid: 'mean_value', 'lhs', 'pce' or a "
                "callable"
            )
        inner = inner_name
    prob = _Problem(view, space, calibrated, tgt, inner, inner_options, seed)

    labels = tuple(f"{space.names[i]}.{s}" for i, s in calibrated)
    x0 = np.array([(space.mean if s == "mean" else space.std)[i] for i, s in calibrated])
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

    mean0, std0 = prob.statistics(x0[None, :])
    if not np.all(np.isfinite(prob.residual(x0[None, :]))):
        from ..errors import EvaluationError

        raise EvaluationError("the inner method returned NaN statistics at the starting point")
    outer_options.setdefault("fd_step", 1e-6)
    ls = least_squares(
        prob.residual, x0, jacobian=prob.analytic_jacobian(), bounds=(lo, hi), method=method,
        **outer_options,
    )
    mean1, std1 = prob.statistics(ls.x[None, :])
    mu, sd = prob.moments(ls.x[None, :])
    new_space = prob.space_at(mu[0], sd[0])
    sv, cond, ok, diag = _identifiability(ls.jacobian, ls.x, labels, len(tgt), identifiability_tol)
    names_out = tuple(model.names_out)
    before = {n: {"mean": float(mean0[0, k]), "std": float(std0[0, k])}
              for k, n in enumerate(names_out)}
    after = {n: {"mean": float(mean1[0, k]), "std": float(std1[0, k])}
             for k, n in enumerate(names_out)}
    calibrated_stats = {
        space.names[i]: {"mean": float(mu[0, i]), "std": float(sd[0, i])} for i, _ in calibrated
    }
    return CUUResult(
        labels=labels, x=ls.x, x0=x0, calibrated=calibrated_stats, space=new_space,
        initial_space=space, fixed=fixed,
        targets=_nested_dict((names_out[r], s, v) for r, s, v in tgt),
        statistics_before=before, statistics_after=after, least_squares=ls,
        singular_values=sv, condition_number=float(cond), identifiable=ok, diagnostic=diag,
        inner=inner_name, n_model_evaluations=prob.n_eval, success=ls.success,
        message=ls.message, names_out=names_out,
    )


def check_cuu(result: CUUResult, model, n: int = 300, *, seed: SeedLike = None,
              method: str = "lhs") -> CUUCheck:
    """Forward-propagate the calibrated distributions with ``n`` LHS samples (one model batch)
    and compare the sampled response statistics with the CUU targets (the thesis confirms each
    CUU with 300-500 LHS samples)."""
    from .sampling import sample

    view = _FixedInputs(model, result.fixed) if result.fixed else model
    s = sample(view, result.space, n, method=method, seed=seed)
    names_out = tuple(model.names_out)
    achieved, rel = {}, {}
    for resp, spec in result.targets.items():
        k = names_out.index(resp)
        for stat, target in spec.items():
            v = float((s.statistics.mean if stat == "mean" else s.statistics.std)[k])
            achieved.setdefault(resp, {})[stat] = v
            rel.setdefault(resp, {})[stat] = (v - target) / (abs(target) if target else 1.0)
    return CUUCheck(sampling=s, achieved=achieved, targets=result.targets, relative_error=rel)
