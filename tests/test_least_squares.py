"""NL2SOL-style least squares on the Moré-Garbow-Hillstrom problems (ACM TOMS 7(1), 1981) and
deterministic calibration of a Model. Minima: f = sum r^2 as published in MGH."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from rotoruq.errors import EvaluationError, ModelShapeError, ParameterError
from rotoruq.methods.least_squares import Convergence, calibrate, least_squares
from rotoruq.methods.mgh_problems import (
    bard,
    box3d,
    brown_dennis,
    freudenstein_roth,
    jennrich_sampson,
    rosenbrock,
)
from rotoruq.model import FunctionModel
from rotoruq.params import Normal, ParameterSpace, Uniform

# name: (residual, x0, published f = sum r^2, published x or None)
PROBLEMS = {
    "rosenbrock": (rosenbrock, [-1.2, 1.0], 0.0, [1.0, 1.0]),
    "freudenstein_roth": (freudenstein_roth, [0.5, -2.0], 48.9842, [11.4128, -0.896805]),
    "bard": (bard, [1.0, 1.0, 1.0], 8.21487e-3, None),
    "box3d": (box3d, [0.0, 10.0, 20.0], 0.0, [1.0, 10.0, 1.0]),
    "jennrich_sampson": (jennrich_sampson, [0.3, 0.4], 124.362, [0.2578, 0.2578]),
    "brown_dennis": (brown_dennis, [25.0, 5.0, -5.0, -1.0], 85822.2, None),
}


@pytest.mark.parametrize("name", list(PROBLEMS))
def test_mgh_problems_reach_published_minimum(name):
    fun, x0, fstar, xstar = PROBLEMS[name]
    res = least_squares(fun, x0, convergence=Convergence(tolerance=1e-10))
    assert res.converged, res.message
    sumsq = 2 * res.cost
    if fstar == 0.0:
        assert sumsq < 1e-12
    else:
        assert sumsq == pytest.approx(fstar, rel=1e-5)
    if xstar is not None:
        # Box 3-D also has the solutions x1 = x2, x3 = 0; from the standard start it finds (1,10,1)
        np.testing.assert_allclose(res.x, xstar, rtol=2e-4, atol=1e-6)
    assert res.n_evaluations < 1000
    assert len(res.models) == res.iterations
    assert set(res.models) <= {"gn", "augmented"}


def test_bard_minimizer_matches_scipy_trf_and_fd_counts():
    res = least_squares(bard, [1, 1, 1], convergence=Convergence(tolerance=1e-12))
    ref = least_squares(bard, [1, 1, 1], optimizer="trf",
                        convergence=Convergence(tolerance=1e-14))
    np.testing.assert_allclose(res.x, ref.x, rtol=1e-5)
    assert ref.optimizer == "trf" and ref.n_evaluations > 0
    assert res == res and res != ref  # results compare by identity (eq=False), never raise
    # a finite-difference Jacobian costs p points in one call: calls << points
    assert res.n_calls < res.n_evaluations


def test_large_residual_problem_uses_augmented_model():
    res = least_squares(brown_dennis, [25.0, 5.0, -5.0, -1.0],
                        convergence=Convergence(tolerance=1e-10))
    assert "augmented" in res.models


def test_analytic_jacobian_accepted_and_counted():
    def jac(X):
        x1 = X[:, 0]
        J = np.zeros((X.shape[0], 2, 2))
        J[:, 0, 0] = -20 * x1
        J[:, 0, 1] = 10
        J[:, 1, 0] = -1
        return J

    res = least_squares(rosenbrock, [-1.2, 1.0], gradient=jac)
    np.testing.assert_allclose(res.x, [1, 1], atol=1e-8)
    assert res.n_gradient_evaluations > 0
    assert res.n_evaluations == res.n_calls  # no finite-difference points


def test_bounds_active_at_solution():
    # unconstrained minimum at (1, 1); with x1 <= 0.5 the bound is active
    res = least_squares(rosenbrock, [-1.2, 1.0], bounds=([-2, -2], [0.5, 2]),
                        convergence=Convergence(tolerance=1e-12))
    assert res.converged
    assert res.x[0] == pytest.approx(0.5, abs=1e-12)
    assert res.x[1] == pytest.approx(0.25, abs=1e-6)  # x2 = x1^2 minimizes the first residual
    res_trf = least_squares(rosenbrock, [-1.2, 1.0], bounds=([-2, -2], [0.5, 2]), optimizer="trf")
    np.testing.assert_allclose(res.x, res_trf.x, atol=1e-6)


def test_linear_regression_covariance_and_confidence_intervals():
    rng = np.random.default_rng(3)
    t = np.linspace(0, 1, 30)
    A = np.column_stack([np.ones_like(t), t])
    y = A @ [1.0, 2.0] + 0.1 * rng.standard_normal(t.size)

    res = least_squares(lambda X: X @ A.T - y, [0.0, 0.0],
                        convergence=Convergence(tolerance=1e-12))
    beta, *_ = np.linalg.lstsq(A, y, rcond=None)
    np.testing.assert_allclose(res.x, beta, rtol=1e-7)
    s2 = np.sum((A @ beta - y) ** 2) / (t.size - 2)
    cov = s2 * np.linalg.inv(A.T @ A)
    np.testing.assert_allclose(res.covariance, cov, rtol=1e-5)
    q = stats.t.ppf(0.975, t.size - 2)
    np.testing.assert_allclose(res.confidence_intervals[:, 1] - res.x, q * np.sqrt(np.diag(cov)),
                               rtol=1e-5)
    # with known data variances the covariance is (A^T W A)^-1
    resw = least_squares(lambda X: X @ A.T - y, [0.0, 0.0], noise_std=np.full(t.size, 0.1),
                         convergence=Convergence(tolerance=1e-12))
    np.testing.assert_allclose(resw.covariance, np.linalg.inv(100 * A.T @ A), rtol=1e-5)


def test_nan_residual_shrinks_the_trust_region():
    # arctan is flat far from its root: the Gauss-Newton step from x = -5 jumps to x ~ 56, where
    # the residual is undefined (NaN for x > 3). The step is rejected, the radius shrinks and
    # the solver still reaches the root x = 1.5.
    calls = []

    def fun(X):
        calls.append(X.copy())
        r = np.arctan(X - 1.5)
        r[X[:, 0] > 3] = np.nan
        return r

    res = least_squares(fun, [-5.0], convergence=Convergence(tolerance=1e-12))
    assert res.converged, res.message
    assert res.x[0] == pytest.approx(1.5, abs=1e-7)
    tried = np.concatenate(calls)[:, 0]
    assert np.sum(tried > 3) >= 1  # failed trials happened and were survived
    assert np.all(np.diff(res.history) <= 0)


def test_bad_inputs():
    with pytest.raises(ParameterError, match="unknown least-squares optimizer"):
        least_squares(rosenbrock, [0, 0], optimizer="bfgs")
    with pytest.raises(ParameterError, match="does not take bounds"):
        least_squares(rosenbrock, [0, 0], optimizer="lm", bounds=([-1, -1], [1, 1]))
    with pytest.raises(EvaluationError, match="starting point"):
        least_squares(lambda X: np.full((X.shape[0], 2), np.nan), [0, 0])
    with pytest.raises(ModelShapeError, match="batched"):
        least_squares(lambda X: np.zeros((3, 2)), [0, 0])
    with pytest.raises(ParameterError, match="lower < upper"):
        least_squares(rosenbrock, [0, 0], bounds=([1, 1], [0, 0]))


def test_max_function_evaluations_respected():
    res = least_squares(brown_dennis, [25.0, 5.0, -5.0, -1.0],
                        convergence=Convergence(max_function_evaluations=20))
    assert not res.converged
    assert res.status == "max_function_evaluations"
    assert res.n_evaluations <= 20


# --- NL2SOL's stopping rules (Dakota's defaults) ----------------------------------------------

T_EXP = np.linspace(0.0, 4.0, 20)


def text_book(X):
    """Dakota's text_book as three least-squares terms (its objective and two constraints)."""
    x1, x2 = X[:, 0], X[:, 1]
    return np.column_stack([(x1 - 1) ** 4 + (x2 - 1) ** 4, x1**2 - 0.5 * x2, x2**2 - 0.5 * x1])


