"""calibrate_bayes against closed-form posteriors, the emulator workflow and bad input."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import rotoruq as rq
from rotoruq.errors import ModelShapeError, ParameterError
from rotoruq.methods.mcmc import (
    ChainOptions,
    EmulatorOptions,
    NoiseModel,
    SamplerConfig,
    calibrate_bayes,
    continue_chain,
)
from rotoruq.methods.mcmc.bayes import _Posterior
from rotoruq.methods.surrogate import ExtrapolationWarning, GaussianProcess

# --- linear-Gaussian: posterior in closed form ----------------------------------------------

RNG = np.random.default_rng(0)
A = RNG.normal(size=(4, 3))
MU0 = np.array([1.0, -1.0, 0.5])
S0 = np.array([1.0, 2.0, 0.5])
NOISE = 0.3
DATA = np.array([0.5, 0.0, 1.0]) @ A.T + RNG.normal(0, NOISE, size=(5, 4))


def linear_problem(with_gradient=True, permute=False):
    names = ["t0", "t1", "t2"]
    space = rq.ParameterSpace({n: rq.Normal(MU0[i], S0[i]) for i, n in enumerate(names)})
    order = [2, 0, 1] if permute else [0, 1, 2]
    names_in = [names[i] for i in order]

    def f(x):  # x columns in names_in order
        theta = np.empty_like(x)
        theta[:, order] = x
        return theta @ A.T

    def g(x):
        return np.broadcast_to(A[:, order], (x.shape[0], 4, 3))

    model = rq.FunctionModel(f, names_in, ["y0", "y1", "y2", "y3"],
                             gradient=g if with_gradient else None)
    prec = np.diag(1 / S0**2) + DATA.shape[0] * A.T @ A / NOISE**2
    cov = np.linalg.inv(prec)
    mean = cov @ (MU0 / S0**2 + A.T @ DATA.sum(0) / NOISE**2)
    return model, space, mean, cov


@pytest.mark.parametrize("method", ["dram", "mh"])
def test_linear_gaussian_posterior_matches_closed_form(method):
    model, space, mean, cov = linear_problem()
    res = calibrate_bayes(model, DATA, space,
                          chains=ChainOptions(sampler=method, n_samples=4500, burn_in=500,
                                              n_chains=4),
                          noise=NoiseModel(noise_std=NOISE), seed=1)
    assert res.chains.shape == (4, 4500, 3)
    sd = np.sqrt(np.diag(cov))
    assert np.all(np.abs(res.mean - mean) < 4.5 * sd / np.sqrt(res.ess))
    # std within MC error of a variance estimate (4.5 sigma of sqrt(2/ESS))
    assert np.all(np.abs(res.std / sd - 1) < 4.5 * np.sqrt(0.5 / res.ess))
    corr = cov / np.outer(sd, sd)
    np.testing.assert_allclose(res.correlation, corr, atol=4.5 / np.sqrt(res.ess.min()))
    # MAP pre-solve lands on the posterior mode (= mean for a Gaussian)
    np.testing.assert_allclose(res.map_point, mean, atol=1e-3 * sd.max())
    # the Gauss-Newton Hessian proposal is exact here: 2.38^2/d * posterior covariance
    np.testing.assert_allclose(res.proposal_covariance, 2.38**2 / 3 * cov, rtol=1e-6)
    assert np.all(res.rhat < 1.02)
    assert abs(res.skewness).max() < 0.15 and abs(res.kurtosis).max() < 0.3
    # KL(post || prior) of two Gaussians in closed form
    S = np.diag(S0**2)
    kl = 0.5 * (np.trace(np.linalg.solve(S, cov)) + (MU0 - mean) @ np.linalg.solve(S, MU0 - mean)
                - 3 + np.linalg.slogdet(S)[1] - np.linalg.slogdet(cov)[1])
    assert abs(res.kl_divergence_gaussian - kl) < 0.1
    assert abs(res.kl_divergence - kl) < 0.25
    ci = res.credible_interval(0.95)
    np.testing.assert_allclose(ci, res.credible_interval_95)
    np.testing.assert_allclose(ci[:, 0], mean - 1.96 * sd, atol=0.1 * sd.max())
    if method == "dram":
        assert len(res.acceptance_per_stage) == 2 and 0 < res.acceptance_per_stage[1] < 1
    else:
        assert len(res.acceptance_per_stage) == 1


def test_finite_difference_jacobian_and_permuted_inputs_agree():
    model, space, mean, cov = linear_problem(with_gradient=False, permute=True)
    res = calibrate_bayes(model, DATA, space,
                          chains=ChainOptions(n_samples=2850, burn_in=150, n_chains=4),
                          noise=NoiseModel(noise_std=NOISE), seed=2)
    np.testing.assert_allclose(res.proposal_covariance, 2.38**2 / 3 * cov, rtol=1e-3)
    assert np.all(np.abs(res.mean - mean) < 4.5 * np.sqrt(np.diag(cov) / res.ess))


def test_same_seed_same_chains():
    model, space, *_ = linear_problem()
    a = calibrate_bayes(model, DATA, space,
                        chains=ChainOptions(n_samples=475, burn_in=25, n_chains=2),
                        noise=NoiseModel(noise_std=NOISE), seed=7)
    b = calibrate_bayes(model, DATA, space,
                        chains=ChainOptions(n_samples=475, burn_in=25, n_chains=2),
                        noise=NoiseModel(noise_std=NOISE), seed=7)
    np.testing.assert_array_equal(a.chains, b.chains)
    # one chain: the evaluation schedule changes the number of model runs, not the chain
    one = [calibrate_bayes(model, DATA, space,
                           chains=ChainOptions(n_samples=760, burn_in=40,
                                               sampler=SamplerConfig(evaluations=ev)),
                           noise=NoiseModel(noise_std=NOISE), seed=8)
           for ev in ("speculative", "minimal")]
    np.testing.assert_array_equal(one[0].chains, one[1].chains)
    assert one[0].acceptance_rate == one[1].acceptance_rate
    assert one[1].n_likelihood_evaluations < one[0].n_likelihood_evaluations
    with pytest.raises(ParameterError, match="unknown evaluations schedule"):
        calibrate_bayes(model, DATA, space,
                        chains=ChainOptions(n_samples=10, sampler=SamplerConfig(evaluations="all")))


@pytest.mark.slow  # ~13 CPU-s; test_same_seed_same_chains stays fast
def test_readme_example_is_bitwise_reproducible():
    """The README's call (an unseeded GaussianProcess emulator, seed=1) twice: every random
    stage (design, GP restarts, MAP starts, chain starts, chains, predictive draws, the KL
    subsample) comes from the call's seed, so chains, MAP and predictive are bitwise equal;
    the caller's emulator is not fitted (a later call fits afresh) and a different seed
    differs. continue_chain without a seed is reproducible too."""
    model = smooth_model()
    space = rq.ParameterSpace({"k": rq.Uniform(0.0, 2.0), "c": rq.Uniform(0.0, 2.0)})
    data = model(np.array([[1.2, 0.7]])) + np.random.default_rng(4).normal(0, 0.1, (5, 2))
    gp = rq.GaussianProcess(trend="reduced_quadratic")

    def run(seed):
        return rq.calibrate_bayes(model, data, prior=space,
                                  chains=ChainOptions(sampler="dram", n_samples=400, burn_in=50,
                                                      n_chains=4),
                                  noise=NoiseModel(noise_std=0.1),
                                  emulator=EmulatorOptions(gp, n_emulator_samples=30),
                                  posterior_predictive=20, seed=seed)

    a, b = run(1), run(1)
    assert not gp._fits and a.emulator is not gp
    for f in ("chains", "log_posterior", "map_point", "predictive", "predictive_inputs",
              "proposal_covariance"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)
    assert a.kl_divergence == b.kl_divergence
    np.testing.assert_array_equal(a.emulator.length_scales, b.emulator.length_scales)
    assert not np.array_equal(run(2).chains, a.chains)
    np.testing.assert_array_equal(continue_chain(a, 100).chains, continue_chain(b, 100).chains)
    assert continue_chain(a, 100).kl_divergence == continue_chain(b, 100).kl_divergence
    # a SeedSequence seed is not consumed: the same object twice gives the same result
    ss = np.random.SeedSequence(5)
    np.testing.assert_array_equal(run(ss).chains, run(ss).chains)


# --- banana (Rosenbrock-type) posterior -----------------------------------------------------


def test_banana_posterior_moments():
    """q = (a, c + a^2), data (0, 0), variances (1, 0.5^2), wide uniform prior:
    a ~ N(0, 1), c | a ~ N(-a^2, 0.25), so E[c] = -1, Var[c] = 0.25 + 2."""
    space = rq.ParameterSpace({"a": rq.Uniform(-6, 6), "c": rq.Uniform(-40, 10)})
    model = rq.FunctionModel(lambda x: np.column_stack([x[:, 0], x[:, 1] + x[:, 0] ** 2]),
                             ["a", "c"], ["q1", "q2"])
    res = calibrate_bayes(model, [0.0, 0.0], space, noise=NoiseModel(noise_std=[1.0, 0.5]),
                          chains=ChainOptions(n_samples=19000, burn_in=1000, n_chains=8),
                          seed=3)
    se = res.std / np.sqrt(res.ess)
    assert abs(res.mean[0]) < 4.5 * se[0]
    assert abs(res.mean[1] + 1.0) < 4.5 * se[1]
    # variance estimates: Var(s^2) ~ (mu4 - sigma^4) / ESS; mu4 - sigma^4 = 2 for a, 56 for c
    assert abs(res.std[0] ** 2 - 1.0) < 4.5 * np.sqrt(2.0 / res.ess[0])
    assert abs(res.std[1] ** 2 - 2.25) < 4.5 * np.sqrt(58.0 / res.ess[1])
    assert res.correlation[0, 1] == pytest.approx(0.0, abs=0.1)  # uncorrelated yet dependent
    assert res.n_out_of_support == 0 or res.n_out_of_support < 0.01 * 8 * 20000


# --- emulator workflow ----------------------------------------------------------------------


def smooth_model():
    def f(x):
        return np.column_stack([2.0 * x[:, 0] + np.sin(x[:, 1]), x[:, 0] * x[:, 1] + x[:, 1]])

    return rq.FunctionModel(f, ["k", "c"], ["T", "Q"])


def test_emulator_workflow_matches_the_true_model():
    model = smooth_model()
    space = rq.ParameterSpace({"k": rq.Uniform(0.0, 2.0), "c": rq.Uniform(0.0, 2.0)})
    truth = np.array([[1.2, 0.7]])
    data = model(truth) + np.random.default_rng(4).normal(0, 0.1, (20, 2))
    kw = dict(noise=NoiseModel(noise_std=0.1),
              chains=ChainOptions(n_samples=3800, burn_in=200, n_chains=4), seed=5)
    direct = calibrate_bayes(model, data, space, **kw)
    emu = calibrate_bayes(model, data, space,
                          emulator=EmulatorOptions(
                              GaussianProcess(trend="reduced_quadratic", seed=0),
                              n_emulator_samples=60),
                          posterior_predictive=50, **kw)
    assert emu.emulator is not None and emu.emulator_loo.q2.min() > 0.999
    se = np.sqrt(direct.std**2 / direct.ess + emu.std**2 / emu.ess)
    assert np.all(np.abs(emu.mean - direct.mean) < 4.5 * se)
    np.testing.assert_allclose(emu.std, direct.std, rtol=0.15)
    # model evaluations: 60 build + 50 predictive; the chains only call the emulator
    assert emu.n_evaluations == 110
    assert direct.n_evaluations >= direct.n_likelihood_evaluations
    assert emu.predictive.shape == (50, 2) and emu.names_out == ("T", "Q")
    np.testing.assert_allclose(emu.predictive, model(emu.predictive_inputs))
    # predictive draws cover the data mean
    assert np.all(np.abs(emu.predictive.mean(0) - data.mean(0)) < 3 * emu.predictive.std(0))


@pytest.mark.parametrize("trend", ["constant", "linear", "reduced_quadratic", "quadratic", None])
@pytest.mark.parametrize("kernel", ["sqexp", "matern32", "matern52"])
def test_compiled_emulator_mean_equals_predict(trend, kernel):
    """The chains' GP mean (compiled, one point at a time) equals GaussianProcess.predict,
    inside and outside the training box, and does not depend on the batch."""
    rng = np.random.default_rng(0)
    X = rng.random((40, 3))
    Y = np.column_stack([np.sin(3 * X[:, 0]) + X[:, 1] ** 2, X[:, 2] * X[:, 0]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gp = GaussianProcess(trend=trend, kernel=kernel, n_restarts=0, seed=0).fit(X, Y)
    Xt = rng.random((25, 3)) * 1.6 - 0.3
    ref = gp.predict(Xt, return_var=False, warn_distance=None)
    fast = gp._mean_fast(Xt)
    # predict forms distances as |a|^2 + |b|^2 - 2 a.b; a rounding error there is multiplied
    # by the kriging weights, which are large for a near-interpolating GP: bound eps sum|w|
    cg = gp.compiled()
    alpha, y_std = cg.alpha, cg.y_std
    tol = 1e-14 * np.abs(alpha).sum(1) * y_std + 1e-12 * np.abs(ref).max(0)
    assert np.all(np.abs(fast - ref) <= tol), (np.abs(fast - ref).max(0), tol)
    np.testing.assert_array_equal(np.vstack([gp._mean_fast(x[None]) for x in Xt]), fast)
    # the compiled Kriging variance (precomputed inverse factors) equals predict's (triangular
    # solves) to round-off of the unit-variance standardized problem
    mean, var = gp._mean_var_fast(Xt)
    ref_mean, ref_var = gp.predict(Xt, warn_distance=None)
    assert np.all(np.abs(mean - ref_mean) <= tol)
    assert np.all(np.abs(var - ref_var) <= 1e-10 * gp.compiled(variance=True).var_scale)


def _stacked_loglik(data, noise_cov, q, var):
    """Direct log-likelihood of all observations stacked, (n_exp m,): mean q repeated, noise
    blocks plus the emulator's error shared by the experiments (a rank-m term)."""
    from scipy.stats import multivariate_normal

    n_exp, m = data.shape
    cov = np.zeros((n_exp * m, n_exp * m))
    for e in range(n_exp):
        cov[e * m:(e + 1) * m, e * m:(e + 1) * m] = noise_cov[e]
    cov += np.kron(np.ones((n_exp, n_exp)), np.diag(var))
    return multivariate_normal(np.tile(q, n_exp), cov).logpdf(data.reshape(-1))


