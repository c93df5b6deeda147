"""How the report renders a step type: its tables, figures and warnings.

The renderers live with their step type (:mod:`rotoruq.steps`, one module per type); the
report looks them up here by a saved result's ``type``. Nothing writes into this lookup: it
reads the step registry, so the report renders the same in a fresh interpreter as after the
study layer ran. A type rotoruq does not know (an older result, a plugin not installed) gets
a generic key/value table, no figures and no warnings.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..render.figures import FigureContext
from ..steps import find_step_type
from ..steps.base import FiguresHook, TablesHook, WarningsHook

__all__ = ["FigureContext", "Rendering", "rendering"]


@dataclass(frozen=True, eq=False)
class Rendering:
    """The renderers of one step type (each may be None).

    tables(result, labels) -> list of :class:`~rotoruq.render.tables.StepTable`;
    figures(result, context) -> list of :class:`~rotoruq.render.figures.Figure`;
    warnings(result, labels) -> list of warning sentences.
    """

    tables: TablesHook | None = None
    figures: FiguresHook | None = None
    warnings: WarningsHook | None = None


_NONE = Rendering()


def rendering(step_type: str) -> Rendering:
    """The renderers of ``step_type`` (all None for a type rotoruq does not know)."""
    st = find_step_type(step_type)
    return _NONE if st is None else Rendering(st.tables, st.figures, st.warnings)
