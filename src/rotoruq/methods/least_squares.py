"""Nonlinear least squares: an NL2SOL-style adaptive solver and deterministic model calibration.

The problem is ``min_x f(x) = 1/2 sum_i w_i r_i(x)^2`` (thesis eqs. 2.29-2.30). The solver,
:func:`least_squares`, follows Dennis, Gay and Welsch (1981, "An adaptive nonlinear
least-squares algorithm", ACM TOMS 7(3), the algorithm behind Dakota's ``nl2sol``):

* a trust region in the scaled norm ``||D s||`` with ``D_i = max(D_i, ||J e_i||)`` (adaptive
  column scaling), steps from the exact (eigen-decomposition) solution of the trust-region
  subproblem, i.e. Levenberg-Marquardt steps with the Moré-Hebden choice of the multiplier;
* two quadratic models of ``f`` (eqs. 2.35 and 2.36): Gauss-Newton, with Hessian ``J^T J``,
  and the augmented model ``J^T J + S`` where ``S`` is a secant approximation of the residual
  curvature term ``Q = sum_i r_i nabla^2 r_i`` (eq. 2.33);
* ``S`` updated after every accepted step by the structured symmetric rank-two update
  ``S+ = S + (z y^T + y z^T)/(y^T s) - (z^T s) y y^T/(y^T s)^2`` with ``y = g+ - g``,
  ``y# = (J+ - J)^T r+``, ``z = y# - S s``, after the size scaling
  ``S <- min(1, |s^T y#| / |s^T S s|) S`` that keeps ``S`` from growing when the residuals
  shrink;
* adaptive model switching: when a trial step is poor and the other model would have
  predicted the actual reduction better, the step is recomputed with the other model at the
  same radius (no evaluation wasted on shrinking); after a good step the model that predicted
  better is used next;
* convergence tests after NL2SOL: relative function convergence (the reduction predicted for
  a full Newton step is at most ``convergence_tolerance * f``), x-convergence (relative step
  below ``x_tolerance``), absolute function convergence (``f <= absolute_tolerance``), and
  false convergence (the radius collapsed without any of the above).

Bounds are handled by an active-set projection: variables on a bound whose gradient pushes
outward are held fixed for the step, the step is solved in the free subspace, and the trial
point is projected back into the box (the predicted reduction is that of the projected step).

Residual functions are *batched*: ``residual(X)`` takes an array ``(k, p)`` of points and
returns ``(k, n_res)``, so a finite-difference Jacobian evaluates all ``p`` shifted points in a
single call. An analytic ``jacobian(X)`` takes ``(k, p)`` and returns ``(k, n_res, p)``.

scipy's ``trf`` and ``lm`` solvers are available through the same function and result type.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

from ..errors import EvaluationError, ModelShapeError, ParameterError
from ..model import evaluate
from ._common import forward_jacobian

__all__ = ["LeastSquaresResult", "least_squares", "CalibrationResult", "calibrate"]

_EPS = np.finfo(float).eps

_CONVERGED = {
    "relative_function": "relative function convergence",
    "absolute_function": "absolute function convergence",
    "x": "x-convergence",
    "gradient": "projected gradient is zero",
}


@dataclass(frozen=True)
class LeastSquaresResult:
    """Outcome of :func:`least_squares`.

    Attributes
    ----------
    x : (p,) best point found.
    residuals : (n_res,) weighted residuals ``sqrt(w) * r(x)`` at ``x``.
    cost : ``1/2 sum w r^2`` at ``x``.
    jacobian : (n_res, p) Jacobian of the weighted residuals at ``x``.
    covariance : (p, p) parameter covariance ``sigma^2 (J^T J)^-1``; ``sigma^2 = 2 cost/(n-p)``
        (residual variance) without weights, 1 with weights (they are inverse data variances).
        NaN when ``n_res <= p`` without weights.
    std : (p,) square roots of the covariance diagonal.
    confidence_intervals : (p, 2) lower/upper ends at level ``confidence`` (Student t with
        ``n-p`` degrees of freedom when sigma is estimated, normal when it comes from weights).
    confidence : level of the intervals (e.g. 0.95).
    iterations : trust-region iterations (trial steps) taken.
    n_evaluations : residual evaluations (points) used, Jacobian finite differences included.
    n_jacobian_evaluations : analytic Jacobian evaluations (points); 0 with finite differences.
    n_calls : batched calls of ``residual`` (a finite-difference Jacobian is one call).
    success : True when a convergence test was met.
    status : short code: relative_function, absolute_function, x, gradient, max_iterations,
        max_function_evaluations, false_convergence (or scipy's status for trf/lm).
    message : human-readable reason for stopping.
    models : per iteration, "gn" (Gauss-Newton) or "augmented" (``J^T J + S``); empty for scipy.
    method : "nl2sol", "trf" or "lm".
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
    n_jacobian_evaluations: int
    n_calls: int
    success: bool
    status: str
    message: str
    models: tuple[str, ...]
    method: str
    history: np.ndarray


class _Residual:
    """Counts and checks batched residual (and Jacobian) evaluations."""

    def __init__(self, fun, jac, sqrt_w: np.ndarray | None, p: int):
        self.fun = fun
        self.jac = jac
        self.sqrt_w = sqrt_w
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
        if self.sqrt_w is not None:
            R = R * self.sqrt_w
        return R

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
        if self.sqrt_w is not None:
            G = G * self.sqrt_w[:, None]
        return G


def _fd_jacobian(
    res: _Residual,
    x: np.ndarray,
    r: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    rel_step: float,
    typical: np.ndarray,
) -> np.ndarray:
    """Forward differences, all ``p`` columns in one batched call; backward next to a bound."""
    return forward_jacobian(res, x, r, rel_step=rel_step, scale=typical, upper=upper)


def _tr_step(
    g: np.ndarray, H: np.ndarray, d: np.ndarray, radius: float
) -> tuple[np.ndarray, bool]:
    """Solve ``min g.s + 1/2 s.H.s`` subject to ``||d * s|| <= radius`` exactly.

    Returns the step and whether it is the interior (unconstrained Newton) step.
    """
    gz = g / d
    Hz = H / np.outer(d, d)
    Hz = 0.5 * (Hz + Hz.T)
    lam, V = np.linalg.eigh(Hz)
    a = V.T @ gz
    lmax = max(abs(lam[-1]), _EPS)
    lmin = lam[0]
    tiny = 1e-13 * lmax

    def znorm(mu: float) -> float:
        return float(np.linalg.norm(a / (lam + mu)))

    if lmin > tiny:
        z = -V @ (a / lam)
        if np.linalg.norm(z) <= radius:
            return z / d, True
    lo = max(0.0, -lmin) + tiny
    if znorm(lo) <= radius:
        # hard case (or singular Gauss-Newton with g in the range): go along the eigenvector
        # of the smallest eigenvalue to the boundary when curvature is negative.
        z = -V @ (a / (lam + lo))
        if lmin < -tiny:
            v = V[:, 0]
            zz = float(z @ z)
            zv = float(z @ v)
            tau = -zv + np.sqrt(zv * zv + max(radius**2 - zz, 0.0))
            z = z + tau * v
        return z / d, False
    hi = lo + np.linalg.norm(a) / radius + lmax
    while znorm(hi) > radius:
        hi *= 2.0
    mu = optimize.brentq(lambda m: znorm(m) - radius, lo, hi, xtol=1e-14 * hi, rtol=1e-12)
    z = -V @ (a / (lam + mu))
    return z / d, False


def _newton_reduction(g: np.ndarray, H: np.ndarray) -> float:
    """``1/2 g^T H^-1 g`` when H is positive definite, else +inf."""
    try:
        c = np.linalg.cholesky(H)
    except np.linalg.LinAlgError:
        return np.inf
    w = np.linalg.solve(c, g)
    return 0.5 * float(w @ w)


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


def least_squares(
    residual: Callable[[np.ndarray], np.ndarray],
    x0,
    *,
    jacobian: Callable[[np.ndarray], np.ndarray] | str | None = None,
    bounds=None,
    method: str = "nl2sol",
    max_iterations: int = 100,
    max_function_evaluations: int = 1000,
    convergence_tolerance: float = 1e-4,
    x_tolerance: float = 1.5e-8,
    absolute_tolerance: float = 1e-20,
    weights=None,
    fd_step: float = 1.5e-8,
    initial_radius: float | None = None,
    confidence: float = 0.95,
) -> LeastSquaresResult:
    """Minimize ``1/2 sum_i w_i r_i(x)^2``.

    Parameters
    ----------
    residual : callable
        Batched: ``residual(X)`` with ``X`` of shape ``(k, p)`` returns ``(k, n_res)``. A point
        whose residuals are not finite counts as a failed evaluation: the step to it is
        rejected and the trust region shrinks.
    x0 : array_like (p,)
        Starting point (projected into the bounds).
    jacobian : None, "fd" or callable
        ``None``/``"fd"``: forward differences with relative step ``fd_step`` (all ``p`` points
        in one call of ``residual``). A callable takes ``(k, p)`` and returns
        ``(k, n_res, p)``.
    bounds : (lower, upper), optional
        Scalars or arrays (p,); use ``+-inf`` for no bound. ``method="lm"`` takes no bounds.
    method : "nl2sol" (default, this module's adaptive solver), "trf" or "lm" (scipy).
    max_iterations, max_function_evaluations, convergence_tolerance :
        Dakota's defaults 100, 1000 and 1e-4. ``convergence_tolerance`` is NL2SOL's relative
        function tolerance (stop when at most that fraction of ``f`` can still be gained);
        for scipy it is passed as ``ftol``. Evaluations count points, Jacobian differences
        included.
    x_tolerance : relative step size for x-convergence (NL2SOL's xctol).
    absolute_tolerance : stop when ``f`` falls below it (NL2SOL's afctol).
    weights : array_like (n_res,), optional
        Inverse variances ``1/sigma_i^2`` of the data behind each residual. With weights the
        covariance is ``(J^T W J)^-1`` (variances known); without, ``s^2 (J^T J)^-1`` with the
        residual variance ``s^2 = sum r^2 / (n_res - p)``.
    initial_radius : scaled trust radius of the first step (default ``100 ||D x0||``, or 100
        when ``x0 = 0``, as MINPACK).
    confidence : level of the returned confidence intervals.

    Returns
    -------
    LeastSquaresResult

    Raises
    ------
    EvaluationError when the residual is not finite at ``x0``.
    ParameterError for bad options.
    """
    x0 = np.atleast_1d(np.asarray(x0, dtype=float)).ravel()
    p = x0.size
    if p == 0 or not np.all(np.isfinite(x0)):
        raise ParameterError(f"x0 must be a non-empty finite vector, got {x0}")
    method = method.lower()
    if method not in ("nl2sol", "trf", "lm"):
        raise ParameterError(f"unknown least-squares method {method!r}; valid: nl2sol, trf, lm")
    if max_iterations < 1 or max_function_evaluations < 1:
        raise ParameterError("max_iterations and max_function_evaluations must be >= 1")
    if not convergence_tolerance > 0:
        raise ParameterError(f"convergence_tolerance must be > 0, got {convergence_tolerance}")
    if not 0 < confidence < 1:
        raise ParameterError(f"confidence must lie in (0, 1), got {confidence}")
    lower, upper = _as_bounds(bounds, p)
    x0 = np.clip(x0, lower, upper)
    sqrt_w = None
    if weights is not None:
        w = np.asarray(weights, dtype=float).ravel()
        if np.any(~np.isfinite(w)) or np.any(w < 0):
            raise ParameterError("weights must be finite and >= 0 (inverse data variances)")
        sqrt_w = np.sqrt(w)
    if jacobian is not None and not callable(jacobian) and jacobian != "fd":
        raise ParameterError(f"jacobian must be None, 'fd' or a callable, got {jacobian!r}")
    analytic = callable(jacobian)
    res = _Residual(residual, jacobian if analytic else None, sqrt_w, p)
    r0 = res(x0[None, :])[0]
    if sqrt_w is not None and sqrt_w.size != r0.size:
        raise ParameterError(f"weights have {sqrt_w.size} entries for {r0.size} residuals")
    if not np.all(np.isfinite(r0)):
        raise EvaluationError(f"residuals are not finite at the starting point x0 = {x0}")
    typical = np.where(x0 != 0, np.abs(x0), 1.0)

    def jac_at(x, r):
        if analytic:
            return res.jacobian(x)
        return _fd_jacobian(res, x, r, lower, upper, fd_step, typical)

    if method in ("trf", "lm"):
        return _scipy(res, jac_at, x0, r0, lower, upper, method, max_function_evaluations,
                      convergence_tolerance, x_tolerance, bounds is not None, sqrt_w is not None,
                      confidence)

    x, r = x0, r0
    f = 0.5 * float(r @ r)
    J = jac_at(x, r)
    if not np.all(np.isfinite(J)):
        raise EvaluationError(f"the Jacobian is not finite at the starting point x0 = {x0}")
    g = J.T @ r
    S = np.zeros((p, p))
    d = np.maximum(np.linalg.norm(J, axis=0), 1e-8 * max(np.linalg.norm(J), 1.0))
    xs = np.linalg.norm(d * x)
    radius = float(initial_radius) if initial_radius else (100.0 * xs if xs > 0 else 100.0)
    model = "gn"
    models: list[str] = []
    history = [f]
    it = 0
    status = ""
    switched = False  # model switched during the current (not yet accepted) iteration

    while True:
        if f <= absolute_tolerance:
            status = "absolute_function"
            break
        free = ~(((x <= lower) & (g > 0)) | ((x >= upper) & (g < 0)))
        if not np.any(free) or np.linalg.norm(g[free]) == 0.0:
            status = "gradient"
            break
        H_gn = J.T @ J
        H = H_gn + S if model == "augmented" else H_gn
        Hf = H[np.ix_(free, free)]
        nreduc = _newton_reduction(g[free], Hf)
        if not np.isfinite(nreduc) and model == "augmented":
            nreduc = _newton_reduction(g[free], H_gn[np.ix_(free, free)])
        if nreduc <= convergence_tolerance * f:
            status = "relative_function"
            break
        if it >= max_iterations:
            status = "max_iterations"
            break
        if res.n_points + 1 + (0 if analytic else p) > max_function_evaluations:
            status = "max_function_evaluations"
            break
        if radius <= x_tolerance * max(np.linalg.norm(d * x), _EPS):
            status = "false_convergence"
            break
        it += 1
        models.append(model)
        s = np.zeros(p)
        s[free], _ = _tr_step(g[free], Hf, d[free], radius)
        xt = np.clip(x + s, lower, upper)
        s = xt - x
        step_norm = float(np.linalg.norm(d * s))
        rt = res(xt[None, :])[0]
        ft = 0.5 * float(rt @ rt) if np.all(np.isfinite(rt)) else np.inf
        actred = f - ft
        lin = float(g @ s)
        pred_gn = -(lin + 0.5 * float(s @ H_gn @ s))
        pred_aug = pred_gn - 0.5 * float(s @ S @ s)
        pred_cur, pred_alt = (pred_aug, pred_gn) if model == "augmented" else (pred_gn, pred_aug)
        rho = actred / pred_cur if pred_cur > 0 else -np.inf
        alt_better = np.isfinite(ft) and abs(actred - pred_alt) < abs(actred - pred_cur)
        if not (np.isfinite(ft) and rho > 1e-4):
            if alt_better and not switched and pred_alt > 0:
                # NL2SOL: the other model explains this step better; retry it at this radius
                model = "gn" if model == "augmented" else "augmented"
                switched = True
                history.append(f)
                continue
            shrink = 0.1 if not np.isfinite(ft) else max(0.1, min(0.5, 0.5 * rho))
            radius = shrink * min(radius, step_norm) if step_norm > 0 else 0.1 * radius
            history.append(f)
            continue
        # accepted step
        Jt = jac_at(xt, rt)
        if not np.all(np.isfinite(Jt)):
            radius = 0.1 * min(radius, step_norm)
            history.append(f)
            continue
        switched = False
        gt = Jt.T @ rt
        y = gt - g
        ys = float(y @ s)
        if ys > 1e-12 * np.linalg.norm(y) * np.linalg.norm(s) and ys > 0:
            ysharp = (Jt - J).T @ rt
            sSs = float(s @ S @ s)
            if sSs != 0.0:
                S = S * min(1.0, abs(float(s @ ysharp)) / abs(sSs))
            z = ysharp - S @ s
            S = S + (np.outer(z, y) + np.outer(y, z)) / ys - float(z @ s) * np.outer(y, y) / ys**2
        if alt_better:
            model = "gn" if model == "augmented" else "augmented"
        if rho > 0.75 and step_norm >= 0.99 * radius:
            radius = 2.0 * radius
        elif rho < 0.25:
            radius = 0.5 * step_norm
        else:
            radius = max(radius, 2.0 * step_norm) if rho > 0.75 else radius
        xscale = np.maximum(np.abs(x), np.abs(xt))
        rel_step = np.max(np.abs(s) * d) / max(np.max(xscale * d), _EPS)
        x, r, f, J, g = xt, rt, ft, Jt, gt
        d = np.maximum(d, np.linalg.norm(J, axis=0))
        history.append(f)
        if rel_step <= x_tolerance and rho > 0.5:
            status = "x"
            break

    success = status in _CONVERGED
    messages = {
        "max_iterations": f"maximum number of iterations ({max_iterations}) reached",
        "max_function_evaluations": (
            f"maximum number of function evaluations ({max_function_evaluations}) reached"
        ),
        "false_convergence": (
            "false convergence: the trust region collapsed without meeting a convergence test "
            "(noisy or non-smooth residuals, failed evaluations, or a wrong Jacobian)"
        ),
    }
    message = _CONVERGED.get(status) or messages[status]
    cov, std, ci = _covariance(J, f, r.size, p, sqrt_w is not None, confidence, x)
    return LeastSquaresResult(
        x=x, residuals=r, cost=f, jacobian=J, covariance=cov, std=std, confidence_intervals=ci,
        confidence=confidence, iterations=it, n_evaluations=res.n_points,
        n_jacobian_evaluations=res.n_jac, n_calls=res.n_calls, success=success, status=status,
        message=message, models=tuple(models), method="nl2sol", history=np.asarray(history),
    )


def _scipy(res, jac_at, x0, r0, lower, upper, method, max_fev, ftol, xtol, bounded,
           absolute, confidence) -> LeastSquaresResult:
    if method == "lm" and bounded and (np.any(np.isfinite(lower)) or np.any(np.isfinite(upper))):
        raise ParameterError("method 'lm' does not take bounds; use 'nl2sol' or 'trf'")
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
        n_jacobian_evaluations=res.n_jac, n_calls=res.n_calls, success=bool(sol.status > 0),
        status=f"scipy_{sol.status}", message=str(sol.message), models=(), method=method,
        history=np.array([0.5 * float(r0 @ r0), f]),
    )


