"""Uncertain parameters: distributions backed by :mod:`scipy.stats` and the
:class:`ParameterSpace` that every method samples from and transforms into.

A distribution is a small frozen object with ``mean``, ``std``, ``bounds`` and the vectorized
``ppf``/``cdf``/``pdf``/``logpdf`` of its scipy counterpart. A ParameterSpace is an ordered
mapping name -> distribution. Points are arrays of shape ``(n, d)`` in the order of
``space.names``.

Standard normal space ("u-space") is reached through the marginal CDFs:
``z = Phi^-1(F_i(x_i))``; for independent variables ``u = z``. With a correlation matrix the
Nataf transformation is used: the correlation ``R`` given in x-space is mapped to the
equivalent correlation ``R0`` of the normal scores ``z`` (solved per pair by Gauss-Hermite
quadrature), and ``u = L^-1 z`` with ``L L^T = R0``.

Epistemic variables are :class:`Interval` objects: one or more intervals with basic probability
assignments (BPAs). Methods that need a density treat them as the BPA-weighted mixture of
uniform densities over their intervals (Dakota does the same when it samples them); the
evidence method (:mod:`rotoruq.methods.evidence`) uses the intervals themselves.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy import stats
from scipy.stats import qmc

from ._rng import SeedLike, as_generator
from .errors import ParameterError

__all__ = [
    "Distribution",
    "Normal",
    "TruncatedNormal",
    "LogNormal",
    "Uniform",
    "LogUniform",
    "Beta",
    "Gamma",
    "Exponential",
    "Gumbel",
    "Weibull",
    "Triangular",
    "Interval",
    "ParameterSpace",
    "nataf_correlation",
    "make_distribution",
    "DISTRIBUTIONS",
]


def _number(name: str, value, what: str) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{what}: {name} must be a number, got {value!r}") from None


def _positive(name: str, value: float, what: str) -> float:
    value = _number(name, value, what)
    if not np.isfinite(value) or value <= 0:
        raise ParameterError(f"{what}: {name} must be a finite number > 0, got {value!r}")
    return value


def _finite(name: str, value: float, what: str) -> float:
    value = _number(name, value, what)
    if not np.isfinite(value):
        raise ParameterError(f"{what}: {name} must be finite, got {value!r}")
    return value


def _ordered(lower: float, upper: float, what: str) -> tuple[float, float]:
    lower, upper = _number("lower", lower, what), _number("upper", upper, what)
    if not (lower < upper):
        raise ParameterError(
            f"{what}: bounds must satisfy lower < upper, got lower={lower!r}, upper={upper!r}"
        )
    return lower, upper


@dataclass(frozen=True)
class Distribution:
    """Base class: a frozen scipy distribution plus the parameters that define it.

    Subclasses set ``_frozen`` in ``__post_init__``. All methods are vectorized.
    """

    @property
    def dist(self):
        """The frozen :mod:`scipy.stats` distribution."""
        return self._frozen  # type: ignore[attr-defined]

    @property
    def kind(self) -> str:
        return type(self).__name__.lower()

    @property
    def mean(self) -> float:
        return float(self.dist.mean())

    @property
    def std(self) -> float:
        return float(self.dist.std())

    @property
    def bounds(self) -> tuple[float, float]:
        """Support of the distribution (may be infinite)."""
        lo, hi = self.dist.support()
        return float(lo), float(hi)

    def ppf(self, q):
        return self.dist.ppf(q)

    def cdf(self, x):
        return self.dist.cdf(x)

    def sf(self, x):
        """Survival function 1 - F(x), computed without cancellation in the upper tail."""
        return self.dist.sf(x)

    def isf(self, q):
        """Inverse survival function: x with sf(x) = q."""
        return self.dist.isf(q)

    def from_z(self, z):
        """Value with normal score ``z``: ``F^-1(Phi(z))``, exact in both tails.

        The lower tail goes through ``ppf(Phi(z))`` and the upper tail through
        ``isf(Phi(-z))``, so no probability is ever rounded to 1 (``Phi(8.3)`` is 1.0 in double
        precision, ``Phi(-37)`` = 5.7e-300 is not 0). Shape of ``z``.
        """
        z = np.asarray(z, dtype=float)
        lower = z <= 0
        with np.errstate(invalid="ignore"):
            lo = self.ppf(stats.norm.cdf(np.where(lower, z, 0.0)))
            hi = self.isf(stats.norm.sf(np.where(lower, 0.0, z)))
        return np.where(lower, lo, hi)

    def to_z(self, x):
        """Normal score ``Phi^-1(F(x))`` of values ``x``, exact in both tails (the smaller of
        the CDF and the survival function is inverted). Clipped to +-37.5 (where the
        tail probability reaches the smallest normal double) at and beyond the support
        bounds. Shape of ``x``."""
        x = np.asarray(x, dtype=float)
        c = np.asarray(self.cdf(x), dtype=float)
        s = np.asarray(self.sf(x), dtype=float)
        tiny = np.finfo(float).tiny
        with np.errstate(invalid="ignore"):
            z = np.where(
                c <= s, stats.norm.ppf(np.maximum(c, tiny)), stats.norm.isf(np.maximum(s, tiny))
            )
        return np.where(np.isnan(x), np.nan, z)

    def pdf(self, x):
        return self.dist.pdf(x)

    def logpdf(self, x):
        return self.dist.logpdf(x)

    def rvs(self, size, seed: SeedLike = None):
        return self.dist.rvs(size=size, random_state=as_generator(seed))

    def describe(self) -> dict:
        """Defining parameters as a plain dict (for reports and study files)."""
        out = {"kind": self.kind}
        for k, v in self.__dict__.items():
            if not k.startswith("_"):
                out[k] = v
        return out


def _freeze(obj, frozen) -> None:
    object.__setattr__(obj, "_frozen", frozen)


@dataclass(frozen=True)
class Normal(Distribution):
    """Normal (Gaussian) distribution N(mean, std^2)."""

    mu: float
    sigma: float

    def __post_init__(self):
        _finite("mean", self.mu, "Normal")
        _positive("std", self.sigma, "Normal")
        _freeze(self, stats.norm(loc=self.mu, scale=self.sigma))

    @property
    def mean(self) -> float:
        return float(self.mu)

    @property
    def std(self) -> float:
        return float(self.sigma)


_SERIES_DELTA = 1e-4


def _normal_mass(a: float, delta: np.ndarray) -> np.ndarray:
    """P(a < X < a + delta) for X ~ N(0, 1), finite a, delta >= 0, without cancellation.

    Below ``delta = 1e-4`` the integral of phi over [a, a + delta] is its Taylor series in
    delta (4 terms, relative error < 1e-14 for |a| < 10); above, the difference of two CDFs
    (or two survival functions when a > 0), which then carries no cancellation worth a digit.
    """
    delta = np.asarray(delta, dtype=float)
    small = delta < _SERIES_DELTA
    d = np.where(small, delta, 0.0)
    series = stats.norm.pdf(a) * d * (
        1.0 - a * d / 2.0 + (a * a - 1.0) * d * d / 6.0 + (3.0 * a - a**3) * d**3 / 24.0
    )
    D = np.where(small, _SERIES_DELTA, delta)
    if a > 0:
        direct = stats.norm.sf(a) - stats.norm.sf(a + D)
    else:
        direct = stats.norm.cdf(a + D) - stats.norm.cdf(a)
    return np.where(small, series, direct)


def _normal_mass_inv(a: float, t: np.ndarray) -> np.ndarray:
    """delta >= 0 with ``_normal_mass(a, delta) = t`` (inverse of the above)."""
    t = np.asarray(t, dtype=float)
    pa = stats.norm.pdf(a)
    with np.errstate(invalid="ignore", divide="ignore"):
        if a > 0:
            direct = stats.norm.isf(stats.norm.sf(a) - t) - a
        else:
            direct = stats.norm.ppf(stats.norm.cdf(a) + t) - a
        small = t < pa * _SERIES_DELTA * 0.5
        d = np.where(small, t / pa, 0.0)
        for _ in range(4):  # Newton on the series; converges in 2-3 steps from t / phi(a)
            f = _normal_mass(a, d) - t
            d = d - f / (pa * np.exp(-a * d - 0.5 * d * d))
            d = np.where(small, d, 0.0)
    return np.where(small, np.maximum(d, 0.0), np.maximum(direct, 0.0))


@dataclass(frozen=True)
class TruncatedNormal(Distribution):
    """Normal(mu, sigma) truncated to [lower, upper] (either may be infinite)."""

    mu: float
    sigma: float
    lower: float = -math.inf
    upper: float = math.inf

    def __post_init__(self):
        _finite("mean", self.mu, "TruncatedNormal")
        _positive("std", self.sigma, "TruncatedNormal")
        _ordered(self.lower, self.upper, "TruncatedNormal")
        a = (self.lower - self.mu) / self.sigma
        b = (self.upper - self.mu) / self.sigma
        _freeze(self, stats.truncnorm(a, b, loc=self.mu, scale=self.sigma))
        z = _normal_mass(a, np.array(b - a)) if np.isfinite(a) else stats.norm.cdf(b)
        object.__setattr__(self, "_mass", float(z))

    # scipy's truncnorm loses the tails (ppf(1e-18) returns the bound itself, to_z(bound+tiny)
    # is 0): the tails are measured from the nearest bound, ``x - lower`` kept exact.
    def _side(self, upper: bool):
        """(standardized bound on this side seen as a lower bound, sign)."""
        if upper:
            return -(self.upper - self.mu) / self.sigma, -1.0
        return (self.lower - self.mu) / self.sigma, 1.0

    def _tail(self, x, upper: bool):
        a, sgn = self._side(upper)
        x = np.clip(np.asarray(x, dtype=float), self.lower, self.upper)
        if not np.isfinite(a):
            return stats.norm.cdf(sgn * (x - self.mu) / self.sigma) / self._mass
        bound = self.upper if upper else self.lower
        delta = np.maximum(sgn * (x - bound) / self.sigma, 0.0)
        return np.minimum(_normal_mass(a, delta) / self._mass, 1.0)

    def _tail_inv(self, q, upper: bool):
        a, sgn = self._side(upper)
        t = np.asarray(q, dtype=float) * self._mass
        if not np.isfinite(a):
            return self.mu + sgn * self.sigma * stats.norm.ppf(t)
        bound = self.upper if upper else self.lower
        return bound + sgn * self.sigma * _normal_mass_inv(a, t)

    def cdf(self, x):
        return self._tail(x, False)

    def sf(self, x):
        return self._tail(x, True)

    def ppf(self, q):
        q = np.asarray(q, dtype=float)
        return np.where(q <= 0.5, self._tail_inv(np.minimum(q, 0.5), False),
                        self._tail_inv(np.maximum(1.0 - q, 0.0), True))

    def isf(self, q):
        q = np.asarray(q, dtype=float)
        return np.where(q <= 0.5, self._tail_inv(np.minimum(q, 0.5), True),
                        self._tail_inv(np.maximum(1.0 - q, 0.0), False))


@dataclass(frozen=True)
class LogNormal(Distribution):
    """Lognormal given by the mean and std of the variable itself (Dakota's convention)."""

    mu: float
    sigma: float

    def __post_init__(self):
        m = _positive("mean", self.mu, "LogNormal")
        s = _positive("std", self.sigma, "LogNormal")
        zeta2 = math.log1p((s / m) ** 2)
        lam = math.log(m) - 0.5 * zeta2
        _freeze(self, stats.lognorm(s=math.sqrt(zeta2), scale=math.exp(lam)))


@dataclass(frozen=True)
class Uniform(Distribution):
    """Uniform on [lower, upper]. Its std is derived from the bounds: (upper-lower)/sqrt(12)."""

    lower: float
    upper: float

    def __post_init__(self):
        lo, hi = _ordered(self.lower, self.upper, "Uniform")
        _finite("lower", lo, "Uniform")
        _finite("upper", hi, "Uniform")
        _freeze(self, stats.uniform(loc=lo, scale=hi - lo))

    # sf/isf measured from the upper bound: scipy's 1 - F loses the upper tail
    def sf(self, x):
        return np.clip((self.upper - np.asarray(x, dtype=float)) / (self.upper - self.lower),
                       0.0, 1.0)

    def isf(self, q):
        return self.upper - np.asarray(q, dtype=float) * (self.upper - self.lower)


@dataclass(frozen=True)
class LogUniform(Distribution):
    """Log-uniform on [lower, upper], 0 < lower < upper."""

    lower: float
    upper: float

    def __post_init__(self):
        _positive("lower", self.lower, "LogUniform")
        _ordered(self.lower, self.upper, "LogUniform")
        _freeze(self, stats.loguniform(self.lower, self.upper))


@dataclass(frozen=True)
class Beta(Distribution):
    """Beta(alpha, beta) scaled to [lower, upper]."""

    alpha: float
    beta: float
    lower: float = 0.0
    upper: float = 1.0

    def __post_init__(self):
        _positive("alpha", self.alpha, "Beta")
        _positive("beta", self.beta, "Beta")
        lo, hi = _ordered(self.lower, self.upper, "Beta")
        _freeze(self, stats.beta(self.alpha, self.beta, loc=lo, scale=hi - lo))
        object.__setattr__(self, "_mirror", stats.beta(self.beta, self.alpha))

    # upper tail through the mirrored Beta(beta, alpha) of (upper - x) / width
    def sf(self, x):
        w = self.upper - self.lower
        return self._mirror.cdf(np.clip((self.upper - np.asarray(x, dtype=float)) / w, 0, 1))

    def isf(self, q):
        return self.upper - (self.upper - self.lower) * self._mirror.ppf(q)


@dataclass(frozen=True)
class Gamma(Distribution):
    """Gamma with shape ``alpha`` and scale ``beta`` (mean alpha*beta)."""

    alpha: float
    beta: float

    def __post_init__(self):
        _positive("alpha", self.alpha, "Gamma")
        _positive("beta", self.beta, "Gamma")
        _freeze(self, stats.gamma(self.alpha, scale=self.beta))


@dataclass(frozen=True)
class Exponential(Distribution):
    """Exponential with scale ``beta`` (mean beta)."""

    beta: float

    def __post_init__(self):
        _positive("beta", self.beta, "Exponential")
        _freeze(self, stats.expon(scale=self.beta))


@dataclass(frozen=True)
class Gumbel(Distribution):
    """Gumbel (largest extreme value) with Dakota's alpha (1/scale) and beta (location)."""

    alpha: float
    beta: float

    def __post_init__(self):
        _positive("alpha", self.alpha, "Gumbel")
        _finite("beta", self.beta, "Gumbel")
        _freeze(self, stats.gumbel_r(loc=self.beta, scale=1.0 / self.alpha))


@dataclass(frozen=True)
class Weibull(Distribution):
    """Weibull with shape ``alpha`` and scale ``beta``."""

    alpha: float
    beta: float

    def __post_init__(self):
        _positive("alpha", self.alpha, "Weibull")
        _positive("beta", self.beta, "Weibull")
        _freeze(self, stats.weibull_min(self.alpha, scale=self.beta))


@dataclass(frozen=True)
class Triangular(Distribution):
    """Triangular on [lower, upper] with mode ``mode``."""

    mode: float
    lower: float
    upper: float

    def __post_init__(self):
        lo, hi = _ordered(self.lower, self.upper, "Triangular")
        _finite("mode", self.mode, "Triangular")
        if not (lo <= float(self.mode) <= hi):
            raise ParameterError(
                f"Triangular: mode must lie in [lower, upper], got mode={self.mode!r}, "
                f"lower={lo!r}, upper={hi!r}"
            )
        _freeze(self, stats.triang((self.mode - lo) / (hi - lo), loc=lo, scale=hi - lo))
        object.__setattr__(self, "_mirror", stats.triang((hi - self.mode) / (hi - lo)))

    # upper tail through the mirrored triangle of (upper - x) / width
    def sf(self, x):
        w = self.upper - self.lower
        return self._mirror.cdf(np.clip((self.upper - np.asarray(x, dtype=float)) / w, 0, 1))

    def isf(self, q):
        return self.upper - (self.upper - self.lower) * self._mirror.ppf(q)


@dataclass(frozen=True)
class Interval(Distribution):
    """Epistemic variable: intervals ``[(lo_1, hi_1), ...]`` with basic probability assignments.

    Parameters
    ----------
    intervals : sequence of (lower, upper) pairs; they may overlap or nest.
    bpa : sequence of weights (one per interval), each > 0, summing to 1 (within 1e-8).
        Default: one interval with BPA 1.

    As a density (for sampling, u-space transforms, moments) the variable is the BPA-weighted
    mixture of uniform densities over the intervals.
    """

    intervals: tuple
    bpa: tuple | None = None

    def __post_init__(self):
        try:
            iv = np.array(self.intervals, dtype=float).reshape(-1, 2)
        except (TypeError, ValueError):
            raise ParameterError(
                f"Interval: intervals must be (lower, upper) pairs, got {self.intervals!r}"
            ) from None
        if iv.shape[0] == 0:
            raise ParameterError("Interval: at least one interval is needed")
        for lo, hi in iv:
            _finite("lower", lo, "Interval")
            _finite("upper", hi, "Interval")
            _ordered(lo, hi, "Interval")
        if self.bpa is None:
            w = np.full(iv.shape[0], 1.0 / iv.shape[0])
        else:
            w = np.array(self.bpa, dtype=float).ravel()
            if w.shape[0] != iv.shape[0]:
                raise ParameterError(
                    f"Interval: {iv.shape[0]} intervals but {w.shape[0]} BPA values"
                )
            if np.any(~np.isfinite(w)) or np.any(w <= 0):
                raise ParameterError(f"Interval: BPA values must be > 0, got {w.tolist()}")
            if abs(w.sum() - 1.0) > 1e-8:
                raise ParameterError(f"Interval: BPA values must sum to 1, got {w.sum()!r}")
        object.__setattr__(self, "intervals", tuple(map(tuple, iv.tolist())))
        object.__setattr__(self, "bpa", tuple(w.tolist()))
        # piecewise-linear mixture CDF on the sorted breakpoints
        knots = np.unique(iv.ravel())
        dens = np.zeros(knots.size - 1)
        for (lo, hi), wk in zip(iv, w, strict=True):
            inside = (knots[:-1] >= lo) & (knots[1:] <= hi)
            dens[inside] += wk / (hi - lo)
        cdf = np.concatenate([[0.0], np.cumsum(dens * np.diff(knots))])
        cdf /= cdf[-1]
        _freeze(self, None)
        object.__setattr__(self, "_knots", knots)
        object.__setattr__(self, "_dens", dens)
        object.__setattr__(self, "_cdfk", cdf)

    @property
    def dist(self):
        return self

    @property
    def kind(self) -> str:
        return "interval"

    @property
    def bounds(self) -> tuple[float, float]:
        return float(self._knots[0]), float(self._knots[-1])

    @property
    def mean(self) -> float:
        iv = np.array(self.intervals)
        return float(np.dot(self.bpa, iv.mean(axis=1)))

    @property
    def std(self) -> float:
        iv = np.array(self.intervals)
        m2 = np.dot(self.bpa, (iv[:, 0] ** 2 + iv[:, 0] * iv[:, 1] + iv[:, 1] ** 2) / 3.0)
        return float(np.sqrt(max(m2 - self.mean**2, 0.0)))

    def cdf(self, x):
        return np.interp(x, self._knots, self._cdfk, left=0.0, right=1.0)

    # the upper tail is measured from the knot above (exact near the upper bound)
    def sf(self, x):
        x = np.asarray(x, dtype=float)
        t, s = self._knots, 1.0 - self._cdfk
        k = np.clip(np.searchsorted(t, x, side="right") - 1, 0, self._dens.size - 1)
        out = s[k + 1] + (t[k + 1] - x) * self._dens[k]
        return np.where(x < t[0], 1.0, np.where(x >= t[-1], 0.0, out))

    def isf(self, q):
        q = np.asarray(q, dtype=float)
        t, s = self._knots, 1.0 - self._cdfk
        # segment k with s[k+1] <= q < s[k] (s decreasing); flat pieces are skipped
        k = np.clip(s.size - 1 - np.searchsorted(s[::-1], q, side="right"), 0, s.size - 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            out = t[k + 1] - (q - s[k + 1]) / self._dens[k]
        return np.where((q < 0) | (q > 1), np.nan, out)

    def ppf(self, q):
        q = np.asarray(q, dtype=float)
        c, t = self._cdfk, self._knots
        # segment k with c[k] < q <= c[k+1]: flat pieces (gaps between intervals) are skipped
        k = np.clip(np.searchsorted(c, q, side="left") - 1, 0, c.size - 2)
        out = t[k] + (q - c[k]) / (c[k + 1] - c[k]) * (t[k + 1] - t[k])
        return np.where((q < 0) | (q > 1), np.nan, out)

    def pdf(self, x):
        x = np.asarray(x, dtype=float)
        k = np.clip(np.searchsorted(self._knots, x, side="right") - 1, 0, self._dens.size - 1)
        inside = (x >= self._knots[0]) & (x <= self._knots[-1])
        return np.where(inside, self._dens[k], 0.0)

    def logpdf(self, x):
        with np.errstate(divide="ignore"):
            return np.log(self.pdf(x))

    def rvs(self, size, seed: SeedLike = None):
        return self.ppf(as_generator(seed).random(size))

    def describe(self) -> dict:
        return {"kind": "interval", "intervals": list(self.intervals), "bpa": list(self.bpa)}


DISTRIBUTIONS: dict[str, type[Distribution]] = {
    "normal": Normal,
    "gaussian": Normal,
    "truncated_normal": TruncatedNormal,
    "lognormal": LogNormal,
    "uniform": Uniform,
    "loguniform": LogUniform,
    "beta": Beta,
    "gamma": Gamma,
    "exponential": Exponential,
    "gumbel": Gumbel,
    "weibull": Weibull,
    "triangular": Triangular,
    "interval": Interval,
}

_ALIASES = {
    "mean": "mu",
    "std": "sigma",
    "std_deviation": "sigma",
    "lower_bound": "lower",
    "upper_bound": "upper",
}


def make_distribution(kind: str, **params) -> Distribution:
    """Build a distribution from its name and keyword parameters.

    ``mean``/``std`` are accepted for ``mu``/``sigma``; ``lower_bound``/``upper_bound`` for
    ``lower``/``upper``. An unknown kind raises :class:`ParameterError` naming the valid ones.
    """
    key = kind.strip().lower().replace("-", "_").replace(" ", "_")
    if key not in DISTRIBUTIONS:
        import difflib

        close = difflib.get_close_matches(key, DISTRIBUTIONS, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ParameterError(
            f"unknown distribution {kind!r}{hint}; valid: {', '.join(sorted(DISTRIBUTIONS))}"
        )
    cls = DISTRIBUTIONS[key]
    kwargs = {_ALIASES.get(k, k): v for k, v in params.items()}
    try:
        return cls(**kwargs)
    except TypeError as exc:
        import inspect

        names = [p for p in inspect.signature(cls).parameters]
        raise ParameterError(
            f"distribution {kind!r} takes {', '.join(names)}; got {', '.join(params)}"
        ) from exc


def _bivariate_corr(d1: Distribution, d2: Distribution, rho0: float, z, w) -> float:
    """Correlation of (F1^-1(Phi(z1)), F2^-1(Phi(z2))) when corr(z1, z2) = rho0."""
    z1 = z[:, 0]
    z2 = rho0 * z[:, 0] + math.sqrt(max(1.0 - rho0 * rho0, 0.0)) * z[:, 1]
    x1 = d1.from_z(z1)
    x2 = d2.from_z(z2)
    return float(np.sum(w * (x1 - d1.mean) * (x2 - d2.mean)) / (d1.std * d2.std))


def nataf_correlation(distributions, correlation, n_quad: int = 32) -> np.ndarray:
    """Correlation matrix of the normal scores (Nataf) equivalent to an x-space correlation.

    For every pair the equation ``corr(x_i, x_j) = R_ij`` is solved for the normal-score
    correlation by Gauss-Hermite quadrature (``n_quad`` points per axis) and root finding.
    Pairs of normals keep ``R_ij``. Raises :class:`ParameterError` when a requested
    correlation cannot be reached with these marginals.
    """
    from scipy.optimize import brentq

    r = np.array(correlation, dtype=float)
    t, wt = np.polynomial.hermite_e.hermegauss(n_quad)
    wt = wt / wt.sum()
    z = np.array(np.meshgrid(t, t, indexing="ij")).reshape(2, -1).T
    w = np.outer(wt, wt).ravel()
    r0 = np.eye(r.shape[0])
    dists = list(distributions)
    for i in range(r.shape[0]):
        for j in range(i + 1, r.shape[0]):
            rij = r[i, j]
            if rij == 0.0:
                continue
            di, dj = dists[i], dists[j]
            if isinstance(di, Normal) and isinstance(dj, Normal):
                r0[i, j] = r0[j, i] = rij
                continue
            lo = _bivariate_corr(di, dj, -0.9999, z, w)
            hi = _bivariate_corr(di, dj, 0.9999, z, w)
            if not (lo <= rij <= hi):
                raise ParameterError(
                    f"correlation {rij} between parameters {i} and {j} is not reachable with "
                    f"their marginals (range [{lo:.4f}, {hi:.4f}])"
                )
            val = brentq(
                lambda q, a=di, b=dj, t=rij: _bivariate_corr(a, b, q, z, w) - t,
                -0.9999,
                0.9999,
                xtol=1e-12,
            )
            r0[i, j] = r0[j, i] = val
    return r0


@dataclass(frozen=True)
class ParameterSpace:
    """An ordered set of named uncertain parameters, independent or correlated.

    Parameters
    ----------
    parameters : mapping name -> Distribution, or iterable of (name, Distribution)
    correlation : array (d, d), optional
        Correlation matrix of the parameters themselves (x-space, Pearson), symmetric, unit
        diagonal, positive definite. Sampling and the u-space transforms use the Nataf model
        (Gaussian copula) with the equivalent normal-score correlation :attr:`nataf`.

    Points are arrays of shape ``(n, d)`` with columns in the order of :attr:`names`.
    """

    parameters: Mapping[str, Distribution] | Iterable[tuple[str, Distribution]]
    correlation: np.ndarray | None = field(default=None, compare=False)
    _items: tuple[tuple[str, Distribution], ...] = field(init=False, repr=False)

    def __post_init__(self):
        items = (
            list(self.parameters.items())
            if isinstance(self.parameters, Mapping)
            else list(self.parameters)
        )
        seen = set()
        for name, dist in items:
            if not isinstance(name, str) or not name:
                raise ParameterError(f"parameter names must be non-empty strings, got {name!r}")
            if name in seen:
                raise ParameterError(f"parameter {name!r} defined twice")
            if not isinstance(dist, Distribution):
                raise ParameterError(
                    f"parameter {name!r}: expected a rotoruq distribution, got {type(dist)}"
                )
            seen.add(name)
        if not items:
            raise ParameterError("a ParameterSpace needs at least one parameter")
        object.__setattr__(self, "_items", tuple(items))
        object.__setattr__(self, "parameters", dict(items))
        chol = None
        r0 = None
        if self.correlation is not None:
            d = len(items)
            try:
                r = np.array(self.correlation, dtype=float)
            except (TypeError, ValueError):
                raise ParameterError(
                    f"correlation must be a ({d}, {d}) matrix of numbers, got "
                    f"{self.correlation!r}") from None
            if r.shape != (d, d):
                raise ParameterError(f"correlation must have shape ({d}, {d}), got {r.shape}")
            if not np.all(np.isfinite(r)) or not np.allclose(r, r.T, atol=1e-12):
                raise ParameterError("correlation matrix must be finite and symmetric")
            if not np.allclose(np.diag(r), 1.0) or np.any(np.abs(r) > 1.0):
                raise ParameterError("correlation matrix needs a unit diagonal and |r_ij| <= 1")
            if np.allclose(r, np.eye(d)):
                r = None
            else:
                try:
                    np.linalg.cholesky(r)
                except np.linalg.LinAlgError:
                    raise ParameterError("correlation matrix is not positive definite") from None
                r0 = nataf_correlation([dd for _, dd in items], r)
                try:
                    chol = np.linalg.cholesky(r0)
                except np.linalg.LinAlgError:
                    raise ParameterError(
                        "the Nataf normal-score correlation is not positive definite for these "
                        "marginals; reduce the correlations"
                    ) from None
            object.__setattr__(self, "correlation", r)
        object.__setattr__(self, "_nataf", r0)
        object.__setattr__(self, "_chol", chol)

    # --- description -----------------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        return tuple(n for n, _ in self._items)

    @property
    def distributions(self) -> tuple[Distribution, ...]:
        return tuple(d for _, d in self._items)

    @property
    def dim(self) -> int:
        return len(self._items)

    def __len__(self) -> int:
        return self.dim

    def __getitem__(self, name: str) -> Distribution:
        try:
            return self.parameters[name]  # type: ignore[index]
        except KeyError:
            raise ParameterError(
                f"unknown parameter {name!r}; this space has {', '.join(self.names)}"
            ) from None

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise ParameterError(
                f"unknown parameter {name!r}; this space has {', '.join(self.names)}"
            ) from None

    @property
    def mean(self) -> np.ndarray:
        """Means, shape (d,)."""
        return np.array([d.mean for d in self.distributions])

    @property
    def std(self) -> np.ndarray:
        """Standard deviations, shape (d,)."""
        return np.array([d.std for d in self.distributions])

    @property
    def bounds(self) -> np.ndarray:
        """Support bounds, shape (d, 2) (may contain +-inf)."""
        return np.array([d.bounds for d in self.distributions])

    @property
    def correlated(self) -> bool:
        return self.correlation is not None

    @property
    def correlation_matrix(self) -> np.ndarray:
        """x-space correlation, shape (d, d) (identity when independent)."""
        return np.eye(self.dim) if self.correlation is None else np.array(self.correlation)

    @property
    def covariance(self) -> np.ndarray:
        """x-space covariance diag(std) R diag(std), shape (d, d)."""
        s = self.std
        return self.correlation_matrix * np.outer(s, s)

    @property
    def nataf(self) -> np.ndarray:
        """Normal-score correlation R0 of the Nataf model, shape (d, d)."""
        return np.eye(self.dim) if self._nataf is None else np.array(self._nataf)

    @property
    def epistemic(self) -> tuple[str, ...]:
        """Names of the :class:`Interval` (epistemic) parameters."""
        return tuple(n for n, d in self._items if isinstance(d, Interval))

    def replace(self, **dists: Distribution) -> ParameterSpace:
        """A new space with some distributions replaced (names must exist; correlation kept)."""
        for name in dists:
            self.index(name)
        return ParameterSpace(
            [(n, dists.get(n, d)) for n, d in self._items], correlation=self.correlation
        )

    def subset(self, names: Iterable[str]) -> ParameterSpace:
        names = list(names)
        corr = None
        if self.correlation is not None:
            idx = [self.index(n) for n in names]
            corr = self.correlation[np.ix_(idx, idx)]
        return ParameterSpace([(n, self[n]) for n in names], correlation=corr)

    # --- transforms ------------------------------------------------------------------------
    def _check(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if x.ndim == 1:
            x = x[None, :]
        if x.ndim != 2 or x.shape[1] != self.dim:
            raise ParameterError(
                f"points must have shape (n, {self.dim}) for parameters {self.names}, "
                f"got {x.shape}"
            )
        return x

    def from_unit(self, q) -> np.ndarray:
        """Map probabilities in (0, 1)^d (shape (n, d)) to parameter values by marginal ppf."""
        q = self._check(q)
        return np.column_stack([d.ppf(q[:, j]) for j, d in enumerate(self.distributions)])

    def to_unit(self, x) -> np.ndarray:
        """Map parameter values to marginal CDF values in [0, 1]^d."""
        x = self._check(x)
        return np.column_stack([d.cdf(x[:, j]) for j, d in enumerate(self.distributions)])

    def to_z(self, x) -> np.ndarray:
        """Marginal normal scores z = Phi^-1(F_i(x_i)), shape (n, d) (correlated if the space
        is). Exact in both tails (see :meth:`Distribution.to_z`), |z| <= 37.5."""
        x = self._check(x)
        return np.column_stack([d.to_z(x[:, j]) for j, d in enumerate(self.distributions)])

    def from_z(self, z) -> np.ndarray:
        """Inverse of :meth:`to_z`: ``x_i = F_i^-1(Phi(z_i))``, exact in both tails."""
        z = self._check(z)
        return np.column_stack([d.from_z(z[:, j]) for j, d in enumerate(self.distributions)])

    def to_u(self, x) -> np.ndarray:
        """Transform to independent standard normal space, shape (n, d).

        Independent: u = Phi^-1(F(x)). Correlated: Nataf, u = L^-1 z with L L^T = R0.
        Both tails are exact to |u| = 37 (the upper tail goes through the survival function);
        beyond a finite support bound, u saturates at +-37.5.
        """
        z = self.to_z(x)
        if self._chol is None:
            return z
        from scipy.linalg import solve_triangular

        return solve_triangular(self._chol, z.T, lower=True).T

    def from_u(self, u) -> np.ndarray:
        """Inverse of :meth:`to_u`."""
        u = self._check(u)
        if self._chol is not None:
            u = u @ self._chol.T
        return self.from_z(u)

    def logpdf(self, x) -> np.ndarray:
        """Joint log density, shape (n,); -inf outside the support.

        Sum of the marginal log densities, plus the Gaussian-copula term when correlated.
        """
        x = self._check(x)
        out = np.zeros(x.shape[0])
        for j, d in enumerate(self.distributions):
            out += d.logpdf(x[:, j])
        if self._chol is not None:
            with np.errstate(invalid="ignore"):
                z = self.to_z(x)
                r0inv = np.linalg.inv(self._nataf)
                quad = np.einsum("ni,ij,nj->n", z, r0inv - np.eye(self.dim), z)
                logdet = 2.0 * np.sum(np.log(np.diag(self._chol)))
                out = out - 0.5 * quad - 0.5 * logdet
        return np.where(np.isnan(out), -np.inf, out)

    def contains(self, x) -> np.ndarray:
        """Boolean mask (n,) of points inside the support bounds."""
        x = self._check(x)
        b = self.bounds
        return np.all((x >= b[:, 0]) & (x <= b[:, 1]), axis=1)

    # --- sampling --------------------------------------------------------------------------
    def sample(self, n: int, seed: SeedLike = None, method: str = "lhs") -> np.ndarray:
        """Draw ``n`` points, shape (n, d).

        method : "lhs" (Latin hypercube, scipy.stats.qmc), "mc" / "random" (plain Monte Carlo),
            "sobol" or "halton" (scrambled low-discrepancy sequences). With correlations the
            design's normal scores are correlated through the Nataf factor, so an LHS design
            is stratified in u-space rather than in each marginal.
        """
        n = int(n)
        if n < 1:
            raise ParameterError(f"number of samples must be >= 1, got {n}")
        rng = as_generator(seed)
        q = unit_design(n, self.dim, rng, method)
        if self._chol is not None:
            # correlate the normal scores of the design (Nataf); marginals keep their law
            return self.from_u(stats.norm.ppf(np.clip(q, 1e-16, 1 - 1e-16)))
        return self.from_unit(q)


def unit_design(n: int, d: int, seed: SeedLike, method: str = "lhs") -> np.ndarray:
    """Points in (0, 1)^d, shape (n, d), from the named design."""
    rng = as_generator(seed)
    m = method.lower()
    if m in ("mc", "random", "monte_carlo"):
        return rng.random((n, d))
    if m in ("lhs", "latin", "latin_hypercube"):
        return qmc.LatinHypercube(d=d, seed=rng).random(n)
    if m == "sobol":
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # non power-of-2 balance warning
            return qmc.Sobol(d=d, scramble=True, seed=rng).random(n)
    if m == "halton":
        return qmc.Halton(d=d, scramble=True, seed=rng).random(n)
    raise ParameterError(f"unknown sampling method {method!r}; valid: lhs, mc, sobol, halton")
