"""Step type ``evidence``: Dempster-Shafer belief and plausibility of response levels from
interval inputs with basic probability assignments."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from ..params import ParameterSpace
from ..render.tables import StepTable
from ..results import StepResult
from ._common import LevelsRecord, levels_arrays
from .base import StepCheck, StepContext, StepType
from .options import REQUIRED, SIGNATURE, Option, choice, integer, number, table

__all__ = ["STEP", "EvidenceRecord", "run_evidence", "evidence_tables", "QUANTITIES"]

#: The per-level quantities an evidence step saves: the levels, cumulative belief and
#: plausibility of response <= level.
QUANTITIES = ("response_levels", "cbf", "cpf")


@dataclass(frozen=True, eq=False)
class EvidenceRecord(LevelsRecord):
    """What an evidence step saves: the :class:`~rotoruq.steps._common.LevelsRecord` of
    :data:`QUANTITIES`; optimizer : how each cell's extremes were found ("ego",
    "sampling"); converged : False when EGO stopped at its evaluation budget."""

    optimizer: str
    converged: bool


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
    record = EvidenceRecord(tuple(ctx.responses), QUANTITIES,
                            *levels_arrays(res, QUANTITIES, ctx.responses), o["optimizer"],
                            bool(getattr(res, "converged", True)))
    arrays, meta = record.parts()
    return StepResult(ctx.name, ctx.type, record.scalars(), arrays, meta={
        "n_evaluations": int(res.n_evaluations), "optimizer": o["optimizer"],
        "converged": record.converged, **meta})


def evidence_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    return EvidenceRecord.read(res).tables(
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
