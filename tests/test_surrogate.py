"""Kriging surrogate: interpolation, leave-one-out, gradients, nugget, warnings, Model use."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.optimize import approx_fprime
from scipy.stats import qmc

from rotoruq.errors import ModelShapeError, ParameterError
from rotoruq.methods.surrogate import ExtrapolationWarning, GaussianProcess, base_jitter
from rotoruq.model import evaluate


def smooth(x: np.ndarray) -> np.ndarray:
    """Two smooth responses on [0, 1]^3, shape (n, 2)."""
    return np.column_stack([
        np.sin(2.0 * x[:, 0]) + x[:, 1] ** 2 + 0.3 * x[:, 2],
        np.exp(-x[:, 0]) * np.cos(1.5 * x[:, 1]) + 0.5 * x[:, 2] ** 2,
    ])


@pytest.fixture(scope="module")
def design():
    x = qmc.LatinHypercube(d=3, seed=1).random(40)
    return x, smooth(x)


@pytest.mark.parametrize("trend", ["constant", "linear", "reduced_quadratic", "quadratic", None])
@pytest.mark.parametrize("kernel", ["sqexp", "matern32", "matern52"])
def test_interpolates_training_points(design, trend, kernel):
    x, y = design
    gp = GaussianProcess(trend=trend, kernel=kernel, n_restarts=0, seed=0).fit(x, y)
    mean, var = gp.predict(x)
    # interpolation up to the (>= 1e-10) jitter on the correlation diagonal
    assert np.max(np.abs(mean - y)) < 1e-4
    assert np.all(var >= 0) and np.max(var) < 1e-5 * y.var(0).max()
    # away from the data the variance is positive
    _, v = gp.predict(np.array([[0.5, 0.5, 0.5], [0.02, 0.97, 0.5]]))
    assert np.all(v > 0)


def test_loo_error_on_smooth_function_below_bound():
    x = qmc.LatinHypercube(d=3, seed=2).random(60)
    y = smooth(x)
    gp = GaussianProcess(trend="reduced_quadratic", kernel="sqexp", seed=0).fit(x, y)
    loo = gp.loo()
    assert loo.errors.shape == (60, 2)
    # stated bound: LOO RMSE below 1 % of the response std on these smooth functions
    assert np.all(loo.nrmse < 1e-2), loo.nrmse
    assert np.all(loo.q2 > 0.999)
    # and the holdout error agrees in magnitude
    xt = np.random.default_rng(3).random((200, 3))
    err = np.sqrt(((gp.predict(xt, return_var=False) - smooth(xt)) ** 2).mean(0))
    assert np.all(err < 3e-2 * y.std(0))


def _matern52(d2):
    s = np.sqrt(5.0 * d2)
    return (1.0 + s + s * s / 3.0) * np.exp(-s)


def _brute_loo(x, y, ell, nugget=1e-10, linear=False):
    """Leave-one-out by refitting (fixed length-scales, Matern 5/2; ordinary Kriging, or
    universal Kriging with a linear trend)."""
    n = len(x)
    F = np.c_[np.ones(n), x] if linear else np.ones((n, 1))
    e = np.empty(n)
    for i in range(n):
        keep = np.arange(n) != i
        xa, ya = x[keep], y[keep]
        d2 = (((xa[:, None, :] - xa[None, :, :]) / ell) ** 2).sum(-1)
        R = _matern52(d2) + nugget * np.eye(n - 1)
        Ri = np.linalg.inv(R)
        fa = F[keep]
        beta = np.linalg.solve(fa.T @ Ri @ fa, fa.T @ Ri @ ya)
        r = _matern52((((xa - x[i]) / ell) ** 2).sum(-1))
        e[i] = y[i] - (F[i] @ beta + r @ Ri @ (ya - fa @ beta))
    return e


@pytest.mark.parametrize("trend", ["constant", "linear"])
def test_loo_closed_form_matches_refitting(trend):
    x = qmc.LatinHypercube(d=2, seed=4).random(25)
    y = np.sin(9 * x[:, 0]) + np.cos(7 * x[:, 1])
    gp = GaussianProcess(trend=trend, kernel="matern52", n_restarts=0, seed=0).fit(x, y)
    ell_unit = gp.length_scales[0] / (x.max(0) - x.min(0))
    xs = (x - x.min(0)) / (x.max(0) - x.min(0))
    brute = _brute_loo(xs, y, ell_unit, linear=trend == "linear")
    np.testing.assert_allclose(gp.loo().errors[:, 0], brute, rtol=1e-4, atol=1e-8)


@pytest.mark.parametrize("kernel", ["sqexp", "matern32", "matern52"])
@pytest.mark.parametrize("trend", ["linear", "quadratic"])
def test_gradient_matches_finite_differences(design, kernel, trend):
    x, y = design
    gp = GaussianProcess(trend=trend, kernel=kernel, n_restarts=0, seed=0).fit(x * 4 - 1, y)
    pts = np.random.default_rng(5).uniform(-0.8, 2.8, (6, 3))
    _, _, g = gp.predict(pts, return_grad=True)
    # central differences; smaller steps drown in the round-off of r @ alpha (|alpha| ~ 1e7
    # with the round-off-level jitter on these smooth functions)
    h = 3e-3
    fd = np.stack([(gp.predict(pts + h * e, return_var=False)
                    - gp.predict(pts - h * e, return_var=False)) / (2 * h) for e in np.eye(3)],
                  axis=-1)
    np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-5 * np.abs(fd).max())


@pytest.mark.parametrize("likelihood", ["ml", "reml"])
@pytest.mark.parametrize("nugget", [None, "estimate", 1e-3])
def test_likelihood_gradient_is_analytic_and_right(design, nugget, likelihood):
    x, y = design
    gp = GaussianProcess(trend="linear", kernel="matern52", nugget=nugget, n_restarts=0,
                         likelihood=likelihood).fit(x, y)
    ys = (y[:, 0] - gp._y_mean[0]) / gp._y_std[0]
    noise = nugget / gp._y_std[0] ** 2 if isinstance(nugget, float) else None
    theta = np.log([0.3, 0.6, 1.2])
    if nugget is not None:
        theta = np.append(theta, np.log(0.01) if nugget == "estimate" else 0.2)
    _, g, _ = gp._solve(ys, theta, noise, True)
    fd = approx_fprime(theta, lambda t: gp._solve(ys, t, noise, False)[0], 1e-7)
    np.testing.assert_allclose(g, fd, rtol=1e-4, atol=1e-4)


def test_estimated_nugget_recovers_noise_variance():
    rng = np.random.default_rng(6)
    x = rng.random((150, 2))
    y = np.sin(3 * x[:, 0]) + np.cos(2 * x[:, 1]) + rng.normal(0, 0.05, 150)
    gp = GaussianProcess(trend="constant", kernel="matern52", nugget="estimate", seed=0).fit(x, y)
    assert 0.5 * 0.05**2 < gp.nugget_variance[0] < 2.0 * 0.05**2
    # a fixed measurement-error variance (eq. 2.39) smooths instead of interpolating
    gp2 = GaussianProcess(trend="constant", kernel="matern52", nugget=0.05**2, seed=0).fit(x, y)
    resid = gp2.predict(x, return_var=False)[:, 0] - y
    assert 0.02 < resid.std() < 0.06
    np.testing.assert_allclose(gp2.nugget_variance, [0.05**2])


def test_simple_kriging_reverts_to_known_mean():
    x = np.linspace(0, 1, 12)[:, None]
    y = np.sin(6 * x[:, 0])
    gp = GaussianProcess(trend=None, mean=0.7, kernel="sqexp", seed=0).fit(x, y)
    np.testing.assert_allclose(gp.predict(x, return_var=False)[:, 0], y, atol=1e-5)
    with pytest.warns(ExtrapolationWarning):
        far = gp.predict(np.array([[40.0]]), return_var=False)
    np.testing.assert_allclose(far, [[0.7]], atol=1e-9)


def test_near_duplicate_points_warn_and_still_fit():
    x = qmc.LatinHypercube(d=2, seed=7).random(20)
    x = np.vstack([x, x[3] + 1e-12])
    y = np.sin(4 * x[:, 0]) + x[:, 1]
    with pytest.warns(RuntimeWarning, match="near-duplicate"):
        gp = GaussianProcess(trend="constant", seed=0).fit(x, y)
    assert np.all(np.isfinite(gp.predict(x)[0]))


def test_extrapolation_warning_states_the_distance(design):
    x, y = design
    gp = GaussianProcess(n_restarts=0, seed=0).fit(x, y)
    lo, hi = x[:, 2].min(), x[:, 2].max()
    expected = (3.0 - hi) / (hi - lo)  # distance beyond the upper face, in box-widths
    with pytest.warns(ExtrapolationWarning, match=f"{expected:.3g} box-widths"):
        gp.predict(np.array([[0.5, 0.5, 3.0]]))
    np.testing.assert_allclose(gp.extrapolation_distance([[0.5, 0.5, 3.0]]), [expected])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gp.predict(np.array([[0.5, 0.5, hi + 0.05 * (hi - lo)]]))  # within tolerance: silent


def test_as_model_follows_the_protocol(design):
    x, y = design
    gp = GaussianProcess(trend="linear", n_restarts=0, seed=0).fit(x, y)
    model = gp.as_model(["a", "b", "c"], ["f", "g"])
    batch = evaluate(model, x[:5])
    np.testing.assert_allclose(batch.values, y[:5], atol=1e-4)
    assert model.gradient(x[:5]).shape == (5, 2, 3)
    with pytest.raises(ModelShapeError):
        gp.as_model(["a", "b"])


def test_bad_input():
    with pytest.raises(ParameterError, match="trend"):
        GaussianProcess(trend="cubic")
    with pytest.raises(ParameterError, match="kernel"):
        GaussianProcess(kernel="rbf")
    with pytest.raises(ParameterError, match="nugget"):
        GaussianProcess(nugget=-1.0)
    with pytest.raises(ParameterError, match="not fitted"):
        GaussianProcess().predict(np.zeros((1, 2)))
    gp = GaussianProcess(n_restarts=0).fit(np.random.default_rng(0).random((10, 2)), np.arange(10.))
    with pytest.raises(ModelShapeError):
        gp.predict(np.zeros((1, 3)))
    with pytest.raises(ModelShapeError):
        GaussianProcess().fit(np.zeros((5, 2)), np.zeros(4))


def _shared_case():
    rng = np.random.default_rng(11)
    x = qmc.LatinHypercube(d=3, seed=rng).random(40) * [2.0, 1.0, 5.0] - [1.0, 0.0, 2.0]
    y = np.sin(2 * x[:, 0]) + x[:, 1] ** 2 - 0.1 * x[:, 2] * x[:, 0]
    xt = rng.random((30, 3)) * [2.0, 1.0, 5.0] - [1.0, 0.0, 2.0]
    return x, y, xt


@pytest.mark.parametrize("kernel", ["sqexp", "matern52"])
def test_fixed_hyperparameters_match_scikit_learn(kernel):
    sk = pytest.importorskip("sklearn.gaussian_process")
    from sklearn.gaussian_process.kernels import RBF, Matern
    from sklearn.gaussian_process.kernels import ConstantKernel as C

    x, y, xt = _shared_case()
    ell = np.array([0.7, 0.5, 2.5])
    var = 1.3
    gp = GaussianProcess(trend=None, kernel=kernel, length_scales=ell, variance=var,
                         optimize=False).fit(x, y)
    np.testing.assert_allclose(gp.length_scales, [ell], rtol=1e-12)
    np.testing.assert_allclose(gp.process_variance, [var], rtol=1e-12)
    assert gp.jitter.shape == (1,) and gp.jitter[0] == pytest.approx(base_jitter(40) * var)
    base = RBF(ell) if kernel == "sqexp" else Matern(ell, nu=2.5)
    ref = sk.GaussianProcessRegressor(C(var) * base, alpha=gp.jitter[0], optimizer=None,
                                      normalize_y=False).fit(x, y)
    mean, var_ours = gp.predict(xt, warn_distance=None)
    m_ref, s_ref = ref.predict(xt, return_std=True)
    np.testing.assert_allclose(mean[:, 0], m_ref, rtol=0, atol=1e-8)
    np.testing.assert_allclose(var_ours[:, 0], s_ref**2, rtol=0, atol=1e-8)


# matern52 here is well conditioned (cond(R) ~ 4e10): the refit is exact. The sqexp fit is near
# singular (cond(R) ~ 1e15): a last-bit change of the length-scales (exp(log(l))) moves sigma^2 by
# ~3e-6 relative with another LAPACK build (the minimum-versions CI job measured it).
@pytest.mark.parametrize("kernel, rtol", [("matern52", 1e-10), ("sqexp", 1e-4)])
def test_fixed_length_scales_with_closed_form_variance_reuse_a_fit(design, kernel, rtol):
    x, y = design
    gp = GaussianProcess(trend="linear", kernel=kernel, n_restarts=1, seed=0).fit(x, y)
    again = GaussianProcess(trend="linear", kernel=kernel, length_scales=gp.length_scales,
                            optimize=False).fit(x, y)
    np.testing.assert_allclose(again.process_variance, gp.process_variance, rtol=rtol)
    xt = np.random.default_rng(1).random((20, x.shape[1])) * 0.8 + 0.1
    np.testing.assert_allclose(again.predict(xt)[0], gp.predict(xt)[0], rtol=rtol, atol=1e-12)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(trend="constant", mean=0.5), "mean= is the known mean of simple Kriging"),
        (dict(optimize=False), "needs length_scales"),
        (dict(variance=1.0), "use it with optimize=False"),
        (dict(length_scales=[0.1, -1.0]), "finite values > 0"),
        (dict(length_scales=[1.0], optimize=False, nugget="estimate"), "needs optimize=True"),
        (dict(length_scales=[1.0], optimize=False, nugget=0.1), "give variance="),
    ],
)
def test_inconsistent_hyperparameter_options_are_rejected(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        GaussianProcess(**kwargs)


def test_length_scale_shape_checked_at_fit(design):
    x, y = design
    with pytest.raises(ParameterError, match="length_scales must have shape"):
        GaussianProcess(length_scales=[1.0, 2.0], optimize=False).fit(x, y)


def _plain_likelihood(gp, ys, theta, noise):
    """The concentrated / fixed-nugget likelihood and gradient of ``GaussianProcess._solve``
    written plainly (fresh temporaries, scipy's wrappers, the symmetric inverse by a loop), as
    before its work arrays: the reference its bits must equal."""
    from scipy import linalg
    from scipy.linalg import lapack

    from rotoruq.methods.surrogate import _corr, _robust_cholesky, _scaled_sqdist

    Xs, F = gp._Xs, gp._F
    n, d = Xs.shape
    inv_ell, eta, s2, dn, conc = gp._unpack(theta, noise)
    R, G = _corr(np.sqrt(_scaled_sqdist(Xs, Xs, inv_ell)), gp.kernel)
    M = s2 * R if s2 != 1.0 else R.copy()
    M[np.diag_indices(n)] += eta + dn
    L, _ = _robust_cholesky(M, base_jitter(n) * s2, ys)
    Lf = linalg.solve_triangular(L, F, lower=True, check_finite=False)
    Ly = linalg.solve_triangular(L, ys, lower=True, check_finite=False)
    beta = np.linalg.lstsq(Lf, Ly, rcond=None)[0]
    rt = Ly - Lf @ beta
    q = float(rt @ rt)
    logdet = 2.0 * np.log(np.diag(L)).sum()
    sig2 = max(q / n, 1e-300) if conc else s2
    ll = -0.5 * n * np.log(sig2) - 0.5 * logdet if conc else -0.5 * q - 0.5 * logdet
    scale = 1.0 / sig2 if conc else 1.0
    alpha = linalg.solve_triangular(L, rt, lower=True, trans=1, check_finite=False)
    Minv = lapack.dpotri(L, lower=1)[0]
    for i in range(1, n):
        Minv[i - 1, i:] = Minv[i:, i - 1]
    Minv = Minv + 0.0
    W = np.multiply.outer(alpha * scale, alpha) - Minv
    g = np.empty_like(theta)
    if not conc:
        g[d] = 0.5 * s2 * float((W * R).sum())
    elif gp.nugget == "estimate":
        g[d] = 0.5 * eta * float(np.trace(W))
    P = W * G
    if s2 != 1.0:
        P = P * s2
    Xe = Xs * inv_ell
    g[:d] = (Xe * Xe * P.sum(1)[:, None]).sum(0) - (Xe * (P @ Xe)).sum(0)
    return ll, g


@pytest.mark.parametrize("kernel", ["sqexp", "matern32", "matern52"])
@pytest.mark.parametrize("nugget", [None, "estimate", 1e-3])
def test_likelihood_work_arrays_keep_the_plain_bits(design, kernel, nugget):
    """The objective's reused work arrays, in-place arithmetic and direct LAPACK calls give
    the plain formulation's likelihood and gradient bit for bit, call after call (the fitted
    hyperparameters follow the optimizer's path, which these bits decide)."""
    from rotoruq.methods.surrogate import _Workspace

    x, y = design
    gp = GaussianProcess(trend="reduced_quadratic", kernel=kernel, nugget=nugget,
                         likelihood="ml", n_restarts=0, seed=0).fit(x, y)
    ys = (y[:, 1] - gp._y_mean[1]) / gp._y_std[1]
    noise = nugget / gp._y_std[1] ** 2 if isinstance(nugget, float) else None
    work = _Workspace(len(ys))
    rng = np.random.default_rng(3)
    for _ in range(4):
        theta = rng.uniform(np.log(0.05), np.log(3.0), 3 + (nugget is not None))
        ll, g, _ = gp._solve(ys, theta, noise, True, work=work)
        ll_ref, g_ref = _plain_likelihood(gp, ys, theta, noise)
        assert ll == ll_ref
        assert g.tobytes() == g_ref.tobytes()
        fresh = gp._solve(ys, theta, noise, True)  # its own work arrays
        assert fresh[0] == ll and fresh[1].tobytes() == g.tobytes()


def test_sqexp_likelihood_gradient_matches_finite_differences(design):
    """The in-place squared-exponential path's gradient (the study's kernel), with work
    arrays reused between the calls, against central differences of the likelihood."""
    from rotoruq.methods.surrogate import _Workspace

    x, y = design
    gp = GaussianProcess(trend="reduced_quadratic", kernel="sqexp", n_restarts=0,
                         seed=0).fit(x, y)
    ys = (y[:, 0] - gp._y_mean[0]) / gp._y_std[0]
    work = _Workspace(len(ys))
    theta = np.log([0.4, 0.7, 1.5])
    _, g, _ = gp._solve(ys, theta, None, True, work=work)
    h = 1e-6
    fd = [(gp._solve(ys, theta + h * e, None, False, work=work)[0]
           - gp._solve(ys, theta - h * e, None, False, work=work)[0]) / (2 * h)
          for e in np.eye(3)]
    np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-5)


