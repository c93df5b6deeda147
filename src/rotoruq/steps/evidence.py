"""Step type ``evidence``: Dempster-Shafer belief and plausibility of response levels from
interval inputs with basic probability assignments."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import SimpleNamespace

from ..params import ParameterSpace
from ..render.tables import StepTable
from ..results import StepResult
from ._common import (
    LEVEL_OPTIONS,
    LevelsRecord,
    check_levels,
    level_request_of,
    levels_arrays,
)
from .base import StepCheck, StepContext, StepType
from .options import REQUIRED, SIGNATURE, Option, choice, integer, number, table

__all__ = ["STEP", "EvidenceRecord", "run_evidence", "evidence_tables", "QUANTITIES"]

#: The per-level quantities an evidence step saves (the names of
#: :func:`rotoruq.methods.levels.evidence_mappings`, belief and plausibility named after the
#: step's distribution and compute: ``cbf``/``cpf`` for a CDF's probabilities, ``ccbf``/
#: ``ccpf`` for a CCDF's, with ``_gen_reliability`` for generalized reliabilities).
QUANTITIES = ("response_levels", "cbf", "cpf")
_INVERSE = ("probability_levels", "belief_response", "plausibility_response",
            "gen_reliability_levels", "belief_gen_response", "plausibility_gen_response")
#: The level tables an evidence step takes (Dakota's global_evidence: no reliability levels).
EVIDENCE_LEVELS = ("response_levels", "probability_levels", "gen_reliability_levels")


@dataclass(frozen=True, eq=False)
class EvidenceRecord(LevelsRecord):
    """What an evidence step saves: the :class:`~rotoruq.steps._common.LevelsRecord` of
    the response levels and their belief and plausibility (``cbf``, ``cpf`` for a CDF,
    ``ccbf``, ``ccpf`` for a CCDF, ``..._gen_reliability`` with ``compute =
    "gen_reliabilities"``), and of the probability and generalized reliability levels and
    their belief and plausibility response levels; optimizer : how each cell's extremes were
    found ("ego", "sampling"); converged : False when EGO stopped at its evaluation budget."""

    optimizer: str
    converged: bool


def evidence_quantities(distribution: str, compute: str) -> tuple[str, str]:
    """The record's names of belief and plausibility for ``distribution`` and ``compute``."""
    pre = "c" if distribution == "cdf" else "cc"
    suffix = "_gen_reliability" if compute == "gen_reliabilities" else ""
    return f"{pre}bf{suffix}", f"{pre}pf{suffix}"


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
    from ..methods.levels import evidence_mappings

    res = evidence(ctx.make_model(space.names, ctx.responses, fixed), space,
                   optimizer=o["optimizer"], n_samples=o["n_samples"],
                   tolerance=o["tolerance"], seed=ctx.rng)
    request = level_request_of(ctx)
    maps = {} if request is None else evidence_mappings(res.cell_min, res.cell_max,
                                                        res.cell_bpa, request)
    bel, pl = evidence_quantities(o["distribution"], o["compute"])
    names = {"belief": bel, "plausibility": pl}
    quantities = tuple(names.get(q, q) for q in maps)
    values, counts = levels_arrays(
        SimpleNamespace(**{names.get(q, q): v for q, v in maps.items()}), quantities,
        ctx.responses)
    keep = [i for i, q in enumerate(quantities) if counts[i].any() or q in (
        "response_levels", bel, pl)]
    record = EvidenceRecord(tuple(ctx.responses), tuple(quantities[i] for i in keep),
                            values[keep], counts[keep], o["optimizer"],
                            bool(getattr(res, "converged", True)))
    arrays, meta = record.parts()
    return StepResult(ctx.name, ctx.type, {}, arrays, meta={
        "n_evaluations": int(res.n_evaluations), "optimizer": o["optimizer"],
        "converged": record.converged, **meta})


def evidence_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    rec = EvidenceRecord.read(res)
    ccdf = "ccbf" in "".join(rec.quantities)
    return rec.tables("Complementary belief (CCBF) and plausibility (CCPF): g > level"
                      if ccdf else "Belief (CBF) and plausibility (CPF): g < level")


def _check_intervals(c: StepCheck) -> None:
    for p in c.options["intervals"]:
        if p not in c.parameters:
            c.fail(("intervals", p), "intervals keyed by names from [parameters]", p)
    check_levels(c, EVIDENCE_LEVELS, ("probabilities", "gen_reliabilities"))


STEP = StepType(
    "evidence", run_evidence, method="rotoruq.methods.evidence:evidence",
    options={"intervals": Option(table, REQUIRED),
             "optimizer": Option(choice("ego", "sampling"), SIGNATURE),
             "n_samples": Option(integer(1), SIGNATURE),
             "tolerance": Option(number(positive=True, allow_zero=False), SIGNATURE),
             **{k: v for k, v in LEVEL_OPTIONS.items() if k != "reliability_levels"}},
    quick={"n_samples": 20}, check=_check_intervals, tables=evidence_tables)
