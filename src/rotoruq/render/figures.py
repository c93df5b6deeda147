"""Figures of the report, drawn from saved step results with matplotlib's object API (no
pyplot, so a notebook's backend is left alone; files are written through Agg).

Every function returns a list of :class:`Figure` (name, caption, matplotlib figure); the
report renders each once, as PNG, writes it to ``figures/`` and embeds the same bytes. Every
axis is labelled with its unit and legends sit outside the data. Where an application hands
the report published numbers behind a figure (:attr:`FigureContext.beside`: Sobol indices,
predictive means and std devs, the data-generating distributions of a synthetic calibration),
they are drawn beside the run's.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .._lazy import lazy_module
from ..params import Distribution
from ..results import StepResult, dict_to_dist

if TYPE_CHECKING:
    from scipy import stats
else:
    stats = lazy_module("scipy.stats")

__all__ = ["Figure", "FigureContext", "tornado", "SobolIndices", "prior_posterior", "chain_traces",
           "trace_points", "TRACE_POINTS", "pair_plot", "PAIR_TICKS", "load_distributions",
           "cuu_comparison", "ground_effect_curves",
           "UNITS", "axis_label", "unit_of", "per_unit", "beside_label", "beside_sobol",
           "beside_predictions", "beside_truth"]

# Units of the rotoruq vocabulary (DESIGN.md section 3); a study file's ``unit`` overrides.
UNITS = {
    "thrust": "N", "torque": "N m", "roll": "N m", "pitch": "N m", "power": "W",
    "ct": "-", "cq": "-", "collective_deg": "deg", "lateral_deg": "deg",
    "longitudinal_deg": "deg", "omega": "rad/s", "rho": "kg/m^3", "height_over_radius": "-",
    "k_flap": "N m/rad", "c_flap": "N m s/rad", "k_lag": "N m/rad", "c_lag": "N m s/rad",
    # the link's law is per unit strain (README): K_p acts as EA [N], its damping as [N s]
    "k_pitch_link": "N", "c_pitch_link": "N s", "ei_flap": "N m^2",
}
_UNIT_PREFIX = {"cla_": "1/deg", "cl0_": "-", "cd0_": "-", "cda_": "1/deg", "cda2_": "1/deg^2"}
# A model's own response whose unit nobody stated is shown in the model's units.
UNKNOWN_UNIT = "model units"

_TICK = 8
#: Tick intervals per axis of a pair plot's panel (at most this many + 1 ticks).
PAIR_TICKS = 3
_LEGEND = {"fontsize": 8, "frameon": False}


@dataclass(frozen=True, eq=False)
class FigureContext:
    """What a step type's figure renderer may use besides its own step.

    study : the study's name. steps : every saved step of the study (name -> result).
    labels, units : display label and unit per input/response name.
    beside : numbers an application (:mod:`rotoruq.report.application`) has the figures draw
        beside the run's, as plain data (it crosses to the figure worker as JSON), or None:
        ``label`` (the legend's name of their source, e.g. ``"thesis"``); ``sobol``: step ->
        response -> input -> main index; ``predictions``: step -> sweep label (``"@4"``) ->
        response -> [mean, std]; ``truth``: calibration step -> the sampling step whose
        input distributions generated its (synthetic) data. Read them with
        :func:`beside_sobol`, :func:`beside_predictions`, :func:`beside_truth`.
    curves : reference curves the run recorded (``study.json`` ``model.curves``).
    """

    study: str
    steps: Mapping[str, StepResult]
    labels: Mapping[str, str] = field(default_factory=dict)
    units: Mapping[str, str] = field(default_factory=dict)
    beside: Mapping[str, Any] | None = None
    curves: Mapping[str, Any] = field(default_factory=dict)


def beside_sobol(ctx: FigureContext, step: str) -> dict[tuple[str, str], float] | None:
    """(response, input) -> the main index ``ctx.beside`` gives for ``step``, or None."""
    table = ((ctx.beside or {}).get("sobol") or {}).get(step)
    if not table:
        return None
    return {(r, p): v for r, row in table.items() for p, v in row.items()}


def beside_predictions(ctx: FigureContext, step: str
                       ) -> dict[str, dict[str, tuple[float, float]]] | None:
    """Sweep label -> response -> (mean, std) ``ctx.beside`` gives for ``step``, or None."""
    table = ((ctx.beside or {}).get("predictions") or {}).get(step)
    if not table:
        return None
    return {lab: {r: (float(v[0]), float(v[1])) for r, v in row.items()}
            for lab, row in table.items()}


def beside_truth(ctx: FigureContext, step: str) -> str | None:
    """The sampling step whose input distributions generated the data ``step`` calibrates on,
    as ``ctx.beside`` gives it, or None."""
    return ((ctx.beside or {}).get("truth") or {}).get(step)


def beside_label(ctx: FigureContext) -> str:
    """The legend's name of the numbers drawn beside the run's (``""``: none)."""
    return str((ctx.beside or {}).get("label") or "")


@dataclass
class Figure:
    name: str
    caption: str
    figure: object  # matplotlib.figure.Figure


def unit_of(name: str, units: Mapping[str, str] | None = None) -> str:
    units = units or {}
    if units.get(name):
        return units[name]
    if name in UNITS:
        return UNITS[name]
    for prefix, u in _UNIT_PREFIX.items():
        if name.startswith(prefix):
            return u
    return UNKNOWN_UNIT


def per_unit(unit: str) -> str:
    """The unit of a density over a quantity in ``unit``: ``"N"`` -> ``"1/N"``,
    ``"1/deg"`` -> ``"deg"``, ``"N m"`` -> ``"1/(N m)"``, ``"-"`` -> ``"-"``.

    Parameters
    ----------
    unit : str
        The quantity's unit as :func:`unit_of` gives it.

    Returns
    -------
    str
        The unit of its probability density.

    Examples
    --------
    >>> per_unit("1/deg"), per_unit("N m"), per_unit("kg/m^3")
    ('deg', '1/(N m)', '1/(kg/m^3)')
    """
    unit = unit.strip()
    if unit in ("-", ""):
        return "-"
    if unit.startswith("1/"):
        rest = unit[2:].strip()
        return rest[1:-1] if rest.startswith("(") and rest.endswith(")") else rest
    return f"1/{unit}" if " " not in unit and "/" not in unit else f"1/({unit})"


def axis_label(name: str, labels: Mapping[str, str] | None = None,
               units: Mapping[str, str] | None = None, what: str = "") -> str:
    """``"C_La(0.3) [1/deg]"``; ``what`` prefixes a statistic (``"PDF of thrust [1/N]"``)."""
    lab = (labels or {}).get(name) or name
    return f"{what}{lab} [{unit_of(name, units)}]"


def _subplots(*args, figsize=None, **kwargs):
    """Figure and axes without pyplot: no global backend switch, nothing to close."""
    from matplotlib.figure import Figure as _MplFigure  # matplotlib loads when drawing

    fig = _MplFigure(figsize=figsize, layout="constrained")
    return fig, fig.subplots(*args, **kwargs)


def _density_hist(ax, x: np.ndarray, bins: int, **kwargs: Any) -> None:
    """A density histogram of ``x`` drawn as one filled step outline (``ax.hist`` draws a
    rectangle per bin, each an artist to lay out and render): the same bins, heights and
    fill. ``kwargs`` go to :meth:`~matplotlib.axes.Axes.stairs` (``color``, ``alpha``,
    ``label``). The outline is a path of 2 (bins + 1) points, so the SVG keeps it as a
    vector: rasterizing it would cost an image of the whole figure per histogram."""
    density, edges = np.histogram(x, bins=bins, density=True)
    ax.stairs(density, edges, fill=True, **kwargs)


def _legend_below(fig, axes) -> None:
    """One legend for the figure, below the axes (never over the data)."""
    handles, names = [], []
    for ax in np.ravel(axes):
        for h, n in zip(*ax.get_legend_handles_labels(), strict=True):
            if n not in names:
                handles.append(h)
                names.append(n)
    if handles:
        fig.legend(handles, names, loc="outside lower center", ncols=min(4, len(names)),
                   **_LEGEND)


def tornado(res: StepResult, sobol: SobolIndices, labels, units=None,
            beside: dict | None = None, beside_name: str = "") -> list[Figure]:
    """Horizontal bars of the main and total Sobol indices per response of step ``res``,
    with their bootstrap intervals when ``sobol`` has them; ``beside``: (response, input) ->
    another source's main index (named ``beside_name`` in the legend), drawn beside the
    run's."""
    inputs, responses = list(sobol.names_in), list(sobol.names_out)
    k = len(responses)
    fig, axes = _subplots(1, k, figsize=(3.4 * k + 1.8, 0.5 * len(inputs) + 2.0),
                          sharey=True, squeeze=False)
    y = np.arange(len(inputs))
    h = 0.28 if beside else 0.4
    ours = " (ours)" if beside else ""
    for a, r in enumerate(responses):
        ax = axes[0, a]
        s = np.asarray(sobol.main[a], dtype=float)
        t = np.asarray(sobol.total[a], dtype=float)

        def err(ci, v, a=a):
            if ci is None:
                return None
            lo, hi = np.asarray(ci[a, :, 0]), np.asarray(ci[a, :, 1])
            if not np.all(np.isfinite(lo)):
                return None
            return np.vstack([np.maximum(v - lo, 0), np.maximum(hi - v, 0)])

        ax.barh(y + h, s, height=h, color="#1f77b4", label=f"main S_i{ours}",
                xerr=err(sobol.main_ci, s), error_kw={"lw": 0.8})
        ax.barh(y, t, height=h, color="#9ecae1", label=f"total T_i{ours}",
                xerr=err(sobol.total_ci, t), error_kw={"lw": 0.8})
        if beside:
            th = [beside.get((r, p), np.nan) for p in inputs]
            ax.barh(y - h, th, height=h, color="#d62728", alpha=0.7,
                    label=f"main S_i ({beside_name})")
        neg = sobol.negligible is not None and bool(sobol.negligible[a])
        ax.set_title(f"{r}" + (" (negligible variance)" if neg else ""), fontsize=9)
        # the axis holds the bars and their whiskers (an interval may pass 1 or go below 0)
        parts: list[np.ndarray] = [s, t, np.zeros(1)] + [
            np.ravel(np.asarray(ci[a], dtype=float)) for ci in (sobol.main_ci, sobol.total_ci)
            if ci is not None]
        ends = np.concatenate(parts)
        ends = ends[np.isfinite(ends)]
        lo = min(0.0, float(ends.min()) * 1.1)
        ax.set_xlim(lo, max(1.0, float(ends.max()) * 1.05))
        ax.axvline(0, color="k", lw=0.5)
        ax.set_xlabel("Sobol index [-]")
        ax.grid(axis="x", alpha=0.3)
        ax.tick_params(labelsize=_TICK)
    axes[0, 0].set_yticks(y, [axis_label(p, labels, units) for p in inputs])
    axes[0, 0].set_ylabel("input")
    _legend_below(fig, axes)
    fig.suptitle(f"Sensitivity indices: {res.meta.get('title') or res.name}", fontsize=10)
    return [Figure(f"{res.name}_tornado", f"Sobol indices with bootstrap intervals "
                   f"({res.name})", fig)]


@dataclass(frozen=True)
class SobolIndices:
    """What :func:`tornado` draws: d inputs, m responses.

    names_in (d), names_out (m); main, total (m, d) Sobol indices; main_ci, total_ci
    (m, d, 2) their intervals (None: none); negligible (m,) whether each response's variance
    is negligible (None: not known).
    """

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    main: np.ndarray
    total: np.ndarray
    main_ci: np.ndarray | None = None
    total_ci: np.ndarray | None = None
    negligible: np.ndarray | None = None


def prior_posterior(res: StepResult, labels, units=None,
                    truth: Mapping[str, Distribution] | None = None) -> list[Figure]:
    """Prior density, the chain's histogram and the normal fit handed on, per parameter."""
    names = res.columns("chain")
    chain = np.asarray(res.arrays["chain"])
    prior = {k: dict_to_dist(v) for k, v in res.meta.get("prior", {}).items()}
    cols = min(3, len(names))
    rows = int(np.ceil(len(names) / cols))
    fig, axes = _subplots(rows, cols, figsize=(3.7 * cols, 2.7 * rows + 0.5), squeeze=False)
    for j, p in enumerate(names):
        ax = axes.flat[j]
        x = chain[:, j]
        lo, hi = np.percentile(x, [0.1, 99.9])
        if p in prior:
            plo, phi = prior[p].bounds
            lo = min(lo, plo) if np.isfinite(plo) else lo
            hi = max(hi, phi) if np.isfinite(phi) else hi
        grid = np.linspace(lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo), 300)
        _density_hist(ax, x, 40, color="#c6dbef", label="posterior (chain)")
        if p in prior:
            ax.plot(grid, prior[p].pdf(grid), "k--", lw=1.2, label="prior")
        ax.plot(grid, stats.norm.pdf(grid, x.mean(), x.std(ddof=1)), "C0", lw=1.5,
                label="normal handed on (mean, std)")
        if truth and p in truth:
            ax.plot(grid, truth[p].pdf(grid), "C2", lw=1.2, label="true (data-generating)")
        ax.set_xlabel(axis_label(p, labels, units), fontsize=9)
        u = unit_of(p, units)
        ax.set_ylabel(f"density [{per_unit(u)}]", fontsize=8)
        ax.tick_params(labelsize=_TICK)
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    _legend_below(fig, axes)
    return [Figure(f"{res.name}_densities", f"Prior and posterior densities ({res.name})", fig)]


