"""Step type ``multifidelity``: mean and variance of the study's model (the high-fidelity one)
from few of its runs and many runs of cheaper models, by multifidelity Monte Carlo, MLBLUE or
approximate control variates (:func:`rotoruq.methods.multifidelity.multifidelity_sample`);
with ``sobol = true`` also its Sobol' main and total indices
(:func:`rotoruq.methods.multifidelity_sobol.multifidelity_sobol`, a budget of its own on top,
the costs the first pilot measured).

The high-fidelity model is the study's ``[model]``, or the ``[models.NAME]`` named by
``high_fidelity`` (a study whose other steps run a cheap ``[model]``); ``models`` names the
low-fidelity ones, each built by the study's model factory as ``make_model(inputs, responses,
fixed, model=NAME)`` (a study's ``[models.NAME]`` tables). The report shows the allocation (runs and
measured cost per model), the estimates with their standard errors and the high-fidelity runs
plain Monte Carlo would need for the same standard errors.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..errors import ParameterError
from ..render.tables import StepTable, cell, label, make_table
from ..results import StepRecord, StepResult
from ._common import named_model, saved_record
from .base import StepCheck, StepContext, StepType
from .options import (
    REQUIRED,
    SIGNATURE,
    Option,
    boolean,
    choice,
    integer,
    number,
    number_list,
    string,
    string_list,
)

__all__ = ["STEP", "MultifidelityRecord", "run_multifidelity", "multifidelity_tables",
           "multifidelity_warnings", "HF_LABEL", "why_dearer"]

_METHOD = "rotoruq.methods.multifidelity:multifidelity_sample"
#: How the report names the study's own ``[model]`` (the high-fidelity one).
HF_LABEL = "model"


@dataclass(frozen=True, eq=False)
class MultifidelityRecord(StepRecord):
    """What a multifidelity step saves: K models (the study's ``[model]`` first, named
    :data:`HF_LABEL`), m responses, s statistics.

    models (K), names_out (m), statistics (s) : the statistics estimated ("mean",
    "variance"; "mean" alone for "mlblue"). estimator : "mfmc", "acvmf", "acvis", "gmf",
    "grd", "gis" or "mlblue" (for ``estimator = "auto"`` the one chosen; the metadata's
    ``estimator_choice`` says why, ``recursion`` gives its recursion index); target : the
    response the
    allocation was optimised for. cost (K,) : cost of one run of each model (seconds when
    ``costs_measured``, else the given cost units); runs (K,) : pilot plus main-phase runs;
    allocation (K,) : main-phase runs; used (K,) 1.0 / 0.0 : whether the estimator uses the
    model; correlation (K, m) : pilot correlation with the high-fidelity model (of the
    adapted models, leave-one-out, when ``adapt`` is "linear"); correlation_unadapted (K, m) :
    the models' own. adapt : "none" or "linear". mean, mean_se,
    variance, variance_se, std (m,) : the estimates and their standard errors.
    n_equivalent_hf, speedup (s, m) : high-fidelity runs plain Monte Carlo needs for the same
    standard error, and their cost over this step's. budget, cost_pilot, cost_main : cost of
    the main phase given and spent, and of the pilot; n_pilot : pilot points.
    names_in (d) : the inputs. sobol : whether the Sobol' indices were estimated (their
    arrays are NaN otherwise); sobol_main, sobol_main_se, sobol_total, sobol_total_se,
    sobol_n_equivalent_hf_main, sobol_n_equivalent_hf_total (m, d) : the indices, their
    standard errors and the high-fidelity runs plain pick-and-freeze needs for the same
    standard errors; sobol_allocation (K,) : main-phase base samples (d + 2 runs each);
    sobol_cost (1,) : the cost of the Sobol' pilot and main phase. groups (G) and
    group_allocation (G,) : for "mlblue", the groups of models given points (names joined
    by "+") and their main-phase points (empty for the other estimators and in records
    saved before them).

    Its flat view: ``budget``, ``cost_pilot``, ``cost_main``; per model ``cost/``, ``runs/``,
    ``allocation/``, ``used/``, ``correlation/<model>/<response>``; per response ``mean/``,
    ``mean_se/``, ``variance/``, ``variance_se/``, ``std/`` and
    ``n_equivalent_hf/<statistic>/``, ``speedup/<statistic>/``; with ``sobol``,
    ``sobol_main/<response>/<input>`` and the other Sobol' arrays.
    """

    AXES = {**{k: ("model",) for k in ("cost", "runs", "allocation", "used")},
            "correlation": ("model", "response"),
            "correlation_unadapted": ("model", "response"),
            **{k: ("response",) for k in ("mean", "mean_se", "variance", "variance_se", "std")},
            "n_equivalent_hf": ("statistic", "response"), "speedup": ("statistic", "response"),
            **{f"sobol_{k}": ("response", "input") for k in (
                "main", "main_se", "total", "total_se", "n_equivalent_hf_main",
                "n_equivalent_hf_total")},
            "sobol_allocation": ("model",), "sobol_cost": ("cost",),
            "group_allocation": ("group",)}
    LABELS = {"model": "models", "statistic": "statistics", "group": "groups"}

    models: tuple[str, ...]
    names_out: tuple[str, ...]
    statistics: tuple[str, ...]
    estimator: str
    target: str
    costs_measured: bool
    cost: np.ndarray
    runs: np.ndarray
    allocation: np.ndarray
    used: np.ndarray
    correlation: np.ndarray
    mean: np.ndarray
    mean_se: np.ndarray
    variance: np.ndarray
    variance_se: np.ndarray
    std: np.ndarray
    n_equivalent_hf: np.ndarray
    speedup: np.ndarray
    budget: float
    cost_pilot: float
    cost_main: float
    n_pilot: int
    adapt: str
    correlation_unadapted: np.ndarray
    names_in: tuple[str, ...]
    sobol: bool
    sobol_main: np.ndarray
    sobol_main_se: np.ndarray
    sobol_total: np.ndarray
    sobol_total_se: np.ndarray
    sobol_n_equivalent_hf_main: np.ndarray
    sobol_n_equivalent_hf_total: np.ndarray
    sobol_allocation: np.ndarray
    sobol_cost: np.ndarray
    groups: tuple[str, ...] = ()
    group_allocation: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def statistic(self, name: str, values: np.ndarray, k: int) -> float:
        """Row ``name`` of a (s, m) array at response ``k``; NaN when not estimated."""
        return float(values[self.statistics.index(name), k]) if name in self.statistics \
            else float("nan")


def run_multifidelity(ctx: StepContext) -> StepResult:
    from ..methods.multifidelity import multifidelity_sample

    o = ctx.options
    hf = o.get("high_fidelity")
    names = (hf or HF_LABEL, *o["models"])
    models = ([named_model(ctx, hf) if hf else ctx.model()]
              + [named_model(ctx, n) for n in o["models"]])
    costs = o.get("costs")
    if costs is not None and len(costs) != len(models):
        raise ParameterError(f"step {ctx.name!r}: costs has {len(costs)} values; it needs one "
                             f"per model ({', '.join(names)})")
    rng_moments, rng_sobol = ctx.rng.spawn(2) if o["sobol"] else (ctx.rng, None)
    # the estimators' own warnings (a pilot too small, pilot points that failed) go into the
    # step's record, so the summary, `rotoruq show` and the report state them
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = multifidelity_sample(models, ctx.space, o["budget"], budget_unit=o["budget_unit"],
                                   estimator=o["estimator"], n_pilot=o["n_pilot"], costs=costs,
                                   adapt=o["adapt"], seed=rng_moments)
    k_models = len(names)
    d, m = ctx.space.dim, len(ctx.responses)
    nan = np.full((m, d), np.nan)
    sob = {"main": nan, "main_se": nan, "total": nan, "total_se": nan,
           "n_equivalent_hf_main": nan, "n_equivalent_hf_total": nan}
    sob_alloc, sob_cost, n_sobol_evals = np.zeros(k_models), np.array([0.0]), 0
    if o["sobol"]:
        from ..methods.multifidelity_sobol import multifidelity_sobol

        with warnings.catch_warnings(record=True) as caught_sobol:
            warnings.simplefilter("always")
            sr = multifidelity_sobol(models, ctx.space, o["budget"],
                                     budget_unit=o["budget_unit"], estimator=o["estimator"],
                                     n_pilot=o["n_pilot"],
                                     costs=[float(c) for c in res.costs], seed=rng_sobol)
        caught += caught_sobol
        sob = {k: np.asarray(v, dtype=float) for k, v in (
            ("main", sr.main), ("main_se", sr.main_se), ("total", sr.total),
            ("total_se", sr.total_se), ("n_equivalent_hf_main", sr.n_equivalent_hf["main"]),
            ("n_equivalent_hf_total", sr.n_equivalent_hf["total"]))}
        sob_alloc = np.asarray(sr.allocation, dtype=float)
        sob_cost = np.array([sr.cost_pilot + sr.cost_main])
        n_sobol_evals = int(sr.n_evaluations)
    record = MultifidelityRecord(
        names, tuple(ctx.responses), tuple(res.statistics), res.estimator, res.target,
        bool(res.costs_measured), np.asarray(res.costs, dtype=float)[:k_models],
        np.asarray(res.allocation, dtype=float) + res.n_pilot,
        np.asarray(res.allocation, dtype=float),
        np.array([float(k in res.models_used) for k in range(k_models)]),
        np.asarray(res.correlation, dtype=float).T, np.asarray(res.mean, dtype=float),
        np.asarray(res.mean_se, dtype=float), np.asarray(res.variance, dtype=float),
        np.asarray(res.variance_se, dtype=float), np.asarray(res.std, dtype=float),
        np.array([np.asarray(res.n_equivalent_hf[s], dtype=float) for s in res.statistics]
                 ).reshape(len(res.statistics), len(ctx.responses)),
        np.array([np.asarray(res.speedup[s], dtype=float) for s in res.statistics]
                 ).reshape(len(res.statistics), len(ctx.responses)),
        float(res.budget), float(res.cost_pilot), float(res.cost_main), int(res.n_pilot),
        res.adapt, np.asarray(res.correlation_unadapted, dtype=float).T,
        tuple(ctx.space.names), bool(o["sobol"]),
        sob["main"], sob["main_se"], sob["total"], sob["total_se"],
        sob["n_equivalent_hf_main"], sob["n_equivalent_hf_total"], sob_alloc, sob_cost,
        *_group_fields(res, names))
    arrays, meta = record.parts()
    return StepResult(ctx.name, ctx.type, {}, arrays, meta={
        "models": list(names), "responses": list(ctx.responses), "estimator": res.estimator,
        "target": res.target,
        "recursion": [int(g) for g in getattr(res.plan, "recursion", ())],
        "estimator_choice": res.choice.reason if res.choice is not None else "",
        "n_pilot": res.n_pilot, "costs_measured": res.costs_measured,
        "n_evaluations": int(res.n_evaluations) + n_sobol_evals,
        "warnings": list(dict.fromkeys(str(w.message) for w in caught)), **meta})


def _group_fields(res, names: tuple[str, ...]) -> tuple[tuple[str, ...], np.ndarray]:
    """MLBLUE's groups with points (model names joined by "+") and their points."""
    used = getattr(res.plan, "used_groups", None)
    if used is None:
        return (), np.zeros(0)
    pairs = used()
    return (tuple("+".join(names[k] for k in g) for g, _ in pairs),
            np.array([float(n) for _, n in pairs]))


