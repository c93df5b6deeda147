"""Marginal distributions of uncertain parameters, backed by :mod:`scipy.stats`.

A distribution is a small frozen object with ``mean``, ``std`` (of the variable itself),
``bounds`` and the vectorized ``ppf``/``cdf``/``sf``/``isf``/``pdf``/``logpdf`` of its scipy
counterpart, plus the exact normal-score maps ``to_z``/``from_z`` used by every u-space method.
Parameters use the words of the study files and Dakota's: ``Normal(mean, std)``,
``LogNormal(mean, std)`` (mean and std of the variable, not of its logarithm: Dakota's
convention; also ``LogNormal(lambda_=, zeta=)`` and ``LogNormal(mean=, error_factor=)``),
``Uniform(lower, upper)``, ``Beta(alpha, beta, lower, upper)``, ``Triangular(mode, lower,
upper)``, ``Frechet(alpha, beta)``, ``HistogramBin(abscissas, counts)``... Every continuous
aleatory type of Dakota 6.24 has its class here, with Dakota's parameterisation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from .._docs import fill_doc
from .._lazy import lazy_module
from .._rng import SeedLike, as_generator
from ..errors import ParameterError

if TYPE_CHECKING:
    from scipy import stats
else:  # imported on first use: reading saved distributions (a report) never needs it
    stats = lazy_module("scipy.stats")


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

    Subclasses are frozen dataclasses whose fields are the defining parameters; they name the
    scipy distribution with ``_freeze`` in ``__post_init__`` (it is built on first use, so
    making a distribution does not import :mod:`scipy.stats`). All methods are vectorized:
    arguments and results have the same shape. ``mean`` and ``std`` are the moments of the
    variable (a field for :class:`Normal` and :class:`LogNormal`, derived for the others;
    :class:`TruncatedNormal`'s fields are those of the parent normal and its moments are
    :attr:`moments`).
    """

    if TYPE_CHECKING:
        _scipy: tuple[str, tuple[Any, ...], dict[str, Any]] | None

        @property
        def mean(self) -> float: ...

        @property
        def std(self) -> float: ...

    @property
    def dist(self) -> Any:
        """The frozen :mod:`scipy.stats` distribution (built on first use)."""
        frozen = self.__dict__.get("_frozen")
        if frozen is None and self._scipy is not None:
            family, args, kwargs = self._scipy
            frozen = getattr(stats, family)(*args, **kwargs)
            object.__setattr__(self, "_frozen", frozen)
        return frozen

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
        """Quantile function F^-1(q), shape of ``q``.

        Parameters
        ----------
        q : array_like
            Probabilities in [0, 1] (any shape).
        """
        return self.dist.ppf(q)

    def cdf(self, x: Any) -> np.ndarray:
        """Cumulative distribution function F(x), shape of ``x``.

        Parameters
        ----------
        x : array_like
            Values of the variable, in its units (any shape).
        """
        return self.dist.cdf(x)

    def sf(self, x: Any) -> np.ndarray:
        """Survival function 1 - F(x), computed without cancellation in the upper tail.

        Parameters
        ----------
        x : array_like
            Values of the variable, in its units (any shape); the result has its shape.
        """
        return self.dist.sf(x)

    def isf(self, q: Any) -> np.ndarray:
        """Inverse survival function: x with sf(x) = q.

        Parameters
        ----------
        q : array_like
            Upper-tail probabilities in [0, 1] (any shape); the result has its shape.
        """
        return self.dist.isf(q)

    def from_z(self, z: Any) -> np.ndarray:
        """Value with normal score ``z``: ``F^-1(Phi(z))``, exact in both tails.

        The lower tail goes through ``ppf(Phi(z))`` and the upper tail through
        ``isf(Phi(-z))``, so no probability is ever rounded to 1 (``Phi(8.3)`` is 1.0 in double
        precision, ``Phi(-37)`` = 5.7e-300 is not 0). Shape of ``z``.

        Parameters
        ----------
        z : array_like
            Standard normal scores (any shape).
        """
        z = np.asarray(z, dtype=float)
        lower = z <= 0
        with np.errstate(invalid="ignore"):
            lo = self.ppf(stats.norm.cdf(np.where(lower, z, 0.0)))
            hi = self.isf(stats.norm.sf(np.where(lower, 0.0, z)))
        return np.where(lower, lo, hi)

    def to_z(self, x: Any) -> np.ndarray:
        """Normal score ``Phi^-1(F(x))`` of values ``x``, exact in both tails.

        The smaller of the CDF and the survival function is inverted. Clipped to +-37.5
        (where the tail probability reaches the smallest normal double) at and beyond the
        support bounds; NaN stays NaN. Shape of ``x``.

        Parameters
        ----------
        x : array_like
            Values of the variable, in its units (any shape).
        """
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
        """Probability density (per unit of the variable), shape of ``x``.

        Parameters
        ----------
        x : array_like
            Values of the variable, in its units (any shape).
        """
        return self.dist.pdf(x)

    def logpdf(self, x: Any) -> np.ndarray:
        """Log density (-inf outside the support), shape of ``x``.

        Parameters
        ----------
        x : array_like
            Values of the variable, in its units (any shape).
        """
        return self.dist.logpdf(x)

    def rvs(self, size: int | tuple[int, ...], *, seed: SeedLike = None) -> np.ndarray:
        """Independent random values, array of shape ``size``.

        Parameters
        ----------
        size : int or tuple of int
            Shape of the result.
        seed : int, SeedSequence, Generator or None
            Random source (:func:`~rotoruq.as_generator`); None draws fresh entropy.
        """
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


