"""Why a claim of the reference study does not hold, computed from the saved results.

Each function reads saved steps (and, for the rotor, the preset numbers ``study.json``
recorded) and returns sentences whose every number comes from the run: local derivatives
from a linear regression on a sampling step's saved inputs and outputs, the blade span where
the pitch is not positive, the model-form gap of a sweep against its spread, the output ratio
CUU targets imply against the model's output-to-output slope, input-spread recovery, and the
validation design of a calibration (data scatter against the likelihood's noise).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..results import StepResult
from ..steps._common import saved_record
from ..steps._sobol import sobol_of
from ..steps.bayes_calibration import posterior_record
from ..steps.cuu import CuuRecord
from ..steps.forward_check import ForwardCheckRecord

__all__ = ["local_effects", "negative_pitch_span", "lift_slope_sections", "sensitivity_causes",
           "model_form_gap", "sweep_growth", "target_consistency", "input_recovery",
           "data_information", "comparison_miss", "calibration_design"]

Steps = Mapping[str, StepResult]
nan = math.nan

# Two responses move together along the calibrated inputs when |corr| is at least this.
_COUPLED = 0.95
# The target ratio and the model's slope disagree when they differ by more than this fraction.
_RATIO_TOL = 0.2
# A posterior correlation this strong is named beside a weakly resolved input.
_MOVES_WITH = 0.5
# A comparison error one calibrated input closes within this many posterior std devs is
# within the posterior's reach.
_REACH = 3.0


def _lab(labels: Mapping[str, str], p: str) -> str:
    return labels.get(p, p)


def _columns(res: StepResult, array: str) -> list[str]:
    return list((res.meta.get("columns") or {}).get(array) or [])


def local_effects(steps: Steps, inputs: Sequence[str], response: str,
                  stds: Mapping[str, float]) -> tuple[str, int, dict[str, float]] | None:
    """Change of ``response`` for +1 std of each input, from a least-squares plane through
    the saved samples of a sampling step of the same study.

    Returns (step name, number of samples, input -> slope * std) for the sampling step that
    covers most of ``inputs``, the one with most samples among those (None when no step saved
    samples of ``response``). Rows with a non-finite value are left out.

    Examples
    --------
    >>> x = np.random.default_rng(0).normal(size=(50, 2))
    >>> s = StepResult("lhs", "sampling", arrays={"inputs": x, "outputs": 3 * x[:, :1] - x[:, 1:]},
    ...                meta={"columns": {"inputs": ["a", "b"], "outputs": ["y"]}})
    >>> step, n, eff = local_effects({"lhs": s}, ["a", "b"], "y", {"a": 0.1, "b": 2.0})
    >>> step, n, round(eff["a"], 12), round(eff["b"], 12)
    ('lhs', 50, 0.3, -2.0)
    """
    best = None
    for res in steps.values():
        if "inputs" not in res.arrays or "outputs" not in res.arrays:
            continue
        cin, cout = _columns(res, "inputs"), _columns(res, "outputs")
        if response not in cout:
            continue
        common = [p for p in inputs if p in cin]
        n = len(res.arrays["inputs"])
        if common and (best is None or (len(common), n) > (len(best[1]), len(best[0].arrays[
                "inputs"]))):
            best = (res, common, cin, cout)
    if best is None:
        return None
    res, common, cin, cout = best
    x = np.asarray(res.arrays["inputs"], dtype=float)
    y = np.asarray(res.arrays["outputs"], dtype=float)[:, cout.index(response)]
    ok = np.all(np.isfinite(x), axis=1) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if len(y) <= x.shape[1] + 1:
        return None
    a = np.column_stack([np.ones(len(y)), x])
    coef = np.linalg.lstsq(a, y, rcond=None)[0][1:]
    return res.name, int(len(y)), {p: float(coef[cin.index(p)] * stds.get(p, math.nan))
                                   for p in common}


def negative_pitch_span(values: Mapping[str, float], fixed: Mapping[str, float]
                        ) -> dict[str, float] | None:
    """Where the linearly twisted blade's pitch theta(r) = collective + twist (r - r_root) /
    (R - r_root) is <= 0: ``r0`` [m], ``fraction`` r0 / R, the section Mach at r0 and at the
    tip, and the pitch at root and tip [deg]. ``values`` are the preset numbers recorded by
    the run, ``fixed`` the step's fixed inputs (a collective set there wins). None without a
    twist or a radius.

    Examples
    --------
    The Bo105 preset at 6 deg collective: -8 deg of twist from r = 1.1 m to R = 4.912 m.

    >>> span = negative_pitch_span({"radius": 4.912, "root_cutout": 1.1, "twist_deg": -8.0,
    ...                             "omega": 44.4, "speed_of_sound": 340.3},
    ...                            {"collective_deg": 6.0})
    >>> round(span["r0"], 3), round(span["fraction"], 3), round(span["mach_r0"], 3)
    (3.959, 0.806, 0.517)
    """
    def num(k):
        v = fixed.get(k, values.get(k))
        try:
            return float(v) if v is not None else math.nan
        except (TypeError, ValueError):
            return math.nan

    big_r, r_root, twist, coll = (num("radius"), num("root_cutout"), num("twist_deg"),
                                  num("collective_deg"))
    if not all(math.isfinite(v) for v in (big_r, r_root, twist, coll)) or big_r <= r_root:
        return None
    tip = coll + twist
    out = {"collective": coll, "twist": twist, "root": r_root, "radius": big_r,
           "tip_pitch": tip, "r0": math.nan, "fraction": 0.0}
    if twist < 0 < coll and tip <= 0:
        r0 = r_root + (coll / -twist) * (big_r - r_root)
        out.update(r0=r0, fraction=r0 / big_r)
    elif coll <= 0:
        out.update(r0=r_root, fraction=r_root / big_r)
    omega, a = num("omega"), num("speed_of_sound")
    if math.isfinite(omega) and math.isfinite(a) and a > 0:
        out["mach_tip"] = omega * big_r / a
        if math.isfinite(out["r0"]):
            out["mach_r0"] = omega * out["r0"] / a
    return out


def lift_slope_sections(spanwise: Mapping | None, stds: Mapping[str, float],
                        labels: Mapping[str, str]) -> list[str]:
    """The physical cause of a lift-slope ranking, from the section loads the run recorded
    at its nominal point (:func:`rotoruq.study.runner.spanwise_record`): the direct thrust
    change for +1 std of each lift slope (inflow and blade motion held), its squared share,
    and where the top one acts (stations, Mach numbers, angles of attack); and, when the run
    also recorded the blade at a twist with no negative pitch, whether the same input stays
    on top there.

    Examples
    --------
    >>> rec = {"r": [1.0, 2.0], "w": [1.0, 1.0], "mach": [0.3, 0.6],
    ...        "alpha_deg": [2.0, -1.0], "inputs": {"collective_deg": 6.0},
    ...        "thrust_derivative": {"a": 100.0, "b": -300.0},
    ...        "station_derivative": {"a": [100.0, 0.0], "b": [0.0, -300.0]}}
    >>> lift_slope_sections(rec, {"a": 0.01, "b": 0.01}, {})[0][:48]
    'the section loads at the nominal point (collecti'
    """
    if not spanwise or not spanwise.get("thrust_derivative") or spanwise.get("failure"):
        return []

    def effects(rec) -> dict[str, float]:
        return {p: float(d) * stds[p] for p, d in rec["thrust_derivative"].items()
                if p in stds and math.isfinite(stds[p])}

    eff = effects(spanwise)
    total = sum(v * v for v in eff.values())
    if not eff or total <= 0:
        return []
    order = sorted(eff, key=lambda p: -abs(eff[p]))
    top = order[0]
    r = np.asarray(spanwise["r"], dtype=float)
    mach = np.asarray(spanwise["mach"], dtype=float)
    alpha = np.asarray(spanwise["alpha_deg"], dtype=float)
    per = np.abs(np.asarray(spanwise["station_derivative"][top], dtype=float))
    acts = per > 1e-6 * per.max()
    coll = (spanwise.get("inputs") or {}).get("collective_deg")
    where = f"collective {coll:g} deg, " if isinstance(coll, int | float) else ""
    out = [f"the section loads at the nominal point ({where}every input at its "
           "mean; reference solve, inflow and blade motion held) give the same order: +1 std "
           "of each lift slope changes the thrust by "
           + ", ".join(f"{eff[p]:+.3g} ({_lab(labels, p)})" for p in order)
           + " N, squared shares "
           + ", ".join(f"{_lab(labels, p)} {eff[p] ** 2 / total:.2f}" for p in order)
           + f"; {_lab(labels, top)} acts on the sections at r = {r[acts].min():.3g} to "
           f"{r[acts].max():.3g} m (Mach {mach[acts].min():.2f} to {mach[acts].max():.2f}), "
           f"where the dynamic pressure is highest and the angle of attack is "
           f"{alpha[acts].min():+.2g} to {alpha[acts].max():+.2g} deg: the outboard sections' "
           "lift-slope term sets the size of the effect, hence the ranking"]
    alt = spanwise.get("no_negative_pitch")
    if alt and not alt.get("failure") and alt.get("thrust_derivative"):
        e2 = effects(alt)
        t2 = sum(v * v for v in e2.values())
        if e2 and t2 > 0:
            top2 = max(e2, key=lambda p: abs(e2[p]))
            same = "still has" if top2 == top else "no longer has"
            out.append(
                f"at {alt['twist_deg']:g} deg of twist (tip pitch 0: no section with negative "
                f"pitch), {_lab(labels, top)} {same} the largest share ("
                + ", ".join(f"{_lab(labels, p)} {e2[p] ** 2 / t2:.2f}"
                            for p in sorted(e2, key=lambda p: -abs(e2[p])))
                + ")" + (": the ranking does not come from the negative pitch"
                         if top2 == top else ""))
    return out


def sensitivity_causes(sens: StepResult, steps: Steps, response: str, claimed: str,
                       labels: Mapping[str, str], values: Mapping[str, float],
                       spanwise: Mapping | None = None) -> list[str]:
    """Why ``claimed`` is not the largest main index of ``response``: the dominant input,
    the local effect of +1 std of each input, for lift slopes the section loads behind the
    ranking (``spanwise``, :func:`lift_slope_sections`), and, for a twisted rotor blade,
    the span where the pitch (hence the angle of attack) is negative (the effect's sign)."""
    got = sobol_of(sens)
    if got is None or response not in got[0].names_out:
        return []
    sobol, std, _ = got
    k = sobol.names_out.index(response)
    inputs = list(sobol.names_in)
    main = {p: float(sobol.main[k, j]) for j, p in enumerate(inputs)}
    top = max(main, key=lambda p: main[p])
    out = [f"{_lab(labels, top)} dominates (S = {main[top]:.3f} against "
           f"{main.get(claimed, math.nan):.3f} for {_lab(labels, claimed)})"]
    if sobol.negligible is not None and sobol.negligible[k]:
        out.append(f"the {response} variance is negligible (std {std[k]:.3g}), the indices "
                   "split noise")
    dists = sens.input_distributions()
    stds = {p: dists[p].std if p in dists else math.nan for p in inputs}
    fx = local_effects(steps, inputs, response, stds)
    signs: dict[str, float] = {}
    if fx is not None:
        step, n, eff = fx
        signs = eff
        order = sorted(eff, key=lambda p: -abs(eff[p]))
        out.append(f"+1 std of each input changes {response} by "
                   + ", ".join(f"{eff[p]:+.3g} ({_lab(labels, p)})" for p in order)
                   + f" (least-squares plane through the {n} saved samples of step {step})")
        total = sum(v * v for v in eff.values() if math.isfinite(v))
        if total > 0:
            # a linear effect's share of the variance: what ranks the main indices
            out.append("the ranking is the size of each input's effect, not its sign: the "
                       "squared effects' shares "
                       + ", ".join(f"{_lab(labels, p)} {eff[p] ** 2 / total:.2f} "
                                   f"(S {main.get(p, math.nan):.2f})" for p in order[:3])
                       + " give the main indices' order")
    lift = [p for p in inputs if p.startswith("cla_")]
    if lift and response == "thrust":
        out += lift_slope_sections(spanwise, {p: stds[p] for p in lift}, labels)
    span = negative_pitch_span(values, sens.meta.get("fixed") or {})
    if lift and span is not None:
        if span["fraction"] > 0 and math.isfinite(span["r0"]):
            mach = ""
            if "mach_r0" in span:
                mach = (f"; section Mach {span['mach_r0']:.2f} there to "
                        f"{span['mach_tip']:.2f} at the tip")
            neg = [_lab(labels, p) for p in sorted(lift, key=lambda p: signs.get(p, 0.0))
                   if signs.get(p, 0.0) < 0]
            carried = (f": there the angle of attack is negative, so a steeper lift slope "
                       f"lowers the lift ({', '.join(neg)} lower the {response}): this sets "
                       "the sign of their effect, not its size" if neg else "")
            out.append(
                f"blade pitch theta(r) = {span['collective']:.3g} deg "
                f"{span['twist']:+.3g} deg (r - {span['root']:.3g} m) / "
                f"{span['radius'] - span['root']:.4g} m is <= 0 outboard of r = "
                f"{span['r0']:.3g} m ({span['fraction']:.2f} R{mach}){carried}")
        else:
            out.append(f"blade pitch is positive over the whole span ({span['collective']:.3g} "
                       f"deg at the root, {span['tip_pitch']:.3g} deg at the tip): the "
                       "ranking comes from the section loads, not from negative lift")
    return out


def model_form_gap(res: StepResult, resp: str, labels_h: Sequence[str], joint: bool,
                   labels: Mapping[str, str]) -> list[str]:
    """A sweep whose miss grows while the model's spread does not: measured - model at
    each point of forward-check step ``res`` against the model std (``joint``: of the joint
    posterior predictive)."""
    rec = saved_record(ForwardCheckRecord, res)
    if rec is None:
        return []
    mean, std, _ = rec.prediction(joint)
    pts = []
    for h in labels_h:
        d, m, s = (rec.at(v, h, resp) for v in (rec.measured, mean, std))
        if not any(map(math.isnan, (d, m, s))):
            pts.append((h, d - m, s))
    if len(pts) < 2:
        return []
    first, last = pts[0], pts[-1]
    params = (", ".join(_lab(labels, p) for p in res.meta.get("parameters") or [])
              or "its inputs")
    trend = "grows" if abs(last[1]) > abs(first[1]) else "shrinks"
    change = abs(last[1] - first[1])
    smax = max(p[2] for p in pts)
    out = (f"the gap measured - model {trend} from {first[1]:+.3g} at {first[0][1:]}R to "
           f"{last[1]:+.3g} at {last[0][1:]}R ({abs(last[1]) / last[2]:.1f} model std devs) "
           f"while the model std stays {min(p[2] for p in pts):.3g} to {smax:.3g}")
    if change > 3 * smax:
        out += (f": its change over the heights ({change:.3g}) is {change / smax:.0f} x the "
                f"largest model std, which a spread of {params} (the step's uncertain inputs) "
                "cannot account for: the model's dependence on the height misses the test's")
    return [out]


def sweep_growth(base: StepResult | None, res: StepResult, resp: Sequence[str], at: str,
                 rows: Sequence[str], joint: bool) -> str:
    """How much the model's and the test's loads change from the 4R reference point of
    forward-check step ``base`` to ``at`` of forward-check step ``res`` (a model-form
    measure: the ground-effect model's strength); ``joint``: of the joint posterior
    predictive."""
    ref = None if base is None else saved_record(ForwardCheckRecord, base)
    rec = saved_record(ForwardCheckRecord, res)
    if ref is None or rec is None:
        return ""
    mean0, std0, _ = ref.prediction(joint)
    mean1 = rec.prediction(joint)[0]
    parts: list[str] = []
    weaker: list[bool] = []
    weaker_abs: list[bool] = []  # loads near zero at 4R: judged only when no other is
    for lab, r in zip(rows, resp, strict=True):
        m0, m1 = ref.at(mean0, "@4", r), rec.at(mean1, at, r)
        d0, d1 = ref.at(ref.measured, "@4", r), rec.at(rec.measured, at, r)
        s0 = ref.at(std0, "@4", r)
        if not all(map(math.isfinite, (m0, m1, d0, d1, s0))):
            continue
        if m0 == 0 or abs(d0) < 3 * s0:
            # a reference near zero (within 3 std devs) makes a percentage meaningless: the
            # change in the load's units, when the test's exceeds the model's spread
            if abs(d1 - d0) > s0:
                parts.append(f"{lab} {m1 - m0:+.3g} against the test's {d1 - d0:+.3g} "
                             "(absolute: the 4R value is near zero)")
                weaker_abs.append(abs(m1 - m0) < abs(d1 - d0))
            continue
        if abs(d1 / d0 - 1) < 0.02:
            continue
        parts.append(f"{lab} {100 * (m1 / m0 - 1):+.1f} % against the test's "
                     f"{100 * (d1 / d0 - 1):+.1f} %")
        weaker.append(abs(m1 / m0 - 1) < abs(d1 / d0 - 1))
    if not parts:
        return ""
    weaker = weaker or weaker_abs
    what = ("weaker than" if all(weaker) else "stronger than" if not any(weaker)
            else "unlike")
    return (f"from 4R to {at[1:]}R the model's loads change " + ", ".join(parts)
            + f": the model's change with the height is {what} the test's, a model-form gap "
            "that no calibration at 4R can close")


def _finite(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def target_consistency(cuu: StepResult, labels: Mapping[str, str]) -> list[str]:
    """Pairs of targeted responses that the model moves together (|corr| >= 0.95 over the
    calibrated samples): the std ratio their targets imply against the model's slope
    d(b)/d(a) along the calibrated inputs. When they differ no input spread matches both."""
    rec = saved_record(CuuRecord, cuu)
    cols = _columns(cuu, "outputs_calibrated")
    if rec is None or "outputs_calibrated" not in cuu.arrays or len(cols) < 2:
        return []
    y = np.asarray(cuu.arrays["outputs_calibrated"], dtype=float)
    y = y[np.all(np.isfinite(y), axis=1)]
    k = {r: rec.names_out.index(r) for r in cols if r in rec.names_out}
    tgt = {r: _finite(rec.target_std[k[r]]) if r in k else None for r in cols}
    out = []
    for i, a in enumerate(cols):
        for j in range(i + 1, len(cols)):
            b = cols[j]
            sa, sb = tgt[a], tgt[b]
            if not sa or not sb or len(y) < 3 or np.std(y[:, i]) == 0 or np.std(y[:, j]) == 0:
                continue
            corr = float(np.corrcoef(y[:, i], y[:, j])[0, 1])
            if abs(corr) < _COUPLED:
                continue
            slope = float(np.cov(y[:, i], y[:, j])[0, 1] / np.var(y[:, i], ddof=1))
            implied = sb / sa
            if abs(implied / abs(slope) - 1) <= _RATIO_TOL:
                continue
            inputs = ", ".join(_lab(labels, p) for p in rec.names_in)
            out.append(
                f"the targets imply std({b}) / std({a}) = {implied:.3g}, the model's "
                f"d{b}/d{a} along the calibrated inputs is {slope:.3g} (corr {corr:+.3f} over "
                f"{len(y)} samples): no spread of {inputs} "
                f"matches both (calibrated std {rec.calibrated_out_std[k[a]]:.3g}"
                f" and {rec.calibrated_out_std[k[b]]:.3g} against targets "
                f"{sa:.3g} and {sb:.3g})")
    return out


def input_recovery(cuu: StepResult, truth: StepResult | None, labels: Mapping[str, str]
                   ) -> tuple[dict[str, float], list[str]]:
    """Calibrated input std / true input std for each calibrated input whose true
    distribution the step that made the targets recorded, and sentences for the inputs
    outside a factor 2 (none for a CUU saved without its record)."""
    rec = saved_record(CuuRecord, cuu)
    if truth is None or rec is None:
        return {}, []
    dists = truth.input_distributions()
    cal = {p: float(rec.std[j]) for j, p in enumerate(rec.names_in)}
    true = {p: float(dists[p].std) for p in rec.names_in if p in dists}
    ratios = {p: cal[p] / true[p] for p in rec.names_in if true.get(p)}
    alive = [_lab(labels, p) for p, r in ratios.items() if r >= 1e-3]

    def collapse(p: str) -> str:
        others = [q for q in alive if q != _lab(labels, p)]
        return ("; the spread collapsed" + (f": the output std devs come from {', '.join(others)}"
                                           if others else "") if ratios[p] < 1e-3 else "")

    out = [f"{_lab(labels, p)}: calibrated std {cal[p]:.3g} against the true "
           f"{true[p]:.3g} (x{r:.2g}{collapse(p)})"
           for p, r in ratios.items() if not 0.5 <= r <= 2.0]
    return ratios, out


def data_information(bayes: StepResult, steps: Steps, params: Sequence[str],
                     labels: Mapping[str, str]) -> list[str]:
    """Why the data leave the posterior of ``params`` wide: the calibrated responses give at
    most one equation each for the calibrated inputs, and a linear-Gaussian posterior built
    from the run's own numbers (each input's effect for +1 prior std, from a least-squares
    plane through a sampling step's saved samples, :func:`local_effects`; the likelihood's
    noise std; the number of data rows) says how much of each input's prior std the data
    can remove, beside the run's posterior/prior std and the input it moves with most.

    In prior-std units the linear-Gaussian posterior covariance is (I + n A^T N^-2 A)^-1, A
    (m, d) the effects, N the noise std devs, n the data rows: along the d - m directions A
    does not see it stays the prior's.

    Examples
    --------
    >>> from rotoruq.steps.bayes_calibration import BayesRecord
    >>> x = np.random.default_rng(0).normal(size=(50, 2))
    >>> lhs = StepResult("lhs", "sampling", arrays={"inputs": x, "outputs": x[:, :1] + x[:, 1:]},
    ...                  meta={"columns": {"inputs": ["a", "b"], "outputs": ["y"]}})
    >>> arrays, meta = BayesRecord.partial(("a", "b"), ("y",), noise_std=np.array([0.1]),
    ...                                    std_ratio=np.array([0.7, 0.7]),
    ...                                    correlation=np.array([[1.0, -0.9], [-0.9, 1.0]])
    ...                                    ).parts()
    >>> from rotoruq.params import Normal
    >>> from rotoruq.results import dist_to_dict
    >>> prior = {"input_distributions": {k: dist_to_dict(Normal(0, 1)) for k in "ab"}}
    >>> b = StepResult("bayes", "bayes_calibration", {}, {"data": np.zeros((4, 1)), **arrays},
    ...                meta={**meta, **prior})
    >>> data_information(b, {"lhs": lhs}, ["a"], {})[0][:62]
    'the 4 data rows measure 1 response (y) for 2 calibrated inputs'
    """
    rec = posterior_record(bayes)
    data = bayes.arrays.get("data")
    if rec is None or data is None or not len(data):
        return []
    names = list(rec.names_in)
    dists = bayes.input_distributions()
    stds = {p: float(dists[p].std) if p in dists else math.nan for p in names}
    rows, used = [], None
    for r in rec.names_out:
        fx = local_effects(steps, names, r, stds)
        if fx is None or set(fx[2]) != set(names):
            return []
        rows.append([fx[2][p] for p in names])
        used = fx[:2]
    a = np.asarray(rows, dtype=float)
    noise = np.asarray(rec.noise_std, dtype=float)
    if not np.all(np.isfinite(a)) or not np.all(noise > 0) or used is None:
        return []
    n, (m, d) = len(data), a.shape
    h = a / noise[:, None]
    cov = np.linalg.inv(np.eye(d) + n * h.T @ h)
    linear = np.sqrt(np.diag(cov))
    run_ratio = np.asarray(rec.std_ratio, dtype=float)
    corr = np.asarray(rec.correlation, dtype=float) if np.size(rec.correlation) else None
    free = d - int(np.linalg.matrix_rank(a))
    resp = ", ".join(rec.names_out)
    out = []
    for p in params:
        if p not in names:
            continue
        j = names.index(p)
        eff = ", ".join(f"{r} {a[i, j]:+.3g}" for i, r in enumerate(rec.names_out))
        text = (f"the {n} data rows measure {m} response{'s' if m > 1 else ''} ({resp}) for {d} "
                f"calibrated inputs: they fix at most {m} combination{'s' if m > 1 else ''} "
                f"of the inputs" + (f" and leave {free} to the prior" if free > 0 else "")
                + f"; +1 prior std of {_lab(labels, p)} changes {eff} (plane through the "
                f"{used[1]} saved samples of step {used[0]}); with the noise std "
                + ", ".join(f"{v:.3g}" for v in noise)
                + f" a linear-Gaussian posterior of these effects keeps {linear[j]:.2f} of "
                f"{_lab(labels, p)}'s prior std (the run's posterior: {run_ratio[j]:.2f})")
        if corr is not None and corr.shape == (d, d) and d > 1:
            k = max((i for i in range(d) if i != j), key=lambda i: abs(corr[j, i]))
            if abs(corr[j, k]) >= _MOVES_WITH:
                text += (f"; it moves with {_lab(labels, names[k])} (posterior corr "
                         f"{corr[j, k]:+.2f})")
        if linear[j] >= 0.5:
            text += (": the data do not separate it from the other inputs, so its posterior "
                     "stays wide and its mean can sit far from the truth")
        else:
            text += (": the data could resolve it; a wider posterior comes from elsewhere "
                     "(the model's nonlinearity, data that do not fit one input)")
        out.append(text)
    return out


def comparison_miss(steps: Steps, bayes: StepResult | None, response: str, error: float,
                    u_num: float, u_input: float, labels: Mapping[str, str]) -> str:
    """What a V&V 20 miss of ``response`` (comparison error ``error`` = S - D) is not: the
    grid (``u_num`` against |E|) nor the calibrated inputs' spread (``u_input``); and what
    closing it with one calibrated input of ``bayes`` would take: the shift, in posterior std
    devs, of the input whose slope (a least-squares plane through a sampling step's saved
    samples, :func:`local_effects`) needs the smallest. "" when nothing is computable.

    Examples
    --------
    >>> from rotoruq.steps.bayes_calibration import BayesRecord
    >>> x = np.random.default_rng(0).normal(size=(30, 2))
    >>> lhs = StepResult("lhs", "sampling", arrays={"inputs": x, "outputs": 0.5 * x[:, :1]},
    ...                  meta={"columns": {"inputs": ["a", "b"], "outputs": ["roll"]}})
    >>> arrays, meta = BayesRecord.partial(("a", "b"), ("roll",),
    ...                                    std=np.array([0.1, 0.1])).parts()
    >>> b = StepResult("bayes", "bayes_calibration", {}, arrays, meta=meta)
    >>> comparison_miss({"lhs": lhs}, b, "roll", -0.25, 1e-3, 0.01, {})[:56]
    'u_num 0.001 is 0.4 % of |E| = 0.25 and u_input 0.01 is 4'
    """
    if not math.isfinite(error) or error == 0:
        return ""
    out = (f"u_num {u_num:.3g} is {100 * u_num / abs(error):.1f} % of |E| = {abs(error):.3g} "
           f"and u_input {u_input:.3g} is {100 * u_input / abs(error):.1f} %: not the grid, "
           "not the spread of the calibrated inputs")
    rec = None if bayes is None else posterior_record(bayes)
    if rec is None:
        return out
    names = list(rec.names_in)
    fx = local_effects(steps, names, response, {p: 1.0 for p in names})
    post = {p: float(rec.std[j]) for j, p in enumerate(names)}
    if fx is None:
        return out
    step, n, slope = fx
    need = {p: abs(error / slope[p]) / post[p] for p in slope
            if slope[p] and math.isfinite(slope[p]) and post.get(p, 0) > 0}
    if not need:
        return out
    best = min(need, key=lambda p: need[p])
    verdict = (f"beyond {_REACH:g} of them: the calibrated inputs cannot produce this "
               f"{response} at their posterior" if need[best] > _REACH else
               f"within {_REACH:g} of them")
    return (out + f"; closing E with one calibrated input would take {need[best]:.3g} posterior "
            f"std devs of {_lab(labels, best)} (d{response}/d{_lab(labels, best)} = "
            f"{slope[best]:.3g}, posterior std {post[best]:.3g}; plane through the {n} saved "
            f"samples of step {step}), {verdict}")


def calibration_design(bayes: StepResult) -> list[str]:
    """The validation design of a calibration: the scatter of its data points against the
    likelihood's noise std. Data scattered far beyond the noise come from different inputs,
    yet the likelihood treats them as repeats of one input.

    Examples
    --------
    >>> from rotoruq.steps.bayes_calibration import BayesRecord
    >>> data = np.array([[2100.0], [2200.0], [2300.0]])
    >>> arrays, meta = BayesRecord.partial(("a",), ("thrust",),
    ...                                    noise_std=np.array([0.5])).parts()
    >>> b = StepResult("bayes", "bayes_calibration", {}, {"data": data, **arrays}, meta=meta)
    >>> calibration_design(b)[0][:57]
    'the 3 data points scatter (std) by thrust 100 against 0.5'
    """
    rec = posterior_record(bayes)
    data = bayes.arrays.get("data")
    if rec is None or data is None or len(data) < 2 or len(rec.names_out) != np.shape(data)[1]:
        return []
    parts = []
    for j, r in enumerate(rec.names_out):
        noise = float(rec.noise_std[j])
        scatter = float(np.std(np.asarray(data, dtype=float)[:, j], ddof=1))
        if noise > 0 and scatter > 3 * noise:
            parts.append(f"{r} {scatter:.3g} against {noise:.3g} (x{scatter / noise:.0f})")
    if not parts:
        return []
    return [f"the {len(data)} data points scatter (std) by " + ", ".join(parts)
            + ": they come from a population of different inputs, but the likelihood treats "
            "them as repeats of one input with that noise, so the posterior is a compromise "
            "point, not the population's mean"]
