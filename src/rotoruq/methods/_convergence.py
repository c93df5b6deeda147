"""The convergence numbers of a set of Markov chains, shared by
:class:`~rotoruq.methods.mcmc.diagnostics.ChainDiagnostics` and the Bayes step's record (a
module of its own, light to import: the step types import it without the samplers)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ChainConvergence"]


@dataclass(frozen=True, eq=False)
class ChainConvergence:
    """Convergence diagnostics of one set of chains, each (d,) per parameter.

    Attributes
    ----------
    rhat_bulk, rhat_folded : ndarray
        Rank-normalised split R-hat of the draws and of their distance to the median
        (dimensionless).
    ess_bulk, ess_tail : ndarray
        Effective sample sizes of the bulk and of the 5 % / 95 % tails (draws).
    mcse_mean, mcse_q05, mcse_q95 : ndarray
        Monte Carlo standard errors of the mean and of the 5 % and 95 % quantiles (units of
        the draws).
    """

    rhat_bulk: np.ndarray
    rhat_folded: np.ndarray
    ess_bulk: np.ndarray
    ess_tail: np.ndarray
    mcse_mean: np.ndarray
    mcse_q05: np.ndarray
    mcse_q95: np.ndarray
