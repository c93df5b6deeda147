"""Step type ``sensitivity``: Sobol main and total indices with bootstrap intervals, and the
output spread that says whether they mean anything."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..methods._sobol_indices import SobolIndices
from ..render.tables import StepTable, cv_or_none, label, make_table, with_unit
from ..results import StepRecord, StepResult
from ._sobol import (
    NEGLIGIBLE_CV,
    sensitivity_figures,
    sensitivity_sweep_figures,
    sobol_warnings,
    spread,
)
from .base import DESIGNS, StepContext, StepType
from .options import SIGNATURE, Option, choice, integer

__all__ = ["STEP", "SensitivityRecord", "run_sensitivity", "sensitivity_tables",
           "sensitivity_figures", "sobol_warnings", "NEGLIGIBLE_CV"]


@dataclass(frozen=True, eq=False)
class SensitivityRecord(StepRecord, SobolIndices):
    """What a sensitivity step saves: m responses, d inputs.

    names_in (d), names_out (m); main, total (m, d) Sobol indices as estimated; main_ci,
    total_ci (m, d, 2) their bootstrap intervals at ``confidence``; mean, variance (m,) of each
    response (the spread that says whether its indices mean anything).
    """

    AXES = {**SobolIndices.AXES, "mean": ("response",), "variance": ("response",)}
    FLAT = {"main": "S", "total": "T", "main_ci": "S_ci", "total_ci": "T_ci",
            "mean": "out_mean", "variance": "out_var"}

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
    record = SensitivityRecord(tuple(ctx.space.names), tuple(ctx.responses),
                               np.asarray(res.main), np.asarray(res.total),
                               np.asarray(res.main_ci), np.asarray(res.total_ci),
                               np.asarray(res.mean, dtype=float),
                               np.asarray(res.variance, dtype=float), float(res.confidence))
    arrays, meta = record.parts()
    return StepResult(ctx.name, ctx.type, {}, arrays, meta={
        "inputs": list(ctx.space.names), "responses": list(ctx.responses),
        "confidence": float(res.confidence),
        "n_evaluations": int(getattr(res, "n_evaluations", 0)), **meta})


def sensitivity_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    rec = SensitivityRecord.read(res)
    conf = rec.confidence
    std = np.sqrt(np.maximum(rec.variance, 0.0))
    negligible = spread(rec.mean, std)[1]
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
    tables=sensitivity_tables, figures=sensitivity_figures, warnings=sobol_warnings,
    sweep_figures=sensitivity_sweep_figures)
