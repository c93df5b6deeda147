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
* adaptive model switching and step assessment as NL2SOL's ``ASSESS``: a trial step that gains
  less than 1e-4 of its predicted reduction is recomputed with the other model (when that one
  would have predicted the actual change 1.5x better) or with a radius from Fletcher's
  quadratic interpolation; one gaining 75 % of the linear prediction grows the radius (up to
  4x) and, when the radius cut it, is recomputed longer at once; a fair step doubles the radius
  when the model foresaw the new gradient or ``f`` still falls steeply along it (NL2SOL's
  gradient tests); the better-predicting model is kept for the next iteration;
* NL2SOL's convergence tests with Dakota's defaults (see :class:`NL2SOLOptions`): relative
  function convergence (the Newton step of the model predicts at most ``tolerance * f``,
  declared after that step is taken, as Dakota does), x-convergence (a full Newton step of
  relative size at most ``x_tolerance``), absolute function convergence, singular convergence
  (no step of the singular radius gains more than ``tolerance * f``: a rank-deficient
  Jacobian) and false convergence (a tiny step still fails). An iteration is an accepted step
  (one Jacobian), as NL2SOL and Dakota count them.

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

__all__ = ["Convergence", "NL2SOLOptions", "NL2SOLOutcome", "nl2sol", "CONVERGED"]

_EPS = np.finfo(float).eps
# NL2SOL's tuning constants (Dennis, Gay, Welsch 1981; PORT defaults)
_TUNER1, _TUNER2, _TUNER3 = 0.1, 1e-4, 0.75  # poor decrease, trivial decrease, increase radius
_TUNER4, _TUNER5 = 0.5, 0.75  # gradient tests that double the radius of a fair step
_RDFCMN, _RDFCMX, _INCFAC, _DECFAC = 0.1, 4.0, 2.0, 0.5  # radius factor bounds
_FUZZ = 1.5  # switch models when the other model's prediction error is 1.5x smaller
# scales D_i = max(DFAC D_i, ||J e_i||): NL2SOL lets them shrink (DFAC 0.6); kept monotone
# (DFAC 1) they cost fewer iterations on the MGH problems and the benchmarks' fits
_DFAC = 1.0

#: status -> message of the stops that count as converged
CONVERGED = {
    "relative_function": "relative function convergence",
    "absolute_function": "absolute function convergence",
    "x": "x-convergence",
    "relative_function_and_x": "relative function convergence and x-convergence",
    "singular": ("singular convergence: no step within the singular radius can reduce f by "
                 "more than singular_tolerance * f; the Jacobian is (nearly) rank-deficient, "
                 "so some parameters are not identified by the data"),
    "gradient": "projected gradient is zero",
}


@dataclass(frozen=True)
class Convergence:
    """When the least-squares iteration stops: its limits and convergence tolerances.

    Dakota's NL2SOL controls, with Dakota's defaults; the field names are the keys of a study
    file's ``least_squares`` step (``max_iterations``, ``max_function_evaluations``,
    ``tolerance``). All tolerances are relative (dimensionless) except ``absolute_tolerance``,
    which is in units of the cost ``f = 1/2 sum (r / noise_std)^2``.

    Parameters
    ----------
    max_iterations : int
        Trust-region iterations (trial steps); Dakota's ``max_iterations``, default 100.
    max_function_evaluations : int
        Residual evaluations (points), Jacobian finite differences included; Dakota's
        ``max_function_evaluations``, default 1000.
    tolerance : float
        Relative function convergence (NL2SOL's rfctol, Dakota's ``convergence_tolerance``,
        default 1e-4): stop when at most that fraction of ``f`` can still be gained. Passed as
        ``ftol`` to scipy's ``trf`` and ``lm``.
    x_tolerance : float
        Relative step size for x-convergence (NL2SOL's xctol, Dakota's ``x_conv_tol``; 1e-5 is
        what Dakota derives from its default ``function_precision`` 1e-10). Passed as ``xtol``
        to scipy.
    absolute_tolerance : float
        Stop when ``f`` falls below it (NL2SOL's afctol, Dakota's ``absolute_conv_tol``,
        default 1e-20).
    singular_tolerance, singular_radius : float
        Singular convergence (NL2SOL's sctol and lmaxs, Dakota's ``singular_conv_tol`` and
        ``singular_radius``; 1e-10 and 1): stop when no step of scaled length
        ``singular_radius`` is predicted to reduce ``f`` by more than
        ``singular_tolerance * f`` (a rank-deficient Jacobian).
    false_convergence_tolerance : float
        False convergence (NL2SOL's xftol, Dakota's ``false_conv_tol``, 1e-8): a step of
        relative size below it that still fails to reduce ``f`` (noisy residuals or a wrong
        Jacobian).

    Notes
    -----
    Only ``max_function_evaluations``, ``tolerance`` and ``x_tolerance`` apply to scipy's
    optimizers.

    Examples
    --------
    >>> import numpy as np
    >>> from rotoruq.methods.least_squares import least_squares
    >>> Convergence(tolerance=1e-10).max_iterations
    100
    >>> t = np.linspace(0.0, 1.0, 5)
    >>> fit = least_squares(lambda p: p[:, :1] + p[:, 1:] * t - (1.0 + 2.0 * t), [0.0, 0.0],
    ...                     convergence=Convergence(max_iterations=20, tolerance=1e-10))
    >>> fit.converged
    True
    """

    max_iterations: int = 100
    max_function_evaluations: int = 1000
    tolerance: float = 1e-4
    x_tolerance: float = 1e-5
    absolute_tolerance: float = 1e-20
    singular_tolerance: float = 1e-10
    singular_radius: float = 1.0
    false_convergence_tolerance: float = 1e-8


