"""Step type ``forward_check``: propagation at one or several operating points (``sweep``)
compared with measured data, optionally normalised by one data row, and the joint posterior
predictive when the inputs come from a Bayes step with a chain.

:func:`forward_check` does the study logic (sweeping, matching data rows, normalising, the
two propagations); :func:`run_forward_check` only adapts it to a step result.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..params import ParameterSpace
from ..render.figures import (
    Figure,
    FigureContext,
    beside_label,
    beside_predictions,
    ground_effect_curves,
    load_distributions,
)
from ..render.tables import StepTable, cell, inputs_table, make_table
from ..results import StepRecord, StepResult
from ._common import MOMENT_KEYS, column_moments, input_arrays, saved_record
from ._discrepancy import DiscrepancyRecord
from .base import DESIGNS, StepCheck, StepContext, StepType
from .bayes_calibration import BayesRecord
from .options import SIGNATURE, Option, choice, integer, number_list, string, table

__all__ = ["STEP", "SweepPoint", "ForwardCheck", "ForwardCheckRecord", "forward_check",
           "posterior_draws", "dropped_correlation", "measurement_std", "propagation_warnings",
           "run_forward_check", "forward_check_tables", "forward_check_figures"]


@dataclass(frozen=True, eq=False)
class SweepPoint:
    """One operating point of a forward check.

    label : ``"@<value of the matched input>"`` ("" without a sweep). point : the fixed inputs
    set at this point. outputs : (n, m) sampled responses, divided by ``scale``.
    pp_outputs : (N, m) responses at the posterior draws, divided by ``scale`` (None without a
    chain). scale : (m,) the normalising data rows' mean (ones without ``normalize_by``).
    measured : (m,) the mean of every data row (repeat) matching the point, divided by
    ``scale`` (NaN where the data set has no such response or no row matches). row : index of
    the first matched row (None: none). n_repeats : (m,) matched rows with a finite value.
    sem : (m,) standard error of that mean, std (ddof 1) / sqrt(n_repeats), divided by
    ``scale`` (NaN with fewer than 2 repeats).
    """

    label: str
    point: Mapping[str, float]
    outputs: np.ndarray
    pp_outputs: np.ndarray | None
    scale: np.ndarray
    measured: np.ndarray
    row: int | None = None
    n_repeats: np.ndarray | None = None
    sem: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class ForwardCheck:
    """Result of :func:`forward_check`: one :class:`SweepPoint` per operating point, the
    number of model evaluations, whether the responses are normalised, the sweep."""

    points: tuple[SweepPoint, ...]
    n_evaluations: int
    normalized: bool
    sweep: Mapping[str, list[float]] = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class ForwardCheckRecord(StepRecord):
    """What a forward check saves: P operating points, m responses, d inputs.

    names_in (d), names_out (m); labels (P) : each point's label (``"@<value>"``, ``""``
    without a sweep); sweep : input -> its P values ({} without one); match : the sweep input
    that picks the data rows (None without a sweep); normalized : responses divided by the
    ``normalize_by`` rows' mean. propagation : "sampling", "joint" or "independent_normals";
    dropped_correlation : (p, q, rho) what independent normals drop (None: nothing).
    moments (P, 4, m) : mean, std, skewness, excess kurtosis of the propagated responses
    (``outputs@<label>``). measured, n_repeats, sem (P, m) : the matched data rows' mean,
    their number and its standard error; nstd (P, m) : |measured - mean| / std. pp_mean,
    pp_std (P, m) : the joint posterior predictive; pp_noise (P, m) : the calibration's noise
    std of one measurement; pp_nstd (P, m) : |measured - pp_mean| / predictive std (see
    :func:`run_forward_check`). NaN: not computed (no matched row, no chain, too few values).
    input_mean, input_std, input_lower, input_upper (d,) : the input distributions.

    Its flat view: ``mean/thrust@4`` (and ``std/``, ``skewness/``, ``kurtosis/``), ``data/``
    (measured), ``data_n/`` (n_repeats), ``data_sem/`` (sem), ``nstd/``, ``pp_mean/``,
    ``pp_std/``, ``pp_noise/``, ``pp_nstd/`` of each computed response and point (no
    ``@<value>`` without a sweep).
    """

    AXES = {"moments": ("point", "statistic", "response"),
            **{k: ("point", "response") for k in (
                "measured", "n_repeats", "sem", "nstd", "pp_mean", "pp_std", "pp_noise",
                "pp_nstd")},
            "input_mean": ("input",), "input_std": ("input",), "input_lower": ("input",),
            "input_upper": ("input",)}
    FLAT = {"moments": "", "measured": "data", "n_repeats": "data_n", "sem": "data_sem"}
    LABELS = {"point": "labels", "statistic": MOMENT_KEYS}

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    labels: tuple[str, ...]
    sweep: dict[str, list[float]]
    match: str | None
    normalized: bool
    propagation: str
    dropped_correlation: tuple[str, str, float] | None
    moments: np.ndarray
    measured: np.ndarray
    n_repeats: np.ndarray
    sem: np.ndarray
    nstd: np.ndarray
    pp_mean: np.ndarray
    pp_std: np.ndarray
    pp_noise: np.ndarray
    pp_nstd: np.ndarray
    input_mean: np.ndarray
    input_std: np.ndarray
    input_lower: np.ndarray
    input_upper: np.ndarray

    def prediction(self, joint: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(mean, std, nstd)`` (P, m) of one propagation: the sampled one (the moments of
        ``outputs<label>`` and ``nstd``) or, ``joint``, the joint posterior predictive
        (``pp_mean``, ``pp_std``, ``pp_nstd``)."""
        if joint:
            return self.pp_mean, self.pp_std, self.pp_nstd
        return self.moments[:, 0], self.moments[:, 1], self.nstd

    def at(self, values: np.ndarray, label: str, response: str) -> float:
        """The element of ``values`` (P, m), one of the record's arrays over points and
        responses, at point ``label`` (``"@4"``) and ``response``; NaN where the record has
        no such point or response (as where it computed none).

        Examples
        --------
        >>> nan = np.full((2, 1), np.nan)
        >>> rec = ForwardCheckRecord(
        ...     ("a",), ("y",), ("@4", "@2"), {"h": [4.0, 2.0]}, "h", False, "sampling", None,
        ...     np.full((2, 4, 1), np.nan), np.array([[1.0], [2.0]]), nan, nan, nan, nan,
        ...     nan, nan, nan, *[np.zeros(1)] * 4)
        >>> rec.at(rec.measured, "@2", "y"), rec.at(rec.measured, "@1", "y")
        (2.0, nan)
        """
        if label not in self.labels or response not in self.names_out:
            return float("nan")
        return float(values[self.labels.index(label), self.names_out.index(response)])


