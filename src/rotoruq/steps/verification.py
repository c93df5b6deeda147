"""Step type ``verification``: solution verification of the study's model at chosen points.

The model's discretization is coarsened by a constant ``ratio`` from the grid the study runs
(the finest level, whose numerical uncertainty u_num a later ``validation`` step uses:
``u_num = "STEP.u_num"``), over ``levels`` grids: three give the observed order and Roache's
GCI with Fs = 1.25, two need the scheme's ``formal_order`` and take Fs = 3 (see
:mod:`rotoruq.methods.verification`). u_num = GCI / Fs in response units (ASME V&V 20).
With ``direction = "finer"`` (three levels) the grid the study runs is the coarsest and
two finer grids judge it: its u_num is its Richardson error where the three converge
monotonically in the asymptotic range, else the three grids' spread (Eca and Hoekstra 2014;
:func:`production_u_num`), which covers the actual error against a 16 times finer solve at
every height and load the reproduction validates (``tests/test_validation.py``).

What is refined:

* the built-in rotor: its Gauss stations and azimuth steps (``refine = "both"``, or only
  ``"azimuth"`` or ``"stations"``), every level solved at the tight tolerance
  :data:`TOLERANCE` so that the iteration error does not pollute the observed order (as
  :class:`rotoruq.rotor.discretization.RotorDiscretization`); the counts must stay integers;
* an external model: the template field ``field`` (a count such as ``n_intervals``: the
  finest level has ``field_value``, by default its value in ``[model] fixed``, each coarser
  one ``ratio`` times fewer), written into the parameters file as a fixed input.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..methods.verification import GRID_FIELDS, GridConvergenceArrays
from ..render.tables import StepTable, make_table, with_unit
from ..results import StepRecord, StepResult
from ._common import saved_record
from .base import StepCheck, StepContext, StepType
from .options import Option, choice, integer, number, string

__all__ = ["STEP", "VerificationRecord", "run_verification", "verify_points",
           "production_u_num", "verification_tables", "verification_warnings", "TOLERANCE",
           "VERIFY_KEYS", "verification_option"]

#: Solver tolerance of the rotor at every verification level.
TOLERANCE = 1e-12


@dataclass(frozen=True, eq=False)
class VerificationRecord(StepRecord, GridConvergenceArrays):
    """What a verification step saves: L levels (finest first), P points, M responses.

    names_in (the step's parameters), names_out (M); points (P) : labels of the points;
    x (P, len(names_in)) : the parameter values at each point; levels (L) : the levels as
    text (rotor: "stations x azimuth steps"; external: the field's value). values (L, P, M).
    observed_order, extrapolated, gci_fine, u_num, asymptotic_ratio (P, M) and
    in_asymptotic_range, converging, oscillatory (P, M) 1.0 / 0.0: as in
    :class:`rotoruq.methods.verification.VerificationResult`. ratio, safety_factor,
    formal_order (NaN: observed), refined : what the levels refine. u_num_max (M,) : the
    largest u_num over the points (what a validation step takes); point_labels (P) : each
    point in the flat view (``"#0"``, ``"#1"``, ...); both empty in a record saved before
    they existed.

    Its flat view: ``u_num/thrust`` (u_num_max), ``u_num/thrust#0`` and the same of every
    (P, M) field, ``values/<level index>/thrust#0``, ``x/<input>#0``.
    """

    AXES = {"x": ("point", "input"), "values": ("level", "point", "response"),
            **{k: ("point", "response") for k in GRID_FIELDS}, "u_num_max": ("response",)}
    FLAT = {"u_num_max": "u_num"}
    LABELS = {"point": "point_labels"}

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    points: tuple[str, ...]
    levels: tuple[str, ...]
    x: np.ndarray
    values: np.ndarray
    ratio: float
    safety_factor: float
    formal_order: float
    refined: str
    u_num_max: np.ndarray = field(default_factory=lambda: np.zeros(0), kw_only=True)
    point_labels: tuple[str, ...] = field(default=(), kw_only=True)


def _rotor_of(model: Any) -> Any:
    """The rotor inside ``model`` (through evaluation wrappers), None when there is none: a
    model with a blade ``grid`` whose constructor takes ``n_stations``, ``n_azimuth`` and
    ``tolerance`` (the built-in rotor; the steps layer does not import it)."""
    seen = 0
    while model is not None and not hasattr(model, "grid") and seen < 8:
        model = getattr(model, "model", None)
        seen += 1
    return model if model is not None and hasattr(model, "grid") else None


def _rotor_factory(rotor: Any, ratio: float, refine: str, name: str):
    n_st, n_az = int(rotor.grid.r.size), int(rotor.grid.psi.size)
    r = int(round(ratio))
    if abs(ratio - r) > 1e-12:
        raise ParameterError(f"step {name!r}: the rotor's stations and azimuth steps are "
                             f"counts: ratio must be an integer > 1, got {ratio:g}")

    def counts(level: int) -> tuple[int, int]:
        out = []
        for n, on, what in ((n_st, refine in ("both", "stations"), "stations"),
                            (n_az, refine in ("both", "azimuth"), "azimuth steps")):
            if level < 0:  # finer than the grid the study runs
                out.append(n * r ** -level if on else n)
                continue
            q, rem = divmod(n, r ** level)
            if on and rem:
                raise ParameterError(
                    f"step {name!r}: coarsening {n} {what} by {r ** level} does not give an "
                    f"integer count: use fewer levels (2, with formal_order), another ratio, "
                    f"or refine = \"azimuth\" / \"stations\"")
            out.append(q if on else n)
        return out[0], out[1]

    def factory(level: int):
        s, a = counts(level)
        return type(rotor)(rotor.preset, names_in=rotor.names_in, names_out=rotor.names_out,
                           fixed=rotor.fixed, airfoil=rotor.airfoil, n_stations=s,
                           n_azimuth=a, tolerance=TOLERANCE)

    return factory, lambda level: "{} stations x {} azimuth steps".format(*counts(level))


def verify_points(ctx: StepContext, options: Mapping[str, Any],
                  points: list[dict[str, float]]) -> tuple[list[Any], list[str], list[str],
                                                           np.ndarray]:
    """Grid convergence of the step's model at ``points`` (input values over the step's
    fixed inputs; the step's parameters at their means unless given), with ``options``
    ``ratio``, ``levels``, ``formal_order``, ``refine``, ``field``, ``field_value``.

    Returns one :class:`~rotoruq.methods.verification.VerificationResult` per point, the
    points' labels, the levels' labels and the parameter values (n_points, d)."""
    from ..methods.verification import verify_discretization

    o = options
    ratio, n_levels = float(o["ratio"]), int(o["levels"])
    means = {n: d.mean for n, d in zip(ctx.space.names, ctx.space.distributions, strict=True)}
    finer = o.get("direction") == "finer"
    # "finer": the grid the study runs is the coarsest of the levels, its u_num read from
    # the finer ones (production_u_num); "coarser": it is the finest
    levels = list(range(1 - n_levels, 1)) if finer else list(range(n_levels))
    labels: list[str] = []
    level_text: list[str] = []
    xs, results = [], []
    for pt in points or [{}]:
        values = {**means, **{k: float(v) for k, v in pt.items()}}
        fixed = {k: v for k, v in values.items() if k not in ctx.space.names}
        x = np.array([[values[n] for n in ctx.space.names]])
        field = o.get("field")
        if field:
            if o.get("field_value") is None and field not in ctx.fixed:
                raise ParameterError(
                    f"step {ctx.name!r}: give field_value = <the value of {field} on the grid "
                    f"the study runs>, or {field} = ... in [model] fixed")
            fine = float(o["field_value"] if o.get("field_value") is not None
                         else ctx.fixed[field])

            def factory(level: int, fixed=fixed, field=field, fine=fine):
                v = fine / ratio**level
                return ctx.model({**fixed, field: float(round(v)) if abs(v - round(v)) < 1e-9
                                  else v})

            def text(level: int, field=field, fine=fine) -> str:
                return f"{field} = {fine / ratio**level:g}"
        else:
            rotor = _rotor_of(ctx.model(fixed))
            if rotor is None:
                raise ParameterError(
                    f"step {ctx.name!r}: the model exposes no discretization; give field = "
                    "\"<its template field, e.g. n_intervals>\" and field_value = <its value>")
            factory, text = _rotor_factory(rotor, ratio, o.get("refine", "both"), ctx.name)
        res = verify_discretization(factory, levels, x, ratio=ratio,
                                    formal_order=o.get("formal_order"))
        results.append(production_u_num(res) if finer else res)
        xs.append(x[0])
        labels.append(", ".join(f"{k} = {float(v):.10g}" for k, v in pt.items()) or "nominal")
        if not level_text:
            level_text = [text(k) for k in levels]
    return results, labels, level_text, np.array(xs)


def production_u_num(res: Any) -> Any:
    """``res`` (a :class:`~rotoruq.methods.verification.VerificationResult` of three grids,
    finest first, the coarsest the grid the study runs) with ``u_num`` the numerical
    uncertainty of that coarsest grid: its Richardson error |f3 - f_ext| where the three
    grids converge monotonically in the asymptotic range, else (oscillatory or outside it,
    where the observed order is not to be trusted) the largest difference between the three
    grids, the data-range estimate of Eca and Hoekstra (2014, J. Comput. Phys. 262, 104),
    their U = 3 max|f_i - f_j| read with Fs = 3 as a standard uncertainty."""
    import dataclasses

    v = np.asarray(res.values, dtype=float)
    if v.shape[0] != 3:
        raise ParameterError("direction = \"finer\" needs levels = 3")
    spread = v.max(axis=0) - v.min(axis=0)
    richardson = np.abs(v[2] - np.asarray(res.extrapolated, dtype=float))
    ok = np.asarray(res.in_asymptotic_range, dtype=bool) & np.isfinite(richardson)
    return dataclasses.replace(res, u_num=np.where(ok, richardson, spread))


def run_verification(ctx: StepContext) -> StepResult:
    """Grid convergence (observed order, GCI, u_num) per point and response."""
    o = ctx.options
    ratio = float(o["ratio"])
    results, labels, level_text, xs = verify_points(ctx, o, o.get("points") or [{}])
    cat = {f: np.concatenate([np.atleast_2d(getattr(r, f)) for r in results]).astype(float)
           for f in GRID_FIELDS}
    rec = VerificationRecord(
        names_in=tuple(ctx.space.names), names_out=tuple(ctx.responses), points=tuple(labels),
        levels=tuple(level_text), x=xs,
        values=np.concatenate([r.values for r in results], axis=1), ratio=ratio,
        safety_factor=float(results[0].safety_factor),
        formal_order=float("nan") if o.get("formal_order") is None else float(o["formal_order"]),
        refined=f"template field {o['field']}" if o.get("field") else
        {"both": "stations and azimuth steps", "azimuth": "azimuth steps",
         "stations": "stations"}[o["refine"]], u_num_max=np.max(cat["u_num"], axis=0),
        point_labels=tuple(f"#{j}" for j in range(len(labels))), **cat)
    arrays, meta = rec.parts()
    return StepResult(ctx.name, ctx.type, {}, arrays, meta={
        "n_evaluations": int(sum(r.n_evaluations for r in results)),
        "responses": list(ctx.responses), **meta})


def verification_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    rec = VerificationRecord.read(res)
    rows = []
    for j, pt in enumerate(rec.points):
        for k, r in enumerate(rec.names_out):
            rows.append([pt, with_unit(r, labels), *[float(v) for v in rec.values[:, j, k]],
                         float(rec.observed_order[j, k]), float(rec.extrapolated[j, k]),
                         float(rec.gci_fine[j, k]), float(rec.u_num[j, k]),
                         float(rec.u_num[j, k]) / abs(float(rec.values[0, j, k]))
                         if rec.values[0, j, k] != 0 else np.inf,
                         "yes" if rec.in_asymptotic_range[j, k] else
                         "oscillatory" if rec.oscillatory[j, k] else "no"])
    order = ("observed" if np.isnan(rec.formal_order)
             else f"assumed {rec.formal_order:g} (two grids)")
    return [make_table(
        f"Solution verification: grid convergence index ({rec.refined}, ratio {rec.ratio:g})",
        ("point", "response [unit]", *[f"level {t} [unit]" for t in rec.levels], "order [-]",
         "Richardson extrapolation [unit]", "GCI fine (relative) [-]", "u_num [unit]",
         "u_num / |S| [-]", "asymptotic range"), rows,
        f"[unit]: the response's unit, beside its name. "
        f"Finest level first (the grid the study runs); order {order}; Fs = "
        f"{rec.safety_factor:g}; u_num = GCI / Fs in response units (ASME V&V 20), the "
        "largest over the points is what a validation step takes.")]


def verification_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    """Grids outside the asymptotic range (the GCI is then not a reliable bound)."""
    rec = saved_record(VerificationRecord, res)
    if rec is None:
        return []
    w = []
    for j, pt in enumerate(rec.points):
        for k, r in enumerate(rec.names_out):
            if not rec.in_asymptotic_range[j, k] and np.isnan(rec.formal_order):
                why = ("oscillatory convergence" if rec.oscillatory[j, k] else
                       "not converging monotonically" if not rec.converging[j, k] else
                       f"observed order {rec.observed_order[j, k]:.2f}")
                w.append(f"{res.name}: {r} at {pt}: grids outside the asymptotic range "
                         f"({why}); its GCI is not a reliable bound")
    return w


def _ratio(v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not v > 1 or v != v:
        raise TypeError("a refinement ratio > 1 (grid spacing coarse / fine)")
    return float(v)


#: Keys of a ``verification = {...}`` table of a validation step (the step type's options).
VERIFY_KEYS = ("ratio", "levels", "formal_order", "refine", "field", "field_value",
               "direction")


def verification_option(v: Any) -> dict:
    """Checker of ``verification = { ratio, levels, formal_order, refine, field, field_value }``
    (defaults as the ``verification`` step type's)."""
    if not isinstance(v, dict):
        raise TypeError("a table { ratio = 2, levels = 2, formal_order = 2.0, ... }")
    bad = [k for k in v if k not in VERIFY_KEYS]
    if bad:
        raise TypeError(f"a table with keys among {', '.join(VERIFY_KEYS)} "
                        f"(found {', '.join(bad)})")
    out = {k: STEP.options[k].default for k in VERIFY_KEYS}
    for k, x in v.items():
        out[k] = STEP.options[k].check(x)
    if out["levels"] == 2 and out["formal_order"] is None:
        raise TypeError("levels = 3 for an observed order, or levels = 2 with formal_order")
    if out["direction"] == "finer" and out["levels"] != 3:
        raise TypeError("direction = \"finer\" with levels = 3 (the study's grid and two "
                        "finer ones)")
    return out


def _points(v: Any) -> list[dict]:
    if not isinstance(v, list) or not all(isinstance(p, dict) for p in v) or not v:
        raise TypeError("a list of tables of input values, e.g. [{ height_over_radius = 4.0 }]")
    return [dict(p) for p in v]


def _check(c: StepCheck) -> None:
    if c.options["levels"] == 2 and c.options["formal_order"] is None:
        c.fail(("levels",), "levels = 3 for an observed order, or levels = 2 with "
               "formal_order = <the scheme's order>", "2")
    for i, pt in enumerate(c.options["points"] or []):
        vals = c.numbers(pt, ("points",), f"points[{i}]")
        for k in vals:
            c.check_input(("points",), k)


STEP = StepType(
    "verification", run_verification, method="rotoruq.methods.verification:verify_discretization",
    provides=("u_num",),
    options={"ratio": Option(_ratio, 2.0),
             "levels": Option(integer(2, 3), 3),
             "formal_order": Option(number(positive=True, allow_zero=False), None),
             "points": Option(_points, None),
             "refine": Option(choice("both", "azimuth", "stations"), "both"),
             "field": Option(string(), None),
             "field_value": Option(number(positive=True, allow_zero=False), None),
             "direction": Option(choice("coarser", "finer"), "coarser")},
    check=_check, tables=verification_tables, warnings=verification_warnings)