def multifidelity_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    rec = MultifidelityRecord.read(res)
    unit = "s" if rec.costs_measured else "cost units"
    adapted = rec.adapt != "none"
    n_out = len(rec.names_out)
    corr_cols = [f"correlation with HF{', adapted' if adapted else ''}: {label(r, labels)}"
                 for r in rec.names_out]
    if adapted:
        corr_cols += [f"correlation with HF, own: {label(r, labels)}" for r in rec.names_out]
    alloc = make_table(
        f"Allocation ({rec.estimator}, {rec.n_pilot}-point pilot)",
        ("model", f"cost per run [{unit}]", "pilot + main runs", *corr_cols),
        [[m + ("" if rec.used[k] else " (not used)"), cell(rec.cost[k]), cell(rec.runs[k]),
          *(cell(rec.correlation[k, j]) for j in range(n_out)),
          *((cell(rec.correlation_unadapted[k, j]) for j in range(n_out)) if adapted else ())]
         for k, m in enumerate(rec.models)],
        note=f"Budget {rec.budget:.4g} {unit} for the main phase (spent "
             f"{rec.cost_main:.4g}) plus the pilot's {rec.cost_pilot:.4g}."
             + (" Low-fidelity models adapted on the pilot (a linear map of their response "
                "and the inputs): the estimator uses the adapted model's correlation "
                "(leave-one-out on the pilot); the model's own is beside it."
                + _kept_as_evaluated(rec, labels) if adapted else "")
             + (" MLBLUE points per group of models (each group's models run on its own "
                "points): " + ", ".join(f"{g} {int(n)}" for g, n in zip(
                    rec.groups, rec.group_allocation, strict=True)) + "."
                if len(rec.groups) else ""))
    est = make_table(
        "Multi-fidelity estimates",
        ("response", "mean", "mean std. error", "std", "variance", "variance std. error",
         "HF runs plain MC needs (mean)", "HF runs plain MC needs (variance)",
         "cost saving (mean)"),
        [[label(r, labels), cell(rec.mean[k]), cell(rec.mean_se[k]), cell(rec.std[k]),
          cell(rec.variance[k]), cell(rec.variance_se[k]),
          cell(rec.statistic("mean", rec.n_equivalent_hf, k)),
          cell(rec.statistic("variance", rec.n_equivalent_hf, k)),
          cell(rec.statistic("mean", rec.speedup, k))] for k, r in enumerate(rec.names_out)],
        note="Standard errors predicted from the pilot's covariances and the allocation; "
             "plain MC: the high-fidelity runs whose sample mean (variance) has the same "
             "standard error; cost saving: their cost over this step's (pilot included).")
    tables = [alloc, est]
    if rec.sobol:
        tables.append(make_table(
            f"Sobol' indices (multi-fidelity, {rec.estimator})",
            ("response", "input", "main", "main std. error", "total", "total std. error",
             "HF runs plain pick-freeze needs (main)", "HF runs plain pick-freeze needs "
             "(total)"),
            [[label(r, labels), label(x, labels), cell(rec.sobol_main[j, i]),
              cell(rec.sobol_main_se[j, i]), cell(rec.sobol_total[j, i]),
              cell(rec.sobol_total_se[j, i]), cell(rec.sobol_n_equivalent_hf_main[j, i]),
              cell(rec.sobol_n_equivalent_hf_total[j, i])]
             for j, r in enumerate(rec.names_out) for i, x in enumerate(rec.names_in)],
            note="Pick-freeze base samples per model (d + 2 runs each): "
                 + ", ".join(f"{m} {int(rec.sobol_allocation[k])}"
                             for k, m in enumerate(rec.models))
                 + f"; cost {cell(rec.sobol_cost[0])} {unit} (its own pilot included, on top "
                 "of the moments'). The indices are ratios of unbiased estimates (bias "
                 "O(1/N) in the HF base samples); standard errors by the delta method from "
                 "the pilot's moments."))
    return tables


