"""Bayesian calibration with Markov chains, thesis sections 2.4.1-2.4.2 and the appendix.

:func:`calibrate_bayes` samples ``p(theta | d) ~ pi(theta) L(theta)`` with a Gaussian likelihood
(eqs. 2.22-2.24), priors from a :class:`~rotoruq.params.ParameterSpace`, a MAP pre-solve as the
chain start, an initial proposal covariance from the Gauss-Newton Hessian of the misfit plus the
prior (eqs. 2.25-2.27) and the MH / DR / AM / DRAM samplers of :mod:`.samplers`. With
``emulator=GaussianProcess(...)`` the model is replaced by a Kriging surrogate fitted on an LHS
design drawn from the prior (the reference study's workflow: 500 rotor runs, 100,000 samples);
with ``emulator=CoKriging(low_fidelity=..., n_low=...)`` by a multi-fidelity one that learns the
model from its runs and many runs of cheaper models (:mod:`rotoruq.methods.cokriging`).
"""

from __future__ import annotations

import copy
import csv
import dataclasses
import logging
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import ArrayLike
from scipy import optimize

from ..._rng import SeedLike, as_generator
from ...errors import EvaluationError, ModelShapeError, ParameterError
from ...model import (
    FD_STEP,
    Model,
    align_inputs,
    evaluate,
    finite_difference,
    has_gradient,
    model_gradient,
)
from ...params import ParameterSpace
from ..cokriging import CoKriging
from ..surrogate import ExtrapolationWarning, GaussianProcess, LeaveOneOut
from . import diagnostics as dg
from ._emulator import Emulator, fit_on_prior
from ._kernels import (
    add_loglik_rows,
    add_loglik_var_rows,
    emulator_logpost_rows,
    scaled_logprior_rows,
)
from .adequacy import (
    WARN_RATIO,
    EmulatorAdequacy,
    RefineConfig,
    check_draws,
    noise_std_of_mean,
    pick_runs,
    posterior_ratio,
)
from .likelihood import GaussianLikelihood
from .noise import extended_prior, multiplier_groups, noise_loglik
from .options import (
    LEGACY_KEYWORDS,
    ChainOptions,
    EmulatorOptions,
    NoiseModel,
    legacy_keywords,
    with_fields,
)
from .proposals import LogPrior, hessian_covariance, prior_scales
from .samplers import SamplerConfig, SamplerState, run_chains

if TYPE_CHECKING:
    from .sbc import SBCResult

__all__ = ["calibrate_bayes", "continue_chain", "BayesResult", "SelfCheckCache"]

log = logging.getLogger(__name__)


class SelfCheckCache(Protocol):
    """Where :func:`calibrate_bayes` keeps self-checks by the identity of their setup (a
    dict will do): each as (result, the warnings its replications raised, as
    ``("module:qualname", message)`` pairs, raised again when it is reused)."""

    def get(self, key: str, /) -> tuple[SBCResult, tuple[tuple[str, str], ...]] | None: ...

    def __setitem__(self, key: str, value: tuple[SBCResult, tuple[tuple[str, str], ...]],
                    /) -> None: ...


# Random stages of a calibration, each with its own child of the call's SeedSequence (spawn
# key = position here): appending a stage never shifts the numbers of another.
#: Seconds per model evaluation above which chains on the model itself (no emulator) use the
#: ``minimal`` evaluation schedule when the sampler is given by name: the chains are the same
#: (a function of the seed alone), only the number of model runs differs (speculative
#: lookahead spends ~2.4x the runs to save calls, right for the compiled rotor, wrong for a
#: solver that runs seconds a point).
SLOW_EVALUATION = 0.01

_STAGES = ("design", "emulator_fit", "start", "chain_starts", "chains", "predictive",
           "summary", "refine", "self_check")


def _stage_seeds(seed: SeedLike) -> dict[str, np.random.SeedSequence]:
    """One SeedSequence per random stage of :func:`calibrate_bayes`, spawned from ``seed``.

    The children are built as ``SeedSequence.spawn`` builds them, without spawning from a
    SeedSequence the caller passed (which would change its state and so the caller's next
    call). A Generator is read once (4 draws) for the root entropy.
    """
    as_generator(seed if not isinstance(seed, np.random.SeedSequence) else None)  # validate
    if isinstance(seed, np.random.Generator):
        root = np.random.SeedSequence(seed.integers(2**63, size=4))
    elif isinstance(seed, np.random.SeedSequence):
        root = seed
    else:
        root = np.random.SeedSequence(None if seed is None else int(seed))
    return {name: _child(root, i) for i, name in enumerate(_STAGES)}


class _Posterior:
    """Batched log posterior in scaled coordinates, counting what it evaluates.

    With a GaussianProcess emulator and a prior of uniform / normal marginals the whole log
    posterior is compiled (:func:`._kernels.emulator_logpost`): ``compiled`` then holds its
    arrays and counters for :func:`run_chains`, and this object evaluates through the same
    kernel. A CoKriging takes the Python route with its levels' compiled GPs.
    """

    def __init__(self, forward, loglik: GaussianLikelihood, logprior: LogPrior,
                 center: np.ndarray, scale: np.ndarray, gp: Emulator | None,
                 emulator_variance: bool = False, noise: _Problem | None = None):
        self.forward, self.loglik, self.logprior = forward, loglik, logprior
        self.center = np.ascontiguousarray(center, dtype=float)
        self.scale = np.ascontiguousarray(scale, dtype=float)
        self.gp = gp
        self.emulator_variance = bool(emulator_variance and gp is not None)
        # evaluations, outside the support, NaN likelihoods, extrapolations, largest extrapolation
        self.cnt = np.zeros(5)
        self.compiled = None
        self.noise = noise  # noise multipliers: the Python route below
        if isinstance(gp, GaussianProcess) and logprior.compiled and noise is None:
            cg = gp.compiled(variance=self.emulator_variance)
            self.compiled = ((self.center, self.scale, logprior.pack, cg.mean_pack, loglik.pack,
                              cg.var_pack, self.emulator_variance), self.cnt)
        if gp is not None:
            box = gp.bounds
            w = box[:, 1] - box[:, 0]
            self._far_lo, self._far_hi = box[:, 0] - 0.1 * w, box[:, 1] + 0.1 * w

    n_evals = property(lambda self: int(self.cnt[0]))
    n_outside = property(lambda self: int(self.cnt[1]))
    n_nan = property(lambda self: int(self.cnt[2]))
    n_extrapolated = property(lambda self: int(self.cnt[3]))
    max_extrapolation = property(lambda self: float(self.cnt[4]))

    def reset_counts(self) -> None:
        self.cnt[:3] = 0.0

    def __call__(self, z: np.ndarray) -> np.ndarray:
        z = np.ascontiguousarray(z, dtype=float)
        if self.compiled is not None:
            out = np.empty(z.shape[0])
            emulator_logpost_rows(z, self.compiled[0], self.cnt, out)
            return out
        n = z.shape[0]
        theta = np.empty_like(z)
        lp = np.empty(n)
        scaled_logprior_rows(z, self.center, self.scale, self.logprior.pack, theta, lp)
        if not self.logprior.compiled:
            lp = self.logprior(theta)
        ok = lp > -np.inf
        nok = int(np.count_nonzero(ok))
        q = np.empty((0, 0))
        if nok and self.noise is not None:
            return self._with_multipliers(theta, ok, lp)
        if nok:
            th = theta if nok == n else theta[ok]
            if self.gp is not None and ((th < self._far_lo) | (th > self._far_hi)).any():
                dist = self.gp.extrapolation_distance(th)
                self.cnt[3] += int((dist > 0.1).sum())
                self.cnt[4] = max(self.cnt[4], float(dist.max()))
            if self.emulator_variance:
                assert self.gp is not None
                q, v = self.gp._mean_var_fast(th)
                add_loglik_var_rows(q, v, self.loglik.pack, lp, self.cnt)
                return lp
            q = np.ascontiguousarray(self.forward(th), dtype=float)
        add_loglik_rows(q, self.loglik.pack, lp, self.cnt)
        return lp

    def _with_multipliers(self, theta: np.ndarray, ok: np.ndarray, lp: np.ndarray) -> np.ndarray:
        """lp (k,) plus the likelihood with noise multipliers at the points ``ok`` of theta
        (model parameters, then precision multipliers)."""
        pb = self.noise
        assert pb is not None and pb.groups is not None and pb.noise_var is not None
        d = pb.n_theta
        th = theta[ok]
        x = np.ascontiguousarray(th[:, :d])
        v = None
        if self.gp is not None:
            if ((x < self._far_lo) | (x > self._far_hi)).any():
                dist = self.gp.extrapolation_distance(x)
                self.cnt[3] += int((dist > 0.1).sum())
                self.cnt[4] = max(self.cnt[4], float(dist.max()))
            if self.emulator_variance:
                q, v = self.gp._mean_var_fast(x)
            else:
                q = self.gp._mean_fast(x)
        else:
            q = np.asarray(self.forward(x), dtype=float)
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            ll = noise_loglik(q, v, th[:, d:], pb.lik.data, pb.noise_var, pb.groups)
        bad = ~np.isfinite(ll)
        self.cnt[0] += th.shape[0]
        self.cnt[1] += int((~ok).sum())
        self.cnt[2] += int(bad.sum())
        out = lp.copy()
        out[ok] = np.where(bad, -np.inf, lp[ok] + ll)
        return out


