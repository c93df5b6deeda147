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

A0 = 5.73  # linear-theory lift slope [1/rad]: initial inflow, BEMT Newton slope, residual check


def _prandtl_factor(f):
    """F = (2/pi) arccos(exp(-f)) and dF/df."""
    f = np.minimum(f, 50.0)
    ex = np.exp(-f)
    F = (2 / np.pi) * np.arccos(ex)
    dF = (2 / np.pi) * ex / np.sqrt(np.maximum(1.0 - ex * ex, 1e-300))
    return F, np.where(f >= 50.0, 0.0, dF)


def prandtl_loss(r, R, r_root, n_blades, v, omega, tip=True, root=True, derivative=False):
    """Prandtl tip (and root) loss factor F in (0, 1], shape broadcast of r and v.

    r : station radii [m]; v : induced velocity [m/s]; omega [rad/s]. With ``derivative``
    returns (F, dF/dv) [s/m] (the exponent f is proportional to 1/|v|: df/dv = -f/v).
    """
    av = np.abs(v)
    phi = np.maximum(av / (omega * r), 1e-6)
    F = np.ones(np.broadcast(r, v, omega).shape)
    dlogF = np.zeros_like(F)
    limited = av / (omega * r) <= 1e-6
    for on, dist in ((tip, R - r), (root and r_root > 0, r - r_root)):
        if not on:
            continue
        f = 0.5 * n_blades * dist / (r * phi)
        Fi, dFi = _prandtl_factor(f)
        F = F * Fi
        dlogF = dlogF + np.where(limited, 0.0, dFi * (-f / np.maximum(av, 1e-300))
                                 ) / np.maximum(Fi, 1e-3)
    Fc = np.maximum(F, 1e-3)
    if not derivative:
        return Fc
    return Fc, np.where(F > 1e-3, F * dlogF * np.sign(v), 0.0)


def uniform_update(v, thrust_be, rho, area, kappa, chord, n_blades, omega, r, w):
    """Newton step on T_BE(v) = 2 rho A v|v| / kappa^2 for the uniform induced velocity.

    v, thrust_be, rho, kappa, omega : (n,). r, w : stations and weights. Returns new v (n,).
    """
    dT_be = -n_blades * 0.5 * rho * chord * A0 * omega * float(np.sum(w * r))
    f = thrust_be - 2 * rho * area * v * np.abs(v) / kappa**2
    df = dT_be - 4 * rho * area * np.abs(v) / kappa**2
    return v - f / df


def annulus_update(v, dT_be, rho, kappa, F, chord, n_blades, omega, r, dF=0.0, d_be=None):
    """Newton step per station on dT_BE(r) = 4 pi rho F(v) r v|v| / kappa^2 (per unit span).

    v, dT_be, F, dF (= dF/dv) : (n, Nr); rho, kappa, omega : (n, 1). d_be : the blade-element
    slope d(dT_BE)/dv (n, Nr), default linear thin-airfoil theory. Returns new v (n, Nr).
    """
    if d_be is None:
        d_be = -n_blades * 0.5 * rho * chord * A0 * omega * r
    f = dT_be - 4 * np.pi * rho * F * r * v * np.abs(v) / kappa**2
    df = d_be - 4 * np.pi * rho * r * (2 * F * np.abs(v) + dF * v * np.abs(v)) / kappa**2
    return v - f / df