def _kept_as_evaluated(rec: MultifidelityRecord, labels: Mapping[str, str]) -> str:
    """The note's sentence on the (model, response) pairs whose adaptation was not used (their
    pilot values, and so their correlation, are the model's own, bitwise)."""
    kept = [f"{m} for {label(r, labels)}" for k, m in enumerate(rec.models) if m != HF_LABEL
            for j, r in enumerate(rec.names_out)
            if rec.correlation[k, j] == rec.correlation_unadapted[k, j]]
    return (" Kept as evaluated (the adaptation correlated worse, leave-one-out): "
            + ", ".join(kept) + "." if kept else "")


def multifidelity_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    rec = saved_record(MultifidelityRecord, res)
    if rec is None:
        return []
    out = []
    for k, m in enumerate(rec.models):
        if m != HF_LABEL and not rec.used[k]:
            out.append(f"low-fidelity model {m!r} was left out: its correlation with the "
                       "high-fidelity model does not pay for its cost")
    for k, r in enumerate(rec.names_out):
        s = rec.statistic("mean", rec.speedup, k)
        if s < 1.0:
            out.append(f"{label(r, labels)}: the multi-fidelity mean costs {1 / s:.2g} times "
                       "what plain Monte Carlo on the high-fidelity model would for the same "
                       f"standard error (pilot included): {_why_dearer(rec, k, labels)}")
    out.extend(res.meta.get("warnings", []) or [])
    return out