@dataclass(frozen=True, eq=False)
class BayesResult(dg.PooledChains):
    """Posterior samples and their summary (the result of :func:`calibrate_bayes`).

    The parameters' fields (``chains``, ``mean``, ...) hold the model parameters only; the
    noise multipliers, when calibrated, have fields of their own; ``kl_divergence`` covers
    both.

    Attributes
    ----------
    names_in : tuple of str
        The d parameter names (columns of ``chains``).
    chains : ndarray of shape (n_chains, n_samples, d)
        Kept samples (after burn-in and thinning), parameter units.
    log_posterior : ndarray of shape (n_chains, n_samples)
        Log posterior density (up to a constant) of each kept sample.
    mean, std : ndarray of shape (d,)
        Posterior mean and standard deviation, parameter units.
    skewness, kurtosis : ndarray of shape (d,)
        Posterior skewness and excess kurtosis (0 for a normal).
    correlation : ndarray of shape (d, d)
        Posterior correlation matrix.
    credible_interval_95 : ndarray of shape (d, 2)
        Equal-tailed 2.5 % / 97.5 % quantiles.
    ess : ndarray of shape (d,)
        Bulk effective sample size (rank-normalised, arviz's standard).
    rhat : ndarray of shape (d,)
        The larger of the rank-normalised split R-hat and its folded form.
    acceptance_rate : float
        Fraction of steps that moved.
    acceptance_per_stage : tuple of float
        (stage 1, stage 2) acceptance of each delayed-rejection stage among the proposals
        made at that stage.
    kl_divergence : float
        KL(posterior || prior) in nats, posterior entropy by the Kozachenko-Leonenko kNN
        estimator.
    kl_divergence_gaussian : float
        The same with a Gaussian posterior entropy.
    map_point : ndarray of shape (d,)
        Chain start from the MAP pre-solve, parameter units.
    proposal_covariance : ndarray of shape (d, d)
        Initial stage-1 proposal covariance, parameter units.
    sampler : str
        The MCMC algorithm (``"dram"``, ``"am"``, ``"dr"``, ``"mh"``).
    burn_in : int
        Steps dropped at the start of each chain.
    thin : int
        Every ``thin``-th step was kept after the burn-in.
    n_likelihood_evaluations : int
        Likelihood evaluations (points) by the chains, speculative ones included (see
        :class:`SamplerConfig` ``evaluations``).
    n_evaluations : int
        True model evaluations (emulator build, MAP and gradients without emulator,
        predictive); with a CoKriging emulator, the calibrated (high-fidelity) model's runs
        only.
    n_nan_likelihood : int
        Proposals rejected because the likelihood was NaN/inf (failed model).
    n_out_of_support : int
        Proposals rejected outside the prior support (not evaluated).
    sampling_seconds : float
        Wall time of the chains, s.
    emulator : GaussianProcess, CoKriging or None
        The fitted emulator (None without one).
    sampling_cpu_seconds : float
        CPU time of the chains, s (what the chains cost on a machine shared with other
        jobs).
    emulator_loo : LeaveOneOut or None
        The emulator's leave-one-out quality (a CoKriging's at its high-fidelity runs,
        :meth:`CoKriging.loo`); None without an emulator.
    predictive_inputs : ndarray of shape (k, d) or None
        Posterior draws pushed through the true model (None unless
        ``posterior_predictive`` > 0).
    predictive : ndarray of shape (k, m) or None
        The true model's responses at ``predictive_inputs``.
    names_out : tuple of str
        The model's responses (columns of ``predictive``).
    emulator_adequacy : EmulatorAdequacy or None
        The emulator's error against the noise over the build design and the posterior, and
        the runs added by refinement.
    noise_multiplier_names : tuple of str
        With ``noise_multipliers``, the k multipliers of the noise variance.
    noise_multiplier_chains : ndarray of shape (n_chains, n_samples, k) or None
        Their chains; their moments by :meth:`noise_multiplier_summary`.
    diagnostics : ChainDiagnostics or None
        Convergence diagnostics of the parameters' chains to arviz's standard
        (rank-normalised split R-hat and its folded form, bulk and tail ESS, MCSE of the mean
        and of the 5 % / 95 % quantiles in parameter units).
    self_check : SBCResult or None
        With ``self_check=N``, the simulation-based calibration of this setup
        (:class:`~rotoruq.methods.mcmc.sbc.SBCResult`): does the method recover parameters
        drawn from the prior from data simulated with the stated noise?
    evaluations : str
        The chains' evaluation schedule, ``"speculative"`` or ``"minimal"`` (chosen
        automatically for a model slower than :data:`SLOW_EVALUATION` s a point when the
        sampler is given by name; the chains are the same, only the model runs differ).
    n_low_fidelity_evaluations : tuple of int
        With a CoKriging emulator, runs of each low-fidelity model (cheapest first; build
        and refinement).
    """

    names_in: tuple[str, ...]
    chains: np.ndarray
    log_posterior: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    skewness: np.ndarray
    kurtosis: np.ndarray
    correlation: np.ndarray
    credible_interval_95: np.ndarray
    ess: np.ndarray
    rhat: np.ndarray
    acceptance_rate: float
    acceptance_per_stage: tuple[float, ...]
    kl_divergence: float
    kl_divergence_gaussian: float
    map_point: np.ndarray
    proposal_covariance: np.ndarray
    sampler: str
    burn_in: int
    thin: int
    n_likelihood_evaluations: int
    n_evaluations: int
    n_nan_likelihood: int
    n_out_of_support: int
    sampling_seconds: float
    emulator: Emulator | None = None
    sampling_cpu_seconds: float = 0.0
    emulator_loo: LeaveOneOut | None = None
    predictive_inputs: np.ndarray | None = None
    predictive: np.ndarray | None = None
    names_out: tuple[str, ...] = ()
    emulator_adequacy: EmulatorAdequacy | None = None
    noise_multiplier_names: tuple[str, ...] = ()
    noise_multiplier_chains: np.ndarray | None = None
    diagnostics: dg.ChainDiagnostics | None = None
    self_check: SBCResult | None = None
    evaluations: str = "speculative"
    n_low_fidelity_evaluations: tuple[int, ...] = ()
    _state: tuple | None = field(default=None, repr=False, compare=False)

    def to_netcdf(self, path: str | Path) -> Path:
        """Write the chains for arviz: ``*.nc`` as an ``InferenceData``-compatible netCDF
        (``posterior`` group, dims chain and draw, one variable per parameter;
        ``sample_stats/lp``), any other suffix as the documented npz of
        :func:`rotoruq.methods.mcmc.export.write_chains`.

        Parameters
        ----------
        path : str or Path
            The file to write.

        Returns
        -------
        Path
            The written file.

        Examples
        --------
        >>> import arviz as az                                  # doctest: +SKIP
        >>> idata = az.from_netcdf(result.to_netcdf("chains.nc"))  # doctest: +SKIP
        """
        from .export import write_chains

        return write_chains(path, self.chains, self.names_in, self.log_posterior,
                            attrs={"sampler": self.sampler})

    def noise_multiplier_summary(self, level: float = 0.95) -> dict[str, tuple[float, ...]]:
        """Posterior mean, std and equal-tailed ``level`` interval of each noise variance
        multiplier: name -> (mean, std, lower, upper).

        Parameters
        ----------
        level : float, optional
            Probability content of the interval, in (0, 1) (default 0.95).
        """
        if self.noise_multiplier_chains is None:
            raise ParameterError("no noise multipliers were calibrated (noise_multipliers=)")
        flat = self.noise_multiplier_chains.reshape(-1, len(self.noise_multiplier_names))
        a = 0.5 * (1.0 - level)
        q = np.quantile(flat, [a, 1.0 - a], axis=0)
        return {n: (float(flat[:, j].mean()), float(flat[:, j].std()), float(q[0, j]),
                    float(q[1, j])) for j, n in enumerate(self.noise_multiplier_names)}

    @property
    def ess_per_second(self) -> np.ndarray:
        """Effective samples per second of sampling (wall time), shape (d,)."""
        return self.ess / max(self.sampling_seconds, 1e-12)

    def summary(self) -> str:
        """A plain-text table of the posterior moments and diagnostics."""
        head = f"{'parameter':<16}{'mean':>12}{'std':>12}{'skew':>10}{'kurt':>10}{'ess':>10}" \
               f"{'rhat':>8}"
        rows = [head]
        for j, n in enumerate(self.names_in):
            rows.append(f"{n:<16}{self.mean[j]:>12.5g}{self.std[j]:>12.4g}"
                        f"{self.skewness[j]:>10.3g}{self.kurtosis[j]:>10.3g}{self.ess[j]:>10.0f}"
                        f"{self.rhat[j]:>8.3f}")
        stages = ", ".join(f"{a:.3f}" for a in self.acceptance_per_stage)
        rows.append(f"sampler {self.sampler}, acceptance {self.acceptance_rate:.3f} (stages: "
                    f"{stages}), KL(prior->post) {self.kl_divergence:.3f} nats, "
                    f"{self.n_nan_likelihood} NaN likelihoods")
        return "\n".join(rows)

    def save(self, path: str | Path) -> Path:
        """Write the chains: ``*.csv`` as a table (chain, step, parameters, log posterior),
        anything else as a NumPy ``.npz`` archive with the chains and the summary arrays (and
        the noise multipliers' chains and the emulator's adequacy when there are any).

        Parameters
        ----------
        path : str or Path
            The file to write (a suffix other than ``.csv`` and ``.npz`` becomes ``.npz``).

        Returns
        -------
        Path
            The written file.
        """
        path = Path(path)
        if path.suffix.lower() == ".csv":
            c, n, d = self.chains.shape
            with open(path, "w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(["chain", "step", *self.names_in, "log_posterior"])
                for k in range(c):
                    for i in range(n):
                        w.writerow([k, i, *(f"{v:.17g}" for v in self.chains[k, i]),
                                    f"{self.log_posterior[k, i]:.17g}"])
            return path
        if path.suffix.lower() != ".npz":
            path = path.with_suffix(".npz")
        arrays = {k: getattr(self, k) for k in (
            "chains", "log_posterior", "mean", "std", "skewness", "kurtosis", "correlation",
            "credible_interval_95", "ess", "rhat", "map_point", "proposal_covariance")}
        if self.noise_multiplier_chains is not None:
            arrays["noise_multiplier_chains"] = self.noise_multiplier_chains
            arrays["noise_multiplier_names"] = np.array(self.noise_multiplier_names)
        if self.emulator_adequacy is not None:
            ad = self.emulator_adequacy
            arrays.update(emulator_noise_std=ad.noise_std, emulator_loo_ratio=ad.loo_ratio,
                          emulator_posterior_ratio=ad.posterior_ratio,
                          emulator_runs_added=np.array(ad.runs_added, dtype=int))
        np.savez(path, names_in=np.array(self.names_in), sampler=self.sampler,
                 acceptance_rate=self.acceptance_rate, kl_divergence=self.kl_divergence,
                 **arrays)
        return path


def _summarize(names, chains_z, lp, post: _Posterior, state: SamplerState, base: dict,
               seed) -> BayesResult:
    theta = post.center + post.scale * chains_z  # (c, n, d)
    flat = theta.reshape(-1, theta.shape[-1])
    if flat.shape[0] < 2:
        raise ParameterError("fewer than 2 samples kept: increase n_samples")
    mean, std, skew, kurt = dg.moments(flat)
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = np.atleast_2d(np.corrcoef(flat, rowvar=False))
    ess, rhat = dg.ess_and_rhat(chains_z)
    # entropy on a near-independent subsample (spacing ~ integrated autocorrelation time)
    rng = as_generator(seed)
    n_sub = int(min(4000, max(50, np.min(ess)), flat.shape[0]))
    idx = rng.choice(flat.shape[0], n_sub, replace=False)
    z_sub = chains_z.reshape(-1, theta.shape[-1])[idx]
    e_logprior = float(np.mean(post.logprior(flat[:: max(1, flat.shape[0] // 20000)])))
    log_jac = float(np.log(post.scale).sum())
    kl_knn = -(dg.entropy_knn(z_sub) + log_jac) - e_logprior
    kl_gauss = -(dg.entropy_gaussian(chains_z.reshape(-1, theta.shape[-1])) + log_jac) \
        - e_logprior
    cnt = state.counts
    steps = cnt["prop1"]
    acc = cnt["acc1"] + cnt["acc2"]
    stages: tuple[float, ...] = (cnt["acc1"] / max(steps, 1),)
    if cnt["prop2"]:
        stages = stages + (cnt["acc2"] / cnt["prop2"],)
    return BayesResult(
        names_in=tuple(names), chains=theta, log_posterior=lp, mean=mean, std=std, skewness=skew,
        kurtosis=kurt, correlation=corr, credible_interval_95=np.quantile(flat, [0.025, 0.975],
                                                                          axis=0).T,
        ess=ess, rhat=rhat, acceptance_rate=acc / max(steps, 1), acceptance_per_stage=stages,
        kl_divergence=float(kl_knn), kl_divergence_gaussian=float(kl_gauss), **base)


def _split_multipliers(res: BayesResult, d: int) -> BayesResult:
    """Move the sampled precision multipliers (columns d..) of a summary to the noise
    fields, as variance multipliers ``1 / tau``."""
    if len(res.names_in) == d:
        return res
    c = res.correlation
    return dataclasses.replace(
        res, names_in=res.names_in[:d], chains=res.chains[..., :d], mean=res.mean[:d],
        std=res.std[:d], skewness=res.skewness[:d], kurtosis=res.kurtosis[:d],
        correlation=c[:d, :d], credible_interval_95=res.credible_interval_95[:d],
        ess=res.ess[:d], rhat=res.rhat[:d], map_point=res.map_point[:d],
        proposal_covariance=res.proposal_covariance[:d, :d],
        noise_multiplier_names=res.names_in[d:],
        noise_multiplier_chains=1.0 / res.chains[..., d:])


def _batched_fd_grad(post: _Posterior, z: np.ndarray, hi: np.ndarray):
    """Log posterior and its gradient at z (d,), forward differences on one batch of d+1
    points (z is scaled: unit prior scale, hence ``scale=1``)."""
    with np.errstate(invalid="ignore"):
        fd = finite_difference(post, z, scale=1.0, central=False, upper=hi)
    return fd.values[0, 0], fd.gradient[0, 0]


def _map(post: _Posterior, z0: np.ndarray, zlo: np.ndarray, zhi: np.ndarray) -> np.ndarray:
    big = 1e30

    def fun(z):
        f, g = _batched_fd_grad(post, z, zhi)
        if not np.isfinite(f) or not np.all(np.isfinite(g)):
            return big, np.zeros_like(z)
        return -f, -g

    bounds = [(None if not np.isfinite(a) else a, None if not np.isfinite(b) else b)
              for a, b in zip(zlo, zhi, strict=True)]
    res = optimize.minimize(fun, z0, jac=True, method="L-BFGS-B", bounds=bounds,
                            options={"maxiter": 500})
    return res.x


class _TrueModel:
    """The model on parameters in prior order, (k, d) -> (k, m), counting evaluations."""

    def __init__(self, model, prior: ParameterSpace):
        self.model = model
        self.perm = align_inputs(model, prior.names)
        self.names_in = prior.names
        self.names_out = tuple(model.names_out)
        self.n_evaluations = 0
        self.seconds = 0.0
        self._direct = not hasattr(model, "evaluate")

    @property
    def seconds_per_evaluation(self) -> float | None:
        """Measured wall time per evaluated point (None before the first evaluation)."""
        return self.seconds / self.n_evaluations if self.n_evaluations else None

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        t0 = time.perf_counter()
        try:
            return self._call(theta)
        finally:
            self.n_evaluations += theta.shape[0]
            self.seconds += time.perf_counter() - t0

    def _call(self, theta: np.ndarray) -> np.ndarray:
        x = theta if self.perm is None else theta[:, self.perm]
        if self._direct:  # a plain batched callable: skip the evaluation layer's bookkeeping
            y = np.asarray(self.model(x), dtype=float)
            if y.ndim == 1 and len(self.names_out) == 1:
                y = y[:, None]
            if y.shape == (x.shape[0], len(self.names_out)):
                return y
        return evaluate(self.model, x).values


@dataclass(frozen=True, eq=False)
class _Problem:
    """Likelihood, prior and the sampler's scaled coordinates ``z = (theta - center) / scale``
    (bounds ``zlo``, ``zhi``); ``resp_idx`` picks the observed responses of the model."""

    names_out: tuple[str, ...]
    resp_idx: np.ndarray
    lik: GaussianLikelihood
    logprior: LogPrior
    center: np.ndarray
    scale: np.ndarray
    zlo: np.ndarray
    zhi: np.ndarray
    space: ParameterSpace
    n_theta: int
    # noise multipliers: group of each observation (n_exp, m), stated variances, names
    groups: np.ndarray | None = None
    noise_var: np.ndarray | None = None
    multiplier_names: tuple[str, ...] = ()

    def pad(self, theta: np.ndarray) -> np.ndarray:
        """A model-parameter point (n_theta,) with the multipliers at their prior mean."""
        return np.concatenate([theta, self.center[self.n_theta:]])


def _noise_covariance(noise_std, noise_covariance, shape: tuple[int, int]):
    """The noise as a covariance argument of :class:`GaussianLikelihood` (unit variance when
    neither is given, Dakota's default)."""
    if noise_std is not None and noise_covariance is not None:
        raise ParameterError("give noise_std or noise_covariance, not both")
    if noise_covariance is not None:
        return noise_covariance
    if noise_std is None:
        return 1.0
    sd = np.asarray(noise_std, dtype=float)
    if np.any(~np.isfinite(sd)) or np.any(sd <= 0):
        raise ParameterError(f"noise_std must be finite and > 0, got {sd}")
    var = sd**2
    if var.ndim == 2 and var.shape[0] == var.shape[1]:  # (n_exp, m), not a covariance
        return np.einsum("ej,jk->ejk", var, np.eye(var.shape[1]))
    return var


def _setup(model, data, prior, names_out, noise_std, noise_covariance, noise_multipliers=None,
           noise_multiplier_prior=(1.0, 1.0)) -> _Problem:
    """Stage 1: observed responses, likelihood, prior and scaled coordinates (with noise
    multipliers: the prior extended by their precision multipliers, :mod:`.noise`)."""
    if not isinstance(prior, ParameterSpace):
        raise ParameterError(f"prior must be a ParameterSpace, got {type(prior).__name__}")
    model_out = tuple(model.names_out)
    if names_out is None:
        resp_idx, observed = np.arange(len(model_out)), model_out
    else:
        missing = [r for r in names_out if r not in model_out]
        if missing:
            raise ParameterError(f"responses {missing} are not outputs of the model "
                                 f"{list(model_out)}")
        observed = tuple(names_out)
        resp_idx = np.array([model_out.index(r) for r in observed])
    shape = np.atleast_2d(np.asarray(data, dtype=float)).shape
    lik = GaussianLikelihood(data, _noise_covariance(noise_std, noise_covariance, shape), observed)
    space, groups, noise_var = prior, None, None
    mnames: tuple[str, ...] = ()
    if noise_multipliers is not None:
        if noise_covariance is not None:
            raise ParameterError("noise_multipliers need independent noise given as noise_std "
                                 "(scalar, per response or per observation), not "
                                 "noise_covariance")
        sd = 1.0 if noise_std is None else np.asarray(noise_std, dtype=float)
        noise_var = np.array(np.broadcast_to(np.square(sd), lik.data.shape), dtype=float)
        groups, mnames = multiplier_groups(noise_multipliers, observed, lik.n_exp)
        a, b = noise_multiplier_prior
        space = extended_prior(prior, mnames, a, b)
    logprior = LogPrior(space)
    center, scale = prior_scales(space)
    return _Problem(observed, resp_idx, lik, logprior, center, scale,
                    (logprior.lo - center) / scale, (logprior.hi - center) / scale, space,
                    prior.dim, groups, noise_var, mnames)


def _build_emulator(emulator, prior: ParameterSpace, truth: _TrueModel, pb: _Problem,
                    n_emulator_samples: int, seeds: dict[str, np.random.SeedSequence]):
    """Stage 2: fit (or check) the emulator of the observed responses on an LHS design of
    the prior; returns (emulator, leave-one-out, best build point or None, low-fidelity
    models: (_TrueModel, response columns) per CoKriging level below the truth).

    An unfitted emulator is copied before fitting (the caller's object stays unfitted, so a
    second call with it fits afresh); a copy without a seed gets the call's
    ``emulator_fit`` seed, so its restarts are reproducible too."""
    if not isinstance(emulator, (GaussianProcess, CoKriging)):
        raise ParameterError("emulator must be a rotoruq GaussianProcess or CoKriging, got "
                             f"{type(emulator).__name__}")
    gp, best_build, d, m = emulator, None, prior.dim, len(pb.names_out)
    lf = _low_fidelity(emulator, prior, truth, pb) if isinstance(emulator, CoKriging) else []
    if _is_fitted(gp):
        if gp.n_inputs != d or gp.n_outputs != m:
            raise ModelShapeError(f"fitted emulator has {gp.n_inputs} inputs and "
                                  f"{gp.n_outputs} outputs; need {d} and {m}")
    else:
        if isinstance(emulator, CoKriging):
            emulator.design_sizes(int(n_emulator_samples))  # bad sizes fail before any run
        build = fit_on_prior(emulator, prior, lambda x: truth(x)[:, pb.resp_idx],
                             n_emulator_samples, design_seed=seeds["design"],
                             fit_seed=seeds["emulator_fit"],
                             low_fidelity=[_columns(t, i) for t, i in lf])
        gp = build.gp
        lp_build = LogPrior(prior)(build.inputs) + pb.lik(build.outputs)
        best_build = build.inputs[int(np.argmax(lp_build))]
    loo = gp.loo()
    log.info("emulator leave-one-out: %s", ", ".join(
        f"{r} RMSE {e:.3g} (Q2 {q:.3f})" for r, e, q in zip(pb.names_out, loo.rmse, loo.q2,
                                                            strict=True)))
    return gp, loo, best_build, lf


def _columns(model: _TrueModel, idx: np.ndarray):
    """The observed responses ``idx`` of a model on prior-ordered points, (k, d) -> (k, m)."""
    return lambda x: model(x)[:, idx]


def _is_fitted(emulator: Emulator) -> bool:
    if isinstance(emulator, GaussianProcess):
        return bool(emulator._fits)
    return bool(emulator._levels)


def _low_fidelity(ck: CoKriging, prior: ParameterSpace, truth: _TrueModel, pb: _Problem
                  ) -> list[tuple[_TrueModel, np.ndarray]]:
    """The low-fidelity models of a CoKriging emulator on the calibrated parameters, each
    with the columns of the observed responses; an error names what differs from the model.
    """
    if not ck.low_fidelity and not _is_fitted(ck):
        raise ParameterError("a CoKriging emulator needs its low-fidelity model(s): "
                             "CoKriging(low_fidelity=model_lf, n_low=...), or fit it first on "
                             "your own runs")
    hf_in = tuple(truth.model.names_in)
    out = []
    for t, mdl in enumerate(ck.low_fidelity):
        lf_in, lf_out = tuple(mdl.names_in), tuple(mdl.names_out)
        if set(lf_in) != set(hf_in):
            raise ParameterError(f"low-fidelity model {t} ({mdl!r}) has inputs {list(lf_in)}; "
                                 f"the calibrated model has {list(hf_in)}: co-kriging needs "
                                 "the same inputs")
        missing = [r for r in pb.names_out if r not in lf_out]
        if missing:
            raise ParameterError(f"low-fidelity model {t} ({mdl!r}) has no responses "
                                 f"{missing} (it has {list(lf_out)}); co-kriging needs every "
                                 f"calibrated response {list(pb.names_out)}")
        out.append((_TrueModel(mdl, prior),
                    np.array([lf_out.index(r) for r in pb.names_out])))
    return out


def _refit(gp: Emulator, truth: _TrueModel, lf, pb: _Problem, new_x: np.ndarray,
           seed: np.random.SeedSequence) -> Emulator:
    """A copy of the emulator refitted with model runs at ``new_x`` added (failed runs left
    out); a CoKriging also gets runs of every low-fidelity model there (nested designs)."""
    runs = [truth(new_x)[:, pb.resp_idx]]
    if isinstance(gp, CoKriging):
        runs = [t(new_x)[:, i] for t, i in lf] + runs
        data = gp.training_data
    else:
        data = [(gp._X, gp._Y)]
    X, Y = [], []
    for (x0, y0), y in zip(data, runs, strict=True):
        ok = np.all(np.isfinite(y), 1)
        X.append(np.vstack([x0, new_x[ok]]))
        Y.append(np.vstack([y0, y[ok]]))
    gp = copy.copy(gp)
    gp.seed = seed
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # jitter notes of near points
        if isinstance(gp, CoKriging):
            gp.fit(X, Y)
        else:
            gp.fit(X[0], Y[0])
    return gp


def _start_point(post: _Posterior, prior: ParameterSpace, pb: _Problem, x0, map_start: bool,
                 best_build, rng) -> tuple[np.ndarray, float]:
    """Stage 3: the chain start (scaled) and its log posterior: ``x0``, or the best of the
    prior mean, the best build point and an LHS batch of the prior, then the MAP
    (L-BFGS-B) from the best few when ``map_start``."""
    d = prior.dim
    if x0 is not None:
        s = np.asarray(x0, dtype=float).reshape(-1)
        if s.size != pb.n_theta:
            raise ParameterError(f"x0 must have {pb.n_theta} values for "
                                 f"{prior.names[:pb.n_theta]}, got {s.size}")
        s = pb.pad(s)
        z0 = (s - pb.center) / pb.scale
        lp0 = post(z0[None])[0]
        if not np.isfinite(lp0):
            raise ParameterError(f"start point x0 = {s} has zero posterior density (outside "
                                 "the prior support or the model fails there)")
        map_seeds = [z0]
    else:
        cands = [pb.center] + ([pb.pad(best_build)] if best_build is not None else [])
        if map_start:
            cands.extend(prior.draw(max(16, 8 * d), design="lhs", seed=rng))
        zc = (np.array(cands) - pb.center) / pb.scale
        lpc = post(zc)
        if not np.any(np.isfinite(lpc)):
            _no_start(prior, pb, len(cands))
        order = np.argsort(-np.where(np.isfinite(lpc), lpc, -np.inf))
        z0, lp0 = zc[order[0]], float(lpc[order[0]])
        map_seeds = [zc[i] for i in order[:3] if np.isfinite(lpc[i])]
    if map_start:
        for zs in map_seeds:
            zm = _map(post, zs, pb.zlo, pb.zhi)
            lpm = post(zm[None])[0]
            if np.isfinite(lpm) and lpm >= lp0:
                z0, lp0 = zm, lpm
    return z0, lp0


def _no_start(prior: ParameterSpace, pb: _Problem, n_candidates: int):
    unbounded = [n for n, lo, hi in zip(prior.names, pb.logprior.lo, pb.logprior.hi,
                                        strict=True)
                 if not (np.isfinite(lo) and np.isfinite(hi))]
    where = f"the prior mean {pb.center}"
    if n_candidates > 1:
        where += f" and {n_candidates - 1} other points drawn from the prior"
    if unbounded:
        raise ParameterError(
            f"no start point: the log posterior is not finite at {where} (the model fails "
            f"or the likelihood is NaN there) and parameters {unbounded} have infinite "
            "prior support, so there is no bounded box to search; pass x0=[...] with "
            "a point where the model works")
    raise EvaluationError(f"no start point: the log posterior is NaN or -inf at {where}")


def _initial_proposal(proposal_covariance, truth: _TrueModel, gp, forward, pb: _Problem,
                      theta0: np.ndarray) -> np.ndarray:
    """Stage 4: the stage-1 proposal covariance in scaled coordinates (d, d)."""
    d = theta0.size
    sd = 2.38**2 / d
    if isinstance(proposal_covariance, str):
        if proposal_covariance == "hessian":
            jac = _jacobian(truth, gp, theta0[:pb.n_theta], forward, pb)
            jac = np.hstack([jac, np.zeros((jac.shape[0], d - pb.n_theta))])
            return sd * hessian_covariance(jac, pb.lik.precision, pb.scale**2, pb.scale)
        if proposal_covariance == "prior":
            return sd * np.eye(d)
        raise ParameterError(f"proposal_covariance must be 'hessian', 'prior' or a (d, d) "
                             f"array, got {proposal_covariance!r}")
    cov = np.asarray(proposal_covariance, dtype=float)
    if cov.shape != (d, d):
        raise ModelShapeError(f"proposal_covariance must be ({d}, {d}), got {cov.shape}")
    try:
        np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        raise ParameterError("proposal_covariance is not positive definite") from None
    return cov / np.outer(pb.scale, pb.scale)


def _jacobian(truth: _TrueModel, gp, theta0, forward, pb: _Problem) -> np.ndarray:
    """d q / d theta at theta0, (m, d) in prior order: emulator, model gradient, or batched FD."""
    if gp is not None:
        return gp.predict(theta0[None], return_var=False, return_grad=True,
                          warn_distance=None)[1][0]
    if has_gradient(truth.model):
        try:
            at = model_gradient(truth.model, theta0, gradient="analytic",
                                names_in=truth.names_in)
            truth.n_evaluations += at.n_evaluations
            g = at.gradient[0][pb.resp_idx]
            if np.all(np.isfinite(g)):
                return g
        except NotImplementedError:
            pass
    J = finite_difference(forward, theta0, fd_step=FD_STEP, scale=1e-3, central=False,
                          upper=pb.logprior.hi[:pb.n_theta]).gradient[0]
    return np.where(np.isfinite(J), J, 0.0)


def _chain_starts(post: _Posterior, z0: np.ndarray, lp0: float, L0: np.ndarray,
                  n_chains: int, rng, chain_rng) -> SamplerState:
    """Stage 5: the MAP for the first chain, the others drawn around it from the Laplace
    approximation (kept where their posterior is finite)."""
    d = z0.size
    x = np.repeat(z0[None], n_chains, axis=0)
    lp = np.full(n_chains, lp0)
    if n_chains > 1:
        cand = z0 + rng.standard_normal((n_chains - 1, d)) @ L0.T / np.sqrt(2.38**2 / d)
        lpc = post(cand)
        good = np.isfinite(lpc)
        x[1:][good], lp[1:][good] = cand[good], lpc[good]
    return SamplerState(x=x, lp=lp, chol=np.repeat(L0[None], n_chains, axis=0),
                        rng=chain_rng)


def _as_sampler(sampler) -> SamplerConfig:
    if isinstance(sampler, SamplerConfig):
        return sampler
    if not isinstance(sampler, str):
        raise ParameterError(f"sampler must be 'mh', 'dr', 'am', 'dram' or a SamplerConfig, got "
                             f"{sampler!r}")
    return SamplerConfig(sampler=sampler)


def _child(ss: np.random.SeedSequence, i: int) -> np.random.SeedSequence:
    """Child ``i`` of ``ss`` as ``ss.spawn`` makes it, without changing ``ss``."""
    return np.random.SeedSequence(ss.entropy, spawn_key=(*ss.spawn_key, i),
                                  pool_size=ss.pool_size)


def _sample(truth, gp, pb: _Problem, prior, cfg, auto_schedule, emulator_variance, x0, map_start,
            best_build, proposal_covariance, n_chains, n_samples, burn_in, thin, seeds) -> dict:
    """Stages 3-5 and the chains on one emulator (or the model): start point, initial
    proposal, chain starts and chains; the chains' kept samples are scaled (n, c, d)."""
    run = _prepare(truth, gp, pb, prior, cfg, auto_schedule, emulator_variance, x0, map_start,
                   best_build, proposal_covariance, n_chains, seeds)
    t0, c0 = time.perf_counter(), time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExtrapolationWarning)
        kept, kept_lp = run_chains(run["post"], run["state"], run["cfg"], n_samples, burn_in,
                                   thin)
    return dict(run, kept=kept, kept_lp=kept_lp, seconds=time.perf_counter() - t0,
                cpu_seconds=time.process_time() - c0)


def _prepare(truth, gp, pb: _Problem, prior, cfg, auto_schedule, emulator_variance, x0,
             map_start, best_build, proposal_covariance, n_chains, seeds) -> dict:
    """Stages 3-5 of :func:`_sample`: the posterior, the start point, the initial proposal
    and the chains' starting state (and the evaluation schedule), ready to run."""
    d = prior.dim
    if gp is not None:
        forward = gp._mean_fast
    elif np.array_equal(pb.resp_idx, np.arange(len(truth.names_out))):
        forward = truth
    else:
        def forward(theta):
            return truth(theta)[:, pb.resp_idx]

    post = _Posterior(forward, pb.lik, pb.logprior, pb.center, pb.scale, gp, emulator_variance,
                      pb if pb.groups is not None else None)
    z0, lp0 = _start_point(post, prior, pb, x0, map_start, best_build,
                           np.random.default_rng(seeds["start"]))
    theta0 = pb.center + pb.scale * z0
    cov_z = _initial_proposal(proposal_covariance, truth, gp, forward, pb, theta0)
    L0 = np.linalg.cholesky(cov_z + 1e-14 * np.eye(d))
    state = _chain_starts(post, z0, lp0, L0, n_chains,
                          np.random.default_rng(seeds["chain_starts"]),
                          np.random.default_rng(seeds["chains"]))
    cost = truth.seconds_per_evaluation
    if (auto_schedule and gp is None and cfg.evaluations == "speculative" and cost is not None
            and cost > SLOW_EVALUATION):
        cfg = dataclasses.replace(cfg, evaluations="minimal")
        log.info("calibrate_bayes: the model takes %.3g s a point (> %g s): the chains use the "
                 "minimal evaluation schedule (the same chains, fewer model runs)", cost,
                 SLOW_EVALUATION)
    post.reset_counts()
    return dict(post=post, theta0=theta0, cov_z=cov_z, state=state, cfg=cfg)


def calibrate_bayes(
    model: Model,
    data: ArrayLike,
    prior: ParameterSpace,
    *,
    names_out: Sequence[str] | None = None,
    noise: NoiseModel | None = None,
    chains: ChainOptions | None = None,
    emulator: GaussianProcess | CoKriging | EmulatorOptions | None = None,
    posterior_predictive: int = 0,
    self_check: int = 0,
    self_check_cache: SelfCheckCache | None = None,
    seed: SeedLike = None,
    **legacy: Any,
) -> BayesResult:
    """Bayesian calibration of the parameters ``prior`` of ``model`` to ``data``.

    Stages: problem setup (likelihood, prior, scaled coordinates), emulator build, start point
    (MAP), initial proposal, chains, posterior predictive, summary.

    Parameters
    ----------
    model : Model (names_in, names_out, batched __call__, optional gradient).
    data : (n_exp, m) observations of the m calibrated responses (one row per experiment), or
        (m,) for one experiment.
    prior : ParameterSpace of the calibrated parameters (names matched to ``model.names_in``);
        its joint density is the prior and its support bounds the chains.
    names_out : names of the model responses that ``data`` observes (default all, in order).
    noise : :class:`~rotoruq.methods.mcmc.options.NoiseModel` (default: unit variance).

        - ``noise_std``: standard deviation of the data noise (data units): scalar, (m,) per
          response or (n_exp, m) per observation. ``noise_covariance``: instead, a full
          (m, m) or (n_exp, m, m) covariance. Neither: unit variance (Dakota's default).
        - ``noise_multipliers``: calibrate the noise too (Dakota's
          ``calibrate_error_multipliers``): "one", "per_response", "per_experiment" or a list
          of observed responses; each multiplies the stated noise variance of its observations
          and is sampled with the parameters (:mod:`.noise`). Needs ``noise_std``.
        - ``noise_multiplier_prior``: (alpha, beta) of each multiplier's inverse-gamma prior
          (default (1, 1): weak, median 1.44).
    chains : :class:`~rotoruq.methods.mcmc.options.ChainOptions` (default: its defaults).

        - ``sampler``: "dram" (default), "am", "dr", "mh", or a :class:`SamplerConfig` with its
          tuning (Dakota DRAM defaults: dr_scale 5, adapt_start 100, adapt_interval 100; pooled
          adaptation; ``evaluations`` "speculative" or "minimal", see :mod:`.samplers`). By
          name, the chains on a model slower than :data:`SLOW_EVALUATION` s a point (measured
          during the start) use the "minimal" schedule; ``BayesResult.evaluations`` says which
          ran.
        - ``n_samples``: kept steps per chain (after burn-in and thinning); each chain takes
          ``burn_in + (n_samples - 1) * thin + 1`` steps. The default with the default burn-in
          is the reference study's 100,000 steps of which 5,000 burn-in.
        - ``burn_in``: steps dropped at the start of each chain (default ``n_samples // 19``,
          5 % of the steps). ``thin``: keep every ``thin``-th step after that.
        - ``n_chains``: chains advanced together; every step evaluates the likelihood of all of
          them in one batched call.
        - ``proposal_covariance``: "hessian" (inverse Gauss-Newton Hessian of the negative log
          posterior at the start, eqs. 2.25-2.27, times 2.38^2/d), "prior" (prior variances
          times 2.38^2/d) or a (d, d) array in parameter units used as given.
        - ``map_start``: start the chains at the maximum a posteriori point (L-BFGS-B from
          ``x0``, or from the best build sample / the prior mean). ``x0``: (d,) start point
          (parameter units).
    emulator : None (the chains call the model itself), a GaussianProcess or CoKriging (its
        options at their defaults), or :class:`~rotoruq.methods.mcmc.options.EmulatorOptions`:

        - ``emulator``: an unfitted GaussianProcess (fitted here on ``n_emulator_samples`` LHS
          points from the prior, evaluated through :func:`rotoruq.model.evaluate`) or a fitted
          one (inputs in ``prior.names`` order, outputs the calibrated responses). Or a
          :class:`~rotoruq.methods.cokriging.CoKriging`: unfitted with ``low_fidelity=``
          (cheaper Models with the model's inputs and the calibrated responses, cheapest
          first) and ``n_low=``, it is fitted on a nested design: the ``n_emulator_samples``
          LHS points of a GaussianProcess with the same seed (runs of ``model``) and, for each
          cheaper model, those points plus LHS points of the prior up to its ``n_low`` (its
          runs, through :func:`rotoruq.model.evaluate`, failed ones left out; counted in
          ``BayesResult.n_low_fidelity_evaluations``). Its recursive predictive mean and
          variance enter the likelihood as a GP's do; ``refine`` adds runs of every model at
          the picked points. Fitted (inputs in prior order, outputs the calibrated responses),
          it is used as given.
        - ``emulator_variance``: add the emulator's Kriging variance at theta to the noise
          variance of each response (Higdon et al. 2004): the emulator's error, one per
          response and shared by all experiments, is integrated out, so the log-determinant
          depends on theta and a sparse emulator widens the posterior instead of making it
          over-confident. False: the GP mean only (the reference thesis). Each evaluation then
          costs ``n^2 / 2`` multiply-adds per response for ``n`` build points, against ``n d``
          for the mean.
        - ``refine``: RefineConfig(n_samples=, target_ratio=, batch=) to refine the emulator
          over the posterior: after the chains, ``batch`` model runs at the posterior draws
          where the emulator's Kriging std relative to the noise std is largest, a refit and
          new chains, until every response's ratio (:class:`EmulatorAdequacy`
          ``posterior_ratio``) is below ``target_ratio`` or ``n_samples`` runs were added.
          None: no refinement (the ratio is still measured, and warned on above
          :data:`.adequacy.WARN_RATIO`).
    posterior_predictive : number of posterior draws pushed through the true model.
    self_check : N > 0 runs N replications of simulation-based calibration of this very
        setup (:func:`~rotoruq.methods.mcmc.sbc.simulation_based_calibration`: parameters
        drawn from ``prior``, data simulated from ``model`` with ``noise_std``, posteriors
        with the same emulator, sampler and emulator variance, short chains) and stores the
        verdict in ``BayesResult.self_check``. Needs ``noise_std`` (not a covariance) and no
        noise multipliers. 0 (default): no self-check.
    self_check_cache : a mapping in which the self-check is looked up before it runs and
        stored after, under :func:`~rotoruq.methods.mcmc.sbc.setup_key` of its setup (the
        true model as this call sees it, prior, fitted emulator, sampler, noise, counts,
        seed; never the data, which the self-check does not use): two calls with the same
        setup share one. A cache kept across runs must also tell the code apart (the study
        runner's does). None: always computed.
    seed : int, SeedSequence or Generator. Every random stage (emulator design, GP
        restarts of an unseeded emulator, MAP starts, chain starts, chains, posterior
        predictive draws, the KL subsample) has its own child of
        ``numpy.random.SeedSequence(seed)``: the same seed gives bitwise the same result.
        The caller's emulator is not modified (an unfitted one is fitted as a copy, in
        ``BayesResult.emulator``).
    **legacy : the flat keyword arguments of rotoruq 0.1 (``n_samples=``, ``burn_in=``,
        ``noise_std=``, ``n_emulator_samples=``, ...; :data:`.options.LEGACY_KEYWORDS`),
        accepted for one release with a ``DeprecationWarning`` naming the record field that
        replaces each; they override that field of the record given.

    Returns
    -------
    BayesResult

    Examples
    --------
    >>> import numpy as np
    >>> import rotoruq as rq
    >>> from rotoruq.methods.mcmc import ChainOptions, NoiseModel
    >>> line = rq.FunctionModel(lambda x: x[:, :1] * [[1.0, 2.0]], ["a"], ["y1", "y2"])
    >>> prior = rq.ParameterSpace({"a": rq.Uniform(0.0, 4.0)})
    >>> post = rq.calibrate_bayes(line, [[1.0, 2.0], [1.2, 1.8]], prior,
    ...                           noise=NoiseModel(noise_std=0.5),
    ...                           chains=ChainOptions(n_samples=400, n_chains=2), seed=1)
    >>> post.chains.shape
    (2, 400, 1)
    """
    t_start = time.perf_counter()
    flat = legacy_keywords("calibrate_bayes", legacy, LEGACY_KEYWORDS)
    noise = with_fields(noise, NoiseModel, flat.get("noise"), "noise")
    chains = with_fields(chains, ChainOptions, flat.get("chains"), "chains")
    if isinstance(emulator, GaussianProcess | CoKriging):
        emulator = EmulatorOptions(emulator)
    elif emulator is not None and not isinstance(emulator, EmulatorOptions):
        raise ParameterError(f"emulator must be a GaussianProcess or CoKriging (or their "
                             f"EmulatorOptions), got {type(emulator).__name__}")
    if emulator is None:  # the emulator's options without an emulator change nothing
        emulator_opts = EmulatorOptions(None, **flat.get("emulator", {}))  # type: ignore[arg-type]
    else:
        emulator_opts = with_fields(emulator, EmulatorOptions, flat.get("emulator"), "emulator")
    sampler, n_samples, burn_in, thin, n_chains = (
        chains.sampler, chains.n_samples, chains.burn_in, chains.thin, chains.n_chains)
    proposal_covariance, map_start, x0 = (
        chains.proposal_covariance, chains.map_start, chains.x0)
    noise_std, noise_covariance = noise.noise_std, noise.noise_covariance
    noise_multipliers, noise_multiplier_prior = (
        noise.noise_multipliers, noise.noise_multiplier_prior)
    surrogate, n_emulator_samples = emulator_opts.emulator, emulator_opts.n_emulator_samples
    emulator_variance, refine = emulator_opts.emulator_variance, emulator_opts.refine
    seeds = _stage_seeds(seed)
    cfg = _as_sampler(sampler)
    n_samples, thin, n_chains = int(n_samples), int(thin), int(n_chains)
    burn_in = n_samples // 19 if burn_in is None else int(burn_in)
    if n_samples < 1 or thin < 1 or n_chains < 1 or burn_in < 0:
        raise ParameterError(f"need n_samples >= 1, burn_in >= 0, thin >= 1 and n_chains >= 1; "
                             f"got {n_samples}, {burn_in}, {thin}, {n_chains}")
    pb = _setup(model, data, prior, names_out, noise_std, noise_covariance, noise_multipliers,
                noise_multiplier_prior)
    space = pb.space
    truth = _TrueModel(model, prior)
    d = prior.dim

    gp, loo, best_build, lf = None, None, None, []
    if refine is not None and not isinstance(refine, RefineConfig):
        raise ParameterError(f"refine must be a RefineConfig or None, got {refine!r}")
    if surrogate is not None:
        if (refine is not None and isinstance(surrogate, CoKriging)
                and not surrogate.low_fidelity):
            raise ParameterError("refine= with a CoKriging emulator adds runs of every "
                                 "fidelity: give its models, CoKriging(low_fidelity=...)")
        gp, loo, best_build, lf = _build_emulator(surrogate, prior, truth, pb,
                                                  n_emulator_samples, seeds)
    elif refine is not None:
        raise ParameterError("refine= refines an emulator: pass "
                             "emulator=EmulatorOptions(GaussianProcess(), refine=...)")

    round_seeds = {k: seeds[k] for k in ("start", "chain_starts", "chains")}
    runs_added: list[int] = []
    ratios: list[np.ndarray] = []
    adequacy = None
    while True:
        run = _sample(truth, gp, pb, space, cfg, not isinstance(sampler, SamplerConfig),
                      emulator_variance, x0, map_start, best_build,
                      proposal_covariance, n_chains, n_samples, burn_in, thin, round_seeds)
        post, kept = run["post"], run["kept"]
        if gp is None:
            break
        noise_sd = noise_std_of_mean(pb.lik.pack)
        draws = check_draws((pb.center + pb.scale * kept)[..., :d])
        var = gp._mean_var_fast(draws)[1]
        ratios.append(posterior_ratio(var, noise_sd))
        budget = 0 if refine is None else refine.n_samples - sum(runs_added)
        if refine is None or np.all(ratios[-1] < refine.target_ratio) or budget <= 0:
            adequacy = EmulatorAdequacy(
                names_out=pb.names_out, noise_std=noise_sd,
                loo_ratio=(np.full(len(noise_sd), np.nan) if loo is None else loo.rmse)
                / noise_sd,
                posterior_ratio=ratios[-1], runs_added=tuple(runs_added),
                posterior_ratio_per_round=np.array(ratios),
                target_ratio=None if refine is None else refine.target_ratio)
            break
        # refine: model runs where the emulator is least sure relative to the noise, a refit
        # (seeded from this round's child) and new chains from the round's own seeds
        k = len(runs_added) + 1
        rs = _child(seeds["refine"], k)
        new_x = pick_runs(draws, var, noise_sd, min(refine.batch, budget))
        runs_added.append(len(new_x))
        gp = _refit(gp, truth, lf, pb, new_x, _child(rs, 0))
        loo = gp.loo()
        best_build = None
        round_seeds = {key: _child(rs, i + 1) for i, key in enumerate(round_seeds)}
        log.info("refinement round %d: %d runs added, emulator/noise std ratio %s", k,
                 runs_added[-1], np.array2string(ratios[-1], precision=3))
    if adequacy is not None and np.any(adequacy.posterior_ratio > WARN_RATIO):
        bad = {r: round(float(v), 3) for r, v in zip(pb.names_out, adequacy.posterior_ratio,
                                                      strict=True) if v > WARN_RATIO}
        warnings.warn(f"emulator error over the posterior is more than {WARN_RATIO} of the "
                      f"noise std (RMS Kriging std / noise std: {bad}); "
                      + ("its variance is in the likelihood, so the posterior is wider than "
                         "the data alone would give" if emulator_variance else
                         "with emulator_variance=False the posterior is over-confident")
                      + ": add build runs (EmulatorOptions n_emulator_samples) or "
                        "EmulatorOptions(refine=RefineConfig())",
                      RuntimeWarning, stacklevel=2)
    theta0, cov_z, state, cfg = run["theta0"], run["cov_z"], run["state"], run["cfg"]
    kept_lp, t_sampling, cpu_sampling = run["kept_lp"], run["seconds"], run["cpu_seconds"]
    if post.n_extrapolated:
        warnings.warn(f"emulator extrapolated for {post.n_extrapolated} proposals, up to "
                      f"{post.max_extrapolation:.3g} box-widths outside its training box",
                      ExtrapolationWarning, stacklevel=2)

    pred_in = pred = None
    if posterior_predictive:
        flat = (pb.center + pb.scale * kept.reshape(-1, space.dim))[:, :d]
        pick = np.random.default_rng(seeds["predictive"])
        pred_in = flat[pick.choice(flat.shape[0], int(posterior_predictive), replace=True)]
        pred = truth(pred_in)
    base = dict(
        map_point=theta0, proposal_covariance=cov_z * np.outer(pb.scale, pb.scale),
        sampler=cfg.sampler, evaluations=cfg.evaluations, burn_in=burn_in, thin=thin,
        n_likelihood_evaluations=post.n_evals,
        n_evaluations=truth.n_evaluations, n_nan_likelihood=post.n_nan,
        n_out_of_support=post.n_outside, sampling_seconds=t_sampling,
        sampling_cpu_seconds=cpu_sampling, emulator=gp, emulator_loo=loo,
        predictive_inputs=pred_in, predictive=pred, names_out=truth.names_out,
        emulator_adequacy=adequacy, _state=(post, state, cfg),
        n_low_fidelity_evaluations=tuple(t.n_evaluations for t, _ in lf),
    )
    res = _summarize(space.names, kept.transpose(1, 0, 2), kept_lp.T, post, state, base,
                     seeds["summary"])
    res = _split_multipliers(res, d)
    res = dataclasses.replace(res, diagnostics=dg.diagnose(res.chains))
    if self_check:
        res = dataclasses.replace(res, self_check=_self_check(
            model, prior, pb, gp, cfg, emulator_variance, noise_std, noise_covariance,
            int(self_check), seeds["self_check"], self_check_cache))
    log.info("calibrate_bayes: %d chains x %d kept steps in %.2f s (total %.2f s)", n_chains,
             n_samples, t_sampling, time.perf_counter() - t_start)
    return res


def _self_check(model, prior: ParameterSpace, pb: _Problem, gp, cfg: SamplerConfig,
                emulator_variance: bool, noise_std, noise_covariance, n_replications: int,
                seed: np.random.SeedSequence,
                cache: SelfCheckCache | None = None) -> SBCResult:
    """Simulation-based calibration of the setup of one :func:`calibrate_bayes` call, from
    ``cache`` when it holds one of the same setup."""
    from .sbc import setup_key, simulation_based_calibration

    if pb.groups is not None:
        raise ParameterError("self_check with noise_multipliers: the replications would need "
                             "the multipliers' prior to simulate data; run the self-check "
                             "without noise_multipliers")
    if noise_covariance is not None or noise_std is None:
        raise ParameterError("self_check simulates data with a noise std per response: give "
                             "noise_std (not noise_covariance, not unit variance by default)")
    std = np.asarray(noise_std, dtype=float)
    if std.ndim == 2:
        if not np.all(std == std[:1]):
            raise ParameterError("self_check simulates data with one noise std per response; "
                                 "this call's noise_std differs between experiments")
        std = std[0]
    settings = dict(noise_std=std, n_replications=n_replications,
                    n_experiments=pb.lik.data.shape[0],
                    names_out=pb.names_out, sampler=cfg, emulator_variance=emulator_variance)
    key = None
    if cache is not None:
        model_key = (f"{type(model).__module__}.{type(model).__qualname__}|"
                     f"{getattr(model, 'model_id', '')}|{tuple(model.names_in)}|"
                     f"{tuple(model.names_out)}")
        key = setup_key(model_key, prior, gp, seed, **settings)
        hit = None if key is None else cache.get(key)
        if hit is not None:
            log.info("self-check reused (setup %s)", key)
            for category, message in hit[1]:  # what its replications warned, as they did
                warnings.warn(message, _warning_class(category), stacklevel=3)
            return hit[0]
    if cache is None or key is None:
        return simulation_based_calibration(model, prior, emulator=gp,  # fitted: as given
                                            seed=seed, **settings)
    with warnings.catch_warnings(record=True) as caught:
        out = simulation_based_calibration(model, prior, emulator=gp, seed=seed, **settings)
    for w in caught:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    cache[key] = (out, tuple((f"{w.category.__module__}:{w.category.__qualname__}",
                              str(w.message)) for w in caught))
    return out


def _warning_class(name: str) -> type[Warning]:
    """The warning category ``module:qualname`` (UserWarning when there is none)."""
    import importlib

    module, _, qualname = name.partition(":")
    try:
        obj: Any = importlib.import_module(module)
        for part in qualname.split("."):
            obj = getattr(obj, part)
    except (ImportError, AttributeError):
        return UserWarning
    return obj if isinstance(obj, type) and issubclass(obj, Warning) else UserWarning


def continue_chain(result: BayesResult, n_samples: int, *, seed: SeedLike = None) -> BayesResult:
    """Keep ``n_samples`` more steps per chain from the final state of ``result`` (same
    proposal and adaptation history, same thinning, no burn-in) and return the combined
    result.

    Without ``seed`` the chains go on bit for bit as one longer run would have.

    Parameters
    ----------
    result : BayesResult
        A result of :func:`calibrate_bayes` (or of this function): it carries the sampler's
        state.
    n_samples : int
        Kept steps to add to each chain (thinned like the original).
    seed : int, SeedSequence, Generator or None, optional
        A new random source for the continued chains (default: the chains' own generator,
        continued).

    Returns
    -------
    BayesResult
        The original and the new samples together, summarised again.
    """
    if result._state is None:
        raise ParameterError("this BayesResult carries no sampler state to continue from")
    post, state, cfg = result._state
    state = state.copy()
    if seed is not None:
        state.reseed(as_generator(seed))
    # the summary's subsample: from the chains' own generator when no seed is given, so the
    # same result continued twice gives the same numbers
    summary_seed = np.random.SeedSequence(state.rng.integers(2**63, size=4))
    ev0, nan0, out0 = post.n_evals, post.n_nan, post.n_outside
    t0, c0 = time.perf_counter(), time.process_time()
    kept, kept_lp = run_chains(post, state, cfg, int(n_samples), 0, result.thin)
    dt, dcpu = time.perf_counter() - t0, time.process_time() - c0
    full = result.chains
    if result.noise_multiplier_chains is not None:
        full = np.concatenate([full, 1.0 / result.noise_multiplier_chains], axis=-1)
    z_old = (full - post.center) / post.scale
    chains_z = np.concatenate([z_old, kept.transpose(1, 0, 2)], axis=1)
    lp = np.concatenate([result.log_posterior, kept_lp.T], axis=1)
    base = {k: getattr(result, k) for k in (
        "map_point", "proposal_covariance", "sampler", "burn_in", "thin", "emulator",
        "emulator_loo", "predictive_inputs", "predictive", "names_out", "emulator_adequacy",
        "evaluations", "n_low_fidelity_evaluations")}
    base.update(
        n_likelihood_evaluations=result.n_likelihood_evaluations + post.n_evals - ev0,
        n_evaluations=result.n_evaluations + (post.n_evals - ev0 if post.gp is None else 0),
        n_nan_likelihood=result.n_nan_likelihood + post.n_nan - nan0,
        n_out_of_support=result.n_out_of_support + post.n_outside - out0,
        sampling_seconds=result.sampling_seconds + dt,
        sampling_cpu_seconds=result.sampling_cpu_seconds + dcpu, _state=(post, state, cfg))
    names = result.names_in + result.noise_multiplier_names
    res = _summarize(names, chains_z, lp, post, state, base, summary_seed)
    res = _split_multipliers(res, len(result.names_in))
    return dataclasses.replace(res, diagnostics=dg.diagnose(res.chains),
                               self_check=result.self_check)


#: calibrate_bayes keywords a self-check replication may set and :class:`_CheckChains` runs
CHECK_OPTIONS = frozenset({"sampler", "emulator_variance", "n_samples", "burn_in", "thin",
                           "n_chains", "map_start", "proposal_covariance"})


class _CheckChains:
    """The chains of one self-check replication on a fitted emulator: the stages of
    :func:`calibrate_bayes` up to its chains, without the summary (moments, KL divergence,
    R-hat, the emulator's adequacy over the posterior) that the self-check never reads;
    built, the chains are ready to start (start point, proposal, chain starts); :meth:`run`
    runs them and :meth:`warn` gives the warning calibrate_bayes gives after them;
    :meth:`extend` takes the steps of :func:`continue_chain`. ``chains`` (c, n, d), parameter
    units, are bitwise those of ``calibrate_bayes(...).chains`` and of the continued results
    for the same arguments and seeds; ``n_evaluations`` their true-model evaluations."""

    def __init__(self, model: Model, data: np.ndarray, prior: ParameterSpace, gp: Emulator, *,
                 noise_std: ArrayLike, names_out: Sequence[str], seed: SeedLike,
                 sampler: str | SamplerConfig = "dram", emulator_variance: bool = True,
                 n_samples: int = 95_000, burn_in: int | None = None, thin: int = 1,
                 n_chains: int = 1, map_start: bool = True,
                 proposal_covariance: str | ArrayLike = "hessian"):
        seeds = _stage_seeds(seed)
        cfg = _as_sampler(sampler)
        n_samples, thin, n_chains = int(n_samples), int(thin), int(n_chains)
        burn_in = n_samples // 19 if burn_in is None else int(burn_in)
        if n_samples < 1 or thin < 1 or n_chains < 1 or burn_in < 0:
            raise ParameterError(f"need n_samples >= 1, burn_in >= 0, thin >= 1 and "
                                 f"n_chains >= 1; got {n_samples}, {burn_in}, {thin}, "
                                 f"{n_chains}")
        pb = _setup(model, data, prior, names_out, noise_std, None)
        if gp.n_inputs != prior.dim or gp.n_outputs != len(pb.names_out):
            raise ModelShapeError(f"fitted emulator has {gp.n_inputs} inputs and "
                                  f"{gp.n_outputs} outputs; need {prior.dim} and "
                                  f"{len(pb.names_out)}")
        self.truth = _TrueModel(model, prior)
        run = _prepare(self.truth, gp, pb, pb.space, cfg, not isinstance(sampler, SamplerConfig),
                       emulator_variance, None, map_start, None, proposal_covariance, n_chains,
                       {k: seeds[k] for k in ("start", "chain_starts", "chains")})
        self.post, self.state, self.cfg, self.thin = run["post"], run["state"], run["cfg"], thin
        self.n_samples, self.burn_in = n_samples, burn_in
        self.chains = np.empty((n_chains, 0, prior.dim))
        self._extrapolated = (0, 0.0)

    @property
    def compiled(self) -> bool:
        """The chains run in compiled code alone (no Python model, nothing that warns): they
        may run on a thread of their own."""
        return self.post.compiled is not None

    def run(self) -> None:
        """The chains (:func:`calibrate_bayes`'s n_samples, burn_in); then ``chains``."""
        # the self-check reports its replications, not each one's chains
        if self.compiled:
            kept = run_chains(self.post, self.state, self.cfg, self.n_samples, self.burn_in,
                              self.thin, progress=False)[0]
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ExtrapolationWarning)
                kept = run_chains(self.post, self.state, self.cfg, self.n_samples, self.burn_in,
                                  self.thin, progress=False)[0]
        self.chains = self.post.center + self.post.scale * kept.transpose(1, 0, 2)
        self._extrapolated = (self.post.n_extrapolated, self.post.max_extrapolation)

    def warn(self) -> None:
        """The warning :func:`calibrate_bayes` gives after its chains (extrapolation; counted
        by :meth:`run`, not by later extensions)."""
        n, far = self._extrapolated
        if n:
            warnings.warn(f"emulator extrapolated for {n} proposals, up to {far:.3g} "
                          "box-widths outside its training box", ExtrapolationWarning,
                          stacklevel=2)

    @property
    def n_evaluations(self) -> int:
        """True-model evaluations (the chains run on the emulator: none of theirs)."""
        return self.truth.n_evaluations

    def extend(self, n_samples: int, seed: SeedLike) -> None:
        """``n_samples`` more kept steps per chain, as ``continue_chain(result, n_samples,
        seed=seed)``."""
        post, state = self.post, self.state
        state.reseed(as_generator(seed))
        kept = run_chains(post, state, self.cfg, int(n_samples), 0, self.thin,
                          progress=False)[0]
        z_old = (self.chains - post.center) / post.scale
        chains_z = np.concatenate([z_old, kept.transpose(1, 0, 2)], axis=1)
        self.chains = post.center + post.scale * chains_z
