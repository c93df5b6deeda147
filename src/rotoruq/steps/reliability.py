"""Step type ``reliability``: MPP search (RIA for response levels, PMA for probability
levels) with first- or second-order integration."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..render.tables import StepTable, levels_tables
from ..results import StepResult
from .base import StepContext, StepType
from .mean_value import LEVELS
from .options import SIGNATURE, Option, choice

__all__ = ["STEP", "run_reliability", "reliability_tables", "APPROXIMATIONS"]

#: ``mpp_search(approximation=)``'s choices (methods.reliability.APPROXIMATIONS; spelled out
#: so that importing the step types does not import the method and scipy.stats)
APPROXIMATIONS = ("none", "x_taylor_mean", "u_taylor_mean", "x_taylor_mpp", "u_taylor_mpp")


def run_reliability(ctx: StepContext) -> StepResult:
    """MPP search (RIA for response levels, PMA for probability levels) with FORM/SORM."""
    from ..methods.reliability import mpp_search

    o = ctx.options
    res = mpp_search(ctx.model(), ctx.space, response_levels=o.get("response_levels"),
                     probability_levels=o.get("probability_levels"),
                     integration=o["integration"], approximation=o["approximation"])
    scalars = {}
    for r in ctx.responses:
        for what in ("response_levels", "cdf_probability", "cdf_reliability",
                     "generalized_reliability", "probability_levels", "probability_response"):
            vals = getattr(res, what, {}).get(r)
            if vals is not None:
                for i, v in enumerate(np.atleast_1d(vals)):
                    scalars[f"{what}/{r}/{i}"] = float(v)
    return StepResult(ctx.name, ctx.type, scalars, meta={
        "n_evaluations": int(getattr(res, "n_evaluations", 0))})


def reliability_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    return levels_tables(res, ("response_levels", "cdf_probability", "cdf_reliability",
                               "generalized_reliability", "probability_levels",
                               "probability_response"), "Reliability (MPP search)")


STEP = StepType(
    "reliability", run_reliability, method="rotoruq.methods.reliability:mpp_search",
    options={"integration": Option(choice("first_order", "second_order"), SIGNATURE),
             "approximation": Option(choice(*APPROXIMATIONS), SIGNATURE),
             **LEVELS},
    tables=reliability_tables)