def test_scaled_distances_and_triangular_solves_keep_the_bits():
    """The in-place distances equal ``sqrt(_scaled_sqdist)`` and the direct ``dtrtrs`` call
    equals ``solve_triangular`` (also for an empty right-hand side) bit for bit; a zero
    pivot raises ``LinAlgError`` (which the objective turns into a rejected step)."""
    from scipy import linalg
    from scipy.linalg import lapack

    from rotoruq.methods.surrogate import _scaled_dist, _scaled_sqdist, _trtrs

    rng = np.random.default_rng(0)
    x = rng.random((37, 4))
    inv_ell = 1.0 / rng.uniform(0.1, 2.0, 4)
    n = len(x)
    h = _scaled_dist(x * inv_ell, np.empty((n, n)), np.empty((n, n)))
    assert h.tobytes() == np.sqrt(_scaled_sqdist(x, x, inv_ell)).tobytes()
    L = lapack.dpotrf(np.exp(-0.5 * h * h) + 1e-3 * np.eye(n), lower=1, clean=1)[0]
    for b in (rng.normal(size=n), rng.normal(size=(n, 3)), np.empty((n, 0))):
        for trans in (0, 1):
            ref = linalg.solve_triangular(L, b, lower=True, trans=trans, check_finite=False)
            got = _trtrs(L, b, lower=1, trans=trans)
            assert got.shape == ref.shape and got.tobytes() == ref.tobytes()
    singular = L.copy(order="F")
    singular[5, 5] = 0.0
    with pytest.raises(np.linalg.LinAlgError, match="info=6"):
        _trtrs(singular, np.ones(n), lower=1)
