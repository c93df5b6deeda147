"""Samplers, diagnostics and the Gaussian likelihood of rotoruq.methods.mcmc."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from rotoruq.errors import ModelShapeError, ParameterError
from rotoruq.methods.mcmc import (
    GaussianLikelihood,
    SamplerConfig,
    SamplerState,
    effective_sample_size,
    run_chains,
    split_rhat,
)
from rotoruq.methods.mcmc.diagnostics import entropy_gaussian, entropy_knn, moments

# --- diagnostics ---------------------------------------------------------------------------


def test_ess_of_independent_and_ar1_chains():
    rng = np.random.default_rng(0)
    iid = rng.standard_normal((4, 5000, 1))
    assert 0.9 * 20000 < effective_sample_size(iid)[0] < 1.1 * 20000
    rho = 0.9
    x = np.empty((4, 20000))
    x[:, 0] = rng.standard_normal(4)
    e = rng.standard_normal((4, 20000)) * np.sqrt(1 - rho**2)
    for t in range(1, 20000):
        x[:, t] = rho * x[:, t - 1] + e[:, t]
    expected = 80000 * (1 - rho) / (1 + rho)  # integrated autocorrelation time of AR(1)
    assert 0.8 * expected < effective_sample_size(x[:, :, None])[0] < 1.2 * expected


def test_split_rhat_detects_disagreeing_chains():
    rng = np.random.default_rng(1)
    good = rng.standard_normal((4, 2000, 2))
    assert np.all(np.abs(split_rhat(good) - 1.0) < 0.01)
    bad = good.copy()
    bad[0] += 1.0
    assert np.all(split_rhat(bad) > 1.05)  # rank-normalised: 1.0997 here, as arviz
    drift = good + np.linspace(0, 3, 2000)[None, :, None]  # non-stationary: halves differ
    assert np.all(split_rhat(drift) > 1.1)


def test_entropy_estimators_on_a_gaussian():
    rng = np.random.default_rng(2)
    cov = np.array([[1.0, 0.6], [0.6, 2.0]])
    x = rng.multivariate_normal([0, 0], cov, 4000)
    exact = 0.5 * np.log((2 * np.pi * np.e) ** 2 * np.linalg.det(cov))
    assert abs(entropy_gaussian(x) - exact) < 0.05
    assert abs(entropy_knn(x) - exact) < 0.1


def test_moments_of_known_distributions():
    x = stats.gamma(4.0).rvs(size=(200000, 1), random_state=3)
    mean, std, skew, kurt = moments(x)
    np.testing.assert_allclose([mean[0], std[0], skew[0], kurt[0]], [4.0, 2.0, 1.0, 1.5],
                               rtol=0.05)


# --- likelihood -----------------------------------------------------------------------------


def test_likelihood_matches_multivariate_normal_sum():
    rng = np.random.default_rng(4)
    m, n_exp = 3, 5
    data = rng.normal(size=(n_exp, m))
    A = rng.normal(size=(n_exp, m, m))
    covs = A @ A.transpose(0, 2, 1) + np.eye(m)
    q = rng.normal(size=(7, m))
    lik = GaussianLikelihood(data, covs)
    expected = [sum(stats.multivariate_normal(qk, covs[e]).logpdf(data[e]) for e in range(n_exp))
                for qk in q]
    np.testing.assert_allclose(lik(q), expected, rtol=1e-10)
    # shared forms: scalar, (m,), (m, m), (n_exp, m)
    full = covs[0]
    for cov, each in [(0.3, np.eye(m) * 0.3), ([0.1, 0.2, 0.3], np.diag([0.1, 0.2, 0.3])),
                      (full, full)]:
        ref = [sum(stats.multivariate_normal(qk, each).logpdf(d) for d in data) for qk in q]
        np.testing.assert_allclose(GaussianLikelihood(data, cov)(q), ref, rtol=1e-10)
    v = rng.uniform(0.1, 1.0, (n_exp, m))
    ref = [sum(stats.multivariate_normal(qk, np.diag(v[e])).logpdf(data[e])
               for e in range(n_exp)) for qk in q]
    np.testing.assert_allclose(GaussianLikelihood(data, v)(q), ref, rtol=1e-10)
    # Gauss-Newton Hessian of the misfit (eq. 2.26)
    J = rng.normal(size=(m, 2))
    np.testing.assert_allclose(lik.gauss_newton_hessian(J),
                               J.T @ sum(np.linalg.inv(c) for c in covs) @ J, rtol=1e-10)


def test_likelihood_bad_input():
    data = np.zeros((4, 2))
    with pytest.raises(ParameterError, match="not positive definite"):
        GaussianLikelihood(data, [[1.0, 2.0], [2.0, 1.0]])
    with pytest.raises(ParameterError, match="not symmetric"):
        GaussianLikelihood(data, [[1.0, 0.5], [0.1, 1.0]])
    with pytest.raises(ParameterError, match="> 0"):
        GaussianLikelihood(data, -1.0)
    with pytest.raises(ModelShapeError, match="does not fit"):
        GaussianLikelihood(data, np.ones(3))
    with pytest.raises(ModelShapeError, match="3 response"):
        GaussianLikelihood(data, 1.0, ("T", "Q", "P"))
    with pytest.raises(ParameterError, match="experiment 1"):
        covs = np.array([np.eye(2), [[1.0, 0.0], [0.0, -1.0]], np.eye(2), np.eye(2)])
        GaussianLikelihood(data, covs)


# --- samplers -------------------------------------------------------------------------------

COV = np.array([[1.0, 0.8], [0.8, 2.0]])
PREC = np.linalg.inv(COV)


def _gauss_logpost(z):
    return -0.5 * np.einsum("ki,ij,kj->k", z, PREC, z)


def _run(method, n_chains=8, steps=6000, proposal_std=1.0, seed=0, target=_gauss_logpost):
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((n_chains, 2))
    state = SamplerState(x=x, lp=target(x),
                         chol=np.repeat(np.eye(2)[None] * proposal_std, n_chains, 0), rng=rng)
    kept, _ = run_chains(target, state, SamplerConfig(sampler=method), steps - 500, burn_in=500)
    return kept.transpose(1, 0, 2), state


@pytest.mark.parametrize("method", ["mh", "dr", "am", "dram"])
def test_stationary_distribution_is_the_target(method):
    chains, state = _run(method)
    flat = chains.reshape(-1, 2)
    ess = effective_sample_size(chains)
    se = np.sqrt(np.diag(COV) / ess)
    assert np.all(np.abs(flat.mean(0)) < 4.5 * se), (flat.mean(0), se)
    cov = np.cov(flat, rowvar=False)
    np.testing.assert_allclose(cov, COV, atol=4.5 * np.sqrt(2.0 / ess.min()) * 2.0)
    if method in ("am", "dram"):  # the adapted proposal approaches 2.38^2/d * target cov
        C = state.chol[0] @ state.chol[0].T
        np.testing.assert_allclose(C / (2.38**2 / 2), COV, rtol=0.25, atol=0.15)


def test_samplers_agree_by_kolmogorov_smirnov():
    """DRAM, AM, DR and MH give the same marginals (thinned to near-independent draws)."""
    samples = {}
    for method in ("mh", "dr", "am", "dram"):
        chains, _ = _run(method, seed=11)
        ess = effective_sample_size(chains).min()
        step = int(np.ceil(chains.shape[0] * chains.shape[1] / ess))
        samples[method] = chains[:, ::step].reshape(-1, 2)
    for method in ("mh", "dr", "am"):
        for j in range(2):
            p = stats.ks_2samp(samples["dram"][:, j], samples[method][:, j]).pvalue
            assert p > 1e-3, (method, j, p)
    # and against the exact marginal
    for j in range(2):
        assert stats.kstest(samples["dram"][:, j], stats.norm(0, np.sqrt(COV[j, j])).cdf).pvalue \
            > 1e-3


def test_delayed_rejection_rescues_a_bad_proposal():
    """A proposal 10x too wide: DR keeps the right target and accepts more than MH."""
    _, st_mh = _run("mh", proposal_std=10.0, steps=3000)
    chains, st_dr = _run("dr", proposal_std=10.0, steps=3000)
    flat = chains.reshape(-1, 2)
    ess = effective_sample_size(chains)
    assert np.all(np.abs(flat.mean(0)) < 4.5 * np.sqrt(np.diag(COV) / ess))
    acc = {k: (s.counts["acc1"] + s.counts["acc2"]) / s.counts["prop1"]
           for k, s in (("mh", st_mh), ("dr", st_dr))}
    assert acc["dr"] > 2 * acc["mh"]
    # stage-2 covariance is the stage-1 one / 25 (Dakota's dr_scale 5)
    assert SamplerConfig().dr_scale == 5.0


def test_support_and_nan_are_rejected():
    def target(z):  # standard normal truncated to z0 > 0, NaN-free by contract (-inf outside)
        out = -0.5 * (z**2).sum(1)
        out[z[:, 0] <= 0] = -np.inf
        return out

    rng = np.random.default_rng(5)
    x = np.abs(rng.standard_normal((4, 2))) + 0.1
    state = SamplerState(x=x, lp=target(x), chol=np.repeat(np.eye(2)[None], 4, 0), rng=rng)
    kept, _ = run_chains(target, state, SamplerConfig("dram"), 3800, burn_in=200)
    assert np.all(kept[:, :, 0] > 0)
    # half-normal mean sqrt(2/pi)
    assert abs(kept[:, :, 0].mean() - np.sqrt(2 / np.pi)) < 0.06


def test_continuing_reproduces_one_long_run():
    rng_a = np.random.default_rng(9)
    x = rng_a.standard_normal((3, 2))

    def make():
        return SamplerState(x=x.copy(), lp=_gauss_logpost(x),
                            chol=np.repeat(np.eye(2)[None], 3, 0), rng=np.random.default_rng(1))

    cfg = SamplerConfig("dram")
    one = make()
    long, _ = run_chains(_gauss_logpost, one, cfg, 1024)
    two = make()
    a, _ = run_chains(_gauss_logpost, two, cfg, 512)
    b, _ = run_chains(_gauss_logpost, two.copy(), cfg, 512)
    np.testing.assert_allclose(np.concatenate([a, b]), long)


def _chain(method, evaluations, n_chains=1, proposal_std=1.0, max_lookahead=8, splits=(1500,),
           block=4096):
    rng = np.random.default_rng(21)
    x = rng.standard_normal((n_chains, 2))
    calls = []

    def target(z):
        calls.append(z.shape[0])
        return _gauss_logpost(z)

    state = SamplerState(x=x, lp=_gauss_logpost(x),
                         chol=np.repeat(np.eye(2)[None] * proposal_std, n_chains, 0), rng=rng)
    cfg = SamplerConfig(method, evaluations=evaluations, max_lookahead=max_lookahead)
    parts = [run_chains(target, state, cfg, n, block=block)[0] for n in splits]
    return np.concatenate(parts), state, calls


@pytest.mark.parametrize("method", ["dram", "am", "dr", "mh"])
@pytest.mark.parametrize("proposal_std", [0.3, 15.0])  # high move rate (tree), low (ahead)
def test_evaluation_schedule_does_not_change_the_chain(method, proposal_std):
    """Speculative evaluation (two-step tree or K steps ahead) takes exactly the steps that
    the minimal schedule (stage 1, then stage 2 if rejected) takes, bit for bit."""
    ref, st_ref, calls_ref = _chain(method, "minimal", proposal_std=proposal_std)
    for kw in ({"max_lookahead": 8}, {"max_lookahead": 3}, {"max_lookahead": 1}):
        got, st, calls = _chain(method, "speculative", proposal_std=proposal_std, **kw)
        np.testing.assert_array_equal(got, ref)
        assert st.counts == st_ref.counts
        np.testing.assert_array_equal(st.chol, st_ref.chol)
        if kw["max_lookahead"] > 1:  # fewer, larger calls
            assert len(calls) < 0.8 * len(calls_ref), (len(calls), len(calls_ref))
        if kw["max_lookahead"] == 8:  # both speculative plans are exercised
            tree_rows = 8 if method in ("dr", "dram") else 3
            if proposal_std < 1:
                assert set(calls) == {tree_rows}, set(calls)
            else:
                assert set(calls) - {tree_rows}, set(calls)
    # several chains: one step per call, stage 2 evaluated with stage 1
    many, _, _ = _chain(method, "minimal", n_chains=3, proposal_std=proposal_std)
    fused, _, calls = _chain(method, "speculative", n_chains=3, proposal_std=proposal_std)
    np.testing.assert_array_equal(fused, many)
    assert len(calls) == 1500


def test_chain_does_not_depend_on_how_the_run_is_split():
    """Random numbers come from per-kind streams: any split into calls and any block size
    give the same chain (so continuing a chain is the same as running it longer)."""
    ref, st_ref, _ = _chain("dram", "speculative", splits=(1500,))
    got, st, _ = _chain("dram", "speculative", splits=(333, 1, 666, 500), block=97)
    np.testing.assert_array_equal(got, ref)
    np.testing.assert_array_equal(st.x, st_ref.x)
    assert st.steps == st_ref.steps == 1500


def test_adaptation_uses_the_exact_history_covariance():
    """After an adaptation step the proposal factor is chol(2.38^2/d (cov + eps I)) of every
    state visited so far (all chains pooled)."""
    rng = np.random.default_rng(3)
    x = rng.standard_normal((4, 2))
    state = SamplerState(x=x, lp=_gauss_logpost(x), chol=np.repeat(np.eye(2)[None], 4, 0),
                         rng=rng)
    kept, _ = run_chains(_gauss_logpost, state, SamplerConfig("am", adapt_interval=50), 300)
    hist = kept.reshape(-1, 2)  # burn_in 0, thin 1: every visited state
    C = 2.38**2 / 2 * (np.cov(hist, rowvar=False) + 1e-8 * np.eye(2))
    np.testing.assert_allclose(state.chol[0], np.linalg.cholesky(C), rtol=1e-10)
    np.testing.assert_allclose(state.mean.mean(0), hist.mean(0), rtol=1e-12, atol=1e-14)


def test_bad_config():
    with pytest.raises(ParameterError, match="unknown MCMC sampler"):
        SamplerConfig("hmc")
    with pytest.raises(ParameterError, match="unknown evaluations schedule 'lazy'"):
        SamplerConfig(evaluations="lazy")
    with pytest.raises(ParameterError, match="max_lookahead must be >= 1"):
        SamplerConfig(max_lookahead=0)
    with pytest.raises(ParameterError, match=r"needs lp \(3,\) and chol"):
        SamplerState(x=np.zeros((3, 2)), lp=np.zeros(2), chol=np.zeros((3, 2, 2)),
                     rng=np.random.default_rng(0))
