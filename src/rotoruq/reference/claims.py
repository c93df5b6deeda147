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
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from ..report.diagnostics import PILEUP_MAX, STD_RATIO_MAX, step_warnings, strong_correlations
from ..results import StepResult
from ..steps._common import saved_record
from ..steps._discrepancy import extrapolation_note
from ..steps.bayes_calibration import posterior_record
from ..steps.cuu import CuuRecord
from ..steps.forward_check import ForwardCheckRecord
from .causes import (
    calibration_design,
    comparison_miss,
    data_information,
    input_recovery,
    model_form_gap,
    sensitivity_causes,
    sweep_growth,
    target_consistency,
)
from .compare import ComparedTable

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
    steps it rests on. beside : the key of the claim that judges the same comparison by the
    ASME V&V 20 budget, when this one is the thesis's criterion shown beside it (not
    counted in the verdict). consistency : True when the comparison is on the calibration's
    own data: it checks the fit, not the model, and the verdict does not count it.
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
    beside: str | None = None
    consistency: bool = False

    @property
    def counted(self) -> bool:
        """Whether the verdict counts this claim: a claim ``beside`` another is the thesis's
        own criterion shown next to the V&V 20 claim that judges the same comparison; a
        comparison on the calibration's own data checks the fit, not the model."""
        return self.beside is None and not self.consistency

    @property
    def passes(self) -> bool | None:
        if self.value is None or not math.isfinite(self.value):
            return None
        return bool(_OPS[self.op](self.value, self.threshold))

    @property
    def requirement(self) -> str:
        """What the claim needs of its value, in words from the threshold's sense:
        ``"at most 0.02"``, ``"at least 0.5"``, ``"a positive value"`` (``> 0``), ``"none"``
        (``<= 0``: a count such as loads outside a band)."""
        t = f"{self.threshold:g}"
        if self.threshold == 0 and self.op in ("<=", ">"):
            return "none" if self.op == "<=" else "a positive value"
        return {"<=": f"at most {t}", ">=": f"at least {t}", ">": f"more than {t}"}[self.op]

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
        d.update(status=c.status, passes=c.passes, thesis_passes=c.thesis_passes,
                 counted=c.counted)
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
    rec = None if res is None else posterior_record(res)
    if res is None or rec is None:
        return []
    out = []
    for word, pile in (("lower", rec.pileup_lo), ("upper", rec.pileup_hi)):
        for j, p in enumerate(rec.names_in):
            if pile[j] > PILEUP_MAX:
                out.append(f"the posterior of {labels.get(p, p)} piles up against its prior's "
                           f"{word} bound ({100 * pile[j]:.0f} % of the chain in the outer 5 %, "
                           f"skewness {rec.skewness[j]:+.2f})")
    weak = [labels.get(p, p) for p, v in zip(rec.names_in, rec.std_ratio, strict=True)
            if v > STD_RATIO_MAX]
    if weak:
        out.append(f"the data barely inform {', '.join(weak)} (posterior std above "
                   f"{STD_RATIO_MAX} x the prior's): the posterior is mostly prior")
    if correlations:
        for p, q, rho in strong_correlations(res, labels)[:3]:
            out.append(f"posterior corr({p}, {q}) = {rho:+.2f}: independent normals ignore it "
                       "and misstate the predictive spread")
    return out


def mean_miss(lab: str, err: float, true: float | None, mean: float | None,
              std: float | None, prior_std: float | None) -> str:
    """A posterior mean's miss of the truth, measured in the posterior's own std devs: a miss
    within about two of them is the posterior's uncertainty (the data do not resolve the
    input to the claim's tolerance), a larger one a biased posterior.

    Examples
    --------
    >>> mean_miss("K_f", 0.14, 15035.5, 12930.0, 1500.0, 2080.0)[:62]
    'K_f: posterior mean 14.0 % from the true mean, 1.4 posterior s'
    """
    out = f"{lab}: posterior mean {100 * err:.1f} % from the true mean"
    if true is None or mean is None or std is None or not std:
        return out
    z = abs(mean - true) / std
    ratio = (f", posterior/data-generating std {std / prior_std:.2f}" if prior_std else "")
    out += f", {z:.1f} posterior std devs (std {std:.3g}{ratio})"
    if z <= 2:
        return out + (": within the posterior's own uncertainty, the data do not resolve it "
                      f"to the claim's tolerance (a 2 % window is {0.02 * abs(true) / std:.2g} "
                      "posterior std devs wide each side)")
    return out + ": outside the posterior's own uncertainty, a biased posterior"


