"""The rotor model at a chosen discretization, for solution verification.

:class:`RotorDiscretization` builds a :class:`~rotoruq.rotor.model.RotorModel` at refinement
level k: ``n_stations * ratio**k`` Gauss stations and ``n_azimuth * ratio**k`` azimuth steps
(a negative k coarsens, where the counts stay integers), at a solver tolerance tight enough
that the iteration error does not pollute the observed order. Level 0 with the default
tolerance is the default model, bitwise.

What order to expect (see ``rotor/_kernel.py`` and ``rotor/geometry.py``): the span integrals
are Gauss-Legendre sums over the stations, the azimuth integrals equal-step sums over a
period. Both are spectral for smooth integrands (the azimuth sum is exact for the harmonics
the blade motion carries). What limits them is the integrand's smoothness: the Prandtl tip
and root loss factor goes like the square root of the distance to the blade's ends, which
makes the span quadrature third order (error ~ N^-2(1 + 1/2)); the airfoil table's linear
interpolation in Mach puts kinks in the integrand where the section Mach crosses a table row,
which makes it second order at best, with an error whose sign changes irregularly as the
stations move across the kinks (Richardson extrapolation then has no asymptotic range).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from ..errors import ParameterError
from .model import RotorModel
from .presets import RotorPreset

__all__ = ["RotorDiscretization"]


@dataclass(frozen=True)
class RotorDiscretization:
    """A factory level -> :class:`RotorModel` over azimuth steps and span stations.

    Parameters
    ----------
    preset : str or RotorPreset
    names_in, names_out, fixed, airfoil : as in :class:`RotorModel`.
    n_stations, n_azimuth : int
        The counts at level 0 (the model's defaults: 10 stations, 36 azimuth steps).
    ratio : int, > 1
        Refinement ratio per level (counts are multiplied by it; grid spacing divided).
    tolerance : float
        Convergence tolerance of the periodic solution at every level (default 1e-12: the
        iteration error stays far below the discretization error; 1e-8 is the model's).
    refine_azimuth, refine_stations : bool
        Which of the two counts the levels refine (both by default).

    Examples
    --------
    >>> from rotoruq.rotor.discretization import RotorDiscretization
    >>> factory = RotorDiscretization("gvpm", names_out=["thrust", "power"])
    >>> model = factory(1)                      # 20 stations, 72 azimuth steps
    >>> model.grid.r.size, model.grid.psi.size
    (20, 72)
    """

    preset: str | RotorPreset = "gvpm"
    names_in: Sequence[str] | None = None
    names_out: Sequence[str] | None = None
    fixed: Mapping[str, float] | None = None
    airfoil: Any = field(default=None, compare=False)
    n_stations: int = 10
    n_azimuth: int = 36
    ratio: int = 2
    tolerance: float = 1e-12
    refine_azimuth: bool = True
    refine_stations: bool = True

    def __post_init__(self) -> None:
        if isinstance(self.ratio, bool) or int(self.ratio) != self.ratio or self.ratio <= 1:
            raise ParameterError(f"ratio must be an integer > 1 (azimuth steps and stations are "
                                 f"counts), got {self.ratio!r}")
        if not (self.refine_azimuth or self.refine_stations):
            raise ParameterError("refine at least one of azimuth steps and stations")

    def counts(self, level: int) -> tuple[int, int]:
        """(n_stations, n_azimuth) at ``level``.

        Parameters
        ----------
        level : int
            Refinement level: 0 is the base grid, each level up multiplies the refined counts
            by ``ratio``, each level down divides them (which must leave whole counts).
        """
        if isinstance(level, bool) or int(level) != level:
            raise ParameterError(f"a rotor discretization level is an integer, got {level!r}")
        k = int(level)
        r = int(self.ratio)

        def scaled(n: int, on: bool, what: str) -> int:
            if not on:
                return n
            if k >= 0:
                return n * r**k
            q, rem = divmod(n, r ** (-k))
            if rem:
                raise ParameterError(f"level {k} coarsens {n} {what} by {r ** (-k)}: not an "
                                     "integer count")
            return q
        return (scaled(self.n_stations, self.refine_stations, "stations"),
                scaled(self.n_azimuth, self.refine_azimuth, "azimuth steps"))

    def __call__(self, level: int) -> RotorModel:
        n_stations, n_azimuth = self.counts(level)
        return RotorModel(self.preset, names_in=self.names_in, names_out=self.names_out,
                          fixed=self.fixed, airfoil=self.airfoil, n_stations=n_stations,
                          n_azimuth=n_azimuth, tolerance=self.tolerance)
