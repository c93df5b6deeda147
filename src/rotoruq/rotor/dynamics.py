"""Blade degrees of freedom (flap beta, lag zeta, feathering theta about the hinge/bearing) as
truncated Fourier series over one revolution, and their linear structural operators.

A periodic quantity is q(psi) = Re(sum_{k=0..H} Q_k exp(i k psi)); its time derivative is
Re(sum i k Omega Q_k exp(i k psi)). For each harmonic the equations of motion

    I_b beta'' + C_b beta' + (K_b + Omega^2 (I_b + e S)) beta          = M_flap
    I_l zeta'' + C_l zeta' + (K_l + Omega^2 e S) zeta                   = M_lag
    I_p th''   + C_p (th' - th_sw') + (K_p + I_p Omega^2) th
               - K_p (th_sw - tan(delta3) beta)                         = M_pitch

(Omega^2 I_p th: propeller moment; K_p = k_link * arm^2) become a 3x3 complex system
Z_k(Omega) Q_k = F_k.
"""

from __future__ import annotations

import numpy as np

__all__ = ["HarmonicBasis", "structural_operator"]


class HarmonicBasis:
    """Synthesis and analysis matrices between harmonics k = 0..H and an azimuth grid."""

    def __init__(self, psi: np.ndarray, n_harmonics: int):
        self.psi = psi
        self.k = np.arange(n_harmonics + 1)
        self.E = np.exp(1j * np.outer(self.k, psi))          # (K, Npsi) synthesis
        scale = np.full(self.k.shape, 2.0 / psi.size)
        scale[0] = 1.0 / psi.size
        self.A = (np.conj(self.E) * scale[:, None]).T         # (Npsi, K) analysis

    def synth(self, Q):
        """(..., K) complex -> (..., Npsi) real."""
        return (Q @ self.E).real

    def synth_d(self, Q):
        """d/dpsi of the series, (..., K) -> (..., Npsi)."""
        return ((1j * self.k * Q) @ self.E).real

    def synth_dd(self, Q):
        return ((-(self.k**2) * Q) @ self.E).real

    def analyse(self, f):
        """(..., Npsi) real -> (..., K) complex."""
        return f @ self.A


def structural_operator(k, omega, I_b, S, e, I_l, I_p, K_b, C_b, K_l, C_l, K_p, C_p, tan_d3):
    """Z of shape (n, K, 3, 3) for DOFs (beta, zeta, theta); inputs (n,) or scalars."""
    n = np.broadcast(omega, K_b, K_l, K_p).shape[0]
    w = np.asarray(omega)[:, None] * k[None, :]               # (n, K)
    Om2 = (np.asarray(omega) ** 2)[:, None]
    Z = np.zeros((n, k.size, 3, 3), dtype=complex)
    Z[..., 0, 0] = (np.asarray(K_b)[:, None] + Om2 * (I_b + e * S) - w**2 * I_b
                    + 1j * w * np.asarray(C_b)[:, None])
    Z[..., 1, 1] = (np.asarray(K_l)[:, None] + Om2 * e * S - w**2 * I_l
                    + 1j * w * np.asarray(C_l)[:, None])
    Z[..., 2, 2] = (np.asarray(K_p)[:, None] + Om2 * I_p - w**2 * I_p
                    + 1j * w * np.asarray(C_p)[:, None])
    Z[..., 2, 0] = np.asarray(K_p)[:, None] * tan_d3
    return Z