def _misses(labels: list[str], vals: list, ok, fmt_item) -> list[str]:
    return [fmt_item(lab, v) for lab, v in zip(labels, vals, strict=True)
            if v is not None and not ok(v)]


# --------------------------------------------------------------------------------- claims
def claims(tables: list[ComparedTable], results: Results | None = None,
           labels: Mapping[str, Mapping[str, str]] | None = None,
           model_values: Mapping[str, Mapping[str, float]] | None = None,
           spanwise: Mapping[str, Mapping] | None = None) -> list[Claim]:
    """The reference study's main claims, on our results and on the thesis's numbers.

    ``tables`` are the compared thesis tables (:func:`rotoruq.reference.compare.compare_tables`);
    ``results`` (study -> step -> result) supplies the diagnostics and the joint posterior
    predictive; ``labels`` (study -> parameter -> label) names parameters in the reasons;
    ``model_values`` (study -> the preset numbers ``study.json`` recorded) give the blade
    geometry a reason may need; ``spanwise`` (study -> the section loads ``study.json``
    recorded, :func:`rotoruq.study.runner.spanwise_record`) the cause of a lift-slope ranking.
    Every reason is computed from these (:mod:`.causes`).
    """
    results = results or {}
    labels = labels or {}
    model_values = model_values or {}
    val = results.get("validation", {})
    exp = results.get("experiment", {})
    lab_v, lab_e = labels.get("validation", {}), labels.get("experiment", {})
    by = {t.ref.number: t for t in tables}
    out: list[Claim] = []

    # Bo105 Bayes: posterior means within 2 % of the data-generating means.
    t = by["3.9"]
    errs = {w: _rel_errors(_col(t, 0, w), _col(t, 2, w)) for w in ("ours", "thesis")}
    reasons = [mean_miss(lab, e, *z) for lab, e, z in zip(
        _rowlabels(t), errs["ours"], zip(_col(t, 0, "ours"), _col(t, 2, "ours"),
                                         _col(t, 3, "ours"), _col(t, 1, "ours"), strict=True),
        strict=True) if e is not None and e > 0.02]
    if reasons and "bayes" in val:
        by_label = {lab_v.get(k, k): k for k in lab_v}
        missed = [by_label.get(lab, lab) for lab, e in zip(_rowlabels(t), errs["ours"],
                                                           strict=True)
                  if e is not None and e > 0.02]
        reasons += data_information(val["bayes"], val, missed, lab_v)
        reasons += calibration_design(val["bayes"])
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
        reasons = sensitivity_causes(s, val, "thrust", "cla_m03", lab_v,
                                     model_values.get("validation", {}),
                                     (spanwise or {}).get("validation"))
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
        if reasons and step in val:
            reasons += target_consistency(val[step], lab_v)
        reasons += _cuu_reasons(val.get(step), lab_v)
        details = tuple(
            f"{lab}: our mean {o:.5g} against the thesis's {th:.5g} ({100 * (o / th - 1):+.0f} "
            "%): the preset's operating point differs from the thesis's model, so the std "
            "devs are compared with our own experimental targets"
            for lab, o, th in zip(_rowlabels(t), _col(t, 0, "ours"), _col(t, 0, "thesis"),
                                  strict=True)
            if o is not None and th and abs(o / th - 1) > 0.1)
        inputs = _input_recovery_claim(by[_INPUT_TABLE[num]], step, what, val, lab_v)
        if inputs.passes is False:
            details += (f"the input spreads are not recovered (smallest calibrated / true std "
                        f"ratio {inputs.value:.3g}; claim {inputs.key}): matching the output "
                        "std devs does not make the thesis's CUU claim hold",)
        out.append(Claim(
            f"bo105_{step}", f"Bo105 CUU ({what}): load std devs reproduced within "
            f"5 % (table {num})", "largest |calibrated std - experimental std| / experimental",
            "<=", 0.05, _worst(errs["ours"]), _worst(errs["thesis"]),
            _kofn(errs["ours"], lambda e: e <= 0.05),
            _kofn(errs["thesis"], lambda e: e <= 0.05),
            reasons=tuple(reasons), warnings=_warnings(val, [step, "bayes"], lab_v),
            details=details))
        out.append(inputs)

    # GVPM forward checks at 4R, 2R, 1R, under both propagations.
    for num, where, step, label in (("4.12", "at 4R", "forward_4r", "@4"),
                                    ("4.16", "at 2R", "forward_ige", "@2"),
                                    ("4.17", "at 1R", "forward_ige", "@1")):
        t = by[num]
        rows = _rowlabels(t)
        keys = [src.split("/")[1].split("@")[0] for _, cells in t.ref.rows
                for _, src in cells[:1] if src is not None]
        thesis_rule = _forward_claims(
            f"gvpm_within_1std_{where[3:]}", f"GVPM: measured loads within one predictive std "
            f"{where} (table {num})", exp, step, label, rows, keys, 1.0,
            _col(t, 3, "thesis"), lab_e)
        vv = _vv20_claim(f"gvpm_vv20_{where[3:]}", where, num, t, exp, label, keys, rows,
                         thesis_rule, lab_e)
        if vv is not None:
            thesis_rule = [replace(c, beside=vv.key) for c in thesis_rule]
            out.append(vv)
        out += thesis_rule

    # GVPM CUU on the commands.
    t = by["4.14"]
    errs = {w: _rel_errors(_col(t, 1, w), _col(t, 2, w)) for w in ("ours", "thesis")}
    reasons = _misses(_rowlabels(t), errs["ours"], lambda e: e <= 0.10,
                      lambda lab, e: f"{lab}: calibrated std {100 * e:.0f} % from the target")
    if reasons and "cuu_commands" in exp:
        reasons += target_consistency(exp["cuu_commands"], lab_e)
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
    out += _heldout_claims(results.get("heldout", {}), labels.get("heldout", {}))
    return [_with_fallback_reason(c) for c in out]


