"""Variance-based sensitivity analysis: main and total Sobol' indices by pick-and-freeze.

Design (Saltelli 2010): two independent base samples A and B of N points each and, for every
input i, the matrix A_B^i (A with column i taken from B). The model is called ONCE on the
stacked batch [A; B; A_B^1; ...; A_B^d] of N (d + 2) points.

Estimators (f_A, f_B, f_i = f(A_B^i); V the variance of f over A and B, f_0 their mean):

* ``"hybrid"`` (default): total = Jansen's ``mean((f_A - f_i)^2) / (2 V_all)``, with V_all the
  variance over all N (d + 2) outputs (every block has the law of f, so this is a lower-noise
  estimate of the same variance); main = the average of the centred Saltelli 2010 estimator
  ``mean((f_B - f_0) (f_i - f_A)) / V_all`` and Janon's estimator (below), whose errors are
  only partly correlated, except for inputs whose estimated total index is below 0.1, which
  take the Saltelli estimate alone: its numerator vanishes with the total effect, while
  Janon's has an error floor of order N^-1/2 for any index near zero (the 8-D Sobol' G
  function's nearly inert inputs). How it was chosen and measured: ``benchmarks/
  sobol_accuracy.py`` (the 0.1 was picked after looking at the G function; 0.05 and 0.2 give
  the same results there, and Ishigami has no input below it).
* ``"saltelli2010"``: main ``mean((f_B - f_0) (f_i - f_A)) / V`` (Saltelli et al. 2010,
  table 2 (b), centred); total (Jansen 1999) ``mean((f_A - f_i)^2) / (2 V)``. The pair used by
  SALib and scipy.stats.sobol_indices.
* ``"jansen"``: main ``(V - mean((f_B - f_i)^2) / 2) / V``; total as above.
* ``"janon"``: main by Janon et al. (2014), the correlation-type estimator of the pairs
  (f_B, f_i), which share x_i, with the pairs' own mean and variance; total
  ``1 - janon(f_A, f_i)`` (those pairs share every input but x_i).

None of these is guaranteed in [0, 1] for finite N; values are reported as computed, with
bootstrap percentile intervals (resampling the N base rows; every estimator is a function of
means of per-row terms, so all resamples cost one matrix product).

References: A. Saltelli et al., Comput. Phys. Commun. 181 (2010) 259-270; M. J. W. Jansen,
Comput. Phys. Commun. 117 (1999) 35-43; A. Janon et al., ESAIM: PS 18 (2014) 342-364.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from .._rng import SeedLike, as_generator
from ..errors import ParameterError
from ..params import ParameterSpace
from ._common import eval_space, nan_rows_warning
from .sampling import _check_method, unit_to_space

__all__ = ["SobolResult", "sobol_indices", "sobol_from_design", "pick_freeze_design"]

ESTIMATORS = ("hybrid", "saltelli2010", "jansen", "janon")


@dataclass(frozen=True)
class SobolResult:
    """Main and total Sobol' indices.

    Attributes
    ----------
    names_in, names_out : input (d) and response (m) names.
    main, total : (m, d) first-order and total-effect indices.
    main_ci, total_ci : (m, d, 2) bootstrap percentile intervals at level ``confidence``
        (NaN when ``n_bootstrap == 0``).
    variance, mean : (m,) response variance and mean over the base samples.
    estimator : estimator name; n_base : N; n_evaluations : N (d + 2) model evaluations;
    n_dropped : (m,) base rows left out because one of their d + 2 evaluations failed.
    """

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    main: np.ndarray
    total: np.ndarray
    main_ci: np.ndarray
    total_ci: np.ndarray
    variance: np.ndarray
    mean: np.ndarray
    estimator: str
    confidence: float
    n_base: int
    n_evaluations: int
    n_dropped: np.ndarray

    def _k(self, response) -> int:
        if response is None:
            if len(self.names_out) != 1:
                raise ParameterError(f"name a response: one of {list(self.names_out)}")
            return 0
        if isinstance(response, int | np.integer):
            return int(response)
        if response not in self.names_out:
            raise ParameterError(f"unknown response {response!r}; valid: {list(self.names_out)}")
        return self.names_out.index(response)

    def ranking(self, response=None, by: str = "total") -> list[tuple[str, float, float]]:
        """Inputs sorted by decreasing ``by`` index ("total" or "main") for one response:
        a list of (name, main, total), ready for a tornado diagram."""
        k = self._k(response)
        if by not in ("total", "main"):
            raise ParameterError(f"by must be 'total' or 'main', got {by!r}")
        key = self.total[k] if by == "total" else self.main[k]
        order = np.argsort(-np.nan_to_num(key, nan=-np.inf), kind="stable")
        return [(self.names_in[i], float(self.main[k, i]), float(self.total[k, i])) for i in order]

    def table(self) -> list[dict]:
        """One dict per (response, input) with the indices and their intervals."""
        rows = []
        for k, r in enumerate(self.names_out):
            for i, x in enumerate(self.names_in):
                rows.append(
                    {
                        "response": r,
                        "input": x,
                        "main": float(self.main[k, i]),
                        "main_lo": float(self.main_ci[k, i, 0]),
                        "main_hi": float(self.main_ci[k, i, 1]),
                        "total": float(self.total[k, i]),
                        "total_lo": float(self.total_ci[k, i, 0]),
                        "total_hi": float(self.total_ci[k, i, 1]),
                    }
                )
        return rows


def pick_freeze_design(space: ParameterSpace, n: int, *, method="sobol", seed=None) -> np.ndarray:
    """The stacked pick-and-freeze batch [A; B; A_B^1; ...; A_B^d], shape (N (d + 2), d).

    A and B are the two halves of one 2d-dimensional design (so the QMC structure is kept).
    """
    n = int(n)
    if n < 2:
        raise ParameterError(f"number of base samples must be >= 2, got {n}")
    method = _check_method(method)
    d = space.dim
    rng = as_generator(seed)
    from scipy.stats import qmc

    if method == "mc":
        q = rng.random((n, 2 * d))
    elif method == "lhs":
        q = qmc.LatinHypercube(d=2 * d, seed=rng).random(n)
    else:
        if method == "sobol":  # 64 bits: scipy.stats.sobol_indices draws the same design
            eng = qmc.Sobol(d=2 * d, scramble=True, seed=rng, bits=64)
        else:
            eng = qmc.Halton(d=2 * d, scramble=True, seed=rng)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            q = eng.random(n)
    qa, qb = q[:, :d], q[:, d:]
    blocks = [qa, qb]
    for i in range(d):
        qi = qa.copy()
        qi[:, i] = qb[:, i]
        blocks.append(qi)
    # the Nataf map acts row-wise, so mapping after the column swap keeps the design exact
    return unit_to_space(space, np.vstack(blocks))


# Every estimator is a function of means of per-row terms, so a bootstrap resample (row counts
# w) is one matrix product w @ T instead of a gather of (B, N, d + 2) arrays.
_BASE_TERMS = 6  # fa, fb, fa^2, fb^2, row sum over all blocks, row sum of squares
_PER_INPUT = 7  # fi, fi^2, fb fi, fb (fi - fa), (fa - fi)^2, fa fi, (fb - fi)^2
SMALL_TOTAL = 0.1


def _row_terms(fa, fb, fi):
    """Per-row terms (N, 6 + 7 d) of centred responses fa, fb (N,) and fi (d, N)."""
    cols = [fa, fb, fa * fa, fb * fb, fa + fb + fi.sum(0), fa * fa + fb * fb + (fi * fi).sum(0)]
    per = np.stack([fi, fi * fi, fb * fi, fb * (fi - fa), (fa - fi) ** 2, fa * fi,
                    (fb - fi) ** 2], axis=1)  # (d, 7, N)
    return np.column_stack(cols + list(per.reshape(-1, fa.size)))


def _indices(means, n, d, estimator):
    """Main, total (..., d) and the A/B variance (...,) from term means (..., 6 + 7 d)."""
    m_a, m_b, m_a2, m_b2, m_s1, m_s2 = (means[..., j] for j in range(_BASE_TERMS))
    per = means[..., _BASE_TERMS:].reshape(*means.shape[:-1], d, _PER_INPUT)
    m_i, m_i2, m_bi, m_bdi, m_jt, m_ai, m_jm = (per[..., j] for j in range(_PER_INPUT))
    var_ab = n * (m_a2 + m_b2 - 0.5 * (m_a + m_b) ** 2) / (2 * n - 1)
    v_all = n * (m_s2 - m_s1**2 / (d + 2)) / (n * (d + 2) - 1)
    f0 = 0.5 * (m_a + m_b)[..., None]
    salt_num = m_bdi - f0 * (m_i - m_a[..., None])  # mean((f_B - f_0) (f_i - f_A))
    jansen_tot = 0.5 * m_jt  # mean((f_A - f_i)^2) / 2

    def janon(m_x, m_x2, m_xi):
        mid = 0.5 * (m_x[..., None] + m_i)
        return (m_xi - mid**2) / (0.5 * (m_x2[..., None] + m_i2) - mid**2)

    if estimator == "janon":
        main = janon(m_b, m_b2, m_bi)
        total = 1.0 - janon(m_a, m_a2, m_ai)
    elif estimator == "hybrid":
        v = v_all[..., None]
        total = jansen_tot / v
        salt = salt_num / v
        main = np.where(total < SMALL_TOTAL, salt, 0.5 * (salt + janon(m_b, m_b2, m_bi)))
    else:
        v = var_ab[..., None]
        if estimator == "saltelli2010":
            main = salt_num / v
        else:  # jansen
            main = (v - 0.5 * m_jm) / v
        total = jansen_tot / v
    return main, total, var_ab


def _name(names_out, k: int) -> str:
    return names_out[k] if names_out is not None else f"y{k}"


def _bootstrap_counts(rng, b: int, n: int) -> np.ndarray:
    """(b, n) multiplicities of the rows in b resamples with replacement of n rows."""
    idx = rng.integers(0, n, size=(b, n)) + (n * np.arange(b))[:, None]
    return np.bincount(idx.ravel(), minlength=b * n).reshape(b, n).astype(float)


def sobol_from_design(
    y,
    d: int,
    *,
    estimator: str = "hybrid",
    n_bootstrap: int = 100,
    confidence: float = 0.95,
    seed: SeedLike = None,
    names_in=None,
    names_out=None,
) -> SobolResult:
    """Indices from responses ``y`` (N (d + 2), m) of :func:`pick_freeze_design`.

    Base rows with a non-finite value in any of their d + 2 evaluations are left out (per
    response), with a RuntimeWarning giving the count. The bootstrap resamples base rows:
    every estimator is a function of means of 6 + 7 d per-row terms, so all ``n_bootstrap``
    resamples are one (n_bootstrap, N) x (N, 6 + 7 d) matrix product.
    """
    estimator = estimator.lower()
    if estimator not in ESTIMATORS:
        raise ParameterError(f"unknown estimator {estimator!r}; valid: {', '.join(ESTIMATORS)}")
    if not 0 < confidence < 1:
        raise ParameterError(f"confidence must lie in (0, 1), got {confidence}")
    if int(n_bootstrap) < 0:
        raise ParameterError(f"n_bootstrap must be >= 0, got {n_bootstrap}")
    y = np.asarray(y, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    if y.shape[0] % (d + 2):
        raise ParameterError(f"{y.shape[0]} responses is not a multiple of d + 2 = {d + 2}")
    n = y.shape[0] // (d + 2)
    m = y.shape[1]
    blocks = y.reshape(d + 2, n, m)
    ok = np.all(np.isfinite(blocks), axis=0)  # (n, m)
    n_dropped = n - ok.sum(axis=0)
    nan_rows_warning(int(np.sum(~ok.all(axis=1))), n, "sobol_indices (base rows)")
    rng = as_generator(seed)
    main = np.full((m, d), np.nan)
    total = np.full((m, d), np.nan)
    main_ci = np.full((m, d, 2), np.nan)
    total_ci = np.full((m, d, 2), np.nan)
    var = np.full(m, np.nan)
    mean = np.full(m, np.nan)
    a = 1.0 - confidence
    for k in range(m):
        rows = np.flatnonzero(ok[:, k])
        nk = rows.size
        if nk < 2:
            continue
        b = blocks[:, rows, k]
        mean[k] = b[:2].mean()
        if np.ptp(b) == 0.0:
            warnings.warn(
                f"sobol_indices: response {_name(names_out, k)!r} is constant over the design "
                f"(= {b.flat[0]:.6g}): it has no variance to apportion, its indices are NaN",
                RuntimeWarning,
                stacklevel=2,
            )
            var[k] = 0.0
            continue
        c = b.mean()  # the estimators are shift invariant; centring avoids cancellation
        terms = _row_terms(b[0] - c, b[1] - c, b[2:] - c)
        with np.errstate(divide="ignore", invalid="ignore"):
            main[k], total[k], var[k] = _indices(terms.mean(0), nk, d, estimator)
            if n_bootstrap > 0:
                chunk = max(1, int(2e7 // (nk * 8)))
                bs_s, bs_t = [], []
                for start in range(0, int(n_bootstrap), chunk):
                    w = _bootstrap_counts(rng, min(chunk, int(n_bootstrap) - start), nk)
                    s_b, t_b, _ = _indices(w @ terms / nk, nk, d, estimator)
                    bs_s.append(s_b)
                    bs_t.append(t_b)
                bs_s = np.concatenate(bs_s)
                bs_t = np.concatenate(bs_t)
                main_ci[k] = np.nanquantile(bs_s, [a / 2, 1 - a / 2], axis=0).T
                total_ci[k] = np.nanquantile(bs_t, [a / 2, 1 - a / 2], axis=0).T
    names_in = tuple(names_in) if names_in is not None else tuple(f"x{i}" for i in range(d))
    names_out = tuple(names_out) if names_out is not None else tuple(f"y{k}" for k in range(m))
    return SobolResult(
        names_in=names_in,
        names_out=names_out,
        main=main,
        total=total,
        main_ci=main_ci,
        total_ci=total_ci,
        variance=var,
        mean=mean,
        estimator=estimator,
        confidence=float(confidence),
        n_base=n,
        n_evaluations=y.shape[0],
        n_dropped=n_dropped,
    )


def sobol_indices(
    model,
    space: ParameterSpace,
    n: int,
    *,
    estimator: str = "hybrid",
    seed: SeedLike = None,
    n_bootstrap: int = 100,
    confidence: float = 0.95,
    method: str = "sobol",
) -> SobolResult:
    """Main and total Sobol' indices of every response with N (d + 2) evaluations.

    Parameters
    ----------
    model : Model; inputs matched to ``space.names`` by name.
    space : ParameterSpace. Indices of correlated inputs are computed on the Nataf model
        but lose their variance-decomposition meaning (they no longer sum to <= 1).
    n : number N of base samples (a power of 2 suits ``method="sobol"``).
    estimator : "hybrid" (default), "saltelli2010", "jansen" or "janon" (module docstring).
    seed : int or Generator (design and bootstrap).
    n_bootstrap : bootstrap resamples for the intervals (0: none; default 100, SALib's
        default, enough for 95 % percentile intervals to about +-0.01 in probability).
    confidence : interval level.
    method : base design: "sobol" (scrambled Sobol', default), "halton", "lhs" or "mc".

    Returns
    -------
    SobolResult with ``main`` and ``total`` of shape (m, d).
    """
    rng = as_generator(seed)
    x = pick_freeze_design(space, n, method=method, seed=rng)
    batch = eval_space(model, space, x)
    return sobol_from_design(
        batch.values,
        space.dim,
        estimator=estimator,
        n_bootstrap=n_bootstrap,
        confidence=confidence,
        seed=rng,
        names_in=space.names,
        names_out=tuple(model.names_out),
    )
