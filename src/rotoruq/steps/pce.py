"""Step type ``pce``: polynomial chaos expansion (quadrature, sparse grid or regression),
its moments and the Sobol indices read from its coefficients."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..render.tables import StepTable, label, make_table
from ..results import StepResult
from ._common import (
    LEVEL_OPTIONS,
    MappingsRecord,
    check_levels,
    level_request_of,
    mapping_fields,
)
from ._sobol import sensitivity_figures, sensitivity_sweep_figures, sobol_warnings
from .base import StepCheck, StepContext, StepType
from .options import SIGNATURE, Option, choice, integer, table

__all__ = ["STEP", "PceRecord", "run_pce", "pce_tables", "SOLVERS"]

#: ``polynomial_chaos(solver=)``'s choices (methods.pce.SOLVERS; spelled out so that importing
#: the step types does not import the method)
SOLVERS = ("least_squares", "omp", "lars", "lasso")


@dataclass(frozen=True, eq=False)
class PceRecord(MappingsRecord):
    """What a pce step saves: m responses, d inputs.

    names_in (d), names_out (m); mean, std (m,) of the expansion; main, total (m, d) Sobol
    indices read from its coefficients; the level mappings
    (:class:`~rotoruq.steps._common.MappingsRecord`) as Dakota's expansion methods compute
    them: reliabilities from the expansion's mean and std, probabilities and generalized
    reliabilities from ``samples_on_expansion`` samples of the expansion; samples_on_expansion :
    how many (0: none drawn).
    """

    AXES = {"mean": ("response",), "std": ("response",), "main": ("response", "input"),
            "total": ("response", "input"), **MappingsRecord.AXES}
    FLAT = {"main": "S", "total": "T", **MappingsRecord.FLAT}

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    mean: np.ndarray
    std: np.ndarray
    main: np.ndarray
    total: np.ndarray
    samples_on_expansion: int = 0


def run_pce(ctx: StepContext) -> StepResult:
    """Polynomial chaos of total order ``order`` by ``estimator`` (quadrature, sparse grid,
    or regression on ``n_samples`` LHS points); level mappings as Dakota's expansion
    methods: reliabilities from the expansion's moments, probabilities and generalized
    reliabilities from ``samples_on_expansion`` LHS samples of the expansion (drawn after the
    fit from the step's generator)."""
    from ..methods.levels import sample_mappings
    from ..methods.pce import polynomial_chaos
    from ..methods.sampling import sample

    o = ctx.options
    pref = o.get("dimension_preference")
    res = polynomial_chaos(ctx.model(), ctx.space, o["order"], estimator=o["estimator"],
                           n_samples=o["n_samples"], solver=o["solver"], seed=ctx.rng,
                           dimension_preference=None if not pref else
                           [float(pref.get(n, np.nan)) for n in ctx.space.names])
    request = level_request_of(ctx)
    n_exp = int(o.get("samples_on_expansion") or 0)
    on_expansion = None
    if request is not None and n_exp and request.needs_samples():
        on_expansion = np.asarray(sample(res.as_model(), ctx.space, n_exp,
                                         seed=ctx.rng).outputs, dtype=float)
    mappings = None if request is None else sample_mappings(
        on_expansion, request, mean=np.asarray(res.mean), std=np.asarray(res.std))
    record = PceRecord(tuple(ctx.space.names), tuple(ctx.responses),
                       np.asarray(res.mean, dtype=float), np.asarray(res.std, dtype=float),
                       np.asarray(res.main), np.asarray(res.total),
                       0 if on_expansion is None else n_exp, **mapping_fields(mappings))
    arrays, meta = record.parts()
    return StepResult(ctx.name, ctx.type, {}, arrays, meta={
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
    out.extend(rec.mapping_tables(rec.names_out, (
        f"Probabilities from {rec.samples_on_expansion} samples of the expansion; reliabilities "
        "from its mean and std." if rec.samples_on_expansion else
        "Projection of the expansion's mean and std (no samples of the expansion).")))
    return out


def _check_pce(c: StepCheck) -> None:
    if c.options["n_samples"] is not None and c.options["estimator"] not in (
            "regression", "sampling"):
        c.fail(("n_samples",), "n_samples only with estimator = \"regression\" or "
               "\"sampling\" (quadrature and sparse grids choose their own points)",
               str(c.options["n_samples"]))
    pref = c.options.get("dimension_preference")
    if pref:
        if c.options["estimator"] != "quadrature":
            c.fail(("dimension_preference",), "dimension_preference only with estimator = "
                   "\"quadrature\" (an anisotropic tensor grid)")
        names = set(c.parameters)
        if not set(pref) <= names or any(not isinstance(v, int | float) or isinstance(v, bool)
                                         or not v > 0 for v in pref.values()):
            c.fail(("dimension_preference",), "a positive number for each of the step's "
                   f"inputs (of {', '.join(sorted(names))})", str(dict(pref)))
    check_levels(c)
    o = c.options
    numerical = [k for k in ("response_levels", "probability_levels",
                             "gen_reliability_levels") if o.get(k)
                 and (k != "response_levels" or o.get("compute") != "reliabilities")]
    if numerical and not o.get("samples_on_expansion"):
        what = [f"response_levels with compute = {o.get('compute')!r}" if k == "response_levels"
                else k for k in numerical]
        c.fail((numerical[0],), f"samples_on_expansion = N (samples of the expansion) for "
               f"{', '.join(what)} (as Dakota, which needs samples on the expansion for these; "
               "without them only compute = \"reliabilities\" and reliability_levels, from "
               "the expansion's moments)")
    if o.get("samples_on_expansion") and not numerical:
        c.fail(("samples_on_expansion",), "samples_on_expansion only with probability or "
               "generalized reliability mappings (levels that need them)",
               str(o["samples_on_expansion"]))


STEP = StepType(
    "pce", run_pce, method="rotoruq.methods.pce:polynomial_chaos", correlated=True,
    options={"order": Option(integer(1), SIGNATURE),
             "estimator": Option(choice("quadrature", "sparse_grid", "regression", "sampling"),
                                 SIGNATURE),
             "dimension_preference": Option(table, None),
             "n_samples": Option(integer(1), SIGNATURE),
             "solver": Option(choice(*SOLVERS), SIGNATURE),
             "samples_on_expansion": Option(integer(2), None),
             **LEVEL_OPTIONS},
    quick={"n_samples": 40}, check=_check_pce,
    tables=pce_tables, figures=sensitivity_figures, warnings=sobol_warnings,
    sweep_figures=sensitivity_sweep_figures,
    modules=("rotoruq.methods.levels", "rotoruq.methods.sampling"))
