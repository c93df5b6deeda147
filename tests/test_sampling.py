import numpy as np
import pytest
from scipy import stats

import rotoruq as rq
from rotoruq.errors import ModelShapeError, ParameterError
from rotoruq.methods.sampling import refine, response_statistics, sample


def lognormal_params(mean, std):
    zeta2 = np.log1p((std / mean) ** 2)
    return np.log(mean) - 0.5 * zeta2, np.sqrt(zeta2)


def test_lognormal_ratio_matches_exact_distribution():
    # X/Y of independent lognormals is lognormal with lambda = l1 - l2, zeta^2 = z1^2 + z2^2
    space = rq.ParameterSpace({"x": rq.LogNormal(2.0, 0.4), "y": rq.LogNormal(1.0, 0.1)})
    model = rq.FunctionModel(lambda v: v[:, 0] / v[:, 1], ["x", "y"], ["r"])
    l1, z1 = lognormal_params(2.0, 0.4)
    l2, z2 = lognormal_params(1.0, 0.1)
    exact = stats.lognorm(s=np.hypot(z1, z2), scale=np.exp(l1 - l2))
    levels = exact.ppf([0.05, 0.5, 0.95])
    res = sample(
        model,
        space,
        20000,
        design="lhs",
        seed=7,
        response_levels=levels,
        probability_levels=[0.1, 0.9],
    )
    st = res.statistics
    assert st.mean[0] == pytest.approx(exact.mean(), rel=2e-3)
    assert st.std[0] == pytest.approx(exact.std(), rel=1e-2)
    assert st.skewness[0] == pytest.approx(float(exact.stats(moments="s")), rel=0.1)
    assert st.kurtosis[0] == pytest.approx(float(exact.stats(moments="k")), rel=0.25)
    np.testing.assert_allclose(st.cdf_probability["r"], [0.05, 0.5, 0.95], atol=4e-3)
    np.testing.assert_allclose(st.probability_response["r"], exact.ppf([0.1, 0.9]), rtol=5e-3)
    assert st.mean_ci[0, 0] < exact.mean() < st.mean_ci[0, 1]
    # empirical CDF / PDF helpers
    v, F = res.ecdf("r")
    assert np.all(np.diff(v) >= 0) and F[-1] == 1.0
    grid, dens = res.kde_pdf("r", grid=exact.ppf([0.25, 0.5, 0.75]))
    np.testing.assert_allclose(dens, exact.pdf(grid), rtol=0.05)
    edges, h = res.histogram_pdf("r", bins=40)
    assert np.sum(h * np.diff(edges)) == pytest.approx(1.0)


def test_normal_response_has_zero_excess_kurtosis_and_exact_cis():
    space = rq.ParameterSpace({"a": rq.Normal(1.0, 2.0)})
    model = rq.FunctionModel(lambda x: x[:, 0], ["a"], ["y"])
    st = sample(model, space, 50000, design="lhs", seed=3).statistics
    assert abs(st.skewness[0]) < 0.02 and abs(st.kurtosis[0]) < 0.05
    assert st.std_ci[0, 0] < 2.0 < st.std_ci[0, 1]


def test_lhs_beats_mc_variance_of_the_mean():
    space = rq.ParameterSpace({f"x{i}": rq.Uniform(0, 1) for i in range(3)})
    model = rq.FunctionModel(
        lambda x: np.exp(x[:, 0]) + np.sin(3 * x[:, 1]) * x[:, 2], space.names, ["f"]
    )
    means = {
        m: [sample(model, space, 64, design=m, seed=s).mean[0] for s in range(40)]
        for m in ("random", "lhs", "sobol")
    }
    var = {m: np.var(v) for m, v in means.items()}
    assert var["lhs"] < 0.3 * var["random"]
    assert var["sobol"] < 0.3 * var["random"]


def test_same_seed_same_numbers_and_designs():
    space = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Gumbel(2.0, 1.0)})
    model = rq.FunctionModel(lambda x: x[:, 0] ** 2 + x[:, 1], space.names, ["f"])
    for m in ("lhs", "random", "sobol", "halton"):
        r1 = sample(model, space, 33, design=m, seed=11)
        r2 = sample(model, space, 33, design=m, seed=11)
        np.testing.assert_array_equal(r1.outputs, r2.outputs)
        assert r1.inputs.shape == (33, 2)
    assert not np.array_equal(
        r1.outputs, sample(model, space, 33, design="halton", seed=12).outputs
    )


def test_refine_lhs_doubles_into_a_latin_hypercube_and_sobol_continues():
    space = rq.ParameterSpace({"a": rq.Uniform(0, 1), "b": rq.Uniform(0, 1)})
    model = rq.FunctionModel(lambda x: x.sum(axis=1), space.names, ["s"])
    r = refine(sample(model, space, 50, seed=1), 50)
    assert r.n_samples == 100 and r.n_evaluations == 100
    for j in range(2):
        counts = np.histogram(r.inputs[:, j], bins=100, range=(0, 1))[0]
        assert np.all(counts == 1)
    r = refine(sample(model, space, 30, seed=1), 17)  # not a doubling: still every stratum <= 2
    assert r.n_samples == 47
    assert np.histogram(r.inputs[:, 0], bins=47, range=(0, 1))[0].max() <= 2
    for design in ("sobol", "halton", "random"):  # a continued sequence: the larger draw
        s1 = refine(sample(model, space, 64, design=design, seed=5), 64)
        s2 = sample(model, space, 128, design=design, seed=5)
        np.testing.assert_array_equal(s1.inputs, s2.inputs)


