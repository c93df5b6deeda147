"""calibrate_bayes with a co-kriging emulator (issue 26): the exact posterior recovered from
few high-fidelity runs, the emulator's variance in the likelihood, coverage, determinism,
refinement and bad input.

The analytic pair: HF ``y = 2 t + 0.1 sin(6 pi t)`` (a wiggle of three periods on the prior
U(0, 1) that six runs cannot resolve), LF ``0.8 y_hf + 0.3 (t - 0.5)`` (scaled and biased).
Its exact posterior is a 1-D integral, done here on a grid of 200,001 points (quadrature
error far below the tolerances).
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import multivariate_normal

import rotoruq as rq
from rotoruq.errors import ParameterError
from rotoruq.methods.mcmc.adequacy import RefineConfig

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from cokriging_calibration import (  # noqa: E402  (the analytic pair has one home)
    GRID,
    NOISE,
    exact_posterior,
    grid_moments,
    hf_response,
    lf_response,
)

pytestmark = pytest.mark.filterwarnings("ignore::rotoruq.methods.surrogate.ExtrapolationWarning")

PRIOR = rq.ParameterSpace({"t": rq.Uniform(0.0, 1.0)})
HF = rq.FunctionModel(lambda x: hf_response(x[:, :1]), ["t"], ["y"])
LF = rq.FunctionModel(lambda x: lf_response(x[:, :1]), ["t"], ["y"])


def _data(theta=0.37, n_exp=3, seed=1):
    rng = np.random.default_rng(seed)
    return hf_response(np.array([theta])) + NOISE * rng.standard_normal((n_exp, 1))


def _emulated(ck, data, variance):
    """Posterior mean and std with the emulator's mean and, with ``variance``, its variance
    shared by the experiments (the stacked Gaussian, in closed form for one response:
    covariance s^2 I + v 11^T)."""
    mean, var = ck.predict(GRID[:, None])
    mean, var = mean[:, 0], var[:, 0] if variance else np.zeros(GRID.size)
    n, s2 = data.shape[0], NOISE**2
    r = data[:, 0][None, :] - mean[:, None]
    ll = -0.5 * ((r**2).sum(1) - var * r.sum(1) ** 2 / (s2 + n * var)) / s2 \
        - 0.5 * np.log1p(n * var / s2)
    return grid_moments(ll)


def _calibrate(emulator, data=None, seed=3, self_check=0, **fields):
    """calibrate_bayes with the fields of its option records given flat (test shorthand)."""
    from rotoruq.methods.mcmc.options import LEGACY_KEYWORDS, legacy_keywords

    flat = dict(noise_std=NOISE, n_samples=4000, n_chains=2, n_emulator_samples=6)
    flat.update(fields)
    rec = legacy_keywords("_calibrate", flat, LEGACY_KEYWORDS, warn=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # emulator error over the posterior
        return rq.calibrate_bayes(HF, _data() if data is None else data, PRIOR,
                                  noise=rq.NoiseModel(**rec["noise"]),
                                  chains=rq.ChainOptions(**rec["chains"]),
                                  emulator=rq.EmulatorOptions(emulator, **rec["emulator"]),
                                  self_check=self_check, seed=seed)


@pytest.fixture(scope="module")
def pair():
    """Co-kriging (6 HF + 30 LF runs) and a GP on the same 6 HF runs, same seed."""
    return (_calibrate(rq.CoKriging(low_fidelity=LF, n_low=30)),
            _calibrate(rq.GaussianProcess()))


def test_cokriging_posterior_is_the_exact_one_and_a_gp_on_the_same_runs_is_not(pair):
    """Six HF runs: the co-kriging posterior's mean is within 0.2 exact stds of the exact
    mean and its std within 10 %; the GP's mean on the same six runs is more than 5 exact
    stds off (and 20x the co-kriging's error)."""
    ck, gp = pair
    m, s = exact_posterior(_data())
    err_ck, err_gp = abs(ck.mean[0] - m) / s, abs(gp.mean[0] - m) / s
    assert err_ck < 0.2, (ck.mean, m, s)
    assert ck.std[0] == pytest.approx(s, rel=0.1)
    assert err_gp > 5.0 and err_gp > 20 * err_ck, (err_gp, err_ck)
    # the nested design: the GP's six HF points, inside the 30 LF points
    (x_lf, _), (x_hf, y_hf) = ck.emulator.training_data
    np.testing.assert_array_equal(x_hf, gp.emulator._X)
    assert x_lf.shape == (30, 1) and all(np.any(np.all(x_lf == x, 1)) for x in x_hf)
    np.testing.assert_array_equal(y_hf, hf_response(x_hf))
    assert ck.n_evaluations == 6 and ck.n_low_fidelity_evaluations == (30,)
    assert gp.n_low_fidelity_evaluations == ()
    # LOO at the HF runs and the adequacy see a near-exact emulator
    assert ck.emulator_loo.errors.shape == (6, 1) and ck.emulator_loo.rmse[0] < 0.01 * NOISE
    assert ck.emulator_adequacy.posterior_ratio[0] < 0.01
    assert gp.emulator_adequacy.posterior_ratio[0] > 1.0


def test_log_posterior_is_prior_plus_the_stacked_gaussian_with_the_cokriging_variance(pair):
    """The chains' log posterior at a few thetas equals the Gaussian density of the stacked
    observations with covariance noise + the co-kriging variance shared by the experiments
    (1e-10): the GP's likelihood, with the co-kriging mean and variance."""
    post = pair[0]._state[0]
    assert post.emulator_variance and post.compiled is None
    ck = pair[0].emulator
    data = post.loglik.data
    theta = np.array([[0.2], [0.33], [0.37], [0.91]])
    mean, var = ck._mean_var_fast(theta)
    ref = [multivariate_normal(np.repeat(mean[k], 3), NOISE**2 * np.eye(3) + var[k, 0]
                               ).logpdf(data[:, 0]) for k in range(4)]
    z = (theta - post.center) / post.scale
    np.testing.assert_allclose(post(z), np.array(ref) + post.logprior(theta), rtol=1e-10)


def test_emulator_variance_widens_the_posterior_where_the_cokriging_is_unsure():
    """3 HF and 10 LF runs, 20 experiments: the co-kriging's std over the posterior is 0.9
    of the noise std of the mean. With its variance in the likelihood the chains give the
    grid posterior of that emulator (mean within 0.15 std, std within 8 %), 1.2 times wider
    or more than the mean-only posterior, which matches its own grid posterior alike."""
    data = _data(n_exp=20)
    on, off = (_calibrate(rq.CoKriging(low_fidelity=LF, n_low=10), data=data,
                          n_emulator_samples=3, emulator_variance=v, n_samples=6000, seed=11)
               for v in (True, False))
    np.testing.assert_array_equal(on.emulator.rho, off.emulator.rho)  # the same emulator
    assert on.emulator_adequacy.posterior_ratio[0] > 0.5
    for res, variance in ((on, True), (off, False)):
        m, s = _emulated(on.emulator, data, variance)
        assert abs(res.mean[0] - m) < 0.15 * s, (variance, res.mean, m, s)
        assert res.std[0] == pytest.approx(s, rel=0.08), (variance, res.std, s)
    assert on.std[0] > 1.2 * off.std[0], (on.std, off.std)


@pytest.mark.slow  # ~5 CPU-s; the SBC of an unfitted co-kriging below checks the coverage fast
def test_coverage_of_the_cokriging_calibration_by_simulation_based_calibration(pair):
    """self_check=40: parameters drawn from the prior, data from the HF model, posteriors with
    this co-kriging emulator (and its variance): the 90 % intervals cover at 0.9 within three
    binomial standard errors and the ranks are uniform (the SBC verdict)."""
    ck = pair[0].emulator
    res = _calibrate(ck, self_check=40, n_samples=600, n_chains=1, seed=5)
    sc = res.self_check
    assert sc.n_replications == 40
    assert sc.passed, sc.reason
    assert abs(sc.coverage_90[0] - 0.9) <= 3 * sc.coverage_90_se


def test_sbc_builds_an_unfitted_cokriging_on_its_nested_design():
    """simulation_based_calibration with an unfitted CoKriging: built once from the prior on
    6 HF and 30 LF runs (only the HF runs counted), then the verdict passes and the 90 %
    coverage is within three binomial standard errors; without a cheap model, a clear error
    before any run."""
    ck = rq.CoKriging(low_fidelity=LF, n_low=30)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        sc = rq.simulation_based_calibration(HF, PRIOR, noise_std=NOISE, n_replications=40,
                                             n_experiments=3, n_draws=19, n_samples=600,
                                             emulator=ck, n_emulator_samples=6, seed=5)
    assert not ck._levels  # the caller's emulator stays unfitted
    assert sc.n_evaluations == 40 + 6
    assert sc.passed, sc.reason
    assert abs(sc.coverage_90[0] - 0.9) <= 3 * sc.coverage_90_se
    with pytest.raises(ParameterError, match="needs its low-fidelity model"):
        rq.simulation_based_calibration(HF, PRIOR, noise_std=NOISE, n_replications=4,
                                        emulator=rq.CoKriging(), seed=1)


def test_same_seed_same_result_bitwise():
    ck = rq.CoKriging(low_fidelity=LF, n_low=12)
    kw = dict(n_samples=300, n_emulator_samples=5)
    a, b, c = _calibrate(ck, **kw), _calibrate(ck, **kw), _calibrate(ck, seed=4, **kw)
    assert not ck._levels  # the caller's emulator stays unfitted
    np.testing.assert_array_equal(a.chains, b.chains)
    np.testing.assert_array_equal(a.emulator.rho, b.emulator.rho)
    for (xa, ya), (xb, yb) in zip(a.emulator.training_data, b.emulator.training_data,
                                  strict=True):
        np.testing.assert_array_equal(xa, xb)
        np.testing.assert_array_equal(ya, yb)
    assert not np.array_equal(a.chains, c.chains)


def test_refinement_adds_runs_of_both_models_and_meets_the_target():
    """refine: each round runs the HF and the LF model at the picked posterior draws (nested
    designs kept) until the co-kriging's error over the posterior is below the target."""
    res = _calibrate(rq.CoKriging(low_fidelity=LF, n_low=8), n_emulator_samples=4,
                     n_samples=1500, refine=RefineConfig(n_samples=12, batch=3,
                                                         target_ratio=0.1))
    ad = res.emulator_adequacy
    assert ad.n_added > 0 and ad.posterior_ratio[0] < 0.1
    assert ad.posterior_ratio_per_round[0, 0] > 1.0
    (x_lf, _), (x_hf, _) = res.emulator.training_data
    assert x_hf.shape[0] == 4 + ad.n_added and x_lf.shape[0] == 8 + ad.n_added
    assert res.n_evaluations == 4 + ad.n_added
    assert res.n_low_fidelity_evaluations == (8 + ad.n_added,)
    m, s = exact_posterior(_data())
    assert abs(res.mean[0] - m) < 0.3 * s and res.std[0] == pytest.approx(s, rel=0.15)


def test_failed_low_fidelity_runs_are_left_out_and_counted():
    """LF runs failing (NaN) above t = 0.8 are left out of its level; all are counted; two
    LF models (a ladder) nest their designs."""
    holes = rq.FunctionModel(lambda x: np.where(x[:, :1] > 0.8, np.nan, lf_response(x[:, :1])),
                             ["t"], ["y"])
    cheap = rq.FunctionModel(lambda x: 0.5 * hf_response(x[:, :1]), ["t"], ["y"])
    res = _calibrate(rq.CoKriging(low_fidelity=[cheap, holes], n_low=[24, 12]),
                     n_samples=300)
    (x0, _), (x1, y1), (x2, _) = res.emulator.training_data
    assert res.n_low_fidelity_evaluations == (24, 12)
    assert x0.shape[0] == 24 and x2.shape[0] == 6
    assert 0 < x1.shape[0] < 12 and np.all(x1 <= 0.8) and np.all(np.isfinite(y1))
    assert res.emulator.rho.shape == (2, 1)


def test_predict_gradient_and_the_fast_path_match_predict():
    """The gradient (for the proposal's Gauss-Newton Hessian) against central differences
    (1e-4: truncation and round-off of h = 1e-4); the chains' compiled mean and variance
    against predict (round-off of an interpolating GP's solves: 1e-8 of the response's
    range, 1e-5 of the largest variance)."""
    t_lf, t_hf = np.linspace(0, 1, 15), np.linspace(0, 1, 5)
    ck = rq.CoKriging(seed=0).fit([t_lf[:, None], t_hf[:, None]],
                                  [lf_response(t_lf), hf_response(t_hf)])
    x = np.array([[0.21], [0.64]])
    h = 1e-4
    _, grad = ck.predict(x, return_var=False, return_grad=True)
    fd = (ck.predict(x + h, return_var=False) - ck.predict(x - h, return_var=False)) / (2 * h)
    np.testing.assert_allclose(grad[:, :, 0], fd, rtol=1e-4)
    xs = np.linspace(0, 1, 41)[:, None]
    mean, var = ck._mean_var_fast(xs)
    ref_mean, ref_var = ck.predict(xs)
    np.testing.assert_allclose(mean, ref_mean, rtol=0, atol=1e-8 * np.ptp(ref_mean))
    np.testing.assert_allclose(ck._mean_fast(xs), mean, rtol=0, atol=1e-8 * np.ptp(ref_mean))
    np.testing.assert_allclose(var, ref_var, rtol=0, atol=1e-5 * ref_var.max())
    assert ref_var.max() > 0


def _six(emulator):
    return rq.EmulatorOptions(emulator, n_emulator_samples=6)


def test_bad_input_is_a_clear_error():
    data = _data()
    kw = dict(noise=rq.NoiseModel(noise_std=NOISE), chains=rq.ChainOptions(n_samples=50))
    with pytest.raises(ParameterError, match="needs its low-fidelity model"):
        rq.calibrate_bayes(HF, data, PRIOR, emulator=_six(rq.CoKriging()), **kw)
    other_in = rq.FunctionModel(lambda x: x[:, :1], ["s"], ["y"])
    with pytest.raises(ParameterError, match=r"low-fidelity model 0 .* inputs \['s'\]"):
        rq.calibrate_bayes(HF, data, PRIOR, emulator=_six(rq.CoKriging(low_fidelity=other_in)),
                           **kw)
    other_out = rq.FunctionModel(lambda x: x[:, :1], ["t"], ["thrust"])
    with pytest.raises(ParameterError, match=r"no responses \['y'\]"):
        rq.calibrate_bayes(HF, data, PRIOR, emulator=_six(rq.CoKriging(low_fidelity=other_out)),
                           **kw)
    with pytest.raises(ParameterError, match="smaller than the high-fidelity design"):
        rq.calibrate_bayes(HF, data, PRIOR, emulator=_six(rq.CoKriging(low_fidelity=LF, n_low=5)),
                           **kw)
    with pytest.raises(ParameterError, match="give low_fidelity= too"):
        rq.CoKriging(n_low=10)
    with pytest.raises(ParameterError, match="non-increasing"):
        rq.CoKriging(low_fidelity=[LF, LF], n_low=[10, 20])
    with pytest.raises(ParameterError, match="not a Model"):
        rq.CoKriging(low_fidelity=[np.sin])
    t_lf, t_hf = np.linspace(0, 1, 9), np.linspace(0, 1, 5)
    fitted = rq.CoKriging(seed=0).fit([t_lf[:, None], t_hf[:, None]],
                                      [lf_response(t_lf), hf_response(t_hf)])
    with pytest.raises(ParameterError, match="refine= with a CoKriging"):
        rq.calibrate_bayes(HF, data, PRIOR,
                           emulator=rq.EmulatorOptions(fitted, n_emulator_samples=6,
                                                       refine=RefineConfig()),
                           **kw)
    with pytest.raises(ParameterError, match="GaussianProcess or CoKriging"):
        rq.calibrate_bayes(HF, data, PRIOR, emulator=HF, **kw)


def test_noise_multipliers_and_continue_chain_run_on_the_cokriging(pair):
    """The multiplier route (the Python log posterior with noise multipliers) and
    continue_chain take the co-kriging as they take a GP: the fitted emulator as given (no
    build runs), its counts carried."""
    ck = pair[0].emulator
    res = _calibrate(ck, noise_multipliers="one", n_samples=800)
    assert res.noise_multiplier_chains is not None and res.n_evaluations == 0
    assert res.n_low_fidelity_evaluations == (0,)
    m, s = exact_posterior(_data())
    assert abs(res.mean[0] - m) < 0.5 * s
    more = rq.continue_chain(pair[0], 200)
    assert more.chains.shape[1] == pair[0].chains.shape[1] + 200
    assert more.n_low_fidelity_evaluations == (30,) and more.emulator is ck