# The thesis's input table of each CUU's output table.
_INPUT_TABLE = {"3.11": "3.10", "3.13": "3.12"}
# An input spread is recovered when calibrated and true std devs agree within this factor.
_RECOVERY_FACTOR = 2.0


def _targets_step(res: StepResult | None, steps: Mapping[str, StepResult]) -> StepResult | None:
    """The step whose samples gave a CUU its targets (``targets = "step.samples"``)."""
    ref = ((res.meta.get("options") or {}).get("targets") if res is not None else None)
    if isinstance(ref, str) and "." in ref:
        return steps.get(ref.split(".", 1)[0])
    return None


def _input_recovery_claim(t: ComparedTable, step: str, what: str, val, labels) -> Claim:
    """The thesis's CUU claim is that the input spreads are recovered: each calibrated input
    std within a factor 2 of the std the targets were made with."""
    def ratios(which):
        out = []
        for true, cal in zip(_col(t, 1, which), _col(t, 3, which), strict=True):
            if true is None or cal is None or true <= 0:
                out.append(None)
            else:
                r = cal / true
                out.append(min(r, 1 / r) if r > 0 else 0.0)
        return out

    ours, thesis = ratios("ours"), ratios("thesis")
    ok = (lambda v: v >= 1 / _RECOVERY_FACTOR)  # noqa: E731
    res = val.get(step)
    reasons: list[str] = []
    if res is not None and not all(v is None or ok(v) for v in ours):
        reasons = input_recovery(res, _targets_step(res, val), labels)[1]
        reasons += _cuu_reasons(res, labels)[:1]
    return Claim(
        f"bo105_{step}_inputs", f"Bo105 CUU ({what}): the input std devs are recovered, each "
        f"within a factor {_RECOVERY_FACTOR:g} of the true one (table {t.ref.number})",
        "smallest min(calibrated / true, true / calibrated) input std over the inputs", ">=",
        1 / _RECOVERY_FACTOR, _worst(ours, largest=False), _worst(thesis, largest=False),
        _kofn(ours, ok), _kofn(thesis, ok), reasons=tuple(reasons),
        warnings=_warnings(val, [step], labels))


def _with_fallback_reason(c: Claim) -> Claim:
    """Every claim that does not hold states at least its number against its threshold."""
    if c.passes is False:
        first = f"{c.metric} = {c.value:.4g}, needs {c.requirement}"
        return Claim(**{**{k: getattr(c, k) for k in c.__dataclass_fields__},
                        "reasons": (first, *c.reasons)})
    return c


def _cuu_reasons(res: StepResult | None, labels) -> list[str]:
    rec = None if res is None else saved_record(CuuRecord, res)
    if rec is None:
        return []
    out = []
    if not rec.identifiable:
        # a saved record holds an infinite condition number as "inf", a NaN as null
        cond = math.nan if rec.condition_number is None else float(rec.condition_number)
        out.append("the calibration is not identifiable: "
                   f"{rec.diagnostic or 'singular sensitivity matrix'} "
                   f"(condition number {cond:.3g})")
    for j, p in enumerate(rec.names_in):
        v, new = float(rec.initial_std[j]), float(rec.std[j])
        if v > 0 and math.isfinite(new) and abs(new / v - 1) > 0.5:
            out.append(f"{labels.get(p, p)} std driven from {v:.4g} to {new:.4g} "
                       f"({100 * (new / v - 1):+.0f} %)")
    return out


