"""Step type ``least_squares``: deterministic calibration (NL2SOL, or scipy's trf / lm) of the
inputs to data; hands on normals at the optimum with the linearised std.

Without a data set in the study, the model's responses ARE the residuals (Dakota's
``calibration_terms`` with no calibration data file) and ``1/2 sum_i w_i r_i^2`` is driven
toward zero. ``x0 = {param = value}`` is the initial point (Dakota's ``initial_point``;
default: the means of the distributions), anywhere within each parameter's bounds (the
support of its distribution, which also bounds the search); ``residual_weights`` are Dakota's
calibration-term ``weights`` (``w_i`` multiplies the squared residual)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from ..params import Normal
from ..render.tables import StepTable, label, make_table
from ..results import StepRecord, StepResult, dist_to_dict
from ._common import per_response
from .base import StepContext, StepType
from .options import SIGNATURE, Option, choice, close_hint, integer, number, number_or_table

__all__ = ["STEP", "LeastSquaresRecord", "run_least_squares", "least_squares_tables",
           "least_squares_warnings", "LEAST_SQUARES"]

LEAST_SQUARES = "rotoruq.methods.least_squares:least_squares"


@dataclass(frozen=True, eq=False)
class LeastSquaresRecord(StepRecord):
    """What a least-squares step saves: d calibrated inputs.

    names_in (d); x (d,) the optimum; std (d,) its linearised std; residuals (k, m) the
    residuals there, per experiment and response; cost (of the scaled residuals); converged,
    message. The flat view: ``value/<input>``, ``std/<input>``, ``cost``, ``converged``.
    """

    AXES = {"x": ("input",), "std": ("input",), "residuals": ("experiment", "response")}
    FLAT = {"x": "value", "residuals": None}

    names_in: tuple[str, ...]
    x: np.ndarray
    std: np.ndarray
    residuals: np.ndarray
    cost: float
    converged: bool
    message: str


#: the report's and ``rotoruq show``'s sentence for a step without data
RESIDUALS_NOTE = ("no data: the model's responses are the residuals, driven toward zero "
                  "(1/2 sum of their squares minimised)")


def x0_table(v: object) -> dict[str, float]:
    """``x0 = {param = value, ...}``: a table of numbers (the names are checked against
    the step's parameters and their bounds when the step starts)."""
    if not isinstance(v, dict) or not v:
        raise TypeError("a table { parameter = value, ... } of the initial point")
    for x in v.values():
        number()(x)
    return {str(k): float(x) for k, x in v.items()}


def initial_point(given: Mapping[str, float] | None, space) -> np.ndarray:
    """The initial point (d,): the distributions' means, replaced by ``given`` (the step's
    ``x0``) where given; ParameterError naming the parameter for a name that is not one of
    the step's parameters or a value outside its bounds (its distribution's support)."""
    x0 = np.asarray(space.mean, dtype=float).copy()
    if not given:
        return x0
    names = list(space.names)
    bounds = np.asarray(space.bounds, dtype=float)
    for name, value in given.items():
        if name not in names:
            raise ParameterError(f"x0 names {name!r}, which is not a calibrated parameter "
                                 f"of this step ({', '.join(names)}){close_hint(name, names)}")
        j = names.index(name)
        lo, hi = bounds[j]
        if not lo <= value <= hi:
            raise ParameterError(f"x0: {name} = {value:g} lies outside its bounds "
                                 f"[{lo:g}, {hi:g}] (the support of its distribution "
                                 f"{space.distributions[j].describe()['kind']})")
        x0[j] = value
    return x0


def run_least_squares(ctx: StepContext) -> StepResult:
    from ..methods.least_squares import calibrate

    o = ctx.options
    sd = per_response(o.get("noise_std"), ctx.responses)
    w = per_response(o.get("residual_weights"), ctx.responses)
    x0 = initial_point(o.get("x0"), ctx.space)
    res = calibrate(
        ctx.model(), ctx.data, ctx.space, x0=x0, noise_std=sd, residual_weights=w,
        optimizer=o["optimizer"], max_iterations=o["max_iterations"],
        max_function_evaluations=o["max_function_evaluations"],
        tolerance=o["tolerance"],
    )
    calibrated = {}
    for j, p in enumerate(res.names_in):
        s = float(res.std[j])
        sd_p = s if np.isfinite(s) and s > 0 else ctx.space[p].std
        calibrated[p] = dist_to_dict(Normal(float(res.x[j]), sd_p))
    record = LeastSquaresRecord(tuple(res.names_in), np.asarray(res.x, dtype=float),
                                np.asarray(res.std, dtype=float), np.asarray(res.residuals),
                                float(res.cost), bool(res.converged), str(res.message))
    arrays, meta = record.parts()
    extra: dict = {"x0": {p: float(v) for p, v in zip(res.names_in, x0, strict=True)},
                   "n_gradient_evaluations": int(res.n_gradient_evaluations),
                   "iterations": int(res.iterations)}
    if res.residual_model:
        extra["residual_model"] = True
    return StepResult(ctx.name, ctx.type, {}, arrays, calibrated, meta={
        "n_evaluations": int(res.n_evaluations), "converged": bool(res.converged),
        "message": res.message, **extra, **meta})


def least_squares_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    rec = LeastSquaresRecord.read(res)
    note = f"Cost {rec.cost:.6g}; {rec.message}"
    counts = (f"{res.meta.get('iterations', '?')} iterations, {res.meta.get('n_evaluations')} "
              "evaluations")
    if res.meta.get("n_gradient_evaluations"):
        counts += f", {res.meta['n_gradient_evaluations']} analytic Jacobians"
    note += f"; {counts}"
    start = res.meta.get("x0")
    if isinstance(start, Mapping) and start:
        note += "; started at " + ", ".join(f"{label(p, labels)} = {float(v):.6g}"
                                            for p, v in start.items())
    title = "Calibrated parameters (least squares)"
    if res.meta.get("residual_model"):
        title = "Calibrated parameters (least squares on the model's responses as residuals)"
        note = f"{RESIDUALS_NOTE[0].upper()}{RESIDUALS_NOTE[1:]}. {note}"
    return [make_table(title, ("parameter", "value", "std"),
                       [[label(p, labels), float(rec.x[j]), float(rec.std[j])]
                        for j, p in enumerate(rec.names_in)], note)]


def least_squares_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    """A least-squares calibration that did not converge."""
    if res.meta.get("converged") is False:
        return [f"{res.name}: least squares did not converge ({res.meta.get('message', '')})"]
    return []


STEP = StepType(
    "least_squares", run_least_squares, method=LEAST_SQUARES,
    provides=("calibrated",), needs_data=True, data_optional=True,
    options={"optimizer": Option(choice("nl2sol", "trf", "lm"), SIGNATURE),
             "max_iterations": Option(integer(1), SIGNATURE),
             "max_function_evaluations": Option(integer(1), SIGNATURE),
             "tolerance": Option(number(positive=True, allow_zero=False), SIGNATURE),
             "noise_std": Option(number_or_table, None),
             "residual_weights": Option(number_or_table, None),
             "x0": Option(x0_table, None)},
    tables=least_squares_tables, warnings=least_squares_warnings)
