"""Bayesian calibration with an additive model discrepancy (Kennedy and O'Hagan 2001).

Observation ``j`` of response ``r`` at configuration ``x`` (for the GVPM rotor the height H/R of
a ground-effect test) is ``y_rj(x) = eta_r(x, theta) + delta_r(x) + eps``, ``eps ~ N(0,
sigma_r^2)``. The discrepancy ``delta_r`` is a zero-mean Gaussian process over ``x`` (squared
exponential or Matern-5/2 kernel; amplitude and length-scale sampled under informative
hyperpriors) or a low-order polynomial with Gaussian coefficients. It is marginalised
analytically: with ``n_c`` repeats at configuration ``c`` the means ``ybar_c`` are sufficient
(``sigma`` known), and ``ybar - eta(theta) ~ N(0, K_delta + diag(sigma^2 / n_c))``, so the
chains sample only ``theta`` and the hyperparameters. After sampling, ``delta`` at any
configuration is drawn per posterior sample from its conditional Gaussian given the residuals.

Identifiability (Brynjarsdottir and O'Hagan 2014): a flexible discrepancy can absorb what
``theta`` does, so the priors must be informative, and the result says, computed, when the two
are confounded: the posterior correlation of each parameter with each discrepancy's mean level
over the data configurations, and the ratio of each parameter's posterior std to its prior
std and to its std in a calibration without discrepancy (Laplace approximation at the MAP).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike
from scipy import optimize

from ..._rng import SeedLike, as_generator
from ...errors import ModelShapeError, ParameterError
from ...model import Model, align_inputs, evaluate
from ...params import ParameterSpace, Uniform
from ..surrogate import GaussianProcess, LeaveOneOut
from . import diagnostics as dg
from ._discrepancy_kernel import MATERN52, SQUARED_EXPONENTIAL, gp_marginal_loglik
from ._emulator import fit_on_prior
from .fd_noise import noisy_hessian
from .options import EmulatorOptions
from .proposals import LogPrior, prior_scales
from .samplers import SamplerConfig, SamplerState, run_chains

__all__ = ["Discrepancy", "DiscrepancyPrediction", "DiscrepancyResult",
           "calibrate_with_discrepancy", "predict_with_discrepancy"]

KINDS = ("gp", "polynomial")
KERNELS = ("squared_exponential", "matern52")
_LOG_2PI = float(np.log(2.0 * np.pi))
_JITTER = 1e-10
_KERNEL_CODES = {"squared_exponential": SQUARED_EXPONENTIAL, "matern52": MATERN52}
_NO_POINT_VAR = np.zeros((0, 0, 0))
#: A MAP closer than this to a bound of a bounded prior (scaled coordinates) is moved inside
#: for its Hessian, whose steps then reach at most the bound.
_EDGE = 3e-3


@dataclass(frozen=True)
class Discrepancy:
    """The form of the additive discrepancy ``delta_r(x)`` of every calibrated response.

    Parameters
    ----------
    kind : "gp" (a zero-mean Gaussian process over the configuration variable) or
        "polynomial" (``sum_k b_k u^k``, ``k <= degree``, ``u`` the configuration scaled to
        [-1, 1] over the data's range, ``b_k ~ N(0, amplitude_scale^2)``).
    kernel : "squared_exponential" or "matern52" (GP only).
    degree : polynomial degree (0: a constant offset), polynomial only.
    amplitude_scale : scale of the half-normal prior of the GP amplitude (the std of
        ``delta``), or the coefficient std of the polynomial, in response units: a scalar or
        one per response. Default, a weakly-informative rule set from the data: the root
        mean square of each response's data (a discrepancy as large as the response itself is
        plausible a priori; 95 % of the half-normal's mass lies below twice it), so the
        amplitude is learned, not bounded by a hand-set scale
        (``benchmarks/discrepancy_coverage.py`` checks the bands it gives in extrapolation).
    length_scale : median of the log-normal prior of the GP length-scale, in configuration
        units. Default: the range of the data's configurations.
    length_scale_log_std : std of ``log(length_scale)`` under its prior (0.5: the 95 % prior
        interval spans a factor of 7).

    Examples
    --------
    >>> Discrepancy(kernel="matern52", amplitude_scale=2.0).kind
    'gp'
    """

    kind: str = "gp"
    kernel: str = "squared_exponential"
    degree: int = 1
    amplitude_scale: float | tuple[float, ...] | None = None
    length_scale: float | None = None
    length_scale_log_std: float = 0.5

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ParameterError(f"discrepancy kind must be one of {KINDS}, got {self.kind!r}")
        if self.kernel not in KERNELS:
            raise ParameterError(f"discrepancy kernel must be one of {KERNELS}, got "
                                 f"{self.kernel!r}")
        if int(self.degree) != self.degree or not 0 <= int(self.degree) <= 3:
            raise ParameterError(f"polynomial discrepancy degree must be an integer in 0..3, "
                                 f"got {self.degree!r}")
        if self.amplitude_scale is not None:
            a = np.atleast_1d(np.asarray(self.amplitude_scale, dtype=float))
            if np.any(~np.isfinite(a)) or np.any(a <= 0):
                raise ParameterError(f"amplitude_scale must be finite and > 0, got {a}")
        if self.length_scale is not None and not (np.isfinite(self.length_scale)
                                                  and self.length_scale > 0):
            raise ParameterError(f"length_scale must be finite and > 0, got {self.length_scale}")
        if not (np.isfinite(self.length_scale_log_std) and self.length_scale_log_std > 0):
            raise ParameterError(f"length_scale_log_std must be finite and > 0, got "
                                 f"{self.length_scale_log_std}")

    @property
    def n_hyper(self) -> int:
        """Sampled hyperparameters per response (amplitude and length-scale for a GP)."""
        return 2 if self.kind == "gp" else 0


def _kernel(kernel: str, x1: np.ndarray, x2: np.ndarray, amp: np.ndarray,
            ell: np.ndarray) -> np.ndarray:
    """Covariance (k, m, n1, n2) between configurations x1 (n1,) and x2 (n2,) for amplitudes
    and length-scales (k, m)."""
    r = np.abs(x1[:, None] - x2[None, :])[None, None] / ell[:, :, None, None]
    a2 = (amp**2)[:, :, None, None]
    if kernel == "squared_exponential":
        return a2 * np.exp(-0.5 * r * r)
    s = np.sqrt(5.0) * r
    return a2 * (1.0 + s + s * s / 3.0) * np.exp(-s)


class _Form:
    """The discrepancy's covariance for given hyperparameters, fixed scales included."""

    def __init__(self, spec: Discrepancy | None, xs: np.ndarray, amp_scale: np.ndarray,
                 ell_median: float):
        self.spec = spec
        self.m = amp_scale.size
        self.amp_scale = amp_scale
        self.ell_median = ell_median
        self.center = 0.5 * (xs.max() + xs.min())
        self.half = max(0.5 * (xs.max() - xs.min()), 1e-300)

    @property
    def n_hyper(self) -> int:
        return 0 if self.spec is None else self.spec.n_hyper * self.m

    def basis(self, x: np.ndarray) -> np.ndarray:
        u = (x - self.center) / self.half
        return u[:, None] ** np.arange(int(self.spec.degree) + 1)[None, :]  # type: ignore[union-attr]

    def cov(self, hyper: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
        """(k, m, n1, n2) for hyper (k, n_hyper) = [log amplitudes (m), log length-scales (m)]."""
        k = hyper.shape[0]
        if self.spec is None:
            return np.zeros((k, self.m, x1.size, x2.size))
        if self.spec.kind == "polynomial":
            B = self.basis(x1) @ self.basis(x2).T
            return np.broadcast_to((self.amp_scale**2)[None, :, None, None] * B[None, None],
                                   (k, self.m, x1.size, x2.size))
        return _kernel(self.spec.kernel, x1, x2, np.exp(hyper[:, :self.m]),
                       np.exp(hyper[:, self.m:]))

    def log_hyperprior(self, hyper: np.ndarray) -> np.ndarray:
        """(k,) log density of the log-hyperparameters (half-normal amplitude with its
        Jacobian, log-normal length-scale)."""
        if self.n_hyper == 0:
            return np.zeros(hyper.shape[0])
        la, ll = hyper[:, :self.m], hyper[:, self.m:]
        s = self.amp_scale[None, :]
        amp = np.exp(la)
        lp_a = np.log(2.0) - np.log(s) - 0.5 * _LOG_2PI - 0.5 * (amp / s) ** 2 + la
        sd = self.spec.length_scale_log_std  # type: ignore[union-attr]
        lp_l = -np.log(sd) - 0.5 * _LOG_2PI - 0.5 * ((ll - np.log(self.ell_median)) / sd) ** 2
        return lp_a.sum(1) + lp_l.sum(1)

    def hyper_center_scale(self) -> tuple[np.ndarray, np.ndarray]:
        if self.n_hyper == 0:
            return np.zeros(0), np.zeros(0)
        sd = self.spec.length_scale_log_std  # type: ignore[union-attr]
        # log of a half-normal: median log(0.674 s), std about 1.1
        c = np.concatenate([np.log(0.674 * self.amp_scale), np.full(self.m,
                                                                    np.log(self.ell_median))])
        return c, np.concatenate([np.full(self.m, 1.1), np.full(self.m, sd)])


class _Forward:
    """eta(x_c, theta) at every configuration: theta (k, d) -> (k, n_c, m) responses."""

    def __init__(self, model: Model, names: tuple[str, ...], config_name: str,
                 resp_idx: np.ndarray):
        if config_name not in tuple(model.names_in):
            raise ParameterError(f"configuration variable {config_name!r} is not an input of "
                                 f"the model; its inputs are {list(model.names_in)}")
        if config_name in names:
            raise ParameterError(f"configuration variable {config_name!r} is also a calibrated "
                                 "parameter")
        self.model = model
        self.perm = align_inputs(model, names + (config_name,))
        self.resp_idx = resp_idx
        self.n_evaluations = 0
        self._direct = not hasattr(model, "evaluate")
        self._m = len(tuple(model.names_out))

    def __call__(self, theta: np.ndarray, xs: np.ndarray) -> np.ndarray:
        k, d = theta.shape
        nc = xs.size
        X = np.empty((k, nc, d + 1))
        X[:, :, :d] = theta[:, None, :]
        X[:, :, d] = xs[None, :]
        X = X.reshape(k * nc, d + 1)
        if self.perm is not None:
            X = X[:, self.perm]
        self.n_evaluations += X.shape[0]
        y = None
        if self._direct:  # a plain batched callable: skip the evaluation layer's bookkeeping
            y = np.asarray(self.model(X), dtype=float)
            if y.ndim == 1 and self._m == 1:
                y = y[:, None]
            if y.shape != (X.shape[0], self._m):
                y = None
        if y is None:
            y = evaluate(self.model, X).values
        return y[:, self.resp_idx].reshape(k, nc, -1)


class _Emulated:
    """eta at the data's configurations from a GP emulator of the model: one output per
    (configuration, response), fitted on an LHS design of the prior run at every
    configuration (:func:`._emulator.fit_on_prior`), its Kriging variance (k, n_c, m) beside
    its mean when ``options.emulator_variance``."""

    def __init__(self, forward: _Forward, prior: ParameterSpace, xs: np.ndarray,
                 options: EmulatorOptions, design_seed, fit_seed):
        if not isinstance(options.emulator, GaussianProcess):
            raise ParameterError("a calibration with a discrepancy takes a GaussianProcess "
                                 f"emulator, got {type(options.emulator).__name__}")
        self.shape = (xs.size, forward.resp_idx.size)
        size = xs.size * forward.resp_idx.size
        self.build = fit_on_prior(
            options.emulator, prior, lambda t: forward(t, xs).reshape(t.shape[0], size),
            int(options.n_emulator_samples), design_seed=design_seed, fit_seed=fit_seed)
        self.gp: GaussianProcess = self.build.gp
        self.variance = bool(options.emulator_variance)
        self.loo: LeaveOneOut = self.gp.loo()

    def __call__(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        t = np.ascontiguousarray(theta, dtype=float)
        if not self.variance:
            return self.gp._mean_fast(t).reshape(-1, *self.shape), None
        mean, var = self.gp._mean_var_fast(t)
        return mean.reshape(-1, *self.shape), var.reshape(-1, *self.shape)


class _Posterior:
    """Batched log posterior of ``z = (phi - center) / scale``, ``phi = [theta, log hyper]``."""

    def __init__(self, forward: _Forward, logprior: LogPrior, form: _Form, xs, ybar, var_mean,
                 center, scale, d: int, emulated: _Emulated | None = None):
        self.forward, self.logprior, self.form = forward, logprior, form
        self.emulated = emulated  # None: the chains run the model itself
        self.xs, self.ybar, self.var_mean = xs, ybar, var_mean  # (nc,), (nc, m), (m, nc)
        self.center, self.scale, self.d = center, scale, d
        self.n_evals = 0
        self._jitter = _JITTER * float(var_mean.max())
        self._fixed: tuple[np.ndarray, np.ndarray] | None = None

    def split(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        phi = self.center + self.scale * np.atleast_2d(z)
        return phi[:, :self.d], phi[:, self.d:]

    def marginal_loglik(self, eta: np.ndarray, hyper: np.ndarray,
                        var: np.ndarray | None = None) -> np.ndarray:
        """(k,) log N(ybar; eta, K_delta + diag(sigma^2 / n_c + var)) summed over responses;
        eta (k, n_c, m), hyper (k, n_hyper) log-hyperparameters, var (k, n_c, m) an
        emulator's variance at each point (None: the model's own eta)."""
        resid = np.ascontiguousarray((self.ybar[None] - eta).transpose(0, 2, 1))  # (k, m, nc)
        out = np.empty(eta.shape[0])
        spec = self.form.spec
        vt = None if var is None else np.ascontiguousarray(var.transpose(0, 2, 1))
        if spec is not None and spec.kind == "gp":
            m = self.ybar.shape[1]
            gp_marginal_loglik(resid, self.xs, self.var_mean,
                               np.ascontiguousarray(hyper[:, :m]),
                               np.ascontiguousarray(hyper[:, m:]),
                               _KERNEL_CODES[spec.kernel], self._jitter,
                               _NO_POINT_VAR if vt is None else vt, out)
        elif vt is not None:  # each point's covariance has its own diagonal: one factor each
            nc = self.xs.size
            C0 = self.form.cov(np.zeros((1, 0)), self.xs, self.xs)[0]
            C = np.broadcast_to(C0[None], (eta.shape[0], *C0.shape)).copy()
            idx = np.arange(nc)
            C[:, :, idx, idx] += self.var_mean[None] + vt + self._jitter
            L = np.linalg.cholesky(C)
            w = np.linalg.solve(L, resid[..., None])[..., 0]
            logdet = 2.0 * np.log(np.diagonal(L, axis1=-2, axis2=-1)).sum(-1)
            out[:] = (-0.5 * ((w * w).sum(-1) + logdet + nc * _LOG_2PI)).sum(-1)
        else:  # the covariance does not depend on the sample: one factor for all
            if self._fixed is None:
                C = self.form.cov(np.zeros((1, 0)), self.xs, self.xs)[0].copy()
                idx = np.arange(self.xs.size)
                C[:, idx, idx] += self.var_mean + self._jitter
                L = np.linalg.cholesky(C)
                self._fixed = (np.linalg.inv(L),
                               2.0 * np.log(np.diagonal(L, axis1=-2, axis2=-1)).sum(-1))
            Linv, logdet = self._fixed
            w = np.einsum("rpq,krq->krp", Linv, resid)
            out[:] = (-0.5 * ((w * w).sum(-1) + logdet[None] + self.xs.size * _LOG_2PI)).sum(-1)
        out[~np.isfinite(out)] = -np.inf
        return out

    def __call__(self, z: np.ndarray) -> np.ndarray:
        theta, hyper = self.split(z)
        self.n_evals += theta.shape[0]
        lp = self.logprior(theta) + self.form.log_hyperprior(hyper)
        ok = np.isfinite(lp)
        if ok.any():
            eta, var = (self.forward(theta[ok], self.xs), None) if self.emulated is None \
                else self.emulated(theta[ok])
            with np.errstate(invalid="ignore", over="ignore"):
                lp[ok] += self.marginal_loglik(eta, hyper[ok], var)
        lp[~np.isfinite(lp)] = -np.inf
        return lp


@dataclass(frozen=True, eq=False)
class DiscrepancyPrediction:
    """Posterior predictions at configurations, with and without the discrepancy.

    The predictions are sums of the draws: ``with_discrepancy = eta + delta + eps`` (a new
    observation), ``without_discrepancy = eta + eps`` (the calibrated model alone, the same
    posterior draws).

    Attributes
    ----------
    configuration_name : str
        The model input that sets the configuration (a test condition: height, speed...).
    configurations : ndarray of shape (n_conditions,)
        Values of ``configuration_name`` predicted at, in its units.
    names_out : tuple of str
        The responses (the last axis of the arrays).
    model_draws : ndarray of shape (n_draws, n_conditions, n_responses)
        ``eta(x, theta)`` at posterior draws of the parameters, response units.
    discrepancy_draws : ndarray of shape (n_draws, n_conditions, n_responses)
        ``delta(x)`` drawn from its conditional Gaussian given the residuals.
    noise_draws : ndarray of shape (n_draws, n_conditions, n_responses)
        ``eps``, the observation noise.
    quantile_levels : ndarray of shape (q,)
        The probabilities of ``quantiles``.
    quantiles, quantiles_without : ndarray of shape (q, n_conditions, n_responses)
        Quantiles of the predictions with and without the discrepancy.
    mean, std : ndarray of shape (n_conditions, n_responses)
        Mean and standard deviation of the predictions with the discrepancy.
    mean_without, std_without : ndarray of shape (n_conditions, n_responses)
        The same without it.

    Examples
    --------
    >>> # pred = predict_with_discrepancy(result, model, [1.0], seed=1)
    >>> # lo, hi = pred.interval(0.9)   # (n_conditions, n_responses) each
    """

    configuration_name: str
    configurations: np.ndarray
    names_out: tuple[str, ...]
    model_draws: np.ndarray
    discrepancy_draws: np.ndarray
    noise_draws: np.ndarray
    quantile_levels: np.ndarray
    quantiles: np.ndarray
    quantiles_without: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    mean_without: np.ndarray
    std_without: np.ndarray

    @property
    def with_discrepancy(self) -> np.ndarray:
        """(n_draws, n_conditions, n_responses) draws of a new observation."""
        return self.model_draws + self.discrepancy_draws + self.noise_draws

    @property
    def without_discrepancy(self) -> np.ndarray:
        """(n_draws, n_conditions, n_responses) draws of ``eta + eps``."""
        return self.model_draws + self.noise_draws

    def interval(self, level: float = 0.9, *, discrepancy: bool = True,
                 noise: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Equal-tailed predictive interval at ``level``: (lower, upper), each
        (n_conditions, n_responses).

        Parameters
        ----------
        level : float, optional
            Probability content, in (0, 1) (default 0.9).
        discrepancy : bool, optional
            Include ``delta`` (default True); False: the calibrated model alone.
        noise : bool, optional
            Include ``eps`` (default True: a new observation); False: the true process.
        """
        if not 0 < level < 1:
            raise ParameterError(f"level must be in (0, 1), got {level}")
        draws = self.model_draws + (self.discrepancy_draws if discrepancy else 0.0) \
            + (self.noise_draws if noise else 0.0)
        a = 0.5 * (1.0 - level)
        lo, hi = np.quantile(draws, [a, 1.0 - a], axis=0)
        return lo, hi


@dataclass(frozen=True, eq=False)
class DiscrepancyResult(dg.PooledChains):
    """Joint posterior of parameters and discrepancy hyperparameters, with identifiability.

    Attributes
    ----------
    names_in : tuple of str
        The d calibrated parameters.
    names_out : tuple of str
        The calibrated responses.
    configuration_name : str
        The model input that sets the configuration of each observation.
    discrepancy : Discrepancy or None
        The form of the discrepancy (None: calibrated without one).
    chains : ndarray of shape (n_chains, n_samples, d)
        Kept parameter samples, parameter units.
    hyper_names : tuple of str
        Sampled hyperparameters (``amplitude[r]``, ``length_scale[r]`` per response for a
        GP; none for a polynomial or without discrepancy).
    hyper_chains : ndarray of shape (n_chains, n_samples, n_hyper)
        Their samples, in their units.
    log_posterior : ndarray of shape (n_chains, n_samples)
        Log posterior density (up to a constant) of each kept sample.
    mean, std : ndarray of shape (d,)
        Posterior mean and standard deviation of the parameters.
    credible_interval_95 : ndarray of shape (d, 2)
        Equal-tailed 2.5 % / 97.5 % quantiles.
    ess, rhat : ndarray of shape (d + n_hyper,)
        Effective sample size and split R-hat, in the order ``names_in + hyper_names``.
    prior_std : ndarray of shape (d,)
        The prior's standard deviations.
    std_ratio_to_prior : ndarray of shape (d,)
        Posterior over prior std.
    std_without_discrepancy : ndarray of shape (d,)
        Posterior std of a calibration without discrepancy (Laplace approximation at its
        MAP, a uniform prior counted as a normal of its variance, at most the prior std; NaN
        when the MAP lies on the edge of the prior support or the Hessian there is not
        positive definite).
    std_ratio_to_no_discrepancy : ndarray of shape (d,)
        ``std`` over ``std_without_discrepancy``.
    configurations : ndarray of shape (n_c,)
        The distinct configurations of the data.
    discrepancy_at_data : ndarray of shape (n_draws, n_c, n_responses)
        Draws of ``delta`` there, response units.
    level_correlation : ndarray of shape (d, n_responses)
        Posterior correlation of each parameter with the discrepancy's mean level over the
        data configurations.
    confounded : ndarray of shape (d,)
        A parameter whose abs(level_correlation) reaches ``confounding_threshold`` for some
        response.
    confounding_threshold : float
        The threshold of ``confounded``.
    identifiability : str
        The finding, in words.
    noise_std : ndarray of shape (n_responses,)
        The noise standard deviation used (given, or pooled from the repeats).
    map_point : ndarray of shape (d,)
        The parameters at the chains' start, the maximum a posteriori point.
    acceptance_rate : float
        Fraction of steps that moved.
    sampler : str
        The MCMC algorithm.
    n_likelihood_evaluations : int
        Likelihood evaluations (points) by the chains.
    n_evaluations : int
        Model evaluations (points).
    sampling_seconds : float
        Wall time of the chains, s.
    prediction : DiscrepancyPrediction or None
        Predictions at ``predict_at`` (None without).
    emulator_runs : int
        Model runs of the emulator's design (0: the chains ran the model itself).
    emulator_loo_ratio : ndarray of shape (n_responses,)
        The emulator's largest leave-one-out RMS error over the data configurations, over the
        noise std (empty without an emulator).
    emulator_posterior_ratio : ndarray of shape (n_responses,)
        The RMS of emulator mean - model at the ``n_draws`` posterior draws and the data
        configurations, over the noise std (empty without an emulator).
    """

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    configuration_name: str
    discrepancy: Discrepancy | None
    chains: np.ndarray
    hyper_names: tuple[str, ...]
    hyper_chains: np.ndarray
    log_posterior: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    credible_interval_95: np.ndarray
    ess: np.ndarray
    rhat: np.ndarray
    prior_std: np.ndarray
    std_ratio_to_prior: np.ndarray
    std_without_discrepancy: np.ndarray
    std_ratio_to_no_discrepancy: np.ndarray
    configurations: np.ndarray
    discrepancy_at_data: np.ndarray
    level_correlation: np.ndarray
    confounded: np.ndarray
    confounding_threshold: float
    identifiability: str
    noise_std: np.ndarray
    map_point: np.ndarray
    acceptance_rate: float
    sampler: str
    n_likelihood_evaluations: int
    n_evaluations: int
    sampling_seconds: float
    prediction: DiscrepancyPrediction | None = None
    _post: _Posterior | None = field(default=None, repr=False, compare=False)
    emulator_runs: int = 0
    emulator_loo_ratio: np.ndarray = field(default_factory=lambda: np.zeros(0))
    emulator_posterior_ratio: np.ndarray = field(default_factory=lambda: np.zeros(0))



def _data(data, configurations, names_out, model, noise_std):
    y = np.asarray(data, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    xc = np.asarray(configurations, dtype=float).reshape(-1)
    if y.ndim != 2 or y.shape[0] != xc.size:
        raise ModelShapeError(f"data must be (n_observations, n_responses) with one "
                              f"configuration per row; got data {np.shape(data)} and "
                              f"{xc.size} configurations")
    if not np.all(np.isfinite(y)) or not np.all(np.isfinite(xc)):
        raise ParameterError("data and configurations must be finite")
    all_out = tuple(model.names_out)
    names = all_out if names_out is None else tuple(names_out)
    unknown = [n for n in names if n not in all_out]
    if unknown:
        raise ParameterError(f"responses {unknown} are not outputs of the model; its outputs "
                             f"are {list(all_out)}")
    if len(names) != y.shape[1]:
        raise ModelShapeError(f"data has {y.shape[1]} columns but {len(names)} responses "
                              f"{names} are calibrated")
    xs, inv, counts = np.unique(xc, return_inverse=True, return_counts=True)
    m = y.shape[1]
    ybar = np.zeros((xs.size, m))
    np.add.at(ybar, inv, y)
    ybar /= counts[:, None]
    if noise_std is None:
        dof = y.shape[0] - xs.size
        if dof < 1:
            raise ParameterError(
                "validation data without repeats needs a stated measurement uncertainty: give "
                "noise_std (no configuration has two observations to estimate it from)")
        sd = np.sqrt(((y - ybar[inv]) ** 2).sum(0) / dof)
    else:
        sd = np.broadcast_to(np.asarray(noise_std, dtype=float), (m,)).copy() \
            if np.size(noise_std) in (1, m) else None
        if sd is None:
            raise ModelShapeError(f"noise_std must be a scalar or one per response ({m}), got "
                                  f"shape {np.shape(noise_std)}")
    if np.any(~np.isfinite(sd)) or np.any(sd <= 0):
        raise ParameterError(f"noise_std must be finite and > 0, got {sd}")
    resp_idx = np.array([all_out.index(n) for n in names])
    return names, xs, ybar, counts, sd, resp_idx, y


def _map_and_covariance(post: _Posterior, z0: np.ndarray, zlo, zhi,
                        flat: np.ndarray | None = None):
    """MAP in scaled coordinates, the inverse finite-difference Hessian of the negative log
    posterior there (:func:`.fd_noise.noisy_hessian`: each direction's step from its noise
    level and curvature; eigenvalues floored), and whether that Hessian was finite and
    positive definite (else the covariance is only a usable proposal, not a Laplace
    approximation).
    ``flat`` (D,) marks coordinates whose prior is uniform: they get the curvature of a
    normal prior of the same variance (Dakota's choice), or a direction the data do not inform
    would make every correlated parameter's variance unbounded."""
    big = 1e30
    D = z0.size
    step = 1e-5 * np.eye(D)

    def f(z):
        v = post(z[None])[0]
        return -v if np.isfinite(v) else big

    def fg(z):  # value and central-difference gradient from one batch of 2 D + 1 points
        v = -post(np.vstack([z[None], z + step, z - step]))
        if not np.all(np.isfinite(v)):
            return (v[0] if np.isfinite(v[0]) else big), np.zeros(D)
        return v[0], (v[1:D + 1] - v[D + 1:]) / 2e-5

    bounds = list(zip(np.where(np.isfinite(zlo), zlo, None), np.where(np.isfinite(zhi), zhi,
                                                                       None), strict=True))
    if np.all(np.isinf(zlo)) and np.all(np.isinf(zhi)):
        res = optimize.minimize(fg, z0, jac=True, method="BFGS", options={"maxiter": 500})
    else:
        res = optimize.minimize(fg, z0, jac=True, method="L-BFGS-B", bounds=bounds,
                                options={"maxiter": 500})
    zm = res.x if f(res.x) <= f(z0) else z0
    # the log posterior carries numerical noise (a trim iteration, an emulator): each
    # direction's second-difference step comes from its measured noise level and curvature,
    # as a fixed small step gives a curvature that is mostly noise; the stencil stays inside
    # a bounded prior's support (a MAP on its edge moved inside by its reach)
    zh = np.clip(zm, zlo + _EDGE, zhi - _EDGE)
    reach = np.minimum(1.0, np.minimum(zh - zlo, zhi - zh))
    with np.errstate(invalid="ignore"):
        est = noisy_hessian(lambda z: -post(z), zh, max_step=reach)
    H = est.hessian
    if not np.all(np.isfinite(H)):  # at the edge of the support: no Laplace approximation
        return zm, np.eye(D), False
    flat_f = np.zeros(D) if flat is None else flat.astype(float)
    # a direction without measurable curvature: the prior's scale (unit variance in scaled
    # coordinates), not a floored curvature's unbounded variance
    H[np.diag_indices(D)] = np.where(est.measured, H[np.diag_indices(D)], 1.0 - flat_f)
    # a uniform prior's coordinate: the curvature of a normal prior of the same variance
    H[np.diag_indices(D)] += flat_f
    w, V = np.linalg.eigh(0.5 * (H + H.T))
    ok = bool(w.min() > 0) and np.array_equal(zh, zm)
    w = np.maximum(w, max(w.max(), 1.0) * 1e-8)
    return zm, (V / w) @ V.T, ok


def calibrate_with_discrepancy(
    model: Model,
    data: ArrayLike,
    prior: ParameterSpace,
    *,
    configurations: ArrayLike,
    configuration_name: str,
    discrepancy: Discrepancy | None = Discrepancy(),
    noise_std: ArrayLike | None = None,
    names_out: Sequence[str] | None = None,
    sampler: str | SamplerConfig = "dram",
    n_samples: int = 10_000,
    burn_in: int | None = None,
    thin: int = 1,
    n_chains: int = 1,
    n_draws: int = 1000,
    predict_at: ArrayLike | None = None,
    confounding_threshold: float = 0.5,
    seed: SeedLike = None,
    emulator: EmulatorOptions | None = None,
) -> DiscrepancyResult:
    """Calibrate ``prior``'s parameters of ``model`` jointly with an additive discrepancy.

    Parameters
    ----------
    model : Model whose inputs are the parameters of ``prior`` and ``configuration_name``.
    data : (n_observations, n_responses) observations (repeats allowed), or (n_observations,)
        for one response.
    prior : ParameterSpace of the calibrated parameters.
    configurations : (n_observations,) the configuration of each row of ``data``, in the units
        of the model input ``configuration_name`` (e.g. H/R).
    configuration_name : the model input that varies between experiments.
    discrepancy : a :class:`Discrepancy`, or None to calibrate without one (the classical
        likelihood over all configurations).
    noise_std : measurement noise std, scalar or one per response (data units). Default: the
        pooled standard deviation of the repeats per response (an error when there are none).
    names_out : the model responses ``data`` observes (default all, in order).
    sampler : "dram" (default), "am", "dr", "mh" or a :class:`SamplerConfig`.
    n_samples : kept steps per chain.
    burn_in : steps dropped first (default ``n_samples // 4``).
    thin : keep every ``thin``-th step.
    n_chains : chains.
    n_draws : posterior samples pushed through the model and the discrepancy's conditional
        (``discrepancy_at_data``, the identifiability measures, the prediction).
    predict_at : configurations at which to predict (e.g. a held-out height); see
        :func:`predict_with_discrepancy`.
    confounding_threshold : |posterior correlation| between a parameter and a discrepancy's
        mean level from which the parameter is reported as confounded.
    seed : int, SeedSequence or Generator; the same seed gives bitwise the same result.
    emulator : an :class:`~rotoruq.methods.mcmc.options.EmulatorOptions` with an unfitted
        GaussianProcess: the chains run on it instead of the model (one output per data
        configuration and response, fitted on ``n_emulator_samples`` LHS points of the prior,
        each run at every data configuration), its Kriging variance added to each point's
        diagonal of the likelihood's covariance when ``emulator_variance`` (the emulator's
        errors across configurations taken as independent). The model itself still gives the
        posterior draws (the discrepancy's conditional, the predictions), where the emulator
        is checked (``emulator_posterior_ratio``), beside its leave-one-out error
        (``emulator_loo_ratio``). None (default): the chains run the model.

    Returns
    -------
    DiscrepancyResult

    Examples
    --------
    >>> import numpy as np, rotoruq as rq
    >>> from rotoruq.model import FunctionModel
    >>> m = FunctionModel(lambda x: x[:, 0] * np.exp(-x[:, 1]), ["a", "h"], ["y"])
    >>> h = np.repeat([1.0, 2.0, 3.0], 3)
    >>> y = 2.0 * np.exp(-h) + 0.1 * (h - 2.0) ** 2
    >>> prior = rq.ParameterSpace({"a": rq.Normal(mean=2.0, std=0.5)})
    >>> res = calibrate_with_discrepancy(m, y, prior, configurations=h,
    ...     configuration_name="h", noise_std=0.02, n_samples=500, n_draws=100,
    ...     discrepancy=Discrepancy(amplitude_scale=0.2), seed=1)
    >>> res.chains.shape
    (1, 500, 1)
    """
    n_samples, thin, n_chains, n_draws = int(n_samples), int(thin), int(n_chains), int(n_draws)
    burn_in = n_samples // 4 if burn_in is None else int(burn_in)
    if n_samples < 2 or thin < 1 or n_chains < 1 or burn_in < 0 or n_draws < 2:
        raise ParameterError(f"need n_samples >= 2, burn_in >= 0, thin >= 1, n_chains >= 1 "
                             f"and n_draws >= 2; got {n_samples}, {burn_in}, {thin}, "
                             f"{n_chains}, {n_draws}")
    if discrepancy is not None and not isinstance(discrepancy, Discrepancy):
        raise ParameterError(f"discrepancy must be a Discrepancy or None, got {discrepancy!r}")
    cfg = sampler if isinstance(sampler, SamplerConfig) else SamplerConfig(sampler=str(sampler))
    names, xs, ybar, counts, sd, resp_idx, y = _data(data, configurations, names_out, model,
                                                     noise_std)
    m, d = len(names), prior.dim
    if discrepancy is not None and discrepancy.kind == "gp" and xs.size < 2:
        raise ParameterError("a GP discrepancy needs data at two configurations or more, got "
                             f"{xs.size}")
    forward = _Forward(model, tuple(prior.names), configuration_name, resp_idx)
    amp = (np.sqrt(np.mean(y**2, axis=0)) if discrepancy is None
           or discrepancy.amplitude_scale is None
           else np.broadcast_to(np.asarray(discrepancy.amplitude_scale, float), (m,)).copy())
    amp = np.where(amp > 0, amp, 1.0)
    ell = float(discrepancy.length_scale) if discrepancy is not None and \
        discrepancy.length_scale is not None else float(max(np.ptp(xs), 1e-12))
    form = _Form(discrepancy, xs, amp, ell)
    rng = as_generator(seed)
    r_chain, r_start, r_draw, r_pred = rng.spawn(4)

    logprior = LogPrior(prior)
    tc, ts = prior_scales(prior)
    hc, hs = form.hyper_center_scale()
    center, scale = np.concatenate([tc, hc]), np.concatenate([ts, hs])
    var_mean = (sd**2)[:, None] / counts[None, :]
    emulated = None
    if emulator is not None:  # children spawned after the four above: those stay as they are
        r_design, r_fit = rng.spawn(2)
        emulated = _Emulated(forward, prior, xs, emulator, r_design,
                             int(r_fit.integers(2**63)))
    post = _Posterior(forward, logprior, form, xs, ybar, var_mean, center, scale, d, emulated)
    zlo = np.concatenate([(logprior.lo - tc) / ts, np.full(form.n_hyper, -np.inf)])
    zhi = np.concatenate([(logprior.hi - tc) / ts, np.full(form.n_hyper, np.inf)])
    z0 = np.zeros(d + form.n_hyper)
    if not np.isfinite(post(z0[None])[0]):
        raise ParameterError(f"the log posterior is not finite at the prior mean {tc} of "
                             f"{prior.names}: the model fails there or the prior is degenerate")
    flat = np.array([isinstance(dist, Uniform) for dist in prior.distributions]
                    + [False] * form.n_hyper)
    zm, cov, _ = _map_and_covariance(post, z0, zlo, zhi, flat)
    D = zm.size
    L0 = np.linalg.cholesky(2.38**2 / D * cov + 1e-12 * np.eye(D))
    x_start = np.repeat(zm[None], n_chains, axis=0)
    lp_start = np.full(n_chains, post(zm[None])[0])
    if n_chains > 1:
        cand = zm + r_start.standard_normal((n_chains - 1, D)) @ np.linalg.cholesky(
            cov + 1e-12 * np.eye(D)).T
        lpc = post(cand)
        good = np.isfinite(lpc)
        x_start[1:][good], lp_start[1:][good] = cand[good], lpc[good]
    state = SamplerState(x=x_start, lp=lp_start, chol=np.repeat(L0[None], n_chains, axis=0),
                         rng=r_chain)
    post.n_evals = 0
    t0 = time.perf_counter()
    kept, kept_lp = run_chains(post, state, cfg, n_samples, burn_in, thin)
    t_sampling = time.perf_counter() - t0
    n_lik = post.n_evals

    zch = kept.transpose(1, 0, 2)  # (c, n, D)
    phi = center + scale * zch
    theta_ch = phi[..., :d]
    hyper_ch = np.exp(phi[..., d:])
    flat_theta = theta_ch.reshape(-1, d)
    cnt = state.counts
    acc = (cnt["acc1"] + cnt["acc2"]) / max(cnt["prop1"], 1)

    # posterior draws of delta at the data configurations (and the predictions)
    flat_z = zch.reshape(-1, D)
    pick = r_draw.choice(flat_z.shape[0], n_draws, replace=flat_z.shape[0] < n_draws)
    th_d, hy_d = post.split(flat_z[pick])
    eta_d = forward(th_d, xs)  # the model itself, emulator or not
    checks: dict = {}
    if emulated is not None:
        with np.errstate(divide="ignore", invalid="ignore"):
            err = eta_d - emulated(th_d)[0]
            checks = dict(
                emulator_runs=emulated.build.n_evaluations,
                emulator_loo_ratio=emulated.loo.rmse.reshape(emulated.shape).max(0) / sd,
                emulator_posterior_ratio=np.sqrt(np.mean(err**2, axis=(0, 1))) / sd)
    delta_d = _conditional_draws(post, eta_d, hy_d, xs, r_draw)
    level = delta_d.mean(axis=1)  # (n_draws, m)
    corr = np.zeros((d, m))
    for j in range(d):
        for r in range(m):
            a, b = th_d[:, j], level[:, r]
            if a.std() > 0 and b.std() > 0:
                corr[j, r] = float(np.corrcoef(a, b)[0, 1])
    confounded = np.any(np.abs(corr) >= confounding_threshold, axis=1)

    std = flat_theta.std(axis=0, ddof=1)
    prior_std = prior.std.astype(float)
    std_without = _laplace_std_without(post, d, tc, ts, zlo[:d], zhi[:d], flat[:d])
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio_prior = std / prior_std
        ratio_without = std / std_without
    ident = _identifiability_text(prior.names, names, corr, confounded, ratio_prior,
                                  ratio_without, discrepancy, confounding_threshold)
    hyper_names = () if form.n_hyper == 0 else tuple(
        [f"amplitude[{n}]" for n in names] + [f"length_scale[{n}]" for n in names])
    ess, rhat = dg.ess_and_rhat(zch)
    res = DiscrepancyResult(
        names_in=tuple(prior.names), names_out=names, configuration_name=configuration_name,
        discrepancy=discrepancy, chains=theta_ch, hyper_names=hyper_names,
        hyper_chains=hyper_ch, log_posterior=kept_lp.T, mean=flat_theta.mean(axis=0), std=std,
        credible_interval_95=np.quantile(flat_theta, [0.025, 0.975], axis=0).T,
        ess=ess, rhat=rhat, prior_std=prior_std,
        std_ratio_to_prior=ratio_prior, std_without_discrepancy=std_without,
        std_ratio_to_no_discrepancy=ratio_without, configurations=xs,
        discrepancy_at_data=delta_d, level_correlation=corr, confounded=confounded,
        confounding_threshold=float(confounding_threshold), identifiability=ident,
        noise_std=sd, map_point=(center + scale * zm)[:d], acceptance_rate=float(acc),
        sampler=cfg.sampler, n_likelihood_evaluations=int(n_lik),
        n_evaluations=forward.n_evaluations, sampling_seconds=t_sampling, _post=post, **checks)
    if predict_at is not None:
        pred = predict_with_discrepancy(res, model, predict_at, n_draws=n_draws, seed=r_pred)
        res = DiscrepancyResult(**{**{f: getattr(res, f) for f in res.__dataclass_fields__},
                                   "prediction": pred})
    return res


def _conditional_draws(post: _Posterior, eta_data: np.ndarray, hyper: np.ndarray,
                       xp: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Draws (k, n_p, m) of delta at xp given the residuals ``ybar - eta_data`` (k, n_c, m):
    mean ``K_pc C^-1 r``, covariance ``K_pp - K_pc C^-1 K_cp`` with ``C = K_cc + D``."""
    k, m = eta_data.shape[0], post.ybar.shape[1]
    if post.form.spec is None:
        return np.zeros((k, xp.size, m))
    xs = post.xs
    resid = (post.ybar[None] - eta_data).transpose(0, 2, 1)[..., None]  # (k, m, nc, 1)
    C = post.form.cov(hyper, xs, xs).copy()
    idx = np.arange(xs.size)
    C[:, :, idx, idx] += post.var_mean[None]
    Kpc = post.form.cov(hyper, xp, xs)
    Kpp = post.form.cov(hyper, xp, xp)
    L = np.linalg.cholesky(C)
    A = np.linalg.solve(L, Kpc.transpose(0, 1, 3, 2))  # L^-1 K_cp
    w = np.linalg.solve(L, resid)
    mean = (A.transpose(0, 1, 3, 2) @ w)[..., 0]  # (k, m, np)
    cov = Kpp - A.transpose(0, 1, 3, 2) @ A
    cov = 0.5 * (cov + cov.transpose(0, 1, 3, 2))
    w_eig, V = np.linalg.eigh(cov)
    root = V * np.sqrt(np.maximum(w_eig, 0.0))[..., None, :]
    z = rng.standard_normal((k, m, xp.size, 1))
    return (mean + (root @ z)[..., 0]).transpose(0, 2, 1)


def _laplace_std_without(post: _Posterior, d: int, tc, ts, zlo, zhi,
                         flat: np.ndarray) -> np.ndarray:
    """Posterior std (d,) of the parameters calibrated without discrepancy (Laplace at the
    MAP): the reference for the identifiability ratio."""
    plain = _Posterior(post.forward, post.logprior, _Form(None, post.xs, post.form.amp_scale,
                                                          post.form.ell_median),
                       post.xs, post.ybar, post.var_mean, tc, ts, d, post.emulated)
    _, cov, ok = _map_and_covariance(plain, np.zeros(d), zlo, zhi, flat)
    if not ok:
        return np.full(d, np.nan)
    # a direction the data do not inform is flat under a uniform prior: its posterior std is
    # the prior's, not the floored curvature's
    return np.minimum(np.sqrt(np.diag(cov)) * ts, post.logprior.space.std.astype(float))


#: Posterior/prior std from which a parameter counts as barely informed by the data (the
#: report's threshold, rotoruq.report.diagnostics.STD_RATIO_MAX).
_PRIOR_BOUND = 0.8


def _identifiability_text(names_in, names_out, corr, confounded, ratio_prior, ratio_without,
                          discrepancy, threshold) -> str:
    if discrepancy is None:
        return "no discrepancy: the parameters absorb any model-form error"
    parts = []
    for j, n in enumerate(names_in):
        r = int(np.argmax(np.abs(corr[j])))
        s = (f"{n}: posterior/prior std {ratio_prior[j]:.2f}, with/without discrepancy "
             f"{ratio_without[j]:.2f}, correlation with the {names_out[r]} discrepancy level "
             f"{corr[j, r]:+.2f}")
        if confounded[j] and ratio_prior[j] >= _PRIOR_BOUND:
            s += (f" (|corr| >= {threshold:g}: confounded with the discrepancy, and the data "
                  f"barely narrow it (posterior/prior std >= {_PRIOR_BOUND:g}): its value "
                  "rests on the priors)")
        elif confounded[j]:
            # the data pin a combination of the parameter and the discrepancy's level: the
            # parameter is narrow, but its value moves with the level the discrepancy takes
            s += (f" (|corr| >= {threshold:g}: traded against the discrepancy's level; the "
                  f"data narrow it to {ratio_prior[j]:.2f} of its prior std only jointly with "
                  "that level, so its value is as uncertain as the discrepancy's level)")
        parts.append(s)
    return "; ".join(parts)


def predict_with_discrepancy(result: DiscrepancyResult, model: Model,
                             configurations: ArrayLike, *, n_draws: int = 1000,
                             quantile_levels: Sequence[float] = (0.05, 0.5, 0.95),
                             seed: SeedLike = None) -> DiscrepancyPrediction:
    """Posterior predictive at new configurations, with and without the discrepancy.

    For ``n_draws`` posterior samples ``(theta, hyperparameters)``: ``eta(x, theta)`` from the
    model, ``delta(x)`` from its conditional Gaussian given that sample's residuals at the data
    configurations (jointly over the requested configurations), and the noise ``eps ~ N(0,
    noise_std^2)`` of a new observation.

    Parameters
    ----------
    result : a :class:`DiscrepancyResult` of :func:`calibrate_with_discrepancy`.
    model : the model it was calibrated with.
    configurations : (n_conditions,) values of the configuration variable (e.g. a held-out
        height).
    n_draws : posterior samples used.
    quantile_levels : probabilities in (0, 1) of the quantiles reported (default 0.05, 0.5,
        0.95).
    seed : int, SeedSequence or Generator.

    Returns
    -------
    DiscrepancyPrediction with arrays (n_draws, n_conditions, n_responses).

    Examples
    --------
    >>> # pred = predict_with_discrepancy(res, model, [1.0], n_draws=500, seed=2)
    >>> # pred.quantiles.shape == (3, 1, len(res.names_out))
    """
    post = result._post
    if post is None:
        raise ParameterError("this DiscrepancyResult carries no posterior to predict from")
    xp = np.asarray(configurations, dtype=float).reshape(-1)
    if xp.size == 0 or not np.all(np.isfinite(xp)):
        raise ParameterError(f"configurations must be finite values, got {xp}")
    q = np.asarray(quantile_levels, dtype=float)
    if q.ndim != 1 or np.any((q <= 0) | (q >= 1)):
        raise ParameterError(f"quantile_levels must be in (0, 1), got {q}")
    if int(n_draws) < 2:
        raise ParameterError(f"n_draws must be >= 2, got {n_draws}")
    if tuple(model.names_out) != tuple(post.forward.model.names_out) or \
            tuple(model.names_in) != tuple(post.forward.model.names_in):
        raise ParameterError("predict with the model the result was calibrated with (its inputs "
                             f"{list(post.forward.model.names_in)} and outputs "
                             f"{list(post.forward.model.names_out)})")
    rng = as_generator(seed)
    d = post.d
    flat = np.concatenate([result.chains, np.log(result.hyper_chains)], axis=-1).reshape(
        -1, d + len(result.hyper_names))
    pick = rng.choice(flat.shape[0], int(n_draws), replace=flat.shape[0] < int(n_draws))
    theta, hyper = flat[pick, :d], flat[pick, d:]
    fwd = _Forward(model, result.names_in, result.configuration_name, post.forward.resp_idx)
    eta_all = fwd(theta, np.concatenate([post.xs, xp]))
    eta_data, eta_p = eta_all[:, :post.xs.size], eta_all[:, post.xs.size:]
    delta = _conditional_draws(post, eta_data, hyper, xp, rng)
    noise = rng.standard_normal(eta_p.shape) * result.noise_std[None, None, :]
    with_d = eta_p + delta + noise
    without = eta_p + noise
    return DiscrepancyPrediction(
        configuration_name=result.configuration_name, configurations=xp,
        names_out=result.names_out, model_draws=eta_p, discrepancy_draws=delta,
        noise_draws=noise, quantile_levels=q, quantiles=np.quantile(with_d, q, axis=0),
        quantiles_without=np.quantile(without, q, axis=0), mean=with_d.mean(0),
        std=with_d.std(0, ddof=1), mean_without=without.mean(0),
        std_without=without.std(0, ddof=1))