@pytest.mark.parametrize("noise", ["per_observation", "full"])
def test_likelihood_with_emulator_variance_equals_the_stacked_gaussian(noise):
    """GaussianLikelihood(q, variance) (compiled, sufficient statistics) equals the Gaussian
    density of all observations with covariance noise + GP variance shared by the
    experiments, computed directly (1e-10); variance 0 gives the plain likelihood."""
    from rotoruq.methods.mcmc import GaussianLikelihood

    rng = np.random.default_rng(3)
    n_exp, m = 4, 3
    data = rng.normal(size=(n_exp, m))
    if noise == "full":
        a = rng.normal(size=(m, m))
        cov = a @ a.T + 0.5 * np.eye(m)
        covs = np.broadcast_to(cov, (n_exp, m, m))
    else:
        cov = rng.uniform(0.1, 2.0, (n_exp, m))
        covs = np.array([np.diag(c) for c in cov])
    lik = GaussianLikelihood(data, cov)
    q = rng.normal(size=(5, m))
    var = rng.uniform(0.0, 3.0, (5, m))
    got = lik(q, var)
    ref = [_stacked_loglik(data, covs, q[k], var[k]) for k in range(5)]
    np.testing.assert_allclose(got, ref, rtol=1e-10, atol=0)
    np.testing.assert_allclose(lik(q, np.zeros_like(q)), lik(q), rtol=1e-12)


