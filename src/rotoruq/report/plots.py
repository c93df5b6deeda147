"""Figures of the report, drawn from saved step results with matplotlib's object API (no
pyplot, so a notebook's backend is left alone; files are written through Agg).

Every function returns a list of :class:`Figure` (name, caption, matplotlib figure); the
report writes each as PNG and SVG and embeds the PNG.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure as _MplFigure
from scipy import stats

from ..study.results import StepResult, dict_to_dist
from .reference import TABLES

__all__ = ["Figure", "figures_for_study", "tornado", "prior_posterior", "chain_traces",
           "pair_plot", "load_distributions", "cuu_comparison", "ground_effect_curves"]


@dataclass
class Figure:
    name: str
    caption: str
    figure: object  # matplotlib.figure.Figure


def _subplots(*args, figsize=None, **kwargs):
    """Figure and axes without pyplot: no global backend switch, nothing to close."""
    fig = _MplFigure(figsize=figsize)
    return fig, fig.subplots(*args, **kwargs)


def _label(name: str, labels: Mapping[str, str]) -> str:
    return labels.get(name) or name


def tornado(res: StepResult, labels: Mapping[str, str], thesis: dict | None = None
            ) -> list[Figure]:
    """Horizontal bars of the main (and total) Sobol indices per response; thesis bars beside
    ours when a thesis table maps this step."""
    inputs, responses = res.meta["inputs"], res.meta["responses"]
    k = len(responses)
    fig, axes = _subplots(1, k, figsize=(3.2 * k + 1.5, 0.45 * len(inputs) + 1.6),
                             sharey=True, squeeze=False)
    y = np.arange(len(inputs))
    for a, r in enumerate(responses):
        ax = axes[0, a]
        s = [res.get(f"S/{r}/{p}") for p in inputs]
        t = [res.get(f"T/{r}/{p}") for p in inputs]
        h = 0.28 if thesis else 0.4
        ax.barh(y + h, s, height=h, color="#1f77b4", label="main S_i")
        ax.barh(y, t, height=h, color="#9ecae1", label="total T_i")
        if thesis:
            th = [thesis.get((r, p), np.nan) for p in inputs]
            ax.barh(y - h, th, height=h, color="#d62728", alpha=0.7, label="thesis S_i")
        ax.set_title(r)
        ax.set_xlim(0, max(1.0, np.nanmax(np.r_[s, t, 0.0]) * 1.05))
        ax.grid(axis="x", alpha=0.3)
    axes[0, 0].set_yticks(y, [_label(p, labels) for p in inputs])
    axes[0, -1].legend(loc="lower right", fontsize=7)
    fig.suptitle(f"Sensitivity indices - {res.meta.get('title') or res.name}", fontsize=10)
    fig.tight_layout()
    return [Figure(f"{res.name}_tornado", f"Sobol indices ({res.name})", fig)]


def prior_posterior(res: StepResult, labels, truth: Mapping[str, object] | None = None
                    ) -> list[Figure]:
    """Prior density, the chain's histogram and the normal fit handed on, per parameter."""
    names = res.columns("chain")
    chain = np.asarray(res.arrays["chain"])
    prior = {k: dict_to_dist(v) for k, v in res.meta.get("prior", {}).items()}
    cols = min(3, len(names))
    rows = int(np.ceil(len(names) / cols))
    fig, axes = _subplots(rows, cols, figsize=(3.6 * cols, 2.6 * rows), squeeze=False)
    for j, p in enumerate(names):
        ax = axes.flat[j]
        x = chain[:, j]
        lo, hi = np.percentile(x, [0.1, 99.9])
        if p in prior:
            plo, phi = prior[p].bounds
            lo = min(lo, plo) if np.isfinite(plo) else lo
            hi = max(hi, phi) if np.isfinite(phi) else hi
        grid = np.linspace(lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo), 300)
        ax.hist(x, bins=40, density=True, color="#c6dbef", label="chain")
        if p in prior:
            ax.plot(grid, prior[p].pdf(grid), "k--", lw=1.2, label="prior")
        ax.plot(grid, stats.norm.pdf(grid, x.mean(), x.std(ddof=1)), "C0", lw=1.5,
                label="calibrated (normal)")
        if truth and p in truth:
            ax.plot(grid, truth[p].pdf(grid), "C2", lw=1.2, label="true")
        ax.set_title(_label(p, labels), fontsize=9)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=7)
    fig.tight_layout()
    return [Figure(f"{res.name}_densities", f"Prior vs posterior ({res.name})", fig)]


