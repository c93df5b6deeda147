"""Comparison tables as CSV files and HTML fragments."""

from __future__ import annotations

import csv
import html
from pathlib import Path

from .compare import ComparedTable

__all__ = ["fmt", "write_csv", "table_html", "step_table_html"]


def fmt(v: float | None) -> str:
    """4 significant digits, scientific for small/large magnitudes; '-' when absent."""
    if v is None:
        return "-"
    if v == 0:
        return "0"
    a = abs(v)
    if a < 1e-2 or a >= 1e5:
        return f"{v:.3e}"
    return f"{v:.4g}"


def write_csv(t: ComparedTable, folder: Path) -> Path:
    """``table_<number>.csv``: one line per cell (row, column, thesis, ours, ours - thesis,
    relative, the difference in the unit the report shows and that unit, source)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"table_{t.ref.number.replace('.', '_')}.csv"
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["row", "column", "thesis", "ours", "ours_minus_thesis", "relative",
                    "difference", "difference_unit", "source"])
        for label, cells in t.rows:
            for col, c in zip(t.ref.columns, cells, strict=True):
                w.writerow([label, col, "" if c.thesis is None else repr(c.thesis),
                            "" if c.ours is None else repr(c.ours),
                            "" if c.diff is None else repr(c.diff),
                            "" if c.rel is None else repr(c.rel),
                            "" if c.diff_value is None else repr(c.diff_value),
                            {"sigma": "thesis std devs", "relative": "fraction of |thesis|",
                             "absolute": "quantity unit"}.get(c.diff_kind, ""),
                            c.source or ""])
    return path


def _agrees(c) -> bool | None:
    """Within 10 % (relative), 1 thesis std (sigma) or 0.05 (absolute: indices, counts)."""
    k, v = c.diff_kind, c.diff_value
    if not k:
        return None
    limit = {"relative": 0.10, "sigma": 1.0, "absolute": 0.05}[k]
    return abs(v) <= limit


def table_html(t: ComparedTable) -> str:
    """An HTML table: for each thesis column, three sub-columns thesis / ours / difference
    (in the thesis's std devs, absolute or relative: see ``ComparedCell.diff_kind``)."""
    e = html.escape
    head1 = "<th rowspan=2></th>" + "".join(f"<th colspan=3>{e(c)}</th>" for c in t.ref.columns)
    head2 = "<th>thesis</th><th>ours</th><th>diff</th>" * len(t.ref.columns)
    body = []
    for label, cells in t.rows:
        tds = []
        for c in cells:
            ok = _agrees(c)
            cls = "" if ok is None else (" class=ok" if ok else " class=off")
            tds.append(f"<td>{fmt(c.thesis)}</td><td{cls}>{fmt(c.ours)}</td>"
                       f"<td>{e(c.diff_text())}</td>")
        body.append(f"<tr><th class=l>{e(label)}</th>{''.join(tds)}</tr>")
    note = f"<p class=note>{e(t.ref.note)}</p>" if t.ref.note else ""
    return (f"<table><thead><tr>{head1}</tr><tr>{head2}</tr></thead>"
            f"<tbody>{''.join(body)}</tbody></table>{note}")


def step_table_html(t) -> str:
    """A :class:`rotoruq.render.tables.StepTable` as an HTML table."""
    from .steptables import fmt_cell

    e = html.escape
    head = "".join(f"<th{' class=l' if j == 0 else ''}>{e(c)}</th>"
                   for j, c in enumerate(t.columns))
    rows = "".join(
        "<tr>" + "".join(f"<td{' class=l' if j == 0 or isinstance(v, str) else ''}>"
                         f"{e(fmt_cell(v))}</td>" for j, v in enumerate(r)) + "</tr>"
        for r in t.rows)
    note = f"<p class=note>{e(t.note)}</p>" if t.note else ""
    return (f"<p><b>{e(t.title)}</b></p><table class=step><thead><tr>{head}</tr></thead>"
            f"<tbody>{rows}</tbody></table>{note}")
