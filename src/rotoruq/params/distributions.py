"""Marginal distributions of uncertain parameters, backed by :mod:`scipy.stats`.

A distribution is a small frozen object with ``mean``, ``std`` (of the variable itself),
``bounds`` and the vectorized ``ppf``/``cdf``/``sf``/``isf``/``pdf``/``logpdf`` of its scipy
counterpart, plus the exact normal-score maps ``to_z``/``from_z`` used by every u-space method.
Parameters use the words of the study files: ``Normal(mean, std)``, ``LogNormal(mean, std)``
(mean and std of the variable, not of its logarithm: Dakota's convention), ``Uniform(lower,
upper)``, ``Beta(alpha, beta, lower, upper)``, ``Triangular(mode, lower, upper)``...
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy import stats

from .._rng import SeedLike, as_generator
from ..errors import ParameterError


def _number(name: str, value: Any, what: str) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{what}: {name} must be a number, got {value!r}") from None


def _positive(name: str, value: Any, what: str) -> float:
    value = _number(name, value, what)
    if not np.isfinite(value) or value <= 0:
        raise ParameterError(f"{what}: {name} must be a finite number > 0, got {value!r}")
    return value


def _finite(name: str, value: Any, what: str) -> float:
    value = _number(name, value, what)
    if not np.isfinite(value):
        raise ParameterError(f"{what}: {name} must be finite, got {value!r}")
    return value


def _ordered(lower: Any, upper: Any, what: str) -> tuple[float, float]:
    lower, upper = _number("lower", lower, what), _number("upper", upper, what)
    if not (lower < upper):
        raise ParameterError(
            f"{what}: bounds must satisfy lower < upper, got lower={lower!r}, upper={upper!r}"
        )
    return lower, upper


class Distribution:
    """Base class: a frozen scipy distribution plus the parameters that define it.

    Subclasses are frozen dataclasses whose fields are the defining parameters; they set the
    scipy distribution with ``_freeze`` in ``__post_init__``. All methods are vectorized:
    arguments and results have the same shape. ``mean`` and ``std`` are the moments of the
    variable (a field for :class:`Normal` and :class:`LogNormal`, derived for the others;
    :class:`TruncatedNormal`'s fields are those of the parent normal and its moments are
    :attr:`moments`).
    """

    if TYPE_CHECKING:
        _frozen: Any

        @property
        def mean(self) -> float: ...

        @property
        def std(self) -> float: ...

    @property
    def dist(self) -> Any:
        """The frozen :mod:`scipy.stats` distribution."""
        return self._frozen

    @property
    def kind(self) -> str:
        """Lower-case name, as in study files (``"normal"``, ``"truncatednormal"``...)."""
        return type(self).__name__.lower()

    @property
    def moments(self) -> tuple[float, float]:
        """(mean, std) of the variable itself."""
        return float(self.dist.mean()), float(self.dist.std())

    @property
    def bounds(self) -> tuple[float, float]:
        """Support of the distribution (may be infinite)."""
        lo, hi = self.dist.support()
        return float(lo), float(hi)

    def ppf(self, q: Any) -> np.ndarray:
        """Quantile function F^-1(q), shape of ``q``."""
        return self.dist.ppf(q)

    def cdf(self, x: Any) -> np.ndarray:
        """Cumulative distribution function F(x), shape of ``x``."""
        return self.dist.cdf(x)

    def sf(self, x: Any) -> np.ndarray:
        """Survival function 1 - F(x), computed without cancellation in the upper tail."""
        return self.dist.sf(x)

    def isf(self, q: Any) -> np.ndarray:
        """Inverse survival function: x with sf(x) = q."""
        return self.dist.isf(q)

    def from_z(self, z: Any) -> np.ndarray:
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

    def to_z(self, x: Any) -> np.ndarray:
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

    def pdf(self, x: Any) -> np.ndarray:
        """Probability density, shape of ``x``."""
        return self.dist.pdf(x)

    def logpdf(self, x: Any) -> np.ndarray:
        """Log density (-inf outside the support), shape of ``x``."""
        return self.dist.logpdf(x)

    def rvs(self, size: int | tuple[int, ...], *, seed: SeedLike = None) -> np.ndarray:
        """Independent random values, array of shape ``size``."""
        return self.dist.rvs(size=size, random_state=as_generator(seed))

    def describe(self) -> dict[str, Any]:
        """Defining parameters as a plain dict, ``{"kind": ..., <field>: value}``: the keys a
        study file uses, so ``make_distribution(**d.describe())`` rebuilds it."""
        out: dict[str, Any] = {"kind": self.kind}
        for k, v in self.__dict__.items():
            if not k.startswith("_"):
                out[k] = v
        return out


class _DerivedMoments(Distribution):
    """Distributions whose mean and std follow from their parameters."""

    @property
    def mean(self) -> float:
        """Mean of the variable."""
        return self.moments[0]

    @property
    def std(self) -> float:
        """Standard deviation of the variable."""
        return self.moments[1]


def _freeze(obj: Distribution, frozen: Any) -> None:
    object.__setattr__(obj, "_frozen", frozen)


@dataclass(frozen=True)
class Normal(Distribution):
    """Normal (Gaussian) distribution N(mean, std^2)."""

    mean: float
    std: float

    def __post_init__(self) -> None:
        _finite("mean", self.mean, "Normal")
        _positive("std", self.std, "Normal")
        _freeze(self, stats.norm(loc=self.mean, scale=self.std))

    @property
    def moments(self) -> tuple[float, float]:
        return float(self.mean), float(self.std)


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
    """Normal(mean, std) truncated to [lower, upper] (either may be infinite).

    ``mean`` and ``std`` are those of the parent normal (Dakota's convention); the moments of
    the truncated variable are :attr:`moments`.
    """

    mean: float
    std: float
    lower: float = -math.inf
    upper: float = math.inf
    _mass: float = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        _finite("mean", self.mean, "TruncatedNormal")
        _positive("std", self.std, "TruncatedNormal")
        _ordered(self.lower, self.upper, "TruncatedNormal")
        a = (self.lower - self.mean) / self.std
        b = (self.upper - self.mean) / self.std
        _freeze(self, stats.truncnorm(a, b, loc=self.mean, scale=self.std))
        z = _normal_mass(a, np.array(b - a)) if np.isfinite(a) else stats.norm.cdf(b)
        object.__setattr__(self, "_mass", float(z))

    @property
    def kind(self) -> str:
        return "truncated_normal"

    # scipy's truncnorm loses the tails (ppf(1e-18) returns the bound itself, to_z(bound+tiny)
    # is 0): the tails are measured from the nearest bound, ``x - lower`` kept exact.
    def _side(self, upper: bool):
        """(standardized bound on this side seen as a lower bound, sign)."""
        if upper:
            return -(self.upper - self.mean) / self.std, -1.0
        return (self.lower - self.mean) / self.std, 1.0

    def _tail(self, x, upper: bool):
        a, sgn = self._side(upper)
        x = np.clip(np.asarray(x, dtype=float), self.lower, self.upper)
        if not np.isfinite(a):
            return stats.norm.cdf(sgn * (x - self.mean) / self.std) / self._mass
        bound = self.upper if upper else self.lower
        delta = np.maximum(sgn * (x - bound) / self.std, 0.0)
        return np.minimum(_normal_mass(a, delta) / self._mass, 1.0)

    def _tail_inv(self, q, upper: bool):
        a, sgn = self._side(upper)
        t = np.asarray(q, dtype=float) * self._mass
        if not np.isfinite(a):
            return self.mean + sgn * self.std * stats.norm.ppf(t)
        bound = self.upper if upper else self.lower
        return bound + sgn * self.std * _normal_mass_inv(a, t)

    def cdf(self, x: Any) -> np.ndarray:
        return self._tail(x, False)

    def sf(self, x: Any) -> np.ndarray:
        return self._tail(x, True)

    def ppf(self, q: Any) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        return np.where(q <= 0.5, self._tail_inv(np.minimum(q, 0.5), False),
                        self._tail_inv(np.maximum(1.0 - q, 0.0), True))

    def isf(self, q: Any) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        return np.where(q <= 0.5, self._tail_inv(np.minimum(q, 0.5), True),
                        self._tail_inv(np.maximum(1.0 - q, 0.0), False))


@dataclass(frozen=True)
class LogNormal(Distribution):
    """Lognormal given by the mean and std of the variable itself (Dakota's convention)."""

    mean: float
    std: float
    _log_mean: float = field(init=False, repr=False, compare=False)
    _log_std: float = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        m = _positive("mean", self.mean, "LogNormal")
        s = _positive("std", self.std, "LogNormal")
        zeta2 = math.log1p((s / m) ** 2)
        lam = math.log(m) - 0.5 * zeta2
        _freeze(self, stats.lognorm(s=math.sqrt(zeta2), scale=math.exp(lam)))
        object.__setattr__(self, "_log_mean", lam)
        object.__setattr__(self, "_log_std", math.sqrt(zeta2))

    @property
    def moments(self) -> tuple[float, float]:
        return float(self.mean), float(self.std)

    # the upper tail through the normal of log(x): scipy 1.11 computes lognorm.isf(q) as
    # ppf(1 - q), which is inf below q ~ 1e-17
    def sf(self, x: Any) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (np.log(np.maximum(x, 0.0)) - self._log_mean) / self._log_std
        return np.where(np.isnan(x), np.nan, stats.norm.sf(t))

    def isf(self, q: Any) -> np.ndarray:
        return np.exp(self._log_mean + self._log_std * stats.norm.isf(q))


@dataclass(frozen=True)
class Uniform(_DerivedMoments):
    """Uniform on [lower, upper]. Its std is derived from the bounds: (upper-lower)/sqrt(12)."""

    lower: float
    upper: float

    def __post_init__(self) -> None:
        lo, hi = _ordered(self.lower, self.upper, "Uniform")
        _finite("lower", lo, "Uniform")
        _finite("upper", hi, "Uniform")
        _freeze(self, stats.uniform(loc=lo, scale=hi - lo))

    # sf/isf measured from the upper bound: scipy's 1 - F loses the upper tail
    def sf(self, x: Any) -> np.ndarray:
        return np.clip((self.upper - np.asarray(x, dtype=float)) / (self.upper - self.lower),
                       0.0, 1.0)

    def isf(self, q: Any) -> np.ndarray:
        return self.upper - np.asarray(q, dtype=float) * (self.upper - self.lower)


@dataclass(frozen=True)
class LogUniform(_DerivedMoments):
    """Log-uniform on [lower, upper], 0 < lower < upper."""

    lower: float
    upper: float

    def __post_init__(self) -> None:
        _positive("lower", self.lower, "LogUniform")
        _ordered(self.lower, self.upper, "LogUniform")
        _freeze(self, stats.loguniform(self.lower, self.upper))


@dataclass(frozen=True)
class Beta(_DerivedMoments):
    """Beta(alpha, beta) scaled to [lower, upper]."""

    alpha: float
    beta: float
    lower: float = 0.0
    upper: float = 1.0
    _mirror: Any = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        _positive("alpha", self.alpha, "Beta")
        _positive("beta", self.beta, "Beta")
        lo, hi = _ordered(self.lower, self.upper, "Beta")
        _freeze(self, stats.beta(self.alpha, self.beta, loc=lo, scale=hi - lo))
        object.__setattr__(self, "_mirror", stats.beta(self.beta, self.alpha))

    # upper tail through the mirrored Beta(beta, alpha) of (upper - x) / width
    def sf(self, x: Any) -> np.ndarray:
        w = self.upper - self.lower
        return self._mirror.cdf(np.clip((self.upper - np.asarray(x, dtype=float)) / w, 0, 1))

    def isf(self, q: Any) -> np.ndarray:
        return self.upper - (self.upper - self.lower) * self._mirror.ppf(q)


@dataclass(frozen=True)
class Gamma(_DerivedMoments):
    """Gamma with shape ``alpha`` and scale ``beta`` (mean alpha*beta)."""

    alpha: float
    beta: float

    def __post_init__(self) -> None:
        _positive("alpha", self.alpha, "Gamma")
        _positive("beta", self.beta, "Gamma")
        _freeze(self, stats.gamma(self.alpha, scale=self.beta))


@dataclass(frozen=True)
class Exponential(_DerivedMoments):
    """Exponential with scale ``beta`` (mean beta)."""

    beta: float

    def __post_init__(self) -> None:
        _positive("beta", self.beta, "Exponential")
        _freeze(self, stats.expon(scale=self.beta))


@dataclass(frozen=True)
class Gumbel(_DerivedMoments):
    """Gumbel (largest extreme value) with Dakota's alpha (1/scale) and beta (location)."""

    alpha: float
    beta: float

    def __post_init__(self) -> None:
        _positive("alpha", self.alpha, "Gumbel")
        _finite("beta", self.beta, "Gumbel")
        _freeze(self, stats.gumbel_r(loc=self.beta, scale=1.0 / self.alpha))


@dataclass(frozen=True)
class Weibull(_DerivedMoments):
    """Weibull with shape ``alpha`` and scale ``beta``."""

    alpha: float
    beta: float

    def __post_init__(self) -> None:
        _positive("alpha", self.alpha, "Weibull")
        _positive("beta", self.beta, "Weibull")
        _freeze(self, stats.weibull_min(self.alpha, scale=self.beta))


@dataclass(frozen=True)
class Triangular(_DerivedMoments):
    """Triangular on [lower, upper] with mode ``mode``."""

    mode: float
    lower: float
    upper: float
    _mirror: Any = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
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
    def sf(self, x: Any) -> np.ndarray:
        w = self.upper - self.lower
        return self._mirror.cdf(np.clip((self.upper - np.asarray(x, dtype=float)) / w, 0, 1))

    def isf(self, q: Any) -> np.ndarray:
        return self.upper - (self.upper - self.lower) * self._mirror.ppf(q)