def _forward(steps: Mapping[str, StepResult], name: str) -> ForwardCheckRecord | None:
    """The record of forward-check step ``name``; None when the study has no such step or it
    was saved before its type had one."""
    res = steps.get(name)
    return None if res is None else saved_record(ForwardCheckRecord, res)


def _computed(v: float) -> float | None:
    return None if math.isnan(v) else v


def _forward_claims(key, text, steps, step, label, rows, resp, limit, thesis_vals, labels
                    ) -> list[Claim]:
    """The same claim under the independent-normal propagation and the joint posterior
    predictive (when the step computed it)."""
    rec = _forward(steps, step)
    out = []
    for prop, joint, tag in ((INDEPENDENT, False, "independent"), (JOINT, True, "joint")):
        vals: list[float | None] = [None] * len(resp)
        reasons: list[str] = []
        if rec is not None:
            mean, std, nstd = rec.prediction(joint)
            raw = [rec.at(nstd, label, r) for r in resp]
            if joint and all(math.isnan(v) for v in raw):
                continue  # no chain: the joint predictive was not computed
            vals = [v if math.isfinite(v) else None for v in raw]
            for lab, r, v in zip(rows, resp, vals, strict=True):
                if v is not None and v > limit:
                    reasons.append(
                        f"{lab}: {v:.2f} std devs (mean {rec.at(mean, label, r):.4g}, "
                        f"measured {rec.at(rec.measured, label, r):.4g}, std "
                        f"{rec.at(std, label, r):.3g})")
        if reasons and label != "@4":
            missed = [(lab, r) for lab, r, v in zip(rows, resp, vals, strict=True)
                      if v is not None and v > limit]
            reasons.append(sweep_growth(steps.get("forward_4r"), steps[step],
                                        [r for _, r in missed], label,
                                        [lab for lab, _ in missed], joint))
        fits = _fits_at_calibration(steps, rows, resp, vals, limit, joint) \
            if reasons and label != "@4" else ""
        if fits:
            reasons.append(fits)
        elif reasons:
            reasons += _bayes_reasons(steps, "bayes", labels, correlations=not joint)
        details: tuple[str, ...] = ()
        if rec is not None and any(not math.isnan(rec.at(rec.pp_std, label, r))
                                   for r in resp):
            details = (_spread_contrast(rec, resp, label),)
        thesis = thesis_vals if not joint else [None] * len(resp)
        out.append(Claim(
            f"{key}_{tag}", text, "largest |measured - mean| / std over the loads", "<=",
            limit, _worst(vals), _worst(thesis), _kofn(vals, lambda v: v <= limit),
            _kofn(thesis, lambda v: v <= limit), propagation=prop,
            reasons=tuple(r for r in reasons if r),
            warnings=_warnings(steps, ["bayes_moments", "bayes"], labels),
            details=tuple(d for d in details if d)))
    return out


def _fits_at_calibration(steps, rows, resp, vals, limit, joint) -> str:
    """When every load missed away from 4R lies within ``limit`` std devs at 4R, the
    calibration's data: the calibration fits there, so its own diagnostics (a posterior piling
    up, inputs the data barely inform) are beside the point of the miss; "" otherwise."""
    ref = _forward(steps, "forward_4r")
    if ref is None:
        return ""
    nstd = ref.prediction(joint)[2]
    missed = [(lab, r) for lab, r, v in zip(rows, resp, vals, strict=True)
              if v is not None and v > limit]
    at4 = [ref.at(nstd, "@4", r) for _, r in missed]
    if not missed or not all(math.isfinite(v) and v <= limit for v in at4):
        return ""
    return ("at 4R, the calibration's data, the same loads lie within "
            + ", ".join(f"{lab} {v:.2f}" for (lab, _), v in zip(missed, at4, strict=True))
            + f" std devs (<= {limit:g}): the calibration fits its data, so its diagnostics "
            "(pile-up, weakly informed inputs) do not explain the miss at this height")


