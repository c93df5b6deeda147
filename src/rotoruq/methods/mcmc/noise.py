"""Noise calibrated with the parameters: multipliers on the noise variance (Dakota's
``calibrate_error_multipliers``).

Each observation's stated noise variance ``V_ej`` is multiplied by ``lambda_g`` of its group
``g``: one multiplier for all (``"one"``), one per response (``"per_response"``), one per
experiment (``"per_experiment"``), or one per named response (the others keep their stated
noise). The prior of each multiplier is Dakota's, an inverse gamma with shape ``alpha`` and
scale ``beta`` (density ``~ lambda^-(alpha+1) exp(-beta / lambda)``); rotoruq's default is
``alpha = beta = 1`` (weak: median 1.44, the data decide), where Dakota's defaults are
tighter. The chains sample the precision multiplier ``tau = 1 / lambda``, whose prior is then
a :class:`~rotoruq.params.Gamma` with shape ``alpha`` and scale ``1 / beta`` (the same prior,
a density the samplers already evaluate); results report ``lambda``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ...errors import ParameterError
from ...params import Gamma, ParameterSpace

__all__ = ["MULTIPLIER_MODES", "multiplier_groups", "extended_prior", "noise_loglik"]

MULTIPLIER_MODES = ("one", "per_response", "per_experiment")


def multiplier_groups(mode: str | Sequence[str], names_out: tuple[str, ...],
                      n_exp: int) -> tuple[np.ndarray, tuple[str, ...]]:
    """Group of each observation (n_exp, m) (-1: no multiplier) and the multipliers' names."""
    m = len(names_out)
    if isinstance(mode, str):
        if mode == "one":
            return np.zeros((n_exp, m), np.int64), ("noise_multiplier",)
        if mode == "per_response":
            return (np.broadcast_to(np.arange(m), (n_exp, m)).astype(np.int64),
                    tuple(f"noise_multiplier:{r}" for r in names_out))
        if mode == "per_experiment":
            return (np.broadcast_to(np.arange(n_exp)[:, None], (n_exp, m)).astype(np.int64),
                    tuple(f"noise_multiplier:experiment_{e}" for e in range(n_exp)))
        raise ParameterError(f"noise_multipliers must be one of {MULTIPLIER_MODES} or a list of "
                             f"observed responses, got {mode!r}")
    names = list(mode)
    if not names:
        raise ParameterError("noise_multipliers: an empty list of responses")
    missing = [r for r in names if r not in names_out]
    if missing:
        raise ParameterError(f"noise_multipliers on responses {missing} that have no data: the "
                             f"calibrated (observed) responses are {list(names_out)}")
    if len(set(names)) != len(names):
        raise ParameterError(f"noise_multipliers names a response twice: {names}")
    g = np.full((n_exp, m), -1, np.int64)
    for k, r in enumerate(names):
        g[:, names_out.index(r)] = k
    return g, tuple(f"noise_multiplier:{r}" for r in names)


def extended_prior(prior: ParameterSpace, names: tuple[str, ...], alpha: float,
                   beta: float) -> ParameterSpace:
    """The parameters' prior and, after them, one Gamma(alpha, scale 1/beta) precision
    multiplier per name (independent of the parameters)."""
    if not (np.isfinite(alpha) and np.isfinite(beta) and alpha > 0 and beta > 0):
        raise ParameterError(f"noise_multiplier_prior (alpha, beta) must be > 0, got "
                             f"({alpha!r}, {beta!r})")
    clash = [n for n in names if n in prior.names]
    if clash:
        raise ParameterError(f"parameter names {clash} clash with the noise multipliers")
    d, k = prior.dim, len(names)
    corr = None
    if prior.correlation is not None:
        corr = np.eye(d + k)
        corr[:d, :d] = prior.correlation
    items = list(zip(prior.names, prior.distributions, strict=True))
    items += [(n, Gamma(float(alpha), 1.0 / float(beta))) for n in names]
    return ParameterSpace(items, correlation=corr)


def noise_loglik(q: np.ndarray, var_emu: np.ndarray | None, tau: np.ndarray, data: np.ndarray,
                 noise_var: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """Log-likelihood (k,) of responses q (k, m) with precision multipliers tau (k, g).

    Observation (e, j) has variance ``noise_var[e, j] / tau[groups[e, j]]`` (stated variance
    where the group is -1); with ``var_emu`` (k, m), an emulator error of that variance per
    response shared by all experiments is integrated out (as in
    :meth:`.likelihood.GaussianLikelihood.__call__`):
    ``-1/2 [sum_e w_ej (d_ej - q_j)^2 - P_j^2 s_j (dbar_j - q_j)^2 / (1 + P_j s_j)
    + log(1 + P_j s_j)] + 1/2 sum log(w / 2 pi)`` with ``w`` the observation precisions,
    ``P_j = sum_e w_ej`` and ``dbar_j`` their weighted data mean.
    """
    t = np.concatenate([tau, np.ones((tau.shape[0], 1))], axis=1)  # group -1 -> factor 1
    w = t[:, groups] / noise_var[None]  # (k, E, m)
    r = data[None] - q[:, None, :]
    acc = (w * r * r).sum((1, 2)) - np.log(w / (2.0 * np.pi)).sum((1, 2))
    if var_emu is not None:
        P = w.sum(1)
        dq = (w * data[None]).sum(1) / P - q
        a = 1.0 + P * var_emu
        acc += (np.log(a) - P * P * var_emu * dq * dq / a).sum(1)
    return -0.5 * acc