def calibration_noise(source: StepResult | None) -> dict[str, float]:
    """Response -> the noise std of one measurement that the calibration ``source`` (a Bayes
    step, with or without a discrepancy) stated or pooled; empty for another step or one
    saved without its record."""
    if source is None:
        return {}
    rec = saved_record(BayesRecord, source) or saved_record(DiscrepancyRecord, source)
    if rec is None:
        return {}
    return {r: float(v) for r, v in zip(rec.names_out, rec.noise_std, strict=True)}


def posterior_draws(source: StepResult | None, names: Sequence[str], n: int,
                    rng: np.random.Generator | None = None) -> np.ndarray | None:
    """``n`` joint draws (n, d) of the inputs ``names`` from ``source``'s saved chain, in
    ``names`` order: the chain thinned to ``n`` evenly spaced draws (their correlation kept,
    every draw inside the prior's support; no random choice). None when that step has no
    chain covering ``names``.

    Parameters
    ----------
    source : the saved Bayes step (its ``chain`` array, (N, d_chain), named columns).
    names : the inputs wanted (a subset of the chain's columns).
    n : number of draws (a draw repeats only when ``n`` exceeds the chain's length).
    rng : draw the ``n`` rows at random from it instead (with replacement when ``n`` exceeds
        the chain's length).

    Returns
    -------
    ndarray, shape (n, len(names)), or None

    Examples
    --------
    >>> import numpy as np
    >>> from rotoruq.results import StepResult
    >>> chain = np.column_stack([np.arange(10.0), -np.arange(10.0)])
    >>> src = StepResult("b", "bayes_calibration", arrays={"chain": chain},
    ...                  meta={"columns": {"chain": ["a", "b"]}})
    >>> posterior_draws(src, ["b"], 4).ravel().tolist()
    [-0.0, -3.0, -6.0, -9.0]
    """
    if source is None or "chain" not in source.arrays:
        return None
    cols = source.columns("chain")
    if not set(names) <= set(cols):
        return None
    chain = np.asarray(source.arrays["chain"], dtype=float)
    if rng is None:
        pick = np.linspace(0, chain.shape[0] - 1, int(n)).round().astype(int)
    else:
        pick = rng.choice(chain.shape[0], size=n, replace=n > chain.shape[0])
    idx = np.array([cols.index(p) for p in names], dtype=int)
    return chain[np.ix_(pick, idx)]


