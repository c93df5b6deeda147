"""Step type ``multifidelity``: mean and variance of the study's model (the high-fidelity one)
from few of its runs and many runs of cheaper models, by multifidelity Monte Carlo or
approximate control variates (:func:`rotoruq.methods.multifidelity.multifidelity_sample`).

The high-fidelity model is the study's ``[model]``; ``models`` names the low-fidelity ones,
each built by the study's model factory as ``make_model(inputs, responses, fixed,
model=NAME)`` (a study's ``[models.NAME]`` tables). The report shows the allocation (runs and
measured cost per model), the estimates with their standard errors and the high-fidelity runs
plain Monte Carlo would need for the same standard errors.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping

from ..errors import ParameterError
from ..render.tables import StepTable, label, make_table, responses, value
from ..results import StepResult
from .base import StepCheck, StepContext, StepType
from .options import (
    REQUIRED,
    SIGNATURE,
    Option,
    choice,
    integer,
    number,
    number_list,
    string_list,
)

__all__ = ["STEP", "run_multifidelity", "multifidelity_tables", "multifidelity_warnings",
           "HF_LABEL"]

_METHOD = "rotoruq.methods.multifidelity:multifidelity_sample"
#: How the report names the study's own ``[model]`` (the high-fidelity one).
HF_LABEL = "model"


def _low_fidelity(ctx: StepContext, name: str):
    params = inspect.signature(ctx.make_model).parameters
    if "model" not in params and not any(p.kind is p.VAR_KEYWORD for p in params.values()):
        raise ParameterError(
            f"step {ctx.name!r}: the low-fidelity model {name!r} needs a model factory that "
            "builds named models (make_model(inputs, responses, fixed, model=NAME)); this "
            "study runner builds only [model]")
    return ctx.make_model(ctx.space.names, ctx.responses, dict(ctx.fixed), model=name)


def run_multifidelity(ctx: StepContext) -> StepResult:
    from ..methods.multifidelity import multifidelity_sample

    o = ctx.options
    names = (HF_LABEL, *o["models"])
    models = [ctx.model()] + [_low_fidelity(ctx, n) for n in o["models"]]
    costs = o.get("costs")
    if costs is not None and len(costs) != len(models):
        raise ParameterError(f"step {ctx.name!r}: costs has {len(costs)} values; it needs one "
                             f"per model ({', '.join(names)})")
    res = multifidelity_sample(models, ctx.space, o["budget"], budget_unit=o["budget_unit"],
                               estimator=o["estimator"], n_pilot=o["n_pilot"], costs=costs,
                               seed=ctx.rng)
    scalars: dict[str, float] = {"budget": res.budget, "cost_pilot": res.cost_pilot,
                                 "cost_main": res.cost_main}
    for k, n in enumerate(names):
        scalars[f"cost/{n}"] = float(res.costs[k])
        scalars[f"runs/{n}"] = float(res.allocation[k] + res.n_pilot)
        scalars[f"allocation/{n}"] = float(res.allocation[k])
        scalars[f"used/{n}"] = float(k in res.models_used)
        for j, r in enumerate(ctx.responses):
            scalars[f"correlation/{n}/{r}"] = float(res.correlation[j, k])
    for j, r in enumerate(ctx.responses):
        scalars[f"mean/{r}"] = float(res.mean[j])
        scalars[f"mean_se/{r}"] = float(res.mean_se[j])
        scalars[f"variance/{r}"] = float(res.variance[j])
        scalars[f"variance_se/{r}"] = float(res.variance_se[j])
        scalars[f"std/{r}"] = float(res.std[j])
        for s in res.statistics:
            scalars[f"n_equivalent_hf/{s}/{r}"] = float(res.n_equivalent_hf[s][j])
            scalars[f"speedup/{s}/{r}"] = float(res.speedup[s][j])
    return StepResult(ctx.name, ctx.type, scalars, meta={
        "models": list(names), "responses": list(ctx.responses), "estimator": res.estimator,
        "target": res.target,
        "n_pilot": res.n_pilot, "costs_measured": res.costs_measured,
        "n_evaluations": int(res.n_evaluations)})


def multifidelity_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    models = list(res.meta.get("models") or [])
    resp = responses(res)
    unit = "s" if res.meta.get("costs_measured") else "cost units"
    alloc = make_table(
        f"Allocation ({res.meta.get('estimator', '?')}, {res.meta.get('n_pilot', '?')}-point "
        "pilot)",
        ("model", f"cost per run [{unit}]", "pilot + main runs",
         *(f"correlation with HF: {label(r, labels)}" for r in resp)),
        [[m + ("" if value(res, f"used/{m}") else " (not used)"), value(res, f"cost/{m}"),
          value(res, f"runs/{m}"), *(value(res, f"correlation/{m}/{r}") for r in resp)]
         for m in models],
        note=f"Budget {value(res, 'budget')} {unit} for the main phase (spent "
             f"{value(res, 'cost_main')}) plus the pilot's {value(res, 'cost_pilot')}.")
    est = make_table(
        "Multi-fidelity estimates",
        ("response", "mean", "mean std. error", "std", "variance", "variance std. error",
         "HF runs plain MC needs (mean)", "HF runs plain MC needs (variance)",
         "cost saving (mean)"),
        [[label(r, labels), value(res, f"mean/{r}"), value(res, f"mean_se/{r}"),
          value(res, f"std/{r}"), value(res, f"variance/{r}"), value(res, f"variance_se/{r}"),
          value(res, f"n_equivalent_hf/mean/{r}"), value(res, f"n_equivalent_hf/variance/{r}"),
          value(res, f"speedup/mean/{r}")] for r in resp],
        note="Standard errors predicted from the pilot's covariances and the allocation; "
             "plain MC: the high-fidelity runs whose sample mean (variance) has the same "
             "standard error; cost saving: their cost over this step's (pilot included).")
    return [alloc, est]


def multifidelity_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    out = []
    for m in res.meta.get("models") or []:
        if m != HF_LABEL and not value(res, f"used/{m}"):
            out.append(f"low-fidelity model {m!r} was left out: its correlation with the "
                       "high-fidelity model does not pay for its cost")
    for r in responses(res):
        s = value(res, f"speedup/mean/{r}")
        if s is not None and s < 1.0:
            out.append(f"{label(r, labels)}: the multi-fidelity mean costs {1 / s:.2g} times "
                       "what plain Monte Carlo on the high-fidelity model would for the same "
                       "standard error (pilot included)")
    return out


def _check(c: StepCheck) -> None:
    if not c.options["models"]:
        c.fail(("models",), "a list of low-fidelity model names", "[]")
    costs = c.options.get("costs")
    if costs is not None and len(costs) != len(c.options["models"]) + 1:
        c.fail(("costs",), f"{len(c.options['models']) + 1} costs ([model] first, then "
               "each of models)", str(list(costs)))


STEP = StepType(
    "multifidelity", run_multifidelity, method=_METHOD,
    options={"models": Option(string_list, REQUIRED),
             "budget": Option(number(positive=True, allow_zero=False), SIGNATURE),
             "budget_unit": Option(choice("cost", "hf_runs"), SIGNATURE),
             "estimator": Option(choice("mfmc", "acvmf", "acvis"), SIGNATURE),
             "n_pilot": Option(integer(4), SIGNATURE),
             "costs": Option(number_list, None)},
    quick={"n_pilot": 10}, check=_check,
    tables=multifidelity_tables, warnings=multifidelity_warnings,
    modules=("rotoruq.methods.multifidelity", "rotoruq.methods.acv"))
