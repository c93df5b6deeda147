import numpy as np
import pytest

import rotoruq as rq
from rotoruq.errors import ParameterError


def test_normal_moments_and_transforms():
    space = rq.ParameterSpace({"a": rq.Normal(2.0, 0.5), "b": rq.Uniform(-1.0, 3.0)})
    assert space.names == ("a", "b")
    np.testing.assert_allclose(space.mean, [2.0, 1.0])
    np.testing.assert_allclose(space.std, [0.5, 4 / np.sqrt(12)])
    x = space.sample(500, seed=3)
    assert x.shape == (500, 2)
    np.testing.assert_allclose(space.from_u(space.to_u(x)), x, rtol=1e-10, atol=1e-12)


def test_lhs_is_stratified_and_seeded():
    space = rq.ParameterSpace({"u": rq.Uniform(0.0, 1.0)})
    x = space.sample(100, seed=1)
    counts = np.histogram(x[:, 0], bins=100, range=(0, 1))[0]
    assert np.all(counts == 1)
    np.testing.assert_array_equal(x, space.sample(100, seed=1))


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
    x = space.sample(100000, seed=1, method="mc")
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
