import numpy as np
import pytest
from scipy import stats

import rotoruq as rq
from rotoruq.errors import EvaluationError, ModelShapeError, ParameterError
from rotoruq.methods.reliability import mean_value, mean_value_from_gradient

A = np.array([2.0, -1.5, 0.5])
C0 = 3.0
MU = np.array([1.0, 2.0, -1.0])
SD = np.array([0.3, 0.2, 0.5])
R = np.array([[1.0, 0.4, -0.2], [0.4, 1.0, 0.3], [-0.2, 0.3, 1.0]])


def linear_space():
    return rq.ParameterSpace({f"x{i}": rq.Normal(MU[i], SD[i]) for i in range(3)}, correlation=R)


def linear_model(with_gradient=False):
    grad = (lambda x: np.broadcast_to(A, (x.shape[0], 1, 3)).copy()) if with_gradient else None
    return rq.FunctionModel(lambda x: C0 + x @ A, ["x0", "x1", "x2"], ["g"], gradient=grad)


def exact_linear():
    cov = R * np.outer(SD, SD)
    return C0 + A @ MU, np.sqrt(A @ cov @ A)


@pytest.mark.parametrize("with_gradient", [False, True])
def test_mean_value_linear_correlated_is_exact(with_gradient):
    mu, sd = exact_linear()
    levels = [mu - sd, mu, mu + 2 * sd]
    res = mean_value(
        linear_model(with_gradient),
        linear_space(),
        response_levels=levels,
        probability_levels=[0.05, 0.5, 0.9],
        reliability_levels=[1.0, 2.0],
    )
    assert res.n_evaluations == (1 if with_gradient else 7)
    assert res.mean[0] == pytest.approx(mu, rel=1e-12)
    assert res.std[0] == pytest.approx(sd, rel=1e-7)
    exact_cdf = stats.norm.cdf(levels, mu, sd)
    np.testing.assert_allclose(res.cdf_probability["g"], exact_cdf, rtol=1e-6)
    np.testing.assert_allclose(res.ccdf_probability["g"], 1 - exact_cdf, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(res.cdf_reliability["g"], (mu - np.array(levels)) / sd, atol=1e-6)
    np.testing.assert_allclose(
        res.probability_response["g"], stats.norm.ppf([0.05, 0.5, 0.9], mu, sd), rtol=1e-7
    )
    np.testing.assert_allclose(res.reliability_response["g"], [mu - sd, mu - 2 * sd], rtol=1e-7)
    np.testing.assert_allclose(res.gradient[0], A, rtol=1e-6)
    assert res.importance.sum() == pytest.approx(1.0)


def test_mean_value_ccdf_inverse_and_independent_importance():
    space = rq.ParameterSpace({"a": rq.Normal(1.0, 0.1), "b": rq.Uniform(0.0, 2.0)})
    model = rq.FunctionModel(lambda x: x[:, 0] * x[:, 1], ["a", "b"], ["p"])
    res = mean_value(model, space, probability_levels=[0.1], distribution="ccdf")
    s = np.array([0.1 * 1.0, 2 / np.sqrt(12) * 1.0])  # std_i * dg/dx_i at the means (1, 1)
    assert res.std[0] == pytest.approx(np.hypot(*s), rel=1e-7)
    np.testing.assert_allclose(res.importance[0], s**2 / np.sum(s**2), rtol=1e-6)
    # CCDF level: P(g > z) = 0.1
    z = res.probability_response["p"][0]
    assert 1 - stats.norm.cdf(z, res.mean[0], res.std[0]) == pytest.approx(0.1, rel=1e-9)


def test_mean_value_permuted_space_and_reuse_of_gradient():
    space = rq.ParameterSpace(
        {
            "x2": rq.Normal(MU[2], SD[2]),
            "x0": rq.Normal(MU[0], SD[0]),
            "x1": rq.Normal(MU[1], SD[1]),
        }
    )
    res = mean_value(linear_model(), space)
    np.testing.assert_allclose(res.gradient[0], A[[2, 0, 1]], rtol=1e-6)
    assert res.names_in == ("x2", "x0", "x1")
    # a nested loop changes the input stds only: no model call needed
    again = mean_value_from_gradient(res.mean, res.gradient, 2 * space.std)
    assert again.std[0] == pytest.approx(2 * res.std[0], rel=1e-12)


def test_mean_value_bad_inputs():
    space = linear_space()
    wrong = rq.FunctionModel(lambda x: np.zeros((x.shape[0], 2)), ["x0", "x1", "x2"], ["g"])
    with pytest.raises(ModelShapeError):
        mean_value(wrong, space)
    failing = rq.FunctionModel(
        lambda x: np.where(x[:, 0] > MU[0], np.nan, 1.0), ["x0", "x1", "x2"], ["g"]
    )
    with pytest.raises(EvaluationError, match="failed"):
        mean_value(failing, space)
    with pytest.raises(ParameterError, match="probability_levels"):
        mean_value(linear_model(), space, probability_levels=[1.5])
    with pytest.raises(ParameterError, match="inputs"):
        mean_value(rq.FunctionModel(lambda x: x[:, 0], ["y"], ["g"]), space)


def test_form_linear_correlated_coincides_with_mean_value_and_exact():
    from rotoruq.methods.reliability import mpp_search

    mu, sd = exact_linear()
    levels = [mu - 2 * sd, mu + sd]
    mv = mean_value(
        linear_model(),
        linear_space(),
        response_levels=levels,
        probability_levels=[0.1],
        reliability_levels=[-1.5],
    )
    for integration in ("first_order", "second_order"):
        r = mpp_search(
            linear_model(),
            linear_space(),
            response_levels=levels,
            probability_levels=[0.1],
            reliability_levels=[-1.5],
            integration=integration,
        )
        assert r.converged
        np.testing.assert_allclose(r.cdf_probability["g"], stats.norm.cdf([-2, 1]), rtol=1e-6)
        np.testing.assert_allclose(r.cdf_probability["g"], mv.cdf_probability["g"], rtol=1e-6)
        np.testing.assert_allclose(r.cdf_reliability["g"], [2.0, -1.0], atol=1e-6)
        np.testing.assert_allclose(
            r.probability_response["g"], stats.norm.ppf(0.1, mu, sd), rtol=1e-6
        )
        np.testing.assert_allclose(r.reliability_response["g"], mu + 1.5 * sd, rtol=1e-6)
        # the MPP lies on the limit state
        np.testing.assert_allclose(C0 + r.mpp_x["g"] @ A, levels, rtol=1e-6)


@pytest.mark.parametrize("sorm, rtol", [("breitung", 0.06), ("hohenbichler", 0.03)])
def test_sorm_on_a_paraboloid(sorm, rtol):
    from rotoruq.methods.reliability import mpp_search

    k, beta = 0.3, 2.5
    space = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Normal(0, 1)})
    model = rq.FunctionModel(lambda x: -x[:, 0] + 0.5 * k * x[:, 1] ** 2, ["a", "b"], ["g"])
    r = mpp_search(model, space, response_levels=[-beta], integration="second_order", sorm=sorm)
    assert r.curvatures["g"][0, 0] == pytest.approx(k, rel=1e-3)
    assert r.cdf_reliability["g"][0] == pytest.approx(beta, rel=1e-6)
    # exact: P(-u1 + k u2^2 / 2 <= -beta) = E[Phi(-beta - k u2^2 / 2)], Gauss-Hermite
    t, w = np.polynomial.hermite_e.hermegauss(80)
    exact = np.sum(w * stats.norm.cdf(-beta - 0.5 * k * t**2)) / np.sum(w)
    form = stats.norm.cdf(-beta)
    assert r.cdf_probability["g"][0] == pytest.approx(exact, rel=rtol)
    assert abs(r.cdf_probability["g"][0] - exact) < abs(form - exact) / 3
