import numpy as np
import pytest

import rotoruq as rq
from rotoruq.errors import ParameterError
from rotoruq.params import restricted_pairing, unit_design


def test_normal_moments_and_transforms():
    space = rq.ParameterSpace({"a": rq.Normal(2.0, 0.5), "b": rq.Uniform(-1.0, 3.0)})
    assert space.names == ("a", "b")
    np.testing.assert_allclose(space.mean, [2.0, 1.0])
    np.testing.assert_allclose(space.std, [0.5, 4 / np.sqrt(12)])
    x = space.draw(500, seed=3)
    assert x.shape == (500, 2)
    np.testing.assert_allclose(space.from_u(space.to_u(x)), x, rtol=1e-10, atol=1e-12)


def test_lhs_is_stratified_and_seeded():
    space = rq.ParameterSpace({"u": rq.Uniform(0.0, 1.0)})
    x = space.draw(100, seed=1)
    counts = np.histogram(x[:, 0], bins=100, range=(0, 1))[0]
    assert np.all(counts == 1)
    np.testing.assert_array_equal(x, space.draw(100, seed=1))


def test_lognormal_uses_mean_and_std_of_variable():
    d = rq.LogNormal(2.0, 0.3)
    assert d.mean == pytest.approx(2.0)
    assert d.std == pytest.approx(0.3)


@pytest.mark.parametrize(
    "build, match",
    [
        (lambda: rq.Normal(0.0, 0.0), "std must be"),
        (lambda: rq.Normal(0.0, -1.0), "std must be"),
        (lambda: rq.Uniform(2.0, 1.0), "lower < upper"),
        (lambda: rq.make_distribution("normall", mean=0, std=1), "did you mean 'normal'"),
    ],
)
def test_bad_distributions(build, match):
    with pytest.raises(ParameterError, match=match):
        build()


def test_unknown_parameter_name():
    space = rq.ParameterSpace({"a": rq.Normal(0, 1)})
    with pytest.raises(ParameterError, match="unknown parameter 'b'"):
        space["b"]


def test_interval_mixture_and_correlated_nataf_space():
    iv = rq.Interval([(0.0, 1.0), (2.0, 3.0)], [0.3, 0.7])
    assert iv.mean == pytest.approx(0.3 * 0.5 + 0.7 * 2.5)
    assert iv.bounds == (0.0, 3.0)
    np.testing.assert_allclose(iv.ppf(iv.cdf([0.2, 2.5, 3.0])), [0.2, 2.5, 3.0])
    r = np.array([[1.0, 0.5], [0.5, 1.0]])
    space = rq.ParameterSpace({"a": rq.LogNormal(1.0, 0.3), "b": rq.Uniform(0, 1)}, correlation=r)
    assert space.nataf[0, 1] > 0.5  # Nataf inflates the normal-score correlation here
    x = space.draw(100000, design="random", seed=1)
    assert np.corrcoef(x.T)[0, 1] == pytest.approx(0.5, abs=0.01)
    np.testing.assert_allclose(space.from_u(space.to_u(x[:50])), x[:50], rtol=1e-9)
    np.testing.assert_allclose(space.covariance[0, 1], 0.5 * 0.3 * (1 / np.sqrt(12)))
    # correlated normals: the joint log density is the bivariate normal one
    from scipy import stats

    sn = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Normal(1, 2)}, correlation=r)
    pts = np.array([[0.3, -0.5], [1.0, 2.0]])
    exact = stats.multivariate_normal([0, 1], sn.covariance).logpdf(pts)
    np.testing.assert_allclose(sn.logpdf(pts), exact, rtol=1e-10)


@pytest.mark.parametrize(
    "corr, match",
    [
        ([[1, 2], [2, 1]], "unit diagonal"),
        ([[1, 0.5], [0.4, 1]], "symmetric"),
        ([[1, 0], [0, 1], [0, 0]], "shape"),
    ],
)
def test_bad_correlation(corr, match):
    with pytest.raises(ParameterError, match=match):
        rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Normal(0, 1)}, correlation=corr)


