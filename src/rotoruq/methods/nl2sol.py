"""The NL2SOL iteration: an adaptive trust-region solver for nonlinear least squares.

``min_x f(x) = 1/2 |r(x)|^2`` after Dennis, Gay and Welsch (1981, "An adaptive nonlinear
least-squares algorithm", ACM TOMS 7(3), the algorithm behind Dakota's ``nl2sol``):

* a trust region in the scaled norm ``||D s||`` with ``D_i = max(D_i, ||J e_i||)`` (adaptive
  column scaling), steps from the exact (eigen-decomposition) solution of the trust-region
  subproblem, i.e. Levenberg-Marquardt steps with the Moré-Hebden choice of the multiplier;
* two quadratic models of ``f`` (thesis eqs. 2.35 and 2.36): Gauss-Newton, with Hessian
  ``J^T J``, and the augmented model ``J^T J + S`` where ``S`` is a secant approximation of
  the residual curvature term ``Q = sum_i r_i nabla^2 r_i`` (eq. 2.33);
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
  a full Newton step is at most ``tolerance * f``), x-convergence (relative step below
  ``x_tolerance``), absolute function convergence (``f <= absolute_tolerance``), and false
  convergence (the radius collapsed without any of the above).

Bounds are handled by an active-set projection: variables on a bound whose gradient pushes
outward are held fixed for the step, the step is solved in the free subspace, and the trial
point is projected back into the box (the predicted reduction is that of the projected step).

The residuals and Jacobian come from callables (:func:`rotoruq.methods.least_squares.
least_squares` builds them: batching, weighting, finite differences and counting live there).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import optimize

__all__ = ["NL2SOLOptions", "NL2SOLOutcome", "nl2sol", "CONVERGED"]

_EPS = np.finfo(float).eps

#: status -> message of the stops that count as converged
CONVERGED = {
    "relative_function": "relative function convergence",
    "absolute_function": "absolute function convergence",
    "x": "x-convergence",
    "gradient": "projected gradient is zero",
}


@dataclass(frozen=True)
class NL2SOLOptions:
    """Stopping rules and the first radius (Dakota's defaults where it has them).

    max_iterations : trial steps. max_function_evaluations : residual points, Jacobian
    differences included (``jacobian_cost`` points per Jacobian). tolerance : relative function
    convergence (NL2SOL's rfctol). x_tolerance : relative step for x-convergence (xctol).
    absolute_tolerance : stop when ``f`` falls below it (afctol). initial_radius : scaled radius
    of the first step (None: ``100 ||D x0||``, or 100 when that is 0, as MINPACK).
    """

    max_iterations: int = 100
    max_function_evaluations: int = 1000
    tolerance: float = 1e-4
    x_tolerance: float = 1.5e-8
    absolute_tolerance: float = 1e-20
    initial_radius: float | None = None


@dataclass(frozen=True, eq=False)
class NL2SOLOutcome:
    """Where the iteration stopped: point ``x`` (p,), residuals ``r`` (n_res,), cost
    ``1/2 r.r``, Jacobian ``J`` (n_res, p), ``iterations``, ``status`` (a key of
    :data:`CONVERGED` or max_iterations, max_function_evaluations, false_convergence),
    ``models`` ("gn"/"augmented" per iteration) and ``history`` (cost per iteration)."""

    x: np.ndarray
    r: np.ndarray
    cost: float
    J: np.ndarray
    iterations: int
    status: str
    models: tuple[str, ...]
    history: np.ndarray


def trust_region_step(
    g: np.ndarray, H: np.ndarray, d: np.ndarray, radius: float
) -> np.ndarray:
    """Solve ``min g.s + 1/2 s.H.s`` subject to ``||d * s|| <= radius`` exactly (p,)."""
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
            return z / d
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
        return z / d
    hi = lo + np.linalg.norm(a) / radius + lmax
    while znorm(hi) > radius:
        hi *= 2.0
    mu = optimize.brentq(lambda m: znorm(m) - radius, lo, hi, xtol=1e-14 * hi, rtol=1e-12)
    return -V @ (a / (lam + mu)) / d


def _newton_reduction(g: np.ndarray, H: np.ndarray) -> float:
    """``1/2 g^T H^-1 g`` when H is positive definite, else +inf."""
    try:
        c = np.linalg.cholesky(H)
    except np.linalg.LinAlgError:
        return np.inf
    w = np.linalg.solve(c, g)
    return 0.5 * float(w @ w)


def _secant_update(S, s, J, Jt, g, gt, rt) -> np.ndarray:
    """The structured (size-scaled) rank-two update of ``S`` after the accepted step ``s``."""
    y = gt - g
    ys = float(y @ s)
    if not (ys > 1e-12 * np.linalg.norm(y) * np.linalg.norm(s) and ys > 0):
        return S
    ysharp = (Jt - J).T @ rt
    sSs = float(s @ S @ s)
    if sSs != 0.0:
        S = S * min(1.0, abs(float(s @ ysharp)) / abs(sSs))
    z = ysharp - S @ s
    return S + (np.outer(z, y) + np.outer(y, z)) / ys - float(z @ s) * np.outer(y, y) / ys**2


def _new_radius(radius: float, rho: float, step_norm: float) -> float:
    """Radius after an accepted step with reduction ratio ``rho``."""
    if rho > 0.75 and step_norm >= 0.99 * radius:
        return 2.0 * radius
    if rho < 0.25:
        return 0.5 * step_norm
    return max(radius, 2.0 * step_norm) if rho > 0.75 else radius


def nl2sol(
    residual: Callable[[np.ndarray], np.ndarray],
    gradient: Callable[[np.ndarray, np.ndarray], np.ndarray],
    x0: np.ndarray,
    r0: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    options: NL2SOLOptions,
    evaluations: Callable[[], int],
    jacobian_cost: int,
) -> NL2SOLOutcome:
    """Run the NL2SOL iteration from ``x0`` (p,) with residuals ``r0`` there.

    residual : one point (p,) -> residuals (n_res,), non-finite where it failed.
    gradient : the Jacobian, (x, r(x)) -> (n_res, p).
    evaluations : residual points spent so far (for ``max_function_evaluations``).
    jacobian_cost : residual points one Jacobian costs (0 for an analytic one).
    """
    o = options
    p = x0.size
    x, r = x0, r0
    f = 0.5 * float(r @ r)
    J = gradient(x, r)
    if not np.all(np.isfinite(J)):
        from ..errors import EvaluationError

        raise EvaluationError(f"the Jacobian is not finite at the starting point x0 = {x0}")
    g = J.T @ r
    S = np.zeros((p, p))
    d = np.maximum(np.linalg.norm(J, axis=0), 1e-8 * max(float(np.linalg.norm(J)), 1.0))
    xs = float(np.linalg.norm(d * x))
    radius = float(o.initial_radius) if o.initial_radius else (100.0 * xs if xs > 0 else 100.0)
    model = "gn"
    models: list[str] = []
    history = [f]
    it = 0
    switched = False  # model switched during the current (not yet accepted) iteration

    while True:
        if f <= o.absolute_tolerance:
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
        if nreduc <= o.tolerance * f:
            status = "relative_function"
            break
        if it >= o.max_iterations:
            status = "max_iterations"
            break
        if evaluations() + 1 + jacobian_cost > o.max_function_evaluations:
            status = "max_function_evaluations"
            break
        if radius <= o.x_tolerance * max(np.linalg.norm(d * x), _EPS):
            status = "false_convergence"
            break
        it += 1
        models.append(model)
        s = np.zeros(p)
        s[free] = trust_region_step(g[free], Hf, d[free], radius)
        xt = np.clip(x + s, lower, upper)
        s = xt - x
        step_norm = float(np.linalg.norm(d * s))
        rt = residual(xt)
        ft = 0.5 * float(rt @ rt) if np.all(np.isfinite(rt)) else np.inf
        actred = f - ft
        pred_gn = -(float(g @ s) + 0.5 * float(s @ H_gn @ s))
        pred_aug = pred_gn - 0.5 * float(s @ S @ s)
        pred_cur, pred_alt = (pred_aug, pred_gn) if model == "augmented" else (pred_gn, pred_aug)
        rho = actred / pred_cur if pred_cur > 0 else -np.inf
        alt_better = np.isfinite(ft) and abs(actred - pred_alt) < abs(actred - pred_cur)
        history.append(f)
        if not (np.isfinite(ft) and rho > 1e-4):
            if alt_better and not switched and pred_alt > 0:
                # NL2SOL: the other model explains this step better; retry it at this radius
                model = "gn" if model == "augmented" else "augmented"
                switched = True
                continue
            shrink = 0.1 if not np.isfinite(ft) else max(0.1, min(0.5, 0.5 * rho))
            radius = shrink * min(radius, step_norm) if step_norm > 0 else 0.1 * radius
            continue
        Jt = gradient(xt, rt)
        if not np.all(np.isfinite(Jt)):
            radius = 0.1 * min(radius, step_norm)
            continue
        switched = False
        gt = Jt.T @ rt
        S = _secant_update(S, s, J, Jt, g, gt, rt)
        if alt_better:
            model = "gn" if model == "augmented" else "augmented"
        radius = _new_radius(radius, float(rho), step_norm)
        xscale = np.maximum(np.abs(x), np.abs(xt))
        rel_step = np.max(np.abs(s) * d) / max(np.max(xscale * d), _EPS)
        x, r, f, J, g = xt, rt, ft, Jt, gt
        d = np.maximum(d, np.linalg.norm(J, axis=0))
        history[-1] = f
        if rel_step <= o.x_tolerance and rho > 0.5:
            status = "x"
            break
    return NL2SOLOutcome(x=x, r=r, cost=f, J=J, iterations=it, status=status,
                         models=tuple(models), history=np.asarray(history))
