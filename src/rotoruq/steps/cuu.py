"""Step type ``cuu``: calibration under uncertainty (nested: an inner propagation, an outer
least squares on the input statistics), then sampled checks of the response statistics with
the initial and the calibrated inputs."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..params import ParameterSpace
from ..render.figures import Figure, FigureContext, cuu_comparison
from ..render.tables import StepTable, label, make_table, parameters, responses, value
from ..results import StepResult, dist_to_dict
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

__all__ = ["STEP", "run_cuu", "cuu_tables", "cuu_figures", "cuu_warnings"]

_SAMPLE = "rotoruq.methods.sampling:sample"


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
    scalars = {}
    for p in ctx.space.names:
        scalars[f"initial_mean/{p}"] = ctx.space[p].mean
        scalars[f"initial_std/{p}"] = ctx.space[p].std
        scalars[f"mean/{p}"] = cal_space[p].mean
        scalars[f"std/{p}"] = cal_space[p].std
    for r, (m, s) in targets.items():
        scalars[f"target_mean/{r}"] = float(m)
        scalars[f"target_std/{r}"] = float(s)
    arrays, columns = {}, {}
    n = o.get("verify_samples", 0)
    if n:
        for tag, space in (("initial", ctx.space), ("calibrated", cal_space)):
            checked = sample(model, space, n, design=o["design"], seed=ctx.rng)
            out = np.asarray(checked.outputs)
            for k, r in enumerate(ctx.responses):
                v = out[:, k][np.isfinite(out[:, k])]
                scalars[f"{tag}_out_mean/{r}"] = float(np.mean(v))
                scalars[f"{tag}_out_std/{r}"] = float(np.std(v, ddof=1))
            arrays[f"outputs_{tag}"] = out
            columns[f"outputs_{tag}"] = list(ctx.responses)
    calibrated = {p: dist_to_dict(d) for p, d in zip(cal_space.names, cal_space.distributions,
                                                      strict=True)}
    return StepResult(ctx.name, ctx.type, scalars, arrays, calibrated, meta={
        "columns": columns, "n_evaluations": int(res.n_evaluations),
        "identifiable": bool(res.identifiable), "diagnostic": res.diagnostic,
        "weighting": res.weighting,
        "condition_number": float(res.condition_number), "message": res.message})


def cuu_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    params = parameters(res)
    resp = responses(res)
    out = [make_table("Inputs: initial and calibrated", (
        "input", "initial mean", "initial std", "calibrated mean", "calibrated std"),
        [[label(p, labels), value(res, f"initial_mean/{p}"), value(res, f"initial_std/{p}"),
          value(res, f"mean/{p}"), value(res, f"std/{p}")] for p in params],
        "Identifiable: " + ("yes" if res.meta.get("identifiable", True) else
                            f"no ({res.meta.get('diagnostic', '')})")
        + ". " + _WEIGHTING_NOTE.get(res.meta.get("weighting", "relative"), ""))]
    out.append(make_table("Responses: targets and sampled statistics",
                          ("response", "target mean", "target std", "initial mean",
                           "initial std", "calibrated mean", "calibrated std"),
                          [[r, value(res, f"target_mean/{r}"), value(res, f"target_std/{r}"),
                            value(res, f"initial_out_mean/{r}"),
                            value(res, f"initial_out_std/{r}"),
                            value(res, f"calibrated_out_mean/{r}"),
                            value(res, f"calibrated_out_std/{r}")]
                           for r in resp]))
    return out


_WEIGHTING_NOTE = {
    "relative": "Residuals relative to the targets, (s - t) / |t| (Dakota's nested model uses "
                "plain differences: weighting = \"absolute\").",
    "absolute": "Residuals are plain differences s - t, as Dakota's nested model.",
}


def cuu_figures(res: StepResult, ctx: FigureContext) -> list[Figure]:
    """Response distributions with the initial and the calibrated inputs against targets."""
    return cuu_comparison(res, ctx.labels, ctx.units)


def cuu_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    """A calibration under uncertainty whose input std devs are not identifiable."""
    if res.meta.get("identifiable") is False:
        diag = res.meta.get("diagnostic") or "the input std devs are not identifiable"
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
