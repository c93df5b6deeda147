import numpy as np
import pytest

import rotoruq as rq
from conftest import ishigami
from rotoruq.errors import ModelShapeError, ParameterError
from rotoruq.methods.sensitivity import ESTIMATORS, sobol_indices

A, B = 7.0, 0.1
V = A**2 / 8 + B * np.pi**4 / 5 + B**2 * np.pi**8 / 18 + 0.5
V1, V2, V13 = 0.5 * (1 + B * np.pi**4 / 5) ** 2, A**2 / 8, 8 * B**2 * np.pi**8 / 225
S_EXACT = np.array([V1, V2, 0.0]) / V
ST_EXACT = np.array([V1 + V13, V2, V13]) / V


def ishigami_setup():
    space = rq.ParameterSpace({k: rq.Uniform(-np.pi, np.pi) for k in ("x1", "x2", "x3")})
    calls = []

    def f(x):
        calls.append(x.shape[0])
        return ishigami(x)

    return space, rq.FunctionModel(f, space.names, ["y"]), calls


@pytest.mark.parametrize("estimator", ESTIMATORS)
def test_ishigami_exact_indices(estimator):
    space, model, calls = ishigami_setup()
    res = sobol_indices(model, space, 4096, estimator=estimator, seed=1, n_bootstrap=100)
    assert calls == [4096 * 5]  # N (d + 2) points in one batch
    assert res.n_evaluations == 4096 * 5
    np.testing.assert_allclose(res.main[0], S_EXACT, atol=0.015)
    np.testing.assert_allclose(res.total[0], ST_EXACT, atol=0.015)
    assert res.variance[0] == pytest.approx(V, rel=0.02)
    lo, hi = res.main_ci[0, :, 0], res.main_ci[0, :, 1]
    assert np.all(lo <= res.main[0]) and np.all(res.main[0] <= hi)
    assert np.all(hi - lo < 0.15)  # bootstrap ignores the QMC gain: conservative
    assert [r[0] for r in res.ranking()] == ["x1", "x2", "x3"]
    assert [r[0] for r in res.ranking(by="main")] == ["x2", "x1", "x3"]


def test_permuted_names_multiple_responses_and_seed():
    space = rq.ParameterSpace(
        {
            "x3": rq.Uniform(-np.pi, np.pi),
            "x1": rq.Uniform(-np.pi, np.pi),
            "x2": rq.Uniform(-np.pi, np.pi),
        }
    )
    model = rq.FunctionModel(
        lambda x: np.column_stack([ishigami(x), x[:, 0] + 2 * x[:, 1]]),
        ["x1", "x2", "x3"],
        ["ish", "lin"],
    )
    r1 = sobol_indices(model, space, 1024, seed=4, n_bootstrap=0)
    r2 = sobol_indices(model, space, 1024, seed=4, n_bootstrap=0)
    np.testing.assert_array_equal(r1.main, r2.main)
    assert r1.main.shape == (2, 3)
    np.testing.assert_allclose(r1.main[0], S_EXACT[[2, 0, 1]], atol=0.03)
    np.testing.assert_allclose(r1.total[1], [0.0, 0.2, 0.8], atol=0.01)  # linear: S = ST
    assert r1.ranking("lin")[0][0] == "x2"
    assert np.isnan(r1.main_ci).all()


def test_failed_rows_dropped_and_bad_input():
    space, _, _ = ishigami_setup()
    model = rq.FunctionModel(
        lambda x: np.where(x[:, 0] > 3.0, np.nan, ishigami(x)), space.names, ["y"]
    )
    with pytest.warns(RuntimeWarning, match="base rows"):
        res = sobol_indices(model, space, 512, seed=2, n_bootstrap=0)
    assert 0 < res.n_dropped[0] < 512 and np.all(np.isfinite(res.main))
    with pytest.raises(ParameterError, match="unknown estimator"):
        sobol_indices(model, space, 64, estimator="martinez")
    bad = rq.FunctionModel(lambda x: np.ones((3, 1)), space.names, ["y"])
    with pytest.raises(ModelShapeError):
        sobol_indices(bad, space, 64)