# Tail transforms. A tail that ends at a finite bound b != 0 cannot be resolved in double
# precision beyond |u| ~ 8 (b + tiny == b), so every bounded family is tested with one instance
# whose lower bound is 0 (lower tail) and one whose upper bound is 0 (upper tail).
U_TAIL = np.array([-37.0, -30.0, -20.0, -12.0, -8.5, -3.0, -1e-6, 0.0, 1e-6, 3.0, 8.5, 12.0,
                   20.0, 30.0, 37.0])
TAIL_CASES = {
    "normal": (rq.Normal(10.0, 5.0), U_TAIL),
    "lognormal": (rq.LogNormal(2.0, 0.5), U_TAIL),
    "gamma": (rq.Gamma(2.0, 1.5), U_TAIL),
    "exponential": (rq.Exponential(2.0), U_TAIL),
    "gumbel": (rq.Gumbel(0.5, 3.0), U_TAIL),
    "weibull": (rq.Weibull(1.5, 2.0), U_TAIL),
    "truncated_normal_lower": (rq.TruncatedNormal(1.0, 2.0, lower=0.0), U_TAIL),
    "truncated_normal_upper": (rq.TruncatedNormal(-1.0, 2.0, upper=0.0), U_TAIL),
    "truncated_normal_both_lower": (rq.TruncatedNormal(1.0, 2.0, 0.0, 4.0), U_TAIL[U_TAIL < 8]),
    "truncated_normal_both_upper": (rq.TruncatedNormal(1.0, 2.0, -3.0, 0.0),
                                    U_TAIL[U_TAIL > -8]),
    "uniform_lower": (rq.Uniform(0.0, 3.0), U_TAIL[U_TAIL < 8]),
    "uniform_upper": (rq.Uniform(-3.0, 0.0), U_TAIL[U_TAIL > -8]),
    "beta_lower": (rq.Beta(2.0, 3.0, 0.0, 2.0), U_TAIL[U_TAIL < 8]),
    "beta_upper": (rq.Beta(2.0, 3.0, -2.0, 0.0), U_TAIL[U_TAIL > -8]),
    "triangular_lower": (rq.Triangular(1.0, 0.0, 3.0), U_TAIL[U_TAIL < 8]),
    "triangular_upper": (rq.Triangular(-1.0, -3.0, 0.0), U_TAIL[U_TAIL > -8]),
    "interval_lower": (rq.Interval([(0.0, 1.0), (2.0, 4.0)], [0.3, 0.7]), U_TAIL[U_TAIL < 8]),
    "interval_upper": (rq.Interval([(-4.0, -2.0), (-1.0, 0.0)], [0.3, 0.7]),
                       U_TAIL[U_TAIL > -8]),
    # both bounds > 0: resolvable only to |u| ~ 8 in either tail (see above)
    "loguniform": (rq.LogUniform(0.1, 10.0), U_TAIL[np.abs(U_TAIL) < 8]),
    "lognormal_lambda_zeta": (rq.LogNormal(lambda_=0.3, zeta=0.8), U_TAIL),
    "lognormal_error_factor": (rq.LogNormal(mean=2.0, error_factor=3.0), U_TAIL),
    "lognormal_bounded_upper": (rq.LogNormal(2.0, 0.5, upper=3.0), U_TAIL[U_TAIL < 8]),
    "frechet": (rq.Frechet(3.0, 2.0), U_TAIL),
    "histogram_bin_lower": (rq.HistogramBin([0.0, 1.0, 3.0], [2.0, 1.0, 0.0]),
                            U_TAIL[U_TAIL < 8]),
    "histogram_bin_upper": (rq.HistogramBin([-3.0, -1.0, 0.0], ordinates=[1.0, 2.0]),
                            U_TAIL[U_TAIL > -8]),
}


