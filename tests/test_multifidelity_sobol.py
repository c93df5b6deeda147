"""Multi-fidelity Sobol' indices on the Ishigami ladder of Qian et al. (2018).

The ladder: f(x) = sin x1 (1 + b4 x3^4 + b2 x3^2) + a sin^2 x2, x ~ U(-pi, pi)^3, with
(a, b4, b2) = (5, 0.1, 0) for the high-fidelity Ishigami function, (4.75, 0.1, 0) and
(3, 0, 0.9) for the two cheap models, costs 1, 0.05, 0.001 per evaluation (Qian et al., sec.
5.1). With g(x3) = 1 + b4 x3^4 + b2 x3^2 every quantity is a moment of x3:
Cov[f, f'] = E[g g'] / 2 + a a' / 8, main indices (E[g]^2 / 2, a^2 / 8, 0) / V and total
indices (E[g^2] / 2, a^2 / 8, Var[g] / 2) / V.
"""

from __future__ import annotations

import numpy as np
import pytest

import rotoruq as rq
from rotoruq.errors import EvaluationError, ParameterError

LADDER = ((5.0, 0.1, 0.0), (4.75, 0.1, 0.0), (3.0, 0.0, 0.9))
COSTS = (1.0, 0.05, 0.001)
SPACE = rq.ParameterSpace({f"x{i}": rq.Uniform(-np.pi, np.pi) for i in (1, 2, 3)})


def _ishigami(a: float, b4: float, b2: float):
    def f(x):
        g = 1.0 + b4 * x[:, 2] ** 4 + b2 * x[:, 2] ** 2
        return np.sin(x[:, 0]) * g + a * np.sin(x[:, 1]) ** 2
    return f


def _models(ladder=LADDER, names_out=("y",)):
    return [rq.FunctionModel(_ishigami(*p), SPACE.names, names_out) for p in ladder]


def _x3_moments() -> np.ndarray:
    """E[x3^(p + q)] for p, q in the powers (0, 2, 4) of g."""
    powers = np.array([0, 2, 4])
    k = powers[:, None] + powers[None, :]
    return np.pi ** k / (k + 1.0)


def _exact(ladder=LADDER):
    """Covariance (K, K) of the ladder's outputs; main, total (3,) of the first model."""
    coef = np.array([[1.0, b2, b4] for _, b4, b2 in ladder])  # g's coefficients of x3^(0, 2, 4)
    a = np.array([p[0] for p in ladder])
    M = _x3_moments()
    cov = 0.5 * coef @ M @ coef.T + np.outer(a, a) / 8.0
    eg = coef[0] @ M[0]
    eg2 = coef[0] @ M @ coef[0]
    v = cov[0, 0]
    main = np.array([eg**2 / 2.0, a[0] ** 2 / 8.0, 0.0]) / v
    total = np.array([eg2 / 2.0, a[0] ** 2 / 8.0, (eg2 - eg**2) / 2.0]) / v
    return cov, main, total


def test_the_ladders_closed_form_matches_sampling_and_the_classic_ishigami_values():
    cov, main, total = _exact()
    # the textbook Ishigami (a = 5, b = 0.1) values
    v = 0.5 * (1 + 0.1 * np.pi**4 / 5) ** 2
    v13 = 0.1**2 * np.pi**8 * (1 / 18 - 1 / 50)
    assert cov[0, 0] == pytest.approx(v + 25 / 8 + v13, rel=1e-12)
    assert main[0] == pytest.approx(v / cov[0, 0], rel=1e-12)
    assert total[2] == pytest.approx(v13 / cov[0, 0], rel=1e-12)
    x = SPACE.draw(400_000, design="random", seed=0)
    y = np.stack([_ishigami(*p)(x) for p in LADDER])
    np.testing.assert_allclose(np.cov(y), cov, rtol=2e-2)
    # and the pilot's correlations are the ladder's
    res = rq.multifidelity_sobol(_models(), SPACE, 100, budget_unit="hf_runs", costs=COSTS,
                                 n_pilot=4000, seed=1)
    rho = cov[0] / np.sqrt(cov[0, 0] * np.diag(cov))
    np.testing.assert_allclose(res.correlation[0], rho, atol=0.01)


R = 100  # repeats
BUDGET = 250  # high-fidelity runs (50 base samples) for the main phase
N_PILOT = 40


@pytest.fixture(scope="module")
def repeats():
    """R multi-fidelity runs and R plain pick-and-freeze runs of the same total cost."""
    models = _models()
    mf = [rq.multifidelity_sobol(models, SPACE, BUDGET, budget_unit="hf_runs", costs=COSTS,
                                 n_pilot=N_PILOT, seed=s) for s in range(R)]
    spent = mf[0].cost_pilot + mf[0].cost_main  # the same for every seed up to rounding
    n_plain = int(spent / (COSTS[0] * (SPACE.dim + 2)))
    plain = [rq.sobol_indices(models[0], SPACE, n_plain, estimator="saltelli2010",
                              design="random", n_bootstrap=0, seed=1000 + s) for s in range(R)]
    return mf, plain, spent