@pytest.mark.filterwarnings("ignore::rotoruq.methods.surrogate.ExtrapolationWarning")
@pytest.mark.filterwarnings("ignore:emulator error over the posterior:RuntimeWarning")
def test_emulator_variance_in_the_posterior_and_the_switch():
    """The compiled emulator posterior with the GP variance equals prior + the stacked
    Gaussian with GaussianProcess.predict's variance at a few thetas (1e-10); with
    emulator_variance=False it is the mean-only posterior; the general (Python) route
    gives the same numbers."""
    # a sparse GP with a nugget: a visible variance and kriging weights small enough that
    # predict's distance formula is exact to 1e-10 (an interpolating GP's are not)
    X = np.random.default_rng(2).random((12, 2)) * 2.0
    gp = GaussianProcess(trend="linear", kernel="matern52", nugget=1e-3, seed=0).fit(
        X, smooth_model()(X))
    on = _emulator_result(n_samples=95, burn_in=5, emulator=gp)
    off = _emulator_result(n_samples=95, burn_in=5, emulator=gp, emulator_variance=False)
    post_on, post_off = on._state[0], off._state[0]
    assert post_on.emulator_variance and not post_off.emulator_variance
    data = post_on.loglik.data
    thetas = np.array([[1.2, 0.7], [0.3, 1.9], [1.95, 0.05], [0.9, 1.1]])
    z = (thetas - post_on.center) / post_on.scale
    mean, var = gp.predict(thetas, warn_distance=None)
    lp_prior = post_on.logprior(thetas)
    covs = np.broadcast_to(np.eye(2) * 0.01, (data.shape[0], 2, 2))
    ref = lp_prior + [_stacked_loglik(data, covs, mean[k], var[k]) for k in range(4)]
    np.testing.assert_allclose(post_on(z), ref, rtol=1e-10)
    assert np.all(var > 0)
    np.testing.assert_allclose(post_off(z), lp_prior + post_off.loglik(mean), rtol=1e-10)
    # the Python route (a prior the compiled kernel does not take) agrees
    general = _Posterior(gp._mean_fast, post_on.loglik, post_on.logprior, post_on.center,
                         post_on.scale, gp, True)
    general.compiled = None
    np.testing.assert_allclose(general(z), post_on(z), rtol=1e-12)


