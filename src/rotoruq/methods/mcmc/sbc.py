"""Simulation-based calibration (Talts, Betancourt, Simpson, Vehtari and Gelman 2018).

A self-check of a Bayesian calibration: draw ``theta_true`` from the prior, simulate data from
the TRUE model plus noise, compute the posterior the same way a study does, and record the rank
of ``theta_true`` among ``L`` roughly independent posterior draws. When the calibration is right
the ranks are uniform on ``0..L`` for every parameter (the posterior, averaged over the prior
predictive, is the prior), the central credible intervals cover ``theta_true`` at their nominal
rate and ``(theta_true - posterior mean) / posterior std`` has unit spread. An over-confident
posterior (an emulator whose error the likelihood ignores, a sampler that has not mixed) piles
the ranks at both ends, under-covers and spreads the z-scores above 1.

Everything random is spawned from one :class:`numpy.random.SeedSequence`: the prior draws, the
noise of each replication, the emulator design and fit, and each replication's chains.
"""

from __future__ import annotations

import dataclasses
import hashlib
import inspect
import math
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np
from numpy.typing import ArrayLike
from scipy import stats

from ..._progress import Phase
from ..._rng import SeedLike, as_seed_sequence
from ...errors import EvaluationError, ModelShapeError, ParameterError
from ...model import Model, align_inputs, evaluate
from ...params import ParameterSpace
from ..cokriging import CoKriging
from ..surrogate import GaussianProcess
from . import diagnostics as dg
from ._emulator import fit_on_prior
from .bayes import (
    CHECK_OPTIONS,
    BayesResult,
    _CheckChains,
    _is_fitted,
    calibrate_bayes,
    continue_chain,
)
from .options import (
    LEGACY_KEYWORDS,
    ChainOptions,
    EmulatorOptions,
    NoiseModel,
    legacy_keywords,
)
from .warmup import BATCH, MIN_BATCHES, mser_warm_up

__all__ = ["SBCResult", "simulation_based_calibration", "setup_key"]

COVERAGE_LEVELS = (0.5, 0.9)