def dropped_correlation(source: StepResult | None, names: Sequence[str]
                        ) -> tuple[str, str, float] | None:
    """The largest |posterior correlation| among ``names`` in ``source``'s chain (p, q, rho):
    what propagating independent normals drops. None without a chain or with one name."""
    if source is None or "chain" not in source.arrays:
        return None
    cols = source.columns("chain")
    use = [p for p in names if p in cols]
    if len(use) < 2:
        return None
    chain = np.asarray(source.arrays["chain"], dtype=float)[:, [cols.index(p) for p in use]]
    c = np.corrcoef(chain, rowvar=False)
    np.fill_diagonal(c, 0.0)
    i, j = np.unravel_index(int(np.nanargmax(np.abs(c))), c.shape)
    i, j = min(i, j), max(i, j)
    return use[i], use[j], float(c[i, j])


def forward_check(model_at: Callable[[Mapping[str, float]], Any], space: ParameterSpace,
                  responses: Sequence[str], n_samples: int, *, design: str,
                  seed: np.random.Generator, sweep: Mapping[str, Sequence[float]] | None = None,
                  match: str | None = None,
                  data_columns: Mapping[str, np.ndarray] | None = None,
                  normalize_by: Mapping[str, float] | None = None,
                  draws: np.ndarray | None = None, draws_only: bool = False
                  ) -> ForwardCheck:
    """Sample ``space`` through the model at each operating point of ``sweep`` and match the
    data.

    Parameters
    ----------
    model_at : ``model_at(point) -> Model`` with the fixed inputs ``point`` set.
    space : the uncertain inputs (d).
    responses : the model's response names (m).
    n_samples : samples per point.
    design : sampling design (``"lhs"``, ...).
    seed : the generator every sample is drawn from (keyword-only).
    sweep : input -> values, equal lengths (one point without).
    match : the sweep input whose value picks the data row (default: the first).
    data_columns : the data set's columns (name -> (k,) values); every row matching a point
        (its repeats) enters that point's measured mean and standard error.
    normalize_by : ``{column: value}``: divide every response by the mean of the data rows
        where ``column == value``.
    draws : (N, d) posterior draws pushed through the model at each point (None: none).
    draws_only : with ``draws``, propagate them alone: ``outputs`` are the responses at the
        draws (the joint propagation) and ``space`` is not sampled.

    Returns
    -------
    ForwardCheck

    Examples
    --------
    >>> import numpy as np
    >>> from rotoruq.params import Normal, ParameterSpace
    >>> from rotoruq.steps.forward_check import forward_check
    >>> class Line:
    ...     names_in, names_out = ("a",), ("y",)
    ...     def __init__(self, k): self.k = k
    ...     def __call__(self, x): return self.k * x
    >>> fc = forward_check(lambda p: Line(p["k"]), ParameterSpace([("a", Normal(1, 0.1))]),
    ...                    ("y",), 50, design="lhs", seed=np.random.default_rng(0),
    ...                    sweep={"k": [1.0, 2.0]},
    ...                    data_columns={"k": np.array([1.0, 2.0]), "y": np.array([1.0, 2.1])})
    >>> [p.label for p in fc.points], float(fc.points[1].measured[0])
    (['@1', '@2'], 2.1)
    """
    from ..methods.sampling import sample
    from ..model import evaluate

    grid: dict[str, list[float]] = {k: list(v) for k, v in (sweep or {}).items()}
    n_points = len(next(iter(grid.values()))) if grid else 1
    match = match or (next(iter(grid)) if grid else None)
    cols = data_columns or {}
    norm_rows = None
    if normalize_by:
        (key, val), = normalize_by.items()
        norm_rows = np.flatnonzero(np.isclose(cols[key], val))
        if norm_rows.size == 0:
            raise ParameterError(f"no data row with {key} = {val} (normalize_by)")
    points, n_eval = [], 0
    for j in range(n_points):
        point = {k: float(v[j]) for k, v in grid.items()}
        label = f"@{point[match]:g}" if grid and match in point else ""
        model = model_at(point)
        pp = None
        if draws is not None:
            pp = np.array(evaluate(model, draws).values, dtype=float)
            n_eval += draws.shape[0]
        if draws_only and pp is not None:
            out, pp = pp, None
        else:
            res = sample(model, space, n_samples, design=design, seed=seed)
            out = np.asarray(res.outputs, dtype=float)
            n_eval += int(res.n_evaluations)
        rows = np.zeros(0, dtype=int)
        if cols and match is not None and match in cols and match in point:
            rows = np.flatnonzero(np.isclose(cols[match], point[match]))
        elif cols and not grid:
            rows = np.arange(len(next(iter(cols.values()))))
        row = int(rows[0]) if rows.size else None
        m = len(responses)
        scale, measured = np.ones(m), np.full(m, np.nan)
        n_rep, sem = np.zeros(m, dtype=int), np.full(m, np.nan)
        for k, r in enumerate(responses):
            if norm_rows is not None and r in cols:
                scale[k] = float(np.nanmean(np.asarray(cols[r], float)[norm_rows]))
            out[:, k] = out[:, k] / scale[k]
            if pp is not None:
                pp[:, k] = pp[:, k] / scale[k]
            if rows.size and r in cols:
                v = np.asarray(cols[r], float)[rows]
                v = v[np.isfinite(v)]
                n_rep[k] = v.size
                if v.size:
                    measured[k] = float(np.mean(v)) / scale[k]
                if v.size > 1:
                    sem[k] = float(np.std(v, ddof=1) / np.sqrt(v.size)) / abs(scale[k])
        points.append(SweepPoint(label, point, out, pp, scale, measured, row, n_rep, sem))
    return ForwardCheck(tuple(points), n_eval, norm_rows is not None, grid)