def exponential_fit(X):
    return X[:, :1] * np.exp(-X[:, 1:2] * T_EXP) - 2.5 * np.exp(-1.3 * T_EXP)


def _tight(fun, x0):
    return least_squares(fun, x0, convergence=Convergence(tolerance=1e-14, x_tolerance=1e-15))


def test_relative_function_convergence_is_as_accurate_as_dakota():
    # Dakota 6.24 nl2sol (convergence_tolerance 1e-4, forward differences; measured by
    # benchmarks/least_squares.py): 5 iterations, relative function convergence, x within
    # 5.1e-6 of the minimizer. The test holds rotoruq to the tolerance's own promise.
    res = least_squares(text_book, [0.9, 1.1])
    ref = _tight(text_book, [0.9, 1.1])
    assert res.status == "relative_function" and res.converged
    assert res.cost - ref.cost <= 1e-4 * ref.cost
    assert np.max(np.abs(res.x - ref.x)) < 1e-4
    assert res.iterations <= 5
    assert len(res.models) == res.iterations  # one model per accepted step (NL2SOL's count)


def test_zero_residual_fit_converges_to_machine_precision():
    # Dakota: 5 iterations, x-convergence at f = 1e-25
    res = least_squares(exponential_fit, [1.0, 0.5])
    assert res.status in ("absolute_function", "x", "relative_function_and_x")
    np.testing.assert_allclose(res.x, [2.5, 1.3], rtol=1e-10)
    assert res.cost < 1e-20
    assert res.iterations <= 5


