"""Step type ``reliability``: MPP search (RIA for response levels, PMA for probability
levels) with first- or second-order integration."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from ..render.tables import StepTable
from ..results import StepResult
from ._common import LevelsRecord, levels_arrays
from .base import StepContext, StepType
from .mean_value import LEVELS
from .options import SIGNATURE, Option, choice

__all__ = ["STEP", "ReliabilityRecord", "run_reliability", "reliability_tables",
           "APPROXIMATIONS", "QUANTITIES", "CCDF_QUANTITIES"]

#: ``mpp_search(approximation=)``'s choices (methods.reliability.APPROXIMATIONS; spelled out
#: so that importing the step types does not import the method and scipy.stats)
APPROXIMATIONS = ("none", "x_taylor_mean", "u_taylor_mean", "x_taylor_mpp", "u_taylor_mpp",
                  "x_two_point", "u_two_point")

#: The per-level quantities a reliability step saves (attributes of the method's result).
QUANTITIES = ("response_levels", "cdf_probability", "cdf_reliability", "generalized_reliability",
              "probability_levels", "probability_response")
#: What ``distribution = "ccdf"`` adds: the complementary probability and reliabilities.
CCDF_QUANTITIES = ("ccdf_probability", "ccdf_reliability", "ccdf_generalized_reliability")


@dataclass(frozen=True, eq=False)
class ReliabilityRecord(LevelsRecord):
    """What a reliability step saves: the :class:`~rotoruq.steps._common.LevelsRecord` of
    :data:`QUANTITIES` (RIA: response levels and their CDF probability, reliability and
    generalized reliability; PMA: probability levels and their response), and with
    ``distribution = "ccdf"`` the :data:`CCDF_QUANTITIES` too (probability levels are then
    read as P(g > z))."""


def run_reliability(ctx: StepContext) -> StepResult:
    """MPP search (RIA for response levels, PMA for probability levels) with FORM/SORM."""
    from ..methods.reliability import mpp_search

    o = ctx.options
    res = mpp_search(ctx.model(), ctx.space, response_levels=o.get("response_levels"),
                     probability_levels=o.get("probability_levels"),
                     integration=o["integration"], approximation=o["approximation"],
                     distribution=o["distribution"])
    quantities = QUANTITIES + (CCDF_QUANTITIES if o["distribution"] == "ccdf" else ())
    record = ReliabilityRecord(tuple(ctx.responses), quantities,
                               *levels_arrays(res, quantities, ctx.responses))
    arrays, meta = record.parts()
    return StepResult(ctx.name, ctx.type, record.scalars(), arrays, meta={
        "n_evaluations": int(getattr(res, "n_evaluations", 0)), **meta})


def reliability_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    return ReliabilityRecord.read(res).tables("Reliability (MPP search)")


STEP = StepType(
    "reliability", run_reliability, method="rotoruq.methods.reliability:mpp_search",
    correlated=True,
    options={"integration": Option(choice("first_order", "second_order"), SIGNATURE),
             "approximation": Option(choice(*APPROXIMATIONS), SIGNATURE),
             "distribution": Option(choice("cdf", "ccdf"), SIGNATURE),
             **LEVELS},
    tables=reliability_tables)