def _spread(out: np.ndarray) -> tuple[float, float]:
    v = out[np.isfinite(out)]
    return float(np.mean(v)), float(np.std(v, ddof=1)) if v.size > 1 else np.nan


def measurement_std(noise: float, n_repeats: int, sem: float) -> float:
    """Std of the measured mean of ``n_repeats`` repeats: the calibration's noise std
    ``noise`` over sqrt(n_repeats) when there is one, else the repeats' own standard error
    ``sem`` (0 when neither is known)."""
    if noise > 0 and n_repeats > 0:
        return noise / np.sqrt(n_repeats)
    return float(sem) if np.isfinite(sem) else 0.0


def run_forward_check(ctx: StepContext) -> StepResult:
    """Propagation at one or several operating points (``sweep``) compared with data (the
    mean of every repeat of a condition, with its standard error).

    When ``from`` is a Bayes step with a chain, ``propagation`` says how:

    * ``"joint"`` (default): ``n_samples`` draws of the chain itself, thinned evenly
      (correlations kept, every draw inside the prior's support), through the model: the
      joint posterior predictive (``mean/``, ``std/`` and the same as ``pp_mean/``,
      ``pp_std/``);
    * ``"independent_normals"`` (the reference study's method, its table 4.15): LHS of normal
      distributions with each parameter's posterior mean and std (``mean/``, ``std/``,
      ``nstd/``), the joint draws beside them (``pp_*``), and a warning naming the largest
      posterior correlation the normals drop.

    ``data/`` is the mean of the matching rows, ``data_sem/`` its standard error (with two
    repeats or more), ``data_n/`` the number of repeats. ``pp_noise/`` is the calibration's
    noise std of one measurement (0 where the calibration did not observe it) and
    ``pp_nstd/`` = |data - pp_mean| / sqrt(pp_std^2 + s_meas^2), with s_meas the std of the
    measured mean
    (:func:`measurement_std`): the distance of the measurement from its predictive
    distribution.
    """
    o = ctx.options
    propagation = o.get("propagation", "joint")
    draws = posterior_draws(ctx.source, ctx.space.names, o["n_samples"])
    joint = draws is not None and propagation == "joint"
    try:
        fc = forward_check(ctx.model, ctx.space, ctx.responses, o["n_samples"],
                           design=o["design"], seed=ctx.rng, sweep=o.get("sweep"),
                           match=o.get("match"), data_columns=ctx.data_columns,
                           normalize_by=o.get("normalize_by"), draws=draws, draws_only=joint)
    except ParameterError as exc:
        raise ParameterError(f"step {ctx.name!r}: {exc}") from None
    src_noise = calibration_noise(ctx.source)
    arrays, columns = {}, {}
    n_pts, m = len(fc.points), len(ctx.responses)
    moments = np.full((n_pts, 4, m), np.nan)
    per = {k: np.full((n_pts, m), np.nan) for k in (
        "measured", "n_repeats", "sem", "nstd", "pp_mean", "pp_std", "pp_noise", "pp_nstd")}
    for i, pt in enumerate(fc.points):
        label = pt.label
        joint_out = pt.outputs if joint else pt.pp_outputs
        for k, r in enumerate(ctx.responses):
            noise = src_noise.get(r, 0.0) / abs(pt.scale[k])
            if joint_out is not None:
                pm, ps = _spread(joint_out[:, k])
                per["pp_mean"][i, k], per["pp_std"][i, k], per["pp_noise"][i, k] = pm, ps, noise
            if pt.row is not None and r in ctx.data_columns:
                measured = float(pt.measured[k])
                n_rep = int(pt.n_repeats[k]) if pt.n_repeats is not None else 1
                sem = float(pt.sem[k]) if pt.sem is not None else np.nan
                mean, std = _spread(pt.outputs[:, k])
                per["measured"][i, k], per["n_repeats"][i, k] = measured, n_rep
                per["sem"][i, k] = sem
                per["nstd"][i, k] = abs(measured - mean) / std if std > 0 else np.inf
                if joint_out is not None:
                    tot = float(np.hypot(per["pp_std"][i, k],
                                         measurement_std(noise, n_rep, sem)))
                    per["pp_nstd"][i, k] = (abs(measured - per["pp_mean"][i, k]) / tot
                                            if tot > 0 else np.inf)
        moments[i] = column_moments(pt.outputs)
        arrays[f"outputs{label}"] = pt.outputs
        columns[f"outputs{label}"] = list(ctx.responses)
        if pt.pp_outputs is not None:
            arrays[f"pp_outputs{label}"] = pt.pp_outputs
            columns[f"pp_outputs{label}"] = list(ctx.responses)
    propagation = ("joint" if joint else "independent_normals" if draws is not None
                   else "sampling")
    meta: dict[str, Any] = {
        "columns": columns, "n_evaluations": fc.n_evaluations,
        "labels": [p.label for p in fc.points], "sweep": dict(fc.sweep),
        "normalized": fc.normalized, "joint_predictive": draws is not None,
        "propagation": propagation}
    dropped = None
    if draws is not None and not joint:
        dropped = dropped_correlation(ctx.source, ctx.space.names)
        if dropped is not None:
            meta["dropped_correlation"] = list(dropped)
    sweep = {k: [float(x) for x in v] for k, v in fc.sweep.items()}
    in_mean, in_std, in_lower, in_upper = input_arrays(ctx.space)
    record = ForwardCheckRecord(
        tuple(ctx.space.names), tuple(ctx.responses), tuple(p.label for p in fc.points),
        sweep, (o.get("match") or next(iter(sweep))) if sweep else None, fc.normalized,
        propagation, dropped, moments, measured=per["measured"], n_repeats=per["n_repeats"],
        sem=per["sem"], nstd=per["nstd"], pp_mean=per["pp_mean"], pp_std=per["pp_std"],
        pp_noise=per["pp_noise"], pp_nstd=per["pp_nstd"], input_mean=in_mean,
        input_std=in_std, input_lower=in_lower, input_upper=in_upper)
    rec_arrays, rec_meta = record.parts()
    return StepResult(ctx.name, ctx.type, {}, {**arrays, **rec_arrays},
                      meta={**meta, **rec_meta})