def _spread_contrast(rec: ForwardCheckRecord, resp, label) -> str:
    """Why the two propagations differ: their predictive std side by side."""
    parts = []
    for r in resp:
        a, b = rec.at(rec.moments[:, 1], label, r), rec.at(rec.pp_std, label, r)
        if math.isfinite(a) and math.isfinite(b):
            parts.append(f"{r} {b:.3g} (independent normals: {a:.3g})")
    if not parts:
        return ""
    return ("why the propagations differ: independent normals drop the posterior's "
            "correlations (and its non-normal shape); model std under the joint posterior: "
            + ", ".join(parts))


def _ground_claims(num, name, resp, t: ComparedTable, exp, labels) -> list[Claim]:
    res = exp.get("ground_effect")
    rec = _forward(exp, "ground_effect")
    heights = ["@4", "@3", "@2", "@1"]
    fig = 5 if name == "C_T" else 6
    out = []
    for prop, joint, tag in ((INDEPENDENT, False, "independent"), (JOINT, True, "joint")):
        if joint and (rec is None or math.isnan(rec.at(rec.pp_mean, "@4", resp))):
            continue
        means: list[float | None] = [None] * 4
        nstd: list[float | None] = [None] * 4
        within: list[str] = []
        if rec is not None:
            mean, std, dist = rec.prediction(joint)
            means = [_computed(rec.at(mean, h, resp)) for h in heights]
            nstd = [_computed(rec.at(dist, h, resp)) for h in heights]
            within = [f"{h[1:]}R: measured {rec.at(rec.measured, h, resp):.4f}, model "
                      f"{rec.at(mean, h, resp):.4f} +- {rec.at(std, h, resp):.3g} ({v:.2f} "
                      "std devs)" for h, v in zip(heights, nstd, strict=True)
                      if v is not None and v > 3.0]
            if within and res is not None:
                within += _ground_strength(rec, resp, name, joint)
                within += model_form_gap(res, resp, heights, joint, labels)
        th_means = _col(t, 0, "thesis")
        th_nstd = _col(t, 3, "thesis") if not joint else [None] * 4

        def growth(m):
            if any(v is None for v in m):
                return None
            return min(m[3] - m[2], m[2] - m[0])

        g = growth(means)
        reasons = []
        if g is not None and g <= 0 and res is not None:
            reasons.append(f"model {name} ratio at 4R, 2R, 1R: {means[0]:.4f}, {means[2]:.4f}, "
                           f"{means[3]:.4f}")
            reasons += model_form_gap(res, resp, heights, joint, labels)
        out.append(Claim(
            f"ge_growth_{resp}_{tag}", f"Ground effect: model {name} ratio grows from 4R to 2R "
            f"to 1R (table {num})", "smallest step of the mean ratio (2R - 4R, 1R - 2R)", ">",
            0.0, g, growth(th_means), None if g is None else (int(g > 0), 1),
            None if growth(th_means) is None else (int(growth(th_means) > 0), 1),
            propagation=prop, reasons=tuple(reasons),
            warnings=_warnings(exp, ["bayes"], labels)))
        out.append(Claim(
            f"ge_within_3std_{resp}_{tag}", f"Ground effect: measured {name} ratio within 3 "
            f"model std devs at every height (table {num}, figure 4.3{fig})",
            "largest |measured - mean| / std over the heights", "<=", 3.0,
            _worst(nstd), _worst(th_nstd), _kofn(nstd, lambda v: v <= 3.0),
            _kofn(th_nstd, lambda v: v <= 3.0), propagation=prop, reasons=tuple(within),
            warnings=_warnings(exp, ["bayes"], labels)))
    return out


def _ground_strength(rec: ForwardCheckRecord, resp: str, name: str, joint: bool
                     ) -> list[str]:
    """The ground-effect model's strength against the test's: the ratio 1R / 4R of each, and
    the model at the reference height (where the ratios are normalised by the test)."""
    mean, std, _ = rec.prediction(joint)
    m4, m1 = rec.at(mean, "@4", resp), rec.at(mean, "@1", resp)
    d4, d1 = rec.at(rec.measured, "@4", resp), rec.at(rec.measured, "@1", resp)
    s4 = rec.at(std, "@4", resp)
    out = []
    if all(map(math.isfinite, (m4, m1, d4, d1))) and m4 and d4:
        out.append(f"model {name}(1R) / {name}(4R) = {m1 / m4:.3f} against the test's "
                   f"{d1 / d4:.3f}: the ground-effect model is "
                   + ("weaker" if m1 / m4 < d1 / d4 else "stronger") + " than the rotor's")
    if all(map(math.isfinite, (m4, d4, s4))) and d4 and s4 > 0 and abs(m4 - d4) > 3 * s4:
        out.append(f"at 4R, the reference height, the model's {name} is already "
                   f"{m4 / d4:.3f} of the test's ({abs(m4 - d4) / s4:.1f} model std devs off)")
    return out


