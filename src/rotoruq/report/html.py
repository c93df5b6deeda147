"""The report: one self-contained HTML page (figures embedded as base64 PNG) plus every figure
as PNG and SVG and every comparison table as CSV.

``write_report([results_dir, ...], report_dir)`` reads saved study outputs (see
:mod:`rotoruq.study.results`) and writes ``report_dir/index.html``, ``figures/`` and
``tables/``. It only reads results: ``rotoruq report RESULTS`` rebuilds it at any time.
"""

from __future__ import annotations

import base64
import datetime as _dt
import html
import io
import json
from collections.abc import Sequence
from pathlib import Path

from ..study.results import StepResult, load_results
from .compare import Claim, claims, compare_tables
from .tables import fmt, table_html, write_csv

__all__ = ["write_report", "find_study_dirs"]

_CSS = """
body{font-family:system-ui,sans-serif;max-width:1200px;margin:auto;padding:1em;color:#222}
table{border-collapse:collapse;margin:.5em 0;font-size:12px}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}
th{background:#f3f3f3}
td.ok{background:#e5f5e0} td.off{background:#fee8c8}
.note{font-size:12px;color:#555;margin-top:0}
figure{margin:1em 0} figure img{max-width:100%}
figcaption{font-size:12px;color:#444}
.holds{color:#1a7f37;font-weight:bold} .fails{color:#b42318;font-weight:bold}
.na{color:#777}
"""


def find_study_dirs(root: str | Path) -> list[Path]:
    """Study output folders under ``root`` (``root`` itself when it is one)."""
    root = Path(root)
    if (root / "study.json").is_file():
        return [root]
    return sorted(p.parent for p in root.glob("*/study.json"))


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    return buf.getvalue()


def _claim_html(c: Claim) -> str:
    def kofn(v):
        return "not run" if v is None else f"{v[0]} of {v[1]}"

    if c.holds is None:
        state = "<span class=na>not checked</span>"
    elif c.holds:
        state = "<span class=holds>holds</span>"
    else:
        state = "<span class=fails>does not hold</span>"
    return (f"<tr><td style='text-align:left'>{html.escape(c.text)}</td><td>{state}</td>"
            f"<td>{kofn(c.ours)}</td><td>{kofn(c.thesis)}</td></tr>")


def _labels(info: dict) -> dict[str, str]:
    return {k: v.get("label") or k for k, v in info.get("parameters", {}).items()}


def _steps_summary(name: str, steps: dict[str, StepResult]) -> str:
    rows = []
    for s in steps.values():
        rows.append(
            f"<tr><td style='text-align:left'>{html.escape(s.name)}</td><td>{s.type}</td>"
            f"<td style='text-align:left'>{html.escape(str(s.meta.get('title', '')))}</td>"
            f"<td>{s.meta.get('n_evaluations', '-')}</td>"
            f"<td>{fmt(s.meta.get('seconds'))}</td></tr>")
    return ("<table><tr><th>step</th><th>type</th><th>what</th><th>evaluations</th>"
            f"<th>seconds</th></tr>{''.join(rows)}</table>")


def write_report(results_dirs: Sequence[str | Path], report_dir: str | Path,
                 title: str = "rotoruq: reproduction of the reference study") -> Path:
    """Write the report of the given study output folders; returns ``index.html``."""
    from .plots import figures_for_study

    report_dir = Path(report_dir)
    fig_dir, tab_dir = report_dir / "figures", report_dir / "tables"
    fig_dir.mkdir(parents=True, exist_ok=True)
    tab_dir.mkdir(parents=True, exist_ok=True)
    studies: dict[str, dict[str, StepResult]] = {}
    infos: dict[str, dict] = {}
    for d in results_dirs:
        for folder in find_study_dirs(d):
            info = json.loads((folder / "study.json").read_text())
            studies[info["name"]] = load_results(folder)
            infos[info["name"]] = info
    tables = compare_tables(studies)
    claim_list = claims(tables)

    parts = [f"<h1>{html.escape(title)}</h1>",
             f"<p class=note>Generated {_dt.datetime.now().isoformat(timespec='seconds')} from "
             f"{', '.join(html.escape(str(p)) for p in results_dirs)}.</p>"]
    quick = [n for n, i in infos.items() if i.get("quick")]
    if quick:
        parts.append(f"<p><b>Quick run</b> ({', '.join(quick)}): small samples; the numbers "
                     "show the pipeline works, not the converged values.</p>")
    parts.append("<h2>Summary: claims of the reference study</h2><table><tr><th>claim</th>"
                 "<th>ours</th><th>ours k of n</th><th>thesis k of n</th></tr>"
                 + "".join(_claim_html(c) for c in claim_list) + "</table>")

    for name, steps in studies.items():
        info = infos[name]
        parts.append(f"<h2>Study {html.escape(name)}: "
                     f"{html.escape(info.get('description', ''))}</h2>")
        parts.append(_steps_summary(name, steps))
        mine = [t for t in tables if t.ref.study == name]
        if mine:
            parts.append("<h3>Tables (thesis beside ours)</h3>")
        for t in mine:
            write_csv(t, tab_dir)
            parts.append(f"<h4 id='table-{t.ref.number}'>Table {t.ref.number}: "
                         f"{html.escape(t.ref.caption)}</h4>")
            parts.append(table_html(t))
        figs = figures_for_study(name, steps, _labels(info))
        if figs:
            parts.append("<h3>Figures</h3>")
        for f in figs:
            png = _png(f.figure)
            (fig_dir / f"{f.name}.png").write_bytes(png)
            f.figure.savefig(fig_dir / f"{f.name}.svg", format="svg")
            b64 = base64.b64encode(png).decode()
            parts.append(f"<figure><img alt='{html.escape(f.caption)}' "
                         f"src='data:image/png;base64,{b64}'>"
                         f"<figcaption>{html.escape(f.caption)}</figcaption></figure>")
    done = {t.ref.study for t in tables}
    other = [t for t in tables if t.ref.study not in studies and t.ref.study in done]
    if other:
        parts.append("<h2>Thesis tables without results in this report</h2><p class=note>"
                     + ", ".join(f"{t.ref.number}" for t in other)
                     + " (run <code>rotoruq reproduce all</code> to fill them).</p>")
    page = ("<!DOCTYPE html><html><head><meta charset='utf-8'>"
            f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>"
            + "\n".join(parts) + "</body></html>")
    index = report_dir / "index.html"
    index.write_text(page, encoding="utf-8")
    return index
