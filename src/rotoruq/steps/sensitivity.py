"""Step type ``sensitivity``: Sobol main and total indices with bootstrap intervals, and the
output spread that says whether they mean anything."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..render.tables import StepTable, label, make_table, parameters, responses, value
from ..results import StepResult
from ._common import input_scalars
from ._sobol import sensitivity_figures, sobol_warnings
from .base import DESIGNS, StepContext, StepType
from .options import SIGNATURE, Option, choice, integer

__all__ = ["STEP", "run_sensitivity", "sensitivity_tables", "sensitivity_figures",
           "sobol_warnings", "output_spread_scalars", "NEGLIGIBLE_CV"]

# A response whose std is below this fraction of |mean| has negligible variance: its Sobol
# indices split up numerical noise and mean nothing physically.
NEGLIGIBLE_CV = 1e-4


def output_spread_scalars(responses: Sequence[str], mean, variance) -> dict:
    """``out_mean``, ``out_var``, ``out_std``, ``out_cv`` (std / |mean|) per response and
    ``negligible/<r>`` = 1 when the CV is below :data:`NEGLIGIBLE_CV`."""
    out = {}
    for k, r in enumerate(responses):
        m, v = float(mean[k]), float(variance[k])
        sd = float(np.sqrt(max(v, 0.0)))
        cv = sd / abs(m) if m != 0 else np.inf
        out.update({f"out_mean/{r}": m, f"out_var/{r}": v, f"out_std/{r}": sd,
                    f"out_cv/{r}": cv, f"negligible/{r}": float(cv < NEGLIGIBLE_CV)})
    return out


def run_sensitivity(ctx: StepContext) -> StepResult:
    """Sobol main and total indices as estimated (negative estimates kept), their bootstrap
    intervals, and the output mean/variance/CV that says whether they mean anything."""
    from ..methods.sensitivity import sobol_indices

    o = ctx.options
    res = sobol_indices(ctx.model(), ctx.space, o["n_samples"], estimator=o["estimator"],
                        design=o["design"], seed=ctx.rng)
    main, total = np.asarray(res.main), np.asarray(res.total)
    main_ci, total_ci = np.asarray(res.main_ci), np.asarray(res.total_ci)
    scalars = output_spread_scalars(ctx.responses, res.mean, res.variance)
    for k, r in enumerate(ctx.responses):
        for j, p in enumerate(ctx.space.names):
            scalars[f"S/{r}/{p}"] = float(main[k, j])
            scalars[f"T/{r}/{p}"] = float(total[k, j])
            scalars[f"S_lo/{r}/{p}"], scalars[f"S_hi/{r}/{p}"] = map(float, main_ci[k, j])
            scalars[f"T_lo/{r}/{p}"], scalars[f"T_hi/{r}/{p}"] = map(float, total_ci[k, j])
    scalars.update(input_scalars(ctx.space))
    return StepResult(ctx.name, ctx.type, scalars, {"main": main, "total": total}, meta={
        "inputs": list(ctx.space.names), "responses": list(ctx.responses),
        "confidence": float(res.confidence),
        "n_evaluations": int(getattr(res, "n_evaluations", 0))})


def sensitivity_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    resp, inputs = responses(res), list(res.meta.get("inputs") or parameters(res))
    conf = res.meta.get("confidence", 0.95)
    out = [make_table("Output spread", ("response", "mean", "variance", "std",
                                        "CV = std / |mean|", "negligible variance"),
                      [[r, value(res, f"out_mean/{r}"), value(res, f"out_var/{r}"),
                        value(res, f"out_std/{r}"), value(res, f"out_cv/{r}"),
                        None if value(res, f"negligible/{r}") is None else
                        ("yes: indices meaningless" if value(res, f"negligible/{r}") else "no")]
                       for r in resp],
                      "A response whose std is below 1e-4 of its mean has negligible variance.")]
    for r in resp:
        neg = value(res, f"negligible/{r}") == 1
        rows = [[label(p, labels), value(res, f"S/{r}/{p}"), value(res, f"S_lo/{r}/{p}"),
                 value(res, f"S_hi/{r}/{p}"), value(res, f"T/{r}/{p}"),
                 value(res, f"T_lo/{r}/{p}"), value(res, f"T_hi/{r}/{p}")] for p in inputs]
        lo, hi = f"{100 * (1 - conf) / 2:g} %", f"{100 * (1 + conf) / 2:g} %"
        out.append(make_table(f"Sobol indices of {r}" + (" (negligible variance)" if neg else ""),
                              ("input", "main S", f"S {lo}", f"S {hi}", "total T", f"T {lo}",
                               f"T {hi}"), rows,
                              "Estimates as computed (a negative value is sampling noise "
                              f"around 0); bootstrap {100 * conf:g} % intervals."))
    return out


STEP = StepType(
    "sensitivity", run_sensitivity, method="rotoruq.methods.sensitivity:sobol_indices",
    options={"n_samples": Option(integer(2), SIGNATURE),
             "design": Option(choice(*DESIGNS), SIGNATURE),
             "estimator": Option(choice("hybrid", "saltelli2010", "jansen", "janon"),
                                 SIGNATURE)},
    quick={"n_samples": 32},
    tables=sensitivity_tables, figures=sensitivity_figures, warnings=sobol_warnings)
