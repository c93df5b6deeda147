"""Number formatting and step tables as HTML fragments."""

from __future__ import annotations

from .escape import text as escape_text

__all__ = ["fmt", "step_table_html"]


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


def step_table_html(t) -> str:
    """A :class:`rotoruq.render.tables.StepTable` as an HTML table."""
    from .steptables import fmt_cell

    e = escape_text
    head = "".join(f"<th{' class=l' if j == 0 else ''}>{e(c)}</th>"
                   for j, c in enumerate(t.columns))
    rows = "".join(
        "<tr>" + "".join(f"<td{' class=l' if j == 0 or isinstance(v, str) else ''}>"
                         f"{e(fmt_cell(v))}</td>" for j, v in enumerate(r)) + "</tr>"
        for r in t.rows)
    note = f"<p class=note>{e(t.note)}</p>" if t.note else ""
    return (f"<p><b>{e(t.title)}</b></p><table class=step><thead><tr>{head}</tr></thead>"
            f"<tbody>{rows}</tbody></table>{note}")