def _why_dearer(rec: MultifidelityRecord, k: int, labels: Mapping[str, str]) -> str:
    lf = [i for i, m in enumerate(rec.models) if m != HF_LABEL and rec.used[i]]
    return why_dearer(
        main=rec.statistic("mean", rec.n_equivalent_hf, k) * rec.cost[0] / rec.cost_main,
        pilot_share=rec.cost_pilot / (rec.cost_pilot + rec.cost_main),
        rho=max((abs(rec.correlation[i, k]) for i in lf), default=0.0),
        target=None if rec.names_out[k] == rec.target else label(rec.target, labels))


def why_dearer(main: float, pilot_share: float, rho: float, target: str | None,
               of: str = "it") -> str:
    """Why a multi-fidelity estimate costs more than plain Monte Carlo, from the run's numbers.

    Parameters
    ----------
    main : the main phase's own saving (plain-MC cost of the same standard error over the
        main phase's cost, pilot left out).
    pilot_share : the pilot's fraction of the cost, pilot included.
    rho : the largest |correlation| on the pilot of a used cheap model with what the
        estimator's control variate needs: the response for a mean, its squared deviations
        for a variance.
    target : the response the allocation was made for, when it is another one.
    of : how the sentence names what ``rho`` correlates ("it": the response).

    Examples
    --------
    >>> why_dearer(2.5, 0.89, 0.99, None)
    "the main phase alone saves 2.5x, and the pilot is 89% of the step's cost"
    >>> print(why_dearer(0.5, 0.3, 0.42, "thrust", of="its squared deviations"))
    the main phase alone costs 2x plain Monte Carlo: the cheap models used correlate with its
    squared deviations at |rho| <= 0.42 on the pilot, and the allocation was made for thrust
    """
    if main >= 1.0:
        return (f"the main phase alone saves {main:.2g}x, and the pilot is {pilot_share:.0%} "
                "of the step's cost")
    why = (f"the main phase alone costs {1 / main:.2g}x plain Monte Carlo: the cheap models "
           f"used correlate with {of} at |rho| <= {rho:.2f} on the pilot")
    return why + (f", and the allocation was made for {target}" if target else "")


