"""The report's figures of a study: each saved step's type's ``figures`` renderer (the
renderers live with their step type in :mod:`rotoruq.steps`, the drawing primitives in
:mod:`rotoruq.render.figures`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..render.figures import Figure, FigureContext, _subplots
from ..results import StepResult
from .hooks import rendering

__all__ = ["figures_for_study", "step_figures"]


def figures_for_study(study: str, steps: Mapping[str, StepResult], labels: Mapping[str, str],
                      units: Mapping[str, str] | None = None,
                      beside: Mapping[str, Any] | None = None,
                      curves: Mapping[str, Mapping[str, list]] | None = None
                      ) -> list[Figure]:
    """All figures for one study's saved steps, in step order: each step's type's ``figures``
    renderer (:mod:`rotoruq.report.hooks`). ``beside``: numbers an application has drawn
    beside the run's (:attr:`rotoruq.render.figures.FigureContext.beside`). ``curves``:
    reference curves the run recorded (``study.json`` ``model.curves``)."""
    ctx = FigureContext(study, steps, labels, units or {}, beside, curves or {})
    figs: list[Figure] = []
    for res in steps.values():
        hook = rendering(res.type).figures
        if hook is not None:
            figs += step_figures(hook, res, ctx)
    return figs


def step_figures(hook, res: StepResult, ctx: FigureContext) -> list[Figure]:
    """The figures ``hook`` (a step type's ``figures`` renderer) draws for ``res``; a figure
    never fails the report: a hook that raises on missing data gives a one-line note."""
    try:
        return list(hook(res, ctx))
    except (KeyError, ValueError, IndexError) as exc:
        fig, ax = _subplots(figsize=(5, 1))
        ax.axis("off")
        ax.text(0.0, 0.5, f"{res.name}: figure not drawn ({exc})", fontsize=8)
        return [Figure(f"{res.name}_missing", f"{res.name}: no figure", fig)]
