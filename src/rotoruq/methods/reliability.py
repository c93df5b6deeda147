"""Reliability methods: the mean value method (MVFOSM) and MPP searches (RIA / PMA) with FORM
and SORM probability integrations.

Conventions (Dakota's). For a response g with mean mu and standard deviation sigma:

* ``beta_cdf = (mu - z) / sigma`` and ``P(g <= z) = Phi(-beta_cdf)``;
* ``beta_ccdf = (z - mu) / sigma`` and ``P(g > z) = Phi(-beta_ccdf)``.

(Thesis eq. 2.9 prints ``Phi(beta_ccdf)``; the minus sign is the consistent form, since
P(g > z) = 1 - Phi((z - mu)/sigma).)
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike
from scipy import stats

from ..errors import EvaluationError, ParameterError, RotoruqError
from ..model import FD_STEP, GradientOption, Model, finite_difference, model_gradient
from ._common import eval_space, levels_per_response

if TYPE_CHECKING:
    from ..params import ParameterSpace

#: levels: None, one sequence for every response, a mapping name -> levels, or one per response
Levels = ArrayLike | Mapping[str, ArrayLike] | None

__all__ = [
    "MeanValueResult",
    "mean_value",
    "mean_value_from_gradient",
    "MPPResult",
    "mpp_search",
    "sorm_probability",
    "DegenerateResponseError",
    "SORMWarning",
]


# ---------------------------------------------------------------------------------------------
# Mean value method (thesis eqs. 2.4-2.9)
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
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

    def cdf(self, name: str, z: ArrayLike) -> np.ndarray:
        """Gaussian CDF P(g <= z) of response ``name`` implied by the two moments.

        Parameters
        ----------
        name : str
            A response name.
        z : float or array_like
            Levels, response units; the result has their shape.
        """
        k = self.names_out.index(name)
        return stats.norm.cdf((np.asarray(z, dtype=float) - self.mean[k]) / self.std[k])


def _distribution(distribution: str) -> str:
    """'cdf' or 'ccdf' (any case), else a ParameterError."""
    d = str(distribution).lower()
    if d not in ("cdf", "ccdf"):
        raise ParameterError(f"distribution must be 'cdf' or 'ccdf', got {distribution!r}")
    return d


def _levels(response_levels, probability_levels, reliability_levels, names_out):
    """Response, probability and reliability levels per response (probabilities checked)."""
    rl = levels_per_response(response_levels, names_out, "response_levels")
    pl = levels_per_response(probability_levels, names_out, "probability_levels")
    bl = levels_per_response(reliability_levels, names_out, "reliability_levels")
    for name, p in pl.items():
        if np.any((p <= 0) | (p >= 1)):
            raise ParameterError(f"probability_levels for {name!r} must lie in (0, 1), got {p}")
    return rl, pl, bl


def mean_value_from_gradient(
    g0: ArrayLike,
    grad: ArrayLike,
    std: ArrayLike,
    correlation: ArrayLike | None = None,
    *,
    response_levels: Levels = None,
    probability_levels: Levels = None,
    reliability_levels: Levels = None,
    distribution: str = "cdf",
    names_in: Sequence[str] | None = None,
    names_out: Sequence[str] | None = None,
    n_evaluations: int = 0,
) -> MeanValueResult:
    """Mean value statistics from a response value and gradient at the input means.

    Cheap (no model calls): a nested loop that only changes input stds can reuse ``grad``.

    Parameters
    ----------
    g0 : (m,) responses at the input means.
    grad : (m, d) gradient at the input means.
    std : (d,) input standard deviations (> 0 or 0 for a fixed input).
    correlation : (d, d) input correlation matrix (x-space), default identity.
    response_levels, probability_levels, reliability_levels : see :func:`mean_value`.
    distribution : str, optional
        ``"cdf"`` (default) or ``"ccdf"``: how probability and reliability levels are read
        (see :func:`mean_value`).
    names_in : sequence of str, optional
        The d input names (default ``x0``, ``x1``, ...).
    names_out : sequence of str, optional
        The m response names (default ``g0``, ``g1``, ...).
    n_evaluations : int, optional
        Model evaluations that gave ``g0`` and ``grad``, reported in the result (default 0).

    Returns
    -------
    MeanValueResult
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
    distribution = _distribution(distribution)
    sg = grad * std[None, :]  # (m, d): s_i dg/dx_i
    rsg = sg @ corr.T  # (m, d): (R s g)_i
    cov_out = sg @ corr @ sg.T
    var = np.einsum("md,md->m", sg, rsg)
    sigma = np.sqrt(np.maximum(var, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        importance = np.where(var[:, None] > 0, sg * rsg / var[:, None], 0.0)

    names_out = tuple(names_out) if names_out is not None else tuple(f"g{i}" for i in range(m))
    names_in = tuple(names_in) if names_in is not None else tuple(f"x{i}" for i in range(d))
    rl, pl, bl = _levels(response_levels, probability_levels, reliability_levels, names_out)

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
    model: Model,
    space: ParameterSpace,
    *,
    response_levels: Levels = None,
    probability_levels: Levels = None,
    reliability_levels: Levels = None,
    distribution: str = "cdf",
    gradient: GradientOption = "auto",
    fd_step: float = FD_STEP,
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
    distribution : str, optional
        ``"cdf"`` (default) or ``"ccdf"``: how probability and reliability levels are read.
    gradient : "auto" (the model's analytic ``gradient`` when it has one, else central finite
        differences on one batch of 2d+1 points), "analytic", "finite_difference" or a
        callable ``g(x: (n, d)) -> (n, m, d)`` (columns in ``space.names`` order).
    fd_step : relative finite-difference step; the step of input i is
        ``fd_step * max(|mu_i|, sigma_i)`` (default :data:`rotoruq.model.FD_STEP`).

    Returns
    -------
    MeanValueResult
    """
    x0 = space.mean
    at = model_gradient(model, x0, gradient=gradient, fd_step=fd_step, scale=space.std,
                        names_in=space.names)
    if at.failures:
        raise EvaluationError(f"mean value method: {at.failures[0]}")
    return mean_value_from_gradient(
        at.values[0],
        at.gradient[0],
        space.std,
        space.correlation_matrix,
        response_levels=response_levels,
        probability_levels=probability_levels,
        reliability_levels=reliability_levels,
        distribution=distribution,
        names_in=space.names,
        names_out=tuple(model.names_out),
        n_evaluations=at.n_evaluations,
    )


# ---------------------------------------------------------------------------------------------
# MPP search: RIA (eq. 2.10) and PMA (eq. 2.11) with FORM (2.12) / SORM (2.13)
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class MPPResult:
    """Result of :func:`mpp_search` (all dicts keyed by response name).

    Forward (RIA) mapping, arrays over ``response_levels[name]``:
    ``cdf_probability`` P(g <= z) and ``ccdf_probability`` P(g > z) (the smaller of the two
    is computed directly, so a tail probability keeps its relative precision);
    ``cdf_reliability`` the FORM index beta_cdf (signed distance of the MPP) and
    ``ccdf_reliability`` = -beta_cdf; ``generalized_reliability`` -Phi^-1(p_cdf) and
    ``ccdf_generalized_reliability`` -Phi^-1(p_ccdf) (they differ from the FORM indices with
    SORM); ``mpp_u`` / ``mpp_x`` (k, d) most probable points; ``curvatures`` (k, d-1)
    principal curvatures (SORM only, else NaN).
    Inverse (PMA) mapping: ``probability_response`` / ``reliability_response`` response
    levels for ``probability_levels`` / ``reliability_levels``, read in the sense of
    ``distribution`` ("cdf": P(g <= z) = p, beta_cdf = beta; "ccdf": P(g > z) = p,
    beta_ccdf = beta; first-order, or second-order levels with
    ``integration="second_order"``); ``pma_mpp_x`` their MPPs.
    ``converged``: every RIA and PMA search met the MPP (KKT) conditions.

    Attributes
    ----------
    names_in, names_out : tuple of str
        The d input and m response names.
    integration : str
        ``"first_order"`` (FORM) or ``"second_order"`` (SORM).
    response_levels : dict of str to ndarray
        Response name -> the k levels z, response units.
    cdf_probability, ccdf_probability : dict of str to ndarray
        P(g <= z) and P(g > z) at the levels.
    cdf_reliability : dict of str to ndarray
        The FORM index beta_cdf (signed distance of the MPP) at the levels.
    generalized_reliability : dict of str to ndarray
        -Phi^-1(P(g <= z)) at the levels.
    mpp_u, mpp_x : dict of str to ndarray of shape (k, d)
        The most probable point of each level in u-space and in the inputs' units.
    curvatures : dict of str to ndarray of shape (k, d - 1)
        Principal curvatures of the limit state at each MPP (SORM only, else NaN).
    probability_levels, reliability_levels : dict of str to ndarray
        Response name -> the levels asked for.
    probability_response, reliability_response : dict of str to ndarray
        Response name -> the response level of each probability / reliability level.
    pma_mpp_x : dict of str to ndarray
        The MPPs of the PMA searches, the inputs' units.
    n_evaluations : int
        Model evaluations (points), gradients and Hessians included.
    converged : bool
        Every RIA and PMA search met the MPP (KKT) conditions.
    ccdf_reliability : dict of str to ndarray
        -beta_cdf at the levels.
    ccdf_generalized_reliability : dict of str to ndarray
        -Phi^-1(P(g > z)) at the levels.
    distribution : str
        ``"cdf"`` or ``"ccdf"``: how the probability and reliability levels were read.
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
    ccdf_reliability: dict = field(default_factory=dict)
    ccdf_generalized_reliability: dict = field(default_factory=dict)
    distribution: str = "cdf"


class DegenerateResponseError(RotoruqError, ValueError):
    """The response does not vary around the search point (constant response): no MPP."""


class SORMWarning(RuntimeWarning):
    """A second-order formula does not apply; the first-order probability is reported."""


class _UModel:
    """The model as a function of u, with batched FD gradients/Hessians.

    Points whose evaluation fails (or whose transform leaves the support) come back as NaN from
    :meth:`trial`, so that a search can shorten its step; :meth:`value_grad` needs every point
    of its stencil and raises :class:`EvaluationError` otherwise.
    """

    def __init__(self, model, space, fd_step):
        self._eval = eval_space
        self.model, self.space, self.h = model, space, fd_step
        self.n_eval = 0
        self._cache: dict = {}

    def values(self, u):
        u = np.atleast_2d(u)
        x = self.space.from_u(u)
        ok = np.all(np.isfinite(x), axis=1)
        out = np.full((u.shape[0], len(self.model.names_out)), np.nan)
        if np.any(ok):
            b = self._eval(self.model, self.space, x[ok])
            self.n_eval += int(ok.sum())
            out[ok] = b.values
        return out

    def trial(self, u, k) -> float:
        """Response k at one point, NaN when the evaluation fails."""
        v = float(self.values(u[None, :])[0, k])
        return v if np.isfinite(v) else np.nan

    def value_grad(self, u):
        key = u.tobytes()
        if key not in self._cache:
            fd = finite_difference(self.values, u, fd_step=self.h, scale=1.0)
            if fd.failures:
                raise EvaluationError(
                    f"MPP search: finite-difference stencil at u = {u} (x = "
                    f"{self.space.from_u(u)[0]}) has failed or non-finite evaluations"
                )
            if len(self._cache) > 64:
                self._cache.clear()
            self._cache[key] = (fd.values[0], fd.gradient[0], fd.steps[0])
        g, grad, _ = self._cache[key]
        return g, grad

    def flat(self, u, k) -> bool:
        """True when the FD differences of response k at u are at round-off level."""
        g, grad = self.value_grad(u)
        h = self._cache[u.tobytes()][2]
        return bool(np.all(np.abs(grad[k]) * h <= 8 * np.finfo(float).eps * max(abs(g[k]), 1e-300)))

    def tangent_hessian(self, u, k, basis):
        """Hessian of response k projected on the rows of ``basis`` ((d-1, d), orthonormal
        tangent directions at u), by central second differences along them: 2(d-1) points
        for the diagonal and 4 per pair of directions, 2(d-1)^2 in one batch (G(u) comes
        from the gradient already computed there). Only this projection enters the
        curvatures; the full 4d^2 + 1-point Hessian costs 17 points in 2-D, this 2."""
        nt = basis.shape[0]
        h = 1e3 * self.h * max(1.0, float(np.max(np.abs(u))))  # larger step: second differences
        e = basis * h
        pts = [u + e[i] for i in range(nt)] + [u - e[i] for i in range(nt)]
        pairs = [(i, j) for i in range(nt) for j in range(i + 1, nt)]
        for i, j in pairs:
            pts += [u + e[i] + e[j], u + e[i] - e[j], u - e[i] + e[j], u - e[i] - e[j]]
        v = self.values(np.array(pts))[:, k] if pts else np.empty(0)
        if not np.all(np.isfinite(v)):
            raise EvaluationError(f"SORM: Hessian stencil at u = {u} has failed evaluations")
        g0 = self.value_grad(u)[0][k]
        hm = np.diag((v[:nt] + v[nt:2 * nt] - 2.0 * g0) / h**2)
        for n, (i, j) in enumerate(pairs):
            f = v[2 * nt + 4 * n: 2 * nt + 4 * n + 4]
            hm[i, j] = hm[j, i] = (f[0] - f[1] - f[2] + f[3]) / (4 * h * h)
        return hm


#: Dakota's ``mpp_search`` options: a first-order Taylor series of the response in x or u at
#: the means (AMV) or re-expanded at every new MPP estimate (AMV+), the two-point adaptive
#: nonlinear approximation (TANA-3) through the last two MPP estimates; "none": the true model.
APPROXIMATIONS = ("none", "x_taylor_mean", "u_taylor_mean", "x_taylor_mpp", "u_taylor_mpp",
                  "x_two_point", "u_two_point")


class _TaylorU(_UModel):
    """First-order Taylor series of the true model (``truth``, a :class:`_UModel`) seen as a
    function of u, expanded at u0 in u-space (``space_x=False``) or at x(u0) in x-space; its
    evaluations cost nothing and are not counted."""

    def __init__(self, truth: _UModel, space_x: bool):
        super().__init__(truth.model, truth.space, truth.h)
        self.truth, self.space_x = truth, space_x

    def expand(self, u0: np.ndarray) -> np.ndarray:
        """Expand at u0 (2d + 1 true evaluations, one batch); returns the true values there."""
        self._cache.clear()
        self.u0 = np.asarray(u0, dtype=float)
        self.x0 = self.space.from_u(self.u0[None, :])[0]
        if self.space_x:
            key = ("x", self.u0.tobytes())  # shared by every response and level
            if key not in self.truth._cache:
                fd = finite_difference(
                    lambda x: self.truth._eval(self.model, self.space, x).values, self.x0,
                    fd_step=self.h)
                if fd.failures:
                    raise EvaluationError(f"AMV: finite-difference stencil at x = {self.x0} "
                                          "has failed or non-finite evaluations")
                self.truth.n_eval += int(fd.n_evaluations)
                self.truth._cache[key] = (fd.values[0], fd.gradient[0])
            self.g0, self.grad0 = self.truth._cache[key]
        else:
            self.g0, self.grad0 = self.truth.value_grad(self.u0)
        return self.g0

    def values(self, u):
        u = np.atleast_2d(u)
        if self.space_x:
            return self.g0[None, :] + (self.space.from_u(u) - self.x0) @ self.grad0.T
        return self.g0[None, :] + (u - self.u0) @ self.grad0.T


#: TANA exponents are bounded to +-_TANA_P_MAX (Dakota's bound; Xu and Grandhi use 5)
_TANA_P_MAX = 10.0


class _TanaU(_TaylorU):
    """Two-point adaptive nonlinear approximation TANA-3 (Xu and Grandhi 1998, Dakota's
    ``x_two_point`` / ``u_two_point``) of the true model through the last two expansion points
    y1, y2 (x or u coordinates, shifted by an offset o so that s = y + o > 0):

    ``g~(y) = g2 + sum_i dg2_i s2_i^(1 - p_i) / p_i (s_i^p_i - s2_i^p_i)
    + eps(y) / 2 sum_i (s_i^p_i - s2_i^p_i)^2``,
    ``eps(y) = H / (sum_i (s_i^p_i - s1_i^p_i)^2 + sum_i (s_i^p_i - s2_i^p_i)^2)``.

    The exponents p_i make the gradient at y1 match in each input
    (``p_i = 1 + ln(dg1_i / dg2_i) / ln(s1_i / s2_i)``), H the value at y1; g~ equals g and its
    gradient at y2 and g at y1. A response of the form ``c + sum_i a_i s_i^q_i`` is reproduced
    exactly. Before the second expansion it is the first-order Taylor series at y2. Where the
    exponents are undefined (a gradient changes sign, or y1_i = y2_i) p_i is +1 or -1, the
    one that reproduces dg1_i better. The offset is 0 where both points are positive,
    ``-2 min(y1_i, y2_i)`` where one is negative (0.1 at 0); a point evaluated below it
    lowers the offset and refits (Dakota's safeguards).
    """

    def __init__(self, truth: _UModel, space_x: bool):
        super().__init__(truth, space_x)
        self.prev: tuple | None = None

    def _y(self, u: np.ndarray) -> np.ndarray:
        return self.space.from_u(u) if self.space_x else u

    def expand(self, u0: np.ndarray) -> np.ndarray:
        if hasattr(self, "g0"):
            self.prev = (self._y(self.u0[None, :])[0], self.g0, self.grad0)
        g = super().expand(u0)
        if self.prev is not None:
            self.lo = np.minimum(self.prev[0], self._y(self.u0[None, :])[0])
            self._fit()
        return g

    def _offset(self) -> np.ndarray:
        lo = self.lo
        return np.where(np.abs(lo) < 1e-10, 0.1, np.where(lo < 0, -2.0 * lo, 0.0))

    def _fit(self) -> None:
        assert self.prev is not None
        y1, g1, dg1 = self.prev
        y2, g2, dg2 = self._y(self.u0[None, :])[0], self.g0, self.grad0
        off = self._offset()
        s1, s2 = y1 + off, y2 + off
        tiny = np.finfo(float).tiny
        with np.errstate(divide="ignore", invalid="ignore"):
            gr = np.where(np.abs(dg2) > tiny, dg1 / dg2, -1.0)  # (m, d)
            pr = np.broadcast_to(np.where(np.abs(s2) > tiny, s1 / s2, -1.0), gr.shape)
            p = 1.0 + np.log(gr) / np.log(pr)
        bad = (gr < tiny) | (pr < tiny) | (np.abs(np.log(np.abs(pr))) < tiny) | ~np.isfinite(p)
        bad |= np.abs(p) < 1e-8
        with np.errstate(divide="ignore", invalid="ignore"):
            err_minus = np.abs((s2 / s1) ** 2 * dg2 - dg1)
        p = np.where(bad, np.where(err_minus < np.abs(dg2 - dg1), -1.0, 1.0), p)
        p = np.clip(p, -_TANA_P_MAX, _TANA_P_MAX)
        self.p, self.s1, self.s2, self.off = p, s1, s2, off
        self.coef = dg2 * s2 ** (1.0 - p) / p  # (m, d)
        self.H = 2.0 * (g1 - g2 - np.sum(self.coef * (s1**p - s2**p), axis=1))
        self._cache.clear()

    def values(self, u):
        if self.prev is None:
            return super().values(u)
        y = self._y(np.atleast_2d(u))
        low = np.any(y + self.off <= 0, axis=0) & np.all(np.isfinite(y), axis=0)
        if np.any(low):
            self.lo = np.where(low, np.minimum(self.lo, y.min(axis=0)), self.lo)
            self._fit()
        s = (y + self.off)[:, None, :]  # (n, 1, d)
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            sp = s**self.p
            d1 = sp - self.s1**self.p
            d2 = sp - self.s2**self.p
            lin = np.sum(self.coef * d2, axis=2)
            q1, q2 = np.sum(d1 * d1, axis=2), np.sum(d2 * d2, axis=2)
            eps = np.where(q1 + q2 > 0, self.H / (q1 + q2), 0.0)
        return self.g0[None, :] + lin + 0.5 * eps * q2


def _approximate(truth, approximation, search, u_start, tol, max_iter, merit=None):
    """MPP by ``search(um) -> (u, converged)`` on approximations of the truth: a Taylor series
    once at u_start (AMV), or re-expanded at each new MPP estimate (AMV+; TANA through the
    last two) until the estimate moves less than sqrt(tol) max(1, |u|). Returns (u, converged,
    true response values at u or None).

    ``merit(um, u)``, given, returns the merit function phi(v, G) of the expansion point u
    (value and gradient of the truth there): a new estimate where phi has not decreased is
    replaced by a shorter move from the last accepted one (halved, one true evaluation a
    trial, until phi decreases). Plain re-expansion is a fixed-point iteration that leaves an
    MPP where the limit state curves more than the beta-sphere (the HL-RF instability); this
    is the improved HL-RF remedy, free while the full moves are accepted."""
    kind = _TanaU if approximation.endswith("_two_point") else _TaylorU
    tay = kind(truth, approximation.startswith("x_"))
    tay.expand(u_start)
    u, conv = search(tay)
    if approximation.endswith("_mean"):
        return u, conv, None
    phi, u_acc, m_acc = None, u, np.inf
    for _ in range(max_iter):
        g = tay.expand(u)
        if merit is not None:
            if phi is not None and not phi(u, g) < m_acc:
                step = 0.5 * (u - u_acc)
                for _ in range(30):
                    gt = truth.values(u_acc + step)[0]
                    if np.all(np.isfinite(gt)) and phi(u_acc + step, gt) < m_acc:
                        break
                    step = 0.5 * step
                u = u_acc + step
                continue
            phi, u_acc = merit(tay, u), u
            m_acc = phi(u, g)
        u_new, conv = search(tay)
        if np.linalg.norm(u_new - u) <= np.sqrt(tol) * max(1.0, float(np.linalg.norm(u))):
            return u, conv, g
        u = u_new
    return u, False, None


def _ria_merit(k, z):
    """``merit`` of :func:`_approximate` for RIA: 0.5 |u|^2 + c |G_k - z| with the weight c of
    the improved HL-RF iteration (:func:`_merit_weight`) at the accepted point."""

    def at(um, u):
        G, grad = um.value_grad(u)
        c = _merit_weight(u, G[k] - z, grad[k])
        return lambda v, Gv: 0.5 * float(v @ v) + c * abs(Gv[k] - z)

    return at


def _merit_weight(u, g, gv):
    """Weight c of |G - z| in the improved HL-RF merit 0.5 |u|^2 + c |G - z| at u (g = G - z,
    gv = grad G): c > |u| / |grad G| makes the HL-RF direction a descent direction."""
    gn = float(np.linalg.norm(gv))
    if gn == 0.0:
        return 0.0
    u_hl = ((gv @ u - g) / gn**2) * gv
    return 2.0 * max(float(np.linalg.norm(u)) / gn, 0.5 * float(u_hl @ u_hl) / max(abs(g), 1e-300))


def _tangent_basis(alpha):
    """Orthonormal basis (d-1, d) of the plane orthogonal to the unit vector alpha."""
    d = alpha.size
    q, _ = np.linalg.qr(np.column_stack([alpha, np.eye(d)]))
    return q[:, 1:d].T


def _probe_start(um, k, name, score):
    """Start point when the response is flat at the origin: the best of the 2d points
    u = +-e_i by ``score(value)``; raises DegenerateResponseError when all are equal."""
    d = um.space.dim
    pts = np.vstack([np.eye(d), -np.eye(d)])
    v = um.values(pts)[:, k]
    g0 = um.value_grad(np.zeros(d))[0][k]
    if np.all(np.isfinite(v)) and np.all(np.abs(v - g0) <= 8 * np.finfo(float).eps * abs(g0)):
        raise DegenerateResponseError(
            f"response {name!r} is constant (= {g0:.6g} at the input means and one standard "
            "deviation away along every input): it has no most probable point; P(g <= z) "
            "is 1 for z >= that value and 0 below"
        )
    ok = np.flatnonzero(np.isfinite(v))
    if ok.size == 0:
        raise EvaluationError(f"MPP search for {name!r}: every probe point around u = 0 failed")
    return pts[ok[np.argmin([score(v[i]) for i in ok])]]


def _ria(um, k, z, tol, max_iter, name, u_start=None):
    """min |u| subject to G(u) = z by the improved HL-RF iteration (Zhang and Der Kiureghian
    1995): the HL-RF direction, a step chosen by Armijo backtracking on the merit function
    0.5 |u|^2 + c |G - z| (c > |u| / |grad G|), non-finite trial points rejected (the step is
    halved). Converged when the MPP (KKT) conditions hold: the point is on the limit state
    (|G - z| / |grad G| <= tol max(1, |u|)) and u is parallel to grad G (the component of u
    orthogonal to grad G <= sqrt(tol) max(1, |u|)). ``u_start``: the first iterate (default
    the origin; an approximation's search starts at its expansion point, so that it finds the
    MPP of the limit state there rather than a far branch of the approximation).

    Returns (u, converged, G(0)).
    """
    d = um.space.dim
    u = np.zeros(d)
    g0 = um.value_grad(u)[0][k]
    if g0 == z:
        return u, True, g0
    if u_start is not None and np.any(u_start):
        u = np.asarray(u_start, dtype=float).copy()
    elif um.flat(u, k):
        u = _probe_start(um, k, name, lambda v: abs(v - z))
    side, probes = (1.0 if g0 > z else -1.0), 3
    for _ in range(max_iter):
        G, grad = um.value_grad(u)
        g, gv = G[k] - z, grad[k]
        gn = float(np.linalg.norm(gv))
        if gn == 0.0 or not np.isfinite(gn):
            return u, False, g0
        scale = max(1.0, float(np.linalg.norm(u)))
        perp = u - (u @ gv) / gn**2 * gv
        if abs(g) / gn <= tol * scale and np.linalg.norm(perp) <= np.sqrt(tol) * scale:
            # a KKT point may be a saddle of |u| on the limit state (symmetric responses
            # lead there from the origin): if the beta-sphere crosses the limit state near it,
            # restart from the crossing probe
            b = float(np.linalg.norm(u))
            better = (_escape_saddle(um, k, u, b, side, side * z)
                      if probes > 0 and b > 0 else None)
            if better is None:
                return u, True, g0
            probes -= 1
            u = better
            continue
        u_hl = ((gv @ u - g) / gn**2) * gv
        step = u_hl - u
        c = _merit_weight(u, g, gv)
        merit = 0.5 * (u @ u) + c * abs(g)
        slope = u @ step - c * abs(g)  # directional derivative of the merit along step
        lam, accepted = 1.0, False
        for _ in range(40):
            ut = u + lam * step
            gt = um.trial(ut, k)
            if np.isfinite(gt) and 0.5 * (ut @ ut) + c * abs(gt - z) <= merit + 1e-4 * lam * min(
                slope, 0.0
            ):
                accepted = True
                break
            lam *= 0.5
        if not accepted:
            return u, False, g0
        u = ut
    G, grad = um.value_grad(u)
    gv = grad[k]
    gn = float(np.linalg.norm(gv))
    scale = max(1.0, float(np.linalg.norm(u)))
    ok = gn > 0 and abs(G[k] - z) / gn <= tol * scale
    ok = ok and np.linalg.norm(u - (u @ gv) / gn**2 * gv) <= np.sqrt(tol) * scale
    return u, bool(ok), g0


def _pma(um, k, beta, tol, max_iter, name):
    """min G(u) (beta > 0) or max G(u) (beta < 0) on the sphere |u| = |beta|.

    Advanced-mean-value iteration (AMV+, the step Dakota's PMA takes: the next point is
    -sign |beta| grad G / |grad G|) made robust: the move follows the great circle towards
    that point and is shortened by Armijo backtracking until the response decreases, so the
    iterate never leaves the sphere and non-finite points are rejected. Converged when u is
    (anti)parallel to grad G: | u / |beta| + sign grad G / |grad G| | <= sqrt(tol), and no
    point 0.05 rad away on the sphere is better (a saddle or maximum of G on the sphere, where
    symmetric responses start, is left through the best such probe).

    Returns (u, converged).
    """
    d = um.space.dim
    b = abs(beta)
    sign = 1.0 if beta >= 0 else -1.0
    u0 = np.zeros(d)
    if um.flat(u0, k):
        u = _probe_start(um, k, name, lambda v: sign * v)
    else:
        u = -sign * um.value_grad(u0)[1][k]
    u = b * u / np.linalg.norm(u)
    probes, lam_prev = 3, 1.0
    for _ in range(max_iter):
        G, grad = um.value_grad(u)
        gv = grad[k]
        gn = float(np.linalg.norm(gv))
        if gn == 0.0:
            return u, False
        n = -sign * gv / gn
        if np.linalg.norm(u / b - n) <= np.sqrt(tol):
            better = _escape_saddle(um, k, u, b, sign, sign * G[k]) if probes > 0 else None
            if better is None:
                return u, True
            probes -= 1
            u = better
            continue
        t = n - (n @ u) / b**2 * u  # tangent component of the target direction
        tn = float(np.linalg.norm(t))
        if tn == 0.0:  # at the maximum instead of the minimum: any tangent direction
            t = _tangent_basis(u / b)[0]
            tn = 1.0
        t /= tn
        theta = float(np.arccos(np.clip(n @ u / b, -1.0, 1.0)))
        f0 = sign * G[k]
        slope = sign * b * (gv @ t)  # d f / d theta at 0 (< 0)
        lam, accepted = min(1.0, 2.0 * lam_prev), False
        for _ in range(40):
            th = lam * theta
            ut = np.cos(th) * u + np.sin(th) * b * t
            gt = um.trial(ut, k)
            if np.isfinite(gt) and sign * gt <= f0 + 1e-4 * th * min(slope, 0.0):
                accepted = True
                break
            # backtrack to the minimum of the parabola through f0, slope and f(th),
            # safeguarded to [0.1, 0.5] of the step (halving for non-finite points)
            curv = sign * gt - f0 - slope * th if np.isfinite(gt) else 0.0
            q = -slope * th * th / (2.0 * curv) / theta if curv > 0 else 0.5 * lam
            lam = min(0.5 * lam, max(0.1 * lam, q))
        if not accepted:
            return u, False
        lam_prev = lam
        u = b * ut / np.linalg.norm(ut)
    G, grad = um.value_grad(u)
    gn = float(np.linalg.norm(grad[k]))
    return u, bool(gn > 0 and np.linalg.norm(u / b + sign * grad[k] / gn) <= np.sqrt(tol))


def _escape_saddle(um, k, u, b, sign, f0, angle=0.05):
    """A stationary point of G on the sphere may be a saddle or a maximum (symmetric
    responses put the AMV start exactly there): probe +-``angle`` radians along each tangent
    direction (2(d-1) evaluations, one batch) and return the best probe if sign G is lower
    than f0 there (PMA: f0 = sign G(u); RIA: f0 = sign z, a probe beyond the limit state on
    the beta-sphere)."""
    d = u.size
    if d < 2:
        return None
    t = _tangent_basis(u / b)
    pts = np.vstack([np.cos(angle) * u + np.sin(angle) * b * t,
                     np.cos(angle) * u - np.sin(angle) * b * t])
    f = sign * um.values(pts)[:, k]
    f = np.where(np.isfinite(f), f, np.inf)
    i = int(np.argmin(f))
    if f[i] < f0 - 1e-9 * max(1.0, abs(f0)):
        return b * pts[i] / np.linalg.norm(pts[i])
    return None


def _curvatures(um, u, k, s):
    """Principal curvatures (d-1,) of the limit state through u, positive when it curves away
    from the origin; s = +1 when the origin lies on the G > z side, -1 otherwise."""
    _, grad = um.value_grad(u)
    gh = s * grad[k]  # h = s (G - z): origin on the h > 0 side
    nrm = np.linalg.norm(gh)
    basis = _tangent_basis(-gh / nrm)
    return np.linalg.eigvalsh(s * um.tangent_hessian(u, k, basis) / nrm)


def sorm_probability(beta: float, kappa: ArrayLike, sorm: str = "breitung") -> float:
    """Second-order probability of the region beyond a limit state at distance beta > 0
    with principal curvatures ``kappa`` (positive: curving away from the origin), eq. 2.13
    (Breitung) or Hohenbichler-Rackwitz (beta replaced by phi(beta)/Phi(-beta)).

    Where the asymptotic formula is undefined (a factor ``1 + c kappa_i <= 0``: the limit
    state curves towards the origin more tightly than the sphere through the MPP) a
    :class:`SORMWarning` names the curvature and the first-order probability Phi(-beta) is
    returned.
    """
    kappa = np.asarray(kappa, dtype=float)
    pf = stats.norm.cdf(-beta)
    if sorm == "breitung":
        c = beta
    elif sorm in ("hohenbichler", "hohenbichler_rackwitz"):
        c = stats.norm.pdf(beta) / pf if pf > 0 else beta
    else:
        raise ParameterError(f"SORM formula must be 'breitung' or 'hohenbichler', got {sorm!r}")
    fac = 1.0 + c * kappa
    if np.any(fac <= 0) or not np.all(np.isfinite(fac)):
        i = int(np.argmin(np.where(np.isfinite(fac), fac, -np.inf)))
        warnings.warn(
            f"SORM ({sorm}) is undefined at beta = {beta:.6g}: 1 + c kappa = {fac[i]:.3g} "
            f"<= 0 for the curvature kappa = {kappa[i]:.6g} (c = {c:.6g}; the limit state is "
            "more concave than the beta-sphere); the first-order probability is reported",
            SORMWarning,
            stacklevel=2,
        )
        return float(pf)
    return float(pf / np.sqrt(np.prod(fac)))


def _sorm_log_probability(beta, kappa, method: str) -> np.ndarray:
    """log of the SORM probability at distances ``beta`` (any shape), -inf where a factor
    1 + c kappa_i is <= 0."""
    beta = np.asarray(beta, dtype=float)
    if method == "breitung":
        c = beta
    else:
        c = np.exp(stats.norm.logpdf(beta) - stats.norm.logsf(beta))
    fac = 1.0 + c[..., None] * np.asarray(kappa, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        logfac = np.where(fac > 0, np.log(np.where(fac > 0, fac, 1.0)), np.inf)
    return stats.norm.logsf(beta) - 0.5 * np.sum(logfac, axis=-1)


def _sorm_beta(p_region: float, kappa, method: str, beta_form: float) -> float:
    """Smallest FORM distance beta whose SORM probability with curvatures ``kappa`` is
    ``p_region`` (bracketed on a grid of beta in (0, 37], then Brent); ``beta_form`` with a
    :class:`SORMWarning` when no beta reaches it (strongly concave limit states)."""
    from scipy.optimize import brentq

    target = float(np.log(p_region))

    def f(b):
        return float(_sorm_log_probability(b, kappa, method)) - target

    grid = np.linspace(1e-6, 37.0, 741)
    vals = _sorm_log_probability(grid, kappa, method) - target
    cross = np.flatnonzero((vals[:-1] > 0) & (vals[1:] <= 0) & np.isfinite(vals[1:]))
    if cross.size == 0:
        warnings.warn(
            f"SORM ({method}): no reliability index gives probability {p_region:.6g} with "
            f"curvatures {np.asarray(kappa)}; the first-order level is reported",
            SORMWarning,
            stacklevel=3,
        )
        return beta_form
    i = int(cross[0])
    return float(brentq(f, grid[i], grid[i + 1], xtol=1e-14, rtol=1e-14))


def mpp_search(
    model: Model,
    space: ParameterSpace,
    *,
    response_levels: Levels = None,
    probability_levels: Levels = None,
    reliability_levels: Levels = None,
    integration: str = "first_order",
    sorm: str = "breitung",
    fd_step: float = FD_STEP,
    tolerance: float = 1e-10,
    max_iterations: int = 200,
    approximation: str = "none",
    distribution: str = "cdf",
) -> MPPResult:
    """Most probable point searches in u-space (Nataf) with FORM or SORM integration.

    RIA (eq. 2.10): for each response level z, ``min u^T u`` subject to ``G(u) = z`` by the
    improved HL-RF iteration (merit-function line search); ``beta_cdf = +|u*|`` when
    g(mean point) > z (the region g <= z excludes the origin), else ``-|u*|``; FORM
    ``P(g <= z) = Phi(-beta_cdf)`` (2.12); SORM (2.13, Breitung or Hohenbichler-Rackwitz) with
    the principal curvatures of the limit state at the MPP from a finite-difference Hessian
    in u-space.

    PMA (eq. 2.11): for each reliability level beta (CDF sense; probability levels are turned
    into ``beta = -Phi^-1(p)``; with ``distribution="ccdf"`` both are read in the
    complementary sense, P(g > z) = p and beta_ccdf = -beta_cdf), ``min G(u)`` (beta > 0)
    or ``max G(u)`` (beta < 0) on the sphere ``u^T u = beta^2`` by AMV+ steps along great
    circles with backtracking; the optimum is the response level. With
    ``integration="second_order"`` the levels are second-order (as Dakota's PMA SORM): the
    radius is iterated until the SORM probability of the region beyond the MPP equals the
    target ``Phi(-|beta|)`` (reliability levels are then read as generalized reliability
    indices).

    Convergence is judged on the MPP conditions (see ``_ria``/``_pma``): ``tolerance`` bounds
    the relative constraint residual and ``sqrt(tolerance)`` the misalignment of u and grad G.
    A point meeting them where the beta-sphere crosses the limit state 0.05 rad away (a saddle
    of |u| on the limit state, where symmetric responses lead) is left through the crossing
    probe (2(d - 1) evaluations per level; PMA probes likewise for a saddle of G).
    ``converged`` is False when any level misses them within ``max_iterations`` iterations.

    Gradients: central finite differences in u-space, each gradient one batched model call
    of 2d + 1 points (step ``fd_step * max(1, |u_i|)``, default
    :data:`rotoruq.model.FD_STEP`; the SORM Hessian, projected on the limit state's tangent
    plane (2(d - 1)^2 points), steps 1000 times further). Raises
    :class:`DegenerateResponseError` for a response that is constant around the means.

    ``approximation`` (Dakota's ``mpp_search``): "none" searches on the model itself;
    "x_taylor_mean" / "u_taylor_mean" (AMV) search once on the first-order Taylor series of the
    response at the means in x- or u-space (one gradient of 2d + 1 evaluations for every
    level; PMA adds one true evaluation at the approximate MPP, which is the response level);
    "x_taylor_mpp" / "u_taylor_mpp" (AMV+) re-expand at each new MPP estimate until it stops
    moving (sqrt(tolerance)), 2d + 1 evaluations per expansion. AMV's probabilities are
    approximate (exact for a response linear in the expansion space); ``n_evaluations``
    counts what the approximation spent. "x_two_point" / "u_two_point" (TANA) search on the
    two-point adaptive nonlinear approximation TANA-3 through the last two MPP estimates
    (the first-order Taylor series at the means before the second), re-expanded as AMV+ until
    the estimate stops moving; same cost per expansion, fewer expansions where the response
    is nonlinear in the expansion space (exact from the second expansion on for a sum of
    powers of the inputs). RIA's SORM curvatures come from the true model at the approximate
    MPP; second-order PMA levels are only computed without approximation.

    ``distribution`` ("cdf" or "ccdf", Dakota's ``distribution cumulative / complementary``)
    says how probability and reliability levels are read; both probabilities and both
    reliability indices of the response levels are always reported.

    Parameters
    ----------
    model : Model
        Batched; its inputs are matched to ``space.names`` by name.
    space : ParameterSpace
        The uncertain inputs (correlations through the Nataf model).
    response_levels : sequence of float, mapping or sequence of sequences, optional
        Levels z (response units) mapped to probabilities and reliability indices: the same
        for every response, a mapping name -> levels, or one sequence per response.
    probability_levels : sequence of float, mapping or sequence of sequences, optional
        Probabilities in (0, 1) mapped to response levels, read in the sense of
        ``distribution``; given like ``response_levels``.
    reliability_levels : sequence of float, mapping or sequence of sequences, optional
        Reliability indices mapped to response levels, read in the sense of
        ``distribution``; given like ``response_levels``.
    integration : str, optional
        ``"first_order"`` (FORM, default) or ``"second_order"`` (SORM).
    sorm : str, optional
        The SORM formula: ``"breitung"`` (default) or ``"hohenbichler"`` (Hohenbichler-
        Rackwitz).
    fd_step : float, optional
        Relative finite-difference step in u-space (default :data:`rotoruq.model.FD_STEP`).
    tolerance : float, optional
        Convergence of the MPP conditions (default 1e-10), see above.
    max_iterations : int, optional
        Iterations per level before it is reported as not converged (default 200).
    approximation : str, optional
        ``"none"`` (default), ``"x_taylor_mean"``, ``"u_taylor_mean"``, ``"x_taylor_mpp"``,
        ``"u_taylor_mpp"``, ``"x_two_point"`` or ``"u_two_point"``, see above.
    distribution : str, optional
        ``"cdf"`` (default: P(g <= z) and beta_cdf) or ``"ccdf"`` (P(g > z) and beta_ccdf):
        how probability and reliability levels are read (Dakota's ``distribution
        cumulative / complementary``).

    Returns
    -------
    MPPResult

    Examples
    --------
    >>> import rotoruq as rq
    >>> sp = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Normal(0, 1)})
    >>> m = rq.FunctionModel(lambda x: 3.0 - x[:, 0] - x[:, 1], ["a", "b"], ["g"])
    >>> r = mpp_search(m, sp, response_levels=[0.0], approximation="u_taylor_mean")
    >>> round(float(r.cdf_reliability["g"][0]), 8), r.n_evaluations  # 3 / sqrt(2)
    (2.12132034, 5)
    """
    tol, max_iter = tolerance, max_iterations
    distribution = _distribution(distribution)
    integration = integration.lower()
    if integration not in ("first_order", "second_order", "form", "sorm"):
        raise ParameterError(
            f"integration must be 'first_order' or 'second_order', got {integration!r}"
        )
    if sorm not in ("breitung", "hohenbichler", "hohenbichler_rackwitz"):
        raise ParameterError(f"SORM formula must be 'breitung' or 'hohenbichler', got {sorm!r}")
    if not (tol > 0 and int(max_iter) >= 1):
        raise ParameterError(f"tolerance must be > 0 and max_iterations >= 1, got {tol!r}, "
                             f"{max_iter!r}")
    if approximation not in APPROXIMATIONS:
        raise ParameterError(f"approximation must be one of {APPROXIMATIONS}, got "
                             f"{approximation!r}")
    second = integration in ("second_order", "sorm")
    if second and approximation != "none" and (probability_levels is not None
                                                or reliability_levels is not None):
        raise ParameterError("second-order PMA levels need the true model's MPPs: use "
                             "approximation='none' with probability or reliability levels "
                             "and integration='second_order'")
    names_out = tuple(model.names_out)
    d = space.dim
    um = _UModel(model, space, fd_step)
    rl, pl, bl = _levels(response_levels, probability_levels, reliability_levels, names_out)
    out: dict[str, dict] = {k: {} for k in ("p", "pc", "b", "gb", "mu", "mx", "kap", "pr", "br",
                                            "pmx")}
    ok = True
    for k, name in enumerate(names_out):
        zs = rl[name]
        n = zs.size
        p_cdf, p_ccdf, b_cdf = np.empty(n), np.empty(n), np.empty(n)
        mu, kap = np.empty((n, d)), np.full((n, max(d - 1, 0)), np.nan)
        for j, z in enumerate(zs):
            if approximation == "none":
                u, conv, gmean = _ria(um, k, z, tol, max_iter, name)
            else:
                res_ria: list = []

                def ria_search(sur, k=k, z=z, res_ria=res_ria, name=name):
                    u, conv, g0 = _ria(sur, k, z, tol, max_iter, name, u_start=sur.u0)
                    res_ria.append(g0)
                    return u, conv

                u, conv, _ = _approximate(um, approximation, ria_search, _u_start(space),
                                          tol, max_iter, merit=_ria_merit(k, z))
                gmean = res_ria[0]  # the first expansion is at the means
            ok &= conv
            if not conv:
                _not_converged("RIA", name, f"response level {z:.6g}", um, u, k, z)
            beta = float(np.linalg.norm(u))
            s = 1.0 if gmean > z else -1.0
            b_cdf[j] = s * beta
            p_region = stats.norm.cdf(-beta)
            if second and d > 1 and beta > 0:
                kap[j] = _curvatures(um, u, k, s)
                p_region = sorm_probability(beta, kap[j], sorm)
            # the region beyond the limit state is the CDF side when it excludes the origin
            p_cdf[j], p_ccdf[j] = (p_region, 1.0 - p_region) if s > 0 else (1.0 - p_region,
                                                                             p_region)
            mu[j] = u
        gbeta = np.where(p_cdf < 0.5, stats.norm.isf(p_cdf), -stats.norm.isf(p_ccdf))
        out["p"][name], out["pc"][name] = p_cdf, p_ccdf
        out["b"][name], out["gb"][name] = b_cdf, gbeta
        out["mu"][name], out["kap"][name] = mu, kap
        out["mx"][name] = space.from_u(mu) if n else np.empty((0, d))
        # PMA searches take CDF indices: a CCDF level beta_ccdf is beta_cdf = -beta_ccdf
        sense = 1.0 if distribution == "cdf" else -1.0
        levels = {"pr": sense * stats.norm.isf(pl[name]), "br": sense * bl[name]}
        pmx = []
        for key, betas in levels.items():
            zz = np.empty(betas.size)
            for j, beta in enumerate(betas):
                if approximation == "none":
                    u, conv = _pma_level(um, k, float(beta), second, sorm, tol, max_iter, name)
                    gu = None
                else:
                    u, conv, gu = _approximate(
                        um, approximation,
                        lambda sur, k=k, beta=beta, name=name: _pma_level(
                            sur, k, float(beta), False, sorm, tol, max_iter, name),
                        _u_start(space), tol, max_iter)
                ok &= conv
                if not conv:
                    _not_converged("PMA", name, f"reliability index {beta:.6g}", um, u, k)
                if gu is None and approximation != "none":
                    gu = um.values(u[None, :])[0]  # AMV: one true evaluation at the MPP
                zz[j] = gu[k] if gu is not None else um.value_grad(u)[0][k]
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
        ccdf_reliability={k: -v for k, v in out["b"].items()},
        ccdf_generalized_reliability={k: -v for k, v in out["gb"].items()},
        distribution=distribution,
    )


def _not_converged(kind, name, level, um, u, k, z=None):
    g, grad = um.value_grad(u)
    detail = f"|u| = {np.linalg.norm(u):.6g}"
    if z is not None:
        gn = np.linalg.norm(grad[k])
        detail += ", distance to the limit state |G - z| / |grad G| = " + (
            f"{abs(g[k] - z) / gn:.3g}" if gn > 0 else "inf (flat response)")
    warnings.warn(
        f"MPP search ({kind}) for {name!r} at {level} did not meet the MPP conditions within "
        f"max_iterations ({detail}): its result is not reliable (the level may be unreachable)",
        RuntimeWarning,
        stacklevel=3,
    )


def _u_start(space):
    """u of the input means (the expansion point of AMV and AMV+)."""
    return space.to_u(np.asarray(space.mean, dtype=float)[None, :])[0]


def _pma_level(um, k, beta, second, sorm, tol, max_iter, name):
    """PMA point for the (generalized, with SORM) CDF reliability index ``beta``."""
    d = um.space.dim
    if beta == 0:
        return np.zeros(d), True
    u, conv = _pma(um, k, beta, tol, max_iter, name)
    if not (second and d > 1):
        return u, conv
    s = 1.0 if beta > 0 else -1.0
    target = stats.norm.cdf(-abs(beta))  # probability of the region beyond the limit state
    radius = abs(beta)
    for _ in range(30):
        kap = _curvatures(um, u, k, s)
        new = _sorm_beta(target, kap, sorm, abs(beta))
        if abs(new - radius) <= 1e-9 * max(1.0, radius):
            return u, conv
        radius = new
        u, conv = _pma(um, k, s * radius, tol, max_iter, name)
    return u, False
