"""Momentum inflow for hover: uniform and BEMT annulus with Prandtl losses.

The steady first-harmonic (Pitt-Peters) inflow is solved together with the blade motion in
:mod:`rotoruq.rotor.hover`: in hover the mass-flow parameter of the moment harmonics is
V = 2 lambda_0 and Pitt-Peters' gain -2/V gives lambda_c,s = C_Mc,s / lambda_0, with
C_M = M / (rho A (Omega R)^2 R) the disk's thrust moments (more load, more inflow).

All updates are Newton steps on the momentum balance, batched over samples; the blade-element
side's derivative is taken from linear thin-airfoil theory (dL/dU_P = -rho c a0 U_T / 2), which
is only a preconditioner: the converged point satisfies the balance with the real c81 loads.
"""

from __future__ import annotations

import numpy as np

__all__ = ["prandtl_loss", "uniform_update", "annulus_update"]

A0 = 5.73  # lift slope [1/rad] used only in the Newton preconditioner


def prandtl_loss(r, R, r_root, n_blades, v, omega, tip=True, root=True):
    """Prandtl tip (and root) loss factor F in (0, 1], shape broadcast of r and v.

    r : station radii [m]; v : induced velocity [m/s]; omega [rad/s].
    """
    phi = np.maximum(np.abs(v) / (omega * r), 1e-6)
    F = np.ones(np.broadcast(r, v, omega).shape)
    if tip:
        f = 0.5 * n_blades * (R - r) / (r * phi)
        F = F * (2 / np.pi) * np.arccos(np.exp(-np.minimum(f, 50.0)))
    if root and r_root > 0:
        f = 0.5 * n_blades * (r - r_root) / (r * phi)
        F = F * (2 / np.pi) * np.arccos(np.exp(-np.minimum(f, 50.0)))
    return np.maximum(F, 1e-3)


def uniform_update(v, thrust_be, rho, area, kappa, chord, n_blades, omega, r, w):
    """Newton step on T_BE(v) = 2 rho A v|v| / kappa^2 for the uniform induced velocity.

    v, thrust_be, rho, kappa, omega : (n,). r, w : stations and weights. Returns new v (n,).
    """
    dT_be = -n_blades * 0.5 * rho * chord * A0 * omega * np.sum(w * r)
    f = thrust_be - 2 * rho * area * v * np.abs(v) / kappa**2
    df = dT_be - 4 * rho * area * np.abs(v) / kappa**2
    return v - f / df


def annulus_update(v, dT_be, rho, kappa, F, chord, n_blades, omega, r):
    """Newton step per station on dT_BE(r) = 4 pi rho F r v|v| / kappa^2 (per unit span).

    v, dT_be, F : (n, Nr); rho, kappa, omega : (n, 1). Returns new v (n, Nr).
    """
    d_be = -n_blades * 0.5 * rho * chord * A0 * omega * r
    f = dT_be - 4 * np.pi * rho * F * r * v * np.abs(v) / kappa**2
    df = d_be - 8 * np.pi * rho * F * r * np.abs(v) / kappa**2
    return v - f / df