# ----------------------------------------------------------------------- V&V 20 claims
def _validation(steps: Mapping[str, StepResult], name: str | None = None):
    """The :class:`~rotoruq.steps.validation.ValidationRecord` of step ``name`` (default: the
    study's first ``validation`` step), with the step; None when there is none or it cannot
    be read."""
    from ..results import RecordError
    from ..steps.validation import ValidationRecord

    cands = ([steps[name]] if name in steps else []) if name else [
        s for s in steps.values() if s.type == "validation"]
    for res in cands:
        if res.type != "validation":
            continue
        try:
            return res, ValidationRecord.read(res)
        except RecordError:
            return None
    return None


def _posterior_of(steps: Mapping[str, StepResult], res: StepResult) -> StepResult | None:
    """The calibration step a validation step took its posterior from (``from``)."""
    up = str(res.meta.get("source") or "").split(".")[0]
    return steps.get(up)


def _posterior_plane(steps: Mapping[str, StepResult], bayes: StepResult | None, label: str
                     ) -> dict[str, StepResult]:
    """The posterior draws a forward check of ``bayes`` propagated at sweep point ``label``
    with their outputs, as a sampling step's samples (a plane's input): the draws are the
    chain thinned as :func:`~rotoruq.steps.forward_check.posterior_draws` thins it for the
    step, row for row with its saved ``pp_outputs<label>``."""
    from ..steps.forward_check import posterior_draws

    out: dict[str, StepResult] = {}
    key = f"pp_outputs{label}"
    for s in steps.values():
        if bayes is None or s.type != "forward_check" or key not in s.arrays:
            continue
        if str(s.meta.get("source") or "").split(".")[0] != bayes.name:
            continue
        names = list(s.meta.get("parameters") or [])
        y = np.asarray(s.arrays[key], dtype=float)
        x = posterior_draws(bayes, names, len(y)) if names else None
        if x is None or len(x) != len(y):
            continue
        out[f"{s.name} (posterior draws at {label[1:]}R)"] = StepResult(
            f"{s.name} (posterior draws at {label[1:]}R)", "sampling",
            arrays={"inputs": x, "outputs": y},
            meta={"columns": {"inputs": names, "outputs": s.columns(key)}})
    return out


def _condition(rec, value: float) -> int | None:
    hit = np.flatnonzero(np.isclose(rec.conditions, value))
    return int(hit[0]) if hit.size else None


def _budget(rec, p: int, j: int, m: int) -> str:
    """E and its validation uncertainty, with the largest part of u_val named."""
    parts = {"u_num": rec.u_num[p, j, m], "u_input": rec.u_input[p, j, m],
             "u_D": rec.u_data[p, j, m]}
    top = max(parts, key=lambda k: parts[k])
    return (f"E = S - D = {rec.comparison_error[p, j, m]:.4g} ({rec.simulation[p, j, m]:.4g} - "
            f"{rec.data_mean[p, j, m]:.4g}), u_val = {rec.u_val[p, j, m]:.3g} ("
            + ", ".join(f"{k} {v:.3g}" for k, v in parts.items())
            + f"; {top} the largest), |E| / u_val = {rec.error_ratio[p, j, m]:.2f}")


