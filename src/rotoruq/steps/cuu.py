"""Step type ``cuu``: calibration under uncertainty (nested: an inner propagation, an outer
least squares on the input statistics), then sampled checks of the response statistics with
the initial and the calibrated inputs."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..params import ParameterSpace
from ..render.figures import Figure, FigureContext, cuu_comparison
from ..render.tables import StepTable, cell, label, make_table
from ..results import StepRecord, StepResult, dist_to_dict
from ._common import saved_record
from .base import DESIGNS, StepCheck, StepContext, StepType
from .least_squares import LEAST_SQUARES
from .options import (
    REQUIRED,
    SIGNATURE,
    Option,
    choice,
    integer,
    number,
    table_or_string,
)

__all__ = ["STEP", "CuuRecord", "run_cuu", "cuu_tables", "cuu_figures", "cuu_warnings"]

_SAMPLE = "rotoruq.methods.sampling:sample"


@dataclass(frozen=True, eq=False)
class CuuRecord(StepRecord):
    """What a calibration under uncertainty saves: d inputs, m responses.

    names_in (d), names_out (m); initial_mean, initial_std, mean, std (d,) : each input's
    distribution before and after calibration. target_mean, target_std (m,) : the response
    targets (NaN: no target). initial_out_mean, initial_out_std, calibrated_out_mean,
    calibrated_out_std (m,) : the responses' sampled statistics with the initial and the
    calibrated inputs (NaN without ``verify_samples``; the samples are the arrays
    ``outputs_initial``, ``outputs_calibrated`` beside the record). identifiable : whether
    the input statistics are identifiable from the targets; diagnostic : why not, in words;
    weighting : "relative" or "absolute" residuals; condition_number : of the outer
    problem's Jacobian; message : the optimizer's. The flat view: ``<field>/<input>``,
    ``<field>/<response>`` (``calibrated_out_std/thrust``), leaving out what is NaN.
    """

    AXES = {**{k: ("input",) for k in ("initial_mean", "initial_std", "mean", "std")},
            **{k: ("response",) for k in (
                "target_mean", "target_std", "initial_out_mean", "initial_out_std",
                "calibrated_out_mean", "calibrated_out_std")}}

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    initial_mean: np.ndarray
    initial_std: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    target_mean: np.ndarray
    target_std: np.ndarray
    initial_out_mean: np.ndarray
    initial_out_std: np.ndarray
    calibrated_out_mean: np.ndarray
    calibrated_out_std: np.ndarray
    identifiable: bool
    diagnostic: str
    weighting: str
    condition_number: float
    message: str


def run_cuu(ctx: StepContext) -> StepResult:
    """Calibration under uncertainty (nested: inner mean value, outer least squares), then
    LHS checks of the response statistics with the initial and the calibrated inputs."""
    from ..methods.cuu import calibrate_under_uncertainty
    from ..methods.sampling import sample

    o = ctx.options
    model = ctx.model()
    targets = {r: ctx.targets[r] for r in ctx.responses if r in ctx.targets}
    stats_ = ["std"] if o["calibrate"] == "std" else (
        ["mean"] if o["calibrate"] == "mean" else ["mean", "std"])
    res = calibrate_under_uncertainty(
        model, ctx.space, calibrate={p: stats_ for p in ctx.space.names},
        targets={r: {"mean": m, "std": s} if "mean" in stats_ else {"std": s}
                 for r, (m, s) in targets.items()},
        inner=o["inner"],
        optimizer=o["optimizer"], weighting=o["weighting"], max_iterations=o["max_iterations"],
        tolerance=o["tolerance"], seed=ctx.rng,
    )
    cal_space: ParameterSpace = res.space
    names, resp = tuple(ctx.space.names), tuple(ctx.responses)
    m = len(resp)
    out_stats = {k: np.full(m, np.nan) for k in (
        "initial_out_mean", "initial_out_std", "calibrated_out_mean", "calibrated_out_std")}
    arrays, columns = {}, {}
    n = o.get("verify_samples", 0)
    if n:
        for tag, space in (("initial", ctx.space), ("calibrated", cal_space)):
            checked = sample(model, space, n, design=o["design"], seed=ctx.rng)
            out = np.asarray(checked.outputs)
            for k in range(m):
                v = out[:, k][np.isfinite(out[:, k])]
                out_stats[f"{tag}_out_mean"][k] = float(np.mean(v))
                out_stats[f"{tag}_out_std"][k] = float(np.std(v, ddof=1))
            arrays[f"outputs_{tag}"] = out
            columns[f"outputs_{tag}"] = list(resp)
    record = CuuRecord(
        names, resp,
        np.array([ctx.space[p].mean for p in names], dtype=float),
        np.array([ctx.space[p].std for p in names], dtype=float),
        np.array([cal_space[p].mean for p in names], dtype=float),
        np.array([cal_space[p].std for p in names], dtype=float),
        np.array([float(targets[r][0]) if r in targets else np.nan for r in resp]),
        np.array([float(targets[r][1]) if r in targets else np.nan for r in resp]),
        **out_stats, identifiable=bool(res.identifiable), diagnostic=str(res.diagnostic or ""),
        weighting=str(res.weighting), condition_number=float(res.condition_number),
        message=str(res.message or ""))
    rec_arrays, rec_meta = record.parts()
    calibrated = {p: dist_to_dict(d) for p, d in zip(cal_space.names, cal_space.distributions,
                                                      strict=True)}
    return StepResult(ctx.name, ctx.type, {}, {**arrays, **rec_arrays}, calibrated, meta={
        "columns": columns, "n_evaluations": int(res.n_evaluations),
        "identifiable": bool(res.identifiable), "diagnostic": res.diagnostic,
        "weighting": res.weighting,
        "condition_number": float(res.condition_number), "message": res.message, **rec_meta})


def cuu_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    rec = CuuRecord.read(res)
    out = [make_table("Inputs: initial and calibrated", (
        "input", "initial mean", "initial std", "calibrated mean", "calibrated std"),
        [[label(p, labels), cell(rec.initial_mean[j]), cell(rec.initial_std[j]),
          cell(rec.mean[j]), cell(rec.std[j])] for j, p in enumerate(rec.names_in)],
        "Identifiable: " + ("yes" if rec.identifiable else f"no ({rec.diagnostic})")
        + ". " + _WEIGHTING_NOTE.get(rec.weighting, ""))]
    out.append(make_table("Responses: targets and sampled statistics",
                          ("response", "target mean", "target std", "initial mean",
                           "initial std", "calibrated mean", "calibrated std"),
                          [[r, cell(rec.target_mean[k]), cell(rec.target_std[k]),
                            cell(rec.initial_out_mean[k]), cell(rec.initial_out_std[k]),
                            cell(rec.calibrated_out_mean[k]), cell(rec.calibrated_out_std[k])]
                           for k, r in enumerate(rec.names_out)]))
    return out


_WEIGHTING_NOTE = {
    "relative": "Residuals relative to the targets, (s - t) / |t| (Dakota's nested model uses "
                "plain differences: weighting = \"absolute\").",
    "absolute": "Residuals are plain differences s - t, as Dakota's nested model.",
}


def cuu_figures(res: StepResult, ctx: FigureContext) -> list[Figure]:
    """Response distributions with the initial and the calibrated inputs against targets."""
    rec = saved_record(CuuRecord, res)
    if rec is None:
        return []
    samples = {tag: np.asarray(res.arrays[f"outputs_{tag}"]) for tag in ("initial", "calibrated")
               if f"outputs_{tag}" in res.arrays}
    return cuu_comparison(res.name, rec.names_in, rec.names_out, rec.initial_std, rec.mean,
                          rec.std, rec.target_mean, rec.target_std, samples, ctx.labels,
                          ctx.units)


def cuu_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    """A calibration under uncertainty whose input std devs are not identifiable."""
    rec = saved_record(CuuRecord, res)
    if rec is not None and not rec.identifiable:
        diag = rec.diagnostic or "the input std devs are not identifiable"
        return [f"{res.name}: not identifiable: {diag}"]
    return []


def _check_targets(c: StepCheck) -> None:
    targets = c.options["targets"]
    if isinstance(targets, str):
        c.reference(targets, "targets", ("samples",))
        return
    allowed = c.responses or c.model.responses
    for r, v in targets.items():
        if r not in allowed:
            c.fail(("targets", r), f"targets keyed by responses ({', '.join(allowed)})", r)
        if (not isinstance(v, list) or len(v) != 2
                or not all(isinstance(x, int | float) and not isinstance(x, bool) for x in v)
                or v[1] <= 0):
            c.fail(("targets", r), f"{r} = [mean, std] with std > 0", repr(v))


STEP = StepType(
    "cuu", run_cuu, method="rotoruq.methods.cuu:calibrate_under_uncertainty",
    provides=("calibrated",),
    options={"targets": Option(table_or_string, REQUIRED),
             "calibrate": Option(choice("std", "mean", "mean_std"), "std"),
             "inner": Option(choice("mean_value", "sampling", "pce"), SIGNATURE),
             "optimizer": Option(choice("nl2sol", "trf", "lm"), SIGNATURE),
             "weighting": Option(choice("relative", "absolute"), SIGNATURE),
             "max_iterations": Option(integer(1), SIGNATURE, method=LEAST_SQUARES),
             "tolerance": Option(number(positive=True, allow_zero=False), SIGNATURE,
                                 method=LEAST_SQUARES),
             "verify_samples": Option(integer(0), 0),
             "design": Option(choice(*DESIGNS), SIGNATURE, method=_SAMPLE)},
    quick={"verify_samples": 40}, check=_check_targets,
    tables=cuu_tables, figures=cuu_figures, warnings=cuu_warnings)
