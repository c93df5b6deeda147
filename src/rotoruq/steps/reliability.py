"""Step type ``reliability``: MPP search (RIA for response levels, PMA for probability
levels) with first- or second-order integration."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..render.tables import StepTable
from ..results import StepResult
from ._common import (
    LEVEL_OPTIONS,
    LevelsRecord,
    MappingsRecord,
    check_levels,
    level_request_of,
    levels_arrays,
    mapping_fields,
)
from .base import StepContext, StepType
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
class ReliabilityRecord(LevelsRecord, MappingsRecord):
    """What a reliability step saves: the :class:`~rotoruq.steps._common.LevelsRecord` of
    :data:`QUANTITIES` (RIA: response levels and their CDF probability, reliability and
    generalized reliability; PMA: probability levels and their response), and with
    ``distribution = "ccdf"`` the :data:`CCDF_QUANTITIES` too (probability levels are then
    read as P(g > z)); and the level mappings as Dakota prints them
    (:class:`~rotoruq.steps._common.MappingsRecord`: every column of every row)."""

    AXES = {**LevelsRecord.AXES, **MappingsRecord.AXES}


def mpp_mappings(res, request):
    """The :class:`~rotoruq.methods.levels.LevelMappings` of an MPP search ``res`` run on
    ``request``'s levels (reliability levels, then generalized ones, as its reliability
    levels): each row's response level, probability, reliability index (the signed MPP
    distance of a response level; the level's own index otherwise) and generalized
    reliability index, in the sense of ``request.distribution``."""
    from scipy import stats

    from ..methods.levels import LevelMappings

    cdf = request.distribution == "cdf"
    table, kinds = {}, {}
    for r in request.names_out:
        z = np.asarray(res.response_levels[r], dtype=float)
        p = np.asarray(res.cdf_probability[r] if cdf else res.ccdf_probability[r])
        b = np.asarray(res.cdf_reliability[r] if cdf else res.ccdf_reliability[r])
        g = np.asarray(res.generalized_reliability[r] if cdf
                       else res.ccdf_generalized_reliability[r])
        pl = np.asarray(res.probability_levels[r], dtype=float)
        bl = np.asarray(res.reliability_levels[r], dtype=float)
        rows = [np.column_stack([z, p, b, g]),
                np.column_stack([res.probability_response[r], pl, -stats.norm.ppf(pl),
                                 -stats.norm.ppf(pl)]),
                np.column_stack([res.reliability_response[r], stats.norm.cdf(-bl), bl, bl])]
        n_rel = request.levels["reliability"][r].size
        kind = np.concatenate([np.zeros(z.size, int), np.ones(pl.size, int),
                               np.full(n_rel, 2), np.full(bl.size - n_rel, 3)])
        table[r] = np.vstack([x.reshape(-1, 4) for x in rows])
        kinds[r] = kind
    return LevelMappings(request.names_out, request.distribution, request.compute, table,
                         kinds)


def run_reliability(ctx: StepContext) -> StepResult:
    """MPP search (RIA for response levels, PMA for probability, reliability and generalized
    reliability levels) with FORM/SORM."""
    from ..methods.reliability import mpp_search

    o = ctx.options
    request = level_request_of(ctx)
    lv = request.levels if request is not None else None
    rel = None if lv is None else {
        r: np.concatenate([lv["reliability"][r], lv["gen_reliability"][r]])
        for r in ctx.responses}
    res = mpp_search(ctx.model(), ctx.space,
                     response_levels=None if lv is None else lv["response"],
                     probability_levels=None if lv is None else lv["probability"],
                     reliability_levels=rel,
                     integration=o["integration"], approximation=o["approximation"],
                     distribution=o["distribution"])
    quantities = QUANTITIES + (CCDF_QUANTITIES if o["distribution"] == "ccdf" else ())
    mappings = None if request is None else mpp_mappings(res, request)
    record = ReliabilityRecord(tuple(ctx.responses), quantities,
                               *levels_arrays(res, quantities, ctx.responses),
                               **mapping_fields(mappings))
    arrays, meta = record.parts()
    return StepResult(ctx.name, ctx.type, {}, arrays, meta={
        "n_evaluations": int(getattr(res, "n_evaluations", 0)), **meta})


def reliability_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    rec = ReliabilityRecord.read(res)
    return [*rec.tables("Reliability (MPP search)"), *rec.mapping_tables(rec.names_out)]


STEP = StepType(
    "reliability", run_reliability, method="rotoruq.methods.reliability:mpp_search",
    correlated=True,
    options={"integration": Option(choice("first_order", "second_order"), SIGNATURE),
             "approximation": Option(choice(*APPROXIMATIONS), SIGNATURE),
             **LEVEL_OPTIONS},
    check=check_levels, tables=reliability_tables, modules=("rotoruq.methods.levels",))
