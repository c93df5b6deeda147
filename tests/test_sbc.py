"""Simulation-based calibration (rotoruq.methods.mcmc.sbc).

Two families of checks:

* the SBC machinery against closed forms: on a linear-Gaussian model the exact conjugate
  posterior gives uniform ranks, nominal coverage and unit z-score spread, and the same
  posterior with its std scaled by k gives a z-score spread of 1/k and a 90 % coverage of
  ``P(|N(0, 1)| < 1.645 k)``;
* calibrate_bayes on a 3-parameter, 4-output nonlinear model (noise std 0.05): without an
  emulator and with an adequate 50-point GP the ranks are uniform (chi-square p > 0.01 per
  parameter) and 90 % coverage is within 0.85-0.95; with a sparse 12-point GP whose error the
  likelihood ignores the same test FAILS (the test can fail). Cases keyed on the features of
  calibrate_bayes (``emulator_variance``, ``refine``) run once those keywords exist.

Seeds are fixed (the tests are deterministic). The acceptance test fails by chance about 3 %
of the time on the p-values (3 parameters at 0.01) and about 5 % on the 90 % coverage bounds
(+- 2.4 binomial standard errors of 200 replications, 3 parameters). Exploration with 200
replications, seeds 1-10: no emulator passed 8 of 8 seeds, the 50-point GP 10 of 10 and the
12-point mean-only GP failed 10 of 10 (smallest coverage 0.30-0.77, largest z-score spread
1.37-7.4).
"""

from __future__ import annotations

import inspect
import warnings

import numpy as np
import pytest
from scipy import stats

import rotoruq as rq
from rotoruq.methods import mcmc
from rotoruq.methods.mcmc import calibrate_bayes

NOISE = 0.05
N_REP = 200
BAYES_KEYWORDS = inspect.signature(calibrate_bayes).parameters


class Nonlinear:
    """3 inputs, 4 smooth nonlinear responses (a plain batched Model)."""

    names_in = ("a", "b", "c")
    names_out = ("y1", "y2", "y3", "y4")

    def __call__(self, x):
        a, b, c = np.asarray(x, dtype=float).T
        return np.column_stack([np.sin(a) + b * c, np.exp(0.5 * a) - c, a * b + 0.3 * c**2,
                                b + 0.5 * np.sin(2 * c)])


PRIOR = rq.ParameterSpace({n: rq.Uniform(-1.0, 1.0) for n in "abc"})