def _three_output_problem():
    def f(x):
        a, b = x[:, 0], x[:, 1]
        return np.column_stack([np.exp(0.8 * a) + b**2, a * b + np.sin(2 * b), np.cos(a) * b])

    model = rq.FunctionModel(f, ["a", "b"], ["y1", "y2", "y3"])
    space = rq.ParameterSpace({"a": rq.Uniform(0.0, 2.0), "b": rq.Uniform(0.0, 2.0)})
    data = f(np.array([[1.1, 0.6]])) + np.random.default_rng(0).normal(0, 0.05, (3, 3))
    return model, space, data


def test_refinement_brings_the_emulator_error_below_target_and_the_posterior_home(tmp_path):
    """A 10-point GP of a 2-parameter, 3-response nonlinear model: its error over the
    posterior is 0.36-0.8 of the noise std (warned), and its posterior mean is off the
    model's own posterior; refinement adds runs at the posterior draws until the ratio is
    below 0.1, and the posterior mean moves to the model's own (within MC error)."""
    from rotoruq.methods.mcmc import RefineConfig

    model, space, data = _three_output_problem()
    kw = dict(noise=NoiseModel(noise_std=0.05),
              chains=ChainOptions(n_samples=1500, burn_in=300, n_chains=4), seed=3)
    direct = calibrate_bayes(model, data, space, **kw)
    with pytest.warns(RuntimeWarning, match="emulator error over the posterior"):
        sparse = calibrate_bayes(model, data, space,
                                 emulator=EmulatorOptions(GaussianProcess(trend="linear"),
                                                          n_emulator_samples=10),
                                 **kw)
    ad = sparse.emulator_adequacy
    assert ad.runs_added == () and np.all(ad.loo_ratio > 0)
    np.testing.assert_allclose(ad.noise_std, 0.05 / np.sqrt(3))
    assert ad.posterior_ratio.max() > 0.3
    cfg = RefineConfig(n_samples=40, target_ratio=0.1, batch=5)
    ref = calibrate_bayes(model, data, space,
                          emulator=EmulatorOptions(GaussianProcess(trend="linear"),
                                                   n_emulator_samples=10,
                                                   refine=cfg),
                          **kw)
    ra = ref.emulator_adequacy
    assert 1 <= len(ra.runs_added) and ra.n_added <= 40
    assert np.all(ra.posterior_ratio < 0.1) and ra.target_ratio == 0.1
    np.testing.assert_array_equal(ra.posterior_ratio_per_round[0], ad.posterior_ratio)
    assert ref.emulator._X.shape[0] == 10 + ra.n_added
    assert ref.n_evaluations == 10 + ra.n_added
    with np.load(ref.save(tmp_path / "post.npz")) as z:
        np.testing.assert_array_equal(z["emulator_runs_added"], ra.runs_added)
    se = np.sqrt(direct.std**2 / direct.ess + ref.std**2 / ref.ess)
    assert np.all(np.abs(ref.mean - direct.mean) < 4.5 * se)
    z_sparse = np.abs(sparse.mean - direct.mean) / direct.std
    z_ref = np.abs(ref.mean - direct.mean) / direct.std
    assert z_ref.max() < z_sparse.max()
    with (pytest.raises(ParameterError, match="refines an emulator"),
          pytest.warns(DeprecationWarning, match="pass emulator=EmulatorOptions")):
        calibrate_bayes(model, data, space, refine=cfg, chains=ChainOptions(n_samples=10))
    with pytest.raises(ParameterError, match="target_ratio"):
        RefineConfig(target_ratio=0.0)


