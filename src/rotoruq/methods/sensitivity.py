"""Variance-based sensitivity analysis: main and total Sobol' indices by pick-and-freeze.

Design (Saltelli 2010): two independent base samples A and B of N points each and, for every
input i, the matrix A_B^i (A with column i taken from B). The model is called ONCE on the
stacked batch [A; B; A_B^1; ...; A_B^d] of N (d + 2) points. A and B are the two halves of one
2d-dimensional design from :func:`rotoruq.params.unit_design` (scrambled Sobol' by default,
as SALib and scipy.stats.sobol_indices draw it).

Estimators (f_A, f_B, f_i = f(A_B^i); f_0 the mean over A and B; V_AB the variance over A and
B; V_all the variance over all N (d + 2) outputs, a lower-noise estimate of the same variance
since every block has the law of f):

* ``"hybrid"`` (default): total = Jansen's ``mean((f_A - f_i)^2) / (2 V_all)``; main = the
  mean of three estimates of the same index whose errors are only partly correlated: the
  centred Saltelli 2010 numerator ``mean((f_B - f_0) (f_i - f_A))`` over V_AB and over V_all,
  and Janon's estimator (below); except for inputs whose Saltelli estimate over V_AB is below
  0.2, which take that estimate alone: Janon's estimator has an error floor of order N^-1/2
  for an index near zero (the G function's inert inputs, Ishigami's x3 whose main effect is 0
  but total is not), while Saltelli's numerator shrinks with the effect. How the rule was
  chosen: ``benchmarks/sobol_accuracy.py`` (per seed, the largest error over all main and
  total indices, paired against the peers' estimator on the same design over >= 300 seeds; the
  0.2 was picked after looking at Ishigami with a = 5, b = 0.5, where 0.1 lost to the peers
  at N = 256; the benchmark lists which functions were looked at and which were not).
* ``"saltelli2010"``: main ``mean((f_B - f_0) (f_i - f_A)) / V_AB`` (Saltelli et al. 2010,
  table 2 (b), centred); total (Jansen 1999) ``mean((f_A - f_i)^2) / (2 V_AB)``. The pair used
  by SALib and scipy.stats.sobol_indices.
* ``"jansen"``: main ``(V_AB - mean((f_B - f_i)^2) / 2) / V_AB``; total as above.
* ``"janon"``: main by Janon et al. (2014), the correlation-type estimator of the pairs
  (f_B, f_i), which share x_i, with the pairs' own mean and variance; total
  ``1 - janon(f_A, f_i)`` (those pairs share every input but x_i).

None of these is guaranteed in [0, 1] for finite N; values are reported as computed.

Intervals: every estimator is a smooth function of the means of 6 + 7 d per-row terms. The
intervals are percentile intervals of a *parametric bootstrap of those means*: ``n_bootstrap``
draws from the normal law with the terms' sample mean and covariance / N (the central limit
theorem for means of i.i.d. rows), each pushed through the estimator. To first order this is
the row-resampling bootstrap (tests compare the two), at O(N K^2) for the covariance plus
O(B K) for the draws instead of O(B N K) for B resamples of N rows: the intervals cost less
than the analysis. Both treat the rows as independent, so with a QMC design (the default)
they are conservative: the design's error is smaller than i.i.d. rows would give.

References: A. Saltelli et al., Comput. Phys. Commun. 181 (2010) 259-270; M. J. W. Jansen,
Comput. Phys. Commun. 117 (1999) 35-43; A. Janon et al., ESAIM: PS 18 (2014) 342-364.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import lapack

from .._rng import SeedLike, as_generator
from ..errors import ParameterError
from ..model import Model
from ..params import ParameterSpace, unit_design
from ._common import eval_space, names_or_default, nan_rows_warning
from ._sobol_indices import SobolIndices
from .sampling import check_design, unit_to_space

__all__ = ["SobolResult", "sobol_indices", "sobol_from_design", "pick_freeze_design"]

ESTIMATORS = ("hybrid", "saltelli2010", "jansen", "janon")


@dataclass(frozen=True, eq=False)
class SobolResult(SobolIndices):
    """Main and total Sobol' indices.

    Attributes
    ----------
    names_in, names_out : tuple of str
        The d input and m response names.
    main, total : ndarray of shape (m, d)
        First-order and total-effect indices.
    main_ci, total_ci : ndarray of shape (m, d, 2)
        Bootstrap percentile intervals at level ``confidence`` (NaN when
        ``n_bootstrap == 0``).
    variance, mean : ndarray of shape (m,)
        Response variance and mean over the base samples (response units).
    estimator : str
        The estimator, one of ``"hybrid"``, ``"saltelli2010"``, ``"jansen"``, ``"janon"``.
    design : str or None
        The base design (``"sobol"``, ...), or None when the responses were handed to
        :func:`sobol_from_design`.
    confidence : float
        The level of ``main_ci`` and ``total_ci``.
    n_samples : int
        N, the number of base samples.
    n_evaluations : int
        N (d + 2) model evaluations.
    n_dropped : ndarray of shape (m,)
        Base rows left out because one of their d + 2 evaluations failed.
    """

    variance: np.ndarray
    mean: np.ndarray
    estimator: str
    design: str | None
    confidence: float
    n_samples: int
    n_evaluations: int
    n_dropped: np.ndarray

    def _k(self, response: str | int | None) -> int:
        if response is None:
            if len(self.names_out) != 1:
                raise ParameterError(f"name a response: one of {list(self.names_out)}")
            return 0
        if isinstance(response, int | np.integer):
            return int(response)
        if response not in self.names_out:
            raise ParameterError(f"unknown response {response!r}; valid: {list(self.names_out)}")
        return self.names_out.index(response)

    def ranking(self, response: str | int | None = None,
                by: str = "total") -> list[tuple[str, float, float]]:
        """Inputs sorted by decreasing ``by`` index for one response.

        Parameters
        ----------
        response : str or int, optional
            The response, by name or index (may be left out when there is only one).
        by : str, optional
            ``"total"`` (default) or ``"main"``: the index to sort by.

        Returns
        -------
        list of (str, float, float)
            (name, main, total) per input, ready for a tornado diagram.
        """
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


def pick_freeze_design(space: ParameterSpace, n_samples: int, *, design: str = "sobol",
                       seed: SeedLike = None) -> np.ndarray:
    """The stacked pick-and-freeze batch [A; B; A_B^1; ...; A_B^d], shape (N (d + 2), d).

    A and B are the two halves of one 2d-dimensional design (so the QMC structure is kept).
    """
    n = int(n_samples)
    if n < 2:
        raise ParameterError(f"n_samples (base samples) must be >= 2, got {n_samples}")
    d = space.dim
    q = unit_design(n, 2 * d, design=check_design(design), seed=as_generator(seed))
    qa, qb = q[:, :d], q[:, d:]
    blocks = [qa, qb]
    for i in range(d):
        qi = qa.copy()
        qi[:, i] = qb[:, i]
        blocks.append(qi)
    # the Nataf map acts row-wise, so mapping after the column swap keeps the design exact
    return unit_to_space(space, np.vstack(blocks))


# Every estimator is a function of means of per-row terms (resampled as a whole by the
# parametric bootstrap).
_BASE_TERMS = 6  # fa, fb, fa^2, fb^2, row sum over all blocks, row sum of squares
_PER_INPUT = 7  # fi, fi^2, fb fi, fb (fi - fa), (fa - fi)^2, fa fi, (fb - fi)^2
SMALL_MAIN = 0.2


def _row_terms(fa: np.ndarray, fb: np.ndarray, fi: np.ndarray) -> np.ndarray:
    """Per-row terms (N, 6 + 7 d) of centred responses fa, fb (N,) and fi (d, N)."""
    cols = [fa, fb, fa * fa, fb * fb, fa + fb + fi.sum(0), fa * fa + fb * fb + (fi * fi).sum(0)]
    per = np.stack([fi, fi * fi, fb * fi, fb * (fi - fa), (fa - fi) ** 2, fa * fi,
                    (fb - fi) ** 2], axis=1)  # (d, 7, N)
    return np.column_stack(cols + list(per.reshape(-1, fa.size)))


def _indices(means: np.ndarray, n: int, d: int, estimator: str,
             small: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Main, total (..., d) and the A/B variance (...,) from term means (..., 6 + 7 d).

    small : (d,) which inputs take the hybrid's Saltelli-only branch; None decides from
    ``means`` (a bootstrap passes the point estimate's choice, so every draw uses one rule).
    """
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
        return janon(m_b, m_b2, m_bi), 1.0 - janon(m_a, m_a2, m_ai), var_ab
    v = var_ab[..., None]
    total = jansen_tot / v
    if estimator == "saltelli2010":
        main = salt_num / v
    elif estimator == "jansen":
        main = (v - 0.5 * m_jm) / v
    else:  # hybrid
        salt = salt_num / v
        if small is None:
            small = salt < SMALL_MAIN
        va = v_all[..., None]
        main = np.where(small, salt, (salt + salt_num / va + janon(m_b, m_b2, m_bi)) / 3.0)
        total = jansen_tot / va
    return main, total, var_ab


