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