def chain_traces(res: StepResult, labels) -> list[Figure]:
    names = res.columns("chain")
    chain = np.asarray(res.arrays["chain"])
    fig, axes = _subplots(len(names), 1, figsize=(8, 1.1 * len(names) + 0.8), sharex=True,
                             squeeze=False)
    step = max(1, chain.shape[0] // 4000)
    for j, p in enumerate(names):
        ax = axes[j, 0]
        ax.plot(np.arange(0, chain.shape[0], step), chain[::step, j], lw=0.4, color="C0")
        ax.set_ylabel(_label(p, labels), fontsize=7, rotation=0, ha="right")
        ax.tick_params(labelsize=7)
    axes[-1, 0].set_xlabel("chain sample (after burn-in)")
    fig.tight_layout()
    return [Figure(f"{res.name}_traces", f"Chain traces ({res.name})", fig)]


def pair_plot(res: StepResult, labels) -> list[Figure]:
    names = res.columns("chain")
    chain = np.asarray(res.arrays["chain"])
    d = len(names)
    idx = np.linspace(0, chain.shape[0] - 1, min(chain.shape[0], 2000)).astype(int)
    fig, axes = _subplots(d, d, figsize=(1.5 * d + 1, 1.5 * d + 1), squeeze=False)
    for i in range(d):
        for j in range(d):
            ax = axes[i, j]
            ax.tick_params(labelsize=5)
            if j > i:
                ax.axis("off")
            elif i == j:
                ax.hist(chain[:, i], bins=30, color="#6baed6")
            else:
                ax.plot(chain[idx, j], chain[idx, i], ".", ms=1, alpha=0.4, color="C0")
            if i == d - 1:
                ax.set_xlabel(_label(names[j], labels), fontsize=6)
            if j == 0:
                ax.set_ylabel(_label(names[i], labels), fontsize=6)
    fig.tight_layout()
    return [Figure(f"{res.name}_pairs", f"Posterior pair plot ({res.name})", fig)]


def load_distributions(res: StepResult) -> list[Figure]:
    """PDF (histogram + KDE) and empirical CDF of every response at every sweep point, with
    the measured value."""
    out = []
    for label in res.meta.get("labels", [""]):
        arr = f"outputs{label}"
        if arr not in res.arrays:
            continue
        resp = res.columns(arr)
        fig, axes = _subplots(2, len(resp), figsize=(3.2 * len(resp), 5), squeeze=False)
        for k, r in enumerate(resp):
            v = np.asarray(res.arrays[arr])[:, k]
            v = v[np.isfinite(v)]
            if v.size < 2:
                continue
            measured = res.scalars.get(f"data/{r}{label}")
            ax = axes[0, k]
            ax.hist(v, bins=30, density=True, color="#c6dbef")
            if np.std(v) > 0:
                g = np.linspace(v.min(), v.max(), 200)
                ax.plot(g, stats.gaussian_kde(v)(g), "C0")
            ax.set_title(f"{r} PDF", fontsize=9)
            ax2 = axes[1, k]
            s = np.sort(v)
            ax2.step(s, np.arange(1, s.size + 1) / s.size, where="post", color="C0")
            ax2.set_title(f"{r} CDF", fontsize=9)
            if measured is not None:
                for a in (ax, ax2):
                    a.axvline(measured, color="C3", ls="--", lw=1.2, label="measured")
                ax2.legend(fontsize=7)
            for a in (ax, ax2):
                a.tick_params(labelsize=7)
        where = f" at H/R = {label[1:]}" if label else ""
        fig.suptitle(f"Load distributions{where} ({res.name})", fontsize=10)
        fig.tight_layout()
        out.append(Figure(f"{res.name}_loads{label.replace('@', '_h')}",
                          f"Load PDFs and CDFs{where} ({res.name})", fig))
    return out


def cuu_comparison(res: StepResult, labels, reference_outputs: np.ndarray | None = None
                   ) -> list[Figure]:
    """Input std devs before/after CUU and output CDFs: initial, calibrated, target data."""
    params = res.meta.get("parameters", [])
    resp = res.columns("outputs_calibrated") or res.meta.get("responses", [])
    n = 1 + len(resp)
    fig, axes = _subplots(1, n, figsize=(3.3 * n, 3.0), squeeze=False)
    ax = axes[0, 0]
    x = np.arange(len(params))
    init = [res.get(f"initial_std/{p}") / abs(res.get(f"mean/{p}") or 1) for p in params]
    cal = [res.get(f"std/{p}") / abs(res.get(f"mean/{p}") or 1) for p in params]
    ax.bar(x - 0.2, init, 0.4, label="initial", color="#9ecae1")
    ax.bar(x + 0.2, cal, 0.4, label="calibrated", color="C0")
    ax.set_xticks(x, [_label(p, labels) for p in params], rotation=30, fontsize=7)
    ax.set_title("input std / |mean|", fontsize=9)
    ax.legend(fontsize=7)
    for k, r in enumerate(resp):
        ax = axes[0, k + 1]
        for tag, style in (("initial", ":"), ("calibrated", "-")):
            arr = res.arrays.get(f"outputs_{tag}")
            if arr is None:
                continue
            v = np.sort(np.asarray(arr)[:, k])
            v = v[np.isfinite(v)]
            ax.plot(v, np.arange(1, v.size + 1) / v.size, style, label=tag)
        m, s = res.scalars.get(f"target_mean/{r}"), res.scalars.get(f"target_std/{r}")
        if m is not None and s is not None:
            g = np.linspace(m - 4 * s, m + 4 * s, 200)
            ax.plot(g, stats.norm.cdf(g, m, s), "k--", lw=1, label="target N(mean, std)")
        ax.set_title(f"{r} CDF", fontsize=9)
        ax.tick_params(labelsize=7)
    axes[0, -1].legend(fontsize=7)
    fig.tight_layout()
    return [Figure(f"{res.name}_cuu", f"Calibration under uncertainty ({res.name})", fig)]


def ground_effect_curves(res: StepResult) -> list[Figure]:
    """C_T/C_T(4R) and C_Q/C_Q(4R) vs H/R: model mean with +-3 std bars, the test points,
    Cheeseman-Bennett and the (digitized, approximate) Fradenburgh curve for C_T."""
    sweep = res.meta.get("sweep", {})
    heights = np.asarray(sweep.get("height_over_radius", []), dtype=float)
    if heights.size == 0:
        return []
    labels = res.meta.get("labels", [])
    out = []
    for r, title in (("ct", "thrust"), ("cq", "torque")):
        if f"mean/{r}{labels[0]}" not in res.scalars:
            continue
        mean = np.array([res.get(f"mean/{r}{lab}") for lab in labels])
        std = np.array([res.get(f"std/{r}{lab}") for lab in labels])
        data = np.array([res.get(f"data/{r}{lab}") for lab in labels])
        fig, ax = _subplots(figsize=(5.5, 4))
        ax.errorbar(heights, mean, yerr=3 * std, fmt="-s", color="C0", capsize=4,
                    label="model (mean +- 3 std)")
        ax.plot(heights, data, "o", color="k", label="experiment")
        h = np.linspace(0.8, 4.2, 200)
        if r == "ct":
            ref = 4.0
            cb = 1.0 / (1.0 - (1.0 / (4.0 * h)) ** 2)
            cb_ref = 1.0 / (1.0 - (1.0 / (4.0 * ref)) ** 2)
            ax.plot(h, cb / cb_ref, "--", color="C1",
                    label="Cheeseman-Bennett (constant power)")
            try:
                from ..rotor.ground_effect import fradenburgh_thrust_ratio

                fr = fradenburgh_thrust_ratio(h)
                ax.plot(h, fr / fradenburgh_thrust_ratio(np.array([ref]))[0], "-.",
                        color="C2", label="Fradenburgh (digitized, approximate)")
            except ImportError:
                pass
        ax.set_xlabel("H/R")
        ax.set_ylabel(f"C_{'T' if r == 'ct' else 'Q'} / C_{'T' if r == 'ct' else 'Q'}(4R test)")
        ax.set_title(f"Normalised {title} coefficient vs height")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        out.append(Figure(f"{res.name}_{r}_vs_height",
                          f"Normalised {title} coefficient vs H/R ({res.name})", fig))
    return out


def _thesis_sobol(step: str, study: str) -> dict | None:
    """(response, input) -> thesis main index for the step, from the reference tables."""
    out = {}
    for t in TABLES:
        if t.study != study:
            continue
        for _, cells in t.rows:
            for value, src in cells:
                if src and src.startswith(f"{step}:S/"):
                    _, r, p = src.split(":", 1)[1].split("/")
                    out[(r, p)] = value
    return out or None


def figures_for_study(study: str, steps: Mapping[str, StepResult], labels: Mapping[str, str]
                      ) -> list[Figure]:
    """All figures for one study's saved steps, in step order."""
    figs: list[Figure] = []
    truth_dists = {}
    for res in steps.values():
        if res.type == "sampling":
            for p, d in res.meta.get("input_distributions", {}).items():
                truth_dists.setdefault(res.name, {})[p] = dict_to_dist(d)
    for res in steps.values():
        try:
            if res.type in ("sensitivity", "pce") and "inputs" in res.meta:
                figs += tornado(res, labels, _thesis_sobol(res.name, study))
            elif res.type == "bayes_calibration" and "chain" in res.arrays:
                truth = truth_dists.get("truth") if study == "validation" else None
                figs += prior_posterior(res, labels, truth)
                figs += chain_traces(res, labels)
                figs += pair_plot(res, labels)
            elif res.type == "forward_check":
                if res.meta.get("normalized"):
                    figs += ground_effect_curves(res)
                else:
                    figs += load_distributions(res)
            elif res.type == "sampling" and "outputs" in res.arrays:
                figs += load_distributions(StepResult(
                    res.name, res.type, res.scalars, {"outputs": res.arrays["outputs"]},
                    meta={"columns": {"outputs": res.columns("outputs")}, "labels": [""]}))
            elif res.type == "cuu":
                figs += cuu_comparison(res, labels)
        except (KeyError, ValueError, IndexError) as exc:  # a figure never fails the report
            fig, ax = _subplots(figsize=(5, 1))
            ax.axis("off")
            ax.text(0.0, 0.5, f"{res.name}: figure not drawn ({exc})", fontsize=8)
            figs.append(Figure(f"{res.name}_missing", f"{res.name}: no figure", fig))
    return figs
