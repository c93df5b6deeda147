"""Gaussian likelihood of calibration data, thesis eqs. 2.22-2.24.

``d_e = q(theta) + eps_e`` for experiments ``e = 1..E`` with ``eps_e ~ N(0, Gamma_e)``. The
misfit ``M = 1/2 sum_e (d_e - q)^T Gamma_e^-1 (d_e - q)`` is quadratic in ``q``, so it is kept as
sufficient statistics ``P = sum_e Gamma_e^-1``, ``b = sum_e Gamma_e^-1 d_e`` and one evaluation
costs O(m^2) whatever the number of experiments.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ...errors import ModelShapeError, ParameterError
from ._kernels import loglik_var_rows, misfit_rows

__all__ = ["GaussianLikelihood"]


def _check_spd(c: np.ndarray, what: str) -> np.ndarray:
    if not np.all(np.isfinite(c)):
        raise ParameterError(f"{what} contains non-finite values")
    if not np.allclose(c, c.T, rtol=1e-10, atol=1e-14 * np.abs(c).max()):
        raise ParameterError(f"{what} is not symmetric")
    try:
        return np.linalg.cholesky(c)
    except np.linalg.LinAlgError:
        ev = np.linalg.eigvalsh(c)
        raise ParameterError(
            f"{what} is not positive definite (smallest eigenvalue {ev.min():.3g})"
        ) from None


class GaussianLikelihood:
    """Gaussian likelihood of ``data`` given model responses.

    Parameters
    ----------
    data : (n_exp, m) or (m,) observations of the m calibrated responses.
    noise_covariance : covariance of the data noise (data units squared), one of
        scalar (same variance for every response and experiment),
        (m,) variances, (m, m) full covariance (shared by all experiments),
        (n_exp, m) per-experiment variances, (n_exp, m, m) per-experiment covariances.
        A square 2-D array is read as the shared (m, m) covariance.
    names_out : response names, for error messages.
    """

    def __init__(self, data: ArrayLike, noise_covariance: ArrayLike,
                 names_out: tuple[str, ...] | None = None) -> None:
        names = names_out
        covariance = noise_covariance
        data = np.asarray(data, dtype=float)
        if data.ndim == 1:
            data = data[None, :]
        if data.ndim != 2:
            raise ModelShapeError(f"data must be (n_exp, m) or (m,), got shape {data.shape}")
        if not np.all(np.isfinite(data)):
            raise ParameterError("data contains non-finite values")
        n_exp, m = data.shape
        if names is not None and len(names) != m:
            raise ModelShapeError(
                f"data has {m} column(s) but {len(names)} response(s) are calibrated "
                f"({', '.join(names)}); give data as (n_exp, {len(names)})"
            )
        cov = np.asarray(covariance, dtype=float)
        var = None  # (n_exp, m) variances when the errors are independent
        if cov.ndim == 0:
            if not (np.isfinite(cov) and cov > 0):
                raise ParameterError(f"data variance must be > 0, got {float(cov)!r}")
            var = np.full((n_exp, m), float(cov))
        elif cov.ndim == 1 and cov.shape == (m,):
            if np.any(~(cov > 0)) or not np.all(np.isfinite(cov)):
                raise ParameterError(f"data variances must be finite and > 0, got {cov}")
            var = np.broadcast_to(cov, (n_exp, m))
        elif cov.ndim == 2 and cov.shape == (m, m):
            covs = np.broadcast_to(cov, (n_exp, m, m))
        elif cov.ndim == 2 and cov.shape == (n_exp, m):
            if np.any(~(cov > 0)) or not np.all(np.isfinite(cov)):
                raise ParameterError("per-experiment data variances must be finite and > 0")
            var = cov
        elif cov.ndim == 3 and cov.shape == (n_exp, m, m):
            covs = cov
        else:
            raise ModelShapeError(
                f"noise covariance of shape {cov.shape} does not fit data of shape {data.shape}: "
                f"use a scalar, ({m},), ({m}, {m}), ({n_exp}, {m}) or ({n_exp}, {m}, {m})"
            )
        if var is not None:  # no factorization needed
            prec_d = 1.0 / var
            P = np.diag(prec_d.sum(0))
            b = (prec_d * data).sum(0)
            c0 = float((prec_d * data * data).sum())
            logdet = float(np.log(var).sum())
        else:
            P, b, c0, logdet = self._full(data, covs, cov.shape == (m, m))
        self.data = data
        self.n_exp, self.m = n_exp, m
        self.precision = P
        self.b = b
        self._c0 = c0
        self._const = -0.5 * (n_exp * m * np.log(2.0 * np.pi) + logdet)
        # diagonal precision (independent errors, the usual case): O(m) per evaluation
        diag = bool(np.count_nonzero(P - np.diag(np.diag(P))) == 0)
        # the data's own mean and scatter, for the likelihood with an emulator's variance:
        # dbar = P^-1 b, resid = c0 - b^T P^-1 b (the misfit at q = dbar)
        p_chol = np.linalg.cholesky(P)
        p_inv = np.linalg.inv(P)
        p_inv = 0.5 * (p_inv + p_inv.T)
        dbar = np.linalg.solve(P, b)
        resid = max(float(c0 - b @ dbar), 0.0)
        logdet_p = float(2.0 * np.log(np.diag(p_chol)).sum())
        self.pack = (np.ascontiguousarray(P), b, float(c0), float(self._const), diag,
                     np.ascontiguousarray(p_inv), dbar, resid, logdet_p)

    @staticmethod
    def _full(data, covs, shared):
        """Sufficient statistics for full covariance matrices (n_exp, m, m)."""
        n_exp, m = data.shape
        P = np.zeros((m, m))
        b = np.zeros(m)
        c0 = 0.0
        logdet = 0.0
        for e in range(1 if shared else n_exp):
            what = "data covariance" if shared else f"data covariance of experiment {e}"
            L = _check_spd(np.array(covs[e]), what)
            Linv = np.linalg.inv(L)
            prec = Linv.T @ Linv
            if shared:
                P = n_exp * prec
                b = prec @ data.sum(0)
                c0 = float(np.einsum("ej,jk,ek->", data, prec, data))
                logdet = n_exp * 2.0 * np.log(np.diag(L)).sum()
            else:
                P += prec
                b += prec @ data[e]
                c0 += float(data[e] @ prec @ data[e])
                logdet += 2.0 * np.log(np.diag(L)).sum()
        return P, b, c0, logdet

    def misfit(self, q: np.ndarray) -> np.ndarray:
        """Misfit ``1/2 sum_e r_e^T Gamma_e^-1 r_e`` (eq. 2.24) for responses q (k, m) -> (k,).

        Parameters
        ----------
        q : array_like of shape (k, m) or (m,)
            Model responses at k points, data units (the residuals are taken against every
            experiment's data).
        """
        q = np.ascontiguousarray(np.atleast_2d(q), dtype=float)
        out = np.empty(q.shape[0])
        misfit_rows(q, self.pack, out)
        return out

    def __call__(self, q: np.ndarray, variance: np.ndarray | None = None) -> np.ndarray:
        """Log-likelihood (eq. 2.23, normalized) for responses q (k, m) -> (k,).

        ``variance`` (k, m): the variance of an emulator's error at each point (response
        units squared), one error per response shared by every experiment (the emulator
        is wrong by the same amount for all of them), integrated out as Higdon et al.
        (2004) do: ``log L = const - 1/2 [resid + log det(I + P S) + r^T (P^-1 + S)^-1 r]``
        with ``S = diag(variance)``, ``r = P^-1 b - q`` and ``resid = c0 - b^T P^-1 b``;
        with ``variance = 0`` it is the likelihood of ``q``.
        """
        if variance is None:
            return self._const - self.misfit(q)
        q = np.ascontiguousarray(np.atleast_2d(q), dtype=float)
        v = np.ascontiguousarray(np.broadcast_to(variance, q.shape), dtype=float)
        out = np.empty(q.shape[0])
        loglik_var_rows(q, v, self.pack, out)
        return out

    def gauss_newton_hessian(self, jac: np.ndarray) -> np.ndarray:
        """``J^T (sum_e Gamma_e^-1) J`` (eq. 2.26) for a Jacobian (m, d).

        Parameters
        ----------
        jac : ndarray of shape (m, d)
            d response / d parameter at a point.
        """
        return jac.T @ self.precision @ jac
