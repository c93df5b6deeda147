"""The reference study's main claims, checked on our results and on the thesis's numbers.

A :class:`Claim` carries the computed value, its threshold and the comparison, so its state
is a function of those numbers only: it reads "holds" exactly when ``value`` passes
``threshold``, "holds, with a warning" when it passes but a diagnostic of a step it rests on
says the number may not be trusted (:func:`rotoruq.report.diagnostics.step_warnings`), and
"does not hold" otherwise, with reasons computed from the run. Claims about forward checks
after a calibration are evaluated under both propagations: the thesis's independent normals
and the joint posterior predictive (chain samples through the model).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field

from ..results import StepResult
from .compare import ComparedTable
from .diagnostics import PILEUP_MAX, STD_RATIO_MAX, step_warnings, strong_correlations

__all__ = ["Claim", "claims", "claims_json", "INDEPENDENT", "JOINT"]

Results = Mapping[str, Mapping[str, StepResult]]

INDEPENDENT = "independent normals from the posterior moments (the thesis's method, table 4.15)"
JOINT = "joint posterior predictive (chain samples through the model)"

_OPS = {"<=": lambda v, t: v <= t, ">=": lambda v, t: v >= t, ">": lambda v, t: v > t}


@dataclass(frozen=True)
class Claim:
    """One claim of the reference study.

    text : the claim. metric : what ``value`` measures. value / thesis_value : ours and the
    thesis's (None: not computable, e.g. the steps did not run). op, threshold : the claim
    holds when ``value op threshold``. ours / thesis : k of n items passing. propagation :
    which forward propagation the numbers come from (None when not a forward check).
    reasons : why it does not hold (computed from the run). warnings : diagnostics of the
    steps it rests on.
    """

    key: str
    text: str
    metric: str
    op: str
    threshold: float
    value: float | None
    thesis_value: float | None
    ours: tuple[int, int] | None = None
    thesis: tuple[int, int] | None = None
    propagation: str | None = None
    reasons: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    details: tuple[str, ...] = field(default=())

    @property
    def passes(self) -> bool | None:
        if self.value is None or not math.isfinite(self.value):
            return None
        return bool(_OPS[self.op](self.value, self.threshold))

    @property
    def thesis_passes(self) -> bool | None:
        if self.thesis_value is None:
            return None
        return bool(_OPS[self.op](self.thesis_value, self.threshold))

    @property
    def holds(self) -> bool | None:
        return self.passes

    @property
    def status(self) -> str:
        p = self.passes
        if p is None:
            return "not checked"
        if not p:
            return "does not hold"
        return "holds, with a warning" if self.warnings else "holds"


def claims_json(claim_list: Sequence[Claim]) -> list[dict]:
    """The claims as plain data (what the report embeds and writes to ``claims.json``)."""
    out = []
    for c in claim_list:
        d = asdict(c)
        d.update(status=c.status, passes=c.passes, thesis_passes=c.thesis_passes)
        out.append(d)
    return out


# --------------------------------------------------------------------------------- helpers
def _col(t: ComparedTable, j: int, which: str) -> list:
    return [getattr(cells[j], which) for _, cells in t.rows]


def _rowlabels(t: ComparedTable) -> list[str]:
    return [lab for lab, _ in t.rows]


def _kofn(vals: Sequence[float | None], ok) -> tuple[int, int] | None:
    if not vals or any(v is None for v in vals):
        return None
    return sum(bool(ok(v)) for v in vals), len(vals)


def _worst(vals: Sequence[float | None], largest: bool = True) -> float | None:
    known = [v for v in vals if v is not None]
    if not vals or len(known) < len(vals):
        return None
    return max(known) if largest else min(known)


def _rel_errors(ref: list, got: list) -> list[float | None]:
    if any(v is None for v in ref + got):
        return [None] * len(ref)
    return [abs(g - r) / abs(r) for r, g in zip(ref, got, strict=True)]


def _warnings(steps: Mapping[str, StepResult], names: Sequence[str], labels) -> tuple[str, ...]:
    w: list[str] = []
    for n in names:
        if n in steps:
            w += step_warnings(steps[n], labels)
    return tuple(dict.fromkeys(w))


def _bayes_reasons(steps: Mapping[str, StepResult], bayes: str, labels,
                   correlations: bool = False) -> list[str]:
    """Posterior diagnostics that explain a miss: pile-up, identifiability, correlation."""
    res = steps.get(bayes)
    if res is None:
        return []
    out = []
    for side, word in (("lo", "lower"), ("hi", "upper")):
        for k, v in res.scalars.items():
            if k.startswith(f"pileup_{side}/") and v > PILEUP_MAX:
                p = k.split("/", 1)[1]
                out.append(f"the posterior of {labels.get(p, p)} piles up against its prior's "
                           f"{word} bound ({100 * v:.0f} % of the chain in the outer 5 %, "
                           f"skewness {res.get(f'skewness/{p}', math.nan):+.2f})")
    weak = [labels.get(k.split("/", 1)[1], k.split("/", 1)[1])
            for k, v in res.scalars.items() if k.startswith("std_ratio/") and v > STD_RATIO_MAX]
    if weak:
        out.append(f"the data barely inform {', '.join(weak)} (posterior std above "
                   f"{STD_RATIO_MAX} x the prior's): the posterior is mostly prior")
    if correlations:
        for p, q, rho in strong_correlations(res, labels)[:3]:
            out.append(f"posterior corr({p}, {q}) = {rho:+.2f}: independent normals ignore it "
                       "and misstate the predictive spread")
    return out


def _misses(labels: list[str], vals: list, ok, fmt_item) -> list[str]:
    return [fmt_item(lab, v) for lab, v in zip(labels, vals, strict=True)
            if v is not None and not ok(v)]


# --------------------------------------------------------------------------------- claims
def claims(tables: list[ComparedTable], results: Results | None = None,
           labels: Mapping[str, Mapping[str, str]] | None = None) -> list[Claim]:
    """The reference study's main claims, on our results and on the thesis's numbers.

    ``tables`` are the compared thesis tables (:func:`rotoruq.report.compare.compare_tables`);
    ``results`` (study -> step -> result) supplies the diagnostics and the joint posterior
    predictive; ``labels`` (study -> parameter -> label) names parameters in the reasons.
    """
    results = results or {}
    labels = labels or {}
    val = results.get("validation", {})
    exp = results.get("experiment", {})
    lab_v, lab_e = labels.get("validation", {}), labels.get("experiment", {})
    by = {t.ref.number: t for t in tables}
    out: list[Claim] = []

    # Bo105 Bayes: posterior means within 2 % of the data-generating means.
    t = by["3.9"]
    errs = {w: _rel_errors(_col(t, 0, w), _col(t, 2, w)) for w in ("ours", "thesis")}
    reasons = _misses(_rowlabels(t), errs["ours"], lambda e: e <= 0.02,
                      lambda lab, e: f"{lab}: posterior mean {100 * e:.1f} % from the true mean")
    reasons += _bayes_reasons(val, "bayes", lab_v)
    out.append(Claim(
        "bo105_bayes_means", "Bo105 Bayes calibration: posterior means within 2 % of the true "
        "means (table 3.9)", "largest |posterior mean - true mean| / |true mean|", "<=", 0.02,
        _worst(errs["ours"]), _worst(errs["thesis"]),
        _kofn(errs["ours"], lambda e: e <= 0.02), _kofn(errs["thesis"], lambda e: e <= 0.02),
        reasons=tuple(reasons), warnings=_warnings(val, ["bayes"], lab_v)))

    # Bo105 mixed sensitivity: C_La(0.3) has the largest main index.
    t = by["3.6"]

    def margin(which):
        v = _col(t, 0, which)
        if any(x is None for x in v):
            return None
        return v[0] - max(v[1:])

    reasons = []
    s = val.get("sens_mixed")
    m = margin("ours")
    if s is not None and m is not None and m < 0:
        main = _col(t, 0, "ours")
        j = max(range(len(main)), key=lambda i: main[i])
        reasons.append(f"{_rowlabels(t)[j]} dominates (S = {main[j]:.3f} against "
                       f"{main[0]:.3f} for C_La(0.3))")
        if s.get("negligible/thrust", math.nan) == 1:
            reasons.append("the thrust variance is negligible (std "
                           f"{s.get('out_std/thrust', math.nan):.3g} N), the indices split noise")
        reasons.append("our NACA 23012 table is generated, not the thesis's (table 3.2): the "
                       "lift slope of each Mach row, hence which row weighs most, differs")
    out.append(Claim(
        "bo105_sens_top", "Bo105 mixed sensitivity: C_La(0.3) has the largest main index of "
        "the mean thrust (table 3.6)", "S(C_La(0.3)) - largest other S", ">", 0.0,
        m, margin("thesis"),
        None if m is None else (int(m > 0), 1),
        None if margin("thesis") is None else (int(margin("thesis") > 0), 1),
        reasons=tuple(reasons), warnings=_warnings(val, ["sens_mixed"], lab_v)))

    # Bo105 CUU: output std devs within 5 % of the experimental ones.
    for num, what, step in (("3.11", "mixed", "cuu_mixed"), ("3.13", "aerodynamic",
                                                              "cuu_aero")):
        t = by[num]
        errs = {w: _rel_errors(_col(t, 1, w), _col(t, 3, w)) for w in ("ours", "thesis")}
        reasons = _misses(_rowlabels(t), errs["ours"], lambda e: e <= 0.05,
                          lambda lab, e: f"{lab}: calibrated std {100 * e:.1f} % from the "
                          "experimental")
        reasons += _cuu_reasons(val.get(step), lab_v)
        details = tuple(
            f"{lab}: our mean {o:.5g} against the thesis's {th:.5g} ({100 * (o / th - 1):+.0f} "
            "%): the preset's operating point differs from the thesis's model, so the std "
            "devs are compared with our own experimental targets"
            for lab, o, th in zip(_rowlabels(t), _col(t, 0, "ours"), _col(t, 0, "thesis"),
                                  strict=True)
            if o is not None and th and abs(o / th - 1) > 0.1)
        out.append(Claim(
            f"bo105_{step}", f"Bo105 CUU ({what}): load std devs reproduced within "
            f"5 % (table {num})", "largest |calibrated std - experimental std| / experimental",
            "<=", 0.05, _worst(errs["ours"]), _worst(errs["thesis"]),
            _kofn(errs["ours"], lambda e: e <= 0.05),
            _kofn(errs["thesis"], lambda e: e <= 0.05),
            reasons=tuple(reasons), warnings=_warnings(val, [step, "bayes"], lab_v),
            details=details))

    # GVPM forward checks at 4R, 2R, 1R, under both propagations.
    for num, where, step, label in (("4.12", "at 4R", "forward_4r", "@4"),
                                    ("4.16", "at 2R", "forward_ige", "@2"),
                                    ("4.17", "at 1R", "forward_ige", "@1")):
        t = by[num]
        rows = _rowlabels(t)
        keys = [src.split("/")[1].split("@")[0] for _, cells in t.ref.rows
                for _, src in cells[:1] if src is not None]
        out += _forward_claims(
            f"gvpm_within_1std_{where[3:]}", f"GVPM: measured loads within one predictive std "
            f"{where} (table {num})", exp, step, label, rows, keys, 1.0,
            _col(t, 3, "thesis"), lab_e)

    # GVPM CUU on the commands.
    t = by["4.14"]
    errs = {w: _rel_errors(_col(t, 1, w), _col(t, 2, w)) for w in ("ours", "thesis")}
    reasons = _misses(_rowlabels(t), errs["ours"], lambda e: e <= 0.10,
                      lambda lab, e: f"{lab}: calibrated std {100 * e:.0f} % from the target")
    reasons += _cuu_reasons(exp.get("cuu_commands"), lab_e)
    out.append(Claim(
        "gvpm_cuu", "GVPM CUU on the commands: load std devs within 10 % of the targets "
        "(table 4.14)", "largest |calibrated std - target| / target", "<=", 0.10,
        _worst(errs["ours"]), _worst(errs["thesis"]),
        _kofn(errs["ours"], lambda e: e <= 0.10), _kofn(errs["thesis"], lambda e: e <= 0.10),
        reasons=tuple(reasons), warnings=_warnings(exp, ["cuu_commands", "bayes"], lab_e)))

    # Ground effect: growth of the ratios and measured ratios within 3 std devs.
    for num, name, resp in (("4.18", "C_T", "ct"), ("4.19", "C_Q", "cq")):
        t = by[num]
        out += _ground_claims(num, name, resp, t, exp, lab_e)
    return [_with_fallback_reason(c) for c in out]


def _with_fallback_reason(c: Claim) -> Claim:
    """Every claim that does not hold states at least its number against its threshold."""
    if c.passes is False:
        first = f"{c.metric} = {c.value:.4g}, needs {c.op} {c.threshold:g}"
        return Claim(**{**{k: getattr(c, k) for k in c.__dataclass_fields__},
                        "reasons": (first, *c.reasons)})
    return c


def _cuu_reasons(res: StepResult | None, labels) -> list[str]:
    if res is None:
        return []
    out = []
    if res.meta.get("identifiable") is False:
        out.append("the calibration is not identifiable: "
                   f"{res.meta.get('diagnostic') or 'singular sensitivity matrix'} "
                   f"(condition number {float(res.meta.get('condition_number') or 'nan'):.3g})")
    for k, v in res.scalars.items():
        if k.startswith("initial_std/"):
            p = k.split("/", 1)[1]
            new = res.get(f"std/{p}", math.nan)
            if v > 0 and math.isfinite(new) and abs(new / v - 1) > 0.5:
                out.append(f"{labels.get(p, p)} std driven from {v:.4g} to {new:.4g} "
                           f"({100 * (new / v - 1):+.0f} %)")
    return out


def _forward_claims(key, text, steps, step, label, rows, resp, limit, thesis_vals, labels
                    ) -> list[Claim]:
    """The same claim under the independent-normal propagation and the joint posterior
    predictive (when the step computed it)."""
    res = steps.get(step)
    out = []
    for prop, prefix, tag in ((INDEPENDENT, "", "independent"), (JOINT, "pp_", "joint")):
        if res is None:
            vals = [None] * len(resp)
        else:
            vals = [res.scalars.get(f"{prefix}nstd/{r}{label}") for r in resp]
            if prefix and all(v is None for v in vals):
                continue  # no chain: the joint predictive was not computed
        vals = [None if v is None or not math.isfinite(v) else float(v) for v in vals]
        reasons: list[str] = []
        for lab, r, v in zip(rows, resp, vals, strict=True):
            if v is not None and v > limit:
                reasons.append(
                    f"{lab}: {v:.2f} std devs "
                    f"(mean {res.get(f'{prefix}mean/{r}{label}', math.nan):.4g}"
                    f", measured {res.get(f'data/{r}{label}', math.nan):.4g}, std "
                    f"{res.get(f'{prefix}std/{r}{label}', math.nan):.3g})")
        if reasons:
            reasons += _bayes_reasons(steps, "bayes", labels, correlations=not prefix)
        details: tuple[str, ...] = ()
        if res is not None and any(f"pp_std/{r}{label}" in res.scalars for r in resp):
            details = (_spread_contrast(res, resp, label),)
        thesis = thesis_vals if not prefix else [None] * len(resp)
        out.append(Claim(
            f"{key}_{tag}", text, "largest |measured - mean| / std over the loads", "<=",
            limit, _worst(vals), _worst(thesis), _kofn(vals, lambda v: v <= limit),
            _kofn(thesis, lambda v: v <= limit), propagation=prop,
            reasons=tuple(r for r in reasons if r),
            warnings=_warnings(steps, ["bayes_moments", "bayes"], labels),
            details=tuple(d for d in details if d)))
    return out


def _spread_contrast(res: StepResult, resp, label) -> str:
    """Why the two propagations differ: their predictive std side by side."""
    parts = []
    for r in resp:
        a, b = res.get(f"std/{r}{label}", math.nan), res.get(f"pp_std/{r}{label}", math.nan)
        if math.isfinite(a) and math.isfinite(b):
            parts.append(f"{r} {b:.3g} (independent normals: {a:.3g})")
    if not parts:
        return ""
    return ("why the propagations differ: independent normals drop the posterior's "
            "correlations (and its non-normal shape); model std under the joint posterior: "
            + ", ".join(parts))


def _ground_claims(num, name, resp, t: ComparedTable, exp, labels) -> list[Claim]:
    res = exp.get("ground_effect")
    heights = ["@4", "@3", "@2", "@1"]
    fig = 5 if name == "C_T" else 6
    out = []
    for prop, prefix, tag in ((INDEPENDENT, "", "independent"), (JOINT, "pp_", "joint")):
        if prefix and (res is None or f"pp_mean/{resp}@4" not in res.scalars):
            continue
        if res is None:
            means = nstd = [None] * 4
        else:
            means = [res.scalars.get(f"{prefix}mean/{resp}{h}") for h in heights]
            nstd = [res.scalars.get(f"{prefix}nstd/{resp}{h}") for h in heights]
        th_means = _col(t, 0, "thesis")
        th_nstd = _col(t, 3, "thesis") if not prefix else [None] * 4

        def growth(m):
            if any(v is None for v in m):
                return None
            return min(m[3] - m[2], m[2] - m[0])

        g = growth(means)
        reasons = []
        if g is not None and g <= 0:
            reasons.append(f"model {name} ratio at 4R, 2R, 1R: {means[0]:.4f}, {means[2]:.4f}, "
                           f"{means[3]:.4f}")
        out.append(Claim(
            f"ge_growth_{resp}_{tag}", f"Ground effect: model {name} ratio grows from 4R to 2R "
            f"to 1R (table {num})", "smallest step of the mean ratio (2R - 4R, 1R - 2R)", ">",
            0.0, g, growth(th_means), None if g is None else (int(g > 0), 1),
            None if growth(th_means) is None else (int(growth(th_means) > 0), 1),
            propagation=prop, reasons=tuple(reasons),
            warnings=_warnings(exp, ["bayes"], labels)))
        reasons = [f"{h[1:]}R: measured {res.get(f'data/{resp}{h}', math.nan):.4f}, model "
                   f"{res.get(f'{prefix}mean/{resp}{h}', math.nan):.4f} +- "
                   f"{res.get(f'{prefix}std/{resp}{h}', math.nan):.3g} ({v:.2f} std devs)"
                   for h, v in zip(heights, nstd, strict=True) if v is not None and v > 3.0]
        if reasons:
            reasons.append("only the pitch-link stiffness is uncertain in this step: the "
                           "spread is that of K_p alone")
        out.append(Claim(
            f"ge_within_3std_{resp}_{tag}", f"Ground effect: measured {name} ratio within 3 "
            f"model std devs at every height (table {num}, figure 4.3{fig})",
            "largest |measured - mean| / std over the heights", "<=", 3.0,
            _worst(nstd), _worst(th_nstd), _kofn(nstd, lambda v: v <= 3.0),
            _kofn(th_nstd, lambda v: v <= 3.0), propagation=prop, reasons=tuple(reasons),
            warnings=_warnings(exp, ["bayes"], labels)))
    return out