def test_correlated_sampling_and_nan_rows_are_dropped_with_a_count():
    space = rq.ParameterSpace(
        {"a": rq.Normal(0, 1), "b": rq.Normal(0, 1)}, correlation=[[1, 0.8], [0.8, 1]]
    )
    model = rq.FunctionModel(
        lambda x: np.column_stack([np.where(x[:, 0] > 1.0, np.nan, x[:, 0]), x[:, 1]]),
        space.names,
        ["f", "g"],
    )
    with pytest.warns(RuntimeWarning, match=r"\d+ of 4000 evaluations failed or returned NaN"):
        res = sample(model, space, 4000, seed=2)
    assert np.corrcoef(res.inputs.T)[0, 1] == pytest.approx(0.8, abs=0.02)
    n_bad = int(np.sum(res.inputs[:, 0] > 1.0))
    assert len(res.failures) == n_bad > 0
    assert res.statistics.n_dropped.tolist() == [n_bad, 0]
    assert res.statistics.n_valid.tolist() == [4000 - n_bad, 4000]
    assert np.isfinite(res.mean).all()
    # truncated at 1: the mean of the kept values is below 0
    assert res.mean[0] == pytest.approx(stats.truncnorm(-np.inf, 1).mean(), abs=0.02)


def test_bad_inputs():
    space = rq.ParameterSpace({"a": rq.Normal(0, 1)})
    with pytest.raises(ModelShapeError):
        sample(rq.FunctionModel(lambda x: np.ones((x.shape[0], 3)), ["a"], ["f"]), space, 10)
    model = rq.FunctionModel(lambda x: x[:, 0], ["a"], ["f"])
    for design in ("grid", "mc"):  # "mc" is spelled "random" (docs/vocabulary.md)
        with pytest.raises(ParameterError, match="unknown design"):
            sample(model, space, 10, design=design)
    with pytest.raises(ParameterError, match=">= 2"):
        sample(model, space, 1)
    with pytest.raises(ParameterError, match="confidence"):
        response_statistics(np.ones((5, 1)), confidence=1.5)


@pytest.mark.parametrize("design", ["lhs", "random", "sobol"])
def test_refine_twice_gives_the_same_points(design):
    space = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Uniform(0, 1)})
    model = rq.FunctionModel(lambda x: x.sum(axis=1), space.names, ["f"])
    gen = np.random.default_rng(4)
    base = sample(model, space, 16, design=design, seed=gen)
    gen.random(100)  # the caller's generator moves on: refine must not depend on it
    r1, r2 = refine(base, 16), refine(base, 16)
    np.testing.assert_array_equal(r1.inputs, r2.inputs)
    again = refine(sample(model, space, 16, design=design, seed=np.random.default_rng(4)), 16)
    np.testing.assert_array_equal(r1.inputs, again.inputs)
    # refining the refined result continues: new points differ from the first extension
    assert not np.array_equal(refine(r1, 16).inputs[32:], r1.inputs[16:])


def test_public_signatures_and_results_follow_the_vocabulary():
    """docs/vocabulary.md for this package's sampling-type methods: n_samples, design=,
    estimator=, keyword-only seed, names_in/names_out, results frozen with eq=False."""
    import dataclasses
    import inspect

    from rotoruq.methods.evidence import EvidenceResult, evidence
    from rotoruq.methods.pce import PCEResult, polynomial_chaos
    from rotoruq.methods.sampling import ResponseStatistics, SamplingResult
    from rotoruq.methods.sensitivity import SobolResult, pick_freeze_design, sobol_indices
    from rotoruq.methods.surrogate import GaussianProcess, LeaveOneOut

    banned = {"n", "method", "n_more", "names", "labels", "n_model_evals", "start"}
    for fn in (sample, refine, sobol_indices, pick_freeze_design, polynomial_chaos, evidence,
               GaussianProcess.__init__):
        params = inspect.signature(fn).parameters
        assert not banned & set(params), (fn.__qualname__, banned & set(params))
        if "seed" in params:
            assert params["seed"].kind is inspect.Parameter.KEYWORD_ONLY, fn.__qualname__
    assert "n_samples" in inspect.signature(sample).parameters
    assert "design" in inspect.signature(sobol_indices).parameters
    assert "estimator" in inspect.signature(polynomial_chaos).parameters
    for cls in (SamplingResult, ResponseStatistics, SobolResult, PCEResult, EvidenceResult,
                LeaveOneOut):
        params = cls.__dataclass_params__
        assert params.frozen and not params.eq, cls.__name__
        fields = {f.name for f in dataclasses.fields(cls)}
        assert not banned & fields, (cls.__name__, banned & fields)


def test_restricted_pairing_sharpens_the_std_of_a_sum_and_survives_refine():
    # sum of 9 standard normals: exact std 3; random pairing errs by ~ sqrt(2 * 36 / n) * 3 / 2
    space = rq.ParameterSpace({f"x{i}": rq.Normal(0, 1) for i in range(9)})
    model = rq.FunctionModel(lambda x: x.sum(axis=1), space.names, ["s"])
    err = {p: [abs(sample(model, space, 500, pairing=p, seed=s).std[0] / 3 - 1)
               for s in range(5)] for p in ("restricted", "random")}
    assert max(err["restricted"]) < 0.005
    assert np.mean(err["random"]) > 3 * np.mean(err["restricted"])
    res = sample(model, space, 200, seed=2)
    assert res.options["pairing"] == "restricted"
    grown = refine(res, 200)  # the new half is paired among itself: still an LHS of 400
    for j in range(9):
        assert np.all(np.histogram(grown.unit[:, j], bins=400, range=(0, 1))[0] == 1)
    off = ~np.eye(9, dtype=bool)
    assert np.abs(stats.spearmanr(grown.inputs).statistic[off]).max() < 0.02
    with pytest.raises(ParameterError, match="unknown pairing"):
        sample(model, space, 10, pairing="iman")
