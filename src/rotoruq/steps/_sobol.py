"""The report parts the Sobol-index step types share (``sensitivity`` and ``pce``): the
tornado figure and the negligible-variance warning. Kept apart from either step's module so
that each one's fingerprint covers its own method only."""

from __future__ import annotations

import math
from collections.abc import Mapping

from ..render.figures import Figure, FigureContext, beside_label, beside_sobol, tornado
from ..render.tables import prefixed
from ..results import StepResult

__all__ = ["sensitivity_figures", "sobol_warnings"]


def sensitivity_figures(res: StepResult, ctx: FigureContext) -> list[Figure]:
    """Tornado of main/total indices (sensitivity and pce steps), with the main indices the
    report's application gives for this step beside them (``ctx.beside``)."""
    if "inputs" not in res.meta:
        return []
    return tornado(res, ctx.labels, ctx.units, beside_sobol(ctx, res.name), beside_label(ctx))


def sobol_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    """Sobol indices of a response with negligible variance (sensitivity, pce)."""
    return [f"{res.name}: {r} has negligible variance (std "
            f"{res.get(f'out_std/{r}', math.nan):.3g}, {res.get(f'out_cv/{r}', math.nan):.1e} of "
            "its mean): its Sobol indices split up numerical noise"
            for r, flag in prefixed(res, "negligible/").items() if flag]

