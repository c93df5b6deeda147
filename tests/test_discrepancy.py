"""Calibration with a Kennedy-O'Hagan discrepancy: a conjugate closed form, the marginal
likelihood against scipy, recovery of known parameters and discrepancy, held-out coverage over
repeated synthetic data sets (with and without discrepancy), determinism and bad input."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

import rotoruq as rq
from rotoruq.errors import ParameterError
from rotoruq.methods.mcmc import EmulatorOptions
from rotoruq.methods.mcmc.discrepancy import (
    Discrepancy,
    calibrate_with_discrepancy,
    predict_with_discrepancy,
)


def const_model():
    """eta(h, a) = a: whatever the data say about a level, a and a constant offset share."""
    return rq.FunctionModel(lambda x: x[:, 0] + 0.0 * x[:, 1], ["a", "h"], ["y"])


def decay_model():
    """eta(h; a, c) = a exp(-c h): a load that decays with the configuration."""
    return rq.FunctionModel(lambda x: x[:, 0] * np.exp(-x[:, 1] * x[:, 2]), ["a", "c", "h"],
                            ["y"])


# --- conjugate closed form: constant model, constant (degree-0) discrepancy -----------------

M0, T0, SIG = 1.0, 0.5, 0.2
H_CONST = np.repeat([1.0, 2.0, 3.0], 4)


@pytest.mark.parametrize("S_B", [0.3, 0.01])
def test_constant_offset_matches_conjugate_posterior(S_B):
    # y_i = a + b + eps, a ~ N(M0, T0^2), b ~ N(0, S_B^2): the posterior is Gaussian and the
    # data inform only a + b, so a and b are confounded (correlation near -1) unless the
    # offset's prior is narrow.
    y = 1.6 + SIG * np.random.default_rng(0).standard_normal(H_CONST.size)
    n = y.size
    prior = rq.ParameterSpace({"a": rq.Normal(M0, T0)})
    res = calibrate_with_discrepancy(
        const_model(), y, prior, configurations=H_CONST, configuration_name="h",
        discrepancy=Discrepancy(kind="polynomial", degree=0, amplitude_scale=S_B),
        noise_std=SIG, n_samples=3000, n_chains=2, n_draws=4000, predict_at=[0.0], seed=3)
    T = T0**2 + S_B**2 + SIG**2 / n
    mean_a = M0 + T0**2 / T * (y.mean() - M0)
    var_a = T0**2 - T0**4 / T
    var_b = S_B**2 - S_B**4 / T
    corr_ab = -T0**2 * S_B**2 / T / np.sqrt(var_a * var_b)
    ess = float(res.ess[0])
    assert ess > 500
    se = np.sqrt(var_a / ess)
    assert abs(res.mean[0] - mean_a) < 4 * se
    assert abs(res.std[0] / np.sqrt(var_a) - 1) < 4 / np.sqrt(2 * ess)
    assert abs(res.level_correlation[0, 0] - corr_ab) < max(0.02, 4 / np.sqrt(ess))
    assert res.confounded[0] == (abs(corr_ab) >= 0.5)
    # without discrepancy the posterior is N with precision 1/T0^2 + n/SIG^2 (Laplace exact)
    sd_plain = np.sqrt(1.0 / (1.0 / T0**2 + n / SIG**2))
    assert res.std_without_discrepancy[0] == pytest.approx(sd_plain, rel=1e-4)
    assert res.std_ratio_to_prior[0] == pytest.approx(res.std[0] / T0)
    # prediction of a new observation: (a + b) | y plus noise
    v_sum = T0**2 + S_B**2
    mean_p = M0 + v_sum / T * (y.mean() - M0)
    sd_p = np.sqrt(v_sum - v_sum**2 / T + SIG**2)
    pred = res.prediction
    assert pred.model_draws.shape == (4000, 1, 1)
    assert abs(pred.mean[0, 0] - mean_p) < 4 * sd_p / np.sqrt(ess)
    assert abs(pred.std[0, 0] / sd_p - 1) < 0.05
    # without the discrepancy the same draws are a + eps: a is anti-correlated with b, so
    # this spread is wider than that of a + b + eps
    assert abs(pred.std_without[0, 0] / np.sqrt(var_a + SIG**2) - 1) < 0.05


# --- the marginal likelihood against scipy on the full data ---------------------------------

@pytest.mark.parametrize("kernel", ["squared_exponential", "matern52"])
def test_marginal_likelihood_matches_full_gaussian(kernel):
    # log N(y; eta 1, sigma^2 I + Z K Z^T) over every observation differs from the
    # means-only form by a constant that depends on neither theta nor the hyperparameters.
    h = np.repeat([1.0, 2.5, 4.0], [2, 3, 4])
    y = np.exp(-0.4 * h) * 2.0 + 0.05 * np.random.default_rng(1).standard_normal(h.size)
    prior = rq.ParameterSpace({"a": rq.Normal(2.0, 0.3), "c": rq.Normal(0.4, 0.05)})
    res = calibrate_with_discrepancy(
        decay_model(), y, prior, configurations=h, configuration_name="h",
        discrepancy=Discrepancy(kernel=kernel, amplitude_scale=0.2), noise_std=0.05,
        n_samples=10, n_draws=2, seed=0)
    post = res._post
    diffs = []
    for a, c, amp, ell in [(2.0, 0.4, 0.1, 1.0), (1.7, 0.45, 0.3, 3.0), (2.2, 0.35, 0.05, 0.4)]:
        eta = a * np.exp(-c * post.xs)
        r = np.abs(h[:, None] - h[None, :]) / ell
        if kernel == "squared_exponential":
            K = amp**2 * np.exp(-0.5 * r**2)
        else:
            K = amp**2 * (1 + np.sqrt(5) * r + 5 * r**2 / 3) * np.exp(-np.sqrt(5) * r)
        full = stats.multivariate_normal(a * np.exp(-c * h), K + 0.05**2 * np.eye(h.size)).logpdf(y)
        ours = post.marginal_loglik(eta[None, :, None], np.log([[amp, ell]]))[0]
        diffs.append(full - ours)
    assert np.ptp(diffs) < 1e-6


# --- recovery on one synthetic data set with a known discrepancy ----------------------------

A_TRUE, C_TRUE = 2.0, 0.5
H_TRAIN = np.array([1.0, 2.0, 3.0, 4.0, 5.0])


def delta_true(h):
    return 0.15 * np.sin(1.4 * h)  # a shape that a exp(-c h) cannot take on


def test_parameters_and_discrepancy_recovered_and_plain_fit_is_biased():
    rng = np.random.default_rng(1)
    h = np.repeat(H_TRAIN, 4)
    sig = 0.02
    y = A_TRUE * np.exp(-C_TRUE * h) + delta_true(h) + sig * rng.standard_normal(h.size)
    prior = rq.ParameterSpace({"a": rq.Normal(2.1, 0.15), "c": rq.Normal(0.48, 0.04)})
    kw = dict(configurations=h, configuration_name="h", noise_std=sig, n_samples=3000,
              n_chains=2, n_draws=2000, seed=11)
    res = calibrate_with_discrepancy(decay_model(), y, prior,
                                     discrepancy=Discrepancy(amplitude_scale=0.2), **kw)
    ci = res.credible_interval(0.95)
    truth = np.array([A_TRUE, C_TRUE])
    assert np.all((ci[:, 0] < truth) & (truth < ci[:, 1])), (ci, truth)
    lo, hi = np.quantile(res.discrepancy_at_data, [0.025, 0.975], axis=0)
    dt = delta_true(res.configurations)[:, None]
    assert np.all((lo < dt) & (dt < hi)), (lo, hi, dt)
    assert np.all(res.rhat < 1.1)
    # the same data without discrepancy: a confident posterior that excludes the truth
    plain = calibrate_with_discrepancy(decay_model(), y, prior, discrepancy=None, **kw)
    ci0 = plain.credible_interval(0.95)
    assert not np.all((ci0[:, 0] < truth) & (truth < ci0[:, 1])), ci0
    assert np.all(plain.std < res.std)
    assert np.all(res.std_ratio_to_no_discrepancy > 2.0)
    assert res.std_without_discrepancy == pytest.approx(plain.std, rel=0.15)
    assert plain.hyper_chains.shape[-1] == 0 and np.all(plain.discrepancy_at_data == 0)


def _on_emulator(n_samples: int = 30, variance: bool = True) -> EmulatorOptions:
    return EmulatorOptions(rq.GaussianProcess(trend="linear"), n_emulator_samples=n_samples,
                           emulator_variance=variance)


def test_on_an_emulator_the_posterior_is_the_models_and_the_emulator_is_checked():
    """The chains on a GP emulator of eta (30 LHS points of the prior, each run at the five
    configurations; its variance in the likelihood) give the posterior the chains on the model
    give, within the Monte Carlo error of the two; the emulator's leave-one-out and posterior
    errors are recorded against the noise std, and the model itself makes the draws."""
    rng = np.random.default_rng(1)
    h = np.repeat(H_TRAIN, 4)
    sig = 0.02
    y = A_TRUE * np.exp(-C_TRUE * h) + delta_true(h) + sig * rng.standard_normal(h.size)
    prior = rq.ParameterSpace({"a": rq.Normal(2.1, 0.15), "c": rq.Normal(0.48, 0.04)})
    kw = dict(configurations=h, configuration_name="h", noise_std=sig, n_samples=3000,
              n_chains=2, n_draws=500, discrepancy=Discrepancy(amplitude_scale=0.2), seed=11)
    model = calibrate_with_discrepancy(decay_model(), y, prior, **kw)
    emu = calibrate_with_discrepancy(decay_model(), y, prior, emulator=_on_emulator(), **kw)
    assert model.emulator_runs == 0 and model.emulator_loo_ratio.size == 0
    assert emu.emulator_runs == 30
    assert emu.n_evaluations == 30 * H_TRAIN.size + 500 * H_TRAIN.size  # design, then draws
    assert np.all(emu.emulator_loo_ratio < 0.3) and np.all(emu.emulator_posterior_ratio < 0.3)
    ess = np.minimum(model.ess[:2], emu.ess[:2])
    se = np.sqrt(model.std**2 / ess + emu.std**2 / ess)
    assert np.all(np.abs(emu.mean - model.mean) < 4 * se), (emu.mean, model.mean, se)
    assert np.all(np.abs(emu.std / model.std - 1) < 4 * np.sqrt(2 / ess))


@pytest.mark.parametrize("kind", ["gp", "polynomial", "none"])
def test_an_emulators_variance_enters_each_points_covariance(kind):
    """marginal_loglik with an emulator variance v (k, n_c, m) is log N(ybar; eta,
    K_delta + diag(sigma^2 / n_c + v)) of each point (scipy), in the compiled GP kernel and in
    the per-point factors of the polynomial and no-discrepancy forms; v = 0 gives the value
    without it."""
    h = np.repeat([1.0, 2.5, 4.0], [2, 3, 4])
    y = np.exp(-0.4 * h) * 2.0 + 0.05 * np.random.default_rng(1).standard_normal(h.size)
    prior = rq.ParameterSpace({"a": rq.Normal(2.0, 0.3), "c": rq.Normal(0.4, 0.05)})
    spec = None if kind == "none" else Discrepancy(kind=kind, amplitude_scale=0.2)
    res = calibrate_with_discrepancy(
        decay_model(), y, prior, configurations=h, configuration_name="h", discrepancy=spec,
        noise_std=0.05, n_samples=10, n_draws=2, seed=0)
    post = res._post
    rng = np.random.default_rng(2)
    eta = 2.0 * np.exp(-0.4 * post.xs)[None, :, None] + 0.01 * rng.standard_normal((3, 3, 1))
    var = rng.uniform(0.0, 0.01, (3, 3, 1))
    hyper = np.log([[0.1, 1.0], [0.3, 3.0], [0.05, 0.4]])[:, :2 if kind == "gp" else 0]
    ours = post.marginal_loglik(eta, hyper, var)
    for i in range(3):
        K = post.form.cov(hyper[i:i + 1], post.xs, post.xs)[0, 0]
        C = K + np.diag(post.var_mean[0] + var[i, :, 0] + post._jitter)
        want = stats.multivariate_normal(eta[i, :, 0], C).logpdf(post.ybar[:, 0])
        assert ours[i] == pytest.approx(want, rel=1e-10, abs=1e-9)
    np.testing.assert_allclose(post.marginal_loglik(eta, hyper, np.zeros_like(var)),
                               post.marginal_loglik(eta, hyper), rtol=1e-12)


def test_a_crude_emulator_is_flagged_and_runs_repeat_bitwise():
    """Four design runs of a model not linear in c: the emulator's leave-one-out error is
    large against the noise, and recorded; the same seed gives the same bits."""
    kw = dict(discrepancy=Discrepancy(kind="polynomial", degree=1, amplitude_scale=0.1),
              n_samples=400, predict_at=[0.5])
    r1 = _small(5, emulator=_on_emulator(4), **kw)
    r2 = _small(5, emulator=_on_emulator(4), **kw)
    assert np.array_equal(r1.chains, r2.chains)
    assert np.array_equal(r1.prediction.with_discrepancy, r2.prediction.with_discrepancy)
    assert np.array_equal(r1.emulator_posterior_ratio, r2.emulator_posterior_ratio)
    assert r1.emulator_runs == 4 and r1.emulator_loo_ratio[0] > 0.3


# --- held-out coverage over repeated synthetic data sets ------------------------------------

H_ALL = np.array([1.0, 2.0, 3.0, 4.0])  # 1.0 is held out (the extreme one, as 1R)
AMP_S, ELL_MED, ELL_LSD, SIG_C = 0.3, 3.0, 0.5, 0.03


def _replicate(rng, spec):
    """Truth drawn from the prior (theta, hyperparameters, delta, noise): the Bayesian 90 %
    predictive interval then covers a new observation with probability 0.90 exactly."""
    a = rng.normal(2.0, 0.3)
    amp = abs(rng.normal(0.0, AMP_S))
    ell = np.exp(rng.normal(np.log(ELL_MED), ELL_LSD))
    r = np.abs(H_ALL[:, None] - H_ALL[None, :]) / ell
    K = amp**2 * np.exp(-0.5 * r**2) + 1e-12 * np.eye(H_ALL.size)
    delta = np.linalg.cholesky(K) @ rng.standard_normal(H_ALL.size)
    h = np.repeat(H_ALL[1:], 3)
    y = a * np.exp(-0.5 * h) + np.repeat(delta[1:], 3) + SIG_C * rng.standard_normal(h.size)
    y_new = a * np.exp(-0.5) + delta[0] + SIG_C * rng.standard_normal()
    return h, y, y_new


def _coverage(n_rep, discrepancy, seed):
    model = rq.FunctionModel(lambda x: x[:, 0] * np.exp(-0.5 * x[:, 1]), ["a", "h"], ["y"])
    prior = rq.ParameterSpace({"a": rq.Normal(2.0, 0.3)})
    ss = np.random.SeedSequence(seed)
    hits = []
    for data_seed, fit_seed in (s.spawn(2) for s in ss.spawn(n_rep)):
        h, y, y_new = _replicate(np.random.default_rng(data_seed), discrepancy)
        res = calibrate_with_discrepancy(
            model, y, prior, configurations=h, configuration_name="h",
            discrepancy=discrepancy, noise_std=SIG_C, n_samples=500, n_chains=4, n_draws=1000,
            predict_at=[1.0], seed=fit_seed)
        lo, hi = res.prediction.interval(0.9)
        hits.append(lo[0, 0] <= y_new <= hi[0, 0])
    return float(np.mean(hits))


N_REP = 80


@pytest.mark.slow
def test_held_out_coverage_nominal_with_discrepancy_and_low_without():
    spec = Discrepancy(amplitude_scale=AMP_S, length_scale=ELL_MED,
                       length_scale_log_std=ELL_LSD)
    cov = _coverage(N_REP, spec, 2024)
    se = np.sqrt(0.9 * 0.1 / N_REP)
    assert abs(cov - 0.9) < 3 * se, cov
    cov0 = _coverage(N_REP, None, 2024)  # the same data sets
    assert cov0 < 0.9 - 5 * se, cov0


def test_map_on_prior_bound_gives_no_laplace_std_and_exponential_posterior():
    # y = a h with data at a = 1.5 but a ~ U(0, 1): the posterior is the normal likelihood
    # truncated far from its mode, close to an exponential of rate (1.5 - 1) / s^2 below 1
    m = rq.FunctionModel(lambda x: x[:, 0] * x[:, 1], ["a", "h"], ["y"])
    h = np.repeat([1.0, 2.0], 3)
    res = calibrate_with_discrepancy(
        m, 1.5 * h, rq.ParameterSpace({"a": rq.Uniform(0.0, 1.0)}), configurations=h,
        configuration_name="h", discrepancy=None, noise_std=0.1, n_samples=4000, n_chains=2,
        n_draws=10, seed=0)
    s2 = 0.1**2 / np.sum(h**2)
    assert res.map_point[0] == pytest.approx(1.0, abs=1e-6)
    assert np.isnan(res.std_without_discrepancy[0])
    rate = 0.5 / s2
    assert res.std[0] == pytest.approx(1.0 / rate, rel=4 / np.sqrt(res.ess[0]))
    assert 1.0 - res.mean[0] == pytest.approx(1.0 / rate, rel=4 / np.sqrt(res.ess[0]))


# --- determinism and bad input --------------------------------------------------------------

def _small(seed, **kw):
    h = np.repeat([1.0, 2.0, 3.0], 3)
    y = 2.0 * np.exp(-0.5 * h) + 0.05 * np.sin(7 * h)
    prior = rq.ParameterSpace({"a": rq.Normal(2.0, 0.3), "c": rq.Normal(0.5, 0.05)})
    args = dict(configurations=h, configuration_name="h", noise_std=0.05, n_samples=200,
                n_draws=50, seed=seed)
    args.update(kw)
    return calibrate_with_discrepancy(decay_model(), y, prior, **args)


def test_same_seed_bitwise_same():
    r1, r2 = _small(5, predict_at=[0.5]), _small(5, predict_at=[0.5])
    assert np.array_equal(r1.chains, r2.chains)
    assert np.array_equal(r1.hyper_chains, r2.hyper_chains)
    assert np.array_equal(r1.prediction.with_discrepancy, r2.prediction.with_discrepancy)
    p1 = predict_with_discrepancy(r1, decay_model(), [0.0, 6.0], n_draws=30, seed=2)
    p2 = predict_with_discrepancy(r2, decay_model(), [0.0, 6.0], n_draws=30, seed=2)
    assert p1.quantiles.shape == (3, 2, 1)
    assert np.array_equal(p1.with_discrepancy, p2.with_discrepancy)
    assert not np.array_equal(_small(6).chains, r1.chains)


def test_bad_input_names_what_was_expected():
    with pytest.raises(ParameterError, match="'height' is not an input of the model"):
        _small(0, configuration_name="height")
    with pytest.raises(ParameterError, match="without repeats needs a stated measurement"):
        _small(0, configurations=[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0], noise_std=None)
    with pytest.raises(ParameterError, match="discrepancy kind must be one of"):
        Discrepancy(kind="spline")
    with pytest.raises(ParameterError, match="amplitude_scale must be finite and > 0"):
        Discrepancy(amplitude_scale=-1.0)
    with pytest.raises(ParameterError, match="noise_std must be finite and > 0"):
        _small(0, noise_std=0.0)


def test_noise_pooled_from_repeats():
    h = np.repeat([1.0, 2.0], 3)
    y = np.array([1.0, 1.2, 0.8, 2.0, 2.1, 1.9])
    prior = rq.ParameterSpace({"a": rq.Normal(1.5, 0.5)})
    res = calibrate_with_discrepancy(const_model(), y, prior, configurations=h,
                                     configuration_name="h", n_samples=20, n_draws=5, seed=0,
                                     discrepancy=Discrepancy(kind="polynomial", degree=1))
    pooled = np.sqrt((0.04 + 0.04 + 0.01 + 0.01) / (6 - 2))
    assert res.noise_std[0] == pytest.approx(pooled)


def test_the_identifiability_sentence_agrees_with_its_numbers():
    """A parameter correlated with the discrepancy's level is said to rest on its prior only
    when the data barely narrow it (posterior/prior std >= 0.8); one the data narrow (issue
    35: 0.08) is said to trade against the level, with its ratio."""
    from rotoruq.methods.mcmc.discrepancy import _identifiability_text

    corr = np.array([[-0.96], [-0.97]])
    text = _identifiability_text(("a", "b"), ("thrust",), corr, np.array([True, True]),
                                 np.array([0.08, 0.93]), np.array([5.0, 1.1]), Discrepancy(),
                                 0.5)
    a, b = text.split("; b: ")
    assert "posterior/prior std 0.08" in a and "rests on the priors" not in a
    assert "traded against the discrepancy's level" in a and "to 0.08 of its prior std" in a
    assert b.startswith("posterior/prior std 0.93") and "rests on the priors" in b


def test_the_extrapolation_flag_quotes_the_coverage_benchmark():
    """The warning of a prediction beyond the calibrated configurations gives its distance
    and the coverage benchmark's numbers, read from the JSON it wrote (and how far short of
    85 % when it is)."""
    import json
    from importlib import resources

    from rotoruq.steps._discrepancy import extrapolation_distance, extrapolation_note

    np.testing.assert_array_equal(extrapolation_distance([1.0, 2.5, 4.0, 5.0], [2.0, 3.0, 4.0]),
                                  [1.0, 0.0, 0.0, 1.0])
    cov = json.loads(resources.files("rotoruq.data").joinpath(
        "discrepancy_coverage.json").read_text())
    vals = [p["coverage"] for p in cov["problems"].values()]
    assert len(vals) >= 2 and cov["replications"] >= 100
    note = extrapolation_note(1.0, 2.0)
    assert note.startswith("an extrapolation, 1 beyond the calibrated range (0.5 x the "
                           "calibrated range)")
    assert f"covered the truth {min(vals):.2f} to {max(vals):.2f} of the time" in note
    assert ("short of 0.85" in note) == (min(vals) < 0.85)