#: Points of a chain trace per parameter at most (the figure is 8 in wide: 1,200 pixels).
TRACE_POINTS = 4000


def trace_points(y: np.ndarray, max_points: int = TRACE_POINTS) -> np.ndarray:
    """Indices of the samples a trace of ``y`` draws: all of them up to ``max_points``,
    else the lowest and the highest sample of each of ``max_points // 2`` consecutive
    blocks, in chain order. The line then reaches every block's extremes: its min/max
    envelope is the full trace's (a spike of one sample is never thinned away, as a stride
    would), at a block of a few samples per pixel. A chain with a non-finite sample is
    drawn through ``max_points`` evenly spread samples.

    Parameters
    ----------
    y : ndarray of shape (n,)
        One parameter's samples in chain order.
    max_points : int, optional
        At most this many indices (>= 2).

    Returns
    -------
    ndarray of int, shape (k,), k <= max_points
        Increasing indices into ``y``.

    Examples
    --------
    >>> y = np.zeros(10_000); y[1234] = 5.0; y[8765] = -3.0
    >>> idx = trace_points(y, 100)
    >>> len(idx) <= 100, y[idx].max(), y[idx].min(), bool(np.all(np.diff(idx) > 0))
    (True, np.float64(5.0), np.float64(-3.0), True)
    """
    y = np.asarray(y)
    n = y.shape[0]
    if n <= max_points:
        return np.arange(n)
    if not np.all(np.isfinite(y)):  # no envelope to keep: evenly spread samples
        return np.unique(np.linspace(0, n - 1, max_points).astype(int))
    blocks = max(1, max_points // 2)
    edges = np.linspace(0, n, blocks + 1).astype(int)  # blocks of n / blocks samples +- 1
    lo = np.minimum.reduceat(y, edges[:-1])
    hi = np.maximum.reduceat(y, edges[:-1])
    keep = np.zeros(n, dtype=bool)
    starts = edges[:-1]
    owner = np.repeat(np.arange(blocks), np.diff(edges))
    # the first sample of its block equal to the block's min (max)
    is_lo, is_hi = y == lo[owner], y == hi[owner]
    first_lo = np.flatnonzero(is_lo)[np.searchsorted(np.flatnonzero(is_lo), starts)]
    first_hi = np.flatnonzero(is_hi)[np.searchsorted(np.flatnonzero(is_hi), starts)]
    keep[first_lo] = keep[first_hi] = True
    return np.flatnonzero(keep)


def chain_traces(res: StepResult, labels, units=None) -> list[Figure]:
    """A trace per parameter of the kept chain (its chains one after the other), each drawn
    through the min and max of consecutive blocks of samples (:func:`trace_points`,
    at most :data:`TRACE_POINTS` points), rasterized in the SVG."""
    names = res.columns("chain")
    chain = np.asarray(res.arrays["chain"])
    fig, axes = _subplots(len(names), 1, figsize=(8, 1.15 * len(names) + 0.9), sharex=True,
                          squeeze=False)
    for j, p in enumerate(names):
        ax = axes[j, 0]
        idx = trace_points(chain[:, j])
        ax.plot(idx, chain[idx, j], lw=0.4, color="C0", rasterized=True)
        ax.set_ylabel(axis_label(p, labels, units), fontsize=8, rotation=0, ha="right",
                      va="center")
        ax.tick_params(labelsize=_TICK)
    axes[-1, 0].set_xlabel("chain sample after burn-in [-]")
    return [Figure(f"{res.name}_traces", f"Chain traces ({res.name})", fig)]


def pair_plot(res: StepResult, labels, units=None) -> list[Figure]:
    """Lower triangle: joint samples (1,000 spread over the chain, rasterized); diagonal:
    marginal histograms; the posterior correlation in each panel's corner (red beyond
    |0.7|). Laid out by hand: constrained layout costs seconds on d^2 axes; only the
    d (d + 1) / 2 axes of the lower triangle and the diagonal are made, each with at most
    four ticks per axis (:data:`PAIR_TICKS` bins: every tick is a set of artists drawn twice,
    for the PNG and the SVG; the panels are 1.6 in wide)."""
    names = res.columns("chain")
    chain = np.asarray(res.arrays["chain"])
    d = len(names)
    idx = np.linspace(0, chain.shape[0] - 1, min(chain.shape[0], 1000)).astype(int)
    corr = np.corrcoef(chain, rowvar=False) if d > 1 else np.ones((1, 1))
    size = 1.6 * d + 1.4
    from matplotlib.figure import Figure as _MplFigure
    from matplotlib.ticker import MaxNLocator

    fig = _MplFigure(figsize=(size, size))
    margin = 1.3 / size
    grid = fig.add_gridspec(d, d, left=margin, bottom=margin, right=0.99, top=0.99,
                            wspace=0.08, hspace=0.08)
    for i in range(d):
        for j in range(i + 1):
            ax = fig.add_subplot(grid[i, j])
            ax.xaxis.set_major_locator(MaxNLocator(PAIR_TICKS))
            ax.yaxis.set_major_locator(MaxNLocator(PAIR_TICKS))
            ax.tick_params(labelsize=7, labelrotation=45, labelbottom=i == d - 1,
                           labelleft=j == 0 and i > 0)
            if i == j:
                counts, edges = np.histogram(chain[:, i], bins=30)
                ax.stairs(counts, edges, fill=True, color="#6baed6")
                ax.set_yticks([])
            else:
                ax.plot(chain[idx, j], chain[idx, i], ".", ms=1.2, alpha=0.4, color="C0",
                        rasterized=True)
                ax.text(0.03, 0.95, f"{corr[i, j]:+.2f}", transform=ax.transAxes, fontsize=7,
                        va="top", color="C3" if abs(corr[i, j]) > 0.7 else "k")
            if i == d - 1:
                ax.set_xlabel(axis_label(names[j], labels, units), fontsize=8)
            if j == 0 and i > 0:
                ax.set_ylabel(axis_label(names[i], labels, units), fontsize=8)
    fig.axes[0].set_ylabel("count [-]", fontsize=8)  # the top-left histogram
    return [Figure(f"{res.name}_pairs", f"Posterior pair plot, correlation in each panel "
                   f"({res.name})", fig)]


def load_distributions(name: str, resp: Sequence[str], labels: Sequence[str],
                       outputs: Sequence[np.ndarray], pp_outputs: Sequence[np.ndarray | None],
                       measured: np.ndarray | None = None, units=None,
                       beside: Mapping[str, Mapping[str, tuple[float, float]]] | None = None,
                       beside_name: str = "") -> list[Figure]:
    """PDF (histogram + KDE) and empirical CDF of every response at every sweep point, with
    the measured value; the joint posterior predictive beside the independent-normal
    propagation when the step has both, and another source's normal N(mean, std) where
    ``beside`` (sweep label -> response -> (mean, std), named ``beside_name``) gives one.

    name : the step's. resp (m) : response names. labels (P) : each point's label (``""``
    without a sweep). outputs : P arrays (n, m) of propagated responses; pp_outputs : P
    arrays (N, m) of the joint posterior predictive, or None. measured (P, m) : the data's
    mean at each point (NaN: none; None: no data).
    """
    out = []
    for i, label in enumerate(labels):
        pp = pp_outputs[i]
        th = (beside or {}).get(label, {}) if label else {}
        fig, axes = _subplots(2, len(resp), figsize=(3.3 * len(resp) + 0.4, 5.6),
                              squeeze=False)
        for k, r in enumerate(resp):
            series = [("independent normals" if pp is not None else "samples",
                       np.asarray(outputs[i])[:, k], "C0")]
            if pp is not None:
                series.append(("joint posterior predictive", np.asarray(pp)[:, k], "C1"))
            ax, ax2 = axes[0, k], axes[1, k]
            lo, hi = np.inf, -np.inf
            for what, v, color in series:
                v = v[np.isfinite(v)]
                if v.size < 2:
                    continue
                lo, hi = min(lo, float(v.min())), max(hi, float(v.max()))
                _density_hist(ax, v, 30, color=color, alpha=0.3)
                if np.std(v) > 0:
                    g = np.linspace(v.min(), v.max(), 200)
                    ax.plot(g, stats.gaussian_kde(v)(g), color=color, label=what)
                s = np.sort(v)
                ax2.step(s, np.arange(1, s.size + 1) / s.size, where="post", color=color,
                         label=what)
            if r in th and th[r][1]:
                th_mean, th_std = th[r]
                g = np.linspace(min(lo, th_mean - 3 * th_std), max(hi, th_mean + 3 * th_std), 200)
                for axis, law in ((ax, stats.norm.pdf), (ax2, stats.norm.cdf)):
                    axis.plot(g, law(g, th_mean, th_std), "k:", lw=1.2,
                              label=f"{beside_name} N(mean, std)")
            if measured is not None and not np.isnan(measured[i, k]):
                for a in (ax, ax2):
                    a.axvline(float(measured[i, k]), color="C3", ls="--", lw=1.2,
                              label="measured")
            u = unit_of(r, units)
            ax.set_ylabel(f"PDF [{per_unit(u)}]", fontsize=8)
            ax2.set_ylabel("CDF [-]", fontsize=8)
            for a in (ax, ax2):
                a.set_xlabel(axis_label(r, None, units), fontsize=8)
                a.tick_params(labelsize=_TICK)
        _legend_below(fig, axes)
        where = f" at H/R = {label[1:]}" if label else ""
        fig.suptitle(f"Response distributions{where} ({name})", fontsize=10)
        out.append(Figure(f"{name}_loads{label.replace('@', '_h')}",
                          f"Response PDFs and CDFs{where} ({name})", fig))
    return out


def cuu_comparison(name: str, params: Sequence[str], resp: Sequence[str],
                   initial_std: np.ndarray, mean: np.ndarray, std: np.ndarray,
                   target_mean: np.ndarray, target_std: np.ndarray,
                   samples: Mapping[str, np.ndarray], labels, units=None) -> list[Figure]:
    """Input std devs before/after CUU and output CDFs: initial, calibrated, target.

    params (d), resp (m) : names; initial_std, mean, std (d,) : each input's std before,
    mean and std after calibration; target_mean, target_std (m,) : the targets (NaN: none);
    samples : "initial"/"calibrated" -> (n, m) sampled responses (either may be missing).
    """
    n = 1 + len(resp)
    fig, axes = _subplots(1, n, figsize=(3.4 * n, 3.6), squeeze=False)
    ax = axes[0, 0]
    x = np.arange(len(params))
    scale = [abs(float(mean[j])) or 1.0 for j in range(len(params))]
    init = [float(initial_std[j]) / scale[j] for j in range(len(params))]
    cal = [float(std[j]) / scale[j] for j in range(len(params))]
    ax.bar(x - 0.2, init, 0.4, label="initial input std", color="#9ecae1")
    ax.bar(x + 0.2, cal, 0.4, label="calibrated input std", color="C0")
    ax.set_xticks(x, [(labels or {}).get(p) or p for p in params], rotation=30, fontsize=_TICK)
    ax.set_xlabel("input")
    ax.set_ylabel("input std / |mean| [-]", fontsize=8)
    for k, r in enumerate(resp):
        ax = axes[0, k + 1]
        for tag, style in (("initial", ":"), ("calibrated", "-")):
            arr = samples.get(tag)
            if arr is None:
                continue
            v = np.sort(np.asarray(arr)[:, k])
            v = v[np.isfinite(v)]
            ax.plot(v, np.arange(1, v.size + 1) / v.size, style, label=f"{tag} inputs (LHS)")
        m, s = float(target_mean[k]), float(target_std[k])
        if not (np.isnan(m) or np.isnan(s)):
            g = np.linspace(m - 4 * s, m + 4 * s, 200)
            ax.plot(g, stats.norm.cdf(g, m, s), "k--", lw=1, label="target N(mean, std)")
        ax.set_xlabel(axis_label(r, None, units), fontsize=8)
        ax.set_ylabel("CDF [-]", fontsize=8)
        ax.tick_params(labelsize=_TICK)
    _legend_below(fig, axes)
    return [Figure(f"{name}_cuu", f"Calibration under uncertainty ({name})", fig)]


def ground_effect_curves(name: str, resp: Sequence[str], labels: Sequence[str],
                         heights: np.ndarray, mean: np.ndarray, std: np.ndarray,
                         pp_mean: np.ndarray, pp_std: np.ndarray, measured: np.ndarray,
                         beside: Mapping[str, Mapping[str, tuple[float, float]]] | None = None,
                         beside_name: str = "",
                         curves: Mapping[str, Mapping[str, list]] | None = None
                         ) -> list[Figure]:
    """C_T/C_T(4R) and C_Q/C_Q(4R) vs H/R: model mean with +-3 std bars under each
    propagation, another source's where ``beside`` (sweep label -> response -> (mean, std),
    named ``beside_name``) gives them, the test points, Cheeseman-Bennett and the (digitized,
    approximate) Fradenburgh curve for C_T.

    name : the step's. resp (m), labels (P) : response names and point labels. heights (P,) :
    H/R of each point. mean, std (P, m) : the propagated responses' moments; pp_mean, pp_std
    (P, m) : the joint posterior predictive's (NaN without a chain); measured (P, m) : the
    data (NaN: none). Responses other than ``ct`` and ``cq`` are not drawn.
    """
    heights = np.asarray(heights, dtype=float)
    if heights.size == 0:
        return []
    out = []
    for r, title in (("ct", "thrust"), ("cq", "torque")):
        if r not in resp or np.isnan(mean[0, list(resp).index(r)]):
            continue
        k = list(resp).index(r)
        sym = "C_T" if r == "ct" else "C_Q"
        fig, ax = _subplots(figsize=(7.2, 4.2))
        series = [(mean, std, "model, independent normals (mean +- 3 std)", "C0", 0.0)]
        if not np.isnan(pp_mean[0, k]):
            series.append((pp_mean, pp_std, "model, joint posterior predictive (mean +- 3 std)",
                           "C1", 0.04))
        for m_, s_, what, color, dx in series:
            ax.errorbar(heights + dx, m_[:, k], yerr=3 * s_[:, k], fmt="-s", color=color,
                        capsize=4, ms=4, label=what)
        if beside:
            th_m, th_s = [], []
            for lab in labels:
                t = beside.get(lab, {}).get(r)
                th_m.append(np.nan if t is None else t[0])
                th_s.append(np.nan if t is None else t[1])
            if np.any(np.isfinite(th_m)):
                ax.errorbar(heights - 0.04, th_m, yerr=3 * np.asarray(th_s), fmt="--^",
                            color="C7", capsize=3, ms=4, label=f"{beside_name} (mean +- 3 std)")
        data = measured[:, k]
        ax.plot(heights, data, "o", color="k", label="experiment")
        h = np.linspace(0.8, 4.2, 200)
        if r == "ct":
            ref = 4.0
            cb = 1.0 / (1.0 - (1.0 / (4.0 * h)) ** 2)
            cb_ref = 1.0 / (1.0 - (1.0 / (4.0 * ref)) ** 2)
            ax.plot(h, cb / cb_ref, "--", color="C4", label="Cheeseman-Bennett (constant power)")
            fr = (curves or {}).get("fradenburgh_thrust_ratio")
            if fr:
                fh = np.asarray(fr["height_over_radius"], dtype=float)
                fv = np.asarray(fr["thrust_ratio"], dtype=float)
                ax.plot(fh, fv / np.interp(ref, fh, fv), "-.", color="C2",
                        label="Fradenburgh (digitized, approximate)")
        ax.set_xlabel("rotor height H/R [-]")
        ax.set_ylabel(f"{sym} / {sym}(4R test) [-]")
        ax.set_title(f"Normalised {title} coefficient vs height", fontsize=10)
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=_TICK)
        fig.legend(loc="outside right upper", **_LEGEND)
        out.append(Figure(f"{name}_{r}_vs_height",
                          f"Normalised {title} coefficient vs H/R ({name})", fig))
    return out


