"""Step type ``pce``: polynomial chaos expansion (quadrature, sparse grid or regression),
its moments and the Sobol indices read from its coefficients."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..render.tables import StepTable, label, make_table
from ..results import StepRecord, StepResult
from ._common import input_scalars
from ._sobol import sensitivity_figures, sobol_warnings
from .base import StepCheck, StepContext, StepType
from .options import SIGNATURE, Option, choice, integer

__all__ = ["STEP", "PceRecord", "run_pce", "pce_tables", "SOLVERS"]

#: ``polynomial_chaos(solver=)``'s choices (methods.pce.SOLVERS; spelled out so that importing
#: the step types does not import the method)
SOLVERS = ("least_squares", "omp", "lars", "lasso")


@dataclass(frozen=True, eq=False)
class PceRecord(StepRecord):
    """What a pce step saves: m responses, d inputs.

    names_in (d), names_out (m); mean, std (m,) of the expansion; main, total (m, d) Sobol
    indices read from its coefficients.
    """

    AXES = {"mean": ("response",), "std": ("response",), "main": ("response", "input"),
            "total": ("response", "input")}

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    mean: np.ndarray
    std: np.ndarray
    main: np.ndarray
    total: np.ndarray


def run_pce(ctx: StepContext) -> StepResult:
    """Polynomial chaos of total order ``order`` by ``estimator`` (quadrature, sparse grid,
    or regression on ``n_samples`` LHS points)."""
    from ..methods.pce import polynomial_chaos

    o = ctx.options
    res = polynomial_chaos(ctx.model(), ctx.space, o["order"], estimator=o["estimator"],
                           n_samples=o["n_samples"], solver=o["solver"], seed=ctx.rng)
    scalars = {}
    for k, r in enumerate(ctx.responses):
        scalars[f"mean/{r}"] = float(res.mean[k])
        scalars[f"std/{r}"] = float(res.std[k])
        for j, p in enumerate(ctx.space.names):
            scalars[f"S/{r}/{p}"] = float(res.main[k, j])
            scalars[f"T/{r}/{p}"] = float(res.total[k, j])
    scalars.update(input_scalars(ctx.space))
    record = PceRecord(tuple(ctx.space.names), tuple(ctx.responses),
                       np.asarray(res.mean, dtype=float), np.asarray(res.std, dtype=float),
                       np.asarray(res.main), np.asarray(res.total))
    arrays, meta = record.parts()
    return StepResult(ctx.name, ctx.type, scalars, arrays, meta={
        "inputs": list(ctx.space.names), "responses": list(ctx.responses),
        "n_evaluations": int(res.n_evaluations), **meta})


def pce_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    rec = PceRecord.read(res)
    out = [make_table("Response moments (polynomial chaos)", ("response", "mean", "std"),
                      [[r, float(rec.mean[k]), float(rec.std[k])]
                       for k, r in enumerate(rec.names_out)])]
    for k, r in enumerate(rec.names_out):
        out.append(make_table(f"Sobol indices of {r} (from the expansion)",
                              ("input", "main S", "total T"),
                              [[label(p, labels), float(rec.main[k, j]), float(rec.total[k, j])]
                               for j, p in enumerate(rec.names_in)]))
    return out


def _check_pce(c: StepCheck) -> None:
    if c.options["n_samples"] is not None and c.options["estimator"] != "regression":
        c.fail(("n_samples",), "n_samples only with estimator = \"regression\" (quadrature "
               "and sparse grids choose their own points)", str(c.options["n_samples"]))


STEP = StepType(
    "pce", run_pce, method="rotoruq.methods.pce:polynomial_chaos", correlated=True,
    options={"order": Option(integer(1), SIGNATURE),
             "estimator": Option(choice("quadrature", "sparse_grid", "regression"), SIGNATURE),
             "n_samples": Option(integer(1), SIGNATURE),
             "solver": Option(choice(*SOLVERS), SIGNATURE)},
    quick={"n_samples": 40}, check=_check_pce,
    tables=pce_tables, figures=sensitivity_figures, warnings=sobol_warnings)
