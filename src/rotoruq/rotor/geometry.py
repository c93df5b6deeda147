"""Blade discretization: Gauss-Legendre stations along the aerodynamic span, the azimuth grid
and the blade's mass properties about its (equivalent) hinge."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .presets import RotorPreset

__all__ = ["BladeGrid", "blade_grid"]

# Equivalent hinge spring of a uniform cantilever: I_hinge * omega_1^2 with
# omega_1 = 1.875^2 sqrt(EI / (m L^4)) and I_hinge = m L^3 / 3  ->  k = (1.875^4 / 3) EI / L.
CANTILEVER_SPRING_FACTOR = 1.8751040687**4 / 3.0


@dataclass(frozen=True)
class BladeGrid:
    """Stations and azimuths.

    r : (Nr,) station radii [m]; w : (Nr,) Gauss weights [m] (sum = aerodynamic span);
    twist : (Nr,) built-in twist [rad]; psi : (Npsi,) azimuths [rad];
    I_flap, I_lag : inertia about the hinge [kg m^2]; S_flap : first mass moment [kg m];
    blade_length : R - e [m].
    """

    r: np.ndarray
    w: np.ndarray
    twist: np.ndarray
    psi: np.ndarray
    I_flap: float
    I_lag: float
    S_flap: float
    blade_length: float


def blade_grid(preset: RotorPreset, n_stations: int = 12, n_azimuth: int = 36) -> BladeGrid:
    """Gauss-Legendre stations on [root_cutout, R] and ``n_azimuth`` equal azimuth steps."""
    if n_stations < 2 or n_azimuth < 5:
        raise ValueError("need at least 2 stations and 5 azimuth steps")
    x, wx = np.polynomial.legendre.leggauss(n_stations)
    r0, R = preset.root_cutout, preset.radius
    r = 0.5 * (R - r0) * x + 0.5 * (R + r0)
    w = 0.5 * (R - r0) * wx
    twist = np.deg2rad(preset.twist_deg) * (r - r0) / (R - r0)
    psi = 2 * np.pi * np.arange(n_azimuth) / n_azimuth
    L = R - preset.hinge_offset
    m = preset.blade_mass_per_length
    return BladeGrid(
        r=r,
        w=w,
        twist=twist,
        psi=psi,
        I_flap=m * L**3 / 3.0,
        I_lag=m * L**3 / 3.0,
        S_flap=m * L**2 / 2.0,
        blade_length=L,
    )