def sobol_sweep(swept: str, values: Sequence[float], steps: Sequence[str],
                sobols: Sequence[SobolIndices], mean: np.ndarray, std: np.ndarray,
                labels: Mapping[str, str] | None = None,
                units: Mapping[str, str] | None = None) -> list[Figure]:
    """Sobol indices and the response across steps that differ in one fixed input.

    One figure per response: the main (solid) and total (dashed) index of every input
    against the swept input's value, and the response's mean +- one std beside them.

    Parameters
    ----------
    swept : str
        The fixed input the steps differ in (e.g. ``advance_ratio``).
    values : sequence of float
        Its value at each step, shape (k,), increasing.
    steps : sequence of str
        The steps' names, in the order of ``values``.
    sobols : sequence of SobolIndices
        Each step's indices (the same inputs and responses in each).
    mean, std : ndarray of shape (k, m)
        Each step's response means and standard deviations, in the responses' units.
    labels, units : mapping of str to str, optional
        Display labels and units of inputs and responses.

    Returns
    -------
    list of Figure
        ``sweep_<swept>_<response>``, one per response.
    """
    x = np.asarray(values, dtype=float)
    first = sobols[0]
    out = []
    for k, r in enumerate(first.names_out):
        fig, (ax, ay) = _subplots(1, 2, figsize=(9, 3.4))
        for j, p in enumerate(first.names_in):
            line, = ax.plot(x, [s.main[k, j] for s in sobols], "o-",
                            label=f"{(labels or {}).get(p) or p}: main")
            ax.plot(x, [s.total[k, j] for s in sobols], "s--", color=line.get_color(),
                    label=f"{(labels or {}).get(p) or p}: total")
        ax.set_xlabel(axis_label(swept, labels, units), fontsize=_TICK)
        ax.set_ylabel("Sobol index [-]", fontsize=_TICK)
        ax.set_title(f"Indices of {(labels or {}).get(r) or r}", fontsize=9)
        ay.errorbar(x, mean[:, k], yerr=std[:, k], fmt="o-", capsize=3, color="k",
                    label="mean +- 1 std")
        ay.set_xlabel(axis_label(swept, labels, units), fontsize=_TICK)
        ay.set_ylabel(axis_label(r, labels, units), fontsize=_TICK)
        ay.set_title(f"{(labels or {}).get(r) or r} across the steps", fontsize=9)
        for a in (ax, ay):
            a.tick_params(labelsize=_TICK)
        _legend_below(fig, (ax, ay))
        out.append(Figure(f"sweep_{swept}_{r}", f"Sobol indices and {r} against {swept} "
                          f"(steps {', '.join(steps)})", fig))
    return out
