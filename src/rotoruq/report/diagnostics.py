"""What a saved step says about its own trustworthiness, computed from the step's scalars.

:func:`step_warnings` lists the diagnostics a reader must know before believing a step's
numbers: its type's ``warnings`` renderer (MCMC convergence, emulator quality,
identifiability, prior-bound pile-up and a posterior far from its prior in
:mod:`rotoruq.steps.bayes_calibration`; Sobol indices of a response with negligible variance
in :mod:`rotoruq.steps.sensitivity`; ...). The claims of the report, its step tables,
``rotoruq show`` and the terminal summary of ``rotoruq run`` all use it, so they always agree.
The thresholds (:data:`THRESHOLDS`) are stated in the report.
"""

from __future__ import annotations

from collections.abc import Mapping

from ..results import StepResult
from ..steps.bayes_calibration import (
    CORR_MAX,
    ESS_MIN,
    LOO_Q2_MIN,
    PILEUP_MAX,
    PRIOR_Z_MAX,
    RHAT_MAX,
    STD_RATIO_MAX,
    THRESHOLDS,
    strong_correlations,
)
from .hooks import rendering

__all__ = ["step_warnings", "strong_correlations", "THRESHOLDS", "ESS_MIN", "RHAT_MAX",
           "LOO_Q2_MIN", "PILEUP_MAX", "STD_RATIO_MAX", "PRIOR_Z_MAX", "CORR_MAX"]


def step_warnings(res: StepResult, labels: Mapping[str, str] | None = None) -> list[str]:
    """Warnings computed from one saved step (empty when it has nothing to flag): its type's
    ``warnings`` renderer (:mod:`rotoruq.report.hooks`)."""
    hook = rendering(res.type).warnings
    return hook(res, labels or {}) if hook is not None else []