@pytest.mark.parametrize("name", sorted(TAIL_CASES))
def test_u_x_u_round_trip_in_the_tails(name):
    dist, u = TAIL_CASES[name]
    space = rq.ParameterSpace({"a": dist})
    x = space.from_u(u[:, None])
    lo, hi = dist.bounds
    assert np.all(np.isfinite(x)) and np.all((x >= lo) & (x <= hi))
    assert np.all(np.diff(x[:, 0]) >= 0)
    np.testing.assert_allclose(space.to_u(x)[:, 0], u, rtol=1e-9, atol=1e-9)


def test_normal_tail_values_are_exact():
    # x = mu + sigma u exactly; the old CDF-then-inverse path was off by 0.04 at u = 8
    space = rq.ParameterSpace({"a": rq.Normal(10.0, 5.0)})
    u = np.array([[-37.0], [-8.0], [8.0], [8.3], [37.0]])
    np.testing.assert_allclose(space.from_u(u), 10.0 + 5.0 * u, rtol=1e-14)


@pytest.mark.parametrize("name", ["uniform_lower", "beta_upper", "loguniform", "triangular_lower"])
def test_bounded_tails_saturate_finitely(name):
    # beyond the representable tail, x sits on its bound and u saturates (never inf or NaN)
    space = rq.ParameterSpace({"a": TAIL_CASES[name][0]})
    x = space.from_u(np.array([[-37.0], [37.0]]))
    assert np.all(np.isfinite(x))
    u = space.to_u(np.vstack([x, np.array(TAIL_CASES[name][0].bounds)[:, None]]))
    assert np.all(np.isfinite(u)) and np.all(np.abs(u) <= 37.6)


def test_correlated_round_trip_far_in_the_tails():
    r = np.array([[1.0, 0.4], [0.4, 1.0]])
    space = rq.ParameterSpace({"a": rq.Normal(10.0, 5.0), "b": rq.Gumbel(0.5, 3.0)}, correlation=r)
    u = np.array([[30.0, -20.0], [-25.0, 25.0], [9.0, 9.0]])
    np.testing.assert_allclose(space.to_u(space.from_u(u)), u, rtol=1e-9, atol=1e-9)


def test_truncated_normal_matches_scipy_in_the_body():
    from scipy import stats

    d = rq.TruncatedNormal(1.0, 2.0, -1.0, 4.0)
    ref = stats.truncnorm(-1.0, 1.5, loc=1.0, scale=2.0)
    x = np.linspace(-2.0, 5.0, 29)
    np.testing.assert_allclose(d.cdf(x), ref.cdf(x), atol=1e-14)
    np.testing.assert_allclose(d.sf(x), ref.sf(x), atol=1e-14)
    q = np.linspace(0.01, 0.99, 25)
    np.testing.assert_allclose(d.ppf(q), ref.ppf(q), atol=1e-12)
    np.testing.assert_allclose(d.isf(q), ref.isf(q), atol=1e-12)


@pytest.mark.parametrize(
    "build, match",
    [
        (lambda: rq.Normal("ten", 1.0), "Normal: mean must be a number, got 'ten'"),
        (lambda: rq.Uniform(0.0, None), "Uniform: upper must be a number"),
        (lambda: rq.Triangular("a", 0.0, 1.0), "Triangular: mode must be a number"),
        (lambda: rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Normal(0, 1)},
                                   correlation=[[1, "x"], ["x", 1]]), "matrix of numbers"),
    ],
)
def test_non_numeric_parameters_are_parameter_errors(build, match):
    with pytest.raises(ParameterError, match=match):
        build()