@pytest.mark.slow  # `repeats` (~17 CPU-s) is theirs alone; the other tests here stay fast
def test_unbiased_over_seeds_with_the_predicted_standard_errors(repeats):
    mf, _, _ = repeats
    _, main, total = _exact()
    for name, exact in (("main", main), ("total", total)):
        est = np.array([getattr(r, name)[0] for r in mf])  # (R, d)
        se = np.array([getattr(r, f"{name}_se")[0] for r in mf])
        spread = est.std(axis=0, ddof=1)
        # the ratio's bias is O(se^2) ~ 1e-4, well inside the mean's sampling error
        assert np.all(np.abs(est.mean(axis=0) - exact) < 4.0 * spread / np.sqrt(R)), name
        ratio = spread / np.sqrt(np.mean(se**2, axis=0))
        assert np.all((ratio > 1 / 1.5) & (ratio < 1.5)), (name, ratio)
    cov, _, _ = _exact()
    v = np.array([r.variance[0] for r in mf])
    assert abs(v.mean() - cov[0, 0]) < 4.0 * v.std(ddof=1) / np.sqrt(R)
    assert v.std(ddof=1) / np.sqrt(np.mean([r.variance_se[0] ** 2 for r in mf])) == \
        pytest.approx(1.0, abs=0.5)


@pytest.mark.slow  # `repeats` (~17 CPU-s) is theirs alone; the other tests here stay fast
def test_smaller_variance_than_plain_pick_freeze_at_equal_cost(repeats):
    mf, plain, spent = repeats
    assert all(abs(r.cost_pilot + r.cost_main - spent) < 0.01 * spent for r in mf)
    for name in ("main", "total"):
        var_mf = np.var([getattr(r, name)[0] for r in mf], axis=0, ddof=1)
        var_plain = np.var([getattr(p, name)[0] for p in plain], axis=0, ddof=1)
        assert np.all(var_mf < var_plain / 5.0), (name, var_mf, var_plain)
        # the predicted cost saving (equivalent HF runs over the cost spent) is what the
        # repeats measure: plain's variance over the multi-fidelity one at equal cost
        predicted = np.mean([r.speedup[name][0] for r in mf], axis=0)
        measured = var_plain / var_mf
        assert np.all((measured / predicted > 0.5) & (measured / predicted < 2.0)), \
            (name, measured, predicted)


def test_the_result_record():
    res = rq.multifidelity_sobol(_models(), SPACE, 200, budget_unit="hf_runs", costs=COSTS,
                                 n_pilot=30, seed=5)
    d = SPACE.dim
    assert res.names_in == SPACE.names and res.names_out == ("y",)
    assert res.models_used[0] == 0 and res.allocation[0] >= 2
    assert np.all(np.diff(res.allocation[list(res.models_used)]) >= 0)  # mfmc: nested
    assert res.cost_main <= 200.0 * (1 + 1e-12) and res.budget == 200.0
    assert res.cost_main == pytest.approx(float((d + 2) * np.dot(COSTS, res.allocation)))
    assert res.n_evaluations == (d + 2) * (30 * 3 + int(res.allocation.sum()))
    assert res.main.shape == res.total_se.shape == (1, d)
    assert res.term_correlation.shape == (1, 2 * d + 1, 3)
    np.testing.assert_allclose(res.term_correlation[:, :, 0], 1.0, rtol=1e-12)
    assert res.weights["main"].shape == (1, d, len(res.models_used) - 1)
    assert res.allocation_term in {"variance", *(f"{s}:{x}" for s in ("main", "total")
                                                 for x in SPACE.names)}
    rows = res.table()
    assert len(rows) == d and rows[1]["input"] == "x2"
    assert rows[1]["total_se"] == res.total_se[0, 1]
    assert rows[0]["main_n_equivalent_hf"] == res.n_equivalent_hf["main"][0, 0]


def test_the_high_fidelity_model_alone_is_plain_pick_freeze():
    # one model: no control variate; the equivalent HF runs are the runs spent
    res = rq.multifidelity_sobol(_models()[:1], SPACE, 500, budget_unit="hf_runs",
                                 costs=[1.0], n_pilot=20, seed=2)
    assert res.allocation.tolist() == [100] and res.weights["total"].shape == (1, 3, 0)
    np.testing.assert_allclose(res.n_equivalent_hf["total"], 500.0, rtol=1e-6)
    np.testing.assert_allclose(res.n_equivalent_hf["main"], 500.0, rtol=1e-6)


@pytest.mark.parametrize("estimator", ["acvmf", "acvis"])
def test_acv_estimators(estimator):
    _, main, total = _exact()
    res = rq.multifidelity_sobol(_models(), SPACE, 1000, budget_unit="hf_runs", costs=COSTS,
                                 n_pilot=30, estimator=estimator, seed=4)
    used = list(res.models_used)
    assert res.estimator == estimator and used[0] == 0 and len(used) >= 2
    assert np.all(res.allocation[used[1:]] >= res.allocation[0]) and res.allocation[0] >= 2
    assert res.cost_main <= 1000.0 * (1 + 1e-12)
    assert np.all(np.abs(res.main[0] - main) < 5.0 * res.main_se[0])
    assert np.all(np.abs(res.total[0] - total) < 5.0 * res.total_se[0])
    assert np.all(res.speedup["total"] > 1.0) and np.all(res.speedup["main"] > 1.0)