def propagation_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    """Independent normals of a correlated posterior: a forward check's or a sampling step's
    record names the largest correlation they drop."""
    from .sampling import SamplingRecord  # sampling imports this module

    rec = saved_record(ForwardCheckRecord, res) or saved_record(SamplingRecord, res)
    if rec is None or not rec.dropped_correlation:
        return []
    p, q, rho = rec.dropped_correlation
    return [f"{res.name}: propagates independent normals of the posterior "
            f"(propagation = \"independent_normals\"), dropping its correlations; the "
            f"largest: {labels.get(p, p)} / {labels.get(q, q)} rho = {rho:+.2f}"]


def forward_check_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    rec = ForwardCheckRecord.read(res)
    out = []
    prop = rec.propagation
    both = prop == "independent_normals"
    for i, lab in enumerate(rec.labels):
        where = f" at {rec.match} = {lab[1:]}" if rec.sweep and lab else ""
        if prop == "joint":
            cols = ["response", "joint mean", "joint std", "measured mean", "repeats",
                    "std error of the mean", "noise std", "|measured - mean| / predictive std"]
        else:
            cols = ["response", "mean", "std", "measured mean", "repeats",
                    "std error of the mean", "|measured - mean| / std"]
            if both:
                cols += ["joint mean", "joint std", "noise std",
                         "|measured - mean| / predictive std"]
        rows = []
        for k, r in enumerate(rec.names_out):
            row = [r, cell(rec.moments[i, 0, k]), cell(rec.moments[i, 1, k]),
                   cell(rec.measured[i, k]), cell(rec.n_repeats[i, k]), cell(rec.sem[i, k])]
            if prop == "joint":
                row += [cell(rec.pp_noise[i, k]), cell(rec.pp_nstd[i, k])]
            else:
                row.append(cell(rec.nstd[i, k]))
            if both:
                row += [cell(rec.pp_mean[i, k]), cell(rec.pp_std[i, k]),
                        cell(rec.pp_noise[i, k]), cell(rec.pp_nstd[i, k])]
            rows.append(row)
        pred = ("predictive std = sqrt(joint std^2 + s^2), s the std of the measured mean: "
                "the calibration's noise std / sqrt(repeats), else the repeats' standard "
                "error")
        note = {"joint": "Propagation: the calibration's chain, thinned (its correlations "
                         "kept), through the model; " + pred + ".",
                "independent_normals": "Propagation: mean/std from LHS of independent "
                "normals with the posterior's means and stds (their "
                "correlations dropped); joint: the chain's draws through the model; "
                + pred + ".",
                }.get(prop, "Propagation: LHS of the step's input distributions.")
        out.append(make_table(f"Propagated responses{where}", cols, rows, note))
    out.append(inputs_table(rec.names_in, rec.input_mean, rec.input_std, rec.input_lower,
                            rec.input_upper, labels))
    return out