def test_distribution_parameters_use_the_study_file_words():
    # README and study files write LogNormal(mean=, std=): the keywords are the fields
    d = rq.LogNormal(mean=2.0, std=0.3)
    assert (d.mean, d.std) == (2.0, 0.3)
    n = rq.Normal(mean=1.5, std=0.2)
    assert (n.mean, n.std) == (1.5, 0.2)
    # every distribution rebuilds from its description, under the same keys
    for dist in [n, d, rq.TruncatedNormal(mean=1.0, std=2.0, lower=0.0),
                 rq.Uniform(lower=0.0, upper=2.0), rq.Beta(alpha=2.0, beta=3.0),
                 rq.Triangular(mode=0.5, lower=0.0, upper=1.0), rq.Gumbel(alpha=1.0, beta=2.0),
                 rq.Interval([(0.0, 1.0), (2.0, 3.0)], [0.3, 0.7])]:
        again = rq.make_distribution(**dist.describe())
        assert again == dist
    with pytest.raises(ParameterError, match="takes mean, std; got mu, sigma"):
        rq.make_distribution("normal", mu=0.0, sigma=1.0)


def test_truncated_normal_moments_are_of_the_truncated_variable():
    from scipy import stats

    d = rq.TruncatedNormal(mean=1.0, std=2.0, lower=0.0, upper=4.0)
    ref = stats.truncnorm(-0.5, 1.5, loc=1.0, scale=2.0)
    assert d.moments == pytest.approx((ref.mean(), ref.std()), rel=1e-12)
    space = rq.ParameterSpace({"t": d})
    assert space.mean[0] == pytest.approx(ref.mean(), rel=1e-12)
    assert space.std[0] == pytest.approx(ref.std(), rel=1e-12)


@pytest.mark.parametrize("design", ["lhs", "random", "sobol", "halton"])
def test_draw_designs_are_seeded_bitwise(design):
    space = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Uniform(0, 1)})
    x = space.draw(64, design=design, seed=7)
    assert x.shape == (64, 2)
    np.testing.assert_array_equal(x, space.draw(64, design=design, seed=7))
    assert not np.array_equal(x, space.draw(64, design=design, seed=8))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"design": "mc"}, "unknown design 'mc'; valid: lhs, random, sobol, halton"),
        ({"seed": True}, "seed must be a non-negative integer.*True"),
        ({"seed": 1.0}, "seed must be a non-negative integer.*float"),
        ({"seed": "1"}, "seed must be a non-negative integer.*str"),
        ({"seed": -1}, "seed must be a non-negative integer, got -1"),
    ],
)
def test_draw_rejects_bad_design_and_seed(kwargs, match):
    space = rq.ParameterSpace({"a": rq.Normal(0, 1)})
    with pytest.raises(ParameterError, match=match):
        space.draw(4, **kwargs)


def test_draw_seed_is_keyword_only_and_n_samples_checked():
    space = rq.ParameterSpace({"a": rq.Normal(0, 1)})
    with pytest.raises(TypeError):
        space.draw(4, "lhs")  # type: ignore[misc]
    with pytest.raises(ParameterError, match="n_samples must be an integer >= 1, got 0"):
        space.draw(0)


def test_as_generator_passes_generators_through_and_accepts_numpy_ints():
    g = np.random.default_rng(3)
    assert rq.as_generator(g) is g
    a = rq.as_generator(np.int64(5)).random(3)
    np.testing.assert_array_equal(a, np.random.default_rng(5).random(3))
    ss = np.random.SeedSequence(9)
    np.testing.assert_array_equal(rq.as_generator(ss).random(2),
                                  np.random.default_rng(np.random.SeedSequence(9)).random(2))


def _strata(q):
    """Stratum index of every entry of a design in (0, 1)^d, shape (n, d)."""
    return np.floor(q * q.shape[0]).astype(int)


