"""Step type ``bayes_calibration``: Bayes calibration by MCMC (DRAM on a GP emulator by
default), its chain diagnostics and what a reader must know before believing it.

Thresholds of its warnings (stated in the report):

* ``ESS_MIN`` effective sample size per parameter below which moments are noisy;
* ``RHAT_MAX`` split R-hat above which the chain has not mixed (Vehtari et al. 2021: 1.01);
* ``LOO_Q2_MIN`` emulator leave-one-out Q^2 below which the emulator is poor;
* ``PILEUP_MAX`` fraction of the chain in the outer 5 % of a bounded prior's range (0.05 for
  a flat posterior) above which the posterior piles up against the bound;
* ``STD_RATIO_MAX`` posterior std / prior std above which the data barely inform a parameter;
* ``PRIOR_Z_MAX`` prior standard deviations between posterior and prior mean beyond which the
  posterior has left the prior's bulk;
* ``CORR_MAX`` |posterior correlation| above which propagating independent normals misstates
  the predictive spread.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..params import Normal, ParameterSpace
from ..render.figures import (
    Figure,
    FigureContext,
    chain_traces,
    pair_plot,
    prior_posterior,
)
from ..render.tables import StepTable, label, make_table, parameters, value
from ..results import StepResult, dict_to_dist, dist_to_dict
from ._common import input_scalars, per_response
from .base import StepContext, StepType
from .options import SIGNATURE, Option, choice, integer, number_or_table

__all__ = ["STEP", "run_bayes_calibration", "chain_diagnostic_scalars", "bayes_tables",
           "bayes_figures", "bayes_warnings", "strong_correlations", "THRESHOLDS",
           "ESS_MIN", "RHAT_MAX", "LOO_Q2_MIN", "PILEUP_MAX", "STD_RATIO_MAX", "PRIOR_Z_MAX",
           "CORR_MAX"]

ESS_MIN = 200.0
RHAT_MAX = 1.01
LOO_Q2_MIN = 0.9
PILEUP_MAX = 0.15
STD_RATIO_MAX = 0.8
PRIOR_Z_MAX = 3.0
CORR_MAX = 0.7

THRESHOLDS = {"ess_min": ESS_MIN, "rhat_max": RHAT_MAX, "loo_q2_min": LOO_Q2_MIN,
              "pileup_max": PILEUP_MAX, "std_ratio_max": STD_RATIO_MAX,
              "prior_z_max": PRIOR_Z_MAX, "corr_max": CORR_MAX}


def chain_diagnostic_scalars(names: Sequence[str], chain: np.ndarray,
                             prior: ParameterSpace) -> dict:
    """Diagnostics of a posterior sample ``chain`` (N, d) against its ``prior``:

    ``std_ratio/p`` posterior std / prior std (near 1: the data do not inform p);
    ``prior_z/p`` (posterior mean - prior mean) / prior std (beyond 3: the posterior left the
    prior's bulk); ``pileup_lo/p``, ``pileup_hi/p`` fraction of the chain in the outer 5 % of
    a bounded prior's range at each end (0.05 for a flat posterior; much more: the posterior
    piles up against the bound); ``corr/p/q`` posterior correlation.
    """
    out = {}
    chain = np.asarray(chain, dtype=float)
    for j, p in enumerate(names):
        d = prior[p]
        x = chain[:, j]
        out[f"std_ratio/{p}"] = float(np.std(x, ddof=1) / d.std) if d.std > 0 else np.nan
        out[f"prior_z/{p}"] = float((np.mean(x) - d.mean) / d.std) if d.std > 0 else np.nan
        lo, hi = d.bounds
        if np.isfinite(lo) and np.isfinite(hi) and hi > lo:
            band = 0.05 * (hi - lo)
            out[f"pileup_lo/{p}"] = float(np.mean(x < lo + band))
            out[f"pileup_hi/{p}"] = float(np.mean(x > hi - band))
    if chain.shape[1] > 1:
        c = np.corrcoef(chain, rowvar=False)
        for i, p in enumerate(names):
            for j in range(i + 1, len(names)):
                out[f"corr/{p}/{names[j]}"] = float(c[i, j])
    return out


def run_bayes_calibration(ctx: StepContext) -> StepResult:
    """Bayes calibration (DRAM on a GP emulator by default). The chain is saved (later forward
    checks push its joint samples through the model); the distributions handed on are the
    normals with the chain's mean and std, as the reference study does (its table 4.15)."""
    import warnings

    from ..methods.mcmc import calibrate_bayes

    o = ctx.options
    emulator = None
    if o["emulator"] == "gp":
        from ..methods.surrogate import GaussianProcess

        emulator = GaussianProcess(trend=o["trend"])
    sd = per_response(o.get("noise_std"), ctx.responses)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = calibrate_bayes(
            ctx.model(), ctx.observations(), ctx.space, sampler=o["sampler"], emulator=emulator,
            n_emulator_samples=o["n_emulator_samples"], n_samples=o["n_samples"],
            burn_in=o["burn_in"], noise_std=sd,
            proposal_covariance=o["proposal"], seed=ctx.rng,
        )
    chain = np.asarray(res.chains).reshape(-1, ctx.space.dim)
    scalars = input_scalars(ctx.space)
    for j, p in enumerate(res.names_in):
        for what in ("mean", "std", "skewness", "kurtosis", "ess", "rhat"):
            scalars[f"{what}/{p}"] = float(np.asarray(getattr(res, what))[j])
        scalars[f"map/{p}"] = float(res.map_point[j])
    scalars["acceptance"] = float(res.acceptance_rate)
    scalars["kl_divergence"] = float(res.kl_divergence)
    scalars.update(chain_diagnostic_scalars(res.names_in, chain, ctx.space))
    loo = getattr(res, "emulator_loo", None)
    if loo is not None:
        for k, r in enumerate(ctx.responses):
            scalars[f"loo_q2/{r}"] = float(np.asarray(loo.q2)[k])
            scalars[f"loo_nrmse/{r}"] = float(np.asarray(loo.nrmse)[k])
    noise = (np.ones(len(ctx.responses)) if sd is None else
             np.broadcast_to(np.asarray(sd, dtype=float), (len(ctx.responses),)))
    for r, v in zip(ctx.responses, noise, strict=True):
        scalars[f"noise_std/{r}"] = float(v)
    posterior = {p: dist_to_dict(Normal(scalars[f"mean/{p}"], scalars[f"std/{p}"]))
                 for p in res.names_in}
    arrays = {"chain": chain, "data": np.asarray(ctx.data)}
    columns = {"chain": list(res.names_in), "data": list(ctx.responses)}
    return StepResult(ctx.name, ctx.type, scalars, arrays, posterior, meta={
        "columns": columns, "n_evaluations": int(res.n_evaluations),
        "noise_model": "unit variance (none given)" if sd is None else "noise_std per response",
        "warnings": sorted({f"{w.category.__name__}: {w.message}" for w in caught})[:10],
        "prior": {p: dist_to_dict(d) for p, d in zip(ctx.space.names, ctx.space.distributions,
                                                      strict=True)}})


