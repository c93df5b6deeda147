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
from ..render.figures import Figure, FigureContext, ground_effect_curves, load_distributions
from ..render.tables import StepTable, inputs_table, make_table, responses, value
from ..results import StepResult
from ._common import input_scalars, stats_scalars
from .base import DESIGNS, StepCheck, StepContext, StepType
from .options import SIGNATURE, Option, choice, integer, number_list, string, table

__all__ = ["STEP", "SweepPoint", "ForwardCheck", "forward_check", "posterior_draws",
           "run_forward_check", "forward_check_tables", "forward_check_figures"]


@dataclass(frozen=True, eq=False)
class SweepPoint:
    """One operating point of a forward check.

    label : ``"@<value of the matched input>"`` ("" without a sweep). point : the fixed inputs
    set at this point. outputs : (n, m) sampled responses, divided by ``scale``.
    pp_outputs : (N, m) responses at the posterior draws, divided by ``scale`` (None without a
    chain). scale : (m,) the normalising data row's values (ones without ``normalize_by``).
    measured : (m,) the matched data row divided by ``scale`` (NaN where the data set has no
    such response or no row matches). row : index of the matched data row (None: none).
    """

    label: str
    point: Mapping[str, float]
    outputs: np.ndarray
    pp_outputs: np.ndarray | None
    scale: np.ndarray
    measured: np.ndarray
    row: int | None = None


@dataclass(frozen=True, eq=False)
class ForwardCheck:
    """Result of :func:`forward_check`: one :class:`SweepPoint` per operating point, the
    number of model evaluations, whether the responses are normalised, the sweep."""

    points: tuple[SweepPoint, ...]
    n_evaluations: int
    normalized: bool
    sweep: Mapping[str, list[float]] = field(default_factory=dict)


def posterior_draws(source: StepResult | None, names: Sequence[str], n: int,
                    rng: np.random.Generator) -> np.ndarray | None:
    """``n`` joint draws (n, d) of the inputs ``names`` from ``source``'s saved chain, in
    ``names`` order (None when that step has no chain covering them)."""
    if source is None or "chain" not in source.arrays:
        return None
    cols = source.columns("chain")
    if not set(names) <= set(cols):
        return None
    chain = np.asarray(source.arrays["chain"], dtype=float)
    pick = rng.choice(chain.shape[0], size=n, replace=n > chain.shape[0])
    idx = np.array([cols.index(p) for p in names], dtype=int)
    return chain[np.ix_(pick, idx)]


def forward_check(model_at: Callable[[Mapping[str, float]], Any], space: ParameterSpace,
                  responses: Sequence[str], n_samples: int, *, design: str,
                  seed: np.random.Generator, sweep: Mapping[str, Sequence[float]] | None = None,
                  match: str | None = None,
                  data_columns: Mapping[str, np.ndarray] | None = None,
                  normalize_by: Mapping[str, float] | None = None,
                  draws: np.ndarray | None = None) -> ForwardCheck:
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
    data_columns : the data set's columns (name -> (k,) values).
    normalize_by : ``{column: value}``: divide every response by the data row where
        ``column == value``.
    draws : (N, d) posterior draws pushed through the model at each point (None: none).

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
    norm_row = None
    if normalize_by:
        (key, val), = normalize_by.items()
        rows = np.flatnonzero(np.isclose(cols[key], val))
        if rows.size == 0:
            raise ParameterError(f"no data row with {key} = {val} (normalize_by)")
        norm_row = int(rows[0])
    points, n_eval = [], 0
    for j in range(n_points):
        point = {k: float(v[j]) for k, v in grid.items()}
        label = f"@{point[match]:g}" if grid and match in point else ""
        model = model_at(point)
        res = sample(model, space, n_samples, design=design, seed=seed)
        out = np.asarray(res.outputs, dtype=float)
        n_eval += int(res.n_evaluations)
        pp = None
        if draws is not None:
            pp = np.array(evaluate(model, draws).values, dtype=float)
            n_eval += draws.shape[0]
        row = None
        if cols and match is not None and match in cols and match in point:
            rows = np.flatnonzero(np.isclose(cols[match], point[match]))
            row = int(rows[0]) if rows.size else None
        elif cols and not grid:
            row = 0
        scale = np.ones(len(responses))
        measured = np.full(len(responses), np.nan)
        for k, r in enumerate(responses):
            if norm_row is not None and r in cols:
                scale[k] = float(cols[r][norm_row])
            out[:, k] = out[:, k] / scale[k]
            if pp is not None:
                pp[:, k] = pp[:, k] / scale[k]
            if row is not None and r in cols:
                measured[k] = float(cols[r][row]) / scale[k]
        points.append(SweepPoint(label, point, out, pp, scale, measured, row))
    return ForwardCheck(tuple(points), n_eval, norm_row is not None, grid)


def _spread(out: np.ndarray) -> tuple[float, float]:
    v = out[np.isfinite(out)]
    return float(np.mean(v)), float(np.std(v, ddof=1)) if v.size > 1 else np.nan