def test_relative_function_test_runs_after_the_step_it_predicts():
    # the test fires on the model at the start of the iteration; the step it proposes is then
    # taken, so the returned point is better than the one the test judged
    res = least_squares(text_book, [0.9, 1.1])
    assert res.history[-1] < res.history[-2]


def test_singular_convergence_names_the_unidentified_parameter():
    # x2 does not enter the residuals and x1 is flat at the minimum f = 1: no step of the
    # singular radius gains anything, the Jacobian is rank-deficient
    def fun(X):
        return np.column_stack([X[:, 0] ** 2, X[:, 0] ** 2 + 1.0, np.ones(X.shape[0])])

    res = least_squares(fun, [0.5, 0.5])
    assert res.status == "singular" and res.converged
    assert "rank-deficient" in res.message and "not identified" in res.message
    assert res.cost == pytest.approx(1.0, abs=1e-6)


def test_false_convergence_on_non_smooth_residuals():
    # a 1e-6 square wave on the residual: forward differences see a wrong slope near the
    # minimum, steps shrink below false_convergence_tolerance without a convergence test met
    def fun(X):
        return np.column_stack([X[:, 0] - 1 + 1e-6 * np.sign(np.sin(1e9 * X[:, 0])),
                                10 * (X[:, 1] - X[:, 0] ** 2)])

    res = least_squares(fun, [-1.2, 1.0])
    assert res.status == "false_convergence" and not res.converged
    assert "false convergence" in res.message
    np.testing.assert_allclose(res.x, [1.0, 1.0], atol=1e-5)  # as close as the noise allows


def test_x_tolerance_controls_x_convergence():
    loose = least_squares(exponential_fit, [1.0, 0.5],
                          convergence=Convergence(x_tolerance=1e-2, absolute_tolerance=0.0))
    tight = least_squares(exponential_fit, [1.0, 0.5],
                          convergence=Convergence(x_tolerance=1e-12, absolute_tolerance=0.0))
    assert loose.status in ("x", "relative_function_and_x")
    assert loose.iterations < tight.iterations


