"""Step type ``sensitivity``: Sobol main and total indices with bootstrap intervals, and the
output spread that says whether they mean anything."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..render.tables import StepTable, cv_or_none, label, make_table, with_unit
from ..results import StepRecord, StepResult
from ._common import input_scalars
from ._sobol import sensitivity_figures, sobol_warnings
from .base import DESIGNS, StepContext, StepType
from .options import SIGNATURE, Option, choice, integer

__all__ = ["STEP", "SensitivityRecord", "run_sensitivity", "sensitivity_tables",
           "sensitivity_figures", "sobol_warnings", "output_spread_scalars", "NEGLIGIBLE_CV"]

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


@dataclass(frozen=True, eq=False)
class SensitivityRecord(StepRecord):
    """What a sensitivity step saves: m responses, d inputs.

    names_in (d), names_out (m); main, total (m, d) Sobol indices as estimated; main_ci,
    total_ci (m, d, 2) their bootstrap intervals at ``confidence``; mean, variance (m,) of each
    response (the spread that says whether its indices mean anything).
    """

    AXES = {"main": ("response", "input"), "total": ("response", "input"),
            "main_ci": ("response", "input", "bound"), "total_ci": ("response", "input", "bound"),
            "mean": ("response",), "variance": ("response",)}

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    main: np.ndarray
    total: np.ndarray
    main_ci: np.ndarray
    total_ci: np.ndarray
    mean: np.ndarray
    variance: np.ndarray
    confidence: float


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
    record = SensitivityRecord(tuple(ctx.space.names), tuple(ctx.responses), main, total,
                               main_ci, total_ci, np.asarray(res.mean, dtype=float),
                               np.asarray(res.variance, dtype=float), float(res.confidence))
    arrays, meta = record.parts()
    return StepResult(ctx.name, ctx.type, scalars, arrays, meta={
        "inputs": list(ctx.space.names), "responses": list(ctx.responses),
        "confidence": float(res.confidence),
        "n_evaluations": int(getattr(res, "n_evaluations", 0)), **meta})


def sensitivity_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    rec = SensitivityRecord.read(res)
    conf = rec.confidence
    std = np.sqrt(np.maximum(rec.variance, 0.0))
    cv = [s / abs(m) if m != 0 else np.inf for s, m in zip(std, rec.mean, strict=True)]
    negligible = [c < NEGLIGIBLE_CV for c in cv]
    out = [make_table("Output spread", ("response", "mean", "variance", "std",
                                        "CV = std / |mean| [-]", "negligible variance"),
                      [[with_unit(r, labels), float(rec.mean[k]), float(rec.variance[k]),
                        float(std[k]), cv_or_none(float(rec.mean[k]), float(std[k])),
                        "yes: indices meaningless" if negligible[k] else "no"]
                       for k, r in enumerate(rec.names_out)],
                      "A response whose std is below 1e-4 of its mean has negligible variance.")]
    lo, hi = f"{100 * (1 - conf) / 2:g} %", f"{100 * (1 + conf) / 2:g} %"
    for k, r in enumerate(rec.names_out):
        rows = [[label(p, labels), float(rec.main[k, j]), float(rec.main_ci[k, j, 0]),
                 float(rec.main_ci[k, j, 1]), float(rec.total[k, j]),
                 float(rec.total_ci[k, j, 0]), float(rec.total_ci[k, j, 1])]
                for j, p in enumerate(rec.names_in)]
        out.append(make_table(f"Sobol indices of {r}"
                              + (" (negligible variance)" if negligible[k] else ""),
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
