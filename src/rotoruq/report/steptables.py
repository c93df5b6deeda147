"""Tables of one saved step's own numbers, for every step type: what a user's study shows in
its report and what ``rotoruq show`` prints or exports.

:func:`step_tables` turns a :class:`~rotoruq.results.StepResult` into a list of
:class:`~rotoruq.render.tables.StepTable` (plain data) with its type's ``tables`` renderer
(each step type's module in :mod:`rotoruq.steps` holds its own); :func:`table_text`,
:func:`table_csv` and :meth:`StepTable.as_dict` render them for a terminal, a spreadsheet and
JSON. The HTML report renders the same tables (:func:`rotoruq.report.tables.step_table_html`).
"""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping

from ..render.tables import Cell, StepTable, make_table
from ..results import RecordError, StepResult
from .diagnostics import step_warnings
from .hooks import rendering

__all__ = ["StepTable", "step_tables", "table_text", "table_csv", "fmt_cell"]


def step_tables(res: StepResult, labels: Mapping[str, str] | None = None) -> list[StepTable]:
    """The tables of one step (its type's ``tables`` renderer, see
    :mod:`rotoruq.report.hooks`; a key/value table without one), then its warnings."""
    labels = labels or {}
    build = rendering(res.type).tables
    flat = [[k, float(v)] for k, v in res.scalars.items()]
    try:
        tables = build(res, labels) if build else [make_table("Results", ("key", "value"), flat)]
    except RecordError as exc:  # saved before its type had a record: the flat view, and why
        tables = [make_table("Results", ("key", "value"), flat, str(exc))]
    tables = [t for t in tables if t.rows]
    warns = step_warnings(res, labels)
    if warns:
        tables.append(make_table("Warnings", ("warning",), [[w] for w in warns]))
    return tables


def fmt_cell(v: Cell) -> str:
    from .tables import fmt

    if v is None:
        return "-"
    if isinstance(v, str):
        return v
    if isinstance(v, int):
        return str(v)
    return fmt(float(v))


def table_text(t: StepTable) -> str:
    """A plain-text table for a terminal."""
    cells = [list(t.columns)] + [[fmt_cell(v) for v in r] for r in t.rows]
    widths = [max(len(row[j]) for row in cells) for j in range(len(t.columns))]
    lines = [t.title, "  ".join(c.ljust(w) for c, w in zip(cells[0], widths, strict=True))]
    lines.append("  ".join("-" * w for w in widths))
    for row in cells[1:]:
        lines.append("  ".join(c.rjust(w) if j else c.ljust(w)
                               for j, (c, w) in enumerate(zip(row, widths, strict=True))))
    if t.note:
        lines.append(f"({t.note})")
    return "\n".join(lines)


def table_csv(t: StepTable) -> str:
    """The table as CSV (full precision, empty cells for "not available")."""
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(t.columns)
    for r in t.rows:
        w.writerow(["" if v is None else (repr(v) if isinstance(v, float) else v) for v in r])
    return buf.getvalue()