def test_restricted_lhs_drives_independent_rank_correlations_to_zero_and_stays_stratified():
    from scipy import stats

    n, d = 500, 9
    worst_random, worst_restricted = 0.0, 0.0
    for seed in range(3):
        q = unit_design(n, d, seed=seed)  # restricted pairing is the default
        q_rand = unit_design(n, d, pairing="random", seed=seed)
        for design in (q, q_rand):
            np.testing.assert_array_equal(np.sort(_strata(design), axis=0),
                                          np.tile(np.arange(n)[:, None], (1, d)))
        off = ~np.eye(d, dtype=bool)
        worst_restricted = max(worst_restricted, np.abs(stats.spearmanr(q).statistic[off]).max())
        worst_random = max(worst_random, np.abs(stats.spearmanr(q_rand).statistic[off]).max())
        # normal scores (what the sum of normal inputs sees) are decorrelated too
        z = stats.norm.ppf(q)
        assert np.abs(np.corrcoef(z.T)[off]).max() < 0.02
    assert worst_restricted < 0.02
    # random pairing leaves correlations of order 1/sqrt(n) (expected max over 36 pairs ~0.1)
    assert worst_random > 0.05


def test_restricted_lhs_reproduces_a_target_correlation_through_nataf():
    from scipy import stats

    r = np.array([[1.0, 0.6, -0.3], [0.6, 1.0, 0.2], [-0.3, 0.2, 1.0]])
    space = rq.ParameterSpace(
        {"a": rq.LogNormal(1.0, 0.5), "b": rq.Uniform(0, 1), "c": rq.Normal(2, 1)},
        correlation=r,
    )
    n = 2000
    x = space.draw(n, seed=4)
    # each marginal exactly stratified: its CDF values hit every stratum once
    np.testing.assert_array_equal(np.sort(_strata(space.to_unit(x)), axis=0),
                                  np.tile(np.arange(n)[:, None], (1, 3)))
    # normal scores correlate as the Nataf R0, ranks as the Gaussian copula's Spearman rho
    off = ~np.eye(3, dtype=bool)
    z = space.to_z(x)
    assert np.abs(np.corrcoef(z.T) - space.nataf)[off].max() < 0.01
    spearman = 6 / np.pi * np.arcsin(space.nataf / 2)
    assert np.abs(stats.spearmanr(x).statistic - spearman)[off].max() < 0.01
    # and the x-space (Pearson) correlation is the one asked for, within the sampling noise of
    # the lognormal's tail (random pairing at this n misses by ~3/sqrt(n) = 0.07)
    assert np.abs(np.corrcoef(x.T) - r)[off].max() < 0.03


def test_restricted_lhs_is_bitwise_seeded_and_degenerate_sizes_are_random_pairs():
    q1 = unit_design(50, 4, seed=7)
    np.testing.assert_array_equal(q1, unit_design(50, 4, seed=7))
    np.testing.assert_array_equal(q1, unit_design(50, 4, seed=np.random.default_rng(7)))
    assert not np.array_equal(q1, unit_design(50, 4, pairing="random", seed=7))
    # n <= d: no pairing can control a singular correlation; the LHS is left randomly paired
    for n in (1, 2, 4):
        np.testing.assert_array_equal(unit_design(n, 4, seed=3),
                                      unit_design(n, 4, pairing="random", seed=3))
    # ... and a correlated space still gets its correlation, through the Nataf factor
    space = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.LogNormal(1, 0.5),
                               "c": rq.Uniform(0, 1)},
                              correlation=[[1, 0.7, 0], [0.7, 1, 0], [0, 0, 1]])
    np.testing.assert_allclose(space.draw(3, seed=1), space.draw(3, pairing="random", seed=1),
                               rtol=1e-12)
    with pytest.raises(ParameterError, match="unknown pairing 'iman'; valid: restricted, random"):
        unit_design(10, 2, pairing="iman")
    with pytest.raises(ParameterError, match="positive definite"):
        restricted_pairing(np.full((5, 2), 0.5), np.random.default_rng(0),
                                     [[1.0, 2.0], [2.0, 1.0]])
