"""What the reference study adds to a report: the claims (verdict, table, ``claims.json``), the
thesis's tables beside ours (HTML and ``tables/table_<number>.csv``) and the thesis's numbers
drawn beside ours in the figures. :data:`APPLICATION` is the object the CLI hands
:func:`rotoruq.report.html.write_report` (``application=``) when a study declares
``[study] reference = "thesis"``; it satisfies :class:`rotoruq.report.application.Application`.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Mapping, Sequence
from typing import Any

from ..report.application import Addition, ReportData, Section
from ..report.diagnostics import THRESHOLDS
from ..report.escape import script_json, slug
from ..report.escape import text as e
from ..report.tables import fmt
from ..steps.bayes_calibration import SELF_CHECK_FAILED
from .claims import INDEPENDENT, JOINT, Claim, claims, claims_json
from .compare import ComparedTable, compare_tables
from .studies import is_reference
from .tables import TABLES

__all__ = ["APPLICATION", "ThesisApplication", "table_csv", "table_html", "beside_numbers"]

_STATUS_CLASS = {"holds": "st-holds", "holds, with a warning": "st-warn",
                 "does not hold": "st-fails", "not checked": "st-na"}
_VERDICTS = (("holds", "hold"), ("holds, with a warning", "hold with a warning"),
             ("does not hold", "do not hold"), ("not checked", "not checked"))


# ------------------------------------------------------------------------ thesis tables
def table_csv(t: ComparedTable) -> str:
    """``table_<number>.csv``: one line per cell (row, column, thesis, ours, ours - thesis,
    relative, the difference in the unit the report shows and that unit, source)."""
    fh = io.StringIO(newline="")
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
    return fh.getvalue()


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


_TABLES_NOTE = (
    "<p class=note>Differences: in the thesis's standard deviations "
    "(\u03c3) for means with a printed std; absolute for indices, "
    "std-dev counts and shape moments or where the thesis value is near "
    "zero; relative (%) otherwise. Colour of our value: "
    "<span style='background:#e5f5e0'>&nbsp;agrees&nbsp;</span> (within "
    "10 %, 1 σ or 0.05 absolute), "
    "<span style='background:#fee8c8'>&nbsp;differs&nbsp;</span>, "
    "uncoloured: nothing to compare.</p>")


# ------------------------------------------------------------------------------- claims
def _claim_row(c: Claim) -> str:
    def kofn(v):
        return "-" if v is None else f"{v[0]} of {v[1]}"

    def num(v):
        return "-" if v is None else fmt(v)

    status = c.status
    thesis = ("-" if c.thesis_passes is None else
              ("holds" if c.thesis_passes else "does not hold"))
    why = "".join(f"<li>{e(r)}</li>" for r in c.reasons)
    why += "".join(f"<li>note: {e(d)}</li>" for d in c.details)
    why = f"<ul class=why>{why}</ul>" if why else ""
    if c.warnings:
        why += (f"<details><summary>{len(c.warnings)} warning(s) from the steps it rests on"
                "</summary><ul class=why>"
                + "".join(f"<li>{e(w)}</li>" for w in c.warnings) + "</ul></details>")
    prop = {INDEPENDENT: "independent normals", JOINT: "joint posterior predictive"}.get(
        c.propagation or "", "")
    return (f"<tr data-claim='{e(c.key)}' data-status='{e(status)}'>"
            f"<td class=l>{e(c.text)}"
            + (f" <i>(the thesis's criterion, shown beside {e(c.beside)}; not counted)</i>"
               if c.beside else "")
            + (" <i>(on the calibration's own data: a consistency check, not counted)</i>"
               if c.consistency else "") + f"</td><td class=l>{e(prop)}</td>"
            f"<td><span class={_STATUS_CLASS[status]}>{e(status)}</span></td>"
            f"<td>{num(c.value)}</td><td>{e(c.op)} {c.threshold:g}</td><td>{kofn(c.ours)}</td>"
            f"<td>{num(c.thesis_value)}</td><td>{thesis}</td>"
            f"<td class=l>{why}</td></tr>")


def _claims_section(claim_list: list[Claim]) -> str:
    head = ("<tr><th class=l>claim</th><th class=l>propagation</th><th>ours</th>"
            "<th>our value</th><th>threshold</th><th>ours k of n</th><th>thesis value</th>"
            "<th>thesis</th><th class=l>why (computed from this run)</th></tr>")
    data = script_json(claims_json(claim_list))
    t = THRESHOLDS
    return (
        "<table id='claims-table'>" + head + "".join(_claim_row(c) for c in claim_list)
        + "</table>"
        "<p class=note>A claim reads <i>holds</i> only when its value passes its threshold; "
        "<i>holds, with a warning</i> when it passes but a step it rests on has a diagnostic "
        f"warning (ESS below {t['ess_min']:g}, R-hat above {t['rhat_max']}, emulator "
        f"leave-one-out Q2 below {t['loo_q2_min']}, a posterior piling up against a prior "
        f"bound (more than {100 * t['pileup_max']:g} % of the chain in its outer 5 %), a "
        f"parameter the data do not inform (posterior std above {t['std_ratio_max']} x the "
        "prior's), a non-identifiable CUU). Forward checks after a calibration are evaluated "
        f"under two propagations: <b>independent normals</b> ({e(INDEPENDENT)}) "
        f"and the <b>joint posterior predictive</b> ({e(JOINT)}, the measurement "
        "compared with the model spread plus the calibration's noise). They differ when the "
        "posterior is correlated: independent normals ignore the correlation.</p>"
        f"<script type='application/json' id='claims-data'>{data}</script>")


def _verdict_counts(claim_list: Sequence[Claim]) -> dict[str, int]:
    """Number of counted claims in each state, in the order the first screen shows them (a
    thesis's criterion shown beside its V&V 20 claim is not counted)."""
    return {k: sum(c.status == k for c in claim_list if c.counted) for k, _ in _VERDICTS}


def _verdict(claim_list: list[Claim]) -> str:
    """The claims' verdict: counts, then one line per counted claim (the thesis's criterion
    nested beside the V&V 20 claim that judges the same comparison)."""
    n = _verdict_counts(claim_list)
    attrs = " ".join(f"data-{_STATUS_CLASS[k][3:]}='{v}'" for k, v in n.items())
    parts = ", ".join(f"<span class={_STATUS_CLASS[k]}>{n[k]} {word}</span>"
                      for k, word in _VERDICTS)
    counted = [c for c in claim_list if c.counted]
    judged = {b.beside for b in claim_list if b.beside}
    stricter = (f"; {len(judged)} of them by the ASME V&amp;V 20 budget, where the thesis "
                "judged by \"within one predictive std\" (its criterion shown beside, not "
                "counted)" if judged else "")
    out = [f"<p class=counts {attrs}><b>{len(counted)} claims of the reference "
           f"study</b>: {parts}. Each is the thesis's statement judged by the threshold "
           f"stated with it{stricter}.</p><ol class=verdict>"]

    def line(c: Claim) -> str:
        prop = {INDEPENDENT: " (independent normals)", JOINT: " (joint predictive)"}.get(
            c.propagation or "", "")
        val = "" if c.value is None else f": {fmt(c.value)}, needs {e(c.requirement)}"
        # a failed self-check of a step the claim rests on, next to the claim (issue 35)
        checks = [w for w in c.warnings if SELF_CHECK_FAILED in w]
        failed = "".join(f" <span class=st-fails data-self-check=failed>{e(w)}</span>"
                         for w in checks)
        return (f"<span class={_STATUS_CLASS[c.status]}>{e(c.status)}</span> "
                f"{e(c.text)}{e(prop)}{val}{failed}")

    def beside(c: Claim) -> None:
        nested = [b for b in claim_list if b.beside == c.key]
        if nested:
            out.append("<ul class=beside>" + "".join(
                f"<li data-beside='{e(b.key)}'>the thesis's criterion, not counted: "
                f"{line(b)}</li>" for b in nested) + "</ul>")

    for c in counted:
        out.append(f"<li data-verdict='{e(c.key)}'>{line(c)}")
        beside(c)
        out.append("</li>")
    out.append("</ol>")
    checks = [c for c in claim_list if c.consistency]
    if checks:
        out.append("<p class=note>Consistency checks on the calibrations' own data (the fit, "
                   "not the model; not counted):</p><ul class=verdict>")
        for c in checks:
            out.append(f"<li data-consistency='{e(c.key)}'>{line(c)}")
            beside(c)
            out.append("</li>")
        out.append("</ul>")
    out.append("<p class=note>Values, thresholds and the reasons computed from this "
               "run: <a href='#claims'>the claims table</a>. Where the thesis judged a "
               "comparison by \"within one predictive std\", the verdict judges it by the "
               "ASME V&amp;V 20 budget (|E| against u_val) and shows the thesis's criterion "
               "beside it: a wider predictive spread passes the thesis's criterion more "
               "easily, not the V&amp;V 20 one.</p>")
    return "".join(out)


# ------------------------------------------------------------------------------ figures
def beside_numbers(study: str, bayes_steps: Sequence[str] = ()) -> dict[str, Any]:
    """What the thesis prints behind a study's figures, as plain data for
    :attr:`rotoruq.render.figures.FigureContext.beside`: the main Sobol indices of the
    study's tables (step -> response -> input -> index), the predictive mean and std of every
    forward step at each sweep point (step -> ``"@H"`` -> response -> [mean, std]) and, in
    chapter 3, the ``truth`` step that generated the synthetic data of ``bayes_steps``."""
    sobol: dict[str, dict[str, dict[str, Any]]] = {}
    for t in TABLES:
        if t.study != study:
            continue
        for _, cells in t.rows:
            for value, src in cells:
                if src and ":S/" in src and not src.startswith(("model:", "data:")):
                    step, key = src.split(":", 1)
                    _, r, p = key.split("/")
                    sobol.setdefault(step, {}).setdefault(r, {})[p] = value
    predictions: dict[str, dict[str, dict[str, list[float]]]] = {}
    for t in TABLES:
        for _, cells in t.rows:
            if len(cells) < 2:
                continue
            (m, src), (s, _src2) = cells[0], cells[1]
            if (src is None or m is None or s is None or src.startswith(("model:", "data:"))
                    or ":mean/" not in src or "@" not in src):
                continue
            step, key = src.split(":", 1)
            r, h = key[len("mean/"):].rsplit("@", 1)
            predictions.setdefault(step, {}).setdefault(f"@{h}", {})[r] = [m, s]
    truth = {b: "truth" for b in bayes_steps} if study == "validation" else {}
    return {"label": "thesis", "sobol": sobol, "predictions": predictions, "truth": truth}


# -------------------------------------------------------------------------- application
class ThesisApplication:
    """The reference study's report hook (see :class:`rotoruq.report.application.Application`).

    It covers the studies that declare ``reference = "thesis"`` and are one of its chapters
    (:func:`rotoruq.reference.studies.is_reference`)."""

    name = "thesis"

    def covers(self, info: Mapping[str, Any]) -> bool:
        return is_reference(info)

    def beside(self, study: str, info: Mapping[str, Any]) -> dict[str, Any] | None:
        types = info.get("step_types") or {}
        return beside_numbers(study, [s for s, t in types.items() if t == "bayes_calibration"])

    def build(self, data: ReportData) -> Addition:
        results = {n: data.studies[n] for n in data.studies}
        values = {n: dict((data.infos[n].get("model") or {}).get("values") or {})
                  for n in data.studies}
        spanwise = {n: (data.infos[n].get("model") or {}).get("spanwise") or {}
                    for n in data.studies}
        tables = compare_tables(results, values)
        claim_list = claims(tables, results, data.labels, values, spanwise)
        files = {"claims.json": json.dumps(claims_json(claim_list), indent=1)}
        per_study: dict[str, tuple[Section, ...]] = {}
        for name in data.studies:
            sid = "-".join(slug(p) for p in ("study", name))
            mine = [t for t in tables if t.ref.study == name]
            sections = [Section(3, "Thesis tables beside ours", f"{sid}-{slug('thesis')}",
                                _TABLES_NOTE)]
            for ct in mine:
                files[f"tables/table_{ct.ref.number.replace('.', '_')}.csv"] = table_csv(ct)
                sections.append(Section(4, f"Table {ct.ref.number}: {ct.ref.caption}",
                                        f"table-{ct.ref.number}", table_html(ct)))
            per_study[name] = tuple(sections)
        return Addition(
            title="rotoruq: reproduction of the reference study",
            verdict=_verdict(claim_list),
            sections=(Section(2, "Claims of the reference study: values, thresholds, reasons",
                              "claims", _claims_section(claim_list)),),
            study_sections=per_study, files=files)


#: The reference study's application object.
APPLICATION = ThesisApplication()
