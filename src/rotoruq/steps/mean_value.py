"""Step type ``mean_value``: first-order mean and std of each response from the gradient at
the input means, and each input's importance factor."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..render.tables import StepTable, label, make_table, parameters, responses, value
from ..results import StepResult
from ._common import input_scalars
from .base import StepContext, StepType
from .options import SIGNATURE, Option, table

__all__ = ["STEP", "run_mean_value", "mean_value_tables", "LEVELS"]

#: The ``response_levels`` / ``probability_levels`` options (mean value, reliability).
LEVELS = {"response_levels": Option(table, SIGNATURE),
          "probability_levels": Option(table, SIGNATURE)}


def run_mean_value(ctx: StepContext) -> StepResult:
    from ..methods.reliability import mean_value

    o = ctx.options
    res = mean_value(ctx.model(), ctx.space, response_levels=o.get("response_levels"),
                     probability_levels=o.get("probability_levels"))
    scalars = {}
    for k, r in enumerate(ctx.responses):
        scalars[f"mean/{r}"] = float(res.mean[k])
        scalars[f"std/{r}"] = float(res.std[k])
        for j, p in enumerate(ctx.space.names):
            scalars[f"importance/{r}/{p}"] = float(res.importance[k, j])
    scalars.update(input_scalars(ctx.space))
    return StepResult(ctx.name, ctx.type, scalars, {"gradient": np.asarray(res.gradient)},
                      meta={"n_evaluations": int(res.n_evaluations)})


def mean_value_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    resp, inputs = responses(res), parameters(res)
    return [make_table("Mean value method (first order)", ("response", "mean", "std"),
                       [[r, value(res, f"mean/{r}"), value(res, f"std/{r}")] for r in resp]),
            make_table("Importance factors", ("input", *resp),
                       [[label(p, labels), *[value(res, f"importance/{r}/{p}") for r in resp]]
                        for p in inputs], "Share of each input in the first-order variance.")]


STEP = StepType(
    "mean_value", run_mean_value, method="rotoruq.methods.reliability:mean_value",
    options=dict(LEVELS), tables=mean_value_tables)
