"""What a saved step says about its own trustworthiness, computed from the step's scalars.

:func:`step_warnings` lists the diagnostics a reader must know before believing a step's
numbers (MCMC convergence, emulator quality, identifiability, prior-bound pile-up, a
posterior far from its prior, Sobol indices of a response with negligible variance). The
claims of the report, its step tables, ``rotoruq show`` and the terminal summary of
``rotoruq run`` all use it, so they always agree.

Thresholds (stated in the report):

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

from collections.abc import Mapping

from ..results import StepResult
from .hooks import rendering

__all__ = ["step_warnings", "strong_correlations", "THRESHOLDS", "bayes_warnings",
           "cuu_warnings", "sobol_warnings", "least_squares_warnings"]

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


def _keys(res: StepResult, prefix: str) -> dict[str, float]:
    return {k[len(prefix):]: float(v) for k, v in res.scalars.items() if k.startswith(prefix)}


def _lab(name: str, labels: Mapping[str, str]) -> str:
    return labels.get(name) or name


def strong_correlations(res: StepResult, labels: Mapping[str, str] | None = None,
                        limit: float = CORR_MAX) -> list[tuple[str, str, float]]:
    """Posterior correlations with |rho| > ``limit``: (label p, label q, rho), strongest
    first."""
    labels = labels or {}
    out = []
    for key, rho in _keys(res, "corr/").items():
        p, q = key.split("/")
        if abs(rho) > limit:
            out.append((_lab(p, labels), _lab(q, labels), rho))
    return sorted(out, key=lambda t: -abs(t[2]))


def step_warnings(res: StepResult, labels: Mapping[str, str] | None = None) -> list[str]:
    """Warnings computed from one saved step (empty when it has nothing to flag): its type's
    ``warnings`` renderer (:mod:`rotoruq.report.hooks`)."""
    hook = rendering(res.type).warnings
    return hook(res, labels or {}) if hook is not None else []


def bayes_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    """MCMC mixing, emulator quality, prior-bound pile-up, identifiability, noise model."""
    w: list[str] = []
    name = res.name

    def listed(prefix, bad, fmt):
        hits = [(p, v) for p, v in _keys(res, prefix).items() if bad(v)]
        return ", ".join(f"{_lab(p, labels)} ({fmt(v)})" for p, v in hits)

    if low := listed("ess/", lambda v: v < ESS_MIN, lambda v: f"{v:.0f}"):
        w.append(f"{name}: low effective sample size (below {ESS_MIN:.0f}): {low}")
    if high := listed("rhat/", lambda v: v > RHAT_MAX, lambda v: f"{v:.3f}"):
        w.append(f"{name}: chain not mixed (R-hat above {RHAT_MAX}): {high}")
    if poor := listed("loo_q2/", lambda v: v < LOO_Q2_MIN, lambda v: f"{v:.3f}"):
        w.append(f"{name}: poor emulator (leave-one-out Q2 below {LOO_Q2_MIN}): {poor}")
    for side, word in (("lo", "lower"), ("hi", "upper")):
        for p, f in _keys(res, f"pileup_{side}/").items():
            if f > PILEUP_MAX:
                w.append(f"{name}: {_lab(p, labels)} piles up against its prior's {word} "
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


def cuu_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    """A calibration under uncertainty whose input std devs are not identifiable."""
    if res.meta.get("identifiable") is False:
        diag = res.meta.get("diagnostic") or "the input std devs are not identifiable"
        return [f"{res.name}: not identifiable: {diag}"]
    return []


def sobol_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    """Sobol indices of a response with negligible variance (sensitivity, pce)."""
    return [f"{res.name}: {r} has negligible variance (std "
            f"{res.get(f'out_std/{r}'):.3g}, {res.get(f'out_cv/{r}'):.1e} of "
            "its mean): its Sobol indices split up numerical noise"
            for r, flag in _keys(res, "negligible/").items() if flag]


def least_squares_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    """A least-squares calibration that did not converge."""
    if res.meta.get("converged") is False:
        return [f"{res.name}: least squares did not converge ({res.meta.get('message', '')})"]
    return []
