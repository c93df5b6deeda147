"""Multi-fidelity Monte Carlo and approximate control variates on the monomial ladder.

The ladder of the ACV papers (Gorodetsky et al. 2020, sec. 6; also PyApprox's and MXMCPy's
examples): f_k(x) = x^(5 - k), x ~ U(0, 1). Every moment is a polynomial integral, so the exact
mean, variance, covariances and fourth moments (and with them each estimator's exact variance)
are known in closed form.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.polynomial import Polynomial

import rotoruq as rq
from rotoruq.errors import ParameterError
from rotoruq.methods.acv import (
    allocate,
    estimator_covariance,
    estimator_variance,
    optimal_weights,
    sample_sets,
)

POWERS = (5, 4, 3)
SPACE = rq.ParameterSpace({"x": rq.Uniform(0.0, 1.0)})


def _ladder(powers=POWERS):
    return [rq.FunctionModel(lambda x, p=p: x[:, 0] ** p, ["x"], ["y"]) for p in powers]


def _exact(powers=POWERS):
    """Mean (K,), covariance (K, K) and E[d_i^2 d_j^2] (K, K) of x^p, x ~ U(0, 1)."""
    def integral(q: Polynomial) -> float:
        Q = q.integ()
        return float(Q(1.0) - Q(0.0))

    polys = [Polynomial([0.0] * p + [1.0]) for p in powers]
    mean = np.array([integral(q) for q in polys])
    d = [q - m for q, m in zip(polys, mean, strict=True)]
    cov = np.array([[integral(a * b) for b in d] for a in d])
    m22 = np.array([[integral(a * a * b * b) for b in d] for a in d])
    return mean, cov, m22


def test_exact_moments_of_the_ladder():
    mean, cov, m22 = _exact()
    x = np.random.default_rng(0).random(400_000)
    Y = np.stack([x**p for p in POWERS])
    np.testing.assert_allclose(mean, Y.mean(axis=1), rtol=5e-3)
    np.testing.assert_allclose(cov, np.cov(Y), rtol=2e-2)
    assert mean[0] == pytest.approx(1 / 6) and cov[0, 0] == pytest.approx(1 / 11 - 1 / 36)


def test_mfmc_allocation_matches_the_closed_form_for_two_models():
    _, cov, _ = _exact((5, 4))
    w, budget = np.array([1.0, 0.01]), 100.0
    rho2 = cov[0, 1] ** 2 / (cov[0, 0] * cov[1, 1])
    r = np.sqrt(w[0] * rho2 / (w[1] * (1.0 - rho2)))  # Peherstorfer et al. (2016), eq. 3.16
    plan = allocate(cov, w, budget, estimator="mfmc")
    assert plan.models == (0, 1)
    assert plan.ratios[1] == pytest.approx(r, rel=1e-12)
    n0 = budget / (w[0] + w[1] * r)
    # whole runs: the high-fidelity count next to the optimum's, what it leaves spent on the
    # cheap model to within one of its runs, no worse than the plain floors
    floors = [int(np.floor(n0)), int(np.floor(r * n0))]
    assert plan.n_samples[0] - floors[0] in (0, 1)
    assert budget - w[1] < plan.cost <= budget
    assert plan.variance <= estimator_variance("mfmc", floors, "mean", cov)
    # the minimum variance, sigma^2 / B (sum_k sqrt(w_k (rho_k^2 - rho_{k+1}^2)))^2 (eq. 3.19)
    v_min = cov[0, 0] / budget * (np.sqrt(w[0] * (1 - rho2)) + np.sqrt(w[1] * rho2)) ** 2
    assert estimator_variance("mfmc", n0 * np.array([1.0, r]), "mean", cov) == pytest.approx(
        v_min, rel=1e-10)
    # with two models ACV-MF is MFMC: its numerical optimum finds the same ratio
    num = allocate(cov, w, budget, estimator="acvmf")
    assert num.ratios[1] == pytest.approx(r, rel=1e-3)


def test_a_nearly_exact_low_fidelity_model_still_gets_two_hf_runs():
    # rho^2 = 1 - 1e-8: the optimum wants a fraction of a high-fidelity run
    cov = np.array([[1.0, 1.0 - 5e-9], [1.0 - 5e-9, 1.0]])
    for estimator in ("mfmc", "acvmf"):
        plan = allocate(cov, [1.0, 1e-3], 20.0, estimator=estimator)
        assert plan.n_samples[0] == 2 and plan.cost <= 20.0
        assert plan.n_samples[1] == int(np.floor((20.0 - 2.0) / 1e-3 + 1e-9))


def test_mfmc_weights_are_peherstorfers():
    _, cov, _ = _exact()
    S = estimator_covariance(sample_sets("mfmc", [40, 400, 4000]), "mean", cov)
    alpha, _ = optimal_weights(S)
    sd = np.sqrt(np.diag(cov))
    rho = cov[0] / (sd[0] * sd)
    # alpha_k = rho_k sigma_1 / sigma_k on (mean over the larger set - over the smaller one)
    np.testing.assert_allclose(alpha, -rho[1:] * sd[0] / sd[1:], rtol=1e-10)


@pytest.mark.parametrize("estimator", ["acvmf", "acvis"])
def test_acv_variance_matches_gorodetsky_closed_form(estimator):
    """Gorodetsky et al. (2020), sec. 4: Var = (C_00 - a^T (F o C)^-1 a) / N with
    a = diag(F) o c, F^IS_ij = (r_i - 1)(r_j - 1) / (r_i r_j), F^MF_ij = (min(r_i, r_j) - 1)
    / min(r_i, r_j) (i != j), F_ii = (r_i - 1) / r_i for both."""
    _, cov, _ = _exact((5, 4, 3, 2))
    N, r = 20, np.array([3.0, 11.0, 40.0])
    lo = np.minimum.outer(r, r)
    F = ((r[:, None] - 1) * (r[None, :] - 1) / np.outer(r, r) if estimator == "acvis"
         else (lo - 1) / lo)
    np.fill_diagonal(F, (r - 1) / r)
    a = np.diag(F) * cov[0, 1:]
    closed = (cov[0, 0] - a @ np.linalg.solve(F * cov[1:, 1:], a)) / N
    ours = estimator_variance(estimator, N * np.concatenate([[1.0], r]), "mean", cov)
    assert ours == pytest.approx(closed, rel=1e-10)


def test_variance_estimator_covariance_is_the_sample_variance_variance():
    _, cov, m22 = _exact((5,))
    n = 30
    S = estimator_covariance(sample_sets("mfmc", [n]), "variance", cov, m22)
    mu4, s4 = m22[0, 0], cov[0, 0] ** 2
    assert S[0, 0] == pytest.approx(mu4 / n - (n - 3) * s4 / (n * (n - 1)), rel=1e-12)


# 300 seeds each, 6.5-9 CPU-s: acvis stays in the fast lane, the other two (and the adapted
# estimators' 200 seeds below) are `slow` (CI's main lane runs them); the closed-form variance
# checks above and the allocation tests stay fast
@pytest.mark.parametrize("estimator", [pytest.param("mfmc", marks=pytest.mark.slow),
                                       pytest.param("acvmf", marks=pytest.mark.slow), "acvis"])
def test_estimators_are_unbiased_with_the_predicted_variance(estimator):
    """300 seeds: the mean of the estimates is within 3.5 standard errors of the exact value
    and their empirical variance matches the exact estimator variance within its own sampling
    error (fourth-moment standard error of a sample variance, 3.5 sigma); the variance at the
    allocation's cost is below plain Monte Carlo's at the same cost."""
    mean, cov, m22 = _exact()
    w, budget = np.array([1.0, 0.05, 0.01]), 400.0
    plan = allocate(cov, w, budget, estimator=estimator, select=False)
    allocation = np.zeros(3, dtype=int)
    allocation[list(plan.models)] = plan.n_samples
    n_rep = 300
    est = {"mean": np.empty(n_rep), "variance": np.empty(n_rep)}
    for i in range(n_rep):
        res = rq.multifidelity_sample(_ladder(), SPACE, None, estimator=estimator, n_pilot=200,
                                      costs=w, allocation=allocation, seed=i)
        est["mean"][i], est["variance"][i] = res.mean[0], res.variance[0]
    sub = np.ix_(plan.models, plan.models)
    for stat, exact in (("mean", mean[0]), ("variance", cov[0, 0])):
        v_theory = estimator_variance(estimator, plan.n_samples, stat, cov[sub], m22[sub])
        e = est[stat]
        assert abs(e.mean() - exact) < 3.5 * np.sqrt(v_theory / n_rep), (stat, e.mean(), exact)
        v_emp = e.var(ddof=1)
        mu4 = np.mean((e - e.mean()) ** 4)
        se_v = np.sqrt((mu4 - v_emp**2 * (n_rep - 3) / (n_rep - 1)) / n_rep)
        assert abs(v_emp - v_theory) < 3.5 * se_v, (stat, v_emp, v_theory, se_v)
        n_plain = plan.cost / w[0]
        v_plain = (cov[0, 0] / n_plain if stat == "mean"
                   else m22[0, 0] / n_plain - (n_plain - 3) * cov[0, 0] ** 2
                   / (n_plain * (n_plain - 1)))
        assert v_emp < 0.5 * v_plain, (stat, v_emp, v_plain)


def test_allocation_from_the_pilot_and_the_result_record():
    mean, cov, _ = _exact()
    w = [1.0, 0.05, 0.01]
    res = rq.multifidelity_sample(_ladder(), SPACE, 400.0, estimator="mfmc", n_pilot=2000,
                                  costs=w, seed=3)
    exact_plan = allocate(cov, np.array(w), 400.0, estimator="mfmc")
    assert res.models_used == exact_plan.models
    np.testing.assert_allclose(res.allocation, exact_plan.n_samples, rtol=0.15)
    assert res.cost_main <= 400.0 and res.cost_pilot == pytest.approx(2000 * sum(w))
    assert res.n_evaluations == 2000 * 3 + int(res.allocation.sum())
    np.testing.assert_allclose(res.correlation[0], cov[0] / np.sqrt(cov[0, 0] * np.diag(cov)),
                               atol=0.02)
    # plain MC needs sigma^2 / se^2 HF runs for the same standard error
    assert res.n_equivalent_hf["mean"][0] == pytest.approx(cov[0, 0] / res.mean_se[0] ** 2,
                                                           rel=0.1)
    assert res.n_equivalent_hf["mean"][0] > 3 * res.budget
    assert abs(res.mean[0] - mean[0]) < 4 * res.mean_se[0]
    assert res.table()[0]["response"] == "y"


def test_budget_in_hf_runs():
    kw = dict(estimator="mfmc", n_pilot=20, costs=[2.0, 0.1, 0.02], seed=4)
    a = rq.multifidelity_sample(_ladder(), SPACE, 50.0, budget_unit="hf_runs", **kw)
    b = rq.multifidelity_sample(_ladder(), SPACE, 100.0, **kw)
    assert a.budget == 100.0 and a.allocation.tolist() == b.allocation.tolist()
    with pytest.raises(ParameterError, match="budget_unit"):
        rq.multifidelity_sample(_ladder(), SPACE, 50.0, budget_unit="seconds", **kw)


def test_measured_costs_and_optimised_acv():
    res = rq.multifidelity_sample(_ladder(), SPACE, 0.05, estimator="acvis", n_pilot=50,
                                  seed=1)
    assert res.costs_measured and np.all(res.costs > 0) and np.all(res.wall_pilot > 0)
    assert res.allocation[0] >= 2 and np.isfinite(res.mean[0]) and np.isfinite(res.std[0])


def test_same_seed_same_result_bitwise():
    kw = dict(estimator="acvmf", n_pilot=30, costs=[1.0, 0.05, 0.01], seed=11)
    a = rq.multifidelity_sample(_ladder(), SPACE, 50.0, **kw)
    b = rq.multifidelity_sample(_ladder(), SPACE, 50.0, **kw)
    assert a.allocation.tolist() == b.allocation.tolist()
    assert a.mean.tobytes() == b.mean.tobytes() and a.variance.tobytes() == b.variance.tobytes()
    c = rq.multifidelity_sample(_ladder(), SPACE, 50.0, **{**kw, "seed": 12})
    assert c.mean.tobytes() != a.mean.tobytes()


def test_bad_input_raises_clear_errors():
    models, w = _ladder(), [1.0, 0.05, 0.01]
    with pytest.raises(ParameterError, match="unknown estimator"):
        rq.multifidelity_sample(models, SPACE, 10.0, estimator="mlmc", costs=w)
    other = rq.FunctionModel(lambda x: x[:, 0], ["x"], ["z"])
    with pytest.raises(ParameterError, match="responses"):
        rq.multifidelity_sample([models[0], other], SPACE, 10.0, costs=[1.0, 0.1])
    with pytest.raises(ParameterError, match="at least 2"):
        rq.multifidelity_sample(models, SPACE, 0.5, costs=w, n_pilot=10, seed=0)
    with pytest.raises(ParameterError, match="non-decreasing"):
        rq.multifidelity_sample(models, SPACE, None, costs=w, allocation=[10, 50, 20], seed=0)
    with pytest.raises(ParameterError, match="either a budget or an allocation"):
        rq.multifidelity_sample(models, SPACE, 10.0, costs=w, allocation=[10, 50, 90])
    with pytest.raises(ParameterError, match="statistics"):
        rq.multifidelity_sample(models, SPACE, 10.0, costs=w, statistics=("median",))
    with pytest.raises(ParameterError, match="costs"):
        rq.multifidelity_sample(models, SPACE, 10.0, costs=[1.0, 0.0, 0.1])


# --- co-kriging ------------------------------------------------------------------------------

def _forrester(x):
    """Forrester, Sobester and Keane (2007): the high-fidelity function on [0, 1]."""
    return (6.0 * x[:, 0] - 2.0) ** 2 * np.sin(12.0 * x[:, 0] - 4.0)


def _forrester_lf(x):
    return 0.5 * _forrester(x) + 10.0 * (x[:, 0] - 0.5) - 5.0


def _currin(x):
    """Currin et al. (1991) exponential function on [0, 1]^2."""
    x1, x2 = x[:, 0], x[:, 1]
    return ((1.0 - np.exp(-0.5 / np.maximum(x2, 1e-12)))
            * (2300 * x1**3 + 1900 * x1**2 + 2092 * x1 + 60)
            / (100 * x1**3 + 500 * x1**2 + 4 * x1 + 20))


def _currin_lf(x):
    """Xiong, Qian and Wu (2013): the average of four shifted copies."""
    def f(a, b):
        return _currin(np.column_stack([a, b]))
    x1, x2 = x[:, 0], x[:, 1]
    lo = np.maximum(0.0, x2 - 0.05)
    return 0.25 * (f(x1 + 0.05, x2 + 0.05) + f(x1 + 0.05, lo) + f(x1 - 0.05, x2 + 0.05)
                   + f(x1 - 0.05, lo))


def test_cokriging_recovers_the_forrester_scale_and_beats_a_gp_on_the_hf_runs():
    x_lf = np.linspace(0.0, 1.0, 11)[:, None]
    x_hf = x_lf[[0, 2, 4, 6, 8, 10]]  # nested in the LF design
    ck = rq.CoKriging(seed=0).fit([x_lf, x_hf], [_forrester_lf(x_lf), _forrester(x_hf)])
    assert ck.rho[0, 0] == pytest.approx(2.0, abs=0.02)  # y_hf = 2 y_lf - 20 (x - 0.5) + 10
    xt = np.linspace(0.0, 1.0, 401)[:, None]
    mean, var = ck.predict(xt)
    gp = rq.GaussianProcess(seed=0).fit(x_hf, _forrester(x_hf))
    rmse_ck = np.sqrt(np.mean((mean[:, 0] - _forrester(xt)) ** 2))
    rmse_gp = np.sqrt(np.mean((gp.predict(xt, return_var=False)[:, 0] - _forrester(xt)) ** 2))
    assert rmse_ck < 0.05 * rmse_gp, (rmse_ck, rmse_gp)
    # interpolates the HF runs, with (near) zero variance there
    m_hf, v_hf = ck.predict(x_hf)
    np.testing.assert_allclose(m_hf[:, 0], _forrester(x_hf), atol=1e-3 * np.ptp(_forrester(xt)))
    assert np.all(var >= 0) and v_hf.max() < 1e-3 * var.max()


def test_cokriging_holdout_error_beats_a_gp_at_equal_hf_runs_in_2d():
    space = rq.ParameterSpace({"a": rq.Uniform(0.0, 1.0), "b": rq.Uniform(0.0, 1.0)})
    x_lf = space.draw(40, seed=1)
    x_hf = x_lf[:10]
    ck = rq.CoKriging(seed=0).fit([x_lf, x_hf], [_currin_lf(x_lf), _currin(x_hf)])
    xt = space.draw(1000, design="random", seed=2)
    gp = rq.GaussianProcess(seed=0).fit(x_hf, _currin(x_hf))
    rmse_ck = np.sqrt(np.mean((ck.predict(xt, return_var=False)[:, 0] - _currin(xt)) ** 2))
    pred_gp = gp.predict(xt, return_var=False, warn_distance=None)[:, 0]
    rmse_gp = np.sqrt(np.mean((pred_gp - _currin(xt)) ** 2))
    assert rmse_ck < 0.5 * rmse_gp, (rmse_ck, rmse_gp)
    model = ck.as_model(["a", "b"], ["y"])
    assert rq.evaluate(model, xt[:5]).values.shape == (5, 1)


def test_cokriging_bad_input():
    ck = rq.CoKriging()
    with pytest.raises(ParameterError, match="not fitted"):
        ck.predict(np.zeros((1, 1)))
    with pytest.raises(ParameterError, match="sequences"):
        ck.fit(np.zeros((5, 1)), np.zeros(5))
    with pytest.raises(ParameterError, match="at least 3"):
        ck.fit([np.zeros((5, 1)), np.zeros((2, 1))], [np.zeros(5), np.zeros(2)])
    with pytest.raises(ParameterError, match="seed"):
        rq.CoKriging({"seed": 1})


# --- the study step type -----------------------------------------------------------------------

def _step_context(options, make_model):
    from rotoruq.steps import STEP_TYPES, StepContext

    st = STEP_TYPES["multifidelity"]
    full = {k: st.default(k) for k in st.options if k not in options}
    full.update(options)
    return st, StepContext(name="mf", type="multifidelity", options=full, space=SPACE,
                           responses=("y",), fixed={}, make_model=make_model,
                           rng=np.random.default_rng(5))


def test_multifidelity_step_runs_the_named_models_and_reports_the_allocation():
    ladder = dict(zip(("model", "x4", "x3", "flat"), _ladder((5, 4, 3, 1)), strict=True))

    def make_model(inputs, responses, fixed, model=None):
        return ladder[model or "model"]

    st, ctx = _step_context({"models": ("x4", "x3"), "budget": 100.0,
                             "costs": (1.0, 0.05, 0.01), "n_pilot": 200}, make_model)
    res = st.run(ctx)
    mean, cov, _ = _exact()
    assert res.meta["models"] == ["model", "x4", "x3"]
    assert abs(res.scalars["mean/y"] - mean[0]) < 4 * res.scalars["mean_se/y"]
    assert res.scalars["runs/model"] == 200 + res.scalars["allocation/model"]
    assert res.scalars["n_equivalent_hf/mean/y"] > 3 * 100.0
    alloc, est = st.tables(res, {})
    assert [row[0] for row in alloc.rows] == ["model", "x4", "x3"]
    assert est.rows[0][0] == "y" and est.rows[0][1] == res.scalars["mean/y"]
    assert st.warnings(res, {}) == []
    # a weak, costly model is left out, and the report says so
    st, ctx = _step_context({"models": ("x4", "flat"), "budget": 100.0,
                             "costs": (1.0, 0.05, 0.9), "n_pilot": 100}, make_model)
    res = st.run(ctx)
    assert res.scalars["used/flat"] == 0.0
    assert any("'flat' was left out" in w for w in st.warnings(res, {}))


def test_multifidelity_step_needs_a_factory_of_named_models():
    st, ctx = _step_context({"models": ("x4",), "budget": 10.0},
                            lambda inputs, responses, fixed: _ladder()[0])
    with pytest.raises(ParameterError, match="builds named models"):
        st.run(ctx)


# --- low-fidelity models adapted on the pilot (adapt="linear") ------------------------------
SPACE2 = rq.ParameterSpace({"a": rq.Uniform(0.0, 1.0), "b": rq.Uniform(0.0, 1.0)})


def _weighted_ladder():
    """HF and an LF that weigh the inputs differently (their error is mostly linear in the
    inputs) plus a nonlinear term they share."""
    hf = rq.FunctionModel(lambda x: x[:, 0] + 0.5 * x[:, 1] + x[:, 0] ** 3, ["a", "b"], ["y"])
    lf = rq.FunctionModel(lambda x: 0.2 * x[:, 0] + 1.5 * x[:, 1] + 0.9 * x[:, 0] ** 3
                          + 0.05 * np.sin(6 * x[:, 1]), ["a", "b"], ["y"])
    return [hf, lf]


def _hf_exact():
    """Mean and variance of a + b / 2 + a^3 over the unit square (Gauss-Legendre, exact)."""
    t, wt = np.polynomial.legendre.leggauss(8)
    t, wt = (t + 1) / 2, wt / 2
    a, b = np.meshgrid(t, t, indexing="ij")
    w2 = np.outer(wt, wt)
    f = a + 0.5 * b + a**3
    mean = float(np.sum(w2 * f))
    return mean, float(np.sum(w2 * (f - mean) ** 2))


def test_linear_adaptation_fits_a_linear_error_exactly_and_reports_loo():
    x = SPACE2.draw(20, seed=1)
    Y = np.stack([x[:, 0] + 0.5 * x[:, 1] + x[:, 0] ** 3,
                  2.0 + 3.0 * (x[:, 0] ** 3) - x[:, 1]], axis=1)[:, :, None]
    ad, loo = rq.LinearAdaptation.fit(x, Y)
    np.testing.assert_allclose(ad.apply(1, x, Y[:, 1]), Y[:, 0], atol=1e-12)
    np.testing.assert_allclose(loo[:, 1], Y[:, 0], atol=1e-10)  # exact: no LOO error
    assert ad.r2_loo[1, 0] == pytest.approx(1.0) and np.all(np.isnan(ad.coef[0]))


def test_adaptation_is_kept_only_where_it_correlates_better_than_the_model_itself():
    """Eight inputs, 13 pilot points: a cheap model whose error is small but not linear in the
    inputs correlates at 0.993 as it is; the 10-coefficient fit leaves it at R^2 0.92 out of
    sample, so it is kept as evaluated (identity map, its own pilot values), while the other
    response, whose error is linear, is adapted exactly."""
    rng = np.random.default_rng(3)
    x = rng.random((13, 8))
    hf = np.sin(2 * np.pi * x[:, 0])
    lf = np.stack([hf + 0.15 * np.cos(5 * x[:, 1] * x[:, 2]), hf - 2 * x[:, 3]], axis=1)
    Y = np.stack([np.stack([hf, hf + x[:, 3]], axis=1), lf], axis=1)
    ad, loo = rq.LinearAdaptation.fit(x, Y)
    assert ad.adapted.tolist() == [[False, False], [False, True]]
    assert ad.r2_loo[1, 0] < np.corrcoef(hf, lf[:, 0])[0, 1] ** 2
    np.testing.assert_array_equal(ad.coef[1, 0], [0.0, 1.0] + [0.0] * 8)
    np.testing.assert_array_equal(loo[:, 1, 0], lf[:, 0])
    np.testing.assert_array_equal(ad.apply(1, x, lf)[:, 0], lf[:, 0])
    np.testing.assert_allclose(loo[:, 1, 1], Y[:, 0, 1], atol=1e-10)
    np.testing.assert_array_equal(loo[:, 0], Y[:, 0])


@pytest.mark.slow  # 200 seeds, ~8.6 CPU-s (see above)
def test_adapted_estimators_are_unbiased_and_their_predicted_se_holds():
    """200 seeds, each with its own pilot (so its own adaptation and allocation): the mean of
    the estimates is within 3.5 standard errors of the exact mean and variance, and the
    empirical variance of the estimates matches the mean predicted se^2 within 35 %; at the
    same cost the adapted estimators' variance is several times smaller than without
    adaptation."""
    mean, var = _hf_exact()
    kw = dict(n_pilot=30, costs=[1.0, 0.01], budget_unit="hf_runs")
    n_rep = 200
    out = {a: {"mean": [], "variance": [], "se_mean": [], "se_var": []}
           for a in ("none", "linear")}
    for i in range(n_rep):
        for a in out:
            r = rq.multifidelity_sample(_weighted_ladder(), SPACE2, 20.0, adapt=a, seed=i, **kw)
            out[a]["mean"].append(r.mean[0])
            out[a]["variance"].append(r.variance[0])
            out[a]["se_mean"].append(r.mean_se[0] ** 2)
            out[a]["se_var"].append(r.variance_se[0] ** 2)
    o = {a: {k: np.array(v) for k, v in d.items()} for a, d in out.items()}
    lin = o["linear"]
    for stat, exact, se2 in (("mean", mean, "se_mean"), ("variance", var, "se_var")):
        e = lin[stat]
        assert abs(e.mean() - exact) < 3.5 * e.std(ddof=1) / np.sqrt(n_rep), (stat, e.mean())
        ratio = e.var(ddof=1) / lin[se2].mean()
        assert 0.65 < ratio < 1.35, (stat, ratio)
        gain = o["none"][stat].var(ddof=1) / e.var(ddof=1)
        assert gain > 3.0, (stat, gain)
    r = rq.multifidelity_sample(_weighted_ladder(), SPACE2, 20.0, adapt="linear", seed=0, **kw)
    assert r.adapt == "linear" and r.correlation[0, 1] > r.correlation_unadapted[0, 1]
    assert r.correlation_unadapted[0, 1] < 0.9 < r.correlation[0, 1]


def test_adaptation_bad_input():
    with pytest.raises(ParameterError, match="adapt must be one of"):
        rq.multifidelity_sample(_weighted_ladder(), SPACE2, 20.0, adapt="quadratic",
                                costs=[1.0, 0.01])
    with pytest.raises(ParameterError, match=r"n_pilot must be >= 7 \(d \+ 5\)"):
        rq.multifidelity_sample(_weighted_ladder(), SPACE2, 20.0, adapt="linear", n_pilot=6,
                                costs=[1.0, 0.01])
