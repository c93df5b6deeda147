import numpy as np
import pytest

import rotoruq as rq
from rotoruq.errors import ModelShapeError, ParameterError
from rotoruq.model import align_inputs


def test_function_model_batch_and_nan_rows():
    m = rq.FunctionModel(lambda x: np.log(x[:, 0]), ["x"], ["y"])
    out = rq.evaluate(m, np.array([[1.0], [-1.0], [np.e]]))
    np.testing.assert_allclose(out.values[[0, 2], 0], [0.0, 1.0])
    assert list(out.failures) == [1]
    assert out.ok.tolist() == [True, False, True]


def test_wrong_shape_is_reported():
    m = rq.FunctionModel(lambda x: np.zeros((x.shape[0], 3)), ["x"], ["y"])
    with pytest.raises(ModelShapeError, match=r"expected \(2, 1\)"):
        rq.evaluate(m, np.zeros((2, 1)))


def test_align_inputs():
    m = rq.FunctionModel(lambda x: x, ["a", "b"], ["a", "b"])
    assert align_inputs(m, ["a", "b"]) is None
    assert align_inputs(m, ["b", "a"]).tolist() == [1, 0]
    with pytest.raises(ParameterError, match="not inputs of the model"):
        align_inputs(m, ["a", "c"])


# --- the one finite-difference gradient --------------------------------------------------------

import inspect  # noqa: E402

from rotoruq.model import (  # noqa: E402
    FD_STEP,
    FixedInputs,
    check_gradient_option,
    finite_difference,
    model_gradient,
)


def _f(x):
    """(n, 2) -> (n, 2): [sin(x0) x1, exp(x1)], gradient [[cos(x0) x1, sin(x0)], [0, exp(x1)]]."""
    return np.column_stack([np.sin(x[:, 0]) * x[:, 1], np.exp(x[:, 1])])


def _grad(x):
    g = np.zeros((x.shape[0], 2, 2))
    g[:, 0, 0] = np.cos(x[:, 0]) * x[:, 1]
    g[:, 0, 1] = np.sin(x[:, 0])
    g[:, 1, 1] = np.exp(x[:, 1])
    return g


POINTS = np.array([[0.3, 1.2], [-2.0, 0.5], [0.0, -0.7]])


def test_central_differences_one_call_and_second_order_accurate():
    calls = []

    def f(x):
        calls.append(x.shape[0])
        return _f(x)

    fd = finite_difference(f, POINTS)
    assert calls == [3 * 5] and fd.n_evaluations == 15  # n (2d + 1) points in ONE call
    np.testing.assert_array_equal(fd.values, _f(POINTS))
    # error ~ h^2 |f'''| + eps/h: 1e-12 + 2e-10 with h = 1e-6 relative
    np.testing.assert_allclose(fd.gradient, _grad(POINTS), rtol=1e-8, atol=1e-8)
    # relative step; fd_step itself at x = 0 (the last point), or fd_step * scale with a scale
    np.testing.assert_allclose(fd.steps[2], FD_STEP * np.array([1.0, 0.7]), rtol=1e-9)
    scaled = finite_difference(_f, POINTS, scale=[2.0, 0.1])
    np.testing.assert_allclose(scaled.steps[2], FD_STEP * np.array([2.0, 0.7]), rtol=1e-9)
    assert not fd.failures


def test_forward_differences_known_values_and_upper_bound():
    seen = []

    def f(x):
        seen.append(x.copy())
        return _f(x)

    x = np.array([0.3, 1.2])
    fd = finite_difference(f, x, central=False, values=_f(x[None]), upper=[np.inf, 1.2])
    assert seen[0].shape == (2, 2)  # d points: the value at x is not evaluated again
    assert np.all(seen[0][:, 1] <= 1.2)  # never past the upper bound: that step went backward
    assert fd.steps[0, 0] > 0 > fd.steps[0, 1]
    np.testing.assert_allclose(fd.gradient[0], _grad(x[None])[0], rtol=1e-5, atol=1e-6)


def test_failed_stencil_points_fail_only_their_point():
    def f(x):
        y = _f(x)
        y[x[:, 0] < -1.0] = np.nan
        return y

    fd = finite_difference(f, POINTS)
    assert list(fd.failures) == [1] and "5 of 5 evaluations failed" in fd.failures[1]
    np.testing.assert_allclose(fd.gradient[[0, 2]], _grad(POINTS[[0, 2]]), rtol=1e-8, atol=1e-8)
    assert np.all(np.isnan(fd.gradient[1]))