@dataclass(frozen=True)
class NL2SOLOptions(Convergence):
    """The stopping rules of :class:`Convergence` and the first radius, with Dakota's defaults
    for ``nl2sol``.

    Dakota passes ``convergence_tolerance`` (default 1e-4) as NL2SOL's rfctol and derives xctol
    and xftol from ``function_precision`` (default 1e-10): ``xctol = sqrt(1e-10) = 1e-5``,
    ``xftol = 100 * 1e-10``; the other values are NL2SOL's own (PORT ``DIVSET``).

    Parameters
    ----------
    max_iterations, max_function_evaluations, tolerance, x_tolerance : int or float
        As in :class:`Convergence`; NL2SOL's trial steps, residual points (``jacobian_cost``
        points per Jacobian), rfctol and xctol.
    absolute_tolerance, singular_tolerance, singular_radius : float
        As in :class:`Convergence`; NL2SOL's afctol, sctol and lmaxs.
    false_convergence_tolerance : float
        As in :class:`Convergence`; NL2SOL's xftol.
    initial_radius : float or None
        lmax0, scaled radius of the first step.
    """

    initial_radius: float | None = 1.0


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


def _relative_step(s: np.ndarray, x: np.ndarray, xt: np.ndarray, d: np.ndarray) -> float:
    """NL2SOL's RELDX: ``max_i |D_i s_i| / max_i D_i (|x_i| + |xt_i|)``."""
    den = float(np.max(d * (np.abs(x) + np.abs(xt))))
    return float(np.max(np.abs(d * s))) / den if den > 0 else 0.0