def _freeze(obj: Distribution, family: str | None, *args: Any, **kwargs: Any) -> None:
    """Name ``obj``'s scipy distribution: ``scipy.stats.<family>(*args, **kwargs)``, built by
    :attr:`Distribution.dist` on first use (None: it has none)."""
    object.__setattr__(obj, "_scipy", None if family is None else (family, args, kwargs))


@dataclass(frozen=True)
class Normal(Distribution):
    """Normal (Gaussian) distribution N(mean, std^2).

    Parameters
    ----------
    mean : float
        Mean, in the variable's units.
    std : float
        Standard deviation (> 0), in the variable's units.
    """

    mean: float
    std: float

    def __post_init__(self) -> None:
        _finite("mean", self.mean, "Normal")
        _positive("std", self.std, "Normal")
        _freeze(self, "norm", loc=self.mean, scale=self.std)

    @property
    def moments(self) -> tuple[float, float]:
        return float(self.mean), float(self.std)

    @property
    def bounds(self) -> tuple[float, float]:
        return -math.inf, math.inf


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

    Parameters
    ----------
    mean : float
        Mean of the parent normal, in the variable's units.
    std : float
        Standard deviation (> 0) of the parent normal.
    lower, upper : float, optional
        Truncation bounds, ``lower < upper`` (default: -inf and +inf, no truncation).
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
        _freeze(self, "truncnorm", a, b, loc=self.mean, scale=self.std)
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


#: Phi^-1(0.95): Dakota's error factor is the 95th over the 50th percentile of a lognormal,
#: ``error_factor = exp(PHI_95 * zeta)`` (its manual rounds PHI_95 to 1.645; its code, and
#: real Dakota 6.24, use the exact quantile: tests/test_dakota_distributions.py).
PHI_95 = 1.6448536269514722  # float(scipy.stats.norm.ppf(0.95)), bit for bit (a test checks)

# LogNormal's three forms (Dakota's option_1, option_2, option_3) by the fields they give
_LOGNORMAL_FORMS = (("mean", "std"), ("mean", "error_factor"), ("lambda_", "zeta"))


def _study_key(name: str) -> str:
    """A field's study-file key (``lambda_`` is ``lambda`` in files and in describe())."""
    return name.rstrip("_")


