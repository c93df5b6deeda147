"""How the report renders a step type: its tables, figures and warnings.

The report reads saved :class:`~rotoruq.results.StepResult` objects and looks up the renderers
of each one's ``type`` here. The step-type registry (:mod:`rotoruq.study.steptypes`) fills
this table when a step type is registered, from the ``tables``, ``figures`` and ``warnings``
hooks of its record; the report itself never imports the study layer. A type without
renderers gets a generic key/value table and no figures.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from ..results import StepResult

__all__ = ["FigureContext", "Rendering", "register_rendering", "rendering", "RENDERINGS"]


@dataclass(frozen=True, eq=False)
class FigureContext:
    """What a figure hook may use besides its own step.

    study : the study's name. steps : every saved step of the study (name -> result).
    labels, units : display label and unit per input/response name.
    reference : the study is a reference study (thesis numbers are drawn beside ours).
    curves : reference curves the run recorded (``study.json`` ``model.curves``).
    """

    study: str
    steps: Mapping[str, StepResult]
    labels: Mapping[str, str] = field(default_factory=dict)
    units: Mapping[str, str] = field(default_factory=dict)
    reference: bool = False
    curves: Mapping[str, Any] = field(default_factory=dict)


TablesHook = Callable[[StepResult, Mapping[str, str]], list]
FiguresHook = Callable[[StepResult, FigureContext], list]
WarningsHook = Callable[[StepResult, Mapping[str, str]], list]


@dataclass(frozen=True, eq=False)
class Rendering:
    """The renderers of one step type (each may be None).

    tables(result, labels) -> list of :class:`~rotoruq.report.steptables.StepTable`;
    figures(result, context) -> list of :class:`~rotoruq.report.plots.Figure`;
    warnings(result, labels) -> list of warning sentences.
    """

    tables: TablesHook | None = None
    figures: FiguresHook | None = None
    warnings: WarningsHook | None = None


RENDERINGS: dict[str, Rendering] = {}


def register_rendering(step_type: str, renderer: Rendering) -> None:
    """Render results of ``step_type`` with ``renderer`` (replaces an earlier one)."""
    RENDERINGS[step_type] = renderer


def rendering(step_type: str) -> Rendering:
    """The renderers of ``step_type`` (all None when none are registered)."""
    return RENDERINGS.get(step_type, _NONE)


_NONE = Rendering()