@pytest.mark.slow  # 17 chains: ~6 s of CPU, up to 20 s on a shared machine
def test_noise_multiplier_learns_an_understated_noise(tmp_path):
    """Data with noise std 0.1 stated as 0.05: the variance multiplier ("one", inverse-gamma
    prior) is sampled with the parameters; over 8 data sets its 90 % interval covers the
    true 4 and the parameters' 90 % intervals cover the truth at about their rate (>= 6 of 8
    each: P(<= 5 of 8) = 0.04 at 0.9), where the stated noise alone covers less. Per
    response: only the understated response's multiplier moves off 1."""
    model, space, _ = _three_output_problem()
    truth = np.array([1.1, 0.6])
    y0 = model(truth[None])
    kw = dict(chains=ChainOptions(n_samples=1000, burn_in=200, n_chains=4))
    lam_cover, th_cover, fixed_cover = 0, np.zeros(2), np.zeros(2)
    for s in range(8):
        data = y0 + np.random.default_rng(100 + s).normal(0, 0.1, (10, 3))
        r = calibrate_bayes(model, data, space,
                            noise=NoiseModel(noise_std=0.05, noise_multipliers="one"), seed=s,
                            **kw)
        assert r.chains.shape == (4, 1000, 2) and r.noise_multiplier_chains.shape == (4, 1000, 1)
        _, _, lo, hi = r.noise_multiplier_summary(0.9)["noise_multiplier"]
        lam_cover += lo <= 4.0 <= hi
        ci = r.credible_interval(0.9)
        th_cover += (ci[:, 0] <= truth) & (truth <= ci[:, 1])
        ci = calibrate_bayes(model, data, space, noise=NoiseModel(noise_std=0.05), seed=s,
                             **kw).credible_interval(0.9)
        fixed_cover += (ci[:, 0] <= truth) & (truth <= ci[:, 1])
    assert lam_cover >= 6 and np.all(th_cover >= 6), (lam_cover, th_cover)
    assert fixed_cover.sum() < th_cover.sum()
    sd = np.array([0.1, 0.05, 0.05])
    data = y0 + np.random.default_rng(7).normal(0, 1, (30, 3)) * sd
    r = calibrate_bayes(model, data, space,
                        noise=NoiseModel(noise_std=0.05, noise_multipliers="per_response"),
                        seed=1, **kw)
    summ = r.noise_multiplier_summary(0.99)
    assert r.noise_multiplier_names == ("noise_multiplier:y1", "noise_multiplier:y2",
                                        "noise_multiplier:y3")
    for name, lam in zip(r.noise_multiplier_names, (4.0, 1.0, 1.0), strict=True):
        assert summ[name][2] <= lam <= summ[name][3], (name, summ[name])
    with np.load(r.save(tmp_path / "post.npz")) as z:
        np.testing.assert_array_equal(z["noise_multiplier_chains"], r.noise_multiplier_chains)
    more = continue_chain(r, 100)
    assert more.noise_multiplier_chains.shape == (4, 1100, 3)
    # (kept as 1 / tau: the round trip is exact to one rounding)
    np.testing.assert_allclose(more.noise_multiplier_chains[:, :1000],
                               r.noise_multiplier_chains, rtol=4e-16)


@pytest.mark.parametrize("mode", ["one", "per_response", "per_experiment"])
def test_noise_multiplier_likelihood_is_the_likelihood_of_the_scaled_noise(mode):
    """With multipliers lambda = 1 / tau the likelihood (emulator variance or none) equals
    GaussianLikelihood with the noise variances multiplied by lambda, observation by
    observation (1e-12)."""
    from rotoruq.methods.mcmc import GaussianLikelihood
    from rotoruq.methods.mcmc.noise import multiplier_groups, noise_loglik

    rng = np.random.default_rng(5)
    n_exp, m = 4, 3
    data = rng.normal(size=(n_exp, m))
    var = rng.uniform(0.1, 2.0, (n_exp, m))
    groups, names = multiplier_groups(mode, ("a", "b", "c"), n_exp)
    q = rng.normal(size=(6, m))
    v = rng.uniform(0.0, 1.0, (6, m))
    tau = rng.uniform(0.2, 3.0, (6, len(names)))
    got = noise_loglik(q, v, tau, data, var, groups)
    got0 = noise_loglik(q, None, tau, data, var, groups)
    for k in range(6):
        lik = GaussianLikelihood(data, var / tau[k][groups])
        np.testing.assert_allclose(got[k], lik(q[k:k + 1], v[k:k + 1])[0], rtol=1e-12)
        np.testing.assert_allclose(got0[k], lik(q[k:k + 1])[0], rtol=1e-12)


def test_noise_multipliers_with_an_emulator_and_named_responses():
    """The multiplier route also runs on an emulator (with its variance) and on a subset
    of responses: the unnamed responses keep their stated noise."""
    model, space, data = _three_output_problem()
    r = calibrate_bayes(model, data, space,
                        emulator=EmulatorOptions(GaussianProcess(trend="linear"),
                                                 n_emulator_samples=30),
                        noise=NoiseModel(noise_std=0.05, noise_multipliers=["y2"]),
                        chains=ChainOptions(n_samples=300, burn_in=50),
                        seed=2)
    assert r.noise_multiplier_names == ("noise_multiplier:y2",)
    assert r.noise_multiplier_chains.shape == (1, 300, 1) and r.chains.shape == (1, 300, 2)
    assert np.all(r.noise_multiplier_chains > 0)
    assert r.emulator_adequacy is not None


def test_noise_multiplier_bad_input():
    model, space, data = _three_output_problem()
    with pytest.raises(ParameterError, match=r"responses \['y3'\] that have no data"):
        calibrate_bayes(model, data[:, :2], space, names_out=["y1", "y2"],
                        noise=NoiseModel(noise_std=0.05, noise_multipliers=["y3"]),
                        chains=ChainOptions(n_samples=10))
    with pytest.raises(ParameterError, match="noise_std must be finite and > 0"):
        calibrate_bayes(model, data, space,
                        noise=NoiseModel(noise_std=[0.05, 0.0, 0.05], noise_multipliers="one"),
                        chains=ChainOptions(n_samples=10))
    with pytest.raises(ParameterError, match="need independent noise"):
        calibrate_bayes(model, data, space,
                        noise=NoiseModel(noise_covariance=np.eye(3), noise_multipliers="one"),
                        chains=ChainOptions(n_samples=10))
    with pytest.raises(ParameterError, match="noise_multipliers must be one of"):
        calibrate_bayes(model, data, space, noise=NoiseModel(noise_multipliers="each"),
                        chains=ChainOptions(n_samples=10))
    with pytest.raises(ParameterError, match=r"\(alpha, beta\) must be > 0"):
        calibrate_bayes(model, data, space,
                        noise=NoiseModel(noise_multipliers="one",
                                         noise_multiplier_prior=(0.0, 1.0)),
                        chains=ChainOptions(n_samples=10))
    with pytest.raises(ParameterError, match="no noise multipliers"):
        calibrate_bayes(model, data, space, noise=NoiseModel(noise_std=0.05),
                        chains=ChainOptions(n_samples=20)).noise_multiplier_summary()