def test_two_models_acvmf_is_mfmc():
    # with one cheap model ACV-MF's sets are MFMC's; its numerical optimum finds the same split
    kw = dict(budget_unit="hf_runs", costs=COSTS[:2], n_pilot=30, seed=2)
    a = rq.multifidelity_sobol(_models()[:2], SPACE, 1000, estimator="mfmc", **kw)
    b = rq.multifidelity_sobol(_models()[:2], SPACE, 1000, estimator="acvmf", **kw)
    assert np.abs(a.allocation - b.allocation).max() <= 0.01 * a.allocation.max()
    np.testing.assert_allclose(a.total, b.total, atol=0.5 * a.total_se.max())


def test_same_seed_same_result_bitwise():
    kw = dict(budget_unit="hf_runs", costs=COSTS, n_pilot=20)
    a = rq.multifidelity_sobol(_models(), SPACE, 100, seed=7, **kw)
    b = rq.multifidelity_sobol(_models(), SPACE, 100, seed=7, **kw)
    c = rq.multifidelity_sobol(_models(), SPACE, 100, seed=8, **kw)
    for f in ("main", "total", "main_se", "total_se", "variance", "allocation"):
        assert np.array_equal(getattr(a, f), getattr(b, f)), f
    assert not np.array_equal(a.main, c.main)


def test_several_responses_and_the_target():
    ladder2 = [rq.FunctionModel(lambda x, p=p: np.column_stack(
        [_ishigami(*p)(x), _ishigami(p[0], 0.0, 0.0)(x)]), SPACE.names, ["y", "z"])
        for p in LADDER[:2]]
    res = rq.multifidelity_sobol(ladder2, SPACE, 100, budget_unit="hf_runs", costs=COSTS[:2],
                                 n_pilot=20, target="z", seed=3)
    assert res.target == "z" and res.main.shape == (2, 3) and len(res.table()) == 6
    # z = sin x1 + a sin^2 x2: x3 has no effect at all, its total index is exactly 0
    assert res.total[1, 2] == 0.0
    with pytest.raises(ParameterError, match="target"):
        rq.multifidelity_sobol(ladder2, SPACE, 100, costs=COSTS[:2], target="w")


def test_bad_input_raises_clear_errors():
    models = _models()
    with pytest.raises(ParameterError, match="unknown estimator"):
        rq.multifidelity_sobol(models, SPACE, 100, estimator="mlmc", costs=COSTS)
    other = rq.FunctionModel(lambda x: x[:, 0], ["x1", "x2", "w"], ["y"])
    with pytest.raises(ParameterError, match="inputs"):
        rq.multifidelity_sobol([models[0], other], SPACE, 100, costs=COSTS[:2])
    renamed = rq.FunctionModel(_ishigami(*LADDER[1]), SPACE.names, ["thrust"])
    with pytest.raises(ParameterError, match="responses"):
        rq.multifidelity_sobol([models[0], renamed], SPACE, 100, costs=COSTS[:2])
    with pytest.raises(ParameterError, match="two high-fidelity base samples"):
        rq.multifidelity_sobol(models, SPACE, 9.0, costs=COSTS)  # 2 (d + 2) = 10 needed
    with pytest.raises(ParameterError, match="base samples"):
        rq.multifidelity_sobol(models, SPACE, 9, budget_unit="hf_runs", costs=COSTS)
    with pytest.raises(ParameterError, match="budget_unit"):
        rq.multifidelity_sobol(models, SPACE, 100, budget_unit="seconds", costs=COSTS)
    with pytest.raises(ParameterError, match="costs"):
        rq.multifidelity_sobol(models, SPACE, 100, costs=[1.0, 0.1])
    with pytest.raises(ParameterError, match="n_pilot"):
        rq.multifidelity_sobol(models, SPACE, 100, costs=COSTS, n_pilot=3)
    with pytest.raises(ParameterError, match="budget"):
        rq.multifidelity_sobol(models, SPACE, -1.0, costs=COSTS)
    broken = rq.FunctionModel(lambda x: np.full(len(x), np.nan), SPACE.names, ["y"])
    with pytest.raises(EvaluationError, match="pilot"):
        rq.multifidelity_sobol([broken, models[1]], SPACE, 100, costs=COSTS[:2], n_pilot=5)


def test_failed_runs_leave_the_pilot_and_stop_the_main_phase():
    def flaky(x):
        y = _ishigami(*LADDER[1])(x)
        return np.where(x[:, 0] > 2.5, np.nan, y)  # fails on ~10 % of the points

    models = [_models()[0], rq.FunctionModel(flaky, SPACE.names, ["y"])]
    with pytest.warns(RuntimeWarning, match="left out of the pilot statistics"), \
            pytest.raises(EvaluationError, match=r"models\[1\] failed"):
        rq.multifidelity_sobol(models, SPACE, 200, budget_unit="hf_runs", costs=COSTS[:2],
                               n_pilot=40, seed=0)
