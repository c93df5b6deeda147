"""Step type ``bayes_calibration``: Bayes calibration by MCMC (DRAM on a GP emulator by
default), its chain diagnostics and what a reader must know before believing it.

Thresholds of its warnings (stated in the report):

* ``ESS_MIN`` effective sample size per parameter below which moments are noisy;
* ``RHAT_MAX`` split R-hat above which the chain has not mixed (Vehtari et al. 2021: 1.01);
* ``LOO_Q2_MIN`` emulator leave-one-out Q^2 (shown, no longer warned on: Q^2 measures the
  emulator against the response's spread, not against the noise that decides the posterior);
* ``POSTERIOR_RATIO_MAX`` the emulator's RMS Kriging std over the posterior / the noise std
  above which the emulator's error matters (:data:`rotoruq.methods.mcmc.adequacy.WARN_RATIO`);
* ``PILEUP_MAX`` fraction of the chain in the outer 5 % of a bounded prior's range (0.05 for
  a flat posterior) above which the posterior piles up against the bound;
* ``STD_RATIO_MAX`` posterior std / prior std above which the data barely inform a parameter;
* ``PRIOR_Z_MAX`` prior standard deviations between posterior and prior mean beyond which the
  posterior has left the prior's bulk;
* ``CORR_MAX`` |posterior correlation| above which propagating independent normals misstates
  the predictive spread.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from ..methods._convergence import ChainConvergence
from ..params import Distribution, Normal, ParameterSpace
from ..params.density import kernel_density
from ..render.figures import (
    Figure,
    FigureContext,
    beside_truth,
    chain_traces,
    pair_plot,
    prior_posterior,
)
from ..render.tables import StepTable, cell, label, make_table
from ..results import RecordError, StepRecord, StepResult, dict_to_dist, dist_to_dict
from ._common import chain_on_model, deferred_writes, named_model, per_response
from ._discrepancy import (
    DiscrepancyRecord,
    check_discrepancy,
    discrepancy_option,
    discrepancy_tables,
    discrepancy_warnings,
    is_discrepancy,
)
from .base import StepCheck, StepContext, StepType
from .options import (
    SIGNATURE,
    Option,
    boolean,
    choice,
    integer,
    number,
    number_list,
    number_or_table,
    string,
    string_list,
    table,
)

__all__ = ["STEP", "BayesRecord", "run_bayes_calibration", "noise_model_text",
           "chain_diagnostics", "read_posterior", "posterior_record", "bayes_tables",
           "bayes_figures", "bayes_warnings", "strong_correlations", "THRESHOLDS",
           "ESS_MIN", "RHAT_MAX", "LOO_Q2_MIN", "PILEUP_MAX", "STD_RATIO_MAX", "PRIOR_Z_MAX",
           "CORR_MAX", "POSTERIOR_RATIO_MAX", "sequential_prior", "SELF_CHECK_FAILED"]

ESS_MIN = 200.0
RHAT_MAX = 1.01
LOO_Q2_MIN = 0.9
PILEUP_MAX = 0.15
STD_RATIO_MAX = 0.8
PRIOR_Z_MAX = 3.0
CORR_MAX = 0.7
POSTERIOR_RATIO_MAX = 0.3

THRESHOLDS = {"ess_min": ESS_MIN, "rhat_max": RHAT_MAX, "loo_q2_min": LOO_Q2_MIN,
              "pileup_max": PILEUP_MAX, "std_ratio_max": STD_RATIO_MAX,
              "prior_z_max": PRIOR_Z_MAX, "corr_max": CORR_MAX,
              "posterior_ratio_max": POSTERIOR_RATIO_MAX}


def chain_diagnostics(names: Sequence[str], chain: np.ndarray,
                      prior: ParameterSpace) -> dict[str, np.ndarray]:
    """Diagnostics (d,) of a posterior sample ``chain`` (N, d) of parameters ``names``
    against their ``prior``, NaN where they do not apply:

    ``std_ratio`` posterior std / prior std (near 1: the data do not inform the parameter);
    ``prior_z`` (posterior mean - prior mean) / prior std (beyond 3: the posterior left the
    prior's bulk); ``pileup_lo``, ``pileup_hi`` fraction of the chain in the outer 5 % of a
    bounded prior's range at each end (0.05 for a flat posterior; much more: the posterior
    piles up against the bound).

    Examples
    --------
    >>> from rotoruq.params import Uniform
    >>> out = chain_diagnostics(["a"], np.array([[0.01], [0.02], [0.5], [0.99]]),
    ...                         ParameterSpace({"a": Uniform(0.0, 1.0)}))
    >>> out["pileup_lo"].tolist(), out["pileup_hi"].tolist()
    ([0.5], [0.25])
    """
    chain = np.asarray(chain, dtype=float)
    out = {k: np.full(len(names), np.nan)
           for k in ("std_ratio", "prior_z", "pileup_lo", "pileup_hi")}
    for j, p in enumerate(names):
        dist, x = prior[p], chain[:, j]
        if dist.std > 0:
            out["std_ratio"][j] = float(np.std(x, ddof=1) / dist.std)
            out["prior_z"][j] = float((np.mean(x) - dist.mean) / dist.std)
        lo, hi = dist.bounds
        if np.isfinite(lo) and np.isfinite(hi) and hi > lo:
            band = 0.05 * (hi - lo)
            out["pileup_lo"][j] = float(np.mean(x < lo + band))
            out["pileup_hi"][j] = float(np.mean(x > hi - band))
    return out


#: The words of a failed self-check in a step's warnings (what a claim resting on it shows).
SELF_CHECK_FAILED = "the self-check (simulation-based calibration) FAILED"


def _empty() -> np.ndarray:
    # the value :meth:`StepRecord.read` gives a field added since a record was saved;
    # :func:`read_posterior` reads it as NaN (not computed) in its shape
    return np.zeros(0)


@dataclass(frozen=True, eq=False)
class BayesRecord(StepRecord, ChainConvergence):
    """What a Bayes calibration step saves besides its flat chain: d parameters, m observed
    responses, k noise multipliers.

    names_in (d), names_out (m), multiplier_names (k). n_chains, n_draws : the chains' shape
    (the saved ``chain`` array is (n_chains * n_draws, d), chain after chain).
    mean, std, skewness, kurtosis (excess) (d,) posterior moments; correlation (d, d);
    map_point (d,) the chains' start (the MAP pre-solve).
    ess, rhat (d,) : the bulk effective sample size and the larger of the bulk and folded
    R-hat; rhat_bulk, rhat_folded : rank-normalised split R-hat; ess_bulk, ess_tail :
    effective sample sizes (draws); mcse_mean, mcse_q05, mcse_q95 : Monte Carlo standard
    errors of the mean and of the 5 % / 95 % quantiles (parameter units) (Vehtari et al.
    2021; NaN without the diagnostics).
    std_ratio, prior_z, pileup_lo, pileup_hi (d,) : the chain against the prior
    (:func:`chain_diagnostics`). kl_divergence : KL(posterior || prior) [nats].
    noise_std (m,) stated noise std of each response (data units; ones for unit variance).
    noise_model : the noise model in words. emulator_variance : the emulator's Kriging
    variance is in the likelihood. posterior_ratio, loo_ratio (m,) : the emulator's RMS
    Kriging std over the posterior and its leave-one-out RMSE, each over the noise std of the
    experiments' mean; loo_q2, loo_nrmse (m,) : its leave-one-out Q^2 and normalised RMSE
    (all NaN without an emulator); runs_added : model runs added by each refinement round;
    target_ratio : refinement target (None without refinement).
    low_fidelity_models (l) : a co-kriging emulator's low-fidelity models, cheapest first;
    low_fidelity_runs (l,) : the runs of each; cokriging_levels (l) : the level above each
    (the next model, the calibrated ``"model"`` last); cokriging_rho (l, m) : the scale of
    each level on the one below (zero-length without co-kriging).
    sbc_rank_histogram (d, bins), sbc_p_value, sbc_coverage_50, sbc_coverage_90 (d,) : the
    self-check (simulation-based calibration; zero-length without one); self_check_passed
    (None without one) and self_check_reason.
    multiplier_mean, multiplier_std, multiplier_lower, multiplier_upper (k,) : posterior of
    the noise variance multipliers (mean, std, 95 % equal-tailed interval).
    acceptance : fraction of chain steps that moved.

    The flat view keeps the keys the step has always had: ``mean/<p>``, ``map/<p>``,
    ``corr/<p>/<q>``, ``noise_std/<r>``, ``cokriging_rho/<level>/<r>``,
    ``multiplier_mean/<name>``, ...
    """

    AXES = {"mean": ("parameter",), "std": ("parameter",),
            "correlation": ("parameter", "parameter"),
            "rhat_bulk": ("parameter",), "rhat_folded": ("parameter",),
            "ess_bulk": ("parameter",), "ess_tail": ("parameter",),
            "mcse_mean": ("parameter",), "mcse_q05": ("parameter",), "mcse_q95": ("parameter",),
            "noise_std": ("response",), "posterior_ratio": ("response",),
            "loo_ratio": ("response",),
            "sbc_rank_histogram": ("parameter", "bin"), "sbc_p_value": ("parameter",),
            "sbc_coverage_50": ("parameter",), "sbc_coverage_90": ("parameter",),
            "multiplier_mean": ("multiplier",), "multiplier_std": ("multiplier",),
            "multiplier_lower": ("multiplier",), "multiplier_upper": ("multiplier",),
            **{k: ("parameter",) for k in ("skewness", "kurtosis", "ess", "rhat", "map_point",
                                            "std_ratio", "prior_z", "pileup_lo",
                                            "pileup_hi")},
            "loo_q2": ("response",), "loo_nrmse": ("response",),
            "low_fidelity_runs": ("low_fidelity",), "cokriging_rho": ("level", "response")}
    FLAT = {"correlation": "corr", "map_point": "map", "sbc_rank_histogram": None}
    LABELS = {"multiplier": "multiplier_names", "low_fidelity": "low_fidelity_models",
              "level": "cokriging_levels"}

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    multiplier_names: tuple[str, ...]
    n_chains: int
    n_draws: int
    mean: np.ndarray
    std: np.ndarray
    correlation: np.ndarray
    noise_std: np.ndarray
    noise_model: str
    emulator_variance: bool
    posterior_ratio: np.ndarray
    loo_ratio: np.ndarray
    runs_added: tuple[int, ...]
    target_ratio: float | None
    sbc_rank_histogram: np.ndarray
    sbc_p_value: np.ndarray
    sbc_coverage_50: np.ndarray
    sbc_coverage_90: np.ndarray
    self_check_passed: bool | None
    self_check_reason: str
    multiplier_mean: np.ndarray
    multiplier_std: np.ndarray
    multiplier_lower: np.ndarray
    multiplier_upper: np.ndarray
    acceptance: float
    # added since the first records: an older record reads them empty (see _empty)
    skewness: np.ndarray = field(default_factory=_empty)
    kurtosis: np.ndarray = field(default_factory=_empty)
    ess: np.ndarray = field(default_factory=_empty)
    rhat: np.ndarray = field(default_factory=_empty)
    map_point: np.ndarray = field(default_factory=_empty)
    std_ratio: np.ndarray = field(default_factory=_empty)
    prior_z: np.ndarray = field(default_factory=_empty)
    pileup_lo: np.ndarray = field(default_factory=_empty)
    pileup_hi: np.ndarray = field(default_factory=_empty)
    kl_divergence: float = math.nan
    loo_q2: np.ndarray = field(default_factory=_empty)
    loo_nrmse: np.ndarray = field(default_factory=_empty)
    low_fidelity_models: tuple[str, ...] = ()
    low_fidelity_runs: np.ndarray = field(default_factory=_empty)
    cokriging_levels: tuple[str, ...] = ()
    cokriging_rho: np.ndarray = field(default_factory=_empty)

    @classmethod
    def partial(cls, names_in: Sequence[str], names_out: Sequence[str],
                **given: Any) -> BayesRecord:
        """A record of which only ``given`` (field -> value) is known: every other array
        NaN (not computed) in its shape, no multipliers, co-kriging, refinement or
        self-check, one chain.

        Examples
        --------
        >>> rec = BayesRecord.partial(("a", "b"), ("thrust",), ess=np.array([80.0, 900.0]))
        >>> rec.ess.tolist(), rec.rhat.shape, rec.correlation.shape, rec.multiplier_mean.size
        ([80.0, 900.0], (2,), (2, 2), 0)
        """
        plain: dict[str, Any] = {
            "multiplier_names": (), "n_chains": 1, "n_draws": 0, "noise_model": "",
            "emulator_variance": False, "runs_added": (), "target_ratio": None,
            "self_check_passed": None, "self_check_reason": "", "acceptance": math.nan,
            "kl_divergence": math.nan, "low_fidelity_models": (), "cokriging_levels": (),
            **given}
        size = {"parameter": len(names_in), "response": len(names_out),
                "multiplier": len(plain["multiplier_names"]),
                "low_fidelity": len(plain["low_fidelity_models"]),
                "level": len(plain["cokriging_levels"])}
        arrays: dict[str, Any] = {k: np.full([size.get(a, 0) for a in axes], np.nan)
                                  for k, axes in cls.AXES.items() if k not in given}
        return cls(names_in=tuple(names_in), names_out=tuple(names_out), **plain, **arrays)

    def completed(self) -> BayesRecord:
        """This record with the arrays an older version did not save (read empty) NaN in
        their shape, and a NaN number saved (as JSON null) NaN again."""
        given = {f.name: getattr(self, f.name) for f in fields(self)
                 if f.name not in ("names_in", "names_out") and not (
                     f.default_factory is _empty and np.size(getattr(self, f.name)) == 0)}
        for k in ("acceptance", "kl_divergence"):
            if given[k] is None:
                given[k] = math.nan
        return BayesRecord.partial(self.names_in, self.names_out, **given)


def noise_model_text(noise_std: Mapping[str, float] | None, multipliers, prior,
                     emulator: bool, emulator_variance: bool) -> str:
    """The noise model of a Bayes step in one sentence (stated in its table and the report)."""
    if noise_std is None:
        text = "unit variance (none given)"
    else:
        text = "noise std per response (" + ", ".join(
            f"{r} {v:g}" for r, v in noise_std.items()) + ")"
    if multipliers is not None:
        which = multipliers if isinstance(multipliers, str) else ", ".join(multipliers)
        text += (f"; noise variance multipliers calibrated ({which}; inverse-gamma prior "
                 f"alpha {prior[0]:g}, beta {prior[1]:g})")
    if emulator:
        text += ("; the emulator's Kriging variance added to the noise variance"
                 if emulator_variance else
                 "; the emulator's mean only (its error ignored)")
    return text


def _refine_config(value):
    if value is None:
        return None
    from ..methods.mcmc.adequacy import RefineConfig

    return RefineConfig(**value)


def _first_of_each_kind(caught) -> list[str]:
    """The first warning of each category, in the order raised: the calibration's own come
    before the self-check's replications, which repeat them. The emulator's adequacy is left
    out (:func:`bayes_warnings` states it from the record)."""
    out: dict[str, str] = {}
    for w in caught:
        if not str(w.message).startswith("emulator error over"):
            out.setdefault(w.category.__name__, f"{w.category.__name__}: {w.message}")
    return list(out.values())


class _StoredSelfChecks:
    """Self-checks kept in the study's store (its ``computed`` table, kind "self_check"),
    under their setup's key (:func:`rotoruq.methods.mcmc.sbc.setup_key`) joined with the
    digest of the code that computes them: a step whose data changed, or another step of
    the same setup, reuses the self-check instead of running it again."""

    def __init__(self, store):
        from ..evaluation.identity import code_digest, code_parts

        self.store = store
        self.code = code_digest(code_parts(["rotoruq.methods.mcmc.sbc"]))

    def get(self, key: str, /):
        import io

        from ..methods.mcmc.sbc import SBCResult

        blob = self.store.get_computed("self_check", f"{key}|{self.code}")
        if blob is None:
            return None
        with np.load(io.BytesIO(blob), allow_pickle=False) as npz:
            arrays = dict(npz)
        caught = arrays.pop("_warnings").reshape(-1, 2)
        return (SBCResult.from_arrays(arrays),
                tuple((str(c), str(m)) for c, m in caught))

    def __setitem__(self, key: str, value, /) -> None:
        import io

        result, caught = value
        buf = io.BytesIO()
        np.savez(buf, _warnings=np.array(caught, dtype=str).reshape(-1, 2),
                 **result.to_arrays())
        self.store.put_computed("self_check", f"{key}|{self.code}", buf.getvalue())


def run_bayes_calibration(ctx: StepContext) -> StepResult:
    """Bayes calibration (DRAM on a GP emulator by default, several chains advanced together).
    The chains are saved (later forward checks and sampling steps propagate their joint
    draws); the distributions handed on are the normals with the chain's mean and std, as
    the reference study does (its table 4.15), for steps that ask for independent normals."""
    import warnings

    from ..methods.mcmc import ChainOptions, EmulatorOptions, NoiseModel, calibrate_bayes

    if ctx.options.get("discrepancy") is not None:  # Kennedy-O'Hagan: steps/_discrepancy.py
        from ._discrepancy import run_discrepancy
        return run_discrepancy(ctx)
    o = ctx.options
    emulator: Any = None
    if o["emulator"] == "gp":
        from ..methods.surrogate import GaussianProcess

        emulator = GaussianProcess(trend=o["trend"])
    elif o["emulator"] == "cokriging":
        from ..methods.cokriging import CoKriging

        emulator = CoKriging({"trend": o["trend"]},
                             low_fidelity=[named_model(ctx, n) for n in o["models"]],
                             n_low=o["n_low"])
    sd = per_response(o.get("noise_std"), ctx.responses)
    multipliers = o.get("noise_multipliers")
    mult_prior = tuple(o.get("noise_multiplier_prior") or (1.0, 1.0))
    model = ctx.model()
    # on an emulator the model runs its design (kept in the store); else the chains run on it
    writes = deferred_writes if emulator is not None else chain_on_model
    with warnings.catch_warnings(record=True) as caught, writes(model):
        warnings.simplefilter("always")
        res = calibrate_bayes(
            model, ctx.observations(), ctx.space,
            noise=NoiseModel(noise_std=sd, noise_multipliers=multipliers,
                             noise_multiplier_prior=mult_prior),
            chains=ChainOptions(sampler=o["sampler"], n_samples=o["n_samples"],
                                burn_in=o["burn_in"], n_chains=o["n_chains"],
                                proposal_covariance=o["proposal"]),
            emulator=None if emulator is None else EmulatorOptions(
                emulator, n_emulator_samples=o["n_emulator_samples"],
                emulator_variance=o["emulator_variance"],
                refine=_refine_config(o.get("refine"))),
            self_check=o["self_check"], seed=ctx.rng,
            self_check_cache=(_StoredSelfChecks(ctx.store) if o["self_check"] and ctx.store
                              is not None else None),
        )
    names = tuple(res.names_in)
    d, m = len(names), len(ctx.responses)
    chains = np.asarray(res.chains, dtype=float)
    chain = chains.reshape(-1, d)
    dg = res.diagnostics
    loo = getattr(res, "emulator_loo", None)
    noise = (np.ones(m) if sd is None else
             np.broadcast_to(np.asarray(sd, dtype=float), (m,)).copy())
    ad = res.emulator_adequacy
    post_ratio = np.full(m, np.nan) if ad is None else np.asarray(ad.posterior_ratio, float)
    loo_ratio = np.full(m, np.nan) if ad is None else np.asarray(ad.loo_ratio, float)
    lf_models: tuple[str, ...] = ()
    lf_runs, rho = np.zeros(0, dtype=int), np.zeros((0, m))
    if o["emulator"] == "cokriging":
        from ..methods.cokriging import CoKriging

        assert isinstance(res.emulator, CoKriging)
        lf_models = tuple(o["models"])
        lf_runs = np.asarray(res.n_low_fidelity_evaluations, dtype=int)
        rho = np.asarray(res.emulator.rho, dtype=float)  # (levels - 1, m)
    sbc = res.self_check
    mnames: tuple[str, ...] = tuple(res.noise_multiplier_names or ())
    msum = res.noise_multiplier_summary() if mnames else {}
    mstats = np.array([msum[n] for n in mnames], dtype=float).reshape(len(mnames), 4)
    noise_dict = None if sd is None else dict(zip(ctx.responses, map(float, noise),
                                                  strict=True))
    text = noise_model_text(noise_dict, multipliers, mult_prior, emulator is not None,
                            bool(o["emulator_variance"]))
    diag = {k: (np.asarray(getattr(dg, k), float) if dg is not None else np.full(d, np.nan))
            for k in ("rhat_bulk", "rhat_folded", "ess_bulk", "ess_tail", "mcse_mean",
                      "mcse_q05", "mcse_q95")}
    sbc_arrays = {f"sbc_{k}": (np.asarray(getattr(sbc, k), float) if sbc is not None
                               else np.zeros(0)) for k in ("p_value", "coverage_50",
                                                           "coverage_90")}
    record = BayesRecord(
        names_in=names, names_out=tuple(ctx.responses), multiplier_names=mnames,
        n_chains=int(chains.shape[0]), n_draws=int(chains.shape[1]),
        mean=np.asarray(res.mean, float), std=np.asarray(res.std, float),
        correlation=np.asarray(res.correlation, float).reshape(d, d), **diag,
        noise_std=noise, noise_model=text,
        emulator_variance=bool(o["emulator_variance"]) and emulator is not None,
        posterior_ratio=post_ratio, loo_ratio=loo_ratio,
        runs_added=tuple(int(k) for k in (ad.runs_added if ad is not None else ())),
        target_ratio=None if ad is None or ad.target_ratio is None else float(ad.target_ratio),
        sbc_rank_histogram=(np.asarray(sbc.rank_histogram, float) if sbc is not None
                            else np.zeros((d, 0))), **sbc_arrays,
        self_check_passed=None if sbc is None else bool(sbc.passed),
        self_check_reason="" if sbc is None else str(sbc.reason),
        multiplier_mean=mstats[:, 0], multiplier_std=mstats[:, 1],
        multiplier_lower=mstats[:, 2], multiplier_upper=mstats[:, 3],
        acceptance=float(res.acceptance_rate),
        skewness=np.asarray(res.skewness, float), kurtosis=np.asarray(res.kurtosis, float),
        ess=np.asarray(res.ess, float), rhat=np.asarray(res.rhat, float),
        map_point=np.asarray(res.map_point, float),
        **chain_diagnostics(names, chain, ctx.space),
        kl_divergence=float(res.kl_divergence),
        loo_q2=np.full(m, np.nan) if loo is None else np.asarray(loo.q2, float),
        loo_nrmse=np.full(m, np.nan) if loo is None else np.asarray(loo.nrmse, float),
        low_fidelity_models=lf_models, low_fidelity_runs=lf_runs,
        # the level above each low-fidelity model: the next one, the calibrated model last
        cokriging_levels=(*lf_models[1:], "model") if lf_models else (), cokriging_rho=rho)
    rec_arrays, rec_meta = record.parts()
    posterior = {p: dist_to_dict(Normal(float(record.mean[j]), float(record.std[j])))
                 for j, p in enumerate(names)}
    arrays = {"chain": chain, "log_posterior": np.asarray(res.log_posterior, dtype=float),
              "data": np.asarray(ctx.data), **rec_arrays}
    columns = {"chain": list(names), "data": list(ctx.responses)}
    if mnames:
        arrays["multiplier_chain"] = np.asarray(res.noise_multiplier_chains,
                                                dtype=float).reshape(-1, len(mnames))
        columns["multiplier_chain"] = list(mnames)
    return StepResult(ctx.name, ctx.type, {}, arrays, posterior, meta={
        "columns": columns, "n_evaluations": int(res.n_evaluations),
        "noise_model": text, "n_chains": int(chains.shape[0]),
        "reuse_data": bool(o.get("reuse_data")),
        "warnings": _first_of_each_kind(caught),
        "prior": {p: dist_to_dict(d) for p, d in zip(ctx.space.names, ctx.space.distributions,
                                                      strict=True)}, **rec_meta})


def sequential_prior(res: StepResult) -> dict[str, Distribution]:
    """The prior a later calibration takes from this Bayes step's posterior
    (``from = "STEP.posterior"`` in a ``bayes_calibration`` step): each parameter's
    :func:`~rotoruq.kernel_density` of the saved chain, reflected at and kept
    inside the support of the prior this step had, so a flat posterior stays flat (excess
    kurtosis -1.2, not a normal's 0) and no draw of the next stage leaves the first prior's
    box. (Other steps taking the posterior get its normals or its joint draws.)

    Parameters
    ----------
    res : StepResult
        A saved ``bayes_calibration`` step with its ``chain`` (N, d) and ``prior``.

    Returns
    -------
    dict of str to Distribution
        Parameter name -> the density of its chain (a
        :class:`~rotoruq.params.HistogramBin` of 256 bins), in the order of the chain's
        columns.

    Examples
    --------
    >>> import numpy as np
    >>> from rotoruq.params import Uniform
    >>> from rotoruq.results import StepResult, dist_to_dict
    >>> chain = np.random.default_rng(0).uniform(0.0, 1.0, (4000, 1))
    >>> res = StepResult("s1", "bayes_calibration", {}, {"chain": chain}, {}, meta={
    ...     "columns": {"chain": ["a"]}, "prior": {"a": dist_to_dict(Uniform(0.0, 1.0))}})
    >>> sequential_prior(res)["a"].bounds
    (0.0, 1.0)
    """
    prior = res.meta.get("prior") or {}
    out: dict[str, Distribution] = {}
    for name in res.columns("chain"):
        support = dict_to_dist(prior[name]).bounds if name in prior else (-np.inf, np.inf)
        out[name] = kernel_density(res.column("chain", name), support)
    return out


def read_posterior(res: StepResult) -> BayesRecord:
    """The posterior summary of a Bayes step as a :class:`BayesRecord`, what its tables,
    warnings and the reference study's reasons read; a step calibrated with a discrepancy
    gives what its :class:`~rotoruq.steps._discrepancy.DiscrepancyRecord` holds of it (the
    rest NaN). :class:`~rotoruq.results.RecordError` for a step saved without its record."""
    if is_discrepancy(res):
        rec = DiscrepancyRecord.read(res)
        d = len(rec.names_in)
        added = {k: v for k, v in (
            ("map_point", rec.map_point), ("std_ratio", rec.std_ratio),
            ("prior_z", rec.prior_z), ("pileup_lo", rec.pileup_lo),
            ("pileup_hi", rec.pileup_hi), ("correlation", rec.correlation))
            if np.size(v)}  # an older record saved none of these
        return BayesRecord.partial(
            rec.names_in, rec.names_out, n_chains=int(rec.chains.shape[0]),
            n_draws=int(rec.chains.shape[1]), mean=rec.mean, std=rec.std,
            ess=rec.ess[:d], rhat=rec.rhat[:d], noise_std=rec.noise_std,
            noise_model=rec.noise_model, acceptance=(
                math.nan if rec.acceptance_rate is None else rec.acceptance_rate), **added)
    return BayesRecord.read(res).completed()


def posterior_record(res: StepResult) -> BayesRecord | None:
    """:func:`read_posterior`, None for a step saved without its record (its warnings and
    the reasons that read it have nothing to say)."""
    try:
        return read_posterior(res)
    except RecordError:
        return None


def bayes_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    rec = read_posterior(res)
    names, resp = rec.names_in, rec.names_out
    prior = res.input_distributions()

    def prior_moment(p: str, what: str) -> float | None:
        return float(getattr(prior[p], what)) if p in prior else None

    rows = [[label(p, labels), prior_moment(p, "mean"), prior_moment(p, "std"),
             *[cell(getattr(rec, f)[j]) for f in ("mean", "std", "skewness", "kurtosis",
                                                   "std_ratio", "pileup_lo", "pileup_hi")]]
            for j, p in enumerate(names)]
    out = [make_table("Prior and posterior", (
        "parameter", "prior mean", "prior std", "posterior mean", "posterior std", "skewness",
        "excess kurtosis", "post/prior std", "outer 5 % low", "outer 5 % high"), rows,
        "post/prior std near 1: the data do not inform the parameter; outer 5 %: "
        "fraction of the chain in the outer 5 % of a bounded prior's range (0.05 when "
        "flat).")]
    n_chains = rec.n_chains
    out.append(make_table(f"Convergence ({n_chains} chain{'s' if n_chains > 1 else ''})", (
        "parameter", "R-hat", "R-hat bulk", "R-hat folded", "ESS bulk", "ESS tail",
        "MCSE of the mean"),
        [[label(p, labels), *[cell(getattr(rec, f)[j]) for f in (
            "rhat", "rhat_bulk", "rhat_folded", "ess", "ess_tail", "mcse_mean")]]
         for j, p in enumerate(names)],
        f"Rank-normalised split R-hat (bulk and folded; R-hat is the larger, above "
        f"{RHAT_MAX} the chains have not mixed), bulk and tail effective sample sizes and the "
        "Monte Carlo standard error of the posterior mean (Vehtari et al. 2021, arviz's "
        "definitions)."))
    rows_noise: list[list[Any]] = [
        ["acceptance rate", cell(rec.acceptance)],
        ["KL divergence posterior || prior [nats]", cell(rec.kl_divergence)],
        *[[f"noise std of {r}", cell(rec.noise_std[k])] for k, r in enumerate(resp)]]
    for k, r in enumerate(resp):
        if np.isfinite(rec.posterior_ratio[k]):
            rows_noise += [[f"emulator std / noise std over the posterior, {r}",
                            float(rec.posterior_ratio[k])],
                           [f"emulator leave-one-out RMSE / noise std, {r}",
                            cell(rec.loo_ratio[k])]]
        if np.isfinite(rec.loo_q2[k]):
            rows_noise.append([f"emulator leave-one-out Q2 of {r}", float(rec.loo_q2[k])])
    if np.isfinite(rec.posterior_ratio).any():  # an emulator whose adequacy was measured
        rows_noise.append(["model runs added by refinement", float(sum(rec.runs_added))])
    for n, runs in zip(rec.low_fidelity_models, rec.low_fidelity_runs, strict=True):
        rows_noise.append([f"co-kriging: runs of the low-fidelity model {n}", float(runs)])
    for a, level in enumerate(rec.cokriging_levels):
        for k, r in enumerate(resp):
            rows_noise.append([f"co-kriging: scale rho of {level} on the level below, {r}",
                               float(rec.cokriging_rho[a, k])])
    out.append(make_table("Noise model and emulator adequacy", ("quantity", "value"),
                          rows_noise,
                          f"Noise model: {rec.noise_model or 'not recorded'}. The "
                          "emulator is adequate when its error over the posterior is a small "
                          f"fraction of the noise (warned above {POSTERIOR_RATIO_MAX})."))
    if rec.multiplier_names:
        out.append(make_table("Noise variance multipliers (posterior)", (
            "multiplier", "mean", "std", "2.5 %", "97.5 %"),
            [[n, *[float(getattr(rec, f"multiplier_{f}")[i])
                   for f in ("mean", "std", "lower", "upper")]]
             for i, n in enumerate(rec.multiplier_names)],
            "Each multiplies the stated noise variance of its observations; 1: the stated "
            "noise is right."))
    if rec.self_check_passed is not None:
        verdict = "passed" if rec.self_check_passed else "FAILED"
        out.append(make_table(f"Self-check (simulation-based calibration): {verdict}", (
            "parameter", "rank uniformity p-value", "50 % coverage", "90 % coverage"),
            [[label(p, labels), *[cell(getattr(rec, f"sbc_{f}")[j])
                                  for f in ("p_value", "coverage_50", "coverage_90")]]
             for j, p in enumerate(names)],
            "Parameters drawn from the prior, data simulated with the stated noise, "
            "calibrated the same way (Talts et al. 2018): uniform ranks and nominal "
            f"coverages mean the posterior is calibrated. {rec.self_check_reason}"))
    if len(names) > 1:
        mat = [[label(p, labels)] + [1.0 if i == j else cell(
            rec.correlation[min(i, j), max(i, j)]) for j in range(len(names))]
            for i, p in enumerate(names)]
        out.append(make_table("Posterior correlation",
                              ("", *[label(q, labels) for q in names]), mat))
    return out


def bayes_figures(res: StepResult, ctx: FigureContext) -> list[Figure]:
    """Prior/posterior densities, chain traces and a pair plot of a Bayes step's chain. When the
    report's application names the sampling step whose input distributions generated the
    (synthetic) data of this calibration (``ctx.beside["truth"]``, e.g. the reference study's
    ``truth`` step), those data-generating densities are drawn beside the posterior."""
    if "chain" not in res.arrays:
        return []
    truth = None
    source = beside_truth(ctx, res.name)
    if source is not None and source in ctx.steps:
        truth = ctx.steps[source].input_distributions()
    figs = prior_posterior(res, ctx.labels, ctx.units, truth or None)
    figs += chain_traces(res, ctx.labels, ctx.units)
    if len(res.columns("chain")) > 1:
        figs += pair_plot(res, ctx.labels, ctx.units)
    return figs



def strong_correlations(res: StepResult, labels: Mapping[str, str] | None = None,
                        limit: float = CORR_MAX) -> list[tuple[str, str, float]]:
    """Posterior correlations with |rho| > ``limit``: (label p, label q, rho), strongest
    first (none for a step saved without its record)."""
    rec = posterior_record(res)
    if rec is None:
        return []
    labels = labels or {}
    names = rec.names_in
    out = [(label(p, labels), label(names[j], labels), float(rec.correlation[i, j]))
           for i, p in enumerate(names) for j in range(i + 1, len(names))
           if abs(rec.correlation[i, j]) > limit]
    return sorted(out, key=lambda t: -abs(t[2]))


def bayes_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    """MCMC mixing, emulator quality, prior-bound pile-up, identifiability, noise model
    (none for a step saved without its record)."""
    rec = posterior_record(res)
    if rec is None:
        return []
    w: list[str] = []
    name = res.name

    def listed(values, bad, fmt, names=rec.names_in):
        return ", ".join(f"{label(p, labels)} ({fmt(v)})"
                         for p, v in zip(names, map(float, values), strict=True) if bad(v))

    if low := listed(rec.ess, lambda v: v < ESS_MIN, lambda v: f"{v:.0f}"):
        w.append(f"{name}: low bulk effective sample size (below {ESS_MIN:.0f}): {low}")
    if low := listed(rec.ess_tail, lambda v: v < ESS_MIN, lambda v: f"{v:.0f}"):
        w.append(f"{name}: low tail effective sample size (below {ESS_MIN:.0f}): the "
                 f"credible intervals are noisy: {low}")
    if high := listed(rec.rhat, lambda v: v > RHAT_MAX, lambda v: f"{v:.3f}"):
        w.append(f"{name}: chains not mixed (rank-normalised R-hat above {RHAT_MAX}): {high}")
    if poor := listed(rec.posterior_ratio, lambda v: v > POSTERIOR_RATIO_MAX,
                      lambda v: f"{v:.2f}", rec.names_out):
        w.append(f"{name}: emulator error over the posterior above {POSTERIOR_RATIO_MAX} of "
                 f"the noise std: {poor}; add n_emulator_samples or refine = {{...}}")
    if rec.self_check_passed is False:
        w.append(f"{name}: {SELF_CHECK_FAILED}: the posterior is not calibrated: "
                 f"{rec.self_check_reason}")
    for word, pile in (("lower", rec.pileup_lo), ("upper", rec.pileup_hi)):
        for p, f in zip(rec.names_in, map(float, pile), strict=True):
            if f > PILEUP_MAX:
                w.append(f"{name}: {label(p, labels)} piles up against its prior's {word} "
                         f"bound ({100 * f:.0f} % of the chain in the outer 5 % of the "
                         "range)")
    if weak := listed(rec.std_ratio, lambda v: v > STD_RATIO_MAX, lambda v: f"{v:.2f}"):
        w.append(f"{name}: not identifiable from these data (posterior std / prior std "
                 f"above {STD_RATIO_MAX}): {weak}")
    if far := listed(rec.prior_z, lambda v: abs(v) > PRIOR_Z_MAX, lambda v: f"{v:+.1f}"):
        w.append(f"{name}: the posterior left the prior's bulk (prior std devs from the "
                 f"prior mean): {far}")
    for msg in res.meta.get("warnings", []) or []:
        w.append(f"{name}: {msg}")
    if rec.noise_model.startswith("unit"):
        w.append(f"{name}: no noise model given: unit data variance for every response")
    if "emulator's mean only" in rec.noise_model:
        w.append(f"{name}: the emulator's own error is not in the likelihood "
                 "(emulator_variance = false)")
    if res.meta.get("reuse_data"):
        w.append(f"{name}: calibrates data an earlier step calibrated too (reuse_data = "
                 "true): the data count twice and the posterior is too narrow")
    return w


_REFINE_KEYS = {"n_samples": integer(1), "target_ratio": number(positive=True,
                                                                    allow_zero=False),
                "batch": integer(1)}


def _refine(v: Any) -> dict | None:
    """``refine = { n_samples, target_ratio, batch }`` (each optional)."""
    v = table(v)
    for k, x in v.items():
        if k not in _REFINE_KEYS:
            raise TypeError(f"a table with keys among {', '.join(_REFINE_KEYS)} (found {k!r})")
        try:
            _REFINE_KEYS[k](x)
        except TypeError as exc:
            raise TypeError(f"refine.{k}: {exc}") from None
    return v


def _multipliers(v: Any) -> str | tuple[str, ...]:
    """``"one"``, ``"per_response"``, ``"per_experiment"`` or a list of responses."""
    if isinstance(v, str):
        return choice("one", "per_response", "per_experiment")(v)
    try:
        return string_list(v)
    except TypeError:
        raise TypeError('"one", "per_response", "per_experiment" or a list of responses'
                        ) from None


def _prior_pair(v: Any) -> tuple[float, float]:
    vals = number_list(v) if isinstance(v, list) else ()
    if len(vals) != 2 or min(vals) <= 0:
        raise TypeError("[alpha, beta], two numbers > 0 (inverse-gamma prior)")
    return (vals[0], vals[1])


def _check_bayes(c: StepCheck) -> None:
    """Noise std > 0 for every response; multipliers only on calibrated responses and with a
    stated noise std; a self-check only with a noise std per response and no multipliers."""
    o = c.options
    responses = c.responses or tuple(c.model.responses)
    sd = o["noise_std"]
    if isinstance(sd, Mapping):
        for r, v in sd.items():
            if v <= 0:
                c.fail(("noise_std", r), "a noise std > 0 (data units)", repr(v))
        missing = [r for r in responses if r not in sd]
        if missing:
            c.fail(("noise_std",), f"a noise std for every calibrated response "
                   f"({', '.join(responses)}); missing {', '.join(missing)}")
    elif sd is not None and sd <= 0:
        c.fail(("noise_std",), "a noise std > 0 (data units)", repr(sd))
    mult = o["noise_multipliers"]
    if mult is not None:
        if sd is None:
            c.fail(("noise_multipliers",), "noise_std given with noise_multipliers (each "
                   "multiplies a stated noise variance)")
        if not isinstance(mult, str):
            for r in mult:
                if r not in responses:
                    c.fail(("noise_multipliers",), "responses this step calibrates, with data "
                           f"({', '.join(responses)})", r)
    elif tuple(o["noise_multiplier_prior"]) != tuple(STEP.default("noise_multiplier_prior")):
        c.fail(("noise_multiplier_prior",), "noise_multipliers = ... with it (a prior of "
               "multipliers that are not calibrated)")
    if o["self_check"]:
        if sd is None:
            c.fail(("self_check",), "noise_std per response with self_check (the "
                   "replications simulate data with it)")
        if mult is not None:
            c.fail(("self_check",), "self_check without noise_multipliers (the replications "
                   "cannot simulate data with a calibrated noise)")
    if o["refine"] is not None and o["emulator"] == "none":
        c.fail(("refine",), 'emulator = "gp" with refine (it refines the emulator)')
    if o["emulator"] == "cokriging":
        if not o.get("models"):
            c.fail(("emulator",), 'models = ["NAME", ...] with emulator = "cokriging" (the '
                   "low-fidelity [models.NAME] the co-kriging emulator learns from, cheapest "
                   "first)", "no models")
        n_low, n_hf = o.get("n_low"), o["n_emulator_samples"]
        if n_low is not None and n_low < n_hf:
            c.fail(("n_low",), f"at least n_emulator_samples ({n_hf}): the low-fidelity "
                   "design contains the high-fidelity one", str(n_low))
    else:
        for key, why in (("models", "low-fidelity models"), ("n_low", "a low-fidelity design")):
            if o.get(key) is not None:
                c.fail((key,), f'emulator = "cokriging" with {key} ({why} are for '
                       "co-kriging)", f'emulator = "{o["emulator"]}"')


def _check(c: StepCheck) -> None:
    _check_bayes(c)
    check_discrepancy(c)


def _tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    """The chain's tables, and with a discrepancy its identifiability and predictions."""
    return bayes_tables(res, labels) + (discrepancy_tables(res, labels)
                                        if is_discrepancy(res) else [])


def _warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    return bayes_warnings(res, labels) + (discrepancy_warnings(res, labels)
                                          if is_discrepancy(res) else [])


# the option records of calibrate_bayes whose fields give the SIGNATURE defaults
_CHAINS = "rotoruq.methods.mcmc.options:ChainOptions"
_EMULATOR = "rotoruq.methods.mcmc.options:EmulatorOptions"
_NOISE = "rotoruq.methods.mcmc.options:NoiseModel"

STEP = StepType(
    "bayes_calibration", run_bayes_calibration, check=_check,
    method="rotoruq.methods.mcmc:calibrate_bayes", provides=("posterior",), needs_data=True,
    options={"sampler": Option(choice("dram", "mh", "dr", "am"), SIGNATURE, method=_CHAINS),
             "n_samples": Option(integer(10), SIGNATURE, method=_CHAINS),
             "burn_in": Option(integer(0), SIGNATURE, method=_CHAINS),
             "n_chains": Option(integer(1), 4),
             "emulator": Option(choice("gp", "cokriging", "none"), "gp"),
             "models": Option(string_list, None),
             "n_low": Option(integer(3), None),
             "trend": Option(choice("constant", "linear", "reduced_quadratic", "quadratic"),
                             SIGNATURE, method="rotoruq.methods.surrogate:GaussianProcess"),
             "n_emulator_samples": Option(integer(2), SIGNATURE, method=_EMULATOR),
             "emulator_variance": Option(boolean, SIGNATURE, method=_EMULATOR),
             "refine": Option(_refine, None),
             "noise_std": Option(number_or_table, None),
             "noise_multipliers": Option(_multipliers, None),
             "noise_multiplier_prior": Option(_prior_pair, SIGNATURE, method=_NOISE),
             "self_check": Option(integer(0), SIGNATURE),
             "reuse_data": Option(boolean, False),
             "proposal": Option(choice("hessian", "prior"), SIGNATURE, method=_CHAINS,
                                param="proposal_covariance"),
             "discrepancy": Option(discrepancy_option, None),
             "configuration": Option(string(), None),
             "predict_at": Option(number_list, None),
             "couple": Option(table, None)},
    quick={"n_samples": 1800, "burn_in": 200, "n_emulator_samples": 60, "self_check": 20},
    tables=_tables, figures=bayes_figures, warnings=_warnings)