def _emulator_result(prior=None, emulator=None, emulator_variance=True, **chains):
    model = smooth_model()
    space = prior or rq.ParameterSpace({"k": rq.Uniform(0.0, 2.0), "c": rq.Uniform(0.0, 2.0)})
    data = model(np.array([[1.2, 0.7]])) + np.random.default_rng(4).normal(0, 0.1, (20, 2))
    gp = emulator or GaussianProcess(trend="linear", seed=0)
    return calibrate_bayes(model, data, space,
                           emulator=EmulatorOptions(gp, n_emulator_samples=40,
                                                    emulator_variance=emulator_variance),
                           noise=NoiseModel(noise_std=0.1), chains=ChainOptions(**chains),
                           seed=6)


def test_compiled_emulator_posterior_equals_the_python_one():
    """With uniform/normal priors the emulator posterior runs compiled; it gives the same
    numbers and counts as the general route (prior, GP mean, likelihood called separately),
    and the compiled chain driver takes the same steps as the Python drivers."""
    from rotoruq.methods.mcmc.samplers import SamplerConfig, run_chains

    res = _emulator_result(n_samples=950, burn_in=50)
    post, state, cfg = res._state
    assert post.compiled is not None
    z = np.random.default_rng(1).normal(0, 1.2, (300, 2))  # some outside the support
    cnt0 = post.cnt.copy()
    a = post(z)
    cnt_a = post.cnt - cnt0
    compiled, post.compiled = post.compiled, None
    try:
        b = post(z)
    finally:
        post.compiled = compiled
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(post.cnt - cnt0 - cnt_a, cnt_a)
    assert 0 < cnt_a[1] < 300 and cnt_a[0] == 300 - cnt_a[1]  # outside / evaluated

    runs = []
    for target, ev in ((post, "minimal"), (lambda q: post(q), "minimal"),
                       (lambda q: post(q), "speculative")):
        st = state.copy()
        runs.append(run_chains(target, st, SamplerConfig(evaluations=ev), 600, burn_in=100)[0])
        assert st.steps == state.steps + 700
    np.testing.assert_array_equal(runs[1], runs[0])
    np.testing.assert_array_equal(runs[2], runs[0])
    # at most one compiled version of each step kernel whichever driver calls it (a kernel
    # loaded from numba's cache registers none of its callees; on a cold cache a compiled
    # caller passing literals made numba compile advance, propose and _step twice: the
    # slow test_compile_notice.py::test_each_step_kernel_is_compiled_once_on_a_cold_cache)
    from rotoruq.methods.mcmc import _kernels as kn

    for kernel in (kn.advance, kn.propose, kn._step, kn._after_step):
        assert len(kernel.signatures) <= 1, (kernel.py_func.__name__, kernel.signatures)


def test_emulator_with_other_priors_takes_the_general_route():
    prior = rq.ParameterSpace({"k": rq.LogNormal(0.2, 0.3), "c": rq.Uniform(0.0, 2.0)})
    res = _emulator_result(prior, n_samples=1900, burn_in=100, n_chains=2)
    assert res._state[0].compiled is None
    assert np.all(res.chains[..., 0] > 0) and np.isfinite(res.mean).all()
    assert res.n_likelihood_evaluations > 0 and res.n_evaluations == 40


def test_emulator_extrapolation_is_warned_with_distance():
    model = smooth_model()
    narrow = rq.ParameterSpace({"k": rq.Uniform(0.9, 1.1), "c": rq.Uniform(0.6, 0.8)})
    X = narrow.draw(30, seed=0)
    gp = GaussianProcess(trend="linear", seed=0).fit(X, model(X))
    wide = rq.ParameterSpace({"k": rq.Normal(1.0, 1.0), "c": rq.Normal(0.7, 1.0)})
    with pytest.warns(ExtrapolationWarning, match=r"box-widths outside its training box"):
        calibrate_bayes(model, [2.0, 1.0], wide, emulator=gp, noise=NoiseModel(noise_std=2.0),
                        chains=ChainOptions(n_samples=570, burn_in=30),
                        seed=1)


def test_nan_likelihoods_are_rejected_and_counted():
    def f(x):
        y = np.column_stack([x[:, 0] + x[:, 1], x[:, 0] - x[:, 1]])
        y[x[:, 0] > 0.6] = np.nan  # the solver "fails" there
        return y

    model = rq.FunctionModel(f, ["a", "b"], ["s", "d"])
    space = rq.ParameterSpace({"a": rq.Uniform(0, 1), "b": rq.Uniform(0, 1)})
    res = calibrate_bayes(model, [1.0, 0.1], space, noise=NoiseModel(noise_std=np.sqrt(0.3)),
                          chains=ChainOptions(n_samples=1900, burn_in=100, n_chains=2),
                          seed=2)
    assert res.n_nan_likelihood > 0
    assert np.all(res.chains[..., 0] <= 0.6)


