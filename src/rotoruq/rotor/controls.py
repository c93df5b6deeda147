"""Swashplate commands: theta_sw(psi) = theta_0 + theta_1c cos(psi) + theta_1s sin(psi).

Conventions (rotor turning counter-clockwise seen from above, psi = 0 over the tail):
``collective_deg`` = theta_0, ``lateral_deg`` = theta_1c, ``longitudinal_deg`` = theta_1s, all at
the pitch link (the blade follows through the pitch-link spring).
"""

from __future__ import annotations

import numpy as np

__all__ = ["swashplate_harmonics"]


def swashplate_harmonics(collective_deg, lateral_deg, longitudinal_deg, n_harmonics: int):
    """Complex harmonics Theta_k (n, K) of the commanded pitch [rad], with
    theta(psi) = Re(sum_k Theta_k exp(i k psi))."""
    th0 = np.deg2rad(np.asarray(collective_deg, dtype=float))
    out = np.zeros(th0.shape + (n_harmonics + 1,), dtype=complex)
    out[..., 0] = th0
    out[..., 1] = np.deg2rad(lateral_deg) - 1j * np.deg2rad(longitudinal_deg)
    return out
