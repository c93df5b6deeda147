"""Tables of one saved step's own numbers, for every step type: what a user's study shows in
its report and what ``rotoruq show`` prints or exports.

:func:`step_tables` turns a :class:`~rotoruq.results.StepResult` into a list of
:class:`StepTable` (plain data); :func:`table_text`, :func:`table_csv` and
:meth:`StepTable.as_dict` render them for a terminal, a spreadsheet and JSON. The HTML report
renders the same tables (:func:`rotoruq.report.tables.step_table_html`).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from ..results import StepResult
from .diagnostics import step_warnings
from .hooks import rendering

__all__ = ["StepTable", "step_tables", "table_text", "table_csv", "fmt_cell",
           "sampling_tables", "forward_check_tables", "sensitivity_tables", "pce_tables",
           "mean_value_tables", "reliability_tables", "evidence_tables", "bayes_tables",
           "least_squares_tables", "cuu_tables"]

Cell = float | str | None


@dataclass(frozen=True)
class StepTable:
    """title; columns (header of each column, the first names the rows); rows of cells
    (floats, text or None for "not available"); note: how to read it."""

    title: str
    columns: tuple[str, ...]
    rows: tuple[tuple[Cell, ...], ...]
    note: str = ""

    def as_dict(self) -> dict:
        def clean(v):
            if isinstance(v, float) and not math.isfinite(v):
                return None if math.isnan(v) else repr(v)
            return v

        return {"title": self.title, "columns": list(self.columns),
                "rows": [[clean(v) for v in r] for r in self.rows], "note": self.note}


def _t(title, columns, rows, note="") -> StepTable:
    return StepTable(title, tuple(columns), tuple(tuple(r) for r in rows), note)


def _v(res: StepResult, key: str) -> float | None:
    v = res.scalars.get(key)
    return None if v is None else float(v)


def _lab(p: str, labels: Mapping[str, str]) -> str:
    return labels.get(p) or p


def _responses(res: StepResult) -> list[str]:
    return list(res.meta.get("responses") or [])


def _params(res: StepResult) -> list[str]:
    return list(res.meta.get("parameters") or res.meta.get("inputs") or [])


def _moments_rows(res: StepResult, names: Sequence[str], suffix: str = "", labels=None):
    labels = labels or {}
    return [[_lab(n, labels), _v(res, f"mean/{n}{suffix}"), _v(res, f"std/{n}{suffix}"),
             _v(res, f"skewness/{n}{suffix}"), _v(res, f"kurtosis/{n}{suffix}")]
            for n in names]


_MOMENTS = ("mean", "std", "skewness", "excess kurtosis")


def sampling_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    resp = res.columns("outputs") or _responses(res)
    out = [_t("Response statistics (model outputs)", ("response", *_MOMENTS),
              _moments_rows(res, resp))]
    if "outputs_clean" in res.arrays:
        out.append(_t("Response statistics with the added noise", ("response", *_MOMENTS),
                      _moments_rows(res, [f"noisy_{r}" for r in resp])))
    out.append(_inputs_table(res, labels))
    return out


def _inputs_table(res: StepResult, labels) -> StepTable:
    return _t("Input distributions", ("input", "mean", "std", "lower", "upper"),
              [[_lab(p, labels), _v(res, f"input_mean/{p}"), _v(res, f"input_std/{p}"),
                _v(res, f"input_lower/{p}"), _v(res, f"input_upper/{p}")]
               for p in _params(res)])


def forward_check_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    resp = _responses(res)
    out = []
    joint = bool(res.meta.get("joint_predictive"))
    for label in res.meta.get("labels") or [""]:
        where = f" at {label[1:]}" if label else ""
        cols = ["response", "mean", "std", "measured", "|measured - mean| / std"]
        if joint:
            cols += ["joint mean", "joint std", "noise std", "|measured - mean| / predictive std"]
        rows = []
        for r in resp:
            row = [r, _v(res, f"mean/{r}{label}"), _v(res, f"std/{r}{label}"),
                   _v(res, f"data/{r}{label}"), _v(res, f"nstd/{r}{label}")]
            if joint:
                row += [_v(res, f"pp_mean/{r}{label}"), _v(res, f"pp_std/{r}{label}"),
                        _v(res, f"pp_noise/{r}{label}"), _v(res, f"pp_nstd/{r}{label}")]
            rows.append(row)
        note = ("mean/std: LHS of the step's input distributions"
                + (" (independent normals from the posterior moments, the thesis's method); "
                   "joint: chain samples through the model (correlations kept); predictive "
                   "std = sqrt(joint std^2 + noise std^2), the calibration's noise model"
                   if joint else "."))
        sweep = res.meta.get("sweep") or {}
        if sweep and label:
            match = next(iter(sweep))
            where = f" at {match} = {label[1:]}"
        out.append(_t(f"Propagated responses{where}", cols, rows, note))
    out.append(_inputs_table(res, labels))
    return out


def sensitivity_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    resp, inputs = _responses(res), list(res.meta.get("inputs") or _params(res))
    conf = res.meta.get("confidence", 0.95)
    out = [_t("Output spread", ("response", "mean", "variance", "std", "CV = std / |mean|",
                                "negligible variance"),
              [[r, _v(res, f"out_mean/{r}"), _v(res, f"out_var/{r}"), _v(res, f"out_std/{r}"),
                _v(res, f"out_cv/{r}"),
                None if _v(res, f"negligible/{r}") is None else
                ("yes: indices meaningless" if _v(res, f"negligible/{r}") else "no")]
               for r in resp],
              "A response whose std is below 1e-4 of its mean has negligible variance.")]
    for r in resp:
        neg = _v(res, f"negligible/{r}") == 1
        rows = [[_lab(p, labels), _v(res, f"S/{r}/{p}"), _v(res, f"S_lo/{r}/{p}"),
                 _v(res, f"S_hi/{r}/{p}"), _v(res, f"T/{r}/{p}"), _v(res, f"T_lo/{r}/{p}"),
                 _v(res, f"T_hi/{r}/{p}")] for p in inputs]
        lo, hi = f"{100 * (1 - conf) / 2:g} %", f"{100 * (1 + conf) / 2:g} %"
        out.append(_t(f"Sobol indices of {r}" + (" (negligible variance)" if neg else ""),
                      ("input", "main S", f"S {lo}", f"S {hi}", "total T", f"T {lo}",
                       f"T {hi}"), rows,
                      "Estimates as computed (a negative value is sampling noise around 0); "
                      f"bootstrap {100 * conf:g} % intervals."))
    return out


def pce_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    resp, inputs = _responses(res), list(res.meta.get("inputs") or _params(res))
    out = [_t("Response moments (polynomial chaos)", ("response", "mean", "std"),
              [[r, _v(res, f"mean/{r}"), _v(res, f"std/{r}")] for r in resp])]
    for r in resp:
        out.append(_t(f"Sobol indices of {r} (from the expansion)", ("input", "main S",
                                                                      "total T"),
                      [[_lab(p, labels), _v(res, f"S/{r}/{p}"), _v(res, f"T/{r}/{p}")]
                       for p in inputs]))
    return out


def mean_value_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    resp, inputs = _responses(res), _params(res)
    return [_t("Mean value method (first order)", ("response", "mean", "std"),
               [[r, _v(res, f"mean/{r}"), _v(res, f"std/{r}")] for r in resp]),
            _t("Importance factors", ("input", *resp),
               [[_lab(p, labels), *[_v(res, f"importance/{r}/{p}") for r in resp]]
                for p in inputs], "Share of each input in the first-order variance.")]


def _levels(res: StepResult, whats: Sequence[str], title: str) -> list[StepTable]:
    out = []
    for r in _responses(res):
        n = max([int(k.rsplit("/", 1)[1]) + 1 for k in res.scalars
                 if k.split("/")[0] in whats and k.split("/")[1] == r] or [0])
        if n == 0:
            continue
        present = [w for w in whats if f"{w}/{r}/0" in res.scalars]
        out.append(_t(f"{title}: {r}", ("level", *[w.replace("_", " ") for w in present]),
                      [[i + 1, *[_v(res, f"{w}/{r}/{i}") for w in present]]
                       for i in range(n)]))
    return out


def reliability_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    return _levels(res, ("response_levels", "cdf_probability", "cdf_reliability",
                         "generalized_reliability", "probability_levels",
                         "probability_response"), "Reliability (MPP search)")


def evidence_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    return _levels(res, ("response_levels", "cbf", "cpf"),
                   "Belief (CBF) and plausibility (CPF) of response <= level")


def bayes_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    names = res.columns("chain") or _params(res)
    rows = [[_lab(p, labels), _v(res, f"input_mean/{p}"), _v(res, f"input_std/{p}"),
             _v(res, f"mean/{p}"), _v(res, f"std/{p}"), _v(res, f"skewness/{p}"),
             _v(res, f"kurtosis/{p}"), _v(res, f"ess/{p}"), _v(res, f"rhat/{p}"),
             _v(res, f"std_ratio/{p}"), _v(res, f"pileup_lo/{p}"), _v(res, f"pileup_hi/{p}")]
            for p in names]
    out = [_t("Prior and posterior", ("parameter", "prior mean", "prior std", "posterior mean",
                                      "posterior std", "skewness", "excess kurtosis", "ESS",
                                      "R-hat", "post/prior std", "outer 5 % low",
                                      "outer 5 % high"), rows,
              "post/prior std near 1: the data do not inform the parameter; outer 5 %: "
              "fraction of the chain in the outer 5 % of a bounded prior's range (0.05 when "
              "flat).")]
    resp = res.columns("data")
    out.append(_t("Chain and noise model", ("quantity", "value"), [
        ["acceptance rate", _v(res, "acceptance")],
        ["KL divergence posterior || prior [nats]", _v(res, "kl_divergence")],
        *[[f"noise std of {r}", _v(res, f"noise_std/{r}")] for r in resp],
        *[[f"emulator leave-one-out Q2 of {r}", _v(res, f"loo_q2/{r}")] for r in resp
          if f"loo_q2/{r}" in res.scalars]],
        f"Noise model: {res.meta.get('noise_model', 'not recorded')}."))
    if len(names) > 1:
        idx = {p: i for i, p in enumerate(names)}
        mat = [[_lab(p, labels)] + [1.0 if p == q else _v(
            res, f"corr/{p}/{q}" if idx[p] < idx[q] else f"corr/{q}/{p}") for q in names]
            for p in names]
        out.append(_t("Posterior correlation", ("", *[_lab(q, labels) for q in names]), mat))
    return out


def least_squares_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    names = [k.split("/", 1)[1] for k in res.scalars if k.startswith("value/")]
    return [_t("Calibrated parameters (least squares)", ("parameter", "value", "std"),
               [[_lab(p, labels), _v(res, f"value/{p}"), _v(res, f"std/{p}")]
                for p in names], f"Cost {res.get('cost'):.6g}; "
               f"{res.meta.get('message', '')}")]


def cuu_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    params = _params(res)
    resp = _responses(res)
    out = [_t("Inputs: initial and calibrated", ("input", "initial mean", "initial std",
                                                 "calibrated mean", "calibrated std"),
              [[_lab(p, labels), _v(res, f"initial_mean/{p}"), _v(res, f"initial_std/{p}"),
                _v(res, f"mean/{p}"), _v(res, f"std/{p}")] for p in params],
              "Identifiable: " + ("yes" if res.meta.get("identifiable", True) else
                                  f"no ({res.meta.get('diagnostic', '')})"))]
    out.append(_t("Responses: targets and sampled statistics",
                  ("response", "target mean", "target std", "initial mean", "initial std",
                   "calibrated mean", "calibrated std"),
                  [[r, _v(res, f"target_mean/{r}"), _v(res, f"target_std/{r}"),
                    _v(res, f"initial_out_mean/{r}"), _v(res, f"initial_out_std/{r}"),
                    _v(res, f"calibrated_out_mean/{r}"), _v(res, f"calibrated_out_std/{r}")]
                   for r in resp]))
    return out


def step_tables(res: StepResult, labels: Mapping[str, str] | None = None) -> list[StepTable]:
    """The tables of one step (its type's ``tables`` renderer, see
    :mod:`rotoruq.report.hooks`; a key/value table without one), then its warnings."""
    labels = labels or {}
    build = rendering(res.type).tables
    tables = build(res, labels) if build else [
        _t("Results", ("key", "value"), [[k, float(v)] for k, v in res.scalars.items()])]
    tables = [t for t in tables if t.rows]
    warns = step_warnings(res, labels)
    if warns:
        tables.append(_t("Warnings", ("warning",), [[w] for w in warns]))
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
