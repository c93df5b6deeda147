"""Moré, Garbow & Hillstrom (ACM TOMS 7(1), 1981) least-squares test problems as batched
residual functions ``r(X: (k, p)) -> (k, n_res)``, for verifying solvers: numbers 1
(Rosenbrock), 2 (Freudenstein-Roth), 8 (Bard), 12 (Box 3-D), 6 (Jennrich-Sampson) and 16
(Brown-Dennis)."""

from __future__ import annotations

import numpy as np

__all__ = ["rosenbrock", "freudenstein_roth", "bard", "box3d", "jennrich_sampson",
           "brown_dennis"]


def rosenbrock(X: np.ndarray) -> np.ndarray:
    return np.column_stack([10 * (X[:, 1] - X[:, 0] ** 2), 1 - X[:, 0]])


def freudenstein_roth(X: np.ndarray) -> np.ndarray:
    x1, x2 = X[:, 0], X[:, 1]
    return np.column_stack(
        [-13 + x1 + ((5 - x2) * x2 - 2) * x2, -29 + x1 + ((x2 + 1) * x2 - 14) * x2]
    )


BARD_Y = np.array(
    [0.14, 0.18, 0.22, 0.25, 0.29, 0.32, 0.35, 0.39, 0.37, 0.58, 0.73, 0.96, 1.34, 2.10, 4.39]
)


def bard(X: np.ndarray) -> np.ndarray:
    i = np.arange(1, 16)
    v = 16 - i
    w = np.minimum(i, v)
    return BARD_Y - (X[:, :1] + i / (v * X[:, 1:2] + w * X[:, 2:3]))


def box3d(X: np.ndarray) -> np.ndarray:
    t = 0.1 * np.arange(1, 11)
    x1, x2, x3 = X[:, :1], X[:, 1:2], X[:, 2:3]
    return np.exp(-t * x1) - np.exp(-t * x2) - x3 * (np.exp(-t) - np.exp(-10 * t))


def jennrich_sampson(X: np.ndarray) -> np.ndarray:
    i = np.arange(1, 11)
    return 2 + 2 * i - (np.exp(i * X[:, :1]) + np.exp(i * X[:, 1:2]))


def brown_dennis(X: np.ndarray) -> np.ndarray:
    t = np.arange(1, 21) / 5
    a = X[:, :1] + t * X[:, 1:2] - np.exp(t)
    b = X[:, 2:3] + X[:, 3:4] * np.sin(t) - np.cos(t)
    return a**2 + b**2