def test_model_gradient_modes_agree_in_any_column_order():
    model = rq.FunctionModel(_f, ["a", "b"], ["u", "v"], gradient=_grad)
    plain = rq.FunctionModel(_f, ["a", "b"], ["u", "v"])
    swapped = POINTS[:, ::-1]  # columns ordered (b, a)
    expect = _grad(POINTS)[:, :, ::-1]
    analytic = model_gradient(model, swapped, names_in=["b", "a"])
    numeric = model_gradient(plain, swapped, names_in=["b", "a"])
    own = model_gradient(plain, swapped, names_in=["b", "a"],
                         gradient=lambda x: _grad(x[:, ::-1])[:, :, ::-1])
    assert analytic.n_evaluations == 3 and numeric.n_evaluations == 15
    np.testing.assert_allclose(analytic.gradient, expect, rtol=1e-15)
    np.testing.assert_allclose(numeric.gradient, expect, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(own.gradient, expect, rtol=1e-15)
    np.testing.assert_array_equal(numeric.values, _f(POINTS))


def test_model_gradient_reports_reasons_and_bad_options():
    failing = rq.FunctionModel(lambda x: np.log(x), ["a"], ["y"])
    with np.errstate(invalid="ignore"):
        out = model_gradient(failing, np.array([[1.0], [-1.0]]))
    assert list(out.failures) == [1] and "non-finite response" in out.failures[1]
    assert check_gradient_option("auto", failing) == "finite_difference"
    with pytest.raises(ParameterError, match="has no gradient method"):
        check_gradient_option("analytic", failing)
    with pytest.raises(ParameterError, match="'finite_difference' or a callable"):
        check_gradient_option("fd", failing)


def test_every_method_defaults_to_the_one_step():
    from rotoruq.methods.cuu import calibrate_under_uncertainty
    from rotoruq.methods.least_squares import least_squares
    from rotoruq.methods.reliability import mean_value, mpp_search

    for f in (finite_difference, model_gradient, least_squares, mean_value, mpp_search,
              calibrate_under_uncertainty):
        assert inspect.signature(f).parameters["fd_step"].default == FD_STEP, f.__name__
    for f in (mean_value, mpp_search):  # deterministic: no seed
        assert "seed" not in inspect.signature(f).parameters


def test_fixed_inputs_hold_columns_and_slice_the_gradient():
    def grad(x):
        return np.column_stack([x[:, 1], x[:, 0], np.ones(len(x))])

    model = rq.FunctionModel(lambda x: (x[:, 0] * x[:, 1] + x[:, 2]), ["a", "k", "b"], ["y"],
                             gradient=grad)
    view = FixedInputs(model, {"k": 3.0})
    assert view.names_in == ("a", "b")
    x = np.array([[1.0, 2.0], [0.5, -1.0]])
    np.testing.assert_allclose(view(x)[:, 0], 3.0 * x[:, 0] + x[:, 1])
    np.testing.assert_allclose(view.gradient(x), [[[3.0, 1.0]], [[3.0, 1.0]]])
    with pytest.raises(ParameterError, match="not inputs"):
        FixedInputs(model, {"zz": 1.0})


# --- vocabulary (docs/vocabulary.md) of the model layer and the calibration methods -----------

RETIRED = {  # old spelling -> the one name
    "method": "sampler / optimizer / design / estimator", "jacobian": "gradient",
    "weights": "noise_std", "data_variance": "noise_std", "data_covariance": "noise_std",
    "start": "x0", "chain_samples": "n_samples", "build_samples": "n_emulator_samples",
    "n_steps": "n_samples", "n": "n_samples", "n_more": "n_samples", "tol": "tolerance",
    "max_iter": "max_iterations", "convergence_tolerance": "tolerance",
    "identifiability_tol": "identifiability_tolerance", "responses": "names_out",
    "names": "names_in", "labels": "names_in", "success": "converged",
    "n_model_evals": "n_evaluations", "n_model_evaluations": "n_evaluations",
    "n_likelihood_evals": "n_likelihood_evaluations", "predictive_names": "names_out",
}


def test_calibration_api_follows_the_vocabulary():
    import dataclasses

    from rotoruq import model as model_layer
    from rotoruq.methods import cuu, least_squares, mcmc, nl2sol, reliability

    checked = 0
    for module in (model_layer, least_squares, nl2sol, cuu, reliability, mcmc):
        for name in module.__all__:
            obj = getattr(module, name)
            if dataclasses.is_dataclass(obj):
                # a result may hold the Jacobian matrix itself; "jacobian" is a retired option
                fields = {f.name for f in dataclasses.fields(obj)} - {"jacobian"}
                assert not fields & RETIRED.keys(), (name, fields & RETIRED.keys())
                if name.endswith(("Result", "Check", "Outcome")) or name in ("Gradient",
                                                                           "EvalBatch"):
                    assert obj.__dataclass_params__.frozen and not obj.__dataclass_params__.eq
            if callable(obj) and not isinstance(obj, type) or isinstance(obj, type) and \
                    not dataclasses.is_dataclass(obj):
                try:
                    params = inspect.signature(obj).parameters
                except (TypeError, ValueError):
                    continue
                assert not params.keys() & RETIRED.keys(), (name, params.keys() & RETIRED.keys())
                if "seed" in params:
                    assert params["seed"].kind is inspect.Parameter.KEYWORD_ONLY, name
                checked += 1
    assert checked >= 15
