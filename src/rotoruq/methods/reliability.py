"""Reliability methods: the mean value method (MVFOSM) and MPP searches (RIA / PMA) with FORM
and SORM probability integrations.

Conventions (Dakota's). For a response g with mean mu and standard deviation sigma:

* ``beta_cdf = (mu - z) / sigma`` and ``P(g <= z) = Phi(-beta_cdf)``;
* ``beta_ccdf = (z - mu) / sigma`` and ``P(g > z) = Phi(-beta_ccdf)``.

(Thesis eq. 2.9 prints ``Phi(beta_ccdf)``; the minus sign is the consistent form, since
P(g > z) = 1 - Phi((z - mu)/sigma).)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from ..errors import ParameterError
from ._common import gradient_at, levels_per_response

__all__ = [
    "MeanValueResult",
    "mean_value",
    "mean_value_from_gradient",
    "MPPResult",
    "mpp_search",
    "sorm_probability",
]


# ---------------------------------------------------------------------------------------------
# Mean value method (thesis eqs. 2.4-2.9)
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MeanValueResult:
    """First-order second-moment statistics of the responses.

    Attributes
    ----------
    names_in, names_out : input (d) and response (m) names.
    mean : (m,) ``g(mu_x)`` (eq. 2.4).
    std : (m,) first-order standard deviation (eq. 2.5, correlations included).
    gradient : (m, d) dg/dx at the input means.
    importance : (m, d) importance factors ``s_i g_i (R s g)_i / sigma_g^2`` (s: input stds,
        R: input correlation); they sum to 1 per response and reduce to
        ``(s_i g_i)^2 / sigma_g^2`` for independent inputs.
    covariance : (m, m) first-order response covariance ``J C J^T``.
    input_std : (d,) input standard deviations used.
    response_levels, cdf_probability, ccdf_probability, cdf_reliability, ccdf_reliability :
        dicts response name -> arrays of the same length: the forward mapping z -> p, beta.
    probability_levels, probability_response : dict name -> arrays: the inverse mapping
        p -> z (p read as CDF or CCDF probability, see ``distribution``).
    reliability_levels, reliability_response : dict name -> arrays: beta -> z.
    distribution : "cdf" or "ccdf", how probability and reliability levels are read.
    n_evaluations : number of model evaluations used.
    """

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    mean: np.ndarray
    std: np.ndarray
    gradient: np.ndarray
    importance: np.ndarray
    covariance: np.ndarray
    input_std: np.ndarray
    response_levels: dict = field(default_factory=dict)
    cdf_probability: dict = field(default_factory=dict)
    ccdf_probability: dict = field(default_factory=dict)
    cdf_reliability: dict = field(default_factory=dict)
    ccdf_reliability: dict = field(default_factory=dict)
    probability_levels: dict = field(default_factory=dict)
    probability_response: dict = field(default_factory=dict)
    reliability_levels: dict = field(default_factory=dict)
    reliability_response: dict = field(default_factory=dict)
    distribution: str = "cdf"
    n_evaluations: int = 0

    def stats(self) -> np.ndarray:
        """(m, 2) array of [mean, std] per response (the CUU inner-loop output)."""
        return np.column_stack([self.mean, self.std])

    def cdf(self, name: str, z) -> np.ndarray:
        """Gaussian CDF P(g <= z) of response ``name`` implied by the two moments."""
        k = self.names_out.index(name)
        return stats.norm.cdf((np.asarray(z, dtype=float) - self.mean[k]) / self.std[k])


def mean_value_from_gradient(
    g0,
    grad,
    std,
    correlation=None,
    *,
    response_levels=None,
    probability_levels=None,
    reliability_levels=None,
    distribution: str = "cdf",
    names_in=None,
    names_out=None,
    n_evaluations: int = 0,
) -> MeanValueResult:
    """Mean value statistics from a response value and gradient at the input means.

    Parameters
    ----------
    g0 : (m,) responses at the input means.
    grad : (m, d) gradient at the input means.
    std : (d,) input standard deviations (> 0 or 0 for a fixed input).
    correlation : (d, d) input correlation matrix (x-space), default identity.
    response_levels, probability_levels, reliability_levels : see :func:`mean_value`.

    Cheap (no model calls): a nested loop that only changes input stds can reuse ``grad``.
    """
    g0 = np.atleast_1d(np.asarray(g0, dtype=float))
    grad = np.asarray(grad, dtype=float).reshape(g0.size, -1)
    std = np.atleast_1d(np.asarray(std, dtype=float))
    m, d = grad.shape
    if std.shape != (d,):
        raise ParameterError(f"std must have shape ({d},), got {std.shape}")
    if np.any(std < 0) or not np.all(np.isfinite(std)):
        raise ParameterError(f"input standard deviations must be finite and >= 0, got {std}")
    corr = np.eye(d) if correlation is None else np.asarray(correlation, dtype=float)
    if corr.shape != (d, d):
        raise ParameterError(f"correlation must have shape ({d}, {d}), got {corr.shape}")
    distribution = distribution.lower()
    if distribution not in ("cdf", "ccdf"):
        raise ParameterError(f"distribution must be 'cdf' or 'ccdf', got {distribution!r}")
    sg = grad * std[None, :]  # (m, d): s_i dg/dx_i
    rsg = sg @ corr.T  # (m, d): (R s g)_i
    cov_out = sg @ corr @ sg.T
    var = np.einsum("md,md->m", sg, rsg)
    sigma = np.sqrt(np.maximum(var, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        importance = np.where(var[:, None] > 0, sg * rsg / var[:, None], 0.0)

    names_out = tuple(names_out) if names_out is not None else tuple(f"g{i}" for i in range(m))
    names_in = tuple(names_in) if names_in is not None else tuple(f"x{i}" for i in range(d))
    rl = levels_per_response(response_levels, names_out, "response_levels")
    pl = levels_per_response(probability_levels, names_out, "probability_levels")
    bl = levels_per_response(reliability_levels, names_out, "reliability_levels")
    for name, p in pl.items():
        if np.any((p <= 0) | (p >= 1)):
            raise ParameterError(f"probability_levels for {name!r} must lie in (0, 1), got {p}")

    cdf_p, ccdf_p, cdf_b, ccdf_b, p_resp, b_resp = {}, {}, {}, {}, {}, {}
    for k, name in enumerate(names_out):
        mu, s = g0[k], sigma[k]
        z = rl[name]
        with np.errstate(divide="ignore", invalid="ignore"):
            b_cdf = (mu - z) / s  # eq. 2.6
        if s == 0:  # deterministic response: step functions
            b_cdf = np.where(z >= mu, -np.inf, np.inf)
        cdf_b[name] = b_cdf
        ccdf_b[name] = -b_cdf
        cdf_p[name] = stats.norm.cdf(-b_cdf)  # eq. 2.8
        ccdf_p[name] = stats.norm.cdf(b_cdf)  # P(g > z) = Phi(-beta_ccdf)
        p = pl[name]
        beta_from_p = -stats.norm.ppf(p)  # beta of the chosen distribution
        b = bl[name]
        if distribution == "cdf":  # eq. 2.7: z = mu - sigma beta_cdf
            p_resp[name] = mu - s * beta_from_p
            b_resp[name] = mu - s * b
        else:  # z = mu + sigma beta_ccdf
            p_resp[name] = mu + s * beta_from_p
            b_resp[name] = mu + s * b

    return MeanValueResult(
        names_in=names_in,
        names_out=names_out,
        mean=g0,
        std=sigma,
        gradient=grad,
        importance=importance,
        covariance=cov_out,
        input_std=std,
        response_levels=rl,
        cdf_probability=cdf_p,
        ccdf_probability=ccdf_p,
        cdf_reliability=cdf_b,
        ccdf_reliability=ccdf_b,
        probability_levels=pl,
        probability_response=p_resp,
        reliability_levels=bl,
        reliability_response=b_resp,
        distribution=distribution,
        n_evaluations=int(n_evaluations),
    )


def mean_value(
    model,
    space,
    *,
    response_levels=None,
    probability_levels=None,
    reliability_levels=None,
    distribution: str = "cdf",
    gradient: str = "auto",
    fd_step: float = 1e-6,
    seed=None,
) -> MeanValueResult:
    """Mean value method (MVFOSM, thesis eqs. 2.4-2.9).

    Parameters
    ----------
    model : Model (batched); its inputs are matched to ``space.names`` by name.
    space : ParameterSpace; its means, stds and correlation matrix are used.
    response_levels : levels z (same for every response, a mapping name -> levels, or one
        sequence per response) mapped to CDF/CCDF probabilities and reliability indices.
    probability_levels : probabilities in (0, 1) mapped to response levels (read as CDF
        probabilities P(g <= z), or CCDF P(g > z) with ``distribution="ccdf"``).
    reliability_levels : reliability indices mapped to response levels
        (``z = mu - sigma beta`` for "cdf", ``z = mu + sigma beta`` for "ccdf").
    gradient : "auto" (the model's analytic ``gradient`` when it has one, else central finite
        differences on one batch of 2d+1 points), "analytic" or "fd".
    fd_step : relative finite-difference step; the step of input i is
        ``fd_step * max(|mu_i|, sigma_i)``.
    seed : unused (deterministic method); accepted for a uniform method signature.

    Returns
    -------
    MeanValueResult
    """
    del seed
    x0 = space.mean
    g0, grad, n_eval = gradient_at(model, space, x0, gradient=gradient, fd_step=fd_step)
    return mean_value_from_gradient(
        g0,
        grad,
        space.std,
        space.correlation_matrix,
        response_levels=response_levels,
        probability_levels=probability_levels,
        reliability_levels=reliability_levels,
        distribution=distribution,
        names_in=space.names,
        names_out=tuple(model.names_out),
        n_evaluations=n_eval,
    )


# ---------------------------------------------------------------------------------------------
# MPP search: RIA (eq. 2.10) and PMA (eq. 2.11) with FORM (2.12) / SORM (2.13)
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MPPResult:
    """Result of :func:`mpp_search` (all dicts keyed by response name).

    Forward (RIA) mapping, arrays over ``response_levels[name]``:
    ``cdf_probability`` P(g <= z) and ``ccdf_probability``; ``cdf_reliability`` the FORM
    index beta_cdf (signed distance of the MPP); ``generalized_reliability`` -Phi^-1(p_cdf)
    (differs from beta_cdf with SORM); ``mpp_u`` / ``mpp_x`` (k, d) most probable points;
    ``curvatures`` (k, d-1) principal curvatures (SORM only, else NaN).
    Inverse (PMA) mapping: ``probability_response`` / ``reliability_response`` response
    levels for ``probability_levels`` / ``reliability_levels`` (CDF sense, FORM).
    """

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    integration: str
    response_levels: dict
    cdf_probability: dict
    ccdf_probability: dict
    cdf_reliability: dict
    generalized_reliability: dict
    mpp_u: dict
    mpp_x: dict
    curvatures: dict
    probability_levels: dict
    probability_response: dict
    reliability_levels: dict
    reliability_response: dict
    pma_mpp_x: dict
    n_evaluations: int
    converged: bool


class _UModel:
    """Response k of the model as a function of u, with batched FD gradients/Hessians."""

    def __init__(self, model, space, fd_step):
        from ._common import eval_space

        self._eval = eval_space
        self.model, self.space, self.h = model, space, fd_step
        self.n_eval = 0
        self._cache: dict = {}

    def values(self, u):
        u = np.atleast_2d(u)
        b = self._eval(self.model, self.space, self.space.from_u(u))
        self.n_eval += u.shape[0]
        if b.failures:
            from ..errors import EvaluationError

            raise EvaluationError(f"MPP search: evaluation failed at u = {u[min(b.failures)]}")
        return b.values

    def value_grad(self, u):
        key = u.tobytes()
        if key not in self._cache:
            d = u.size
            h = self.h * np.maximum(1.0, np.abs(u))
            pts = np.repeat(u[None, :], 2 * d + 1, axis=0)
            i = np.arange(d)
            pts[1 + i, i] += h
            pts[1 + d + i, i] -= h
            v = self.values(pts)
            self._cache = {key: (v[0], (v[1 : d + 1] - v[d + 1 :]).T / (2 * h))}
        return self._cache[key]

    def hessian(self, u, k):
        """Central-difference Hessian of response k in u-space, one batch of 2d^2+1 points."""
        d = u.size
        h = 1e3 * self.h * np.maximum(1.0, np.abs(u))  # larger step: second differences
        e = np.eye(d) * h
        pts = [u]
        for i in range(d):
            for j in range(d):
                pts += [u + e[i] + e[j], u + e[i] - e[j], u - e[i] + e[j], u - e[i] - e[j]]
        v = self.values(np.array(pts))[:, k]
        f = v[1:].reshape(d, d, 4)
        return (f[..., 0] - f[..., 1] - f[..., 2] + f[..., 3]) / (4 * np.outer(h, h))


def _tangent_basis(alpha):
    """Orthonormal basis (d-1, d) of the plane orthogonal to the unit vector alpha."""
    d = alpha.size
    q, _ = np.linalg.qr(np.column_stack([alpha, np.eye(d)]))
    return q[:, 1:d].T


def _ria(um, k, z, tol, max_iter):
    from scipy.optimize import minimize

    d = um.space.dim
    g0, grad0 = um.value_grad(np.zeros(d))
    # start on the linearized limit state
    gk = grad0[k]
    u_start = (z - g0[k]) * gk / max(gk @ gk, 1e-300)
    cons = {
        "type": "eq",
        "fun": lambda u: um.value_grad(u)[0][k] - z,
        "jac": lambda u: um.value_grad(u)[1][k],
    }
    res = minimize(
        lambda u: u @ u,
        u_start,
        jac=lambda u: 2 * u,
        constraints=[cons],
        method="SLSQP",
        options={"maxiter": max_iter, "ftol": tol},
    )
    return res.x, bool(res.success), g0[k]


def _pma(um, k, beta, tol, max_iter):
    from scipy.optimize import minimize

    d = um.space.dim
    g0, grad0 = um.value_grad(np.zeros(d))
    gk = grad0[k]
    sign = 1.0 if beta >= 0 else -1.0  # beta_cdf > 0: lower tail (minimize g)
    nrm = np.linalg.norm(gk)
    u_start = -sign * abs(beta) * gk / nrm if nrm > 0 else np.full(d, abs(beta) / np.sqrt(d))
    cons = {"type": "eq", "fun": lambda u: u @ u - beta**2, "jac": lambda u: 2 * u}
    res = minimize(
        lambda u: sign * um.value_grad(u)[0][k],
        u_start,
        jac=lambda u: sign * um.value_grad(u)[1][k],
        constraints=[cons],
        method="SLSQP",
        options={"maxiter": max_iter, "ftol": tol},
    )
    return res.x, bool(res.success)


def sorm_probability(beta: float, kappa, method: str = "breitung") -> float:
    """Second-order probability of the region beyond a limit state at distance beta > 0
    with principal curvatures ``kappa`` (positive: curving away from the origin), eq. 2.13
    (Breitung) or Hohenbichler-Rackwitz (beta replaced by phi(beta)/Phi(-beta))."""
    kappa = np.asarray(kappa, dtype=float)
    pf = stats.norm.cdf(-beta)
    if method == "breitung":
        c = beta
    elif method in ("hohenbichler", "hohenbichler_rackwitz"):
        c = stats.norm.pdf(beta) / stats.norm.cdf(-beta)
    else:
        raise ParameterError(f"SORM method must be 'breitung' or 'hohenbichler', got {method!r}")
    fac = 1.0 + c * kappa
    if np.any(fac <= 0):
        return float("nan")  # the asymptotic formula does not apply
    return float(pf / np.sqrt(np.prod(fac)))


def mpp_search(
    model,
    space,
    *,
    response_levels=None,
    probability_levels=None,
    reliability_levels=None,
    integration: str = "first_order",
    sorm: str = "breitung",
    fd_step: float = 1e-5,
    tol: float = 1e-10,
    max_iter: int = 100,
    seed=None,
) -> MPPResult:
    """Most probable point searches in u-space (Nataf) with FORM or SORM integration.

    RIA (eq. 2.10): for each response level z, ``min u^T u`` subject to ``G(u) = z``;
    ``beta_cdf = +|u*|`` when g(mean point) > z (the region g <= z excludes the origin), else
    ``-|u*|``; FORM ``P(g <= z) = Phi(-beta_cdf)`` (2.12); SORM (2.13, Breitung or
    Hohenbichler-Rackwitz) with the principal curvatures of the limit state at the MPP from a
    finite-difference Hessian in u-space.

    PMA (eq. 2.11): for each reliability level beta (CDF sense; probability levels are turned
    into ``beta = -Phi^-1(p)``), ``min G(u)`` (beta > 0) or ``max G(u)`` (beta < 0) on the
    sphere ``u^T u = beta^2``; the optimum is the response level (FORM).

    Optimizer: scipy SLSQP. Gradients: central finite differences in u-space, each gradient
    one batched model call of 2d + 1 points (step ``fd_step * max(1, |u_i|)``).
    """
    del seed
    integration = integration.lower()
    if integration not in ("first_order", "second_order", "form", "sorm"):
        raise ParameterError(
            f"integration must be 'first_order' or 'second_order', got {integration!r}"
        )
    second = integration in ("second_order", "sorm")
    names_out = tuple(model.names_out)
    d = space.dim
    um = _UModel(model, space, fd_step)
    rl = levels_per_response(response_levels, names_out, "response_levels")
    pl = levels_per_response(probability_levels, names_out, "probability_levels")
    bl = levels_per_response(reliability_levels, names_out, "reliability_levels")
    out = {k: {} for k in ("p", "pc", "b", "gb", "mu", "mx", "kap", "pr", "br", "pmx")}
    ok = True
    for k, name in enumerate(names_out):
        zs = rl[name]
        n = zs.size
        p_cdf, b_cdf, gbeta = np.empty(n), np.empty(n), np.empty(n)
        mu, kap = np.empty((n, d)), np.full((n, max(d - 1, 0)), np.nan)
        for j, z in enumerate(zs):
            u, conv, gmean = _ria(um, k, z, tol, max_iter)
            ok &= conv
            beta = float(np.linalg.norm(u))
            s = 1.0 if gmean > z else -1.0
            b_cdf[j] = s * beta
            p_region = stats.norm.cdf(-beta)
            if second and d > 1 and beta > 0:
                _, grad = um.value_grad(u)
                gh = s * grad[k]  # h = s (G - z): origin on the h > 0 side
                nrm = np.linalg.norm(gh)
                alpha = -gh / nrm
                basis = _tangent_basis(alpha)
                hess = s * um.hessian(u, k)
                kap[j] = np.linalg.eigvalsh(basis @ hess @ basis.T / nrm)
                p_region = sorm_probability(beta, kap[j], sorm)
            p_cdf[j] = p_region if s > 0 else 1.0 - p_region
            gbeta[j] = -stats.norm.ppf(p_cdf[j])
            mu[j] = u
        out["p"][name], out["pc"][name] = p_cdf, 1.0 - p_cdf
        out["b"][name], out["gb"][name] = b_cdf, gbeta
        out["mu"][name], out["kap"][name] = mu, kap
        out["mx"][name] = space.from_u(mu) if n else np.empty((0, d))
        p = pl[name]
        if np.any((p <= 0) | (p >= 1)):
            raise ParameterError(f"probability_levels for {name!r} must lie in (0, 1), got {p}")
        levels = {"pr": -stats.norm.ppf(p), "br": bl[name]}
        pmx = []
        for key, betas in levels.items():
            zz = np.empty(betas.size)
            for j, beta in enumerate(betas):
                if beta == 0:
                    u = np.zeros(d)
                    conv = True
                else:
                    u, conv = _pma(um, k, float(beta), tol, max_iter)
                ok &= conv
                zz[j] = um.value_grad(u)[0][k]
                pmx.append(u)
            out[key][name] = zz
        out["pmx"][name] = space.from_u(np.array(pmx)) if pmx else np.empty((0, d))
    return MPPResult(
        names_in=space.names,
        names_out=names_out,
        integration="second_order" if second else "first_order",
        response_levels=rl,
        cdf_probability=out["p"],
        ccdf_probability=out["pc"],
        cdf_reliability=out["b"],
        generalized_reliability=out["gb"],
        mpp_u=out["mu"],
        mpp_x=out["mx"],
        curvatures=out["kap"],
        probability_levels=pl,
        probability_response=out["pr"],
        reliability_levels=bl,
        reliability_response=out["br"],
        pma_mpp_x=out["pmx"],
        n_evaluations=um.n_eval,
        converged=bool(ok),
    )