def _name(names_out: Sequence[str] | None, k: int) -> str:
    return names_out[k] if names_out is not None else f"y{k}"


def _mean_draws(rng: np.random.Generator, terms: np.ndarray, b: int) -> np.ndarray:
    """(b, K) draws of the term means from their normal law N(mean, cov / N).

    The covariance is singular by construction (the row sums, and (f_A - f_i)^2 against
    f_A^2, f_A f_i and f_i^2, are linear combinations of other terms), so it is factored by
    LAPACK's pivoted Cholesky for semidefinite matrices (dpstrf), not eigh: a 27 x 27 eigh
    took 40 ms with two BLAS threads on a busy machine, dpstrf takes microseconds."""
    n, k = terms.shape
    mean = terms.mean(0)
    centred = terms - mean
    cov = centred.T @ centred / ((n - 1) * n)
    c, piv, rank, _ = lapack.dpstrf(cov, lower=1)
    root = np.zeros((k, k))
    root[piv - 1, :rank] = np.tril(c)[:, :rank]  # cov = root @ root.T
    return mean + rng.standard_normal((b, rank)) @ root[:, :rank].T


def _quantiles(draws: np.ndarray, a: float) -> np.ndarray:
    """(d, 2) percentile interval of draws (b, d); nanquantile (slow) only if needed."""
    q = np.nanquantile if np.isnan(draws).any() else np.quantile
    return q(draws, [a / 2, 1 - a / 2], axis=0).T