def test_continue_chain_and_export(tmp_path):
    model, space, mean, cov = linear_problem()
    res = calibrate_bayes(model, DATA, space,
                          chains=ChainOptions(n_samples=1000, burn_in=200, n_chains=2),
                          noise=NoiseModel(noise_std=NOISE), seed=3)
    more = continue_chain(res, 1000)
    assert more.chains.shape == (2, 2000, 3)
    np.testing.assert_array_equal(more.chains[:, :1000], res.chains)
    assert more.n_likelihood_evaluations > res.n_likelihood_evaluations
    assert more.sampling_seconds > res.sampling_seconds
    # continuing does not consume the original state: same continuation twice
    np.testing.assert_array_equal(continue_chain(res, 1000).chains, more.chains)
    p = more.save(tmp_path / "post.npz")
    with np.load(p) as z:
        np.testing.assert_array_equal(z["chains"], more.chains)
        assert tuple(z["names_in"]) == space.names
    c = more.save(tmp_path / "post.csv")
    table = np.loadtxt(c, delimiter=",", skiprows=1)
    assert table.shape == (4000, 6)
    np.testing.assert_allclose(table[:2000, 2:5], more.chains[0])
    assert "t0" in more.summary()


# --- bad input ------------------------------------------------------------------------------


def test_data_with_wrong_number_of_responses():
    model, space, *_ = linear_problem()
    with pytest.raises(ModelShapeError, match=r"data has 3 column\(s\) but 4 response"):
        calibrate_bayes(model, np.zeros((5, 3)), space, chains=ChainOptions(n_samples=10))
    with pytest.raises(ParameterError, match="not outputs of the model"):
        calibrate_bayes(model, np.zeros((5, 1)), space, names_out=["thrust"],
                        chains=ChainOptions(n_samples=10))


def test_non_positive_definite_covariance():
    model, space, *_ = linear_problem()
    bad = np.eye(4)
    bad[0, 1] = bad[1, 0] = 2.0
    with pytest.raises(ParameterError, match="not positive definite"):
        calibrate_bayes(model, DATA, space, noise=NoiseModel(noise_covariance=bad),
                        chains=ChainOptions(n_samples=10))
    with pytest.raises(ParameterError, match="proposal_covariance is not positive definite"):
        calibrate_bayes(model, DATA, space,
                        chains=ChainOptions(proposal_covariance=-np.eye(3), n_samples=10))


def test_infinite_support_prior_without_start_point():
    def f(x):
        y = x.copy()
        y[x[:, 0] < 5.0] = np.nan  # only works far from the prior mean
        return y

    model = rq.FunctionModel(f, ["kp"], ["m"])
    space = rq.ParameterSpace({"kp": rq.Normal(0.0, 1.0)})
    with pytest.raises(ParameterError, match=r"\['kp'\] have infinite prior support.*x0="):
        calibrate_bayes(model, [6.0], space, chains=ChainOptions(n_samples=95, burn_in=5))
    res = calibrate_bayes(model, [6.0], space,
                          chains=ChainOptions(x0=[6.0], n_samples=285, burn_in=15),
                          seed=0)
    assert np.all(res.chains >= 5.0)
    with pytest.raises(ParameterError, match="zero posterior density"):
        calibrate_bayes(model, [6.0], space, chains=ChainOptions(x0=[1.0], n_samples=95, burn_in=5))


def test_bad_sampler_arguments():
    model, space, *_ = linear_problem()
    with pytest.raises(ParameterError, match="unknown MCMC sampler"):
        calibrate_bayes(model, DATA, space, chains=ChainOptions(sampler="nuts", n_samples=10))
    with pytest.raises(ParameterError, match="burn_in"):
        calibrate_bayes(model, DATA, space, chains=ChainOptions(n_samples=10, burn_in=-1))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ParameterError, match="ParameterSpace"):
            calibrate_bayes(model, DATA, {"t0": rq.Normal(0, 1)}, chains=ChainOptions(n_samples=10))


def test_non_gaussian_priors_are_sampled_exactly_when_data_say_nothing():
    """Uninformative data (huge variance): the posterior is the prior (Beta, LogNormal)."""
    space = rq.ParameterSpace({"p": rq.Beta(2.0, 3.0), "s": rq.LogNormal(2.0, 0.5)})
    model = rq.FunctionModel(lambda x: x[:, :1] + 0.0 * x[:, 1:], ["p", "s"], ["y"])
    res = calibrate_bayes(model, [0.4], space, noise=NoiseModel(noise_std=1e4),
                          chains=ChainOptions(n_samples=5700, burn_in=300, n_chains=8,
                                              proposal_covariance="prior"),
                          seed=4)
    se = res.std / np.sqrt(res.ess)
    assert np.all(np.abs(res.mean - space.mean) < 4.5 * se)
    assert np.all(np.abs(res.std / space.std - 1) < 4.5 * np.sqrt(1.0 / res.ess) + 0.02)
    assert res.chains[..., 0].min() >= 0.0 and res.chains[..., 1].min() > 0.0
    # posterior = prior: no information gained. The kNN estimate is near 0; the Gaussian
    # entropy over-estimates a skewed posterior's entropy, so that KL estimate is slightly < 0
    assert abs(res.kl_divergence) < 0.1
    assert -0.2 < res.kl_divergence_gaussian < 0.0