def forward_check_figures(res: StepResult, ctx: FigureContext) -> list[Figure]:
    """Ground-effect curves of a normalized sweep, else the propagated load distributions
    (the samples: the arrays ``outputs<label>``, ``pp_outputs<label>`` beside the record)."""
    rec = saved_record(ForwardCheckRecord, res)
    if rec is None:
        return []
    if rec.normalized:
        heights = np.asarray(rec.sweep.get("height_over_radius", []), dtype=float)
        return ground_effect_curves(res.name, rec.names_out, rec.labels, heights,
                                    rec.moments[:, 0], rec.moments[:, 1], rec.pp_mean,
                                    rec.pp_std, rec.measured,
                                    beside=beside_predictions(ctx, res.name),
                                    beside_name=beside_label(ctx),
                                    curves=ctx.curves)
    outputs = [np.asarray(res.arrays[f"outputs{lab}"]) for lab in rec.labels]
    pp = [None if f"pp_outputs{lab}" not in res.arrays
          else np.asarray(res.arrays[f"pp_outputs{lab}"]) for lab in rec.labels]
    return load_distributions(res.name, rec.names_out, rec.labels, outputs, pp,
                              rec.measured, ctx.units,
                              beside=beside_predictions(ctx, res.name),
                              beside_name=beside_label(ctx))


def _check_sweep(c: StepCheck) -> None:
    sweep = c.options["sweep"]
    if sweep is None:
        return
    lengths = set()
    for k, v in sweep.items():
        c.check_input(("sweep", k), k)
        try:
            lengths.add(len(number_list(v)))
        except TypeError:
            c.fail(("sweep", k), f"{k} = [numbers] in sweep", repr(v))
    if len(lengths) != 1:
        c.fail(("sweep",), "sweep lists of equal length")
    if c.options["normalize_by"] is not None:
        c.numbers(c.options["normalize_by"], ("normalize_by",), "normalize_by")


STEP = StepType(
    "forward_check", run_forward_check, method="rotoruq.methods.sampling:sample",
    options={"n_samples": Option(integer(1), SIGNATURE),
             "design": Option(choice(*DESIGNS), SIGNATURE),
             "sweep": Option(table, None),
             "match": Option(string(), None),
             "normalize_by": Option(table, None),
             "propagation": Option(choice("joint", "independent_normals"), "joint")},
    quick={"n_samples": 40}, check=_check_sweep,
    tables=forward_check_tables, figures=forward_check_figures, warnings=propagation_warnings)
