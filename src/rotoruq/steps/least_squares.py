"""Step type ``least_squares``: deterministic calibration (NL2SOL, or scipy's trf / lm) of the
inputs to data; hands on normals at the optimum with the linearised std."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..params import Normal
from ..render.tables import StepTable, label, make_table
from ..results import StepRecord, StepResult, dist_to_dict
from ._common import per_response
from .base import StepContext, StepType
from .options import SIGNATURE, Option, choice, integer, number, number_or_table

__all__ = ["STEP", "LeastSquaresRecord", "run_least_squares", "least_squares_tables",
           "least_squares_warnings", "LEAST_SQUARES"]

LEAST_SQUARES = "rotoruq.methods.least_squares:least_squares"


@dataclass(frozen=True, eq=False)
class LeastSquaresRecord(StepRecord):
    """What a least-squares step saves: d calibrated inputs.

    names_in (d); x (d,) the optimum; std (d,) its linearised std; residuals (k, m) the
    residuals there, per experiment and response; cost (of the scaled residuals); converged,
    message.
    """

    AXES = {"x": ("input",), "std": ("input",), "residuals": ("experiment", "response")}

    names_in: tuple[str, ...]
    x: np.ndarray
    std: np.ndarray
    residuals: np.ndarray
    cost: float
    converged: bool
    message: str


def run_least_squares(ctx: StepContext) -> StepResult:
    from ..methods.least_squares import calibrate

    o = ctx.options
    sd = per_response(o.get("noise_std"), ctx.responses)
    res = calibrate(
        ctx.model(), ctx.observations(), ctx.space, noise_std=sd,
        optimizer=o["optimizer"], max_iterations=o["max_iterations"],
        max_function_evaluations=o["max_function_evaluations"],
        tolerance=o["tolerance"],
    )
    scalars = {}
    calibrated = {}
    for j, p in enumerate(res.names_in):
        scalars[f"value/{p}"] = float(res.x[j])
        s = float(res.std[j])
        scalars[f"std/{p}"] = s
        sd_p = s if np.isfinite(s) and s > 0 else ctx.space[p].std
        calibrated[p] = dist_to_dict(Normal(float(res.x[j]), sd_p))
    scalars["cost"] = float(res.cost)
    record = LeastSquaresRecord(tuple(res.names_in), np.asarray(res.x, dtype=float),
                                np.asarray(res.std, dtype=float), np.asarray(res.residuals),
                                float(res.cost), bool(res.converged), str(res.message))
    arrays, meta = record.parts()
    return StepResult(ctx.name, ctx.type, scalars, arrays, calibrated, meta={
        "n_evaluations": int(res.n_evaluations), "converged": bool(res.converged),
        "message": res.message, **meta})


def least_squares_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    rec = LeastSquaresRecord.read(res)
    return [make_table("Calibrated parameters (least squares)", ("parameter", "value", "std"),
                       [[label(p, labels), float(rec.x[j]), float(rec.std[j])]
                        for j, p in enumerate(rec.names_in)],
                       f"Cost {rec.cost:.6g}; {rec.message}")]


def least_squares_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    """A least-squares calibration that did not converge."""
    if res.meta.get("converged") is False:
        return [f"{res.name}: least squares did not converge ({res.meta.get('message', '')})"]
    return []


STEP = StepType(
    "least_squares", run_least_squares, method=LEAST_SQUARES,
    provides=("calibrated",), needs_data=True,
    options={"optimizer": Option(choice("nl2sol", "trf", "lm"), SIGNATURE),
             "max_iterations": Option(integer(1), SIGNATURE),
             "max_function_evaluations": Option(integer(1), SIGNATURE),
             "tolerance": Option(number(positive=True, allow_zero=False), SIGNATURE),
             "noise_std": Option(number_or_table, None)},
    tables=least_squares_tables, warnings=least_squares_warnings)
