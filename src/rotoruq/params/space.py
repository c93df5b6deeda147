"""The :class:`ParameterSpace`: an ordered mapping name -> distribution that every method
draws points from and transforms into.

Points are arrays of shape ``(n, d)`` in the order of ``space.names``. Standard normal space
("u-space") is reached through the marginal CDFs, ``z = Phi^-1(F_i(x_i))``; for independent
variables ``u = z``, with a correlation matrix through the Nataf model
(:mod:`rotoruq.params.nataf`). Every u <-> x transform is exact in both tails to |u| = 37.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .._lazy import lazy_module
from .._rng import SeedLike, as_generator
from ..errors import ParameterError
from .distributions import Distribution
from .interval import Interval
from .nataf import nataf_model
from .pairing import PAIRINGS, restricted_pairing

if TYPE_CHECKING:
    from scipy import linalg, stats
    from scipy.stats import qmc
else:  # imported on first use: a space read from saved results (a report) needs none
    linalg = lazy_module("scipy.linalg")
    stats = lazy_module("scipy.stats")
    qmc = lazy_module("scipy.stats.qmc")

__all__ = ["DESIGNS", "PAIRINGS", "ParameterSpace", "unit_design"]

DESIGNS = ("lhs", "random", "sobol", "halton")
"""Names of the point designs of :func:`unit_design` and :meth:`ParameterSpace.draw`."""


@dataclass(frozen=True, eq=False)
class ParameterSpace:
    """An ordered set of named uncertain parameters, independent or correlated.

    Points are arrays of shape ``(n, d)`` with columns in the order of :attr:`names`.

    Parameters
    ----------
    parameters : mapping of str to Distribution, or iterable of (str, Distribution)
        The parameters, by name, in order (d of them, at least one; names unique).
    correlation : array_like of shape (d, d), optional
        Correlation matrix of the parameters themselves (x-space, Pearson), symmetric, unit
        diagonal, positive definite. Sampling and the u-space transforms use the Nataf model
        (Gaussian copula) with the equivalent normal-score correlation :attr:`nataf`.
        Default: independent.
    """

    parameters: Mapping[str, Distribution] | Iterable[tuple[str, Distribution]]
    correlation: np.ndarray | None = None
    _items: tuple[tuple[str, Distribution], ...] = field(init=False, repr=False)
    _nataf: np.ndarray | None = field(init=False, repr=False)
    _chol: np.ndarray | None = field(init=False, repr=False)

    def __post_init__(self) -> None:
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
        model = nataf_model([d for _, d in items], self.correlation)
        object.__setattr__(self, "_items", tuple(items))
        object.__setattr__(self, "parameters", dict(items))
        object.__setattr__(self, "correlation", model.correlation)
        object.__setattr__(self, "_nataf", model.nataf)
        object.__setattr__(self, "_chol", model.cholesky)

    # --- description -----------------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        """The parameter names, in order (the columns of a point array)."""
        return tuple(n for n, _ in self._items)

    @property
    def distributions(self) -> tuple[Distribution, ...]:
        """The parameter distributions, in the order of :attr:`names`."""
        return tuple(d for _, d in self._items)

    @property
    def dim(self) -> int:
        """The number of parameters, d."""
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
        """The column of parameter ``name`` in a point array.

        Parameters
        ----------
        name : str
            A parameter name; another raises :class:`~rotoruq.ParameterError`.
        """
        try:
            return self.names.index(name)
        except ValueError:
            raise ParameterError(
                f"unknown parameter {name!r}; this space has {', '.join(self.names)}"
            ) from None

    @property
    def mean(self) -> np.ndarray:
        """Means, shape (d,)."""
        return np.array([d.moments[0] for d in self.distributions])

    @property
    def std(self) -> np.ndarray:
        """Standard deviations, shape (d,)."""
        return np.array([d.moments[1] for d in self.distributions])

    @property
    def bounds(self) -> np.ndarray:
        """Support bounds, shape (d, 2) (may contain +-inf)."""
        return np.array([d.bounds for d in self.distributions])

    @property
    def correlated(self) -> bool:
        """Whether a correlation matrix was given (the parameters are then not independent)."""
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
        """A new space with some distributions replaced (names must exist; correlation kept).

        Parameters
        ----------
        **dists : Distribution
            The new distribution of each parameter to replace, by name.
        """
        for name in dists:
            self.index(name)
        return ParameterSpace(
            [(n, dists.get(n, d)) for n, d in self._items], correlation=self.correlation
        )

    def subset(self, names_in: Iterable[str]) -> ParameterSpace:
        """A new space with only these parameters (in this order; correlation kept).

        Parameters
        ----------
        names_in : iterable of str
            Names of the parameters to keep, in the order of the new space.
        """
        names = list(names_in)
        corr = None
        if self.correlation is not None:
            idx = [self.index(n) for n in names]
            corr = self.correlation[np.ix_(idx, idx)]
        return ParameterSpace([(n, self[n]) for n in names], correlation=corr)

    # --- transforms ------------------------------------------------------------------------
    def _check(self, x: Any) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if x.ndim == 1:
            x = x[None, :]
        if x.ndim != 2 or x.shape[1] != self.dim:
            raise ParameterError(
                f"points must have shape (n, {self.dim}) for parameters {self.names}, "
                f"got {x.shape}"
            )
        return x

    def _marginals(self, method: str, points: Any) -> np.ndarray:
        """Apply each marginal's ``method`` (``"ppf"``, ``"cdf"``, ...) to its column."""
        points = self._check(points)
        return np.column_stack(
            [getattr(d, method)(points[:, j]) for j, d in enumerate(self.distributions)]
        )

    def from_unit(self, q: Any) -> np.ndarray:
        """Map probabilities in (0, 1)^d to parameter values by marginal ppf, shape (n, d).

        Parameters
        ----------
        q : array_like of shape (n, d) or (d,)
            Marginal probabilities, one column per parameter.
        """
        return self._marginals("ppf", q)

    def to_unit(self, x: Any) -> np.ndarray:
        """Map parameter values to marginal CDF values in [0, 1]^d, shape (n, d).

        Parameters
        ----------
        x : array_like of shape (n, d) or (d,)
            Points, in the parameters' units.
        """
        return self._marginals("cdf", x)

    def to_z(self, x: Any) -> np.ndarray:
        """Marginal normal scores z = Phi^-1(F_i(x_i)), shape (n, d).

        The scores are correlated if the space is. Exact in both tails (see
        :meth:`Distribution.to_z`), |z| <= 37.5.

        Parameters
        ----------
        x : array_like of shape (n, d) or (d,)
            Points, in the parameters' units.
        """
        return self._marginals("to_z", x)

    def from_z(self, z: Any) -> np.ndarray:
        """Inverse of :meth:`to_z`: ``x_i = F_i^-1(Phi(z_i))``, exact in both tails.

        Parameters
        ----------
        z : array_like of shape (n, d) or (d,)
            Marginal normal scores.
        """
        return self._marginals("from_z", z)

    def to_u(self, x: Any) -> np.ndarray:
        """Transform to independent standard normal space, shape (n, d).

        Independent: u = Phi^-1(F(x)). Correlated: Nataf, u = L^-1 z with L L^T = R0.
        Both tails are exact to |u| = 37 (the upper tail goes through the survival function);
        beyond a finite support bound, u saturates at +-37.5.

        Parameters
        ----------
        x : array_like of shape (n, d) or (d,)
            Points, in the parameters' units.
        """
        z = self.to_z(x)
        if self._chol is None:
            return z
        return linalg.solve_triangular(self._chol, z.T, lower=True).T

    def from_u(self, u: Any) -> np.ndarray:
        """Inverse of :meth:`to_u`: points in the parameters' units, shape (n, d).

        Parameters
        ----------
        u : array_like of shape (n, d) or (d,)
            Points in independent standard normal space.
        """
        u = self._check(u)
        if self._chol is not None:
            u = u @ self._chol.T
        return self.from_z(u)

    def logpdf(self, x: Any) -> np.ndarray:
        """Joint log density, shape (n,); -inf outside the support.

        Sum of the marginal log densities, plus the Gaussian-copula term when correlated.

        Parameters
        ----------
        x : array_like of shape (n, d) or (d,)
            Points, in the parameters' units.
        """
        x = self._check(x)
        out = np.zeros(x.shape[0])
        for j, d in enumerate(self.distributions):
            out += d.logpdf(x[:, j])
        if self._chol is not None:
            with np.errstate(invalid="ignore"):
                z = self.to_z(x)
                r0inv = np.linalg.inv(self.nataf)
                quad = np.einsum("ni,ij,nj->n", z, r0inv - np.eye(self.dim), z)
                logdet = 2.0 * np.sum(np.log(np.diag(self._chol)))
                out = out - 0.5 * quad - 0.5 * logdet
        return np.where(np.isnan(out), -np.inf, out)

    def contains(self, x: Any) -> np.ndarray:
        """Boolean mask (n,) of points inside the support bounds.

        Parameters
        ----------
        x : array_like of shape (n, d) or (d,)
            Points, in the parameters' units.
        """
        x = self._check(x)
        b = self.bounds
        return np.all((x >= b[:, 0]) & (x <= b[:, 1]), axis=1)

    # --- drawing points ------------------------------------------------------------------
    def draw(
        self,
        n_samples: int,
        *,
        design: str = "lhs",
        pairing: str = "restricted",
        seed: SeedLike = None,
    ) -> np.ndarray:
        """Draw ``n_samples`` points, shape (n_samples, d).

        Parameters
        ----------
        n_samples : int
            Number of points.
        design : str
            "lhs" (Latin hypercube), "random" (plain Monte Carlo), "sobol" or "halton"
            (scrambled low-discrepancy sequences), all from :mod:`scipy.stats.qmc`.
        pairing : str
            For "lhs" only: "restricted" (default, as Dakota: Iman-Conover pairing of the
            columns, so the sample's normal-score correlation is near the Nataf correlation
            of the space, the identity when independent; every marginal stays stratified) or
            "random" (columns paired at random; with correlations the normal scores are then
            correlated through the Nataf factor, so the design is stratified in u-space
            rather than in each marginal, as the other designs are).
        seed : int, numpy Generator or None
            The same seed gives the same points, bitwise.

        Returns
        -------
        ndarray, shape (n_samples, d)
            The points in the parameters' own units, columns in ``names`` order.

        Examples
        --------
        >>> import rotoruq as rq
        >>> space = rq.ParameterSpace({"a": rq.Normal(0, 1), "b": rq.Uniform(0, 1)})
        >>> space.draw(4, seed=1).shape
        (4, 2)
        """
        target = self.nataf if self._chol is not None else None
        q = unit_design(n_samples, self.dim, design=design, pairing=pairing,
                        correlation=target, seed=seed)
        if self._chol is not None and not (design == "lhs" and pairing == "restricted"):
            # correlate the normal scores of the design (Nataf); marginals keep their law
            return self.from_u(stats.norm.ppf(np.clip(q, 1e-16, 1 - 1e-16)))
        return self.from_unit(q)


