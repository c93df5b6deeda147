"""Step type ``pce``: polynomial chaos expansion (quadrature, sparse grid or regression),
its moments and the Sobol indices read from its coefficients."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..render.tables import StepTable, label, make_table, parameters, responses, value
from ..results import StepResult
from ._common import input_scalars
from ._sobol import sensitivity_figures, sobol_warnings
from .base import StepCheck, StepContext, StepType
from .options import SIGNATURE, Option, choice, integer

__all__ = ["STEP", "run_pce", "pce_tables"]


def run_pce(ctx: StepContext) -> StepResult:
    """Polynomial chaos of total order ``order`` by ``estimator`` (quadrature, sparse grid,
    or regression on ``n_samples`` LHS points)."""
    from ..methods.pce import polynomial_chaos

    o = ctx.options
    res = polynomial_chaos(ctx.model(), ctx.space, o["order"], estimator=o["estimator"],
                           n_samples=o["n_samples"], seed=ctx.rng)
    scalars = {}
    for k, r in enumerate(ctx.responses):
        scalars[f"mean/{r}"] = float(res.mean[k])
        scalars[f"std/{r}"] = float(res.std[k])
        for j, p in enumerate(ctx.space.names):
            scalars[f"S/{r}/{p}"] = float(res.main[k, j])
            scalars[f"T/{r}/{p}"] = float(res.total[k, j])
    scalars.update(input_scalars(ctx.space))
    return StepResult(ctx.name, ctx.type, scalars, {"main": np.asarray(res.main),
                                                    "total": np.asarray(res.total)}, meta={
        "inputs": list(ctx.space.names), "responses": list(ctx.responses),
        "n_evaluations": int(res.n_evaluations)})


def pce_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    resp, inputs = responses(res), list(res.meta.get("inputs") or parameters(res))
    out = [make_table("Response moments (polynomial chaos)", ("response", "mean", "std"),
                      [[r, value(res, f"mean/{r}"), value(res, f"std/{r}")] for r in resp])]
    for r in resp:
        out.append(make_table(f"Sobol indices of {r} (from the expansion)",
                              ("input", "main S", "total T"),
                              [[label(p, labels), value(res, f"S/{r}/{p}"),
                                value(res, f"T/{r}/{p}")] for p in inputs]))
    return out


def _check_pce(c: StepCheck) -> None:
    if c.options["n_samples"] is not None and c.options["estimator"] != "regression":
        c.fail(("n_samples",), "n_samples only with estimator = \"regression\" (quadrature "
               "and sparse grids choose their own points)", str(c.options["n_samples"]))


STEP = StepType(
    "pce", run_pce, method="rotoruq.methods.pce:polynomial_chaos",
    options={"order": Option(integer(1), SIGNATURE),
             "estimator": Option(choice("quadrature", "sparse_grid", "regression"), SIGNATURE),
             "n_samples": Option(integer(1), SIGNATURE)},
    quick={"n_samples": 40}, check=_check_pce,
    tables=pce_tables, figures=sensitivity_figures, warnings=sobol_warnings)