def _model_reduction(g: np.ndarray, H: np.ndarray, s: np.ndarray) -> float:
    return -(float(g @ s) + 0.5 * float(s @ H @ s))


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

    An iteration is one accepted step (one Jacobian), as NL2SOL counts them; trial steps that
    are rejected, recomputed with the other model or with a larger radius belong to it. The
    step assessment and convergence tests are those of NL2SOL's ``ASSESS`` (Dennis, Gay and
    Welsch 1981): a step that gains less than ``1e-4`` of the predicted reduction is rejected
    (try the other model, then a radius from Fletcher's quadratic interpolation); one that
    gains less than 10 % is accepted with half the radius unless the other model explains it
    better; one that gains 75 % of the linear prediction ``-g.s`` grows the radius up to four
    times and, when it was cut by the radius, is recomputed longer at once; any other accepted
    step doubles the radius when the model predicted the new gradient within half the old
    one's scaled norm or ``g+.s < 0.75 g.s`` (gradient tests). Convergence is
    judged on steps whose actual reduction is at most twice the predicted one: relative
    function (the Newton step of the model at the start of the iteration predicts at most
    ``tolerance * f``), x-convergence (a full Newton step of relative size at most
    ``x_tolerance``), singular convergence (a step of scaled length ``singular_radius`` gains at
    most ``tolerance * f``); absolute function convergence when ``f <= absolute_tolerance``;
    false convergence when a step of relative size at most ``false_convergence_tolerance``
    fails to reduce ``f``.
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
    if o.initial_radius:
        radius = float(o.initial_radius)
    else:
        xs = float(np.linalg.norm(d * x))
        radius = 100.0 * xs if xs > 0 else 100.0
    model = "gn"
    models: list[str] = []
    history = [f]
    it = 0
    status = ""

    while not status:
        if f <= o.absolute_tolerance:
            status = "absolute_function"
            break
        free = ~(((x <= lower) & (g > 0)) | ((x >= upper) & (g < 0)))
        if not np.any(free) or np.linalg.norm(g[free]) == 0.0:
            status = "gradient"
            break
        if it >= o.max_iterations:
            status = "max_iterations"
            break
        H_gn = J.T @ J
        H_of = {"gn": H_gn, "augmented": H_gn + S}
        gf = g[free]
        emax = o.tolerance * f

        def newton(m: str, gf=gf, free=free, H_of=H_of) -> float:
            return _newton_reduction(gf, H_of[m][np.ix_(free, free)])

        def trial(m: str, rad: float, free=free, H_of=H_of, gf=gf, x=x, d=d):
            s = np.zeros(p)
            s[free] = trust_region_step(gf, H_of[m][np.ix_(free, free)], d[free], rad)
            xt = np.clip(x + s, lower, upper)
            s = xt - x
            rt = residual(xt)
            ft = 0.5 * float(rt @ rt) if np.all(np.isfinite(rt)) else np.inf
            return s, xt, rt, ft

        def pred_of(m: str, s: np.ndarray, H_of=H_of, g=g) -> float:
            return _model_reduction(g, H_of[m], s)

        stage, radinc = 1, 0
        gradient_tests = False
        best = None  # the best decreasing trial of this iteration, kept while trying longer
        accept = None
        while accept is None:
            if evaluations() + 1 + jacobian_cost > o.max_function_evaluations:
                if best is not None:
                    accept, radius = best, best[5]
                    break
                status = "max_function_evaluations"
                break
            nreduc = newton(model)
            s, xt, rt, ft = trial(model, radius)
            dstnrm = float(np.linalg.norm(d * s))
            is_newton = dstnrm < 0.999 * radius and np.isfinite(nreduc)
            pred = pred_of(model, s)
            gts = float(g @ s)
            fdif = f - ft
            cand = (s, xt, rt, ft, pred, dstnrm, is_newton, model, nreduc)
            if best is not None and not ft < best[3]:
                accept, radius = best, best[5]  # the longer step is worse: keep the saved one
                gradient_tests = True
                break
            if not np.isfinite(ft):
                radius = _DECFAC * dstnrm if dstnrm > 0 else _DECFAC * radius
                radinc -= 1
                continue
            if not fdif > _TUNER2 * pred:
                # no (or a trivial) decrease
                if 0.0 < nreduc <= emax:
                    status = "relative_function"
                    break
                if _relative_step(s, x, xt, d) <= o.false_convergence_tolerance:
                    status = "false_convergence"
                    break
                other = "augmented" if model == "gn" else "gn"
                if stage < 2 and _FUZZ * abs(fdif - pred_of(other, s)) < abs(fdif - pred):
                    model, stage = other, stage + 1
                    continue
                stage = 2
                radfac = 0.5
                if fdif < 0.0:  # Fletcher: minimizer of the quadratic through f, g.s and ft
                    radfac = max(_RDFCMN, 0.5 * gts / (gts + fdif))
                radius = radfac * dstnrm
                radinc -= 1
                continue
            if fdif <= _TUNER1 * pred:
                other = "augmented" if model == "gn" else "gn"
                if stage < 2 and _FUZZ * abs(fdif - pred_of(other, s)) < abs(fdif - pred):
                    model, stage = other, stage + 1
                    best = cand
                    continue
                accept, radius = cand, 0.5 * dstnrm
                break
            if fdif < -_TUNER3 * gts or radinc < 0:
                accept, radius = cand, max(dstnrm, _EPS)
                gradient_tests = True
                break
            radfac = _RDFCMX
            if fdif < (0.5 / radfac - 1.0) * gts:
                radfac = max(_INCFAC, 0.5 * gts / (gts + fdif))
            radius = radfac * dstnrm
            if is_newton:
                accept = cand
                break
            best = cand  # cut by the radius: recompute it longer at once
            radinc += 1
        if accept is None:
            break
        s, xt, rt, ft, pred, dstnrm, is_newton, model, nreduc = accept
        fdif = f - ft
        reldx = _relative_step(s, x, xt, d)
        Jt = gradient(xt, rt)
        if not np.all(np.isfinite(Jt)):
            radius = 0.1 * dstnrm
            continue
        it += 1
        models.append(model)
        gt = Jt.T @ rt
        if gradient_tests and (
                np.linalg.norm((H_of[model] @ s - (gt - g)) / d)
                <= _TUNER4 * np.linalg.norm(g / d) or float(gt @ s) < _TUNER5 * float(g @ s)):
            # the model foresaw the new gradient, or f still falls steeply along s
            radius = _INCFAC * dstnrm
        S = _secant_update(S, s, J, Jt, g, gt, rt)
        other = "augmented" if model == "gn" else "gn"

        if _FUZZ * abs(fdif - pred_of(other, s)) < abs(fdif - pred):
            model = other
        f0 = f
        x, r, f, J, g = xt, rt, ft, Jt, gt
        d = np.maximum(_DFAC * d, np.linalg.norm(J, axis=0))
        history.append(f)
        if f <= o.absolute_tolerance:
            status = "absolute_function"
        elif 0.5 * fdif <= pred:  # the model was trustworthy on this step
            emax = o.tolerance * f0
            rf_met = 0.0 < nreduc <= emax
            x_met = is_newton and reldx <= o.x_tolerance
            if rf_met or x_met:
                status = ("relative_function_and_x" if rf_met and x_met else
                          "relative_function" if rf_met else "x")
            elif pred <= emax and (dstnrm > o.singular_radius or not np.isfinite(nreduc)):
                status = "singular"
    return NL2SOLOutcome(x=x, r=r, cost=f, J=J, iterations=it, status=status,
                         models=tuple(models), history=np.asarray(history))