def bayes_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    names = res.columns("chain") or parameters(res)
    rows = [[label(p, labels), value(res, f"input_mean/{p}"), value(res, f"input_std/{p}"),
             value(res, f"mean/{p}"), value(res, f"std/{p}"), value(res, f"skewness/{p}"),
             value(res, f"kurtosis/{p}"), value(res, f"ess/{p}"), value(res, f"rhat/{p}"),
             value(res, f"std_ratio/{p}"), value(res, f"pileup_lo/{p}"),
             value(res, f"pileup_hi/{p}")]
            for p in names]
    out = [make_table("Prior and posterior", (
        "parameter", "prior mean", "prior std", "posterior mean", "posterior std", "skewness",
        "excess kurtosis", "ESS", "R-hat", "post/prior std", "outer 5 % low",
        "outer 5 % high"), rows,
        "post/prior std near 1: the data do not inform the parameter; outer 5 %: "
        "fraction of the chain in the outer 5 % of a bounded prior's range (0.05 when "
        "flat).")]
    resp = res.columns("data")
    out.append(make_table("Chain and noise model", ("quantity", "value"), [
        ["acceptance rate", value(res, "acceptance")],
        ["KL divergence posterior || prior [nats]", value(res, "kl_divergence")],
        *[[f"noise std of {r}", value(res, f"noise_std/{r}")] for r in resp],
        *[[f"emulator leave-one-out Q2 of {r}", value(res, f"loo_q2/{r}")] for r in resp
          if f"loo_q2/{r}" in res.scalars]],
        f"Noise model: {res.meta.get('noise_model', 'not recorded')}."))
    if len(names) > 1:
        idx = {p: i for i, p in enumerate(names)}
        mat = [[label(p, labels)] + [1.0 if p == q else value(
            res, f"corr/{p}/{q}" if idx[p] < idx[q] else f"corr/{q}/{p}") for q in names]
            for p in names]
        out.append(make_table("Posterior correlation",
                              ("", *[label(q, labels) for q in names]), mat))
    return out