def _check(c: StepCheck) -> None:
    if not c.options["models"]:
        c.fail(("models",), "a list of low-fidelity model names", "[]")
    if c.options.get("sobol") and c.options.get("estimator") not in ("mfmc", "acvmf", "acvis"):
        est = str(c.options.get("estimator"))
        why = ("mlblue estimates the mean only" if est == "mlblue"
               else "the Sobol' indices have those allocations")
        c.fail(("estimator",), f"mfmc, acvmf or acvis with sobol = true ({why})", est)
    hf = c.options.get("high_fidelity")
    if hf and hf in c.options["models"]:
        c.fail(("models",), f"low-fidelity models other than the high_fidelity {hf!r}",
               str(list(c.options["models"])))
    costs = c.options.get("costs")
    if costs is not None and len(costs) != len(c.options["models"]) + 1:
        first = f"the high_fidelity {hf!r}" if hf else "[model]"
        c.fail(("costs",), f"{len(c.options['models']) + 1} costs ({first} first, then "
               "each of models)", str(list(costs)))


STEP = StepType(
    "multifidelity", run_multifidelity, method=_METHOD,
    options={"models": Option(string_list, REQUIRED),
             "budget": Option(number(positive=True, allow_zero=False), SIGNATURE),
             "budget_unit": Option(choice("cost", "hf_runs"), SIGNATURE),
             "estimator": Option(choice("mfmc", "acvmf", "acvis", "gmf", "grd", "gis", "mlblue",
                                       "auto"), SIGNATURE),
             "n_pilot": Option(integer(4), SIGNATURE),
             "adapt": Option(choice("none", "linear"), SIGNATURE),
             "sobol": Option(boolean, False),
             "costs": Option(number_list, None),
             "high_fidelity": Option(string(), None)},
    quick={"n_pilot": 10}, check=_check,
    tables=multifidelity_tables, warnings=multifidelity_warnings,
    modules=("rotoruq.methods.multifidelity", "rotoruq.methods.multifidelity_sobol",
             "rotoruq.methods.acv", "rotoruq.methods.mf_choice", "rotoruq.methods.mf_pilot",
             "rotoruq.methods.mlblue"))
