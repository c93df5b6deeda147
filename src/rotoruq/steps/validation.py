"""Step type ``validation``: the ASME V&V 20 comparison error E = S - D with its validation
uncertainty u_val = sqrt(u_num^2 + u_input^2 + u_D^2), the interval E +- k u_val, |E| / u_val
and the area metric, per response and condition, with the reference study's "within n sigma"
beside them.

Where the predictions come from (``from``):

* a Bayes step calibrated with a discrepancy (``discrepancy = {...}``): its predictions at the
  data's configurations and at ``predict_at``, with the discrepancy (``eta + delta``) and
  without it (``eta``), both validated;
* a Bayes step with a chain: the joint posterior predictive, chain draws through the model at
  each condition;
* no ``from``: samples of the step's input distributions through the model.

u_input is the spread of those predictions (the propagated input uncertainty, no measurement
noise). A comparison on data the calibration behind the predictions used (the ``from`` step's
data, or its own ``from``'s, matched by value, not by data-set name) is a consistency check,
not a validation: it is labelled so (``calibration_data``), its u_val is the fit's residual
uncertainty sqrt(u_num^2 + u_D^2 - u_input^2) (:func:`rotoruq.methods.validation.validate`;
for the prediction that was fit: with the discrepancy, or the calibration's own; the model
alone of a discrepancy calibration keeps the full budget), and the run's verdict does not
count it; u_D = sqrt(s^2 / n + u_systematic^2) from the repeats of each condition (s their
sample std) and the stated ``u_systematic``; u_num a number (or one per response), the GCI
of the model at each condition (``verification = { ratio = 2, levels = 2, formal_order = 2 }``,
the options of the ``verification`` step type) or the ``u_num`` of an earlier
``verification`` step (``u_num = "STEP.u_num"``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import ParameterError
from ..methods.validation import ComparisonArrays
from ..render.figures import Figure, FigureContext, axis_label
from ..render.tables import StepTable, make_table, with_unit
from ..results import StepRecord, StepResult
from ._common import saved_record
from ._discrepancy import (
    DiscrepancyRecord,
    extrapolation_distance,
    extrapolation_note,
    is_discrepancy,
)
from .base import DESIGNS, StepCheck, StepContext, StepType
from .forward_check import posterior_draws
from .options import SIGNATURE, Option, choice, integer, number, number_list, string, table
from .verification import verification_option

__all__ = ["STEP", "ValidationRecord", "run_validation", "validation_tables",
           "validation_figures", "validation_warnings", "predictions_at", "per_response_values",
           "ONE_ROW_AREA"]

#: Names of the prediction kinds a validation step compares.
JOINT, WITH, WITHOUT, PRIOR, NONE = (
    "joint posterior predictive", "with discrepancy", "without discrepancy (same posterior)",
    "input distributions", "calibrated without discrepancy")


@dataclass(frozen=True, eq=False)
class ValidationRecord(StepRecord, ComparisonArrays):
    """What a validation step saves: p prediction kinds, c conditions, m responses.

    predictions (p) : the prediction kinds (e.g. "with discrepancy", "without discrepancy").
    configuration : the input that varies between conditions ("" without conditions).
    conditions (c) : its values. names_out (m).
    simulation, data_mean, comparison_error, u_num, u_input, u_data, u_val, lower, upper,
    error_ratio, area_metric, relative_area_metric, sigma_distance : (p, c, m), as in
    :class:`rotoruq.methods.validation.ValidationResult` (response units).
    within_n_sigma : (p, c, m) 1.0 / 0.0, the reference study's criterion.
    band_lower, band_upper : (p, c, m) the ``level`` equal-tailed band of a new measurement
    (the predictive samples plus N(0, u_D^2)); inside_band : (p, c, m) 1.0 / 0.0 whether the
    data mean lies in it.
    predictive : (p, n, c, m) the predictive samples validated. data : (k, m) the measured
    rows used; data_condition : (k,) the condition index of each row.
    n_repeats : (c,). held_out : (c,) 1.0 where the calibration did not see the condition's
    data (a Bayes step's ``predict_at``), else 0.0. calibration_data : (c, m) 1.0 where the
    condition's measured response was data of the calibration the predictions come from
    (a consistency check, not counted as validation), else 0.0; empty in a record saved
    before it existed. extrapolation : (c,) how far each condition lies outside the range of
    the conditions with calibration data (configuration units; 0 inside or without
    conditions; empty in an older record). coverage_factor : k. n_sigma : the
    reference criterion's threshold. level : of the band. u_num_source : where u_num came from.
    prediction_labels (p) : each prediction kind in the flat view ("" for the first, e.g.
    "without_discrepancy"); condition_labels (c) : each condition in it ("@<value>", ""
    without conditions); both empty in a record saved before they existed.
    pooled_area_metric : (p, m) the area metric pooled over the conditions (u-pooling,
    :func:`rotoruq.methods.validation.pooled_area_metric`): dimensionless, 0 to 0.5; pit :
    (p, k, m) the u = F_c(D) of each data row under its condition's prediction. Both empty in
    a record saved before them.

    Its flat view: ``comparison_error/thrust@4`` of the first prediction kind,
    ``comparison_error/without_discrepancy/thrust@4`` of another, and so on for every
    (p, c, m) field; ``n_repeats@4``, ``held_out@4``; not the samples and the data.
    """

    AXES = {name: ("prediction", "condition", "response") for name in (
        "simulation", "data_mean", "comparison_error", "u_num", "u_input", "u_data", "u_val",
        "lower", "upper", "error_ratio", "area_metric", "relative_area_metric",
        "sigma_distance", "within_n_sigma", "band_lower", "band_upper", "inside_band")} | {
        "predictive": ("prediction", "sample", "condition", "response"),
        "data": ("row", "response"), "data_condition": ("row",), "n_repeats": ("condition",),
        "conditions": ("condition",), "held_out": ("condition",),
        "pooled_area_metric": ("prediction", "response"),
        "pit": ("prediction", "row", "response"),
        "calibration_data": ("condition", "response"), "extrapolation": ("condition",)}
    FLAT = {"predictive": None, "data": None, "data_condition": None, "conditions": None,
            "pit": None, "calibration_data": None}
    LABELS = {"prediction": "prediction_labels", "condition": "condition_labels"}

    predictions: tuple[str, ...]
    configuration: str
    conditions: np.ndarray
    names_out: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    error_ratio: np.ndarray
    area_metric: np.ndarray
    relative_area_metric: np.ndarray
    sigma_distance: np.ndarray
    within_n_sigma: np.ndarray
    band_lower: np.ndarray
    band_upper: np.ndarray
    inside_band: np.ndarray
    predictive: np.ndarray
    data: np.ndarray
    data_condition: np.ndarray
    n_repeats: np.ndarray
    held_out: np.ndarray
    coverage_factor: float
    n_sigma: float
    level: float
    u_num_source: str
    prediction_labels: tuple[str, ...] = field(default=(), kw_only=True)
    condition_labels: tuple[str, ...] = field(default=(), kw_only=True)
    pooled_area_metric: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)),
                                           kw_only=True)
    pit: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)), kw_only=True)
    calibration_data: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)),
                                         kw_only=True)
    extrapolation: np.ndarray = field(default_factory=lambda: np.zeros(0), kw_only=True)

    def beyond(self, j: int) -> float:
        """How far condition ``j`` lies outside the calibrated conditions (0 inside, or in
        a record saved before ``extrapolation``)."""
        e = np.asarray(self.extrapolation, dtype=float)
        return float(e[j]) if e.size == self.conditions.size and np.isfinite(e[j]) else 0.0

    def calibrated_span(self) -> float:
        """The range of the conditions with calibration data (0 with one or none)."""
        rows = self.calibrated().any(axis=1)
        return float(np.ptp(self.conditions[rows])) if rows.sum() > 1 else 0.0

    def calibrated(self) -> np.ndarray:
        """(c, m) bool: the comparisons on the calibration's own data (all False in a record
        saved before ``calibration_data``)."""
        c, m = self.conditions.size, len(self.names_out)
        cal = np.asarray(self.calibration_data, dtype=float)
        return cal > 0 if cal.shape == (c, m) else np.zeros((c, m), dtype=bool)


def per_response_values(value, responses: Sequence[str], what: str) -> np.ndarray:
    """A number or a table ``{response: number}`` as (m,) in ``responses`` order; a table
    must name every response."""
    if isinstance(value, Mapping):
        missing = [r for r in responses if r not in value]
        if missing:
            raise ParameterError(f"{what} = {{...}} gives no value for {missing}; give one per "
                                 f"response ({', '.join(responses)})")
        return np.array([float(value[r]) for r in responses])
    return np.full(len(responses), float(value))


def _u_num(ctx: StepContext, points: Sequence[Mapping[str, float]]
           ) -> tuple[np.ndarray, str]:
    """u_num (m,) or (c, m), and where it came from."""
    verify = ctx.options.get("verification")
    if verify is not None:
        from .verification import verify_points

        results, _, levels, _ = verify_points(ctx, verify, [dict(p) for p in points])
        u = np.concatenate([np.atleast_2d(r.u_num) for r in results]).astype(float)
        if verify.get("direction") == "finer":
            return u, (f"at each condition, of the grid run ({levels[-1]}) against two finer "
                       f"ones ({' / '.join(levels[:-1])}): its Richardson error, or the three "
                       "grids' spread where they do not converge monotonically")
        order = ("observed order" if verify.get("formal_order") is None
                 else f"assumed order {verify['formal_order']:g}")
        return u, (f"from the GCI at each condition (levels {' / '.join(levels)}, {order}, "
                   f"u_num = GCI / Fs)")
    spec = ctx.options["u_num"]
    if not isinstance(spec, str):
        return per_response_values(spec, ctx.responses, "u_num"), "stated"
    step = spec.split(".")[0]
    previous = getattr(ctx, "previous", None)
    if previous is None or step not in previous:
        raise ParameterError(f"step {ctx.name!r}: u_num = {spec!r} needs the result of step "
                             f"{step!r}, which this run does not hand to the step")
    from .verification import VerificationRecord

    rec = VerificationRecord.read(previous[step])
    out = np.zeros(len(ctx.responses))
    for k, r in enumerate(ctx.responses):
        if r not in rec.names_out:
            raise ParameterError(f"step {ctx.name!r}: verification step {step!r} has no u_num "
                                 f"of {r!r} (it verified {', '.join(rec.names_out)})")
        # the largest over the verified points: conservative where points differ
        out[k] = float(np.max(rec.u_num[:, rec.names_out.index(r)]))
    return out, f"step {step} (largest over its points)"


def _conditions(ctx: StepContext) -> tuple[str, list[dict[str, float]]]:
    cond = ctx.options.get("conditions")
    if not cond:
        return "", [{}]
    grid = {k: list(v) for k, v in cond.items()}
    match = ctx.options.get("match") or next(iter(grid))
    if match not in grid:
        raise ParameterError(f"step {ctx.name!r}: match = {match!r} is not a key of conditions "
                             f"({', '.join(grid)})")
    n = len(grid[match])
    return match, [{k: float(v[j]) for k, v in grid.items()} for j in range(n)]


def predictions_at(ctx: StepContext, configuration: str, points: Sequence[Mapping[str, float]]
                   ) -> tuple[tuple[str, ...], np.ndarray, np.ndarray, dict[str, object]]:
    """The predictive samples (p, n, c, m) at ``points``, their kinds (see the module), which
    points the calibration held out (c,) and the draws left out (``{"count", "first"}``).

    A draw the model rejects at any point (a posterior draw outside the model's valid
    regime, e.g. torsional divergence) is left out at every point, so the samples stay
    paired across conditions; more than half of them failing is an error."""
    from ..model import evaluate

    src = ctx.source
    n = ctx.options["n_samples"]
    if src is not None and is_discrepancy(src):

        rec = DiscrepancyRecord.read(src)
        at = np.asarray(rec.predict_configurations, dtype=float)
        idx = []
        for pt in points:
            if rec.configuration not in pt:
                raise ParameterError(
                    f"step {ctx.name!r}: from = a calibration with a discrepancy over "
                    f"{rec.configuration!r}: give conditions = {{ {rec.configuration} = "
                    "[...] }}")
            hit = np.flatnonzero(np.isclose(at, pt[rec.configuration]))
            if hit.size == 0:
                raise ParameterError(
                    f"step {ctx.name!r}: {rec.configuration} = {pt[rec.configuration]:g} is "
                    f"not among the calibration's predictions ({', '.join(f'{v:g}' for v in at)});"
                    " add it to its predict_at")
            idx.append(int(hit[0]))
        if any(r not in rec.names_out for r in ctx.responses):
            raise ParameterError(f"step {ctx.name!r}: the calibration predicts only "
                                 f"{', '.join(rec.names_out)}")
        sel = [rec.names_out.index(r) for r in ctx.responses]
        eta = rec.pred_model[:, idx][:, :, sel]
        held = np.array([float(np.any(np.isclose(rec.held_out, at[i]))) for i in idx])
        none: dict[str, object] = {"count": 0, "first": ""}
        if rec.kind == "none":
            return (NONE,), eta[None], held, none
        delta = rec.pred_discrepancy[:, idx][:, :, sel]
        return (WITH, WITHOUT), np.stack([eta + delta, eta]), held, none
    draws = posterior_draws(src, ctx.space.names, n, ctx.rng)
    kind = JOINT
    if draws is None:
        from ..methods.sampling import sample

        draws = np.asarray(sample(_Inputs(ctx.space.names), ctx.space, n,
                                  design=ctx.options["design"], seed=ctx.rng).inputs)
        kind = PRIOR
    out, bad, first = [], np.zeros(len(draws), dtype=bool), ""
    for pt in points:
        batch = evaluate(ctx.model(pt), draws)
        values = np.asarray(batch.values, dtype=float)
        failed = ~np.all(np.isfinite(values), axis=1)
        if failed.any() and not first:
            i = int(np.flatnonzero(failed)[0])
            first = f"at {dict(pt)}: {batch.failures.get(i, 'NaN output')}"
        bad |= failed
        out.append(values)
    if 2 * bad.sum() > len(draws):
        raise ParameterError(f"step {ctx.name!r}: {int(bad.sum())} of {len(draws)} predictive "
                             f"samples failed (first {first})")
    pred = np.stack(out, axis=1)[~bad]
    return (kind,), pred[None], np.zeros(len(points)), {"count": int(bad.sum()),
                                                           "first": first}


class _Inputs:
    """A model returning its inputs: draws the design of a space through ``sample``."""

    def __init__(self, names: Sequence[str]):
        self.names_in = tuple(names)
        self.names_out = tuple(names)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(x, dtype=float)


def _data_rows(ctx: StepContext, match: str, points) -> tuple[np.ndarray, np.ndarray]:
    cols = ctx.data_columns
    missing = [r for r in ctx.responses if r not in cols]
    if missing:
        raise ParameterError(f"step {ctx.name!r}: the data set has no column {missing}")
    y = np.column_stack([np.asarray(cols[r], dtype=float) for r in ctx.responses])
    if not match:
        return y, np.zeros(len(y), dtype=int)
    if match not in cols:
        raise ParameterError(f"step {ctx.name!r}: the data set has no column {match!r} to match "
                             f"the conditions (columns: {', '.join(cols)})")
    rows, which = [], []
    for j, pt in enumerate(points):
        hit = np.flatnonzero(np.isclose(np.asarray(cols[match], dtype=float), pt[match]))
        if hit.size == 0:
            raise ParameterError(f"step {ctx.name!r}: no data row with {match} = "
                                 f"{pt[match]:g}")
        rows.extend(hit.tolist())
        which.extend([j] * hit.size)
    return y[rows], np.array(which, dtype=int)


def _lineage(ctx: StepContext) -> list[StepResult]:
    """The ``from`` step and its own ``from`` steps, nearest first (what the predictions
    were conditioned on)."""
    out: list[StepResult] = []
    res = ctx.source
    previous = getattr(ctx, "previous", None) or {}
    while res is not None and all(r is not res for r in out):
        out.append(res)
        up = str(res.meta.get("source") or "").split(".")[0]
        res = previous.get(up)
    return out


def _calibration_mask(ctx: StepContext, data: np.ndarray, which: np.ndarray,
                      held: np.ndarray) -> np.ndarray:
    """(c, m) bool: where a measured response at a condition was data of a calibration
    behind the predictions (the ``from`` lineage): a row whose values equal a calibration
    row on every response that calibration used, by value (an alias or a copy of the data
    set is the same data); a discrepancy step saves its held-out rows too, which it did not
    calibrate on (``held``, (c,))."""
    out = np.zeros((held.size, len(ctx.responses)), dtype=bool)
    for res in _lineage(ctx):
        cal = res.arrays.get("data")
        cols = ((res.meta.get("columns") or {}).get("data")) or []
        shared = [r for r in cols if r in ctx.responses]
        if cal is None or not shared or np.ndim(cal) != 2:
            continue
        a = np.asarray(cal, dtype=float)[:, [list(cols).index(r) for r in shared]]
        b = data[:, [ctx.responses.index(r) for r in shared]]
        hit = np.isclose(b[:, None, :], a[None, :, :], rtol=1e-12, atol=0.0).all(-1).any(1)
        seen = held <= 0 if is_discrepancy(res) else np.ones(held.size, dtype=bool)
        for j in np.unique(which[hit]):
            out[j, [ctx.responses.index(r) for r in shared]] |= bool(seen[j])
    return out


def run_validation(ctx: StepContext) -> StepResult:
    """V&V 20 comparison error, area metric and "within n sigma" per condition and response
    (see the module docstring for the predictions, u_num, u_input and u_D)."""
    from ..methods.validation import pooled_area_metric, validate

    o = ctx.options
    match, points = _conditions(ctx)
    data, which = _data_rows(ctx, match, points)
    n_rep = np.bincount(which, minlength=len(points))
    usys = o.get("u_systematic")
    if usys is None and np.any(n_rep < 2):
        single = [f"{match} = {points[j][match]:g}" if match else "the only condition"
                  for j in np.flatnonzero(n_rep < 2)]
        raise ParameterError(
            f"step {ctx.name!r} (validation): the data have a single row at {', '.join(single)}"
            ": the measurement's uncertainty cannot be estimated from repeats; state it as "
            "u_systematic = { " + ", ".join(f"{r} = ..." for r in ctx.responses)
            + " } (a standard uncertainty per response)")
    u_sys = None if usys is None else per_response_values(usys, ctx.responses, "u_systematic")
    u_num, u_num_source = _u_num(ctx, points)
    kinds, pred, held, left_out = predictions_at(ctx, match, points)
    calibrated = _calibration_mask(ctx, data, which, held)
    cal_at = np.asarray([points[j][match] for j in range(len(points))
                         if match and calibrated[j].any()], dtype=float)
    far = (extrapolation_distance(np.asarray([p[match] for p in points], dtype=float), cal_at)
           if cal_at.size
           else np.zeros(len(points)))
    per_cond = [data[which == j] for j in range(len(points))]
    conds = [points[j][match] if match else j for j in range(len(points))]
    fields: dict[str, list] = {}
    lo_q, hi_q = 0.5 * (1 - o["level"]), 0.5 * (1 + o["level"])
    rng = np.random.default_rng(ctx.rng.integers(2**63))
    for p in range(len(kinds)):
        res = validate([pred[p, :, j] for j in range(len(points))], per_cond, u_num=u_num,
                       u_systematic=u_sys, names_out=ctx.responses, conditions=conds,
                       coverage_factor=o["coverage_factor"], n_sigma=o["n_sigma"],
                       # the model alone of a discrepancy calibration is not what was fit to
                       # the data: its comparison keeps the full budget (still not counted)
                       calibration=calibrated if kinds[p] != WITHOUT else False)
        for f in ("simulation", "data_mean", "comparison_error", "u_num", "u_input", "u_data",
                  "u_val", "lower", "upper", "error_ratio", "area_metric",
                  "relative_area_metric", "sigma_distance"):
            fields.setdefault(f, []).append(np.asarray(getattr(res, f), dtype=float))
        fields.setdefault("within_n_sigma", []).append(res.within_n_sigma.astype(float))
        # band of a new measurement: prediction plus the measurement's own uncertainty
        meas = pred[p] + rng.standard_normal(pred[p].shape) * res.u_data[None]
        lo, hi = np.quantile(meas, [lo_q, hi_q], axis=0)
        fields.setdefault("band_lower", []).append(lo)
        fields.setdefault("band_upper", []).append(hi)
        fields.setdefault("inside_band", []).append(
            ((lo <= res.data_mean) & (res.data_mean <= hi)).astype(float))
        pooled = pooled_area_metric([pred[p, :, j] for j in range(len(points))], per_cond)
        fields.setdefault("pooled_area_metric", []).append(pooled.area)
        fields.setdefault("pit", []).append(pooled.u)
    rec = ValidationRecord(
        predictions=kinds, configuration=match, conditions=np.asarray(conds, dtype=float),
        names_out=tuple(ctx.responses), predictive=pred, data=data, data_condition=which,
        n_repeats=n_rep, held_out=held, coverage_factor=float(o["coverage_factor"]),
        n_sigma=float(o["n_sigma"]), level=float(o["level"]), u_num_source=u_num_source,
        prediction_labels=tuple("" if p == 0 else kind.split(" (")[0].replace(" ", "_")
                                for p, kind in enumerate(kinds)),
        condition_labels=tuple(f"@{c:g}" if match else "" for c in conds),
        calibration_data=calibrated.astype(float), extrapolation=far,
        **{k: np.stack(v) for k, v in fields.items()})
    arrays, meta = rec.parts()
    return StepResult(ctx.name, ctx.type, {}, arrays, meta={
        "n_evaluations": int((pred.shape[1] + int(left_out["count"])) * pred.shape[2])  # type: ignore[call-overload]
        if kinds[0] in (JOINT, PRIOR)
        else 0,
        "responses": list(ctx.responses), "failed_draws": left_out, **meta})


def _fmt_cond(rec: ValidationRecord, j: int, m: int | None = None) -> str:
    text = f"{rec.configuration} = {rec.conditions[j]:g}" if rec.configuration else "-"
    if m is not None and rec.calibrated()[j, m]:
        return text + " (calibration data: consistency, not validation)"
    far = rec.beyond(j)
    return (text + (" (held out)" if rec.held_out[j] else "")
            + (f" (extrapolation, {far:g} beyond the calibrated range)" if far > 0 else ""))


def validation_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    rec = ValidationRecord.read(res)
    k = rec.coverage_factor
    out = []
    for p, kind in enumerate(rec.predictions):
        rows = []
        for j in range(rec.conditions.size):
            for m, r in enumerate(rec.names_out):
                rows.append([
                    _fmt_cond(rec, j, m), with_unit(r, labels), float(rec.simulation[p, j, m]),
                    float(rec.data_mean[p, j, m]), float(rec.comparison_error[p, j, m]),
                    float(rec.u_num[p, j, m]), float(rec.u_input[p, j, m]),
                    float(rec.u_data[p, j, m]), float(rec.u_val[p, j, m]),
                    f"[{rec.lower[p, j, m]:.4g}, {rec.upper[p, j, m]:.4g}]",
                    float(rec.error_ratio[p, j, m]), _area_cell(rec, p, j, m),
                    float(rec.relative_area_metric[p, j, m]) if rec.n_repeats[j] > 1 else "-",
                    f"{rec.sigma_distance[p, j, m]:.2f} ("
                    + ("yes" if rec.within_n_sigma[p, j, m] else "no") + ")",
                    "yes" if rec.inside_band[p, j, m] else "no"])
        out.append(make_table(
            f"V&V 20 comparison error ({kind})",
            ("condition", "response [unit]", "S [unit]", "D [unit]", "E = S - D [unit]",
             "u_num [unit]", "u_input [unit]", "u_D [unit]", "u_val [unit]",
             f"E +- {k:g} u_val [unit]", "|E| / u_val [-]", "area metric [unit]",
             "area / |D| [-]",
             f"|S - D| / predictive std [-] (within {rec.n_sigma:g} sigma)",
             f"D in {100 * rec.level:g} % band"), rows,
            f"[unit]: the response's unit, beside its name. "
            f"S: mean of the predictions ({kind}); D: mean of the repeats ("
            f"{int(rec.n_repeats.min())} to {int(rec.n_repeats.max())} per condition); "
            f"u_val = sqrt(u_num^2 + u_input^2 + u_D^2), u_num {rec.u_num_source}"
            f"; the model error lies in E +- {k:g} u_val; |E| / u_val > {k:g}: a model error the "
            "uncertainties do not hide. Area metric: between the predictive and the data's "
            "empirical CDFs (Ferson et al. 2008), it does not shrink as the spread grows; "
            "the distance in predictive std devs beside it. Band: of a new "
            "measurement (prediction plus N(0, u_D^2))."
            + (" " + ONE_ROW_AREA if np.any(rec.n_repeats < 2) else "")
            + (" Rows on calibration data check the fit's consistency, not the model: S "
               "took in part of D's noise, so u_val = sqrt(u_num^2 + u_D^2 - u_input^2) "
               "there, and the verdict does not count them." if rec.calibrated().any()
               else "")))
    held = [j for j in range(rec.conditions.size) if rec.held_out[j]]
    if held:
        rows = [[_fmt_cond(rec, j), with_unit(r, labels), kind, float(rec.data_mean[p, j, m]),
                 f"[{rec.band_lower[p, j, m]:.4g}, {rec.band_upper[p, j, m]:.4g}]",
                 "inside" if rec.inside_band[p, j, m] else "outside",
                 float(rec.error_ratio[p, j, m]), _area_cell(rec, p, j, m)]
                for j in held for m, r in enumerate(rec.names_out)
                for p, kind in enumerate(rec.predictions)]
        out.insert(0, make_table(
            "Held-out test", ("condition", "response [unit]", "prediction", "measured [unit]",
                              f"{100 * rec.level:g} % band of a new measurement [unit]",
                              "measured is", "|E| / u_val [-]", "area metric [unit]"), rows,
            "Conditions whose data the calibration did not see: out-of-sample predictions. "
            "[unit]: the response's unit, beside its name. " + ONE_ROW_AREA))
    if rec.pooled_area_metric.size:
        out.append(_pooled_table(rec))
    return out


#: Why the area metric of one data row is not shown as a score of the predictions.
ONE_ROW_AREA = (
    "With one data row the area metric is the prediction's mean distance to that value: a "
    "narrow prediction off the mark scores better than a wide one around it, so it ranks "
    "nothing; compare the predictions by their bands here and by the area metric pooled over "
    "the conditions (u-pooling).")


def _area_cell(rec: ValidationRecord, p: int, j: int, m: int) -> float | str:
    """The area metric at one condition, or why it is not a score there (one data row)."""
    if rec.n_repeats[j] < 2:
        return "one row: not a score (see the pooled area metric)"
    return float(rec.area_metric[p, j, m])


def _pooled_table(rec: ValidationRecord) -> StepTable:
    """The area metric pooled over the conditions, per prediction kind and response."""
    k, c = rec.pit.shape[1], rec.conditions.size
    rows = []
    for p, kind in enumerate(rec.predictions):
        for m, r in enumerate(rec.names_out):
            u = rec.pit[p, :, m]
            rows.append([kind, r, float(rec.pooled_area_metric[p, m]) if k > 1 else
                         "one measurement: no pooled score",
                         ", ".join(f"{v:.3f}" for v in u)])
    return make_table(
        "Area metric pooled over the conditions (u-pooling)",
        ("prediction", "response", "pooled area metric", "u = F(D) of each data row"), rows,
        f"Ferson, Oberkampf and Ginzburg (2008): each of the {k} data rows of the {c} "
        "condition(s) becomes u = F(D), the predictive CDF at its own condition; right "
        "predictions give uniform u's. The area between their empirical CDF and the uniform's "
        f"is 0 for a perfect match, {1 / (4 * k):.3g} for u's at the uniform's {k} "
        "quantiles, and at most 0.5 (every u at 0 or 1: every measurement outside its "
        "prediction). Unlike the per-condition area metric it judges a prediction over all "
        "conditions at once, in no response's units." if k > 1 else
        "A single measurement gives u^2 / 2 + (1 - u)^2 / 2 >= 0.25 whatever the prediction: "
        "no score. " + ONE_ROW_AREA)


def validation_figures(res: StepResult, ctx: FigureContext) -> list[Figure]:
    """Per response: data, the prediction's band and E with its +- k u_val bar, against the
    condition."""
    from matplotlib.figure import Figure as MplFigure

    rec = saved_record(ValidationRecord, res)
    if rec is None:
        return []
    x = rec.conditions if rec.configuration else np.arange(rec.conditions.size, dtype=float)
    figs = []
    width = 0.08 * (np.ptp(x) or 1.0)
    for m, r in enumerate(rec.names_out):
        fig = MplFigure(figsize=(7.0, 3.4), layout="constrained")
        ax1, ax2 = fig.subplots(1, 2)
        for row, c in zip(rec.data[:, m], rec.data_condition, strict=True):
            ax1.plot(x[c], row, "k.", ms=6)
        ax1.plot([], [], "k.", label="data")
        for p, kind in enumerate(rec.predictions):
            dx = (p - (len(rec.predictions) - 1) / 2) * width
            ax1.errorbar(x + dx, rec.simulation[p, :, m],
                         yerr=[rec.simulation[p, :, m] - rec.band_lower[p, :, m],
                               rec.band_upper[p, :, m] - rec.simulation[p, :, m]],
                         fmt="o", ms=4, capsize=3, color=f"C{p}",
                         label=f"{kind}, {100 * rec.level:g} % band")
            ax2.errorbar(x + dx, rec.comparison_error[p, :, m],
                         yerr=rec.coverage_factor * rec.u_val[p, :, m], fmt="o", ms=4,
                         capsize=3, color=f"C{p}", label=f"E +- {rec.coverage_factor:g} u_val "
                         f"({kind})")
        ax2.axhline(0.0, color="k", lw=0.8)
        for j in np.flatnonzero(rec.held_out):
            for ax in (ax1, ax2):
                ax.axvspan(x[j] - 2.5 * width, x[j] + 2.5 * width, color="0.92", zorder=0,
                           label="held out (not calibrated on)")
        for ax, what in ((ax1, ""), (ax2, "E = S - D of ")):
            ax.set_xlabel(rec.configuration or "condition", fontsize=8)
            ax.set_ylabel(axis_label(r, None, ctx.units, what), fontsize=8)
            ax.tick_params(labelsize=7)
            ax.legend(fontsize=6)
        figs.append(Figure(f"{res.name}_{r}_validation",
                           f"Validation of {r} ({res.name}): data and the predictions' "
                           f"{100 * rec.level:g} % bands; comparison error E with its "
                           f"+- {rec.coverage_factor:g} u_val bar", fig))
    return figs


def validation_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    """A resolved model error (|E| > k u_val), and where the thesis's criterion passes a
    comparison the V&V 20 budget rejects."""
    rec = saved_record(ValidationRecord, res)
    if rec is None:
        return []
    w = []
    left = res.meta.get("failed_draws") or {}
    if isinstance(left, Mapping) and left.get("count"):
        w.append(f"{res.name}: {left['count']} of {left['count'] + rec.predictive.shape[1]} "
                 f"predictive draws left out: the model failed on them ({left.get('first')})")
    k = rec.coverage_factor
    for j in range(rec.conditions.size):
        if rec.beyond(j) > 0 and WITH in rec.predictions:
            w.append(f"{res.name}: the predictions at {_fmt_cond(rec, j)} are "
                     + extrapolation_note(rec.beyond(j), rec.calibrated_span()))
    for p, kind in enumerate(rec.predictions):
        for j in range(rec.conditions.size):
            for m, r in enumerate(rec.names_out):
                ratio = float(rec.error_ratio[p, j, m])
                if ratio > k and rec.calibrated()[j, m]:
                    w.append(f"{res.name}: {r} at {_fmt_cond(rec, j)} ({kind}): the "
                             "calibration does not fit its own data, E = "
                             f"{rec.comparison_error[p, j, m]:.4g} with the fit's residual "
                             f"u_val = {rec.u_val[p, j, m]:.4g} (|E| / u_val = {ratio:.2f} > "
                             f"{k:g}; a consistency check, not a validation)")
                elif ratio > k:
                    extra = (f"; the within-{rec.n_sigma:g}-sigma criterion passes it "
                             f"({rec.sigma_distance[p, j, m]:.2f} sigma)"
                             if rec.within_n_sigma[p, j, m] else "")
                    w.append(f"{res.name}: {r} at {_fmt_cond(rec, j)} ({kind}): model error "
                             f"resolved, E = {rec.comparison_error[p, j, m]:.4g} with u_val = "
                             f"{rec.u_val[p, j, m]:.4g} (|E| / u_val = {ratio:.2f} > {k:g})"
                             + extra)
    return w


def _check(c: StepCheck) -> None:
    cond = c.options["conditions"]
    if cond is not None:
        lengths = set()
        for key, v in cond.items():
            c.check_input(("conditions", key), key)
            try:
                lengths.add(len(number_list(v)))
            except TypeError:
                c.fail(("conditions", key), f"{key} = [numbers] in conditions", repr(v))
        if len(lengths) != 1:
            c.fail(("conditions",), "conditions lists of equal length")
    match = c.options["match"]
    if match is not None and (cond is None or match not in cond):
        c.fail(("match",), f"a key of conditions ({', '.join(cond or {}) or 'none given'})",
               match)
    if c.options["verification"] is not None and c.options["u_num"] != 0.0:
        c.fail(("verification",), "either u_num = ... or verification = {...} (u_num from the "
               "GCI at each condition), not both")
    if not 0 < c.options["level"] < 1:
        c.fail(("level",), "a band level between 0 and 1 (e.g. 0.9)", repr(c.options["level"]))
    for key in ("u_num", "u_systematic"):
        v = c.options[key]
        if isinstance(v, str):
            if key == "u_systematic":
                c.fail((key,), "a number >= 0 or a table { response = number }", v)
            c.reference(v, key, ("u_num",))
        elif isinstance(v, Mapping):
            vals = c.numbers(v, (key,), key)
            if any(x < 0 for x in vals.values()):
                c.fail((key,), "standard uncertainties >= 0", repr(v))
        elif v is not None and v < 0:
            c.fail((key,), "a standard uncertainty >= 0", repr(v))


def _uncertainty(v):
    if isinstance(v, str | Mapping):
        return v if isinstance(v, str) else table(v)
    return number(positive=True)(v)


STEP = StepType(
    "validation", run_validation, method="rotoruq.methods.validation:validate",
    options={"conditions": Option(table, None),
             "match": Option(string(), None),
             "u_num": Option(_uncertainty, 0.0),
             "verification": Option(verification_option, None),
             "u_systematic": Option(_uncertainty, None),
             "coverage_factor": Option(number(positive=True, allow_zero=False), SIGNATURE),
             "n_sigma": Option(number(positive=True, allow_zero=False), SIGNATURE),
             "level": Option(number(positive=True, allow_zero=False), 0.9),
             "n_samples": Option(integer(2), 1000),
             "design": Option(choice(*DESIGNS), "lhs")},
    needs_data=True, quick={"n_samples": 300}, check=_check,
    tables=validation_tables, figures=validation_figures, warnings=validation_warnings)
