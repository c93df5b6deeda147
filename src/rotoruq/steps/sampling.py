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
from .forward_check import propagation_warnings
from .options import SIGNATURE, Option, choice, integer, number_or_table

__all__ = ["STEP", "run_sampling", "sampling_tables", "sampling_figures"]

_SAMPLE = "rotoruq.methods.sampling:sample"


def run_sampling(ctx: StepContext) -> StepResult:
    """Propagate the step's inputs by a sampling design; with ``from = "<bayes
    step>.posterior"`` and ``propagation = "joint"`` (default), the chain's own draws (thinned
    evenly, correlations kept) instead; ``"independent_normals"`` samples the normals of the
    posterior moments (the reference study) and warns with the correlation it drops."""
    from ..methods.sampling import sample
    from ..model import evaluate
    from .forward_check import dropped_correlation, posterior_draws

    o = ctx.options
    propagation = o.get("propagation", "joint")
    draws = posterior_draws(ctx.source, ctx.space.names, o["n_samples"])
    meta: dict = {}
    if draws is not None and propagation == "joint":
        ev = evaluate(ctx.model(), draws)
        inputs, clean = draws, np.array(ev.values, dtype=float)
        n_eval, n_fail = draws.shape[0], int(np.sum(~np.all(np.isfinite(clean), axis=1)))
        meta["propagation"] = "joint"
    else:
        res = sample(ctx.model(), ctx.space, o["n_samples"], design=o["design"],
                     seed=ctx.rng)
        inputs, clean = np.asarray(res.inputs), np.asarray(res.outputs)
        n_eval, n_fail = int(res.n_evaluations), len(res.failures)
        meta["propagation"] = "sampling" if draws is None else "independent_normals"
        dropped = None if draws is None else dropped_correlation(ctx.source, ctx.space.names)
        if dropped is not None:
            meta["dropped_correlation"] = list(dropped)
    noisy = clean + noise(ctx, o.get("noise_std"), clean.shape)
    scalars = stats_scalars(ctx.responses, clean)
    scalars.update(stats_scalars([f"noisy_{r}" for r in ctx.responses], noisy))
    scalars.update(input_scalars(ctx.space))
    arrays = {"inputs": inputs, "outputs": noisy}
    columns = {"inputs": list(ctx.space.names), "outputs": list(ctx.responses)}
    if o.get("noise_std"):
        arrays["outputs_clean"] = clean
        columns["outputs_clean"] = list(ctx.responses)
    return StepResult(ctx.name, ctx.type, scalars, arrays, meta={
        "columns": columns, "n_evaluations": n_eval, "failures": n_fail, **meta})


def sampling_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    resp = res.columns("outputs") or responses(res)
    out = [make_table("Response statistics (model outputs)", ("response", *MOMENTS),
                      moments_rows(res, resp))]
    if "outputs_clean" in res.arrays:
        out.append(make_table("Response statistics with the added noise",
                              ("response", *MOMENTS),
                              moments_rows(res, [f"noisy_{r}" for r in resp])))
    out.append(inputs_table(res, labels))
    prop = res.meta.get("propagation")
    if prop in ("joint", "independent_normals"):
        out[0] = make_table(out[0].title, out[0].columns, out[0].rows,
                            "Propagation: " + ("the calibration's chain, thinned (its "
                                               "correlations kept)." if prop == "joint" else
                                               "independent normals of the posterior's "
                                               "means and stds (correlations dropped)."))
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
             "noise_std": Option(number_or_table, 0.0),
             "propagation": Option(choice("joint", "independent_normals"), "joint")},
    quick={"n_samples": 40},
    tables=sampling_tables, figures=sampling_figures, warnings=propagation_warnings,
    modules=("rotoruq.methods.sampling",))