@dataclass(frozen=True, eq=False)
class SBCResult:
    """Outcome of :func:`simulation_based_calibration`.

    Attributes
    ----------
    names_in : tuple of str
        The d parameter names (the columns of the arrays below).
    n_draws : int
        L, the thinned posterior draws each rank is taken among (ranks run over 0..L).
    theta_true : ndarray of shape (n_replications, d)
        The prior draws the data were simulated at, parameter units.
    ranks : ndarray of shape (n_replications, d)
        Number of thinned posterior draws below ``theta_true``.
    rank_histogram : ndarray of shape (d, n_bins)
        Counts of the ranks in ``n_bins`` bins of ``0..L``; bin b holds ranks r with
        ``floor(r * n_bins / (L + 1)) == b``.
    bin_probability : ndarray of shape (n_bins,)
        The probability of each bin under uniform ranks (1 / n_bins when n_bins divides
        L + 1).
    p_value : ndarray of shape (d,)
        Chi-square test of the histogram against ``bin_probability`` (n_bins - 1 degrees of
        freedom).
    z_scores : ndarray of shape (n_replications, d)
        ``(theta_true - posterior mean) / posterior std``.
    z_score_std : ndarray of shape (d,)
        Their standard deviation over replications (1 when calibrated, above 1 when
        over-confident).
    coverage_50, coverage_90 : ndarray of shape (d,)
        Fraction of replications whose central (equal-tailed) 50 % and 90 % credible
        intervals contain ``theta_true``.
    coverage_50_se, coverage_90_se : float
        Their binomial standard errors at the nominal rate, ``sqrt(p (1 - p) /
        n_replications)``.
    posterior_mean, posterior_std : ndarray of shape (n_replications, d)
        Each replication's posterior mean and standard deviation, parameter units.
    ess : ndarray of shape (n_replications,)
        Smallest effective sample size over the parameters of each replication's posterior
        draws (after its warm-up).
    n_autocorrelated : int
        Replications whose ESS stayed below ``n_draws`` (their ranks come from
        autocorrelated draws).
    warm_up : ndarray of shape (n_replications,)
        Draws each replication's chains dropped at their start by the MSER-5 rule
        (:func:`~rotoruq.methods.mcmc.warmup.mser_warm_up`: largest over chains and
        parameters, at most half of the kept draws), after the default calibration's fixed
        burn-in; 0 for draws a ``calibrate`` callable returned (used as returned).
    n_unsettled : int
        Replications whose MSER-5 truncation point reached that cap: their chains had not
        settled within the first half of their draws.
    alpha : float
        Significance level of the uniformity test.
    coverage_tolerance : float
        Allowed distance of a coverage from its nominal rate, in binomial standard errors.
    passed : bool
        Every parameter passes every test.
    reason : str
        Which parameter fails which test (or a one-line summary of the pass).
    n_evaluations : int
        True-model evaluations (data simulation and emulator build, plus what the default
        calibration spent).
    seconds : float
        Wall time, s.
    """

    names_in: tuple[str, ...]
    n_draws: int
    theta_true: np.ndarray
    ranks: np.ndarray
    rank_histogram: np.ndarray
    bin_probability: np.ndarray
    p_value: np.ndarray
    z_scores: np.ndarray
    z_score_std: np.ndarray
    coverage_50: np.ndarray
    coverage_90: np.ndarray
    coverage_50_se: float
    coverage_90_se: float
    posterior_mean: np.ndarray
    posterior_std: np.ndarray
    ess: np.ndarray
    n_autocorrelated: int
    warm_up: np.ndarray
    n_unsettled: int
    alpha: float
    coverage_tolerance: float
    passed: bool
    reason: str
    n_evaluations: int
    seconds: float

    @property
    def n_replications(self) -> int:
        """Number of replications (simulated data sets)."""
        return int(self.ranks.shape[0])

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Every field as a numpy array (numbers 0-d, texts as unicode), for ``np.savez``;
        :meth:`from_arrays` gives the result back, bitwise."""
        return {f.name: np.asarray(getattr(self, f.name)) for f in dataclasses.fields(self)}

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray]) -> SBCResult:
        """The result :meth:`to_arrays` wrote.

        Parameters
        ----------
        arrays : mapping of str to ndarray
            One array per field, as :meth:`to_arrays` gives them (an ``np.load`` of its
            ``np.savez`` file).
        """
        kinds: dict[str, Callable[[np.ndarray], Any]] = {
            "names_in": lambda a: tuple(str(v) for v in a), "reason": str, "passed": bool,
            "n_draws": int, "n_autocorrelated": int, "n_evaluations": int, "n_unsettled": int}
        out: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            a = np.asarray(arrays[f.name])
            out[f.name] = kinds[f.name](a) if f.name in kinds else (
                float(a) if a.ndim == 0 else a)
        return cls(**out)

    def summary(self) -> str:
        """A plain-text table: p-value, z-score spread and coverages per parameter."""
        rows = [f"{'parameter':<16}{'p_value':>10}{'z_std':>8}{'cov50':>8}{'cov90':>8}"]
        for j, n in enumerate(self.names_in):
            rows.append(f"{n:<16}{self.p_value[j]:>10.3g}{self.z_score_std[j]:>8.3f}"
                        f"{self.coverage_50[j]:>8.3f}{self.coverage_90[j]:>8.3f}")
        rows.append(f"{self.n_replications} replications, L = {self.n_draws} draws; "
                    f"{'PASS' if self.passed else 'FAIL'}: {self.reason}")
        return "\n".join(rows)


def _n_bins(n_replications: int, n_draws: int) -> int:
    """At least 10 expected ranks per bin, at most 20 bins, never more bins than ranks."""
    return int(min(20, max(2, n_replications // 10), n_draws + 1))


def _thin(draws: np.ndarray, n_draws: int) -> np.ndarray:
    """``n_draws`` draws evenly spaced over the pooled chains: their spacing n / n_draws is at
    least the chain's n / ESS whenever ESS >= n_draws."""
    flat = draws.reshape(-1, draws.shape[-1])
    idx = np.round(np.linspace(0, flat.shape[0] - 1, n_draws)).astype(int)
    return flat[idx]