def sobol_from_design(
    y: np.ndarray,
    d: int,
    *,
    estimator: str = "hybrid",
    n_bootstrap: int = 100,
    confidence: float = 0.95,
    names_in: Sequence[str] | None = None,
    names_out: Sequence[str] | None = None,
    seed: SeedLike = None,
) -> SobolResult:
    """Indices from responses ``y`` (N (d + 2), m) of :func:`pick_freeze_design`.

    Base rows with a non-finite value in any of their d + 2 evaluations are left out (per
    response), with a RuntimeWarning giving the count. ``n_bootstrap`` draws of the
    parametric bootstrap (module docstring) give the intervals; ``seed`` drives them.
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
            means = terms.mean(0)
            small = None
            if estimator == "hybrid":
                salt, _, _ = _indices(means, nk, d, "saltelli2010")
                small = salt < SMALL_MAIN
            main[k], total[k], var[k] = _indices(means, nk, d, estimator, small)
            if n_bootstrap > 0:
                s_b, t_b, _ = _indices(_mean_draws(rng, terms, int(n_bootstrap)), nk, d,
                                       estimator, small)
                main_ci[k] = _quantiles(s_b, a)
                total_ci[k] = _quantiles(t_b, a)
    names_in = names_or_default(names_in, d, "x")
    names_out = names_or_default(names_out, m, "y")
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
        design=None,
        confidence=float(confidence),
        n_samples=n,
        n_evaluations=y.shape[0],
        n_dropped=n_dropped,
    )


def sobol_indices(
    model: Model,
    space: ParameterSpace,
    n_samples: int,
    *,
    estimator: str = "hybrid",
    design: str = "sobol",
    n_bootstrap: int = 100,
    confidence: float = 0.95,
    seed: SeedLike = None,
) -> SobolResult:
    """Main and total Sobol' indices of every response with N (d + 2) evaluations.

    Parameters
    ----------
    model : Model
        Inputs matched to ``space.names`` by name; called on N (d + 2) points in one batch.
    space : ParameterSpace
        The d uncertain inputs. Indices of correlated inputs are computed on the Nataf model
        but lose their variance-decomposition meaning (they no longer sum to <= 1).
    n_samples : int
        Number N of base samples (a power of 2 suits ``design="sobol"``).
    estimator : str
        "hybrid" (default), "saltelli2010", "jansen" or "janon" (module docstring).
    design : str
        Base design: "sobol" (scrambled Sobol', default), "halton", "lhs" or "random".
    n_bootstrap : int
        Draws of the parametric bootstrap for the intervals (0: none; default 100, SALib's
        default number of resamples).
    confidence : float
        Interval level, in (0, 1).
    seed : int, numpy Generator or None
        Seeds the design and the intervals; the same seed gives the same indices, bitwise.

    Returns
    -------
    SobolResult
        ``main`` and ``total`` of shape (m, d) (dimensionless shares of each response's
        variance), ``main_ci`` and ``total_ci`` (m, d, 2).

    Examples
    --------
    y = a + 2 b with a, b independent standard normals: Var y = 1 + 4, so the main (and total)
    indices are 1/5 and 4/5:

    >>> import numpy as np
    >>> import rotoruq as rq
    >>> space = rq.ParameterSpace({"a": rq.Normal(0.0, 1.0), "b": rq.Normal(0.0, 1.0)})
    >>> model = rq.FunctionModel(lambda x: x[:, :1] + 2.0 * x[:, 1:], space.names, ["y"])
    >>> s = rq.sobol_indices(model, space, 1024, seed=1, n_bootstrap=0)
    >>> s.main.shape, s.n_evaluations                        # (m, d); N (d + 2) evaluations
    ((1, 2), 4096)
    >>> np.allclose(s.main, [[0.2, 0.8]], atol=0.03), np.allclose(s.total, [[0.2, 0.8]], atol=0.03)
    (True, True)
    """
    rng = as_generator(seed)
    design = check_design(design)
    x = pick_freeze_design(space, n_samples, design=design, seed=rng)
    batch = eval_space(model, space, x)
    res = sobol_from_design(
        batch.values,
        space.dim,
        estimator=estimator,
        n_bootstrap=n_bootstrap,
        confidence=confidence,
        names_in=space.names,
        names_out=tuple(model.names_out),
        seed=rng,
    )
    return dataclasses.replace(res, design=design)