def bayes_figures(res: StepResult, ctx: FigureContext) -> list[Figure]:
    """Prior/posterior densities, chain traces and a pair plot of a Bayes step's chain; in the
    reference validation study, the ``truth`` sampling step's distributions are drawn too."""
    if "chain" not in res.arrays:
        return []
    truth = None
    if ctx.reference and ctx.study == "validation" and "truth" in ctx.steps:
        truth = {p: dict_to_dist(d) for p, d in
                 ctx.steps["truth"].meta.get("input_distributions", {}).items()}
    figs = prior_posterior(res, ctx.labels, ctx.units, truth or None)
    figs += chain_traces(res, ctx.labels, ctx.units)
    if len(res.columns("chain")) > 1:
        figs += pair_plot(res, ctx.labels, ctx.units)
    return figs


def _prefixed(res: StepResult, prefix: str) -> dict[str, float]:
    return {k[len(prefix):]: float(v) for k, v in res.scalars.items() if k.startswith(prefix)}


def strong_correlations(res: StepResult, labels: Mapping[str, str] | None = None,
                        limit: float = CORR_MAX) -> list[tuple[str, str, float]]:
    """Posterior correlations with |rho| > ``limit``: (label p, label q, rho), strongest
    first."""
    labels = labels or {}
    out = []
    for key, rho in _prefixed(res, "corr/").items():
        p, q = key.split("/")
        if abs(rho) > limit:
            out.append((label(p, labels), label(q, labels), rho))
    return sorted(out, key=lambda t: -abs(t[2]))


def bayes_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    """MCMC mixing, emulator quality, prior-bound pile-up, identifiability, noise model."""
    w: list[str] = []
    name = res.name

    def listed(prefix, bad, fmt):
        hits = [(p, v) for p, v in _prefixed(res, prefix).items() if bad(v)]
        return ", ".join(f"{label(p, labels)} ({fmt(v)})" for p, v in hits)

    if low := listed("ess/", lambda v: v < ESS_MIN, lambda v: f"{v:.0f}"):
        w.append(f"{name}: low effective sample size (below {ESS_MIN:.0f}): {low}")
    if high := listed("rhat/", lambda v: v > RHAT_MAX, lambda v: f"{v:.3f}"):
        w.append(f"{name}: chain not mixed (R-hat above {RHAT_MAX}): {high}")
    if poor := listed("loo_q2/", lambda v: v < LOO_Q2_MIN, lambda v: f"{v:.3f}"):
        w.append(f"{name}: poor emulator (leave-one-out Q2 below {LOO_Q2_MIN}): {poor}")
    for side, word in (("lo", "lower"), ("hi", "upper")):
        for p, f in _prefixed(res, f"pileup_{side}/").items():
            if f > PILEUP_MAX:
                w.append(f"{name}: {label(p, labels)} piles up against its prior's {word} "
                         f"bound ({100 * f:.0f} % of the chain in the outer 5 % of the "
                         "range)")
    if weak := listed("std_ratio/", lambda v: v > STD_RATIO_MAX, lambda v: f"{v:.2f}"):
        w.append(f"{name}: not identifiable from these data (posterior std / prior std "
                 f"above {STD_RATIO_MAX}): {weak}")
    if far := listed("prior_z/", lambda v: abs(v) > PRIOR_Z_MAX, lambda v: f"{v:+.1f}"):
        w.append(f"{name}: the posterior left the prior's bulk (prior std devs from the "
                 f"prior mean): {far}")
    for msg in res.meta.get("warnings", []) or []:
        w.append(f"{name}: {msg}")
    if str(res.meta.get("noise_model", "")).startswith("unit"):
        w.append(f"{name}: no noise model given: unit data variance for every response")
    return w


STEP = StepType(
    "bayes_calibration", run_bayes_calibration,
    method="rotoruq.methods.mcmc:calibrate_bayes", provides=("posterior",), needs_data=True,
    options={"sampler": Option(choice("dram", "mh", "dr", "am"), SIGNATURE),
             "n_samples": Option(integer(10), SIGNATURE),
             "burn_in": Option(integer(0), SIGNATURE),
             "emulator": Option(choice("gp", "none"), "gp"),
             "trend": Option(choice("constant", "linear", "reduced_quadratic", "quadratic"),
                             SIGNATURE, method="rotoruq.methods.surrogate:GaussianProcess"),
             "n_emulator_samples": Option(integer(2), SIGNATURE),
             "noise_std": Option(number_or_table, None),
             "proposal": Option(choice("hessian", "prior"), SIGNATURE,
                                param="proposal_covariance")},
    quick={"n_samples": 1800, "burn_in": 200, "n_emulator_samples": 60},
    tables=bayes_tables, figures=bayes_figures, warnings=bayes_warnings)