def test_a_slow_model_gets_the_minimal_schedule_and_the_same_chains():
    """Issue 24: speculative lookahead spends ~2.4x the model runs; for a model slower than
    SLOW_EVALUATION a point the chains switch to the minimal schedule by themselves. The
    chain is a function of the seed alone, so it is bitwise the one the fast model gives."""
    import time

    from rotoruq.methods.mcmc import bayes

    def f(x):
        return np.column_stack([x[:, 0] + 0.5 * x[:, 1], x[:, 0] * x[:, 1]])

    def slow(x):
        time.sleep(1.5 * bayes.SLOW_EVALUATION * len(x))
        return f(x)

    prior = rq.ParameterSpace({"a": rq.Uniform(-1, 1), "b": rq.Uniform(-1, 1)})
    data = f(np.array([[0.3, -0.4]])) + 0.01
    kw = dict(noise=NoiseModel(noise_std=0.1), seed=5,
              chains=ChainOptions(n_samples=40, burn_in=0, map_start=False,
                                  proposal_covariance="prior"))
    fast_run = rq.calibrate_bayes(rq.FunctionModel(f, ["a", "b"], ["y1", "y2"]), data, prior,
                                  **kw)
    slow_run = rq.calibrate_bayes(rq.FunctionModel(slow, ["a", "b"], ["y1", "y2"]), data,
                                  prior, **kw)
    assert fast_run.evaluations == "speculative" and slow_run.evaluations == "minimal"
    np.testing.assert_array_equal(slow_run.chains, fast_run.chains)
    assert slow_run.n_likelihood_evaluations < fast_run.n_likelihood_evaluations
    assert slow_run.n_likelihood_evaluations <= 2 * 40  # stage 1, and stage 2 when rejected


def test_the_flat_keywords_of_0_1_still_work_for_one_release():
    """calibrate_bayes takes its options as three records; the flat keywords of rotoruq 0.1
    give bitwise the same result with a DeprecationWarning naming the record field; an unknown
    keyword is a TypeError with the closest name."""
    import inspect

    assert len(inspect.signature(calibrate_bayes).parameters) <= 12
    model, space, *_ = linear_problem()
    new = calibrate_bayes(model, DATA, space, noise=NoiseModel(noise_std=NOISE),
                          chains=ChainOptions(n_samples=200, burn_in=20, n_chains=2,
                                              sampler="am"), seed=3)
    with pytest.warns(DeprecationWarning) as caught:
        old = calibrate_bayes(model, DATA, space, noise_std=NOISE, n_samples=200, burn_in=20,
                              n_chains=2, sampler="am", seed=3)
    said = {str(w.message) for w in caught}
    assert ("calibrate_bayes(burn_in=...) is deprecated and will be removed in the next "
            "release: pass chains=ChainOptions(burn_in=...)") in said
    assert any("pass noise=NoiseModel(noise_std=...)" in m for m in said)
    assert all(w.filename == __file__ for w in caught)  # the warning points at the caller
    np.testing.assert_array_equal(old.chains, new.chains)
    # a flat keyword overrides that field of the record given
    with pytest.warns(DeprecationWarning, match="ChainOptions"):
        mixed = calibrate_bayes(model, DATA, space, noise=NoiseModel(noise_std=NOISE),
                                chains=ChainOptions(n_samples=200, burn_in=0, n_chains=2,
                                                    sampler="am"), burn_in=20, seed=3)
    np.testing.assert_array_equal(mixed.chains, new.chains)
    with pytest.raises(TypeError, match="'n_sample'.*did you mean 'n_samples'"):
        calibrate_bayes(model, DATA, space, n_sample=10)
    with pytest.raises(ParameterError, match="chains must be a ChainOptions"):
        calibrate_bayes(model, DATA, space, chains=100)


def test_a_histogram_prior_is_compiled_bitwise_its_logpdf():
    """A kernel-density (histogram) marginal, a sequential calibration's stage-2 prior, is
    evaluated in the compiled kernel: bitwise the marginal's own logpdf added to the other
    terms (at random points, exactly on every bin edge and one ulp either side), -inf outside
    the box; the emulator posterior on it is then compiled (issue 34: its self-check ran on
    the Python route, 62 of the experiment chapter's 90 CPU-s)."""
    from rotoruq.methods.mcmc.proposals import LogPrior
    from rotoruq.params import kernel_density

    rng = np.random.default_rng(3)
    kde = kernel_density(2.0 * rng.beta(2.0, 3.0, 4000), (0.0, 2.0), n_bins=64)
    prior = rq.ParameterSpace({"k": kde, "c": rq.Uniform(0.0, 2.0)})
    lp = LogPrior(prior)
    assert lp.compiled
    edges = np.asarray(kde.abscissas)
    k = np.concatenate([rng.uniform(-0.1, 2.1, 3000), edges, np.nextafter(edges, -np.inf),
                        np.nextafter(edges, np.inf), [np.nan]])
    c = np.where(np.arange(k.size) % 7 == 0, 2.5, 1.0)  # some outside the box in c
    with np.errstate(invalid="ignore"):
        expected = np.where(c <= 2.0, -np.log(2.0) + kde.logpdf(k), -np.inf)
    expected[np.isnan(expected)] = -np.inf
    got = lp(np.column_stack([k, c]))
    np.testing.assert_array_equal(got, expected)
    assert np.isfinite(got).sum() > 2000 and np.isneginf(got).sum() > 400
    # beside a marginal the kernel does not take, the histogram stays on the Python route
    mixed = LogPrior(rq.ParameterSpace({"k": kde, "c": rq.LogNormal(1.0, 0.5)}))
    assert not mixed.compiled and [j for j, _ in mixed._other] == [0, 1]

    res = _emulator_result(rq.ParameterSpace({"k": kernel_density(
        rng.normal(1.2, 0.3, 4000).clip(0.0, 2.0), (0.0, 2.0)), "c": rq.Uniform(0.0, 2.0)}),
        n_samples=400, burn_in=100)
    assert res._state[0].compiled is not None
    assert np.all(np.isfinite(res.chains)) and abs(res.mean[0] - 1.2) < 0.2