def _sbc(seed=1, n_replications=N_REP, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the sparse GP's LOO Q2 warning, extrapolation
        return rq.simulation_based_calibration(Nonlinear(), PRIOR, noise_std=NOISE,
                                               n_replications=n_replications, seed=seed, **kw)


def _calibrated(r) -> bool:
    """The issue's acceptance test: every p > 0.01 and 0.85 <= 90 % coverage <= 0.95."""
    return bool(np.all(r.p_value > 0.01) and np.all((r.coverage_90 >= 0.85)
                                                    & (r.coverage_90 <= 0.95)))


# --- the machinery against closed forms (exact conjugate posteriors, no MCMC) -------------------

A = np.array([[1.0, 0.5, 0.0], [0.0, 1.0, -0.3], [0.4, 0.0, 1.0], [0.2, 0.2, 0.2]])
MU0, S0 = np.array([0.5, -1.0, 2.0]), np.array([1.0, 0.5, 2.0])
LINEAR_PRIOR = rq.ParameterSpace({f"t{j}": rq.Normal(MU0[j], S0[j]) for j in range(3)})
LINEAR = rq.FunctionModel(lambda x: x @ A.T, LINEAR_PRIOR.names, [f"y{i}" for i in range(4)])


def _conjugate(noise, n_experiments, scale):
    """Exact posterior draws of the linear-Gaussian model, std multiplied by ``scale``."""
    prec = n_experiments * A.T @ A / noise**2 + np.diag(1 / S0**2)
    cov = np.linalg.inv(prec)

    def calibrate(data, *, seed):
        mean = cov @ (A.T @ data.sum(0) / noise**2 + MU0 / S0**2)
        return np.random.default_rng(seed).multivariate_normal(mean, scale**2 * cov, 400)

    return calibrate


def test_exact_posterior_is_calibrated():
    r = rq.simulation_based_calibration(LINEAR, LINEAR_PRIOR, noise_std=0.3, n_experiments=2,
                                        n_replications=1000, calibrate=_conjugate(0.3, 2, 1.0),
                                        seed=3)
    assert r.passed, r.reason
    assert np.all(r.p_value > 0.01)
    # binomial standard errors of 1000 replications: 4 of them
    assert np.all(np.abs(r.coverage_90 - 0.9) < 4 * r.coverage_90_se)
    assert np.all(np.abs(r.coverage_50 - 0.5) < 4 * r.coverage_50_se)
    assert r.coverage_90_se == pytest.approx(np.sqrt(0.09 / 1000))
    # z ~ N(0, 1): the sample std of 1000 has a standard error of 1 / sqrt(2000)
    assert np.all(np.abs(r.z_score_std - 1.0) < 4 / np.sqrt(2000))
    assert r.rank_histogram.shape == (3, 20) and np.all(r.rank_histogram.sum(1) == 1000)
    assert r.bin_probability == pytest.approx(np.full(20, 0.05))
    assert r.ranks.min() >= 0 and r.ranks.max() <= r.n_draws == 99


def test_overconfident_posterior_fails_with_the_predicted_spread():
    k = 0.7
    r = rq.simulation_based_calibration(LINEAR, LINEAR_PRIOR, noise_std=0.3,
                                        n_replications=1000, calibrate=_conjugate(0.3, 1, k),
                                        seed=4)
    assert not r.passed
    assert np.all(np.abs(r.z_score_std - 1 / k) < 4 / k / np.sqrt(2000))
    expected90 = 2 * stats.norm.cdf(stats.norm.ppf(0.95) * k) - 1
    se = np.sqrt(expected90 * (1 - expected90) / 1000)
    assert np.all(np.abs(r.coverage_90 - expected90) < 4 * se)
    assert np.all(r.p_value < 1e-6)
    for name in LINEAR_PRIOR.names:
        assert f"{name}: ranks not uniform" in r.reason
        assert f"{name}: 90% interval covers" in r.reason


def test_calibrate_without_seed_is_called_with_the_data_only():
    exact = _conjugate(0.3, 1, 1.0)
    seen = []

    def calibrate(data):
        seen.append(data.shape)
        return exact(data, seed=len(seen))

    r = rq.simulation_based_calibration(LINEAR, LINEAR_PRIOR, noise_std=0.3, n_replications=5,
                                        calibrate=calibrate, seed=0)
    assert seen == [(1, 4)] * 5 and r.ranks.shape == (5, 3)


def test_bins_need_not_divide_the_ranks():
    """L = 30 (31 rank values) in 20 bins: unequal exact bin probabilities, still uniform."""
    r = rq.simulation_based_calibration(LINEAR, LINEAR_PRIOR, noise_std=0.3, n_draws=30,
                                        n_replications=600, calibrate=_conjugate(0.3, 1, 1.0),
                                        seed=5)
    assert r.bin_probability.sum() == pytest.approx(1.0)
    assert set(np.round(r.bin_probability * 31).astype(int)) == {1, 2}
    assert np.all(r.p_value > 0.01)


# --- calibrate_bayes on a nonlinear model ------------------------------------------------------

@pytest.mark.slow  # 25-35 s: 200 chains of 3,000 steps on the (uncompiled) model
def test_no_emulator_is_calibrated():
    r = _sbc()
    assert _calibrated(r), r.summary()
    assert r.passed, r.reason
    assert r.n_autocorrelated == 0


def test_adequate_emulator_is_calibrated():
    """A 50-point GP built once from the prior: 8-12 s (compiled emulator chains)."""
    r = _sbc(emulator=rq.GaussianProcess(seed=0), n_emulator_samples=50)
    assert _calibrated(r), r.summary()
    assert r.n_evaluations >= N_REP + 50


def test_sparse_emulator_mean_only_fails():
    """A 12-point GP, likelihood on its mean only (the thesis's, today's default): over-
    confident, the same test fails (5-12 s)."""
    kw = {"emulator_variance": False} if "emulator_variance" in BAYES_KEYWORDS else {}
    r = _sbc(emulator=rq.GaussianProcess(seed=0), n_emulator_samples=12, **kw)
    assert not _calibrated(r), r.summary()
    assert not r.passed
    assert np.max(r.z_score_std) > 1.15


@pytest.mark.slow
def test_sparse_emulator_variance_alone_is_not_enough():
    """The 12-point GP's own predictive variance in the likelihood (Higdon et al. 2004) widens
    the posterior, but its maximum-likelihood length-scales under-state its error on so few
    points: measured 90 % coverage 0.71-0.81 (mean only, same design: 0.56-0.72), and the
    z-score spread grows (3.4-3.8 against 1.5-2.3: a few replications land far from the
    truth, where the variance's log-determinant pulls toward the 12 training points). The
    variance is not a fix on its own; refinement (next test) is."""
    mean_only = _sbc(emulator=rq.GaussianProcess(seed=0), n_emulator_samples=12,
                     emulator_variance=False)
    with_var = _sbc(emulator=rq.GaussianProcess(seed=0), n_emulator_samples=12,
                    emulator_variance=True)
    assert np.all(with_var.coverage_90 >= mean_only.coverage_90), with_var.summary()
    assert np.mean(with_var.coverage_90) > np.mean(mean_only.coverage_90) + 0.05


@pytest.mark.slow
def test_sparse_emulator_with_refinement_is_calibrated():
    """The same 12-point GP refined at the posterior (runs added where its std over the
    noise std is largest) passes the test the mean-only emulator fails."""
    r = _sbc(emulator=rq.GaussianProcess(seed=0), n_emulator_samples=12,
             emulator_variance=True, refine=mcmc.RefineConfig())
    assert _calibrated(r), r.summary()


# --- reproducibility and bad input -----------------------------------------------------------

def test_same_seed_same_result_bitwise():
    kw = dict(n_replications=4, n_samples=300, n_draws=19, emulator=rq.GaussianProcess(),
              n_emulator_samples=15)
    r1, r2, r3 = _sbc(seed=7, **kw), _sbc(seed=7, **kw), _sbc(seed=8, **kw)
    for field in ("theta_true", "ranks", "posterior_mean", "posterior_std", "ess"):
        np.testing.assert_array_equal(getattr(r1, field), getattr(r2, field))
    assert not np.array_equal(r1.posterior_mean, r3.posterior_mean)


def test_replications_on_an_emulator_are_the_chains_of_calibrate_bayes():
    """The replications run their chains alone (no summary): bitwise the chains
    calibrate_bayes and continue_chain give, ESS-driven continuations included."""
    from rotoruq.methods.mcmc import bayes, continue_chain
    from rotoruq.methods.mcmc import diagnostics as dg

    gp = rq.GaussianProcess(trend="linear", seed=3).fit(
        PRIOR.draw(30, design="lhs", seed=3), Nonlinear()(PRIOR.draw(30, design="lhs", seed=3)))
    data = Nonlinear()(np.array([[0.1, -0.2, 0.3]])) + 0.01
    kw = dict(n_samples=120, burn_in=60, map_start=False, sampler="dram")
    seed = np.random.SeedSequence(11)
    lean = bayes._CheckChains(Nonlinear(), data, PRIOR, gp, seed=seed, noise_std=0.1,
                              names_out=list(Nonlinear.names_out), emulator_variance=False,
                              **kw)
    lean.run()
    full = calibrate_bayes(Nonlinear(), data, PRIOR, names_out=list(Nonlinear.names_out),
                           noise=mcmc.NoiseModel(noise_std=0.1), chains=mcmc.ChainOptions(**kw),
                           emulator=mcmc.EmulatorOptions(gp, emulator_variance=False),
                           seed=seed)
    np.testing.assert_array_equal(lean.chains, full.chains)
    for k, s_k in enumerate(np.random.SeedSequence(12).spawn(2)):
        lean.extend(120 * 2**k, s_k)
        full = continue_chain(full, 120 * 2**k, seed=s_k)
        np.testing.assert_array_equal(lean.chains, full.chains)
    np.testing.assert_array_equal(dg.effective_sample_size(lean.chains), full.ess)


def test_replications_give_the_same_bits_on_any_number_of_threads():
    import numba

    kw = dict(n_replications=6, n_samples=150, n_draws=19, emulator=rq.GaussianProcess(),
              n_emulator_samples=15)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = _sbc(seed=3, **kw)
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        many = _sbc(seed=3, **kw)
    finally:
        numba.set_num_threads(before)
    for f in ("theta_true", "ranks", "posterior_mean", "posterior_std", "ess", "p_value"):
        np.testing.assert_array_equal(getattr(one, f), getattr(many, f))


def test_self_check_is_reused_by_its_setup_not_its_data(tmp_path):
    """Two calls with the same setup and other data share one self-check (from a dict or
    the store); another seed or prior computes its own; the result is bitwise the one
    computed afresh."""
    from rotoruq.evaluation.store import Store
    from rotoruq.methods.mcmc.sbc import setup_key
    from rotoruq.steps.bayes_calibration import _StoredSelfChecks

    gp = rq.GaussianProcess(trend="linear", seed=3).fit(
        PRIOR.draw(30, design="lhs", seed=3), Nonlinear()(PRIOR.draw(30, design="lhs", seed=3)))
    y = Nonlinear()(np.array([[0.1, -0.2, 0.3], [0.0, 0.4, -0.5]]))
    kw = dict(noise=mcmc.NoiseModel(noise_std=0.1), emulator=gp, self_check=4,
              chains=mcmc.ChainOptions(n_samples=400, map_start=False))

    def run(data, seed=5, cache=None):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return calibrate_bayes(Nonlinear(), data, PRIOR, seed=seed, self_check_cache=cache,
                                   **kw).self_check

    fresh = run(y[:1])
    for cache in ({}, _StoredSelfChecks(Store(tmp_path / "e.db"))):
        first = run(y[:1], cache=cache)
        again = run(y[1:], cache=cache)
        for r in (first, again):
            for f in ("theta_true", "ranks", "rank_histogram", "p_value", "coverage_90",
                      "posterior_mean", "ess"):
                np.testing.assert_array_equal(getattr(r, f), getattr(fresh, f))
            assert (r.passed, r.reason, r.names_in) == (fresh.passed, fresh.reason,
                                                        fresh.names_in)
        assert not np.array_equal(run(y[1:], seed=6, cache=cache).theta_true,
                                  fresh.theta_true)
    other = rq.ParameterSpace({n: rq.Uniform(-1.0, 1.1) for n in "abc"})
    ss = np.random.SeedSequence(1)
    assert setup_key("m", PRIOR, gp, ss, n=1) == setup_key("m", PRIOR, gp, ss, n=1)
    assert len({setup_key("m", PRIOR, gp, ss, n=1), setup_key("m", other, gp, ss, n=1),
                setup_key("m2", PRIOR, gp, ss, n=1), setup_key("m", PRIOR, gp, ss, n=2),
                setup_key("m", PRIOR, gp, np.random.SeedSequence(2), n=1)}) == 5
    assert setup_key("m", PRIOR, rq.GaussianProcess(), ss) is None  # unfitted


@pytest.mark.parametrize("kw, match", [
    ({"noise_std": 0.0}, "noise_std must be finite and > 0"),
    ({"noise_std": [0.1, -0.1, 0.1, 0.1]}, "noise_std must be finite and > 0"),
    ({"noise_std": [0.1, 0.1]}, r"noise_std must be a scalar or \(4,\)"),
    ({"noise_std": 0.1, "names_out": ["y9"]}, "not responses of the model"),
    ({"noise_std": 0.1, "n_replications": 1}, "n_replications >= 2"),
    ({"noise_std": 0.1, "alpha": 1.5}, "0 < alpha < 1"),
    ({"noise_std": 0.1, "calibrate": lambda data, *, seed: np.zeros((10, 3)),
      "emulator": rq.GaussianProcess()}, "default calibration only"),
    ({"noise_std": 0.1, "calibrate": lambda data, *, seed: np.zeros((10, 2))},
     r"shape \(n, 3\)"),
    ({"noise_std": 0.1, "seed": 1.5}, "seed must be"),
])
def test_bad_input(kw, match):
    kw = {"n_replications": 3, "seed": 0, **kw}
    with pytest.raises((rq.ParameterError, rq.errors.ModelShapeError), match=match):
        rq.simulation_based_calibration(Nonlinear(), PRIOR, **kw)
