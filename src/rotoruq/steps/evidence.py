"""Step type ``evidence``: Dempster-Shafer belief and plausibility of response levels from
interval inputs with basic probability assignments."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..params import ParameterSpace
from ..render.tables import StepTable, levels_tables
from ..results import StepResult
from .base import StepCheck, StepContext, StepType
from .options import REQUIRED, SIGNATURE, Option, choice, integer, number, table

__all__ = ["STEP", "run_evidence", "evidence_tables"]


def run_evidence(ctx: StepContext) -> StepResult:
    """Dempster-Shafer evidence: ``intervals = {x = [[lo, hi, bpa], ...]}`` per input."""
    from ..methods.evidence import evidence
    from ..params import Interval

    o = ctx.options
    space = ParameterSpace([
        (p, Interval(tuple((float(lo), float(hi)) for lo, hi, _ in cells),
                     tuple(float(w) for _, _, w in cells)))
        for p, cells in o["intervals"].items()])
    fixed = dict(ctx.fixed)
    fixed.update({p: d.mean for p, d in zip(ctx.space.names, ctx.space.distributions,
                                             strict=True) if p not in space.names})
    res = evidence(ctx.make_model(space.names, ctx.responses, fixed), space,
                   response_levels=o.get("response_levels"), optimizer=o["optimizer"],
                   n_samples=o["n_samples"], tolerance=o["tolerance"], seed=ctx.rng)
    scalars = {}
    for r in ctx.responses:
        for what in ("response_levels", "cbf", "cpf"):
            for i, v in enumerate(np.atleast_1d(getattr(res, what).get(r, []))):
                scalars[f"{what}/{r}/{i}"] = float(v)
    return StepResult(ctx.name, ctx.type, scalars, meta={
        "n_evaluations": int(res.n_evaluations), "optimizer": o["optimizer"],
        "converged": bool(getattr(res, "converged", True))})


def evidence_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    return levels_tables(res, ("response_levels", "cbf", "cpf"),
                         "Belief (CBF) and plausibility (CPF) of response <= level")


def _check_intervals(c: StepCheck) -> None:
    for p in c.options["intervals"]:
        if p not in c.parameters:
            c.fail(("intervals", p), "intervals keyed by names from [parameters]", p)


STEP = StepType(
    "evidence", run_evidence, method="rotoruq.methods.evidence:evidence",
    options={"intervals": Option(table, REQUIRED),
             "optimizer": Option(choice("ego", "sampling"), SIGNATURE),
             "n_samples": Option(integer(1), SIGNATURE),
             "tolerance": Option(number(positive=True, allow_zero=False), SIGNATURE),
             "response_levels": Option(table, SIGNATURE)},
    quick={"n_samples": 20}, check=_check_intervals, tables=evidence_tables)
