"""Step type ``mean_value``: first-order mean and std of each response from the gradient at
the input means, and each input's importance factor."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..render.tables import StepTable, label, make_table
from ..results import StepResult
from ._common import (
    LEVEL_OPTIONS,
    MappingsRecord,
    check_levels,
    level_request_of,
    mapping_fields,
)
from .base import StepContext, StepType

__all__ = ["STEP", "MeanValueRecord", "run_mean_value", "mean_value_tables"]


@dataclass(frozen=True, eq=False)
class MeanValueRecord(MappingsRecord):
    """What a mean-value step saves: m responses, d inputs.

    names_in (d), names_out (m); mean, std (m,) first-order moments; importance (m, d) each
    input's share of the first-order variance; gradient (m, d) at the input means; the level
    mappings (:class:`~rotoruq.steps._common.MappingsRecord`) through the normal of those
    moments, every column of every row (Dakota's mean value method).
    """

    AXES = {"mean": ("response",), "std": ("response",), "importance": ("response", "input"),
            "gradient": ("response", "input"), **MappingsRecord.AXES}
    FLAT = {"gradient": None, **MappingsRecord.FLAT}

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    mean: np.ndarray
    std: np.ndarray
    importance: np.ndarray
    gradient: np.ndarray


def run_mean_value(ctx: StepContext) -> StepResult:
    from ..methods.levels import moment_mappings
    from ..methods.reliability import mean_value

    res = mean_value(ctx.model(), ctx.space)
    request = level_request_of(ctx)
    mappings = None if request is None else moment_mappings(res.mean, res.std, request)
    record = MeanValueRecord(tuple(ctx.space.names), tuple(ctx.responses),
                             np.asarray(res.mean, dtype=float), np.asarray(res.std, dtype=float),
                             np.asarray(res.importance, dtype=float), np.asarray(res.gradient),
                             **mapping_fields(mappings))
    arrays, meta = record.parts()
    return StepResult(ctx.name, ctx.type, {}, arrays,
                      meta={"n_evaluations": int(res.n_evaluations), **meta})


def mean_value_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    rec = MeanValueRecord.read(res)
    return [make_table("Mean value method (first order)", ("response", "mean", "std"),
                       [[r, float(rec.mean[k]), float(rec.std[k])]
                        for k, r in enumerate(rec.names_out)]),
            make_table("Importance factors", ("input", *rec.names_out),
                       [[label(p, labels), *[float(v) for v in rec.importance[:, j]]]
                        for j, p in enumerate(rec.names_in)],
                       "Share of each input in the first-order variance."),
            *rec.mapping_tables(rec.names_out, "Through the normal of the first-order mean "
                                "and std (Dakota's mean value method).")]


STEP = StepType(
    "mean_value", run_mean_value, method="rotoruq.methods.reliability:mean_value",
    options=dict(LEVEL_OPTIONS), check=check_levels, tables=mean_value_tables,
    modules=("rotoruq.methods.levels",), correlated=True)
