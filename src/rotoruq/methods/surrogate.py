"""Gaussian-process (Kriging) surrogates, thesis section 2.5.

``f(x) ~ g(x)^T beta + eps(x)`` with ``Cov(eps(x), eps(x')) = sigma^2 r(x, x') + Delta^2 delta``
(eqs. 2.37-2.39). Simple Kriging (known constant trend), ordinary Kriging (constant trend) and
universal Kriging (linear, reduced quadratic = main effects only, full quadratic) with
anisotropic squared-exponential or Matern 3/2, 5/2 correlations.

Inputs are scaled to the unit box of the training points and each response is standardized.
Hyperparameters (log length-scales, and the nugget when estimated) maximize the likelihood
concentrated over ``beta`` (generalized least squares) and ``sigma^2``; the gradient is analytic
and the optimizer is L-BFGS-B from several starts. One GP is fitted per response.

Examples
--------
A smooth function of 2 inputs learned from 30 Latin hypercube points; inputs are (n, d),
responses (n, m), in their own units:

>>> import numpy as np
>>> from scipy.stats import qmc
>>> X = qmc.LatinHypercube(d=2, seed=0).random(30)                # (30, 2)
>>> Y = (np.sin(3 * X[:, 0]) + X[:, 1] ** 2)[:, None]              # (30, 1)
>>> gp = GaussianProcess(trend="reduced_quadratic", kernel="sqexp", seed=0).fit(X, Y)
>>> Xnew = np.array([[0.25, 0.5], [0.75, 0.1]])
>>> mean, var = gp.predict(Xnew)                                  # (n, m), (n, m)
>>> mean.shape, var.shape
((2, 1), (2, 1))
>>> bool(np.max(np.abs(mean[:, 0] - (np.sin(3 * Xnew[:, 0]) + Xnew[:, 1] ** 2))) < 1e-2)
True
>>> mean, var, grad = gp.predict(Xnew, return_grad=True)          # grad (n, m, d)
>>> grad.shape
(2, 1, 2)
>>> gp.loo().rmse.shape                                           # leave-one-out, per response
(1,)
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import linalg, optimize
from scipy.linalg import lapack
from scipy.spatial import cKDTree

from .._progress import Phase
from .._rng import SeedLike, as_generator
from ..errors import ModelShapeError, ParameterError
from ._common import one_blas_thread
from ._gp_mean import CompiledGP, compile_gp, gp_mean_batch, gp_mean_var_batch

__all__ = ["GaussianProcess", "LeaveOneOut", "GPModel", "ExtrapolationWarning", "CompiledGP"]

TRENDS = ("constant", "linear", "reduced_quadratic", "quadratic", None)
KERNELS = ("sqexp", "matern32", "matern52")
_LOG_ELL_BOUNDS = (np.log(1e-3), np.log(1e2))
_LOG_ETA_BOUNDS = (np.log(1e-10), np.log(1.0))
_EPS = float(np.finfo(float).eps)


def base_jitter(n: int) -> float:
    """First jitter tried on an n x n correlation matrix, relative to its unit diagonal: n eps,
    the size of the Cholesky factorization's own backward error (Higham, Accuracy and
    Stability, thm. 10.3), so a smaller one would be lost in round-off. A larger one smooths
    the interpolant: its holdout error grows like the jitter's square root (1e-10, the
    former value, gave 3x scikit-learn's holdout error on the 4-D case of
    ``benchmarks/gp_fit.py``)."""
    return n * _EPS

_MAX_JITTER = 1e-4
# Largest relative residual of the training-system solve accepted before the jitter is
# raised. Chosen among 1e-4 ... 1e-8 on the interpolation test design and benchmarks/gp_fit.py:
# 1e-4 let a numerically singular optimum through (training-point error 0.03), 1e-6 and
# tighter raised the jitter mid-optimization often enough to cost 6 % holdout error in 9-D.
_SOLVE_TOL = 1e-5
_SCREEN_POINTS = 150


class ExtrapolationWarning(UserWarning):
    """A GP was asked to predict far outside the box of its training points."""


# --- correlation functions -------------------------------------------------------------------
def _corr(h: np.ndarray, kernel: str) -> tuple[np.ndarray, np.ndarray]:
    """Correlation R(h) and G(h) with dR/dlog(ell_k) = G * r_k^2 and dR/dx_k = -G * dx_k/ell_k^2.

    ``h`` is the scaled distance sqrt(sum_k (dx_k / ell_k)^2).
    """
    if kernel == "sqexp":
        r = np.exp(-0.5 * h * h)
        return r, r
    if kernel == "matern32":
        s = np.sqrt(3.0) * h
        e = np.exp(-s)
        return (1.0 + s) * e, 3.0 * e
    s = np.sqrt(5.0) * h
    e = np.exp(-s)
    return (1.0 + s + s * s / 3.0) * e, (5.0 / 3.0) * (1.0 + s) * e


def _scaled_sqdist(a: np.ndarray, b: np.ndarray, inv_ell: np.ndarray) -> np.ndarray:
    a = a * inv_ell
    b = b * inv_ell
    d2 = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T
    return np.maximum(d2, 0.0)


def _scaled_dist(xe: np.ndarray, out: np.ndarray, tmp: np.ndarray) -> np.ndarray:
    """``sqrt(_scaled_sqdist(x, x, inv_ell))`` of the scaled points ``xe = x * inv_ell``
    (n, d), written into ``out`` (n, n) with ``tmp`` (n, n) as scratch: the same operations
    in the same order, the same bits, without the four n x n temporaries."""
    s = (xe * xe).sum(1)
    ab = np.matmul(2.0 * xe, xe.T, out=tmp)
    d2 = np.add.outer(s, s, out=out)
    d2 -= ab
    np.maximum(d2, 0.0, out=d2)
    return np.sqrt(d2, out=d2)


class _Workspace:
    """The n x n arrays one likelihood objective writes into at every call (allocating
    them afresh cost as much as the arithmetic on them at n = 500)."""

    def __init__(self, n: int) -> None:
        self.a = np.empty((n, n))
        self.b = np.empty((n, n))
        self.c = np.empty((n, n))


def _trtrs(L: np.ndarray, b: np.ndarray, lower: int, trans: int = 0) -> np.ndarray:
    """``linalg.solve_triangular(L, b, check_finite=False)`` for a Fortran-ordered ``L``
    (a ``dpotrf`` factor): the same LAPACK call without its wrappers' checks, which cost
    more than the solve at n = 150; a zero on the diagonal raises ``LinAlgError`` as there."""
    if b.size == 0:
        return np.empty_like(b)
    x, info = lapack.dtrtrs(L, b, lower=lower, trans=trans)
    if info != 0:
        raise np.linalg.LinAlgError(f"triangular solve failed (info={info})")
    return x


# --- trend bases -----------------------------------------------------------------------------
def _basis(z: np.ndarray, trend: str | None) -> np.ndarray:
    n, d = z.shape
    if trend is None:
        return np.zeros((n, 0))
    cols = [np.ones((n, 1))]
    if trend in ("linear", "reduced_quadratic", "quadratic"):
        cols.append(z)
    if trend == "reduced_quadratic":
        cols.append(z * z)
    if trend == "quadratic":
        i, j = np.triu_indices(d)
        cols.append(z[:, i] * z[:, j])
    return np.hstack(cols)


def _basis_grad(z: np.ndarray, trend: str | None) -> np.ndarray:
    """Derivative of the basis w.r.t. z, shape (n, p, d)."""
    n, d = z.shape
    p = _basis(z[:1], trend).shape[1]
    g = np.zeros((n, p, d))
    if trend in (None, "constant"):
        return g
    eye = np.arange(d)
    g[:, 1 + eye, eye] = 1.0
    if trend == "reduced_quadratic":
        g[:, 1 + d + eye, eye] = 2.0 * z
    if trend == "quadratic":
        i, j = np.triu_indices(d)
        for c, (a, b) in enumerate(zip(i, j, strict=True)):
            g[:, 1 + d + c, a] += z[:, b]
            g[:, 1 + d + c, b] += z[:, a]
    return g


def _robust_cholesky(a: np.ndarray, jitter: float,
                     rhs: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """Lower Cholesky factor of ``a + jitter I``, raising the jitter x100 until the factor
    exists and, when ``rhs`` (n,) is given, solves ``(a + jitter I) z = rhs`` to a relative
    residual below :data:`_SOLVE_TOL`: with the jitter at round-off level a factor can exist
    and still be too ill-conditioned to interpolate with (its likelihood is then round-off,
    which an optimizer would climb). ``a`` is modified in place (its diagonal)."""
    diag = np.diag_indices(a.shape[0])
    added = 0.0
    while True:
        a[diag] += jitter - added
        added = jitter
        c, info = lapack.dpotrf(a, lower=1, clean=1, overwrite_a=0)
        if info == 0:
            if rhs is None:
                return c, jitter
            z, _ = lapack.dpotrs(c, rhs, lower=1)  # cho_solve's call, without its checks
            if np.linalg.norm(a @ z - rhs) <= _SOLVE_TOL * np.linalg.norm(rhs):
                return c, jitter
        if jitter >= _MAX_JITTER:
            raise np.linalg.LinAlgError(
                f"correlation matrix not positive definite even with jitter {jitter:.1e}"
            )
        jitter *= 100.0


@dataclass(frozen=True, eq=False)
class LeaveOneOut:
    """Closed-form leave-one-out cross-validation (Dubrule 1983).

    Attributes
    ----------
    errors : ndarray of shape (n, m)
        ``y_i - yhat_{-i}(x_i)`` at the n training points, in response units.
    rmse : ndarray of shape (m,)
        Root mean square leave-one-out error, response units.
    nrmse : ndarray of shape (m,)
        ``rmse`` divided by the std of the training responses.
    q2 : ndarray of shape (m,)
        ``1 - sum(e^2) / sum((y - mean y)^2)`` (1 = perfect).
    """

    errors: np.ndarray
    rmse: np.ndarray
    nrmse: np.ndarray
    q2: np.ndarray


@dataclass
class _Fit:
    """Hyperparameters and solved systems of one response (standardized units)."""

    inv_ell: np.ndarray  # (d,)
    eta: float  # nugget ratio added to R (concentrated) or 0
    sigma2: float  # process variance (standardized units)
    noise: float  # Delta^2 in standardized units when the nugget is fixed, else 0
    concentrated: bool
    chol: np.ndarray  # lower factor of M
    beta: np.ndarray  # (p,)
    alpha: np.ndarray  # M^-1 (y - F beta)  (n,)
    ft_minv_f_chol: np.ndarray | None  # Cholesky of F^T M^-1 F
    minv_f: np.ndarray  # M^-1 F  (n, p)
    jitter: float
    loglik: float


class GaussianProcess:
    """Kriging surrogate with maximum-likelihood hyperparameters.

    The jitter actually added to the covariance diagonal (response units squared, per
    response) is :attr:`jitter`.

    Parameters
    ----------
    trend : "constant" (ordinary Kriging), "linear", "reduced_quadratic" (main effects, no
        cross terms), "quadratic", or None (simple Kriging with known mean ``mean``).
    kernel : "sqexp", "matern32" or "matern52" (anisotropic, one length-scale per input).
    nugget : None (interpolation, with the smallest jitter that keeps the Cholesky stable),
        a float or (m,) array = measurement-error variance Delta^2 in response units
        (thesis eq. 2.39), or "estimate" (noise-to-signal ratio fitted by maximum likelihood).
    n_restarts : number of random starts of L-BFGS-B in addition to the default start.
    mean : known mean of the responses for simple Kriging (scalar or (m,), response units);
        only with ``trend=None`` (default 0), a :class:`ParameterError` otherwise (with a
        trend the mean is estimated).
    length_scales : (d,) or (m, d) length-scales in input units. With ``optimize=False``
        they are used as given; with ``optimize=True`` they replace the default first start.
    variance : process variance sigma^2 (scalar or (m,), response units squared); only with
        ``optimize=False``. None: its closed-form maximum-likelihood value given the
        length-scales (needs an interpolating GP, ``nugget=None``).
    optimize : False to build the GP from the given hyperparameters without any likelihood
        optimization (to reuse a fit or compare with another library); needs
        ``length_scales`` and a nugget that is None or a fixed variance.
    likelihood : "ml" (maximum likelihood), "reml" (restricted maximum likelihood: the p
        trend coefficients' degrees of freedom are taken out, sigma^2 = q / (n - p)), or
        "auto" (default): REML for the full quadratic trend, ML otherwise. With
        p = (d + 1)(d + 2) / 2 trend terms (55 in 9-D) ML under-estimates sigma^2 and its
        optimum degenerates to tiny length-scales (holdout nRMSE 0.037 against 0.0007 with
        REML on the 9-D borehole case of ``benchmarks/gp_fit.py``).
    screen_points : with more than twice this many training points (and at least 8 per trend
        coefficient), the starts are screened on a random subset of that size and only the
        best is polished on all points; None runs every start on all points.
    seed : int, SeedSequence or Generator for the random starts (and the screening subset).
        None draws fresh entropy from the operating system at every :meth:`fit`: two fits
        then differ; :func:`~rotoruq.methods.mcmc.calibrate_bayes` gives an unseeded
        emulator a seed spawned from its own.
    """

    def __init__(
        self,
        trend: str | None = "constant",
        kernel: str = "sqexp",
        nugget: None | float | str | Sequence[float] = None,
        n_restarts: int = 2,
        mean: float | Sequence[float] | None = None,
        *,
        length_scales: Sequence[float] | np.ndarray | None = None,
        variance: float | Sequence[float] | None = None,
        optimize: bool = True,
        likelihood: str = "auto",
        screen_points: int | None = _SCREEN_POINTS,
        seed: SeedLike = None,
    ) -> None:
        if trend not in TRENDS:
            raise ParameterError(f"unknown trend {trend!r}; valid: {TRENDS}")
        if kernel not in KERNELS:
            raise ParameterError(f"unknown kernel {kernel!r}; valid: {KERNELS}")
        if isinstance(nugget, str) and nugget != "estimate":
            raise ParameterError(f"nugget must be None, a variance or 'estimate', got {nugget!r}")
        if nugget is not None and not isinstance(nugget, str):
            arr = np.asarray(nugget, dtype=float)
            if np.any(~np.isfinite(arr)) or np.any(arr < 0):
                raise ParameterError(f"nugget variance must be finite and >= 0, got {nugget!r}")
        if int(n_restarts) < 0:
            raise ParameterError(f"n_restarts must be >= 0, got {n_restarts}")
        if mean is not None and trend is not None:
            raise ParameterError(
                f"mean= is the known mean of simple Kriging (trend=None); with trend={trend!r} "
                "the mean is estimated from the data: drop mean= or set trend=None"
            )
        if mean is not None and not np.all(np.isfinite(np.asarray(mean, dtype=float))):
            raise ParameterError(f"mean must be finite, got {mean!r}")
        if length_scales is not None:
            ls = np.asarray(length_scales, dtype=float)
            if ls.ndim not in (1, 2) or np.any(~np.isfinite(ls)) or np.any(ls <= 0):
                raise ParameterError(
                    f"length_scales must be a (d,) or (m, d) array of finite values > 0, got "
                    f"{length_scales!r}"
                )
        if variance is not None:
            if optimize:
                raise ParameterError("variance= fixes the process variance: use it with "
                                     "optimize=False (with optimization it is estimated)")
            v = np.asarray(variance, dtype=float)
            if np.any(~np.isfinite(v)) or np.any(v <= 0):
                raise ParameterError(f"variance must be finite and > 0, got {variance!r}")
        if not optimize:
            if length_scales is None:
                raise ParameterError("optimize=False needs length_scales= (and optionally "
                                     "variance=): there is nothing to fit them with")
            if nugget == "estimate":
                raise ParameterError("nugget='estimate' needs optimize=True; with fixed "
                                     "hyperparameters give the nugget as a variance")
            if nugget is not None and variance is None:
                raise ParameterError("with a fixed nugget variance and optimize=False, give "
                                     "variance= too (it is no longer in closed form)")
        self.trend = trend
        self.kernel = kernel
        self.nugget = nugget
        self.n_restarts = int(n_restarts)
        self.mean = 0.0 if mean is None else mean
        self.seed = seed
        self.length_scales_init = None if length_scales is None else np.asarray(
            length_scales, dtype=float)
        self.variance_init = None if variance is None else np.asarray(variance, dtype=float)
        self.optimize = bool(optimize)
        if likelihood not in ("auto", "ml", "reml"):
            raise ParameterError(
                f"likelihood must be 'auto', 'ml' or 'reml', got {likelihood!r}")
        if likelihood == "auto":
            likelihood = "reml" if trend == "quadratic" else "ml"
        self.likelihood = likelihood
        if screen_points is not None and int(screen_points) < 2:
            raise ParameterError(f"screen_points must be None or >= 2, got {screen_points!r}")
        self.screen_points = None if screen_points is None else int(screen_points)
        self._fits: list[_Fit] = []

    # --- fitting ---------------------------------------------------------------------------
    def fit(self, X, Y) -> GaussianProcess:
        """Fit one GP per response column.

        Rows with non-finite values are dropped with a warning.

        The fit runs on one BLAS thread (:func:`~rotoruq.methods._common.one_blas_thread`):
        LAPACK's factorizations on more threads give other last bits (issue 35), and on a busy
        machine a second thread made fits 5-14x slower (issue 12). Results do not depend on
        the thread count.

        Parameters
        ----------
        X : array_like of shape (n, d)
            Training inputs, in input units.
        Y : array_like of shape (n,) or (n, m)
            Training responses, in response units.

        Returns
        -------
        GaussianProcess
            This GP, fitted.
        """
        with one_blas_thread():
            return self._fit(X, Y)

    def _fit(self, X, Y) -> GaussianProcess:
        X = np.asarray(X, dtype=float)
        Y = np.asarray(Y, dtype=float)
        if X.ndim == 1:
            X = X[:, None]
        if Y.ndim == 1:
            Y = Y[:, None]
        if X.ndim != 2 or Y.ndim != 2 or X.shape[0] != Y.shape[0]:
            raise ModelShapeError(f"X must be (n, d) and Y (n, m) with the same n; got "
                                  f"{X.shape} and {Y.shape}")
        ok = np.all(np.isfinite(X), 1) & np.all(np.isfinite(Y), 1)
        if not np.all(ok):
            warnings.warn(f"GaussianProcess.fit: dropping {int((~ok).sum())} rows with non-finite "
                          "inputs or responses", RuntimeWarning, stacklevel=3)
            X, Y = X[ok], Y[ok]
        n, d = X.shape
        m = Y.shape[1]
        p = _basis(np.zeros((1, d)), self.trend).shape[1]
        if n < max(2, p + 1):
            raise ParameterError(f"GaussianProcess needs at least {max(2, p + 1)} points for "
                                 f"trend {self.trend!r} in {d}-D, got {n}")
        self._lo = X.min(0)
        span = X.max(0) - self._lo
        self._span = np.where(span > 0, span, 1.0)
        self._X = X
        self._Y = Y
        self._Xs = (X - self._lo) / self._span
        self._y_mean = Y.mean(0) if self.trend is not None else np.zeros(m)
        ystd = Y.std(0)
        self._y_std = np.where(ystd > 0, ystd, 1.0)
        self._F = _basis(self._Xs - 0.5, self.trend)
        self._warn_duplicates()
        rng = as_generator(self.seed)
        if self.trend is None:
            mu = np.broadcast_to(np.asarray(self.mean, dtype=float), (m,))
            self._y_mean = mu.copy()
        noise = None
        if self.nugget is not None and not isinstance(self.nugget, str):
            noise = np.broadcast_to(np.asarray(self.nugget, dtype=float), (m,)) / self._y_std**2
        log_ell0 = None
        if self.length_scales_init is not None:
            ls = self.length_scales_init
            if ls.shape not in ((d,), (m, d)):
                raise ParameterError(f"length_scales must have shape ({d},) or ({m}, {d}) for "
                                     f"{d} inputs and {m} responses, got {ls.shape}")
            log_ell0 = np.log(np.broadcast_to(ls, (m, d)) / self._span)
        s2_fixed = None
        if self.variance_init is not None:
            v = self.variance_init
            if v.shape not in ((), (1,), (m,)):
                raise ParameterError(f"variance must be a scalar or ({m},), got {v.shape}")
            s2_fixed = np.broadcast_to(v.reshape(-1) if v.ndim else v, (m,)) / self._y_std**2
            if noise is None:
                noise = np.zeros(m)  # a fixed sigma^2: the non-concentrated likelihood path
        self._fits = []
        phase = Phase(f"emulator fit ({n} points)", m) if self.optimize else None
        for j in range(m):
            ys = (Y[:, j] - self._y_mean[j]) / self._y_std[j]
            nj = None if noise is None else float(noise[j])
            if not self.optimize:
                assert log_ell0 is not None  # checked in __init__
                theta = log_ell0[j]
                if nj is not None:
                    assert s2_fixed is not None  # a fixed nugget needs variance= (__init__)
                    theta = np.append(theta, np.log(s2_fixed[j]))
                self._fits.append(self._fit_at(ys, theta, nj))
            else:
                self._fits.append(self._fit_one(ys, nj, rng,
                                                None if log_ell0 is None else log_ell0[j]))
                assert phase is not None  # self.optimize
                phase.advance()
        if phase is not None:
            phase.close()
        self._build_fast()
        worst = max(f.jitter if f.concentrated else f.jitter / f.sigma2 for f in self._fits)
        if worst > base_jitter(n) * 1.01 and self.nugget is None:
            warnings.warn(f"GaussianProcess: correlation matrix was ill-conditioned; a jitter of "
                          f"{worst:.1e} was added to its diagonal", RuntimeWarning, stacklevel=3)
        return self

    def _warn_duplicates(self) -> None:
        pairs = cKDTree(self._Xs).query_pairs(r=1e-6 * np.sqrt(self._Xs.shape[1]),
                                              output_type="ndarray")
        if len(pairs):
            i, j = pairs[0]
            warnings.warn(f"GaussianProcess: {len(pairs)} pair(s) of near-duplicate training "
                          f"points (e.g. rows {i} and {j}); the Cholesky factorization will "
                          "add jitter, consider nugget='estimate'", RuntimeWarning, stacklevel=4)

    def _unpack(self, theta: np.ndarray, noise: float | None):
        d = self._Xs.shape[1]
        inv_ell = np.exp(-theta[:d])
        if noise is not None:  # fixed Delta^2: sigma^2 is a free parameter, not concentrated
            return inv_ell, 0.0, float(np.exp(theta[d])), noise, False
        eta = float(np.exp(theta[d])) if self.nugget == "estimate" else 0.0
        return inv_ell, eta, 1.0, 0.0, True

    def _solve(self, ys: np.ndarray, theta: np.ndarray, noise: float | None, want_grad: bool,
               Xs: np.ndarray | None = None, F: np.ndarray | None = None,
               work: _Workspace | None = None):
        """Log-likelihood (concentrated when possible), its gradient and the solved systems.

        ``work`` holds the n x n arrays of an optimizer's calls (one per objective); every
        step writes into them in the order of the arithmetic it replaces, so the bits do not
        depend on it."""
        if Xs is None or F is None:
            Xs, F = self._Xs, self._F
        n, d = Xs.shape
        if work is None:
            work = _Workspace(n)
        inv_ell, eta, s2, dn, conc = self._unpack(theta, noise)
        Xe = Xs * inv_ell
        h = _scaled_dist(Xe, work.b, work.c)
        if self.kernel == "sqexp":  # exp(-0.5 h h) in place: h's buffer is free after
            R = np.multiply(h, -0.5, out=work.a)
            R *= h
            G = R = np.exp(R, out=R)
        else:
            R, G = _corr(h, self.kernel)
        M = work.b
        if s2 != 1.0:
            np.multiply(R, s2, out=M)
        else:
            np.copyto(M, R)
        M.flat[::n + 1] += eta + dn
        L, jitter = _robust_cholesky(M, base_jitter(n) * s2, ys)
        Lf = _trtrs(L, F, lower=1)
        Ly = _trtrs(L, ys, lower=1)
        if F.shape[1]:
            beta, *_ = np.linalg.lstsq(Lf, Ly, rcond=None)
            rt = Ly - Lf @ beta
        else:
            beta = np.zeros(0)
            rt = Ly
        q = float(rt @ rt)
        logdet = 2.0 * np.log(np.diag(L)).sum()
        p = F.shape[1]
        reml = self.likelihood == "reml" and p > 0
        if conc and reml:
            # restricted likelihood: the trend's p degrees of freedom are not counted as
            # information about sigma^2 and the length-scales (Harville 1974)
            c_f = np.linalg.cholesky(Lf.T @ Lf + 1e-12 * np.eye(p))
            sig2 = max(q / (n - p), 1e-300)
            ll = -0.5 * (n - p) * np.log(sig2) - 0.5 * logdet - np.log(np.diag(c_f)).sum()
            scale = 1.0 / sig2
        elif conc:
            sig2 = max(q / n, 1e-300)
            ll = -0.5 * n * np.log(sig2) - 0.5 * logdet
            scale = 1.0 / sig2
        else:
            sig2 = s2
            ll = -0.5 * q - 0.5 * logdet
            scale = 1.0
        alpha = _trtrs(L, rt, lower=1, trans=1)
        out = dict(L=L, beta=beta, alpha=alpha, sig2=sig2, jitter=jitter, Lf=Lf, ll=ll,
                   inv_ell=inv_ell, eta=eta, s2=s2, dn=dn, conc=conc)
        if not want_grad:
            return ll, None, out
        qf = None
        if conc and reml:
            qf = linalg.solve_triangular(
                c_f, _trtrs(L, Lf, lower=1, trans=1).T, lower=True, check_finite=False)
        # L is not returned from here on: its memory takes M^-1 (lower triangle; the upper
        # stays L's zeros, clean=1)
        Minv, info = lapack.dpotri(L, lower=1, overwrite_c=1)
        # the upper triangle from the lower as Minv + tril(Minv, -1).T: off the diagonal a
        # value plus L's +0.0 (-0 -> +0), the diagonal its value + 0.0
        S = np.add(Minv, Minv.T, out=work.b)
        S.flat[::n + 1] = Minv.diagonal() + 0.0
        if qf is not None:  # M^-1 -> the projection M^-1 - M^-1 F (F^T M^-1 F)^-1 F^T M^-1
            S -= qf.T @ qf
        # W = scale * alpha alpha^T - M^-1, formed in place
        W = np.multiply.outer(alpha * scale, alpha, out=work.c)
        W -= S
        g = np.empty_like(theta)
        if not conc:
            g[d] = 0.5 * s2 * float((W * R).sum())
        elif self.nugget == "estimate":
            g[d] = 0.5 * eta * float(np.trace(W))
        P = np.multiply(W, G, out=W)  # W is not read after: P takes its memory
        if s2 != 1.0:
            P *= s2
        rows = P.sum(1)
        g[:d] = (Xe * Xe * rows[:, None]).sum(0) - (Xe * (P @ Xe)).sum(0)
        return ll, g, out

    def _fit_one(self, ys: np.ndarray, noise: float | None, rng, log_ell0=None) -> _Fit:
        n, d = self._Xs.shape
        extra = noise is not None or self.nugget == "estimate"
        bounds = [_LOG_ELL_BOUNDS] * d
        if noise is not None:
            bounds.append((np.log(1e-6), np.log(1e3)))
        elif self.nugget == "estimate":
            bounds.append(_LOG_ETA_BOUNDS)
        lb, ub = np.array([b[0] for b in bounds]), np.array([b[1] for b in bounds])
        starts = [np.full(d, np.log(0.5)) if log_ell0 is None else np.asarray(log_ell0)]
        lo_s, hi_s = np.log(0.05), np.log(3.0)
        for _ in range(self.n_restarts):
            starts.append(lo_s + (hi_s - lo_s) * rng.random(d))
        if extra:
            x0 = 0.0 if noise is not None else np.log(1e-4)
            starts = [np.append(s, x0 + (0.0 if k == 0 else rng.normal(0.0, 1.0)))
                      for k, s in enumerate(starts)]

        def make_objective(Xs, F, yv):
            work = _Workspace(Xs.shape[0])

            def objective(theta):
                try:
                    ll, g, _ = self._solve(yv, theta, noise, True, Xs, F, work)
                except np.linalg.LinAlgError:
                    return 1e30, np.zeros_like(theta)
                return -ll, -g
            return objective

        def run(obj, s, maxfun):
            # the likelihood is numerically rough where R is near singular (long sqexp
            # length-scales): cap the evaluations instead of letting line searches thrash
            return optimize.minimize(obj, np.clip(s, lb, ub), jac=True, method="L-BFGS-B",
                                     bounds=bounds, options={"maxfun": maxfun, "ftol": 1e-8})

        p = self._F.shape[1]
        screen = None if self.screen_points is None else max(self.screen_points, 8 * p)
        if len(starts) > 1 and screen is not None and n > 2 * screen:
            # multi-start on a random subset (cheap), then one polish on all points; the
            # subset keeps >= 8 points per trend coefficient
            sub = rng.choice(n, screen, replace=False)
            obj_sub = make_objective(self._Xs[sub], self._F[sub], ys[sub])
            screened = [run(obj_sub, s, 150) for s in starts]
            starts = [min(screened, key=lambda r: r.fun).x]
        obj = make_objective(self._Xs, self._F, ys)
        best = None
        for s in starts:
            res = run(obj, s, 60 if len(starts) == 1 else 150)
            if best is None or res.fun < best.fun:
                best = res
        assert best is not None  # starts is never empty
        return self._fit_at(ys, best.x, noise)

    def _fit_at(self, ys: np.ndarray, theta: np.ndarray, noise: float | None) -> _Fit:
        """The solved systems of one response at hyperparameters ``theta``."""
        _, _, o = self._solve(ys, theta, noise, False)
        L, Lf = o["L"], o["Lf"]
        minv_f = linalg.solve_triangular(L, Lf, lower=True, trans=1, check_finite=False)
        ftf = None
        if Lf.shape[1]:
            ftf = linalg.cholesky(Lf.T @ Lf + 1e-12 * np.eye(Lf.shape[1]), lower=True)
        return _Fit(inv_ell=o["inv_ell"], eta=o["eta"], sigma2=o["sig2"], noise=o["dn"],
                    concentrated=o["conc"], chol=L, beta=o["beta"], alpha=o["alpha"],
                    ft_minv_f_chol=ftf, minv_f=minv_f, jitter=o["jitter"], loglik=o["ll"])

    # --- description -----------------------------------------------------------------------
    def _check_fitted(self):
        if not self._fits:
            raise ParameterError("GaussianProcess is not fitted; call fit(X, Y) first")

    @property
    def n_inputs(self) -> int:
        """Number of inputs d of the training data."""
        self._check_fitted()
        return self._X.shape[1]

    @property
    def n_outputs(self) -> int:
        """Number of responses m (one GP each)."""
        self._check_fitted()
        return len(self._fits)

    @property
    def length_scales(self) -> np.ndarray:
        """Length-scales in input units, shape (m, d)."""
        self._check_fitted()
        return np.array([self._span / f.inv_ell for f in self._fits])

    @property
    def process_variance(self) -> np.ndarray:
        """sigma^2 per response in response units squared, shape (m,)."""
        self._check_fitted()
        return np.array([f.sigma2 for f in self._fits]) * self._y_std**2

    @property
    def nugget_variance(self) -> np.ndarray:
        """Delta^2 per response in response units squared, shape (m,) (0 for interpolation)."""
        self._check_fitted()
        v = [f.noise if not f.concentrated else f.eta * f.sigma2 for f in self._fits]
        return np.array(v) * self._y_std**2

    @property
    def jitter(self) -> np.ndarray:
        """Variance added to the covariance diagonal for a stable Cholesky factorization, per
        response, in response units squared, shape (m,). It starts at n eps sigma^2
        (:func:`base_jitter`, n training points) and is raised x100 while the factorization
        fails (a warning says so when it was raised)."""
        self._check_fitted()
        return np.array([f.jitter * f.sigma2 if f.concentrated else f.jitter
                         for f in self._fits]) * self._y_std**2

    @property
    def bounds(self) -> np.ndarray:
        """Training box, shape (d, 2)."""
        self._check_fitted()
        return np.column_stack([self._lo, self._lo + self._span])

    def __repr__(self) -> str:
        state = f"fitted n={self._X.shape[0]}, d={self.n_inputs}, m={self.n_outputs}" \
            if self._fits else "not fitted"
        return f"GaussianProcess(trend={self.trend!r}, kernel={self.kernel!r}, {state})"

    # --- prediction ------------------------------------------------------------------------
    def extrapolation_distance(self, X) -> np.ndarray:
        """Euclidean distance (n,) of points outside the training box, in box-widths.

        Parameters
        ----------
        X : array_like of shape (n, d) or (d,)
            Points, in input units (0 for a point inside the box).
        """
        self._check_fitted()
        xs = (np.atleast_2d(np.asarray(X, dtype=float)) - self._lo) / self._span
        out = np.maximum(0.0, -xs) + np.maximum(0.0, xs - 1.0)
        return np.sqrt((out * out).sum(1))

    def predict(self, X, return_var: bool = True, return_grad: bool = False,
                warn_distance: float = 0.1):
        """Predict the latent function at a batch of points.

        Returns ``mean`` (n, m), then ``var`` (n, m) if ``return_var`` (the Kriging variance
        including the trend uncertainty, without the measurement noise), then ``grad``
        (n, m, d) (d mean / d x, analytic) if ``return_grad``; a single array when only the
        mean is asked for.

        Parameters
        ----------
        X : array_like of shape (n, d) or (d,)
            Points, in input units, columns in the training order.
        return_var : bool, optional
            Also return the Kriging variance (default True).
        return_grad : bool, optional
            Also return the gradient of the mean (default False).
        warn_distance : float or None, optional
            Warn (:class:`ExtrapolationWarning`) when a point lies farther than this many
            box-widths outside the training box (default 0.1; None: never).
        """
        self._check_fitted()
        X = np.atleast_2d(np.asarray(X, dtype=float))
        d = self._X.shape[1]
        if X.shape[1] != d:
            raise ModelShapeError(f"GP trained on {d} inputs, got points of shape {X.shape}")
        if warn_distance is not None:
            dist = self.extrapolation_distance(X)
            if dist.size and dist.max() > warn_distance:
                i = int(dist.argmax())
                nfar = int((dist > warn_distance).sum())
                warnings.warn(f"GaussianProcess asked to extrapolate: {nfar} "
                              f"point(s) outside the training box, the farthest (row {i}) at "
                              f"{dist[i]:.3g} box-widths", ExtrapolationWarning, stacklevel=2)
        xs = (X - self._lo) / self._span
        n, m = X.shape[0], len(self._fits)
        f = _basis(xs - 0.5, self.trend)
        mean = np.empty((n, m))
        var = np.empty((n if return_var else 0, m))
        grad = np.empty((n if return_grad else 0, m, d))
        fg = _basis_grad(xs - 0.5, self.trend) if return_grad else np.empty((0, 0, d))
        for j, fit in enumerate(self._fits):
            h = np.sqrt(_scaled_sqdist(xs, self._Xs, fit.inv_ell))
            r, G = _corr(h, self.kernel)
            s_cross = 1.0 if fit.concentrated else fit.sigma2
            k = s_cross * r
            mu = k @ fit.alpha + (f @ fit.beta if f.shape[1] else 0.0)
            mean[:, j] = self._y_mean[j] + self._y_std[j] * mu
            if return_var:
                v = linalg.solve_triangular(fit.chol, k.T, lower=True, check_finite=False)
                v0 = 1.0 if fit.concentrated else fit.sigma2
                s = v0 - (v * v).sum(0)
                if f.shape[1]:
                    u = (k @ fit.minv_f - f).T
                    w = linalg.solve_triangular(fit.ft_minv_f_chol, u, lower=True,
                                                check_finite=False)
                    s = s + (w * w).sum(0)
                scale = fit.sigma2 if fit.concentrated else 1.0
                var[:, j] = np.maximum(s, 0.0) * scale * self._y_std[j] ** 2
            if return_grad:
                ie2 = fit.inv_ell**2
                wv = (s_cross * G) * fit.alpha[None, :]  # (n, ntrain)
                # d k/dx_k = -G dx_k / ell_k^2
                g = -(xs * wv.sum(1)[:, None] - wv @ self._Xs) * ie2
                if f.shape[1]:
                    g = g + np.einsum("npd,p->nd", fg, fit.beta)
                grad[:, j, :] = g * (self._y_std[j] / self._span)
        out = [mean]
        if return_var:
            out.append(var)
        if return_grad:
            out.append(grad)
        return out[0] if len(out) == 1 else tuple(out)

    def _build_fast(self) -> None:
        """Pack every response's training points and weights for the compiled mean (the
        variance's arrays are built on demand by :meth:`compiled`)."""
        self._compiled = compile_gp(
            self._lo, self._span, self._Xs, np.array([f.inv_ell for f in self._fits]),
            np.array([f.alpha * (1.0 if f.concentrated else f.sigma2) for f in self._fits]),
            np.array([f.beta for f in self._fits]), self.trend, self.kernel, self._y_mean,
            self._y_std)

    def compiled(self, variance: bool = False) -> CompiledGP:
        """This GP's arrays for the compiled kernels (:class:`CompiledGP`).

        Parameters
        ----------
        variance : bool, optional
            Also the Kriging variance's arrays (built once, kept: an inverse triangular factor
            per response, n^3/3 flops and n^2 doubles each); default False.

        Examples
        --------
        >>> import numpy as np
        >>> from rotoruq.methods._gp_mean import gp_mean_var_batch
        >>> X = np.linspace(0, 1, 8)[:, None]
        >>> gp = GaussianProcess(seed=0).fit(X, np.sin(3 * X))
        >>> mean, var = gp_mean_var_batch(np.array([[0.3]]), gp.compiled(variance=True))
        >>> bool(np.allclose(var, gp.predict(np.array([[0.3]]))[1], atol=1e-12))
        True
        """
        self._check_fitted()
        if not variance or self._compiled.has_variance:
            return self._compiled
        li, mf, ci, v0, vs = [], [], [], [], []
        for j, fit in enumerate(self._fits):
            c = 1.0 if fit.concentrated else fit.sigma2
            with one_blas_thread():  # trtri on two threads: other bits (issue 35)
                linv, info = lapack.dtrtri(fit.chol, lower=1)
                p = fit.minv_f.shape[1]
                ci.append(linalg.solve_triangular(fit.ft_minv_f_chol, np.eye(p), lower=True)
                          if p else np.zeros((0, 0)))
            if info != 0:
                raise np.linalg.LinAlgError(f"triangular inverse failed (info={info})")
            li.append(c * np.tril(linv))
            mf.append(c * fit.minv_f)
            v0.append(1.0 if fit.concentrated else fit.sigma2)
            vs.append((fit.sigma2 if fit.concentrated else 1.0) * self._y_std[j] ** 2)
        self._compiled = dataclasses.replace(
            self._compiled, chol_inv=np.ascontiguousarray(li), minv_f=np.ascontiguousarray(mf),
            trend_chol_inv=np.ascontiguousarray(ci), v0=np.array(v0), var_scale=np.array(vs))
        return self._compiled

    def _mean_fast(self, X: np.ndarray) -> np.ndarray:
        """Mean only, no checks (used inside Markov chains), X (k, d) -> (k, m)."""
        return gp_mean_batch(X, self._compiled.mean_pack)

    def _mean_var_fast(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean and Kriging variance, no checks, X (k, d) -> (k, m), (k, m)."""
        return gp_mean_var_batch(X, self.compiled(variance=True))

    # --- cross-validation ------------------------------------------------------------------
    def loo(self) -> LeaveOneOut:
        """Leave-one-out errors in closed form (Dubrule 1983), with the hyperparameters kept
        fixed: ``e_i = (Q y)_i / Q_ii`` with ``Q = M^-1 - M^-1 F (F^T M^-1 F)^-1 F^T M^-1``.

        Only ``Q y`` and ``diag(Q)`` are needed: ``M^-1 y`` by two triangular solves and
        ``diag(M^-1)`` as the column sums of squares of ``L^-1`` (one triangular inverse,
        n^3/3 flops; the full ``M^-1`` would cost twice that plus n x n products). Runs on one
        BLAS thread like :meth:`fit` (issues 12, 35)."""
        self._check_fitted()
        n = self._X.shape[0]
        errs = np.empty((n, len(self._fits)))
        with one_blas_thread():
            for j, fit in enumerate(self._fits):
                ys = (self._Y[:, j] - self._y_mean[j]) / self._y_std[j]
                linv, info = lapack.dtrtri(fit.chol, lower=1)
                if info != 0:
                    raise np.linalg.LinAlgError(f"triangular inverse failed (info={info})")
                qy = linalg.cho_solve((fit.chol, True), ys, check_finite=False)
                qdiag = np.einsum("ij,ij->j", linv, linv)
                if self._F.shape[1]:
                    w = linalg.solve_triangular(fit.ft_minv_f_chol, fit.minv_f.T, lower=True,
                                                check_finite=False)
                    qy = qy - w.T @ (w @ ys)
                    qdiag = qdiag - np.einsum("ij,ij->j", w, w)
                errs[:, j] = qy / qdiag * self._y_std[j]
        rmse = np.sqrt((errs**2).mean(0))
        ystd = self._Y.std(0)
        ystd = np.where(ystd > 0, ystd, 1.0)
        q2 = 1.0 - (errs**2).sum(0) / ((self._Y - self._Y.mean(0)) ** 2).sum(0).clip(1e-300)
        return LeaveOneOut(errors=errs, rmse=rmse, nrmse=rmse / ystd, q2=q2)

    def as_model(self, names_in: Sequence[str], names_out: Sequence[str] | None = None) -> GPModel:
        """This GP as a :class:`~rotoruq.model.Model` (mean and analytic gradient).

        Parameters
        ----------
        names_in : sequence of str
            The d input names, in the training order.
        names_out : sequence of str, optional
            The m response names (default ``y0``, ``y1``, ...).
        """
        self._check_fitted()
        names_in = tuple(names_in)
        names_out = tuple(names_out) if names_out is not None else tuple(
            f"y{j}" for j in range(self.n_outputs))
        if len(names_in) != self.n_inputs or len(names_out) != self.n_outputs:
            raise ModelShapeError(f"GP has {self.n_inputs} inputs and {self.n_outputs} outputs; "
                                  f"got names {names_in} and {names_out}")
        return GPModel(self, names_in, names_out)


class GPModel:
    """A fitted :class:`GaussianProcess` seen through the Model protocol."""

    def __init__(self, gp: GaussianProcess, names_in: tuple[str, ...], names_out: tuple[str, ...]):
        self.gp = gp
        self.names_in = names_in
        self.names_out = names_out

    def __call__(self, x) -> np.ndarray:
        return self.gp.predict(x, return_var=False)

    def gradient(self, x) -> np.ndarray:
        return self.gp.predict(x, return_var=False, return_grad=True)[1]

    def __repr__(self) -> str:
        return f"GPModel({self.gp!r}, in={self.names_in}, out={self.names_out})"