def _vv20_claim(key: str, where: str, num: str, t: ComparedTable, steps, label: str,
                keys: Sequence[str], rows: Sequence[str], thesis_rule: Sequence[Claim],
                labels) -> Claim | None:
    """The thesis's forward comparison at one height judged by ASME V&V 20: every load's
    |E| <= k u_val (k the validation step's coverage factor). The thesis's own value uses its
    table's mean, std and measurement with our stated u_D (the thesis has no u_num)."""
    found = _validation(steps, "validate") or _validation(steps)
    if found is None:
        return None
    res, rec = found
    j = _condition(rec, float(label[1:]))
    pairs = [(lab, r) for lab, r in zip(rows, keys, strict=True) if r in rec.names_out]
    if j is None or not pairs:
        return None
    k, p = rec.coverage_factor, 0
    ms = [rec.names_out.index(r) for _, r in pairs]
    ratios = [float(rec.error_ratio[p, j, m]) for m in ms]
    consistency = bool(rec.calibrated()[j, ms].all())
    # a consistency check the Monte Carlo error does not resolve (NaN) is not judged
    unjudged = [lab for (lab, _), v in zip(pairs, ratios, strict=True) if math.isnan(v)]
    if unjudged and len(unjudged) < len(ratios):
        pairs = [(lab, r) for (lab, r), v in zip(pairs, ratios, strict=True)
                 if not math.isnan(v)]
        ms = [m for m, v in zip(ms, ratios, strict=True) if not math.isnan(v)]
        ratios = [v for v in ratios if not math.isnan(v)]
    ok = (lambda v: v <= k)  # noqa: E731
    th_mean, th_std, th_data = (_col(t, c, "thesis") for c in (0, 1, 2))
    th_ratio: list[float | None] = []
    for (lab, _r), m in zip(pairs, ms, strict=True):
        i = list(rows).index(lab)
        if None in (th_mean[i], th_std[i], th_data[i]):
            th_ratio.append(None)
        else:
            th_ratio.append(abs(th_mean[i] - th_data[i])
                            / math.hypot(th_std[i], float(rec.u_data[p, j, m])))
    reasons = []
    j4 = _condition(rec, 4.0)
    for (lab, _r), m, v in zip(pairs, ms, ratios, strict=True):
        if ok(v):
            continue
        why = f"{lab}: {_budget(rec, p, j, m)} > {k:g}: a model error the uncertainties do not "
        why += (f"hide, about {100 * rec.comparison_error[p, j, m] / rec.data_mean[p, j, m]:+.1f}"
                " % of the measurement" if rec.data_mean[p, j, m] else "hide")
        reasons.append(why)
        post = _posterior_of(steps, res)
        miss = comparison_miss({**steps, **_posterior_plane(steps, post, label)}, post,
                               rec.names_out[m],
                               float(rec.comparison_error[p, j, m]), float(rec.u_num[p, j, m]),
                               float(rec.u_input[p, j, m]), labels)
        if miss:
            reasons.append(f"{lab}: {miss}")
        if j4 is not None and j4 != j and rec.simulation[p, j4, m] and rec.data_mean[p, j4, m]:
            ds = rec.simulation[p, j, m] / rec.simulation[p, j4, m] - 1
            dd = rec.data_mean[p, j, m] / rec.data_mean[p, j4, m] - 1
            reasons.append(
                f"{lab}: from 4R to {where[3:]} the model changes by {100 * ds:+.1f} % against "
                f"the test's {100 * dd:+.1f} % (E {rec.comparison_error[p, j4, m]:.3g} at 4R, "
                f"{rec.comparison_error[p, j, m]:.3g} at {where[3:]}): model form, not "
                "calibration, at this height")
    def area(lab: str, m: int) -> str:
        a, d = rec.area_metric[p, j, m], rec.data_mean[p, j, m]
        # a percent of a measurement smaller than its own uncertainty says nothing
        return f"{lab} {a:.3g}" + (f" ({100 * a / abs(d):.1f} % of D)"
                                   if abs(d) > rec.u_data[p, j, m] else "")

    details = ["area metric (does not shrink as the spread grows): " + ", ".join(
        area(lab, m) for (lab, _), m in zip(pairs, ms, strict=True))]
    for c in thesis_rule:
        if c.value is not None:
            details.append(
                f"the thesis's criterion beside it ({c.metric} <= {c.threshold:g}, "
                f"{'independent normals' if c.propagation == INDEPENDENT else 'joint'}): "
                f"{c.value:.2f}, {'holds' if c.passes else 'does not hold'}")
    if rec.u_num_source:
        details.append(f"u_num {rec.u_num_source}; u_D the stated measurement uncertainty "
                       "and the repeats' standard error")
    if consistency:
        details.insert(0, f"the test {where} is the calibration's own data: a consistency "
                       "check of the fit, not a validation, and not counted; S took in part "
                       "of D's noise, so u_val = sqrt(u_num^2 + u_D^2 - u_input^2)"
                       + (f"; not judged for {', '.join(unjudged)}: u_input is within "
                          "Monte Carlo error of u_D there (the fit interpolates the datum)"
                          if unjudged else ""))
        text = (f"GVPM {where} (calibration data): the calibration reproduces its own data "
                f"within the fit's residual uncertainty, |E| <= {k:g} u_val for every load "
                f"(table {num}'s comparison; a consistency check, not a validation)")
        metric = ("largest |E| / u_val over the loads (E = S - D, u_val = sqrt(u_num^2 + "
                  "u_D^2 - u_input^2), the fit's residual)")
    else:
        text = (f"GVPM {where}: model and test agree within the validation uncertainty, "
                f"|E| <= {k:g} u_val for every load (ASME V&V 20 on table {num}'s comparison)")
        metric = ("largest |E| / u_val over the loads (E = S - D, u_val = sqrt(u_num^2 + "
                  "u_input^2 + u_D^2))")
    return Claim(
        key, text, metric, "<=", k, _worst(ratios), _worst(th_ratio), _kofn(ratios, ok),
        _kofn(th_ratio, ok), propagation=JOINT if rec.predictions[p].startswith("joint") else
        None, reasons=tuple(reasons), warnings=_warnings(steps, [res.name, "bayes"], labels),
        details=tuple(details), consistency=consistency)


