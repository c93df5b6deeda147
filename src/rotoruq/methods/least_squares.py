"""Nonlinear least squares (thesis eqs. 2.29-2.30) and deterministic model calibration.

:func:`least_squares` minimizes ``f(x) = 1/2 sum_i (r_i(x) / noise_std_i)^2`` with the NL2SOL
iteration of :mod:`.nl2sol` (default) or scipy's ``trf`` / ``lm``, and returns the parameter
covariance and confidence intervals. :func:`calibrate` fits model inputs to data with it.

Residual functions are *batched*: ``residual(X)`` takes an array ``(k, p)`` of points and
returns ``(k, n_res)``, so a finite-difference Jacobian evaluates all ``p`` shifted points in a
single call (forward differences, as NL2SOL, through :func:`rotoruq.model.finite_difference`).
An analytic ``gradient(X)`` takes ``(k, p)`` and returns ``(k, n_res, p)``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import ArrayLike
from scipy import optimize, stats

from .._options import legacy_keywords, legacy_mapping, with_fields
from ..errors import EvaluationError, ModelShapeError, ParameterError
from ..model import FD_STEP, GradientOption, Model, evaluate, finite_difference
from .nl2sol import CONVERGED, Convergence, NL2SOLOptions, nl2sol

if TYPE_CHECKING:
    from ..params import ParameterSpace

__all__ = ["Convergence", "LeastSquaresResult", "least_squares", "CalibrationResult",
           "calibrate", "LEGACY_KEYWORDS"]

OPTIMIZERS = ("nl2sol", "trf", "lm")


#: The flat keyword arguments of least_squares before its option record (deprecated, accepted
#: for one release): old name -> (parameter, record class name, field).
LEGACY_KEYWORDS: Mapping[str, tuple[str, str, str]] = legacy_mapping("convergence", Convergence)


def solver_options(function: str, options: Mapping[str, Any]) -> dict[str, Any]:
    """The keyword options of :func:`least_squares` that ``function`` (:func:`calibrate`,
    :func:`~rotoruq.methods.cuu.calibrate_under_uncertainty`) passes on, with the fields of
    :class:`Convergence` given flat (as a study file's step gives them) gathered into its
    ``convergence`` record: no deprecation there, these entry points take them flat."""
    options = dict(options)
    flat = {k: options.pop(k) for k in list(options) if k in LEGACY_KEYWORDS}
    if flat:
        fields = legacy_keywords(function, flat, LEGACY_KEYWORDS, warn=False)["convergence"]
        options["convergence"] = with_fields(options.get("convergence"), Convergence, fields,
                                             "convergence")
    return options


@dataclass(frozen=True, eq=False)
class LeastSquaresResult:
    """Outcome of :func:`least_squares`.

    Attributes
    ----------
    x : (p,) best point found.
    residuals : (n_res,) scaled residuals ``r(x) / noise_std`` at ``x``.
    cost : ``1/2 sum (r / noise_std)^2`` at ``x``.
    jacobian : (n_res, p) Jacobian of the scaled residuals at ``x``.
    covariance : (p, p) parameter covariance ``sigma^2 (J^T J)^-1``; ``sigma^2 = 2 cost/(n-p)``
        (residual variance) without ``noise_std``, 1 with it (the noise is then known).
        NaN when ``n_res <= p`` without ``noise_std``.
    std : (p,) square roots of the covariance diagonal.
    confidence_intervals : (p, 2) lower/upper ends at level ``confidence`` (Student t with
        ``n-p`` degrees of freedom when sigma is estimated, normal when the noise is known).
    confidence : level of the intervals (e.g. 0.95).
    iterations : trust-region iterations (trial steps) taken.
    n_evaluations : residual evaluations (points) used, Jacobian finite differences included.
    n_gradient_evaluations : analytic Jacobian evaluations (points); 0 with finite differences.
    n_calls : batched calls of ``residual`` (a finite-difference Jacobian is one call).
    converged : True when a convergence test was met.
    status : why it stopped (NL2SOL's tests): relative_function, x, relative_function_and_x,
        absolute_function, singular, gradient (converged); max_iterations,
        max_function_evaluations, false_convergence (not); scipy's status for trf/lm.
    message : human-readable reason for stopping.
    models : per iteration, "gn" (Gauss-Newton) or "augmented" (``J^T J + S``); empty for scipy.
    optimizer : "nl2sol", "trf" or "lm".
    history : (iterations+1,) cost after each iteration (the accepted one).
    """

    x: np.ndarray
    residuals: np.ndarray
    cost: float
    jacobian: np.ndarray
    covariance: np.ndarray
    std: np.ndarray
    confidence_intervals: np.ndarray
    confidence: float
    iterations: int
    n_evaluations: int
    n_gradient_evaluations: int
    n_calls: int
    converged: bool
    status: str
    message: str
    models: tuple[str, ...]
    optimizer: str
    history: np.ndarray


class _Residual:
    """Counts and checks batched residual (and Jacobian) evaluations."""

    def __init__(self, fun, jac, inv_std: np.ndarray | None, p: int):
        self.fun = fun
        self.jac = jac
        self.inv_std = inv_std
        self.p = p
        self.n_res: int | None = None
        self.n_points = 0
        self.n_jac = 0
        self.n_calls = 0

    def __call__(self, X: np.ndarray) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        k = X.shape[0]
        R = np.asarray(self.fun(X), dtype=float)
        self.n_points += k
        self.n_calls += 1
        if R.ndim == 1 and k == 1:
            R = R[None, :]
        if R.ndim != 2 or R.shape[0] != k or (self.n_res is not None and R.shape[1] != self.n_res):
            expected = f"({k}, {self.n_res if self.n_res is not None else 'n_res'})"
            raise ModelShapeError(
                f"residual function returned shape {R.shape} for {k} points of dimension "
                f"{self.p}; a batched residual must return {expected}"
            )
        if self.n_res is None:
            self.n_res = R.shape[1]
        if self.inv_std is not None:
            R = R * self.inv_std
        return R

    def one(self, x: np.ndarray) -> np.ndarray:
        """Residuals (n_res,) at one point (p,)."""
        return self(x[None, :])[0]

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        G = np.asarray(self.jac(np.asarray(x, dtype=float)[None, :]), dtype=float)
        self.n_jac += 1
        if G.ndim == 3:
            G = G[0]
        if G.shape != (self.n_res, self.p):
            raise ModelShapeError(
                f"jacobian returned shape {G.shape}; expected (1, {self.n_res}, {self.p}) "
                f"or ({self.n_res}, {self.p})"
            )
        if self.inv_std is not None:
            G = G * self.inv_std[:, None]
        return G


def _as_bounds(bounds, p: int) -> tuple[np.ndarray, np.ndarray]:
    if bounds is None:
        return np.full(p, -np.inf), np.full(p, np.inf)
    lo, hi = bounds
    lo = np.broadcast_to(np.asarray(lo, dtype=float), (p,)).copy()
    hi = np.broadcast_to(np.asarray(hi, dtype=float), (p,)).copy()
    if np.any(lo >= hi):
        raise ParameterError(f"bounds must satisfy lower < upper, got lower={lo}, upper={hi}")
    return lo, hi


def _covariance(J, cost, n_res, p, absolute, confidence, x):
    """Covariance (p, p), std (p,) and confidence intervals (p, 2) from the Jacobian."""
    JtJ = J.T @ J
    dof = n_res - p
    if absolute:
        s2 = 1.0
        q = stats.norm.ppf(0.5 + 0.5 * confidence)
    elif dof > 0:
        s2 = 2.0 * cost / dof
        q = stats.t.ppf(0.5 + 0.5 * confidence, dof)
    else:
        s2, q = np.nan, np.nan
    cov = s2 * np.linalg.pinv(JtJ)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    ci = np.column_stack([x - q * std, x + q * std])
    return cov, std, ci


def _check_solver_options(x0, optimizer: str, max_iterations: int, max_function_evaluations: int,
                          tolerance: float, confidence: float) -> np.ndarray:
    x0 = np.atleast_1d(np.asarray(x0, dtype=float)).ravel()
    if x0.size == 0 or not np.all(np.isfinite(x0)):
        raise ParameterError(f"x0 must be a non-empty finite vector, got {x0}")
    if optimizer not in OPTIMIZERS:
        raise ParameterError(f"unknown least-squares optimizer {optimizer!r}; valid: "
                             f"{', '.join(OPTIMIZERS)}")
    if max_iterations < 1 or max_function_evaluations < 1:
        raise ParameterError("max_iterations and max_function_evaluations must be >= 1")
    if not tolerance > 0:
        raise ParameterError(f"tolerance must be > 0, got {tolerance}")
    if not 0 < confidence < 1:
        raise ParameterError(f"confidence must lie in (0, 1), got {confidence}")
    return x0


def _inverse_noise(noise_std) -> np.ndarray | None:
    """``1 / noise_std`` (scalar or (n_res,)), checked; None without noise."""
    if noise_std is None:
        return None
    sd = np.asarray(noise_std, dtype=float).ravel()
    if np.any(~np.isfinite(sd)) or np.any(sd <= 0):
        raise ParameterError("noise_std must be finite and > 0 (standard deviations of the data)")
    return 1.0 / sd


def least_squares(
    residual: Callable[[np.ndarray], np.ndarray],
    x0: ArrayLike,
    *,
    gradient: GradientOption = "auto",
    bounds: tuple[ArrayLike, ArrayLike] | None = None,
    optimizer: str = "nl2sol",
    convergence: Convergence | None = None,
    noise_std: ArrayLike | None = None,
    fd_step: float = FD_STEP,
    initial_radius: float | None = 1.0,
    confidence: float = 0.95,
    **legacy: Any,
) -> LeastSquaresResult:
    """Minimize ``1/2 sum_i (r_i(x) / noise_std_i)^2``.

    Parameters
    ----------
    residual : callable
        Batched: ``residual(X)`` with ``X`` of shape ``(k, p)`` returns ``(k, n_res)``. A point
        whose residuals are not finite counts as a failed evaluation: the step to it is
        rejected and the trust region shrinks.
    x0 : array_like (p,)
        Starting point (projected into the bounds).
    gradient : "auto" / "finite_difference" or callable
        "auto" and "finite_difference": forward differences with relative step ``fd_step``
        (default :data:`rotoruq.model.FD_STEP`; all ``p`` points in one call of ``residual``,
        backward next to an upper bound). A callable takes ``(k, p)`` and returns
        ``(k, n_res, p)``.
    bounds : (lower, upper), optional
        Scalars or arrays (p,); use ``+-inf`` for no bound. ``optimizer="lm"`` takes no bounds.
    optimizer : "nl2sol" (default, :mod:`.nl2sol`), "trf" or "lm" (scipy).
    convergence : :class:`Convergence`, optional
        The iteration limits and convergence tolerances (default: Dakota's, ``max_iterations``
        100, ``max_function_evaluations`` 1000, ``tolerance`` 1e-4, ...). Evaluations count
        points, Jacobian differences included.
    noise_std : scalar or array_like (n_res,), optional
        Standard deviations of the data behind each residual (residual units). With them the
        covariance is ``(J^T W J)^-1``, ``W = diag(1 / noise_std^2)`` (noise known); without,
        ``s^2 (J^T J)^-1`` with the residual variance ``s^2 = sum r^2 / (n_res - p)``.
    fd_step : float, optional
        Relative finite-difference step of the Jacobian (default
        :data:`rotoruq.model.FD_STEP`): input i moves by ``fd_step * max(|x_i|, s_i)``,
        ``s_i`` the size of ``x0_i`` (1 where it is 0).
    initial_radius : scaled trust radius ``||D s||`` of the first step (NL2SOL's lmax0,
        default 1; None: ``100 ||D x0||``, or 100 when ``x0 = 0``, as MINPACK).
    confidence : level of the returned confidence intervals.
    **legacy : the flat keyword arguments of rotoruq 0.1 (``max_iterations=``,
        ``tolerance=``, ``x_tolerance=``, ...; :data:`LEGACY_KEYWORDS`), the fields of
        :class:`Convergence`: accepted for one release with a ``DeprecationWarning`` (a flat
        keyword overrides that field of ``convergence``).

    Returns
    -------
    LeastSquaresResult

    Raises
    ------
    EvaluationError when the residual is not finite at ``x0``.
    ParameterError for bad options.
    TypeError for an unknown keyword argument.

    Examples
    --------
    A straight line y = p0 + p1 t through 5 exact points (p0 = 1, p1 = 2); the residual takes
    ``k`` trial points (k, 2) at once and returns (k, 5):

    >>> import numpy as np
    >>> t = np.linspace(0.0, 1.0, 5)
    >>> res = least_squares(lambda p: p[:, :1] + p[:, 1:] * t - (1.0 + 2.0 * t), [0.0, 0.0])
    >>> res.converged, np.round(res.x, 8).tolist()
    (True, [1.0, 2.0])

    Tighter tolerances:

    >>> fit = least_squares(lambda p: p[:, :1] + p[:, 1:] * t - (1.0 + 2.0 * t), [0.0, 0.0],
    ...                     convergence=Convergence(tolerance=1e-12, x_tolerance=1e-12))
    >>> fit.status in ("relative_function", "x", "relative_function_and_x",
    ...                "absolute_function")
    True
    """
    flat = legacy_keywords("least_squares", legacy, LEGACY_KEYWORDS)
    conv = with_fields(convergence, Convergence, flat.get("convergence"), "convergence")
    max_iterations, max_function_evaluations = conv.max_iterations, conv.max_function_evaluations
    tolerance, x_tolerance = conv.tolerance, conv.x_tolerance
    false_convergence_tolerance = conv.false_convergence_tolerance
    optimizer = optimizer.lower()
    start = _check_solver_options(x0, optimizer, max_iterations, max_function_evaluations,
                                  tolerance, confidence)
    p = start.size
    lower, upper = _as_bounds(bounds, p)
    start = np.clip(start, lower, upper)
    inv_std = _inverse_noise(noise_std)
    if not callable(gradient) and gradient not in ("auto", "finite_difference"):
        raise ParameterError(f"gradient must be 'auto', 'finite_difference' or a callable "
                             f"(k, p) -> (k, n_res, p), got {gradient!r}")
    analytic = callable(gradient)
    res = _Residual(residual, gradient if analytic else None, inv_std, p)
    r0 = res.one(start)
    if inv_std is not None and inv_std.size not in (1, r0.size):
        raise ParameterError(f"noise_std has {inv_std.size} entries for {r0.size} residuals")
    if not np.all(np.isfinite(r0)):
        raise EvaluationError(f"residuals are not finite at the starting point x0 = {start}")
    typical = np.where(start != 0, np.abs(start), 1.0)

    def jac_at(x: np.ndarray, r: np.ndarray) -> np.ndarray:
        if analytic:
            return res.jacobian(x)
        return finite_difference(res, x, fd_step=fd_step, scale=typical, central=False,
                                 upper=upper, values=r[None, :]).gradient[0]

    known_noise = inv_std is not None
    if optimizer in ("trf", "lm"):
        return _scipy(res, jac_at, start, r0, lower, upper, optimizer, max_function_evaluations,
                      tolerance, x_tolerance, bounds is not None, known_noise, confidence)
    options = NL2SOLOptions(max_iterations=max_iterations,
                            max_function_evaluations=max_function_evaluations,
                            tolerance=tolerance, x_tolerance=x_tolerance,
                            absolute_tolerance=conv.absolute_tolerance,
                            singular_tolerance=conv.singular_tolerance,
                            singular_radius=conv.singular_radius,
                            false_convergence_tolerance=false_convergence_tolerance,
                            initial_radius=initial_radius)
    out = nl2sol(res.one, jac_at, start, r0, lower, upper, options, lambda: res.n_points,
                 0 if analytic else p)
    stops = {
        "max_iterations": f"maximum number of iterations ({max_iterations}) reached",
        "max_function_evaluations": (
            f"maximum number of function evaluations ({max_function_evaluations}) reached"
        ),
        "false_convergence": (
            f"false convergence: a step of relative size below {false_convergence_tolerance:g} "
            f"failed to reduce f without any convergence test being met (noisy or non-smooth "
            f"residuals, failed evaluations, or a wrong Jacobian)"
        ),
    }
    cov, std, ci = _covariance(out.J, out.cost, out.r.size, p, known_noise, confidence, out.x)
    return LeastSquaresResult(
        x=out.x, residuals=out.r, cost=out.cost, jacobian=out.J, covariance=cov, std=std,
        confidence_intervals=ci, confidence=confidence, iterations=out.iterations,
        n_evaluations=res.n_points, n_gradient_evaluations=res.n_jac, n_calls=res.n_calls,
        converged=out.status in CONVERGED, status=out.status,
        message=CONVERGED.get(out.status) or stops[out.status], models=out.models,
        optimizer="nl2sol", history=out.history,
    )


def _scipy(res, jac_at, x0, r0, lower, upper, method, max_fev, ftol, xtol, bounded,
           absolute, confidence) -> LeastSquaresResult:
    if method == "lm" and bounded and (np.any(np.isfinite(lower)) or np.any(np.isfinite(upper))):
        raise ParameterError("optimizer 'lm' does not take bounds; use 'nl2sol' or 'trf'")
    cache = {x0.tobytes(): r0}

    def fun(x):
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = res(x[None, :])[0]
        out = cache[key]
        return np.where(np.isfinite(out), out, 1e150)

    def jac(x):
        r = fun(x)
        return jac_at(np.asarray(x, dtype=float), r)

    kw = dict(jac=jac, method=method, ftol=ftol, xtol=xtol, max_nfev=max_fev, x_scale="jac")
    if method == "trf":
        kw["bounds"] = (lower, upper)
    sol = optimize.least_squares(fun, x0, **kw)
    x = sol.x
    r = sol.fun
    f = 0.5 * float(r @ r)
    J = np.asarray(sol.jac)
    cov, std, ci = _covariance(J, f, r.size, x.size, absolute, confidence, x)
    return LeastSquaresResult(
        x=x, residuals=r, cost=f, jacobian=J, covariance=cov, std=std, confidence_intervals=ci,
        confidence=confidence, iterations=int(sol.nfev), n_evaluations=res.n_points,
        n_gradient_evaluations=res.n_jac, n_calls=res.n_calls, converged=bool(sol.status > 0),
        status=f"scipy_{sol.status}", message=str(sol.message), models=(), optimizer=method,
        history=np.array([0.5 * float(r0 @ r0), f]),
    )


# --- deterministic calibration of a Model ------------------------------------------------------


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """Outcome of :func:`calibrate`.

    Attributes
    ----------
    names_in : calibrated input names, in the order of ``x``.
    x : (p,) best parameter values.
    parameters : mapping name -> best value.
    residuals : (n_exp, m) model minus data at ``x`` (unscaled, in the units of the data);
        without data, the model's responses (the residuals themselves), n_exp = 1.
    cost : ``1/2 sum w (r / noise_std)^2`` at ``x`` (``noise_std`` and the weights ``w`` 1
        when not given).
    covariance, std, confidence_intervals : from the Jacobian at ``x`` (see
        :class:`LeastSquaresResult`).
    iterations : outer iterations.
    n_evaluations : model evaluations (points) used, Jacobian differences included.
    n_gradient_evaluations : analytic Jacobians the solver used (points); 0 with finite
        differences. With a model whose evaluations return their gradient too
        (``evaluate_gradient``: an external driver's own gradients) every evaluation asks for
        both, as Dakota's NL2SOL does, and these Jacobians cost no run of their own.
    converged, message : from the solver.
    optimizer : the solver used (``"nl2sol"``, ``"trf"`` or ``"lm"``).
    least_squares : the full :class:`LeastSquaresResult`.
    residual_model : True when there were no data: the responses were the residuals.
    """

    names_in: tuple[str, ...]
    x: np.ndarray
    parameters: dict[str, float]
    residuals: np.ndarray
    cost: float
    covariance: np.ndarray
    std: np.ndarray
    confidence_intervals: np.ndarray
    iterations: int
    n_evaluations: int
    converged: bool
    message: str
    optimizer: str
    least_squares: LeastSquaresResult
    n_gradient_evaluations: int = 0
    residual_model: bool = False


def _observations(data, names_out: tuple[str, ...]) -> np.ndarray:
    """Data as (n_exp, m), checked against the model's responses."""
    m = len(names_out)
    data = np.asarray(data, dtype=float)
    if data.ndim == 1:
        data = data[None, :]
    if data.ndim != 2 or data.shape[1] != m:
        raise ParameterError(
            f"data must have shape (n_exp, {m}) with columns {names_out}, got {data.shape}"
        )
    if not np.all(np.isfinite(data)):
        raise ParameterError("data contain NaN or infinite values")
    if data.shape[0] == 0:
        raise ParameterError(
            f"calibrate needs data: got no observations (shape {data.shape}); give at least "
            f"one row of the {m} responses {names_out}"
        )
    return data


def _calibrated(parameters, x0, bounds) -> tuple[tuple[str, ...], np.ndarray, Any]:
    """Names, start point (p,) and bounds of the calibrated inputs."""
    from ..params import ParameterSpace

    if isinstance(parameters, ParameterSpace):
        names = parameters.names
        start = parameters.mean if x0 is None else x0
        if bounds is None:
            b = parameters.bounds
            bounds = (b[:, 0], b[:, 1])
    else:
        names = tuple(parameters)
        start = x0
    p = len(names)
    if p == 0 or len(set(names)) != p:
        raise ParameterError(f"parameters must be distinct input names, got {names}")
    if start is None:
        raise ParameterError("x0 is required when parameters is a list of names")
    start = np.asarray(start, dtype=float).ravel()
    if start.size != p:
        raise ParameterError(f"x0 has {start.size} values for {p} parameters {names}")
    if isinstance(bounds, Mapping):
        lo = np.array([bounds.get(n, (-np.inf, np.inf))[0] for n in names], dtype=float)
        hi = np.array([bounds.get(n, (-np.inf, np.inf))[1] for n in names], dtype=float)
        bounds = (lo, hi)
    return names, start, bounds


def _experiment_inputs(model, names: tuple[str, ...], fixed: Mapping, n_exp: int):
    """``inputs(X: (k, p)) -> (k * n_exp, d)`` model points: each candidate with the fixed
    inputs of every experiment, columns in ``model.names_in`` order."""
    from ..model import align_inputs

    all_names = names + tuple(fixed)
    overlap = set(names) & set(fixed)
    if overlap:
        raise ParameterError(f"inputs both calibrated and fixed: {sorted(overlap)}")
    unknown = [n for n in all_names if n not in tuple(model.names_in)]
    if unknown:
        raise ParameterError(
            f"not inputs of the model: {unknown}; model inputs are {list(model.names_in)}"
        )
    no_value = [n for n in model.names_in if n not in all_names]
    if no_value:
        raise ParameterError(
            f"model inputs with no value: {no_value}; calibrate them or give them in fixed"
        )
    perm = align_inputs(model, all_names)
    block = np.empty((n_exp, len(fixed)))
    for j, (name, value) in enumerate(fixed.items()):
        v = np.asarray(value, dtype=float)
        if v.ndim == 0 or v.size == 1:
            block[:, j] = float(v.ravel()[0])
        elif v.shape == (n_exp,):
            block[:, j] = v
        else:
            raise ParameterError(
                f"fixed input {name!r}: give a scalar or one value per experiment ({n_exp}), "
                f"got shape {v.shape}"
            )

    def inputs(X: np.ndarray) -> np.ndarray:
        full = np.concatenate([np.repeat(X, n_exp, axis=0), np.tile(block, (X.shape[0], 1))],
                              axis=1)
        return full if perm is None else full[:, perm]

    return inputs


def _noise_per_observation(noise_std, shape: tuple[int, int]) -> np.ndarray | None:
    """``noise_std`` (scalar, (m,) or (n_exp, m)) as one value per observation, raveled."""
    if noise_std is None:
        return None
    sd = np.asarray(noise_std, dtype=float)
    try:
        sd = np.broadcast_to(sd, shape)
    except ValueError:
        raise ParameterError(
            f"noise_std must be a scalar, ({shape[1]},) or {shape}, got {sd.shape}"
        ) from None
    if np.any(~np.isfinite(sd)) or np.any(sd <= 0):
        raise ParameterError("noise_std must be finite and > 0")
    return sd.ravel()


def calibrate(
    model: Model,
    data: ArrayLike | None,
    parameters: Sequence[str] | ParameterSpace,
    *,
    x0: ArrayLike | None = None,
    bounds: tuple[ArrayLike, ArrayLike] | Mapping[str, tuple[float, float]] | None = None,
    noise_std: ArrayLike | None = None,
    residual_weights: ArrayLike | None = None,
    fixed: Mapping[str, float | Sequence[float]] | None = None,
    optimizer: str = "nl2sol",
    gradient: GradientOption = "auto",
    **options: Any,
) -> CalibrationResult:
    """Fit model inputs to data by least squares on the residuals ``model - data``.

    Parameters
    ----------
    model : Model
        Any object of the rotoruq Model protocol (``names_in``, ``names_out``, batched call).
    data : array_like (n_exp, m) or (m,), or None
        Observations of all ``m`` responses (columns in ``model.names_out`` order), one row per
        experiment (replicates, or different conditions given through ``fixed``). None: the
        model's responses ARE the residuals (Dakota's ``calibration_terms`` without a
        calibration data file), driven toward zero: ``1/2 sum_i r_i^2`` is minimized.
    parameters : list of input names, or ParameterSpace
        The calibrated inputs. A ParameterSpace supplies starting values (its means) and bounds
        (its supports) unless ``x0``/``bounds`` are given.
    x0 : array_like (p,), optional
        Starting values (required when ``parameters`` is a list of names).
    bounds : (lower, upper) arrays (p,), or mapping name -> (lower, upper), optional.
    noise_std : float, (m,) or (n_exp, m), optional
        Standard deviations of the observations (data units); residuals are divided by them
        and the parameter covariance takes the noise as known.
    residual_weights : float, (m,) or (n_exp, m), optional
        Dakota's calibration-term ``weights``: ``w_i`` multiplies the squared residual, so
        residual and gradient are scaled by ``sqrt(w_i)`` (as Dakota's weighting of primary
        responses). Weights >= 0; unlike ``noise_std`` they leave the residual variance
        estimated.
    fixed : mapping name -> value or (n_exp,) values, optional
        The other model inputs, held fixed; an array gives one value per experiment.
    optimizer : "nl2sol" (default), "trf" or "lm".
    gradient : "auto" (the model's analytic gradient when it has one, else finite
        differences, all columns of a Jacobian in one model batch), "analytic",
        "finite_difference", or a callable ``g(x: (n, d)) -> (n, m, d)`` in
        ``model.names_in`` order.
    **options : passed to :func:`least_squares`: ``convergence`` (a :class:`Convergence`),
        ``fd_step``, ``initial_radius``, ``confidence``; the fields of :class:`Convergence`
        may be given flat here (``max_iterations=``, ``tolerance=``, ..., as a study file's
        step gives them), gathered into its ``convergence``.

    Returns
    -------
    CalibrationResult

    Examples
    --------
    The gain ``k`` of y = k u from 3 experiments at u = 1, 2, 3 (``fixed`` gives one u per row of
    ``data``), measured exactly with k = 2.5:

    >>> import numpy as np
    >>> import rotoruq as rq
    >>> model = rq.FunctionModel(lambda x: x[:, :1] * x[:, 1:], ["k", "u"], ["y"])
    >>> fit = rq.calibrate(model, [[2.5], [5.0], [7.5]], ["k"], x0=[1.0],
    ...                    fixed={"u": [1.0, 2.0, 3.0]})
    >>> round(float(fit.x[0]), 8)
    2.5
    """
    from ..model import check_gradient_option

    names_out = tuple(model.names_out)
    residual_model = data is None
    data = (np.zeros((1, len(names_out))) if residual_model
            else _observations(data, names_out))
    n_exp, m = data.shape
    names, start, box = _calibrated(parameters, x0, bounds)
    p = len(names)
    if residual_model and m < p:
        raise ParameterError(
            f"{p} parameters {names} cannot be calibrated on the model's {m} responses "
            f"{names_out} taken as residuals: the least-squares problem is underdetermined"
        )
    if n_exp * m < p:
        raise ParameterError(
            f"{p} parameters {names} cannot be calibrated on {n_exp * m} observations: "
            "the least-squares problem is underdetermined; add data or fix parameters"
        )
    inputs = _experiment_inputs(model, names, dict(fixed or {}), n_exp)
    noise = _noise_per_observation(noise_std, data.shape)
    weights = residual_weights
    if weights is not None:
        w = np.asarray(weights, dtype=float)
        if w.size and (np.any(~np.isfinite(w)) or np.any(w < 0)):
            raise ParameterError(f"residual_weights must be finite and >= 0, got "
                                 f"{w.ravel().tolist()}")
        try:
            sw = np.sqrt(np.broadcast_to(w, data.shape)).ravel()
        except ValueError:
            raise ParameterError(f"residual_weights must be a scalar, ({m},) or {data.shape}, got "
                                 f"{w.shape}") from None
        # w r^2 = (r / (1/sqrt(w)))^2; noise_std's known-noise covariance is not implied
        scale = sw if noise is None else sw / noise
    else:
        scale = None if noise is None else 1.0 / noise

    mode = check_gradient_option(gradient, model)
    # a model whose one evaluation gives values and gradient (an external driver's own
    # gradients): every residual evaluation asks for both, as Dakota's NL2SOL does with
    # analytic gradients (speculative gradients), and the Jacobian at an accepted point is
    # the one already returned: no second run of the model there
    joint = (getattr(model, "evaluate_gradient", None)
             if mode != "finite_difference" and not callable(mode) else None)
    seen: dict[bytes, tuple[np.ndarray, np.ndarray | None]] = {}  # point -> (R, G) unscaled
    failure: list[str] = []  # the last reason a residual evaluation failed

    def raw_residual(X: np.ndarray) -> np.ndarray:
        P = inputs(X)
        if callable(joint):
            got = joint(P)
            values, G = np.asarray(got.values, dtype=float), np.asarray(got.gradient, float)
            reasons = got.failures
        else:
            batch = evaluate(model, P)
            values, G, reasons = batch.values, None, batch.failures
        if reasons:
            failure[:] = [next(iter(reasons.values()))]
        R = values.reshape(X.shape[0], n_exp * m) - data.ravel()[None, :]
        for k in range(X.shape[0]):
            g = None if G is None else G[k * n_exp:(k + 1) * n_exp]
            seen[X[k].tobytes()] = (R[k], g)
        return R

    def residual(X: np.ndarray) -> np.ndarray:
        R = raw_residual(X)
        return R if weights is None or scale is None else R * scale

    jac: Callable[[np.ndarray], np.ndarray] | str = "finite_difference"
    if mode != "finite_difference":
        model_grad = mode if callable(mode) else cast(Any, model).gradient
        cols = [list(model.names_in).index(n) for n in names]

        def jac(X: np.ndarray) -> np.ndarray:
            known = [seen.get(x.tobytes(), (None, None))[1] for x in X]
            if all(g is not None for g in known):
                G = np.concatenate(cast(list, known))
            elif callable(joint):
                got = joint(inputs(X))
                if got.failures:
                    i, why = next(iter(got.failures.items()))
                    raise EvaluationError(f"the model's gradient failed at {names} = "
                                          f"{X[i // n_exp].tolist()}: {why}")
                G = np.asarray(got.gradient, dtype=float)
            else:
                G = np.asarray(model_grad(inputs(X)), dtype=float)  # (k*n_exp, m, d)
            if not np.all(np.isfinite(G)):
                raise EvaluationError(f"the model's gradient is not finite at {names} = "
                                      f"{X.tolist()}")
            J = G.reshape(G.shape[0], m, -1)[:, :, cols].reshape(X.shape[0], n_exp * m, p)
            return J if weights is None or scale is None else J * scale[None, :, None]

    try:
        ls = least_squares(residual, start, gradient=jac, bounds=box, optimizer=optimizer,
                           noise_std=noise if weights is None else None,
                           **solver_options("calibrate", options))
    except EvaluationError as exc:
        if failure and failure[0] not in str(exc):  # say why the model failed
            raise EvaluationError(f"{exc}: {failure[0]}") from exc
        raise
    if weights is not None and noise is not None:  # the noise is known: covariance (J^T J)^-1
        cov, std, ci = _covariance(ls.jacobian, ls.cost, ls.residuals.size, p, True,
                                   ls.confidence, ls.x)
        ls = replace(ls, covariance=cov, std=std, confidence_intervals=ci)
    at = seen.get(ls.x.tobytes())  # the optimum was evaluated: not run again
    r = (raw_residual(ls.x[None, :])[0] if at is None else at[0]).reshape(n_exp, m)
    return CalibrationResult(
        names_in=names, x=ls.x,
        parameters={n: float(v) for n, v in zip(names, ls.x, strict=True)},
        residuals=r, cost=ls.cost, covariance=ls.covariance, std=ls.std,
        confidence_intervals=ls.confidence_intervals, iterations=ls.iterations,
        n_evaluations=ls.n_evaluations * n_exp, converged=ls.converged, message=ls.message,
        optimizer=ls.optimizer, least_squares=ls,
        n_gradient_evaluations=ls.n_gradient_evaluations * n_exp,
        residual_model=residual_model,
    )