def test_max_iterations_counts_accepted_steps():
    res = least_squares(rosenbrock, [-1.2, 1.0], convergence=Convergence(max_iterations=3))
    assert res.status == "max_iterations" and res.iterations == 3
    assert len(res.history) == 4  # the start and one cost per accepted step
    assert np.all(np.diff(res.history) < 0)


def test_the_flat_keywords_of_0_1_still_work_for_one_release():
    """least_squares takes its stopping rules as a Convergence record; the flat keywords of
    rotoruq 0.1 give bitwise the same result with a DeprecationWarning naming the record field;
    an unknown keyword is a TypeError with the closest name."""
    import inspect
    import warnings

    assert len(inspect.signature(least_squares).parameters) <= 12
    new = least_squares(brown_dennis, [25.0, 5.0, -5.0, -1.0],
                        convergence=Convergence(tolerance=1e-10, x_tolerance=1e-9,
                                                max_function_evaluations=200))
    with pytest.warns(DeprecationWarning) as caught:
        old = least_squares(brown_dennis, [25.0, 5.0, -5.0, -1.0], tolerance=1e-10,
                            x_tolerance=1e-9, max_function_evaluations=200)
    said = {str(w.message) for w in caught}
    assert ("least_squares(tolerance=...) is deprecated and will be removed in the next "
            "release: pass convergence=Convergence(tolerance=...)") in said
    assert len(said) == 3
    assert all(w.filename == __file__ for w in caught)  # the warning points at the caller
    for field in ("x", "residuals", "jacobian", "covariance", "history"):
        np.testing.assert_array_equal(getattr(old, field), getattr(new, field))
    assert (old.cost, old.iterations, old.n_evaluations, old.status) == (
        new.cost, new.iterations, new.n_evaluations, new.status)
    # a flat keyword overrides that field of the record given
    with pytest.warns(DeprecationWarning, match="Convergence"):
        mixed = least_squares(brown_dennis, [25.0, 5.0, -5.0, -1.0],
                              convergence=Convergence(tolerance=1.0, x_tolerance=1e-9,
                                                      max_function_evaluations=200),
                              tolerance=1e-10)
    np.testing.assert_array_equal(mixed.x, new.x)
    with pytest.raises(TypeError, match="'max_iteration'.*did you mean 'max_iterations'"):
        least_squares(rosenbrock, [-1.2, 1.0], max_iteration=3)
    with pytest.raises(ParameterError, match="convergence must be a Convergence"):
        least_squares(rosenbrock, [-1.2, 1.0], convergence={"tolerance": 1e-3})
    # calibrate and calibrate_under_uncertainty take the fields flat (a study step's options),
    # without a warning, gathered into the same record
    model = FunctionModel(lambda x: x[:, :1] * np.array([[1.0, 2.0, 3.0]]), ["k"],
                          ["y1", "y2", "y3"])
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        flat = calibrate(model, [2.4, 5.1, 7.4], ["k"], x0=[1.0], tolerance=1e-12,
                         max_iterations=7)
    rec = calibrate(model, [2.4, 5.1, 7.4], ["k"], x0=[1.0],
                    convergence=Convergence(tolerance=1e-12, max_iterations=7))
    np.testing.assert_array_equal(flat.x, rec.x)
    assert flat.least_squares.history.tolist() == rec.least_squares.history.tolist()


# --- calibrate --------------------------------------------------------------------------------


def _decay_model():
    # y_j = a * exp(-b * t_j) at three times, inputs (b, a, t_shift) in a permuted order
    t = np.array([0.5, 1.0, 2.0])

    def f(x):
        b, a, c = x[:, 0], x[:, 1], x[:, 2]
        return a[:, None] * np.exp(-b[:, None] * (t + c[:, None]))

    return FunctionModel(f, ["b", "a", "c"], ["y05", "y1", "y2"]), t


