"""Comparison tables as CSV files and HTML fragments."""

from __future__ import annotations

import csv
import html
from pathlib import Path

from .compare import ComparedTable

__all__ = ["fmt", "write_csv", "table_html"]


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
    """``table_<number>.csv``: one line per cell (row, column, thesis, ours, diff, rel)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"table_{t.ref.number.replace('.', '_')}.csv"
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["row", "column", "thesis", "ours", "ours_minus_thesis", "relative", "source"])
        for label, cells in t.rows:
            for col, c in zip(t.ref.columns, cells, strict=True):
                w.writerow([label, col, "" if c.thesis is None else repr(c.thesis),
                            "" if c.ours is None else repr(c.ours),
                            "" if c.diff is None else repr(c.diff),
                            "" if c.rel is None else repr(c.rel), c.source or ""])
    return path


def table_html(t: ComparedTable) -> str:
    """An HTML table: for each thesis column, three sub-columns thesis / ours / difference."""
    e = html.escape
    head1 = "<th rowspan=2></th>" + "".join(f"<th colspan=3>{e(c)}</th>" for c in t.ref.columns)
    head2 = "<th>thesis</th><th>ours</th><th>diff</th>" * len(t.ref.columns)
    body = []
    for label, cells in t.rows:
        tds = []
        for c in cells:
            rel = ""
            if c.rel is not None:
                rel = f" ({100 * c.rel:+.0f} %)" if abs(c.rel) < 100 else ""
            cls = ""
            if c.rel is not None:
                cls = " class=ok" if abs(c.rel) <= 0.1 else " class=off"
            tds.append(f"<td>{fmt(c.thesis)}</td><td{cls}>{fmt(c.ours)}</td>"
                       f"<td>{fmt(c.diff)}{rel}</td>")
        body.append(f"<tr><th>{e(label)}</th>{''.join(tds)}</tr>")
    note = f"<p class=note>{e(t.ref.note)}</p>" if t.ref.note else ""
    return (f"<table><thead><tr>{head1}</tr><tr>{head2}</tr></thead>"
            f"<tbody>{''.join(body)}</tbody></table>{note}")

