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

__all__ = ["HarmonicBasis", "structural_operator", "fixed_sum", "apply_blocks"]


class HarmonicBasis:
    """Synthesis and analysis between harmonics k = 0..H and an azimuth grid.

    No matrix product: BLAS kernels block differently for different batch sizes and change
    the last bits, so sums are elementwise terms or per-row reductions (see fixed_sum).
    """

    def __init__(self, psi: np.ndarray, n_harmonics: int):
        self.psi = psi
        self.k = np.arange(n_harmonics + 1)
        kp = np.outer(self.k, psi)
        self.cos, self.sin = np.cos(kp), np.sin(kp)               # (K, Npsi)
        scale = np.full(self.k.shape, 2.0 / psi.size)
        scale[0] = 1.0 / psi.size
        # analysis weights: Q_k = sum_j f_j (W[k, j] + i W[K + k, j])
        self._W = np.concatenate([self.cos * scale[:, None], -self.sin * scale[:, None]])

    def synth(self, Q):
        """(..., K) complex -> (..., Npsi) real: sum_k Re(Q_k) cos k psi - Im(Q_k) sin k psi."""
        out = Q[..., 0].real[..., None] * self.cos[0]
        for k in range(1, self.k.size):
            out = out + (Q[..., k].real[..., None] * self.cos[k]
                         - Q[..., k].imag[..., None] * self.sin[k])
        return out

    def synth_d(self, Q):
        """d/dpsi of the series, (..., K) -> (..., Npsi)."""
        out = np.zeros(Q.shape[:-1] + (self.psi.size,))
        for k in range(1, self.k.size):
            out = out - k * (Q[..., k].real[..., None] * self.sin[k]
                             + Q[..., k].imag[..., None] * self.cos[k])
        return out

    def analyse(self, f):
        """(..., Npsi) real -> (..., K) complex: one per-row reduction over azimuth."""
        K = self.k.size
        prod = np.multiply(f[..., None, :], self._W,
                           out=np.empty(f.shape[:-1] + (2 * K, self.psi.size)))
        s = np.add.reduce(prod, axis=-1)
        return s[..., :K] + 1j * s[..., K:]


def fixed_sum(x, w=None):
    """sum_j x[..., j] (* w[j]) as one reduction over the last axis of a C-contiguous array.

    The reduction runs row by row along contiguous memory, so its order (numpy's pairwise
    summation) is the same for a sample whatever the other samples or the batch size; a
    matrix product (BLAS) or a reduction over a strided axis may change the last bits.
    """
    out = np.empty(x.shape)
    if w is None:
        out[...] = x
    else:
        np.multiply(x, w, out=out)
    return np.add.reduce(out, axis=-1)


def apply_blocks(A, q):
    """y[:, i, k] = sum_j A[:, k, i, j] q[:, j, k] for A (n, K, 3, 3), q (n, 3, K)."""
    At = np.moveaxis(A, 1, -1)                                  # (n, i, j, K)
    y = At[:, :, 0, :] * q[:, None, 0, :]
    for j in range(1, q.shape[1]):
        y = y + At[:, :, j, :] * q[:, None, j, :]
    return y


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