def _as_draws(out: Any, d: int) -> np.ndarray:
    """Posterior draws (c, n, d) from what a calibration returned."""
    if isinstance(out, BayesResult):
        arr = out.chains
    else:
        arr = np.asarray(out, dtype=float)
    if arr.ndim == 2:
        arr = arr[None]
    if arr.ndim != 3 or arr.shape[-1] != d:
        raise ModelShapeError(f"calibrate must return a BayesResult or posterior draws of "
                              f"shape (n, {d}) or (n_chains, n, {d}); got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise EvaluationError("calibrate returned non-finite posterior draws")
    return arr


def _uniformity(ranks: np.ndarray, n_draws: int, n_bins: int):
    """Histogram (d, n_bins), exact bin probabilities (n_bins,) and chi-square p-values (d,)."""
    per_rank = np.floor(np.arange(n_draws + 1) * n_bins / (n_draws + 1)).astype(int)
    prob = np.bincount(per_rank, minlength=n_bins) / (n_draws + 1.0)
    bins = per_rank[ranks]  # (n_rep, d)
    hist = np.stack([np.bincount(bins[:, j], minlength=n_bins) for j in range(ranks.shape[1])])
    expected = prob * ranks.shape[0]
    chi2 = ((hist - expected) ** 2 / expected).sum(1)
    return hist, prob, stats.chi2.sf(chi2, n_bins - 1)


def _verdict(names, p_value, coverage, n_rep, alpha, tolerance) -> tuple[bool, str]:
    fails = []
    for j, n in enumerate(names):
        if not p_value[j] > alpha:
            fails.append(f"{n}: ranks not uniform (chi-square p = {p_value[j]:.3g} <= {alpha})")
        for level, cov in zip(COVERAGE_LEVELS, coverage, strict=True):
            se = math.sqrt(level * (1 - level) / n_rep)
            if abs(cov[j] - level) > tolerance * se:
                fails.append(f"{n}: {level:.0%} interval covers {cov[j]:.3f}, outside "
                             f"{level:.2f} +- {tolerance:g} x {se:.3f}")
    if fails:
        return False, "; ".join(fails)
    return True, (f"ranks uniform (smallest p = {p_value.min():.3g} > {alpha}) and coverages "
                  f"within {tolerance:g} binomial standard errors of 50 % and 90 %")


def simulation_based_calibration(
    model: Model,
    prior: ParameterSpace,
    *,
    noise_std: ArrayLike,
    n_replications: int = 200,
    n_experiments: int = 1,
    calibrate: Callable[..., Any] | None = None,
    n_draws: int = 99,
    n_samples: int = 2000,
    emulator: GaussianProcess | CoKriging | None = None,
    n_emulator_samples: int = 500,
    names_out: Sequence[str] | None = None,
    alpha: float = 0.01,
    coverage_tolerance: float = 3.0,
    seed: SeedLike = None,
    **options: Any,
) -> SBCResult:
    """Simulation-based calibration of a Bayesian calibration of ``prior`` on ``model``.

    Each of ``n_replications`` replications draws ``theta_true`` from ``prior``, simulates
    ``n_experiments`` observations ``model(theta_true) + noise_std * N(0, 1)`` from the TRUE
    model (never the emulator), computes the posterior with ``calibrate`` and records the rank
    of ``theta_true`` among ``n_draws`` posterior draws thinned to be roughly independent (draws
    evenly spaced over the chains, at least ``n / ESS`` apart).

    Parameters
    ----------
    model : Model (names_in, names_out, batched __call__); the data are simulated from it.
    prior : ParameterSpace of the calibrated parameters; theta_true is drawn from it.
    noise_std : standard deviation of the simulated noise and of the likelihood, data units:
        scalar or (m,) per observed response; every value > 0.
    n_replications : replications (200 or more for a test of any power).
    n_experiments : observations per replication (rows of the simulated data).
    calibrate : None (default): :func:`calibrate_bayes` with ``n_samples`` kept DRAM steps
        (a fixed burn-in of ``n_samples // 2`` steps, no MAP start), ``noise_std``,
        ``names_out``, the emulator and ``options``. Each replication's chains drop their
        warm-up, the MSER-5 truncation point of their kept draws
        (:func:`~rotoruq.methods.mcmc.warmup.mser_warm_up`: largest over chains and
        parameters, at most half the draws): a chain that drifts longer than the fixed
        burn-in would otherwise pile its ranks at one end. Chains whose ESS after their
        warm-up stays below ``n_draws`` are continued (up to 3 times) with
        :func:`continue_chain` (the warm-up taken again over the longer chains); after the
        first continuation, only while that ESS grown in proportion to the length the
        continuations would reach could be half of ``n_draws`` (else the shortfall is
        certain; the reason says how many replications' chains did not mix). Otherwise a
        callable ``calibrate(data, seed=SeedSequence)`` with ``data`` (n_experiments, m)
        returning a :class:`BayesResult` or posterior draws (n, d) or (n_chains, n, d) in
        ``prior.names`` order; a callable without a ``seed`` parameter is called as
        ``calibrate(data)`` (then its randomness is its own); its draws are used as
        returned (its burn-in is its own).
    n_draws : L, the thinned draws each rank is taken among (ranks 0..L; 99 gives 100 values).
    n_samples : kept chain steps of the default calibration.
    emulator : with the default calibration, a GaussianProcess built ONCE from the prior (on
        ``n_emulator_samples`` LHS points of the true model; an unfitted GP without its own
        seed gets one spawned here) and used as fitted in every replication (the emulator does
        not depend on the data). A fitted GP is used as given. An unfitted
        :class:`~rotoruq.methods.cokriging.CoKriging` with ``low_fidelity`` models is built the
        same way on its nested design (its cheap models' runs are not counted in
        ``n_evaluations``).
    n_emulator_samples : int, optional
        Runs of the true model that an unfitted emulator is built on (default 500).
    names_out : model responses that the data observe (default all).
    alpha : the uniformity test fails when the chi-square p-value <= alpha (per parameter).
    coverage_tolerance : a coverage fails when it is more than this many binomial standard
        errors from its nominal rate.
    seed : int, SeedSequence, Generator or None; the same seed gives bitwise the same result.
    **options : further options of :func:`calibrate_bayes` (default calibration), flat: the
        fields of its option records by name (``sampler=``, ``emulator_variance=``, ...).

    Returns
    -------
    SBCResult

    Notes
    -----
    The rank histogram has ``n_bins = min(20, max(2, n_replications // 10), n_draws + 1)``
    bins (at least 10 expected ranks per bin, at most 20); the chi-square test uses each bin's
    exact probability under uniform ranks, so ``n_bins`` need not divide ``n_draws + 1``. With
    ``d`` parameters the test fails by chance with probability about ``1 - (1 - alpha)^d``.

    Examples
    --------
    >>> import numpy as np, rotoruq as rq
    >>> prior = rq.ParameterSpace({"a": rq.Normal(0.0, 1.0), "b": rq.Normal(1.0, 0.5)})
    >>> model = rq.FunctionModel(lambda x: np.column_stack([x[:, 0] + x[:, 1] ** 2,
    ...                                                     x[:, 0] - x[:, 1]]),
    ...                          ["a", "b"], ["y1", "y2"])
    >>> r = rq.simulation_based_calibration(model, prior, noise_std=0.3, n_replications=20,
    ...                                     n_draws=19, n_samples=600, seed=1)
    >>> r.ranks.shape, r.rank_histogram.shape
    ((20, 2), (2, 2))
    """
    t_start = time.perf_counter()
    n_replications, n_experiments, n_draws = int(n_replications), int(n_experiments), int(n_draws)
    if n_replications < 2 or n_experiments < 1 or n_draws < 1:
        raise ParameterError(f"need n_replications >= 2, n_experiments >= 1 and n_draws >= 1; "
                             f"got {n_replications}, {n_experiments}, {n_draws}")
    if not 0 < alpha < 1 or not coverage_tolerance > 0:
        raise ParameterError(f"need 0 < alpha < 1 and coverage_tolerance > 0; got {alpha}, "
                             f"{coverage_tolerance}")
    if calibrate is not None and (emulator is not None or options):
        raise ParameterError("emulator and calibrate_bayes options apply to the default "
                             "calibration only; pass them inside your calibrate callable")
    names_model = tuple(model.names_out)
    obs = names_model if names_out is None else tuple(names_out)
    unknown = [n for n in obs if n not in names_model]
    if unknown:
        raise ParameterError(f"names_out {unknown} are not responses of the model; expected "
                             f"some of {list(names_model)}")
    cols = np.array([names_model.index(n) for n in obs])
    m, d = len(obs), prior.dim
    noise = np.asarray(noise_std, dtype=float)
    if noise.ndim > 1 or (noise.ndim == 1 and noise.size != m):
        raise ModelShapeError(f"noise_std must be a scalar or ({m},) for responses {list(obs)}, "
                              f"got shape {noise.shape}")
    if not np.all(np.isfinite(noise)) or not np.all(noise > 0):
        raise ParameterError(f"noise_std must be finite and > 0, got {noise_std!r}")
    perm = align_inputs(model, prior.names)

    def observed(mdl: Model, perm_m: np.ndarray | None, cols_m: np.ndarray):
        def f(theta: np.ndarray) -> np.ndarray:
            x = theta if perm_m is None else theta[:, perm_m]
            return np.asarray(evaluate(mdl, x).values, dtype=float)[:, cols_m]
        return f

    truth = observed(model, perm, cols)
    low_fidelity = []
    if isinstance(emulator, CoKriging) and not _is_fitted(emulator):
        if not emulator.low_fidelity:
            raise ParameterError("an unfitted CoKriging emulator needs its low-fidelity "
                                 "model(s): CoKriging(low_fidelity=model_lf, n_low=...)")
        emulator.design_sizes(int(n_emulator_samples))  # bad sizes fail before any run
        for t, mdl in enumerate(emulator.low_fidelity):
            missing = [n for n in obs if n not in tuple(mdl.names_out)]
            if missing:
                raise ParameterError(f"low-fidelity model {t} has no responses {missing}; "
                                     f"co-kriging needs every observed response {list(obs)}")
            low_fidelity.append(observed(mdl, align_inputs(mdl, prior.names), np.array(
                [tuple(mdl.names_out).index(n) for n in obs])))

    ss = as_seed_sequence(seed)
    s_theta, s_emulator, *s_reps = ss.spawn(2 + n_replications)
    theta_true = prior.draw(n_replications, design="random", seed=np.random.default_rng(s_theta))
    clean = truth(theta_true)
    n_evaluations = n_replications
    bad = np.flatnonzero(~np.all(np.isfinite(clean), 1))
    if bad.size:
        raise EvaluationError(f"the model failed (non-finite responses) at {bad.size} of "
                              f"{n_replications} prior draws, first at {theta_true[bad[0]]}")

    gp = None
    if calibrate is None and emulator is not None:
        gp = emulator
        if not _is_fitted(gp):
            s_design, s_fit = s_emulator.spawn(2)
            build = fit_on_prior(emulator, prior, truth, n_emulator_samples,
                                 design_seed=s_design, fit_seed=np.random.default_rng(s_fit),
                                 low_fidelity=low_fidelity)
            gp = build.gp
            n_evaluations += build.n_evaluations

    # no MAP pre-solve by default: its finite-difference L-BFGS-B costs 20x the chain here,
    # while a burn-in of half the kept steps forgets the start at a fraction of that
    bayes_options = {"n_samples": int(n_samples), "burn_in": int(n_samples) // 2,
                     "map_start": False, **options}
    # the flat options of calibrate_bayes into the fields of its option records
    records = legacy_keywords("simulation_based_calibration", {
        k: v for k, v in bayes_options.items() if k in LEGACY_KEYWORDS}, LEGACY_KEYWORDS,
        warn=False)
    rest = {k: v for k, v in bayes_options.items() if k not in LEGACY_KEYWORDS}
    takes_seed = calibrate is not None and _takes_seed(calibrate)
    ranks = np.empty((n_replications, d), dtype=int)
    z = np.empty((n_replications, d))
    mean = np.empty((n_replications, d))
    std = np.empty((n_replications, d))
    covered = np.zeros((len(COVERAGE_LEVELS), n_replications, d), dtype=bool)
    ess = np.empty(n_replications)
    warm = np.zeros(n_replications, dtype=np.int64)
    n_short = n_unsettled = 0
    # on a fitted emulator the replications run the chains alone (no posterior summary nor
    # diagnostics, which the self-check never reads): the same chains, bitwise
    lean = None
    if calibrate is None and gp is not None and set(bayes_options) <= CHECK_OPTIONS:
        lean = _replications(model, prior, gp, clean, noise, obs, s_reps, n_experiments,
                             n_draws, bayes_options)
    # per-replication calibrations report here (the lean ones in _replications)
    phase = Phase("self-check replications", n_replications) if lean is None else None
    for i, s_rep in enumerate(s_reps):
        ess_i = None
        if lean is not None:  # their draws after the warm-up, as _after_warm_up gives them
            (draws, warm[i], settled), ess_i, n_ev = lean[i]
            n_evaluations += n_ev
            n_unsettled += not settled
        else:
            draws, ess_i, n_ev = _replication(model, prior, gp, clean[i], noise, obs, s_rep,
                                              n_experiments, n_draws, calibrate, takes_seed,
                                              bayes_options, records, rest, d)
            n_evaluations += n_ev
            assert phase is not None  # lean is None here
            phase.advance()
            if calibrate is None:  # the ESS the chains return is that of their draws after it
                draws, warm[i], settled = _after_warm_up(draws)
                n_unsettled += not settled
        if ess_i is None:
            ess_i = dg.effective_sample_size(draws)
        ess[i] = float(ess_i.min())
        n_short += bool(ess[i] < n_draws)
        flat = draws.reshape(-1, d)
        thinned = _thin(draws, n_draws)
        ranks[i] = (thinned < theta_true[i]).sum(0)
        mean[i], std[i] = flat.mean(0), flat.std(0, ddof=1)
        z[i] = (theta_true[i] - mean[i]) / std[i]
        for k, level in enumerate(COVERAGE_LEVELS):
            lo, hi = np.quantile(flat, [0.5 - level / 2, 0.5 + level / 2], axis=0)
            covered[k, i] = (lo <= theta_true[i]) & (theta_true[i] <= hi)

    if phase is not None:
        phase.close()
    hist, prob, p_value = _uniformity(ranks, n_draws, _n_bins(n_replications, n_draws))
    coverage = covered.mean(1)
    passed, reason = _verdict(prior.names, p_value, coverage, n_replications, alpha,
                              coverage_tolerance)
    if calibrate is None:
        reason += _warm_up_text(warm, n_unsettled, int(bayes_options.get("burn_in", 0)))
    if n_short:
        reason += (f"; {n_short} of {n_replications} replications' chains have an ESS below "
                   f"the {n_draws} draws the ranks need (median ESS {np.median(ess):.3g}): "
                   f"their ranks are autocorrelated, so part of this verdict is the sampler's "
                   f"mixing, not the posterior's calibration")
    se = [math.sqrt(lv * (1 - lv) / n_replications) for lv in COVERAGE_LEVELS]
    return SBCResult(
        names_in=tuple(prior.names), n_draws=n_draws, theta_true=theta_true, ranks=ranks,
        rank_histogram=hist, bin_probability=prob, p_value=p_value, z_scores=z,
        z_score_std=z.std(0, ddof=1), coverage_50=coverage[0], coverage_90=coverage[1],
        coverage_50_se=se[0], coverage_90_se=se[1], posterior_mean=mean, posterior_std=std,
        ess=ess, n_autocorrelated=n_short, warm_up=warm, n_unsettled=n_unsettled,
        alpha=float(alpha),
        coverage_tolerance=float(coverage_tolerance), passed=passed, reason=reason,
        n_evaluations=n_evaluations, seconds=time.perf_counter() - t_start)


def _warm_up_text(warm: np.ndarray, n_unsettled: int, burn_in: int) -> str:
    """The reason's clause on the replications' warm-up (from the run)."""
    text = (f"; warm-up by MSER-5 after the fixed burn-in of {burn_in} steps: median "
            f"{np.median(warm):.0f}, largest {int(warm.max())} draws dropped")
    if n_unsettled:
        text += (f", {n_unsettled} of {warm.size} replications' chains had not settled within "
                 f"half their draws (at the cap: their warm-up is a lower bound, the ranks of "
                 f"those replications carry drift)")
    return text


def setup_key(model_key: str, prior: ParameterSpace, emulator: Any, seed: SeedLike,
              **settings: Any) -> str | None:
    """The identity of a self-check's setup: a digest of everything that changes its answer
    and nothing else (not the data it checks): ``model_key`` (the true model the
    replications simulate from, and the code, as the caller identifies them), the prior,
    the fitted emulator's training data and hyperparameters, the seed and ``settings`` (the
    remaining arguments of :func:`simulation_based_calibration`: counts, noise, sampler,
    ...). None when the setup cannot be identified (an unfitted emulator or a co-kriging
    one, a seed that is not a SeedSequence or an int)."""
    if isinstance(seed, np.random.SeedSequence):
        seed_doc: Any = [repr(seed.entropy), list(seed.spawn_key), seed.pool_size]
    elif isinstance(seed, int | np.integer):
        seed_doc = int(seed)
    else:
        return None
    if not isinstance(emulator, GaussianProcess) or not _is_fitted(emulator):
        return None
    h = hashlib.sha256()

    def add(obj: Any) -> None:
        if isinstance(obj, np.ndarray):
            a = np.ascontiguousarray(obj)
            h.update(f"{a.dtype.str}{a.shape}".encode())
            h.update(a.tobytes())
        elif dataclasses.is_dataclass(obj) and not isinstance(obj, type):
            add(type(obj).__qualname__)
            for f in dataclasses.fields(obj):
                add(f.name)
                add(getattr(obj, f.name))
        elif isinstance(obj, list | tuple):
            h.update(b"[")
            for v in obj:
                add(v)
            h.update(b"]")
        elif isinstance(obj, dict):
            for k in sorted(obj):
                add(k)
                add(obj[k])
        else:
            h.update(repr(obj).encode())
        h.update(b"\0")

    add(["sbc-setup-2", model_key, seed_doc])  # 2: MSER-5 warm-up of the replications
    add([(n, type(d).__qualname__, d.describe()) for n, d in
         zip(prior.names, prior.distributions, strict=True)])
    add(None if prior.correlation is None else np.asarray(prior.correlation, dtype=float))
    gp = emulator
    add([type(gp).__qualname__, {k: v for k, v in vars(gp).items()
                                 if not k.startswith("_") and k != "seed"}])
    add([gp._X, gp._Y, list(gp._fits)])
    add({k: (np.asarray(v, dtype=float) if isinstance(v, np.ndarray | list) else v)
         for k, v in settings.items()})
    return h.hexdigest()[:32]


#: Times a replication's chains are continued (by n_samples, 2 n_samples, 4 n_samples) while
#: their ESS stays below the draws the ranks need.
N_EXTENSIONS = 3
#: After the first continuation, another runs only while the ESS, grown in proportion to the
#: chains' final length, could reach this share of the draws the ranks need: chains that
#: barely move (ESS 2 after 4000 steps) are not continued fourfold for a foregone shortfall.
PROJECTED_ESS_SHARE = 0.5


def _worth_extending(ess: np.ndarray, n_kept: int, k: int, n_samples: int,
                     n_draws: int) -> bool:
    """Whether to continue chains of ``n_kept`` draws with ESS ``ess`` (d,) at continuation
    ``k`` (0-based): their ESS is below ``n_draws`` and, from the second continuation on,
    scaled by the length the remaining continuations would reach, at least
    :data:`PROJECTED_ESS_SHARE` of it."""
    low = float(np.min(ess))
    if low >= n_draws:
        return False
    if k == 0:  # a chain stuck before its proposal adapted can still mix: one doubling always
        return True
    final = n_kept + sum(n_samples * 2**j for j in range(k, N_EXTENSIONS))
    return low * final / max(n_kept, 1) >= PROJECTED_ESS_SHARE * n_draws


def _after_warm_up(chains: np.ndarray) -> tuple[np.ndarray, int, bool]:
    """Chains (c, n, d) without their MSER-5 warm-up (:func:`mser_warm_up`), the warm-up
    (draws) and whether it settled before the cap; chains too short for the rule as they
    are."""
    if chains.shape[1] < MIN_BATCHES * BATCH:
        return chains, 0, True
    w = mser_warm_up(chains)
    return chains[:, w.steps:], w.steps, w.settled


def _replication(model: Model, prior: ParameterSpace, gp: Any, clean: np.ndarray,
                 noise: np.ndarray, obs: tuple[str, ...], s_rep: np.random.SeedSequence,
                 n_experiments: int, n_draws: int, calibrate: Callable[..., Any] | None,
                 takes_seed: bool, options: dict, records: dict, rest: dict, d: int
                 ) -> tuple[np.ndarray, np.ndarray | None, int]:
    """One replication through ``calibrate`` or :func:`calibrate_bayes`: posterior draws
    (c, n, d), the ESS of those after their warm-up (:func:`calibrate_bayes`; None for
    ``calibrate``) and true-model evaluations."""
    s_noise, s_cal, s_more = s_rep.spawn(3)
    eps = np.random.default_rng(s_noise).standard_normal((n_experiments, len(obs)))
    data = clean + noise * eps
    if calibrate is not None:
        out = calibrate(data, seed=s_cal) if takes_seed else calibrate(data)
        return _as_draws(out, d), None, 0
    res = calibrate_bayes(model, data, prior, names_out=list(obs),
                          noise=NoiseModel(noise_std=noise, **records.get("noise", {})),
                          chains=ChainOptions(**records.get("chains", {})),
                          emulator=None if gp is None else EmulatorOptions(
                              gp, **records.get("emulator", {})),
                          seed=s_cal, **rest)
    for k, s_k in enumerate(s_more.spawn(N_EXTENSIONS)):
        kept = _after_warm_up(res.chains)[0]
        ess = dg.effective_sample_size(kept)
        if not _worth_extending(ess, kept.shape[1], k, int(options["n_samples"]), n_draws):
            return res.chains, ess, res.n_evaluations
        res = continue_chain(res, int(options["n_samples"]) * 2**k, seed=s_k)
    return res.chains, dg.effective_sample_size(_after_warm_up(res.chains)[0]), \
        res.n_evaluations


def _replications(model: Model, prior: ParameterSpace, gp: Any, clean: np.ndarray,
                  noise: np.ndarray, obs: tuple[str, ...], s_reps: list, n_experiments: int,
                  n_draws: int, options: dict
                  ) -> list[tuple[tuple[np.ndarray, int, bool], np.ndarray, int]]:
    """The default calibration of every replication on the fitted emulator ``gp``: posterior
    draws after their warm-up (:func:`_after_warm_up` of the chains: draws (c, n, d), the
    warm-up and whether it settled), the ESS (d,) of those draws and true-model
    evaluations, per replication.

    Each replication's chains are continued (up to 3 times) while the ESS of their draws
    after the MSER-5 warm-up (:func:`_after_warm_up`) stays below
    ``n_draws`` and could reach it (:func:`_worth_extending`), as with
    :func:`continue_chain`. Replications are independent: when every
    one runs in compiled code alone they run on ``numba.get_num_threads()`` threads, each
    from its own seeds, so the numbers do not depend on the thread count. The warnings come
    in the order of a one-by-one run (each replication's start, then its chains').
    """
    m = len(obs)
    reps, more, caught = [], [], []
    for i, s_rep in enumerate(s_reps):
        s_noise, s_cal, s_more = s_rep.spawn(3)
        eps = np.random.default_rng(s_noise).standard_normal((n_experiments, m))
        with warnings.catch_warnings(record=True) as got:
            reps.append(_CheckChains(model, clean[i] + noise * eps, prior, gp, noise_std=noise,
                                     names_out=list(obs), seed=s_cal, **options))
        caught.append(got)
        more.append(s_more.spawn(N_EXTENSIONS))
    n_samples = int(options["n_samples"])

    after: list[Any] = [None] * len(reps)

    def chains(i: int, emit: bool) -> np.ndarray:
        rep = reps[i]
        if emit:
            _warn_again(caught[i])
        rep.run()
        if emit:
            rep.warn()
        for k, s_k in enumerate(more[i]):
            after[i] = _after_warm_up(rep.chains)
            ess = dg.effective_sample_size(after[i][0])
            if not _worth_extending(ess, after[i][0].shape[1], k, n_samples, n_draws):
                return ess
            rep.extend(n_samples * 2**k, s_k)
        after[i] = _after_warm_up(rep.chains)
        return dg.effective_sample_size(after[i][0])

    n_threads = min(numba.get_num_threads(), len(reps))
    phase = Phase("self-check replications", len(reps))

    def counted(i: int, emit: bool) -> np.ndarray:
        ess = chains(i, emit)
        phase.advance()
        return ess

    if all(r.compiled for r in reps):  # nothing warns while they run: any order will do
        if n_threads > 1:
            with ThreadPoolExecutor(n_threads) as pool:
                ess = list(pool.map(counted, range(len(reps)), [False] * len(reps)))
        else:
            ess = [counted(i, False) for i in range(len(reps))]
        for got, rep in zip(caught, reps, strict=True):
            _warn_again(got)
            rep.warn()
    else:
        ess = [counted(i, True) for i in range(len(reps))]
    phase.close()
    return [(a, e, r.n_evaluations) for r, a, e in zip(reps, after, ess, strict=True)]


def _warn_again(caught: list) -> None:
    for w in caught:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def _takes_seed(func: Callable[..., Any]) -> bool:
    try:
        params = inspect.signature(func).parameters
    except (TypeError, ValueError):
        return True
    return "seed" in params or any(p.kind is inspect.Parameter.VAR_KEYWORD
                                   for p in params.values())