def unit_design(
    n_samples: int,
    dim: int,
    *,
    design: str = "lhs",
    pairing: str = "restricted",
    correlation: np.ndarray | None = None,
    seed: SeedLike = None,
) -> np.ndarray:
    """Points in (0, 1)^dim, shape (n_samples, dim), from the named design.

    Raises :class:`~rotoruq.errors.ParameterError` for an unknown design or pairing, or
    ``n_samples < 1``.

    Parameters
    ----------
    n_samples : int
        Number of points, >= 1.
    dim : int
        Number of dimensions, >= 1.
    design : one of :data:`DESIGNS`.
    pairing : one of :data:`PAIRINGS`, used by ``design="lhs"`` only. "restricted" (default,
        Dakota's LHS): the columns of the Latin hypercube are re-ordered by
        :func:`~rotoruq.params.pairing.restricted_pairing` so that the normal scores
        Phi^-1(q) have correlation near ``correlation`` (identity by default); every column
        still hits each of its n strata once. With ``n_samples <= dim`` no pairing can
        control the correlation: the columns stay randomly paired (and a ``correlation`` is
        imposed on their normal scores by its Cholesky factor). "random": columns
        paired at random (scipy's Latin hypercube as is).
    correlation : (dim, dim) target correlation of the normal scores for a restricted LHS
        (e.g. a space's Nataf correlation :attr:`ParameterSpace.nataf`); ignored otherwise.
    seed : int, numpy Generator or None; the same seed gives the same points, bitwise.

    Examples
    --------
    >>> q = unit_design(8, 3, seed=1)
    >>> q.shape
    (8, 3)
    >>> import numpy as np
    >>> bool(np.all(np.sort(np.floor(q * 8), axis=0) == np.arange(8)[:, None]))
    True
    """
    if isinstance(n_samples, bool) or int(n_samples) != n_samples or n_samples < 1:
        raise ParameterError(f"n_samples must be an integer >= 1, got {n_samples!r}")
    if pairing not in PAIRINGS:
        raise ParameterError(f"unknown pairing {pairing!r}; valid: {', '.join(PAIRINGS)}")
    n_samples = int(n_samples)
    rng = as_generator(seed)
    if design == "random":
        return rng.random((n_samples, dim))
    if design == "lhs":
        q = qmc.LatinHypercube(d=dim, seed=rng).random(n_samples)
        if pairing == "restricted":
            q = restricted_pairing(q, rng, correlation)
        return q
    if design == "sobol":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # non power-of-2 balance warning
            return qmc.Sobol(d=dim, scramble=True, seed=rng).random(n_samples)
    if design == "halton":
        return qmc.Halton(d=dim, scramble=True, seed=rng).random(n_samples)
    raise ParameterError(f"unknown design {design!r}; valid: {', '.join(DESIGNS)}")