def test_calibrate_recovers_parameters_from_several_experiments():
    model, t = _decay_model()
    truth = {"a": 3.0, "b": 0.7}
    rng = np.random.default_rng(0)
    clean = truth["a"] * np.exp(-truth["b"] * t)
    data = clean + 0.01 * rng.standard_normal((5, 3))
    res = calibrate(model, data, ["a", "b"], x0=[1.0, 0.1], fixed={"c": 0.0},
                    noise_std=1e-2, tolerance=1e-12)
    assert res.names_in == ("a", "b")
    np.testing.assert_allclose(res.x, [3.0, 0.7], rtol=0.02)
    assert res.residuals.shape == (5, 3)
    assert res.n_evaluations == 5 * res.least_squares.n_evaluations  # 5 experiments per point
    # the intervals from known variances cover the truth
    lo, hi = res.least_squares.confidence_intervals.T
    assert np.all((lo < [3.0, 0.7]) & ([3.0, 0.7] < hi))
    assert res.parameters == {"a": pytest.approx(res.x[0]), "b": pytest.approx(res.x[1])}


def test_calibrate_with_parameter_space_and_per_experiment_conditions():
    model, t = _decay_model()
    shifts = np.array([0.0, 0.5, 1.0])
    data = 2.0 * np.exp(-0.4 * (t[None, :] + shifts[:, None]))
    space = ParameterSpace({"a": Uniform(1.0, 5.0), "b": Normal(0.3, 0.1)})
    res = calibrate(model, data, space, fixed={"c": shifts},
                    convergence=Convergence(tolerance=1e-12))
    np.testing.assert_allclose(res.x, [2.0, 0.4], rtol=1e-6)
    assert res.cost < 1e-14


def test_calibrate_bad_inputs():
    model, _ = _decay_model()
    with pytest.raises(ParameterError, match="no value"):
        calibrate(model, np.ones(3), ["a", "b"], x0=[1, 1])
    with pytest.raises(ParameterError, match="not inputs of the model"):
        calibrate(model, np.ones(3), ["a", "zz"], x0=[1, 1], fixed={"c": 0})
    with pytest.raises(ParameterError, match="columns"):
        calibrate(model, np.ones(4), ["a", "b"], x0=[1, 1], fixed={"c": 0})
    with pytest.raises(ParameterError, match="x0"):
        calibrate(model, np.ones(3), ["a", "b"], fixed={"c": 0})
    with pytest.raises(ParameterError, match="noise_std"):
        calibrate(model, np.ones(3), ["a", "b"], x0=[1, 1], fixed={"c": 0}, noise_std=-1)
    # no data: an error, not the start point reported as a successful fit
    with pytest.raises(ParameterError, match="needs data: got no observations"):
        calibrate(model, np.empty((0, 3)), ["a", "b"], x0=[1, 1], fixed={"c": 0})
    one = FunctionModel(lambda x: x[:, 0] * x[:, 1], ["a", "b"], ["y"])
    with pytest.raises(ParameterError, match="underdetermined"):
        calibrate(one, [2.0], ["a", "b"], x0=[1, 1])


def test_scipy_lm_through_same_interface_and_batched_fd_calls():
    sizes = []

    def fun(X):
        sizes.append(X.shape[0])
        return jennrich_sampson(X)

    res = least_squares(fun, [0.3, 0.4], optimizer="lm",
                        convergence=Convergence(tolerance=1e-10))
    assert res.optimizer == "lm" and res.converged
    assert 2 * res.cost == pytest.approx(124.362, rel=1e-5)
    assert res.n_evaluations == sum(sizes)
    sizes.clear()
    ours = least_squares(fun, [0.3, 0.4])
    assert set(sizes) == {1, 2}  # trial points alone, Jacobians as one batch of p = 2 points
    assert ours.n_evaluations == sum(sizes)
