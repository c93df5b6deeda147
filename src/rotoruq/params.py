"""Uncertain parameters: distributions backed by :mod:`scipy.stats` and the
:class:`ParameterSpace` that every method samples from and transforms into.

A distribution is a small frozen object with ``mean``, ``std``, ``bounds`` and the vectorized
``ppf``/``cdf``/``pdf``/``logpdf`` of its scipy counterpart. A ParameterSpace is an ordered
mapping name -> distribution. Points are arrays of shape ``(n, d)`` in the order of
``space.names``.

Standard normal space ("u-space") is reached through the marginal CDFs:
``u = Phi^-1(F_i(x_i))`` for independent variables.
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
    "ParameterSpace",
    "make_distribution",
    "DISTRIBUTIONS",
]


def _positive(name: str, value: float, what: str) -> float:
    value = float(value)
    if not np.isfinite(value) or value <= 0:
        raise ParameterError(f"{what}: {name} must be a finite number > 0, got {value!r}")
    return value


def _finite(name: str, value: float, what: str) -> float:
    value = float(value)
    if not np.isfinite(value):
        raise ParameterError(f"{what}: {name} must be finite, got {value!r}")
    return value


def _ordered(lower: float, upper: float, what: str) -> tuple[float, float]:
    lower, upper = float(lower), float(upper)
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
        if not (lo <= self.mode <= hi):
            raise ParameterError(
                f"Triangular: mode must lie in [lower, upper], got mode={self.mode!r}, "
                f"lower={lo!r}, upper={hi!r}"
            )
        _freeze(self, stats.triang((self.mode - lo) / (hi - lo), loc=lo, scale=hi - lo))


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


@dataclass(frozen=True)
class ParameterSpace:
    """An ordered set of named, independent uncertain parameters.

    Parameters
    ----------
    parameters : mapping name -> Distribution, or iterable of (name, Distribution)

    Points are arrays of shape ``(n, d)`` with columns in the order of :attr:`names`.
    """

    parameters: Mapping[str, Distribution] | Iterable[tuple[str, Distribution]]
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

    def replace(self, **dists: Distribution) -> ParameterSpace:
        """A new space with some distributions replaced (names must exist)."""
        for name in dists:
            self.index(name)
        return ParameterSpace([(n, dists.get(n, d)) for n, d in self._items])

    def subset(self, names: Iterable[str]) -> ParameterSpace:
        return ParameterSpace([(n, self[n]) for n in names])

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

    def to_u(self, x) -> np.ndarray:
        """Transform to independent standard normal space, u = Phi^-1(F(x)), shape (n, d)."""
        q = np.clip(self.to_unit(x), 1e-300, 1 - 1e-16)
        return stats.norm.ppf(q)

    def from_u(self, u) -> np.ndarray:
        """Inverse of :meth:`to_u`."""
        u = self._check(u)
        return self.from_unit(stats.norm.cdf(u))

    def logpdf(self, x) -> np.ndarray:
        """Joint log density of independent marginals, shape (n,); -inf outside the support."""
        x = self._check(x)
        out = np.zeros(x.shape[0])
        for j, d in enumerate(self.distributions):
            out += d.logpdf(x[:, j])
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
            "sobol" or "halton" (scrambled low-discrepancy sequences).
        """
        n = int(n)
        if n < 1:
            raise ParameterError(f"number of samples must be >= 1, got {n}")
        rng = as_generator(seed)
        q = unit_design(n, self.dim, rng, method)
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
