"""Step type ``sampling``: propagate the input distributions by a sampling design (LHS by
default), optionally with measurement noise added to the outputs."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..render.figures import Figure, FigureContext, load_distributions
from ..render.tables import MOMENTS, StepTable, inputs_table, make_table, moments_rows, responses
from ..results import StepResult
from ._common import input_scalars, noise, stats_scalars
from .base import DESIGNS, StepContext, StepType
from .options import SIGNATURE, Option, choice, integer, number_or_table

__all__ = ["STEP", "run_sampling", "sampling_tables", "sampling_figures"]

_SAMPLE = "rotoruq.methods.sampling:sample"


def run_sampling(ctx: StepContext) -> StepResult:
    from ..methods.sampling import sample

    o = ctx.options
    res = sample(ctx.model(), ctx.space, o["n_samples"], design=o["design"], seed=ctx.rng)
    clean = np.asarray(res.outputs)
    noisy = clean + noise(ctx, o.get("noise_std"), clean.shape)
    scalars = stats_scalars(ctx.responses, clean)
    scalars.update(stats_scalars([f"noisy_{r}" for r in ctx.responses], noisy))
    scalars.update(input_scalars(ctx.space))
    arrays = {"inputs": np.asarray(res.inputs), "outputs": noisy}
    columns = {"inputs": list(ctx.space.names), "outputs": list(ctx.responses)}
    if o.get("noise_std"):
        arrays["outputs_clean"] = clean
        columns["outputs_clean"] = list(ctx.responses)
    return StepResult(ctx.name, ctx.type, scalars, arrays, meta={
        "columns": columns, "n_evaluations": int(res.n_evaluations),
        "failures": len(res.failures)})


def sampling_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    resp = res.columns("outputs") or responses(res)
    out = [make_table("Response statistics (model outputs)", ("response", *MOMENTS),
                      moments_rows(res, resp))]
    if "outputs_clean" in res.arrays:
        out.append(make_table("Response statistics with the added noise",
                              ("response", *MOMENTS),
                              moments_rows(res, [f"noisy_{r}" for r in resp])))
    out.append(inputs_table(res, labels))
    return out


def sampling_figures(res: StepResult, ctx: FigureContext) -> list[Figure]:
    """Distributions of the sampled responses."""
    if "outputs" not in res.arrays:
        return []
    return load_distributions(StepResult(
        res.name, res.type, res.scalars, {"outputs": res.arrays["outputs"]},
        meta={"columns": {"outputs": res.columns("outputs")}, "labels": [""]}), ctx.units)


STEP = StepType(
    "sampling", run_sampling, method=_SAMPLE, provides=("samples",),
    options={"n_samples": Option(integer(1), SIGNATURE),
             "design": Option(choice(*DESIGNS), SIGNATURE),
             "noise_std": Option(number_or_table, 0.0)},
    quick={"n_samples": 40},
    tables=sampling_tables, figures=sampling_figures,
    modules=("rotoruq.methods.sampling",))