@dataclass(frozen=True)
class LogNormal(Distribution):
    """Lognormal in any of Dakota's three forms, optionally truncated (Dakota's bounded
    lognormal).

    Give exactly one of

    * ``mean``, ``std``: mean and std of the variable itself (Dakota's ``means``,
      ``std_deviations``; the positional form ``LogNormal(mean, std)``);
    * ``mean``, ``error_factor``: Dakota's ``means``, ``error_factors`` with
      ``zeta = ln(error_factor) / Phi^-1(0.95)`` (:data:`PHI_95`; the 95th over the 50th
      percentile), ``error_factor > 1``;
    * ``lambda_``, ``zeta``: mean and std of ``ln x`` (Dakota's ``lambdas``, ``zetas``; the
      study-file and :meth:`describe` key is ``lambda``).

    The other fields are derived from the given ones (``mean = exp(lambda + zeta^2 / 2)``,
    ``std = mean sqrt(exp(zeta^2) - 1)``). ``lower`` (>= 0) and ``upper`` truncate the
    distribution like Dakota's ``lower_bounds``/``upper_bounds``: ``ln x`` is then the normal
    (lambda, zeta) truncated to [ln lower, ln upper], the fields still describe the parent
    lognormal (Dakota's convention, as for :class:`TruncatedNormal`) and :attr:`moments` are
    those of the truncated variable. :meth:`describe` gives the form that was given.

    Parameters
    ----------
    mean : float, optional
        Mean (> 0) of the (parent) variable, in its units.
    std : float, optional
        Standard deviation (> 0) of the (parent) variable.
    lambda_ : float, optional
        Mean of ``ln x``.
    zeta : float, optional
        Standard deviation (> 0) of ``ln x``.
    error_factor : float, optional
        The 95th over the 50th percentile (> 1), with ``mean``.
    lower, upper : float, optional
        Truncation bounds, ``0 <= lower < upper`` (default 0 and +inf: not truncated).

    Examples
    --------
    >>> d = LogNormal(lambda_=0.0, zeta=0.5)
    >>> round(d.mean, 6), round(d.std, 6)
    (1.133148, 0.603901)
    >>> d.describe()
    {'kind': 'lognormal', 'lambda': 0.0, 'zeta': 0.5}
    >>> round(float(LogNormal(mean=1.0, error_factor=3.0).zeta), 6)   # ln 3 / 1.6449
    0.667909
    """

    mean: float = math.nan
    std: float = math.nan
    lambda_: float = math.nan
    zeta: float = math.nan
    error_factor: float = math.nan
    lower: float = 0.0
    upper: float = math.inf
    _form: tuple[str, ...] = field(init=False, repr=False, compare=False)
    _log_mean: float = field(init=False, repr=False, compare=False)
    _log_std: float = field(init=False, repr=False, compare=False)
    _log: TruncatedNormal | None = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        what = "LogNormal"
        given = tuple(k for k in ("mean", "std", "lambda_", "zeta", "error_factor")
                      if not (isinstance(getattr(self, k), float) and math.isnan(getattr(self, k))))
        form = next((f for f in _LOGNORMAL_FORMS if set(f) == set(given)), None)
        if form is None:
            raise ParameterError(
                f"{what}: give mean and std, or mean and error_factor, or lambda and zeta "
                f"(Dakota's three forms); got {', '.join(map(_study_key, given)) or 'none'}")
        if form == ("mean", "std"):
            m = _positive("mean", self.mean, what)
            s = _positive("std", self.std, what)
            zeta2 = math.log1p((s / m) ** 2)
            lam = math.log(m) - 0.5 * zeta2
            zeta = math.sqrt(zeta2)
        else:
            if form == ("mean", "error_factor"):
                m = _positive("mean", self.mean, what)
                ef = _finite("error_factor", self.error_factor, what)
                if not ef > 1.0:
                    raise ParameterError(f"{what}: error_factor must be > 1, got {ef!r}")
                zeta = math.log(ef) / PHI_95
                lam = math.log(m) - 0.5 * zeta * zeta
            else:
                lam = _finite("lambda", self.lambda_, what)
                zeta = _positive("zeta", self.zeta, what)
                m = math.exp(lam + 0.5 * zeta * zeta)
                if not np.isfinite(m):
                    raise ParameterError(f"{what}: lambda={lam!r}, zeta={zeta!r} give an "
                                         "infinite mean")
            object.__setattr__(self, "mean", m)
            object.__setattr__(self, "std", m * math.sqrt(math.expm1(zeta * zeta)))
        for k, v in (("lambda_", lam), ("zeta", zeta),
                     ("error_factor", math.exp(PHI_95 * zeta))):
            if k not in form:
                object.__setattr__(self, k, v)
        lo = _number("lower", self.lower, what)
        hi = _number("upper", self.upper, what)
        if not (0.0 <= lo < hi) or np.isnan(hi):
            raise ParameterError(f"{what}: bounds must satisfy 0 <= lower < upper, got "
                                 f"lower={self.lower!r}, upper={self.upper!r}")
        log = None
        if lo > 0.0 or np.isfinite(hi):
            log = TruncatedNormal(lam, zeta, math.log(lo) if lo > 0 else -math.inf,
                                  math.log(hi))
        _freeze(self, "lognorm", s=zeta, scale=math.exp(lam))
        object.__setattr__(self, "_form", form)
        object.__setattr__(self, "_log_mean", lam)
        object.__setattr__(self, "_log_std", zeta)
        object.__setattr__(self, "_log", log)

    @property
    def moments(self) -> tuple[float, float]:
        if self._log is None:
            return float(self.mean), float(self.std)
        # E[x^k] = exp(k lambda + k^2 zeta^2 / 2) P(a - k zeta < Z < b - k zeta) / P(a < Z < b)
        lam, zeta = self._log_mean, self._log_std
        a = (self._log.lower - lam) / zeta
        b = (self._log.upper - lam) / zeta

        def mass(k: float) -> float:
            lo, hi = a - k * zeta, b - k * zeta
            if hi <= 0:
                return float(stats.norm.cdf(hi) - stats.norm.cdf(lo))
            return float(stats.norm.sf(lo) - stats.norm.sf(hi))

        m1 = math.exp(lam + zeta * zeta / 2) * mass(1.0) / mass(0.0)
        m2 = math.exp(2 * lam + 2 * zeta * zeta) * mass(2.0) / mass(0.0)
        return m1, math.sqrt(max(m2 - m1 * m1, 0.0))

    @property
    def bounds(self) -> tuple[float, float]:
        return float(self.lower), float(self.upper)

    def describe(self) -> dict[str, Any]:
        """The form that was given (``{"kind": "lognormal", "lambda": ..., "zeta": ...}``...),
        plus ``lower``/``upper`` when truncated."""
        out: dict[str, Any] = {"kind": self.kind}
        out.update({_study_key(k): getattr(self, k) for k in self._form})
        if self._log is not None:
            out.update(lower=self.lower, upper=self.upper)
        return out

    def _logx(self, x: Any) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(x > 0, np.log(np.maximum(x, 0.0)), -np.inf)

    def cdf(self, x: Any) -> np.ndarray:
        if self._log is None:
            return self.dist.cdf(x)
        return self._log.cdf(self._logx(x))

    # the upper tail through the normal of log(x): scipy 1.11 computes lognorm.isf(q) as
    # ppf(1 - q), which is inf below q ~ 1e-17
    def sf(self, x: Any) -> np.ndarray:
        if self._log is not None:
            return self._log.sf(self._logx(x))
        x = np.asarray(x, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (np.log(np.maximum(x, 0.0)) - self._log_mean) / self._log_std
        return np.where(np.isnan(x), np.nan, stats.norm.sf(t))

    def ppf(self, q: Any) -> np.ndarray:
        if self._log is None:
            return self.dist.ppf(q)
        return np.clip(np.exp(self._log.ppf(q)), self.lower, self.upper)

    def isf(self, q: Any) -> np.ndarray:
        if self._log is not None:
            return np.clip(np.exp(self._log.isf(q)), self.lower, self.upper)
        return np.exp(self._log_mean + self._log_std * stats.norm.isf(q))

    def pdf(self, x: Any) -> np.ndarray:
        if self._log is None:
            return self.dist.pdf(x)
        x = np.asarray(x, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(x > 0, self._log.pdf(self._logx(x)) / x, 0.0)

    def logpdf(self, x: Any) -> np.ndarray:
        if self._log is None:
            return self.dist.logpdf(x)
        with np.errstate(divide="ignore"):
            return np.log(self.pdf(x))

    def rvs(self, size: int | tuple[int, ...], *, seed: SeedLike = None) -> np.ndarray:
        if self._log is None:
            return super().rvs(size, seed=seed)
        return self.ppf(as_generator(seed).random(size))


@dataclass(frozen=True)
class Uniform(_DerivedMoments):
    """Uniform on [lower, upper]. Its std is derived from the bounds: (upper-lower)/sqrt(12).

    Parameters
    ----------
    lower, upper : float
        The bounds, ``lower < upper``, in the variable's units.
    """

    lower: float
    upper: float

    def __post_init__(self) -> None:
        lo, hi = _ordered(self.lower, self.upper, "Uniform")
        _finite("lower", lo, "Uniform")
        _finite("upper", hi, "Uniform")
        _freeze(self, "uniform", loc=lo, scale=hi - lo)

    # scipy's arithmetic (loc + scale * standard moment, its support likewise) without
    # importing it: the same bits (tests/test_report_imports.py)
    @property
    def moments(self) -> tuple[float, float]:
        lo, hi = float(self.lower), float(self.upper)
        w = hi - lo
        return 0.5 * w + lo, math.sqrt(1.0 / 12 * w * w)

    @property
    def bounds(self) -> tuple[float, float]:
        lo, hi = float(self.lower), float(self.upper)
        w = hi - lo
        return 0.0 * w + lo, 1.0 * w + lo

    # sf/isf measured from the upper bound: scipy's 1 - F loses the upper tail
    def sf(self, x: Any) -> np.ndarray:
        return np.clip((self.upper - np.asarray(x, dtype=float)) / (self.upper - self.lower),
                       0.0, 1.0)

    def isf(self, q: Any) -> np.ndarray:
        return self.upper - np.asarray(q, dtype=float) * (self.upper - self.lower)


@dataclass(frozen=True)
class LogUniform(_DerivedMoments):
    """Log-uniform on [lower, upper], 0 < lower < upper: log(x) is uniform.

    Parameters
    ----------
    lower, upper : float
        The bounds, ``0 < lower < upper``, in the variable's units.
    """

    lower: float
    upper: float

    def __post_init__(self) -> None:
        _positive("lower", self.lower, "LogUniform")
        _ordered(self.lower, self.upper, "LogUniform")
        _freeze(self, "loguniform", self.lower, self.upper)


class _MirroredTail(_DerivedMoments):
    """A distribution on [lower, upper] whose upper tail is read from ``_mirror``, the
    standardized distribution of (upper - x) / width (Beta(beta, alpha) for a Beta, the
    mirrored triangle for a Triangular): accurate where 1 - cdf would cancel."""

    lower: float
    upper: float

    @property
    def _mirror(self) -> Any:
        """The frozen scipy distribution of (upper - x) / width (built on first use)."""
        mirror = self.__dict__.get("_mirror_frozen")
        if mirror is None:
            family, args = self.__dict__["_mirror_scipy"]
            mirror = getattr(stats, family)(*args)
            object.__setattr__(self, "_mirror_frozen", mirror)
        return mirror

    def sf(self, x: Any) -> np.ndarray:
        w = self.upper - self.lower
        return self._mirror.cdf(np.clip((self.upper - np.asarray(x, dtype=float)) / w, 0, 1))

    def isf(self, q: Any) -> np.ndarray:
        return self.upper - (self.upper - self.lower) * self._mirror.ppf(q)


@dataclass(frozen=True)
class Beta(_MirroredTail):
    """Beta(alpha, beta) scaled to [lower, upper].

    Parameters
    ----------
    alpha, beta : float
        The shape parameters (> 0) of the beta distribution on [0, 1].
    lower, upper : float, optional
        The bounds it is scaled to (default 0 and 1), in the variable's units.
    """

    alpha: float
    beta: float
    lower: float = 0.0
    upper: float = 1.0

    def __post_init__(self) -> None:
        _positive("alpha", self.alpha, "Beta")
        _positive("beta", self.beta, "Beta")
        lo, hi = _ordered(self.lower, self.upper, "Beta")
        _freeze(self, "beta", self.alpha, self.beta, loc=lo, scale=hi - lo)
        object.__setattr__(self, "_mirror_scipy", ("beta", (self.beta, self.alpha)))


_SHAPE_SCALE_PARAMETERS = """
    Parameters
    ----------
    alpha : float
        Shape (> 0).
    beta : float
        Scale (> 0), in the variable's units.
    """


@dataclass(frozen=True)
class _ShapeScale(_DerivedMoments):
    """A scipy family with shape ``alpha`` and scale ``beta`` (``_family``: its name in
    :mod:`scipy.stats`)."""

    _family: ClassVar[str]
    alpha: float
    beta: float

    def __post_init__(self) -> None:
        what = type(self).__name__
        _positive("alpha", self.alpha, what)
        _positive("beta", self.beta, what)
        _freeze(self, self._family, self.alpha, scale=self.beta)


@fill_doc(parameters=_SHAPE_SCALE_PARAMETERS)
@dataclass(frozen=True)
class Gamma(_ShapeScale):
    """Gamma with shape ``alpha`` and scale ``beta`` (mean alpha*beta).

    %(parameters)s
    """

    _family = "gamma"


@dataclass(frozen=True)
class Exponential(_DerivedMoments):
    """Exponential with scale ``beta`` (mean beta).

    Parameters
    ----------
    beta : float
        Scale (> 0) and mean, in the variable's units.
    """

    beta: float

    def __post_init__(self) -> None:
        _positive("beta", self.beta, "Exponential")
        _freeze(self, "expon", scale=self.beta)


@dataclass(frozen=True)
class Gumbel(_DerivedMoments):
    """Gumbel (largest extreme value) with Dakota's alpha (1/scale) and beta (location).

    Parameters
    ----------
    alpha : float
        Inverse scale (> 0), per unit of the variable.
    beta : float
        Location (the mode), in the variable's units.
    """

    alpha: float
    beta: float

    def __post_init__(self) -> None:
        _positive("alpha", self.alpha, "Gumbel")
        _finite("beta", self.beta, "Gumbel")
        _freeze(self, "gumbel_r", loc=self.beta, scale=1.0 / self.alpha)


@fill_doc(parameters=_SHAPE_SCALE_PARAMETERS)
@dataclass(frozen=True)
class Weibull(_ShapeScale):
    """Weibull with shape ``alpha`` and scale ``beta``.

    %(parameters)s
    """

    _family = "weibull_min"


@dataclass(frozen=True)
class Triangular(_MirroredTail):
    """Triangular on [lower, upper] with mode ``mode``.

    Parameters
    ----------
    mode : float
        The most likely value, ``lower <= mode <= upper``.
    lower, upper : float
        The bounds, ``lower < upper``, in the variable's units.
    """

    mode: float
    lower: float
    upper: float

    def __post_init__(self) -> None:
        lo, hi = _ordered(self.lower, self.upper, "Triangular")
        _finite("mode", self.mode, "Triangular")
        if not (lo <= float(self.mode) <= hi):
            raise ParameterError(
                f"Triangular: mode must lie in [lower, upper], got mode={self.mode!r}, "
                f"lower={lo!r}, upper={hi!r}"
            )
        _freeze(self, "triang", (self.mode - lo) / (hi - lo), loc=lo, scale=hi - lo)
        object.__setattr__(self, "_mirror_scipy", ("triang", ((hi - self.mode) / (hi - lo),)))


@dataclass(frozen=True)
class Frechet(_DerivedMoments):
    """Frechet (type II largest extreme value) with Dakota's shape ``alpha`` and scale
    ``beta``: ``F(x) = exp(-(beta / x)^alpha)`` for x > 0 (scipy's ``invweibull(alpha,
    scale=beta)``).

    Mean ``beta Gamma(1 - 1/alpha)``, variance ``beta^2 (Gamma(1 - 2/alpha) - Gamma(1 -
    1/alpha)^2)``: ``alpha > 2`` (a finite std, which every rotoruq method needs).

    Parameters
    ----------
    alpha : float
        Shape, > 2.
    beta : float
        Scale (> 0), in the variable's units.

    Examples
    --------
    >>> d = Frechet(alpha=3.0, beta=2.0)
    >>> round(d.mean, 6), round(float(d.cdf(2.0)), 6)          # 2 Gamma(2/3), exp(-1)
    (2.708236, 0.367879)
    """

    alpha: float
    beta: float

    def __post_init__(self) -> None:
        a = _positive("alpha", self.alpha, "Frechet")
        if not a > 2.0:
            raise ParameterError(f"Frechet: alpha must be > 2 (a finite std), got {a!r}")
        _positive("beta", self.beta, "Frechet")
        _freeze(self, "invweibull", a, scale=self.beta)

    @property
    def moments(self) -> tuple[float, float]:
        a, b = float(self.alpha), float(self.beta)
        g1, g2 = math.gamma(1.0 - 1.0 / a), math.gamma(1.0 - 2.0 / a)
        return b * g1, b * math.sqrt(max(g2 - g1 * g1, 0.0))

    def _t(self, x: Any) -> np.ndarray:
        """(beta / x)^alpha, +inf at and below 0."""
        x = np.asarray(x, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(x > 0, (self.beta / np.maximum(x, 0.0)) ** self.alpha, np.inf)

    def cdf(self, x: Any) -> np.ndarray:
        return np.exp(-self._t(x))

    def sf(self, x: Any) -> np.ndarray:
        return -np.expm1(-self._t(x))

    def ppf(self, q: Any) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where((q < 0) | (q > 1), np.nan,
                            self.beta * (-np.log(q)) ** (-1.0 / self.alpha))

    def isf(self, q: Any) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where((q < 0) | (q > 1), np.nan,
                            self.beta * (-np.log1p(-q)) ** (-1.0 / self.alpha))


class _PiecewiseDensity(_DerivedMoments):
    """A density constant on each piece between the sorted ``_edges`` (``_dens``, one value a
    piece): its support, log-density and sampling by inversion of its ``ppf``."""

    _edges: np.ndarray
    _dens: np.ndarray

    @property
    def bounds(self) -> tuple[float, float]:
        return float(self._edges[0]), float(self._edges[-1])

    def _bin(self, x: np.ndarray) -> np.ndarray:
        return np.clip(np.searchsorted(self._edges, x, side="right") - 1, 0, self._dens.size - 1)

    def pdf(self, x: Any) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        inside = (x >= self._edges[0]) & (x <= self._edges[-1])
        return np.where(inside, self._dens[self._bin(x)], 0.0)

    def logpdf(self, x: Any) -> np.ndarray:
        with np.errstate(divide="ignore"):
            return np.log(self.pdf(x))

    def rvs(self, size: int | tuple[int, ...], *, seed: SeedLike = None) -> np.ndarray:
        return self.ppf(as_generator(seed).random(size))


@dataclass(frozen=True)
class HistogramBin(_PiecewiseDensity):
    """Piecewise-uniform density over bins (Dakota's ``histogram_bin_uncertain``).

    :meth:`describe` gives the form that was given (counts or ordinates).

    Parameters
    ----------
    abscissas : sequence of float
        The n + 1 strictly increasing bin edges, in the variable's units.
    counts : sequence of float, optional
        n counts (the mass of each bin, relative), or n + 1 with the last 0 (Dakota's form:
        one count per abscissa, the last closing the last bin); >= 0 with a positive total,
        normalised.
    ordinates : sequence of float, optional
        Instead of ``counts``: the density of each bin (relative, normalised; the mass of bin
        i is ``ordinates[i] * width_i``), n or n + 1 values likewise, >= 0 with a positive
        total.

    Examples
    --------
    >>> d = HistogramBin(abscissas=[0.0, 1.0, 3.0], counts=[1.0, 1.0, 0.0])
    >>> d.mean, float(d.cdf(1.0)), float(d.pdf(2.0))
    (1.25, 0.5, 0.25)
    """

    abscissas: Any
    counts: Any = None
    ordinates: Any = None
    _edges: np.ndarray = field(init=False, repr=False, compare=False)
    _dens: np.ndarray = field(init=False, repr=False, compare=False)
    _cum: np.ndarray = field(init=False, repr=False, compare=False)
    _upper: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        what = "HistogramBin"
        try:
            x = np.array(self.abscissas, dtype=float)
        except (TypeError, ValueError):
            raise ParameterError(f"{what}: abscissas must be numbers, got "
                                 f"{self.abscissas!r}") from None
        if x.ndim != 1 or x.size < 2 or not np.all(np.isfinite(x)) or np.any(np.diff(x) <= 0):
            raise ParameterError(f"{what}: abscissas must be at least 2 finite, strictly "
                                 f"increasing numbers, got {self.abscissas!r}")
        if (self.counts is None) == (self.ordinates is None):
            raise ParameterError(f"{what}: give counts or ordinates (one of them) with the "
                                 "abscissas")
        key = "counts" if self.counts is not None else "ordinates"
        raw = self.counts if self.counts is not None else self.ordinates
        try:
            c = np.array(raw, dtype=float)
        except (TypeError, ValueError):
            raise ParameterError(f"{what}: {key} must be numbers, got {raw!r}") from None
        n = x.size - 1
        if c.ndim != 1 or c.size not in (n, n + 1) or (c.size == n + 1 and c[-1] != 0):
            raise ParameterError(
                f"{what}: {n + 1} abscissas need {n} {key} (one per bin) or {n + 1} with the "
                f"last 0 (Dakota's form), got {c.size}: {list(raw)!r}")
        c = c[:n]
        if not np.all(np.isfinite(c)) or np.any(c < 0) or not c.sum() > 0:
            raise ParameterError(f"{what}: {key} must be >= 0 with a positive total, got "
                                 f"{list(raw)!r}")
        width = np.diff(x)
        mass = c if key == "counts" else c * width
        mass = mass / mass.sum()
        object.__setattr__(self, "abscissas", tuple(x.tolist()))
        object.__setattr__(self, key, tuple(np.asarray(raw, dtype=float).tolist()))
        object.__setattr__(self, "_edges", x)
        object.__setattr__(self, "_dens", mass / width)
        # cumulative mass below each edge and above it (the upper tail summed from the top)
        object.__setattr__(self, "_cum", np.concatenate([[0.0], np.cumsum(mass)]))
        object.__setattr__(self, "_upper", np.concatenate([np.cumsum(mass[::-1])[::-1], [0.0]]))
        _freeze(self, "rv_histogram", (mass, x), density=False)

    @property
    def kind(self) -> str:
        return "histogram_bin"

    @property
    def moments(self) -> tuple[float, float]:
        a, b = self._edges[:-1], self._edges[1:]
        p = np.diff(self._cum)
        mean = float(np.dot(p, (a + b) / 2.0))
        var = float(np.dot(p, (b - a) ** 2 / 12.0 + ((a + b) / 2.0 - mean) ** 2))
        return mean, math.sqrt(var)

    def cdf(self, x: Any) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        k = self._bin(x)
        out = self._cum[k] + (x - self._edges[k]) * self._dens[k]
        return np.where(x <= self._edges[0], 0.0, np.where(x >= self._edges[-1], 1.0, out))

    # the upper tail measured from the edge above (exact near the upper bound)
    def sf(self, x: Any) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        k = self._bin(x)
        out = self._upper[k + 1] + (self._edges[k + 1] - x) * self._dens[k]
        return np.where(x <= self._edges[0], 1.0, np.where(x >= self._edges[-1], 0.0, out))

    def ppf(self, q: Any) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        c, t = self._cum, self._edges
        # bin k with c[k] < q <= c[k+1]: empty bins are skipped
        k = np.clip(np.searchsorted(c, q, side="left") - 1, 0, c.size - 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            out = t[k] + (q - c[k]) / self._dens[k]
        out = np.minimum(out, t[k + 1])
        return np.where((q < 0) | (q > 1) | np.isnan(q), np.nan, np.where(q <= 0, t[0], out))

    def isf(self, q: Any) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        s, t = self._upper, self._edges
        # bin k with s[k+1] <= q < s[k] (s decreasing); empty bins are skipped
        k = np.clip(s.size - 1 - np.searchsorted(s[::-1], q, side="left"), 0, s.size - 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            out = t[k + 1] - (q - s[k + 1]) / self._dens[k]
        out = np.maximum(out, t[k])
        return np.where((q < 0) | (q > 1) | np.isnan(q), np.nan, np.where(q <= 0, t[-1], out))

    def describe(self) -> dict[str, Any]:
        key = "counts" if self.counts is not None else "ordinates"
        return {"kind": self.kind, "abscissas": list(self.abscissas),
                key: list(getattr(self, key))}
