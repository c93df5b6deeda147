import numpy as np
import pytest

import rotoruq as rq
from rotoruq.errors import ParameterError
from rotoruq.methods.pce import polynomial_chaos, total_order_indices


def rosenbrock(x):
    return 100 * (x[:, 1] - x[:, 0] ** 2) ** 2 + (1 - x[:, 0]) ** 2


@pytest.mark.parametrize("estimator", ["quadrature", "sparse_grid", "regression"])
@pytest.mark.parametrize("order", [4, 5])
def test_rosenbrock_mean_is_402(estimator, order):
    space = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Normal(0, 1)})
    model = rq.FunctionModel(rosenbrock, ["a", "b"], ["r"])
    res = polynomial_chaos(model, space, order, estimator=estimator, seed=1)
    assert res.mean[0] == pytest.approx(402.0, rel=1e-10)
    # exact variance: E[f^2] - 402^2 with Gaussian moments (a polynomial of degree 4)
    assert res.variance[0] == pytest.approx(1102406.0, rel=1e-9)
    assert res.n_terms == {4: 15, 5: 21}[order]  # eq. 2.16
    x = space.draw(5, seed=3)
    np.testing.assert_allclose(res.predict(x)[:, 0], rosenbrock(x), rtol=1e-9)


def test_ishigami_sobol_from_coefficients_and_surrogate_sampling():
    space = rq.ParameterSpace({k: rq.Uniform(-np.pi, np.pi) for k in ("x1", "x2", "x3")})
    model = rq.FunctionModel(
        lambda x: np.sin(x[:, 0]) + 7 * np.sin(x[:, 1]) ** 2 + 0.1 * x[:, 2] ** 4 * np.sin(x[:, 0]),
        space.names,
        ["y"],
    )
    res = polynomial_chaos(model, space, 10, quadrature_points=12)
    assert res.families == ("legendre",) * 3
    np.testing.assert_allclose(res.main[0], [0.3139, 0.4424, 0.0], atol=2e-3)
    np.testing.assert_allclose(res.total[0], [0.5576, 0.4424, 0.2437], atol=2e-3)
    surrogate = res.as_model()
    assert surrogate.names_in == space.names and surrogate.names_out == ("y",)
    x = space.draw(50, seed=2)
    np.testing.assert_array_equal(surrogate(x), res.predict(x))
    prop = rq.sample(surrogate, space, 20000, design="random", seed=1)
    assert prop.outputs.shape == (20000, 1)
    assert prop.mean[0] == pytest.approx(3.5, abs=0.05)  # the exact mean a + 0.5 ... = 3.5


def test_askey_families_are_exact_for_polynomials():
    space = rq.ParameterSpace(
        {
            "a": rq.Beta(2, 3, 0, 2),
            "b": rq.Gamma(3, 0.5),
            "c": rq.Exponential(2.0),
            "d": rq.Normal(1, 0.2),
        }
    )
    coef = np.array([1.0, 2.0, 3.0, 4.0])
    model = rq.FunctionModel(lambda x: x @ coef + x[:, 0] * x[:, 1], space.names, ["y"])
    res = polynomial_chaos(model, space, 2)
    assert res.families == ("jacobi", "genlaguerre", "laguerre", "hermite")
    m, s = space.mean, space.std
    exact_mean = m @ coef + m[0] * m[1]
    # Var(sum c_i x_i + x0 x1) for independent inputs
    v01 = (s[0] ** 2 + m[0] ** 2) * (s[1] ** 2 + m[1] ** 2) - (m[0] * m[1]) ** 2
    exact_var = (
        (coef[2] * s[2]) ** 2
        + (coef[3] * s[3]) ** 2
        + v01
        + (coef[0] * s[0]) ** 2
        + (coef[1] * s[1]) ** 2
        + 2 * coef[0] * m[1] * s[0] ** 2
        + 2 * coef[1] * m[0] * s[1] ** 2
    )
    assert res.mean[0] == pytest.approx(exact_mean, rel=1e-10)
    assert res.variance[0] == pytest.approx(exact_var, rel=1e-9)


def test_truncation_and_bad_input():
    assert total_order_indices(3, 2).shape == (10, 3)
    space = rq.ParameterSpace({"a": rq.Normal(0, 1)})
    model = rq.FunctionModel(lambda x: x[:, 0], ["a"], ["y"])
    with pytest.raises(ParameterError, match="order"):
        polynomial_chaos(model, space, 0)
    with pytest.raises(ParameterError, match="unknown PCE estimator"):
        polynomial_chaos(model, space, 2, estimator="collocation")
    with pytest.raises(ParameterError, match="n_samples"):
        polynomial_chaos(model, space, 3, estimator="regression", n_samples=2)
