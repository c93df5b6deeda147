"""Chain diagnostics: rank-normalised R-hat, bulk/tail ESS, MCSE, moments, KL divergence.

R-hat, ESS and MCSE follow Vehtari, Gelman, Simpson, Carpenter and Buerkner (2021, "Rank-
normalization, folding, and localization: an improved R-hat for assessing convergence of
MCMC", Bayesian Analysis 16(2)), the estimators arviz and Stan report:

* chains are split in halves (a drifting chain then disagrees with itself);
* *rank normalisation*: the pooled draws are replaced by ``Phi^-1((rank - 3/8) / (N + 1/4))``,
  so R-hat and ESS exist for heavy tails and are invariant to monotone transforms;
* *folding*: ``|x - median(x)|`` rank-normalised exposes chains that agree in location but
  not in scale; the reported R-hat is the larger of the bulk and folded values;
* ESS from the multi-chain autocorrelation (within/between variances), summed with Geyer's
  initial monotone sequence; *bulk* ESS on the rank-normalised draws, *tail* ESS as the
  smaller ESS of the indicators ``x <= q05`` and ``x <= q95``;
* MCSE of the mean ``sd / sqrt(ESS_mean)`` and of a quantile from the beta-distributed
  coverage of the quantile indicator.

Everything is vectorised over the parameter axis. KL divergence prior -> posterior is
``KL = -H[post] - E_post[log prior]`` with the posterior entropy from the Kozachenko-Leonenko
k-nearest-neighbour estimator (and, separately, from a Gaussian approximation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import special, stats
from scipy.spatial import cKDTree

from ..._docs import fill_doc
from ...errors import ParameterError
from .._convergence import ChainConvergence

__all__ = ["autocovariance", "effective_sample_size", "split_rhat", "mcse_mean",
           "mcse_quantile", "ChainDiagnostics", "diagnose", "moments", "entropy_knn",
           "entropy_gaussian"]

#: fewest draws per chain the split estimators accept (as arviz)
MIN_DRAWS = 4


def autocovariance(x: np.ndarray) -> np.ndarray:
    """Autocovariance of each chain along axis -1 by FFT (biased, divided by n), same shape."""
    x = np.asarray(x, dtype=float)
    n = x.shape[-1]
    f = np.fft.rfft(x - x.mean(-1, keepdims=True), n=2 * n, axis=-1)
    return np.fft.irfft(f * np.conj(f), n=2 * n, axis=-1)[..., :n] / n


def _as_chains(chains: np.ndarray) -> np.ndarray:
    x = np.asarray(chains, dtype=float)
    if x.ndim != 3 or 0 in x.shape:
        raise ParameterError(
            f"chains must be a non-empty array (n_chains, n_draws, n_parameters); "
            f"got shape {x.shape}")
    return x


def _split(x: np.ndarray) -> np.ndarray:
    """(c, n, d) -> (2c, n // 2, d): first and last halves (the middle draw of odd n dropped)."""
    half = x.shape[1] // 2
    return np.concatenate([x[:, :half], x[:, x.shape[1] - half:]], axis=0)


def _average_ranks(a: np.ndarray) -> np.ndarray:
    """Ranks 1..N of each column of ``a`` (N, d), ties given their average rank: the numbers
    of ``scipy.stats.rankdata(a, method="average", axis=0)`` (a column holding a NaN is all
    NaN), about twice as fast on Markov chains.

    A chain repeats its point at every rejected proposal: each column is taken as runs of
    equal consecutive values, only the runs are sorted, and a group of equal values (one run
    or several) gets ``(first + last) / 2 + 1`` of the positions it covers in the sorted
    column. Every rank is an integer or half-integer below 2**52, so that average is exact
    and the order the sort leaves equal values in changes nothing.

    Examples
    --------
    >>> import numpy as np
    >>> _average_ranks(np.array([[3.0, 1.0], [1.0, 1.0], [3.0, 2.0], [2.0, 0.5]])).T
    array([[3.5, 1. , 3.5, 2. ],
           [2.5, 2.5, 4. , 1. ]])
    """
    n, d = a.shape
    out = np.empty((n, d))
    if n == 0:
        return out
    start = np.empty(n, dtype=bool)
    start[0] = True
    for j in range(d):
        x = a[:, j]
        if np.isnan(x).any():
            out[:, j] = np.nan
            continue
        np.not_equal(x[1:], x[:-1], out=start[1:])
        first = np.flatnonzero(start)  # where each run of equal consecutive values starts
        counts = np.diff(first, append=n)
        order = np.argsort(x[first], kind="stable")
        vals, sc = x[first][order], counts[order]
        # new[k]: sorted run k starts a group of equal values (k = runs closes the last)
        new = np.empty(vals.size + 1, dtype=bool)
        new[0] = new[-1] = True
        np.not_equal(vals[1:], vals[:-1], out=new[1:-1])
        before = np.concatenate(([0], np.cumsum(sc)))  # positions before each sorted run
        lo = before[np.flatnonzero(new[:-1])]  # each group's first and last position
        hi = before[np.flatnonzero(new[1:]) + 1] - 1
        ranks = np.empty(vals.size)
        ranks[order] = ((lo + hi + 2) * 0.5)[np.cumsum(new[:-1]) - 1]
        out[:, j] = np.repeat(ranks, counts)
    return out


def _rank_normalise(x: np.ndarray) -> np.ndarray:
    """Pooled ranks per parameter mapped to normal scores (Blom's offset 3/8), same shape."""
    m, n, d = x.shape
    rank = _average_ranks(x.reshape(m * n, d))
    # stats.norm.ppf without its argument checks: ndtri(q) * 1 + 0 into a C-ordered array
    # (the FFT of the ESS depends on the layout in its last bits)
    z = np.empty(rank.shape)
    z[...] = special.ndtri((rank - 0.375) / (m * n + 0.25)) + 0.0
    return z.reshape(m, n, d)


def _rhat_core(x: np.ndarray) -> np.ndarray:
    """Potential scale reduction of (m, n, d) chains as given (no split), (d,)."""
    n = x.shape[1]
    within = x.var(1, ddof=1).mean(0)
    between = n * x.mean(1).var(0, ddof=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.sqrt((between / within + n - 1.0) / n)


def _ess_core(x: np.ndarray) -> np.ndarray:
    """ESS of (m, n, d) chains as given (no split), (d,): Geyer's initial monotone sequence.

    The truncation is the one of Stan and arviz: autocorrelations are summed in adjacent
    pairs up to the first pair whose sum is not positive, the pair sums are made
    non-increasing, and the even lag of the first rejected pair is added when positive.
    """
    m, n, d = x.shape
    size = m * n
    xt = np.moveaxis(x, 2, 0)  # (d, m, n)
    acov = autocovariance(xt)
    mean_var = acov[:, :, 0].mean(1) * n / (n - 1.0)
    var_plus = mean_var * (n - 1.0) / n
    if m > 1:
        var_plus = var_plus + xt.mean(2).var(1, ddof=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = 1.0 - (mean_var[:, None] - acov.mean(1)) / var_plus[:, None]  # (d, n)
    rho[:, 0] = 1.0
    n_pairs = max(1, (n - 1) // 2)  # pairs (rho_2k, rho_2k+1) the sequence may reach
    pairs = rho[:, 0:2 * n_pairs:2] + rho[:, 1:2 * n_pairs:2]  # (d, n_pairs)
    nonpos = pairs <= 0.0
    k_stop = np.where(nonpos.any(1), nonpos.argmax(1), n_pairs - 1)  # first rejected pair
    kept = np.arange(n_pairs)[None, :] < k_stop[:, None]
    monotone = np.minimum.accumulate(np.where(kept, pairs, np.inf), axis=1)
    head = np.where(kept, monotone, 0.0).sum(1)
    rows = np.arange(d)
    even = rho[rows, 2 * k_stop]
    tail = np.where((even > 0.0) | (pairs[rows, k_stop] >= 0.0), even, 0.0)
    tau = np.maximum(-1.0 + 2.0 * head + tail, 1.0 / np.log10(size))
    ess = size / tau
    ess[np.isnan(rho).any(1)] = np.nan
    flat = x.reshape(size, d)
    ess[np.ptp(flat, axis=0) < np.finfo(float).resolution] = float(size)
    return ess


def effective_sample_size(chains: np.ndarray, *, kind: str = "bulk",
                          prob: float | None = None) -> np.ndarray:
    """Effective sample size per parameter (Vehtari et al. 2021).

    Parameters
    ----------
    chains : ndarray, shape (n_chains, n_draws, d)
        Draws of each chain, in any units.
    kind : {"bulk", "tail", "mean", "quantile"}
        ``bulk``: split chains, rank-normalised (efficiency of location summaries, robust to
        heavy tails). ``tail``: the smaller ESS of the 5 % and 95 % quantile indicators.
        ``mean``: split chains as they are (the ESS the MCSE of the mean uses).
        ``quantile``: ESS of the indicator ``x <= q_prob``.
    prob : float, optional
        Quantile level in (0, 1), only (and required) for ``kind="quantile"``.

    Returns
    -------
    ndarray, shape (d,)
        ESS in draws (between 0 and, for antithetic chains, more than n_chains * n_draws);
        ``n_chains * n_draws`` when there are fewer than 4 draws per chain.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.random.default_rng(0).normal(size=(4, 1000, 2))  # independent draws
    >>> bool(np.all(np.abs(effective_sample_size(x) / 4000 - 1) < 0.25))
    True
    """
    x = _as_chains(chains)
    c, n, d = x.shape
    if n < MIN_DRAWS:
        return np.full(d, float(c * n))
    if kind == "bulk":
        return _ess_core(_rank_normalise(_split(x)))
    if kind == "mean":
        return _ess_core(_split(x))
    if kind == "tail":
        return np.minimum(_ess_quantile(x, 0.05), _ess_quantile(x, 0.95))
    if kind == "quantile":
        if prob is None or not 0.0 < float(prob) < 1.0:
            raise ParameterError(f"prob must be a quantile level in (0, 1); got {prob!r}")
        return _ess_quantile(x, float(prob))
    raise ParameterError(
        f"kind must be one of 'bulk', 'tail', 'mean', 'quantile'; got {kind!r}")


def _ess_quantile(x: np.ndarray, prob: float) -> np.ndarray:
    q = np.quantile(x.reshape(-1, x.shape[2]), prob, axis=0)
    return _ess_core(_split((x <= q).astype(float)))


def split_rhat(chains: np.ndarray, *, kind: str = "rank") -> np.ndarray:
    """Split R-hat per parameter; by default the rank-normalised, folded one.

    Parameters
    ----------
    chains : ndarray, shape (n_chains, n_draws, d)
        Draws of each chain. One chain is split in two halves and still gives an R-hat.
    kind : {"rank", "bulk", "folded", "classic"}
        ``rank``: max of ``bulk`` and ``folded`` (Vehtari et al. 2021, what arviz reports).
        ``bulk``: split, rank-normalised. ``folded``: split, ``|x - median|`` rank-normalised
        (sensitive to chains with different spreads). ``classic``: split R-hat of BDA3 on the
        raw draws (for comparison with older tools).

    Returns
    -------
    ndarray, shape (d,)
        R-hat (dimensionless, 1 at convergence; 1.01 is the usual threshold); NaN with fewer
        than 4 draws per chain.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.random.default_rng(0).normal(size=(4, 1000, 1))
    >>> x[0] *= 3.0  # one chain three times wider: same mean, flagged by the folded R-hat
    >>> bool(split_rhat(x)[0] > 1.01), bool(split_rhat(x, kind="classic")[0] < 1.01)
    (True, True)
    """
    x = _as_chains(chains)
    if x.shape[1] < MIN_DRAWS:
        return np.full(x.shape[2], np.nan)
    s = _split(x)
    if kind == "classic":
        return _rhat_core(s)
    if kind not in ("rank", "bulk", "folded"):
        raise ParameterError(
            f"kind must be one of 'rank', 'bulk', 'folded', 'classic'; got {kind!r}")
    if kind == "bulk":
        return _rhat_core(_rank_normalise(s))
    folded = _folded_rhat(s)
    return folded if kind == "folded" else np.fmax(_rhat_core(_rank_normalise(s)), folded)


def _folded_rhat(s: np.ndarray) -> np.ndarray:
    """The folded R-hat of split chains ``s`` (2c, n, d)."""
    median = np.median(s.reshape(-1, s.shape[2]), axis=0)
    return _rhat_core(_rank_normalise(np.abs(s - median)))


def _bulk(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bulk ESS, bulk R-hat and folded R-hat of chains (c, n, d) with at least
    :data:`MIN_DRAWS` draws each: the numbers of ``effective_sample_size(x)``,
    ``split_rhat(x, kind="bulk")`` and ``split_rhat(x, kind="folded")``, the split chains
    rank-normalised once for the first two."""
    s = _split(x)
    z = _rank_normalise(s)
    return _ess_core(z), _rhat_core(z), _folded_rhat(s)


def ess_and_rhat(chains: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(effective_sample_size(chains), split_rhat(chains))`` (bulk ESS, rank R-hat), the
    same numbers, the split chains rank-normalised once for both.

    Parameters
    ----------
    chains : ndarray, shape (n_chains, n_draws, d)
        Draws of each chain.

    Returns
    -------
    tuple of ndarray
        Bulk ESS (d,) and rank-normalised split R-hat (d,).

    Examples
    --------
    >>> import numpy as np
    >>> x = np.random.default_rng(0).normal(size=(2, 300, 2))
    >>> ess, rhat = ess_and_rhat(x)
    >>> bool(np.array_equal(ess, effective_sample_size(x))), bool(np.array_equal(
    ...     rhat, split_rhat(x)))
    (True, True)
    """
    x = _as_chains(chains)
    c, n, d = x.shape
    if n < MIN_DRAWS:
        return np.full(d, float(c * n)), np.full(d, np.nan)
    ess, bulk, folded = _bulk(x)
    return ess, np.fmax(bulk, folded)


#: the entries :func:`mcse_mean` and :func:`mcse_quantile` share: their draws, their result
#: and the i.i.d. draws of their examples
_MCSE_DOC = {"chains": """
    chains : ndarray, shape (n_chains, n_draws, d)
        Draws of each chain.
    """, "returns": """
    Returns
    -------
    ndarray, shape (d,)
        MCSE in the units of the draws.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.random.default_rng(0).normal(size=(4, 2500, 1))
    """}


@fill_doc(**_MCSE_DOC)
def mcse_mean(chains: np.ndarray) -> np.ndarray:
    """Monte Carlo standard error of the posterior mean, ``sd / sqrt(ESS_mean)``.

    Parameters
    ----------
    %(chains)s

    %(returns)s
    >>> bool(abs(mcse_mean(x)[0] - 0.01) < 0.001)  # iid: 1 / sqrt(10000)
    True
    """
    x = _as_chains(chains)
    sd = x.reshape(-1, x.shape[2]).std(0, ddof=1)
    return sd / np.sqrt(effective_sample_size(x, kind="mean"))


@fill_doc(**_MCSE_DOC)
def mcse_quantile(chains: np.ndarray, prob: float) -> np.ndarray:
    """Monte Carlo standard error of the ``prob`` quantile (Vehtari et al. 2021, sec. 4.3).

    Half the distance between the draws at the 15.9 % and 84.1 % points of the beta
    distribution of the quantile's coverage, ``Beta(ESS p + 1, ESS (1 - p) + 1)``, with the
    ESS of the indicator ``x <= q_p``.

    Parameters
    ----------
    %(chains)s
    prob : float
        Quantile level in (0, 1).

    %(returns)s
    >>> bool(0.01 < mcse_quantile(x, 0.5)[0] < 0.02)  # iid median: sqrt(pi/2) / 100
    True
    """
    x = _as_chains(chains)
    if not 0.0 < float(prob) < 1.0:
        raise ParameterError(f"prob must be a quantile level in (0, 1); got {prob!r}")
    d = x.shape[2]
    if x.shape[1] < MIN_DRAWS:
        return np.full(d, np.nan)
    return _mcse_quantile(np.sort(x.reshape(-1, d), axis=0), float(prob),
                          _ess_quantile(x, float(prob)))


def _mcse_quantile(srt: np.ndarray, prob: float, ess: np.ndarray) -> np.ndarray:
    """:func:`mcse_quantile` from the pooled draws sorted per parameter ``srt`` (N, d) and
    the ESS (d,) of the quantile's indicator."""
    d = srt.shape[1]
    with np.errstate(invalid="ignore"):
        a = stats.beta.ppf(np.array([0.1586553, 0.8413447])[:, None],
                           ess * prob + 1.0, ess * (1.0 - prob) + 1.0)  # (2, d)
    size = srt.shape[0]
    lo = np.floor(np.fmax(a[0] * size - 1.0, 0.0))
    hi = np.ceil(np.fmin(a[1] * size - 1.0, size - 1.0))
    out = np.full(d, np.nan)
    ok = np.isfinite(lo) & np.isfinite(hi)
    cols = np.flatnonzero(ok)
    out[ok] = 0.5 * (srt[hi[ok].astype(int), cols] - srt[lo[ok].astype(int), cols])
    return out



class PooledChains:
    """The draws of a posterior result with ``chains`` (n_chains, n_draws, d) of the model
    parameters, pooled: :attr:`samples` and :meth:`credible_interval` (the base of
    :class:`~rotoruq.methods.mcmc.bayes.BayesResult` and
    :class:`~rotoruq.methods.mcmc.discrepancy.DiscrepancyResult`)."""

    chains: np.ndarray

    @property
    def samples(self) -> np.ndarray:
        """All kept samples of the parameters pooled over chains, (n_chains * n_draws, d)."""
        return self.chains.reshape(-1, self.chains.shape[-1])

    def credible_interval(self, level: float = 0.95) -> np.ndarray:
        """Equal-tailed credible interval (d, 2) of the parameters at ``level``, in their
        units.

        Parameters
        ----------
        level : float, optional
            Probability content, in (0, 1) (default 0.95).
        """
        if not 0 < level < 1:
            raise ParameterError(f"level must be in (0, 1), got {level}")
        a = 0.5 * (1.0 - level)
        return np.quantile(self.samples, [a, 1.0 - a], axis=0).T


@dataclass(frozen=True, eq=False)
class ChainDiagnostics(ChainConvergence):
    """Convergence diagnostics of one set of chains, each (d,) per parameter: the fields of
    :class:`~rotoruq.methods._convergence.ChainConvergence` and ``rhat``, the
    rank-normalised split R-hat, max of bulk and folded (dimensionless)."""

    rhat: np.ndarray


def diagnose(chains: np.ndarray) -> ChainDiagnostics:
    """All diagnostics of chains (n_chains, n_draws, d) at once.

    Parameters
    ----------
    chains : ndarray, shape (n_chains, n_draws, d)
        Draws of each chain.

    Returns
    -------
    ChainDiagnostics
        R-hat (bulk, folded and their max), bulk and tail ESS, MCSE of the mean and of the
        5 % / 95 % quantiles, each of shape (d,).

    Examples
    --------
    >>> import numpy as np
    >>> dg = diagnose(np.random.default_rng(0).normal(size=(4, 500, 3)))
    >>> dg.rhat.shape, bool(np.all(dg.rhat < 1.01))
    ((3,), True)
    """
    x = _as_chains(chains)
    c, n, d = x.shape
    if n < MIN_DRAWS:
        bulk = folded = mcse_q05 = mcse_q95 = np.full(d, np.nan)
        ess_bulk = ess_tail = np.full(d, float(c * n))
    else:
        # each estimator once: the split chains rank-normalised once (bulk R-hat and ESS),
        # the 5 % and 95 % indicators' ESS once (tail ESS and the quantiles' MCSE), the
        # draws sorted once; the same numbers as the public functions one by one
        ess_bulk, bulk, folded = _bulk(x)
        e05, e95 = _ess_quantile(x, 0.05), _ess_quantile(x, 0.95)
        ess_tail = np.minimum(e05, e95)
        srt = np.sort(x.reshape(-1, d), axis=0)
        mcse_q05, mcse_q95 = _mcse_quantile(srt, 0.05, e05), _mcse_quantile(srt, 0.95, e95)
    return ChainDiagnostics(
        rhat=np.fmax(bulk, folded), rhat_bulk=bulk, rhat_folded=folded,
        ess_bulk=ess_bulk, ess_tail=ess_tail, mcse_mean=mcse_mean(x), mcse_q05=mcse_q05,
        mcse_q95=mcse_q95)


def moments(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Mean, std (ddof=1), skewness and excess kurtosis of samples (n, d), each (d,)."""
    mean = x.mean(0)
    c = x - mean
    m2 = (c * c).mean(0)
    with np.errstate(divide="ignore", invalid="ignore"):
        skew = (c**3).mean(0) / m2**1.5
        kurt = (c**4).mean(0) / m2**2 - 3.0
    return mean, x.std(0, ddof=1), skew, kurt


def entropy_knn(x: np.ndarray, k: int = 4) -> float:
    """Kozachenko-Leonenko entropy estimate (nats) of i.i.d.-like samples (n, d).

    Repeated rows (rejected MCMC moves) are removed first: they carry no extra information for
    a density estimate once the chain is thinned past its autocorrelation.
    """
    x = np.unique(np.asarray(x, dtype=float), axis=0)
    n, d = x.shape
    if n <= k + 1:
        return np.nan
    dist, _ = cKDTree(x).query(x, k=k + 1)
    eps = dist[:, k]
    eps = eps[eps > 0]
    log_vd = 0.5 * d * np.log(np.pi) - special.gammaln(0.5 * d + 1.0)
    return float(special.digamma(n) - special.digamma(k) + log_vd + d * np.log(eps).mean())


def entropy_gaussian(x: np.ndarray) -> float:
    """Entropy (nats) of the Gaussian with the sample covariance of x (n, d)."""
    d = x.shape[1]
    cov = np.atleast_2d(np.cov(x, rowvar=False))
    sign, logdet = np.linalg.slogdet(cov)
    if sign <= 0:
        return -np.inf
    return float(0.5 * (d * (1.0 + np.log(2.0 * np.pi)) + logdet))