# --- deterministic calibration of a Model ------------------------------------------------------


@dataclass(frozen=True)
class CalibrationResult:
    """Outcome of :func:`calibrate`.

    Attributes
    ----------
    names : calibrated input names, in the order of ``x``.
    x : (p,) best parameter values.
    parameters : mapping name -> best value.
    residuals : (n_exp, m) model minus data at ``x`` (unweighted, in the units of the data).
    cost : ``1/2 sum w r^2`` at ``x`` (``w`` = inverse data variances, 1 without them).
    covariance, std, confidence_intervals : from the Jacobian at ``x`` (see
        :class:`LeastSquaresResult`).
    iterations : outer iterations.
    n_evaluations : model evaluations (points) used, Jacobian differences included.
    success, message : from the solver.
    least_squares : the full :class:`LeastSquaresResult`.
    """

    names: tuple[str, ...]
    x: np.ndarray
    parameters: dict[str, float]
    residuals: np.ndarray
    cost: float
    covariance: np.ndarray
    std: np.ndarray
    confidence_intervals: np.ndarray
    iterations: int
    n_evaluations: int
    success: bool
    message: str
    least_squares: LeastSquaresResult


def calibrate(
    model,
    data,
    parameters,
    *,
    x0=None,
    bounds=None,
    data_variance=None,
    fixed: Mapping[str, float | Sequence[float]] | None = None,
    method: str = "nl2sol",
    jacobian: str = "auto",
    **options,
) -> CalibrationResult:
    """Fit model inputs to data by least squares on the residuals ``model - data``.

    Parameters
    ----------
    model : Model
        Any object of the rotoruq Model protocol (``names_in``, ``names_out``, batched call).
    data : array_like (n_exp, m) or (m,)
        Observations of all ``m`` responses (columns in ``model.names_out`` order), one row per
        experiment (replicates, or different conditions given through ``fixed``).
    parameters : list of input names, or ParameterSpace
        The calibrated inputs. A ParameterSpace supplies starting values (its means) and bounds
        (its supports) unless ``x0``/``bounds`` are given.
    x0 : array_like (p,), optional
        Starting values (required when ``parameters`` is a list of names).
    bounds : (lower, upper) arrays (p,), or mapping name -> (lower, upper), optional.
    data_variance : float, (m,) or (n_exp, m), optional
        Variances of the observations; residuals are weighted by their inverse and the
        parameter covariance uses them as known.
    fixed : mapping name -> value or (n_exp,) values, optional
        The other model inputs, held fixed; an array gives one value per experiment.
    method : "nl2sol" (default), "trf" or "lm".
    jacobian : "auto" (the model's analytic gradient when it has one, else finite
        differences, all columns of a Jacobian in one model batch), "model" or "fd".
    **options : passed to :func:`least_squares` (max_iterations, max_function_evaluations,
        convergence_tolerance, ...).

    Returns
    -------
    CalibrationResult
    """
    from ..model import align_inputs, has_gradient
    from ..params import ParameterSpace

    names_out = tuple(model.names_out)
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
    n_exp = data.shape[0]
    if n_exp == 0:
        raise ParameterError(
            f"calibrate needs data: got no observations (shape {data.shape}); give at least "
            f"one row of the {m} responses {names_out}"
        )

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
    if n_exp * m < p:
        raise ParameterError(
            f"{p} parameters {names} cannot be calibrated on {n_exp * m} observations: "
            "the least-squares problem is underdetermined; add data or fix parameters"
        )
    if start is None:
        raise ParameterError("x0 is required when parameters is a list of names")
    start = np.asarray(start, dtype=float).ravel()
    if start.size != p:
        raise ParameterError(f"x0 has {start.size} values for {p} parameters {names}")
    if isinstance(bounds, Mapping):
        lo = np.array([bounds.get(n, (-np.inf, np.inf))[0] for n in names], dtype=float)
        hi = np.array([bounds.get(n, (-np.inf, np.inf))[1] for n in names], dtype=float)
        bounds = (lo, hi)

    fixed = dict(fixed or {})
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
    fixed_block = np.empty((n_exp, len(fixed)))
    for j, (name, value) in enumerate(fixed.items()):
        v = np.asarray(value, dtype=float)
        if v.ndim == 0 or v.size == 1:
            fixed_block[:, j] = float(v.ravel()[0])
        elif v.shape == (n_exp,):
            fixed_block[:, j] = v
        else:
            raise ParameterError(
                f"fixed input {name!r}: give a scalar or one value per experiment ({n_exp}), "
                f"got shape {v.shape}"
            )

    weights = None
    if data_variance is not None:
        var = np.asarray(data_variance, dtype=float)
        try:
            var = np.broadcast_to(var, data.shape)
        except ValueError:
            raise ParameterError(
                f"data_variance must be a scalar, ({m},) or {data.shape}, got {var.shape}"
            ) from None
        if np.any(~np.isfinite(var)) or np.any(var <= 0):
            raise ParameterError("data_variance must be finite and > 0")
        weights = (1.0 / var).ravel()

    def inputs(X):
        k = X.shape[0]
        full = np.concatenate(
            [np.repeat(X, n_exp, axis=0), np.tile(fixed_block, (k, 1))], axis=1
        )
        return full if perm is None else full[:, perm]

    def residual(X):
        k = X.shape[0]
        values = evaluate(model, inputs(X)).values
        return values.reshape(k, n_exp * m) - data.ravel()[None, :]

    use_model_grad = jacobian == "model" or (jacobian == "auto" and has_gradient(model))
    if jacobian not in ("auto", "model", "fd"):
        raise ParameterError(f"jacobian must be 'auto', 'model' or 'fd', got {jacobian!r}")
    jac = None
    if use_model_grad:
        cols = [list(model.names_in).index(n) for n in names]

        def jac(X):
            G = np.asarray(model.gradient(inputs(X)), dtype=float)  # (k*n_exp, m, d)
            return G[:, :, cols].reshape(X.shape[0], n_exp * m, p)

    ls = least_squares(residual, start, jacobian=jac, bounds=bounds, method=method,
                       weights=weights, **options)
    r = residual(ls.x[None, :])[0].reshape(n_exp, m)
    return CalibrationResult(
        names=names, x=ls.x, parameters={n: float(v) for n, v in zip(names, ls.x, strict=True)},
        residuals=r, cost=ls.cost, covariance=ls.covariance, std=ls.std,
        confidence_intervals=ls.confidence_intervals, iterations=ls.iterations,
        n_evaluations=ls.n_evaluations * n_exp, success=ls.success, message=ls.message,
        least_squares=ls,
    )