def _heldout_claims(steps: Mapping[str, StepResult], labels) -> list[Claim]:
    """Beyond the thesis (the ``heldout`` study): calibrated on 4R, 3R and 2R with a
    discrepancy over H/R, is the held-out 1R prediction right?"""
    found = _validation(steps, "validate_heldout")
    if found is None:
        return []
    res, rec = found
    held = np.flatnonzero(rec.held_out > 0)
    if not held.size or not rec.predictions:
        return []
    j, p, k = int(held[0]), 0, rec.coverage_factor
    far = rec.beyond(j)
    at = f"{rec.configuration} = {rec.conditions[j]:g}" + (
        f" (an extrapolation, {far:g} beyond the calibrated range)" if far > 0 else "")
    flag = (f"{rec.configuration} = {rec.conditions[j]:g} is "
            + extrapolation_note(far, rec.calibrated_span()),) if far > 0 else ()
    names = [labels.get(r, r) for r in rec.names_out]
    inside = [float(v) for v in rec.inside_band[p, j]]
    ratios = [float(v) for v in rec.error_ratio[p, j]]
    pct = f"{100 * rec.level:g} %"
    # (record, prediction, condition, what): the other predictions of the held-out loads
    others = [(rec, q, j, kind) for q, kind in enumerate(rec.predictions) if q != p]
    for name, what in (("validate_no_discrepancy", "calibrated on the same heights without "
                        "a discrepancy"),
                       ("validate_thesis", "the thesis's calibration (its nine inputs, its "
                        "4R loads)")):
        f = _validation(steps, name)
        if f is not None and (jj := _condition(f[1], rec.conditions[j])) is not None:
            others.append((f[1], 0, jj, what))

    def beside(field: str, fmt) -> list[str]:
        return [f"{what}: " + ", ".join(
            f"{names[m]} {fmt(getattr(orec, field)[q, jj, orec.names_out.index(r)])}"
            for m, r in enumerate(rec.names_out) if r in orec.names_out)
            for orec, q, jj, what in others]

    band = [f"{n}: measured {rec.data_mean[p, j, m]:.4g}, band [{rec.band_lower[p, j, m]:.4g}, "
            f"{rec.band_upper[p, j, m]:.4g}] ({rec.predictions[p]})"
            for m, n in enumerate(names) if not inside[m]]
    vv = [f"{n}: {_budget(rec, p, j, m)} > {k:g}" for m, n in enumerate(names)
          if ratios[m] > k]
    warn = _warnings(steps, [res.name, "bayes_discrepancy"], labels)
    return [
        Claim("heldout_1r_band", f"Held-out {at} (beyond the thesis): the measured loads fall "
              f"inside the {pct} prediction band of the calibration on the other heights with a "
              "model discrepancy", f"loads outside the {pct} band of a new measurement", "<=",
              0.0, float(len(inside) - sum(inside)), None, (int(sum(inside)), len(inside)),
              reasons=tuple(band), warnings=warn,
              details=flag + tuple(f"inside the band? {s}" for s in beside(
                  "inside_band", lambda v: "yes" if v else "no"))),
        Claim("heldout_1r_vv20", f"Held-out {at} (beyond the thesis): |E| <= {k:g} u_val for "
              "every load with the model discrepancy (ASME V&V 20)",
              "largest |E| / u_val over the loads", "<=", k, max(ratios), None,
              _kofn(ratios, lambda v: v <= k), reasons=tuple(vv), warnings=warn,
              details=flag + tuple(f"|E| / u_val, {s}" for s in beside(
                  "error_ratio", lambda v: f"{v:.2f}")) + tuple(
                  f"area metric, {s}" for s in beside("area_metric", lambda v: f"{v:.3g}")))]