def run_forward_check(ctx: StepContext) -> StepResult:
    """Propagation at one or several operating points (``sweep``) compared with data.

    Two propagations when ``from`` is a Bayes step with a chain:

    * independent normals (the reference study's method, its table 4.15): LHS of the normal
      distributions built from each parameter's posterior mean and std (``mean/``, ``std/``,
      ``nstd/`` keys);
    * the joint posterior predictive: ``n`` draws of the chain itself (correlations kept)
      through the true model (``pp_mean/``, ``pp_std/``). ``pp_noise/`` is the calibration's
      noise std of that response (0 where the calibration did not observe it) and
      ``pp_nstd/`` = |data - pp_mean| / sqrt(pp_std^2 + pp_noise^2): the distance of the
      measurement from the predictive distribution of a measurement.
    """
    o = ctx.options
    draws = posterior_draws(ctx.source, ctx.space.names, o["n_samples"], ctx.rng)
    try:
        fc = forward_check(ctx.model, ctx.space, ctx.responses, o["n_samples"],
                           design=o["design"], seed=ctx.rng, sweep=o.get("sweep"),
                           match=o.get("match"), data_columns=ctx.data_columns,
                           normalize_by=o.get("normalize_by"), draws=draws)
    except ParameterError as exc:
        raise ParameterError(f"step {ctx.name!r}: {exc}") from None
    src_noise = ctx.source.scalars if ctx.source is not None else {}
    scalars: dict[str, float] = {}
    arrays, columns = {}, {}
    for pt in fc.points:
        label = pt.label
        for k, r in enumerate(ctx.responses):
            if pt.pp_outputs is not None:
                noise = float(src_noise.get(f"noise_std/{r}", 0.0)) / pt.scale[k]
                pm, ps = _spread(pt.pp_outputs[:, k])
                scalars.update({f"pp_mean/{r}{label}": pm, f"pp_std/{r}{label}": ps,
                                f"pp_noise/{r}{label}": noise})
            if pt.row is not None and r in ctx.data_columns:
                measured = float(pt.measured[k])
                mean, std = _spread(pt.outputs[:, k])
                scalars[f"data/{r}{label}"] = measured
                scalars[f"nstd/{r}{label}"] = abs(measured - mean) / std if std > 0 else np.inf
                if pt.pp_outputs is not None:
                    tot = float(np.hypot(scalars[f"pp_std/{r}{label}"], noise))
                    scalars[f"pp_nstd/{r}{label}"] = (
                        abs(measured - scalars[f"pp_mean/{r}{label}"]) / tot if tot > 0
                        else np.inf)
        scalars.update(stats_scalars(ctx.responses, pt.outputs, label))
        arrays[f"outputs{label}"] = pt.outputs
        columns[f"outputs{label}"] = list(ctx.responses)
        if pt.pp_outputs is not None:
            arrays[f"pp_outputs{label}"] = pt.pp_outputs
            columns[f"pp_outputs{label}"] = list(ctx.responses)
    scalars.update(input_scalars(ctx.space))
    return StepResult(ctx.name, ctx.type, scalars, arrays, meta={
        "columns": columns, "n_evaluations": fc.n_evaluations,
        "labels": [p.label for p in fc.points], "sweep": dict(fc.sweep),
        "normalized": fc.normalized, "joint_predictive": draws is not None})


def forward_check_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    resp = responses(res)
    out = []
    joint = bool(res.meta.get("joint_predictive"))
    for lab in res.meta.get("labels") or [""]:
        where = f" at {lab[1:]}" if lab else ""
        cols = ["response", "mean", "std", "measured", "|measured - mean| / std"]
        if joint:
            cols += ["joint mean", "joint std", "noise std", "|measured - mean| / predictive std"]
        rows = []
        for r in resp:
            row = [r, value(res, f"mean/{r}{lab}"), value(res, f"std/{r}{lab}"),
                   value(res, f"data/{r}{lab}"), value(res, f"nstd/{r}{lab}")]
            if joint:
                row += [value(res, f"pp_mean/{r}{lab}"), value(res, f"pp_std/{r}{lab}"),
                        value(res, f"pp_noise/{r}{lab}"), value(res, f"pp_nstd/{r}{lab}")]
            rows.append(row)
        note = ("mean/std: LHS of the step's input distributions"
                + (" (independent normals from the posterior moments, the thesis's method); "
                   "joint: chain samples through the model (correlations kept); predictive "
                   "std = sqrt(joint std^2 + noise std^2), the calibration's noise model"
                   if joint else "."))
        sweep = res.meta.get("sweep") or {}
        if sweep and lab:
            match = next(iter(sweep))
            where = f" at {match} = {lab[1:]}"
        out.append(make_table(f"Propagated responses{where}", cols, rows, note))
    out.append(inputs_table(res, labels))
    return out


def forward_check_figures(res: StepResult, ctx: FigureContext) -> list[Figure]:
    """Ground-effect curves of a normalized sweep, else the propagated load distributions."""
    if res.meta.get("normalized"):
        return ground_effect_curves(res, thesis=ctx.reference, curves=ctx.curves)
    return load_distributions(res, ctx.units, thesis=ctx.reference)


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
             "normalize_by": Option(table, None)},
    quick={"n_samples": 40}, check=_check_sweep,
    tables=forward_check_tables, figures=forward_check_figures)
