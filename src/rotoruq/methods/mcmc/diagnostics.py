"""Chain diagnostics: effective sample size, split R-hat, moments, KL divergence.

ESS follows the multi-chain estimator of Vehtari et al. (2021) without rank normalization:
autocovariances by FFT, combined across chains through the within/between variances, summed
with Geyer's initial monotone sequence. KL divergence prior -> posterior is
``KL = -H[post] - E_post[log prior]`` with the posterior entropy from the Kozachenko-Leonenko
k-nearest-neighbour estimator (and, separately, from a Gaussian approximation).
"""

from __future__ import annotations

import numpy as np
from scipy import special
from scipy.spatial import cKDTree

__all__ = ["autocovariance", "effective_sample_size", "split_rhat", "moments",
           "entropy_knn", "entropy_gaussian"]


def autocovariance(x: np.ndarray) -> np.ndarray:
    """Autocovariance of each chain along axis -1 by FFT (biased, divided by n), same shape."""
    x = np.asarray(x, dtype=float)
    n = x.shape[-1]
    f = np.fft.rfft(x - x.mean(-1, keepdims=True), n=2 * n, axis=-1)
    return np.fft.irfft(f * np.conj(f), n=2 * n, axis=-1)[..., :n] / n


def effective_sample_size(chains: np.ndarray) -> np.ndarray:
    """ESS per parameter of chains (c, n, d) -> (d,)."""
    chains = np.asarray(chains, dtype=float)
    c, n, d = chains.shape
    if n < 4:
        return np.full(d, float(c * n))
    out = np.empty(d)
    for j in range(d):
        x = chains[:, :, j]
        acov = autocovariance(x)  # (c, n)
        chain_var = acov[:, 0] * n / (n - 1.0)
        W = chain_var.mean()
        var_plus = W * (n - 1.0) / n
        if c > 1:
            var_plus += x.mean(1).var(ddof=1)
        if not var_plus > 0:
            out[j] = float(c * n)
            continue
        rho = 1.0 - (W - acov.mean(0)) / var_plus
        rho[0] = 1.0
        # Geyer: sums of adjacent pairs, truncated at the first negative pair, made monotone
        npairs = n // 2
        pairs = rho[: 2 * npairs].reshape(npairs, 2).sum(1)
        neg = np.flatnonzero(pairs <= 0)
        k = neg[0] if neg.size else npairs
        pairs = np.minimum.accumulate(pairs[:k]) if k else pairs[:1]
        tau = -1.0 + 2.0 * pairs.sum()
        tau = max(tau, 1.0 / np.log10(max(c * n, 10)))
        out[j] = c * n / tau
    return out


def split_rhat(chains: np.ndarray) -> np.ndarray:
    """Split R-hat (Gelman et al., BDA3) per parameter of chains (c, n, d) -> (d,)."""
    chains = np.asarray(chains, dtype=float)
    c, n, d = chains.shape
    half = n // 2
    if half < 2:
        return np.full(d, np.nan)
    parts = np.concatenate([chains[:, :half], chains[:, n - half:]], axis=0)  # (2c, half, d)
    means = parts.mean(1)
    W = parts.var(1, ddof=1).mean(0)
    B = half * means.var(0, ddof=1)
    var_plus = (half - 1.0) / half * W + B / half
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.sqrt(var_plus / W)


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
