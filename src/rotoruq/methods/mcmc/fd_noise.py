"""Finite differences of a noisy function: its noise level and a Hessian with steps set by it.

A log posterior computed through a trim iteration, an emulator or any solver with a
tolerance carries numerical noise: values at nearby points scatter by some ``eps_f`` around a
smooth function. A central second difference with step ``h`` then errs by about
``4 eps_f / h**2`` (noise) plus ``h**2 |f''''| / 12`` (truncation), so a fixed small step gives
a curvature that is mostly noise. Following Moré and Wild:

* :func:`noise_level` estimates ``eps_f`` from a few equally spaced values along a direction
  (ECnoise: the k-th differences of the values; for noise, their scaled root mean square
  ``sqrt(gamma_k mean((Delta^k f)^2))``, ``gamma_k = (k!)^2 / (2k)!``, is the same for every
  k and the differences change sign; Moré and Wild 2011, "Estimating computational noise",
  SIAM J. Sci. Comput. 33(3));
* :func:`noisy_hessian` takes each direction's second-difference step from that noise level
  and the curvature, ``h = (eps_f / |f''|)**(1/4)``, after a first estimate at
  ``h = eps_f**(1/4)`` (Moré and Wild 2012, "Estimating derivatives of noisy simulations",
  ACM TOMS 38(3), their procedure for ``f''``), and marks a direction whose second difference
  stays within the noise at the largest step allowed as without measurable curvature.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from math import factorial

import numpy as np

from ...errors import ParameterError

__all__ = ["HessianEstimate", "NoiseEstimate", "coordinate_noise", "noise_level",
           "noisy_hessian"]

#: Differences of order 1 to this one are compared (Moré and Wild 2011 use 6).
_MAX_ORDER = 6
#: A second difference counts as curvature when it is this many noise levels (Moré and Wild
#: 2012's tau_1).
_SIGNAL = 100.0
#: A second difference is accepted as curvature from this many noise levels (the step is
#: chosen for _SIGNAL; the noise's scatter may leave it somewhat below).
_ACCEPT = 10.0
#: Steps of the noise table in scaled coordinates, tried from the first down (a step too
#: large for the function's smooth part to vanish from the differences gives no estimate).
_NOISE_STEPS = (1e-6, 1e-8, 1e-4)
#: Points of the noise table (Moré and Wild 2011: 7 to 9).
_NOISE_POINTS = 9


@dataclass(frozen=True)
class NoiseEstimate:
    """The noise level of a function along one direction (:func:`noise_level`).

    Attributes
    ----------
    level : float
        ``eps_f``, the standard deviation of the noise, in the function's units (0 when all
        the values are equal: noise below the values' resolution).
    order : int
        The order of the differences it comes from (0 when ``level`` is 0 or unknown).
    found : bool
        The differences of three consecutive orders agree within a factor 4 and change sign
        (ECnoise's test); False: the spacing was too large for the smooth part to vanish,
        and ``level`` is the smallest of the scaled differences, an upper bound.
    """

    level: float
    order: int
    found: bool


def noise_level(values: np.ndarray) -> NoiseEstimate:
    """Noise level of a function from values at equally spaced points along a line (ECnoise).

    Parameters
    ----------
    values : array_like of shape (n,)
        ``f(x + i h p)`` for ``i = 0 .. n - 1`` (n >= 4; Moré and Wild use 7 to 9), function
        units; the spacing ``h`` must be small enough for the smooth part of ``f`` to vanish
        from the higher differences.

    Returns
    -------
    NoiseEstimate

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> x = 1.0 + 1e-6 * np.arange(9)
    >>> est = noise_level(np.sin(x) + 1e-5 * rng.standard_normal(9))
    >>> est.found, bool(2e-6 < est.level < 5e-5)
    (True, True)
    """
    f = np.asarray(values, dtype=float).reshape(-1)
    if f.size < 4 or not np.all(np.isfinite(f)):
        raise ParameterError(f"noise_level needs 4 finite values or more, got {f}")
    if np.all(f == f[0]):
        return NoiseEstimate(0.0, 0, True)
    top = min(_MAX_ORDER, f.size - 1)
    levels = np.zeros(top + 1)
    signs = np.zeros(top + 1, dtype=bool)
    diff = f.copy()
    for k in range(1, top + 1):
        diff = np.diff(diff)
        gamma = factorial(k) ** 2 / factorial(2 * k)
        levels[k] = np.sqrt(gamma * np.mean(diff * diff))
        signs[k] = diff.min() < 0 < diff.max()
    for k in range(1, top - 1):
        window = levels[k:k + 3]
        if window.max() <= 4.0 * window.min() and signs[k]:
            return NoiseEstimate(float(levels[k]), k, True)
    k = int(np.argmin(levels[1:])) + 1
    return NoiseEstimate(float(levels[k]), k, False)


def coordinate_noise(fun: Callable[[np.ndarray], np.ndarray], x: np.ndarray,
                     f0: float | None = None) -> np.ndarray:
    """Noise level of a function along each coordinate at a point (:func:`noise_level`).

    Nine values spaced 1e-6 along each coordinate (one batch of points), again at 1e-8 and
    then 1e-4 for the coordinates whose table gave no estimate; without an estimate at any
    spacing, the smallest upper bound. At least the rounding of the value at ``x``
    (``4 eps |f(x)|``).

    Parameters
    ----------
    fun : callable
        ``fun(points)`` with points (k, d) returns the k values (k,).
    x : array_like of shape (d,)
        The point, in coordinates of about unit scale.
    f0 : float, optional
        ``fun(x)``, when known (else evaluated).

    Returns
    -------
    ndarray of shape (d,)
        The noise's standard deviation along each coordinate, function units.

    Examples
    --------
    >>> import numpy as np
    >>> f = lambda z: (z**2).sum(1) + 1e-6 * np.sin(1e7 * z[:, 1])  # rough along z_1 only
    >>> eps = coordinate_noise(f, np.ones(2))
    >>> bool(eps[0] < 1e-14), bool(2e-7 < eps[1] < 4e-6)
    (True, True)
    """
    x = np.asarray(x, dtype=float).reshape(-1)
    d = x.size
    eye = np.eye(d)
    if f0 is None:
        f0 = float(np.asarray(fun(x[None]), dtype=float).reshape(-1)[0])
    offsets = np.arange(_NOISE_POINTS) - _NOISE_POINTS // 2
    noise = np.full(d, np.nan)
    todo = np.arange(d)
    for spacing in _NOISE_STEPS:  # one batch per spacing, for the coordinates not yet found
        if todo.size == 0:
            break
        pts = x[None, None] + spacing * offsets[None, :, None] * eye[todo][:, None, :]
        table = np.asarray(fun(pts.reshape(-1, d)), dtype=float).reshape(todo.size,
                                                                          _NOISE_POINTS)
        left = []
        for i, row in zip(todo, table, strict=True):
            if not np.all(np.isfinite(row)):
                left.append(i)
                continue
            est = noise_level(row)
            if est.found:
                noise[i] = est.level
            else:
                left.append(i)
                noise[i] = est.level if np.isnan(noise[i]) else min(noise[i], est.level)
        todo = np.array(left, dtype=int)
    noise = np.where(np.isfinite(noise), noise, 0.0)
    return np.maximum(noise, 4.0 * np.finfo(float).eps * max(abs(f0), 1.0))


@dataclass(frozen=True)
class HessianEstimate:
    """A finite-difference Hessian with per-direction steps (:func:`noisy_hessian`).

    Attributes
    ----------
    hessian : ndarray of shape (d, d)
        Second derivatives, function units over the coordinates' units squared; a row and
        column of a direction without measurable curvature are 0.
    steps : ndarray of shape (d,)
        The second-difference step of each coordinate, its units.
    noise : ndarray of shape (d,)
        The noise level found along each coordinate, function units.
    measured : ndarray of shape (d,) of bool
        False where the second difference stayed within the noise (below ``10 eps_f``) at
        the largest step allowed: no curvature measurable there.
    n_evaluations : int
        Points evaluated.
    """

    hessian: np.ndarray
    steps: np.ndarray
    noise: np.ndarray
    measured: np.ndarray
    n_evaluations: int


def noisy_hessian(fun: Callable[[np.ndarray], np.ndarray], x: np.ndarray, *,
                  max_step: float | np.ndarray = 1.0) -> HessianEstimate:
    """Hessian of a noisy function, each coordinate's step set by its noise and curvature.

    Along each coordinate ``i``: the noise level ``eps_i`` (:func:`coordinate_noise`), a
    first curvature ``mu_a`` at the step ``eps_i**(1/4)``, then the step
    ``h_i = (eps_i / |mu_a|)**(1/4)`` (the step that balances the second difference's
    truncation and noise errors for a function whose fourth derivative is of the order of its
    second; Moré and Wild 2012) and the curvature there, the step lengthened to
    ``sqrt(100 eps_i / |mu_a|)`` where that is longer (a weak curvature whose second
    difference would stay within the noise), at most ``max_step``. A coordinate whose second
    difference stays below ``10 eps_i`` has no measurable curvature (``measured`` False, its
    row and column 0). The mixed derivatives use the four points ``x +- h_i e_i +- h_j e_j``.
    Every stage is one batch of points.

    Parameters
    ----------
    fun : callable
        ``fun(points)`` with points (k, d) returns the k values (k,); finite near ``x``.
    x : array_like of shape (d,)
        The point, in coordinates of about unit scale (the steps' scale).
    max_step : float or array_like of shape (d,)
        The largest step per coordinate (default 1: the scale of the coordinates), e.g. the
        distance to a bound of the support.

    Returns
    -------
    HessianEstimate

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> A = np.array([[2.0, 0.5], [0.5, 1.0]])
    >>> f = lambda z: 0.5 * np.einsum("ki,ij,kj->k", z, A, z) + 1e-6 * rng.standard_normal(len(z))
    >>> est = noisy_hessian(f, np.zeros(2))
    >>> bool(np.allclose(est.hessian, A, rtol=0.02)), est.measured.tolist()
    (True, [True, True])
    """
    x = np.asarray(x, dtype=float).reshape(-1)
    d = x.size
    hmax = np.broadcast_to(np.asarray(max_step, dtype=float), (d,)).copy()
    if d == 0 or not np.all(np.isfinite(x)) or np.any(~(hmax > 0)):
        raise ParameterError(f"noisy_hessian needs a finite point and steps > 0, got x = {x}, "
                             f"max_step = {hmax}")
    n_eval = 0

    def values(points: np.ndarray) -> np.ndarray:
        nonlocal n_eval
        n_eval += points.shape[0]
        v = np.asarray(fun(points), dtype=float).reshape(-1)
        if v.shape != (points.shape[0],):
            raise ParameterError(f"fun returned {v.shape} values for {points.shape[0]} points")
        return v

    eye = np.eye(d)
    f0 = float(values(x[None])[0])
    noise = coordinate_noise(values, x, f0)

    def curvature(h: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Central second differences along the coordinates ``rows``, steps ``h[rows]``."""
        step = h[rows, None] * eye[rows]
        v = values(np.concatenate([x + step, x - step]))
        second = v[:rows.size] - 2.0 * f0 + v[rows.size:]
        return second / (h[rows] ** 2), second

    # a first curvature at eps**(1/4); where its second difference is within the noise,
    # the largest step allowed instead
    h_a = np.minimum(noise ** 0.25, hmax)
    every = np.arange(d)
    mu_a, second = curvature(h_a, every)
    weak = ~(np.abs(second) >= _SIGNAL * noise)
    if weak.any():
        rows = np.flatnonzero(weak)
        mu_a[rows], second_max = curvature(hmax, rows)
        weak[rows] = ~(np.abs(second_max) >= _ACCEPT * noise[rows])
    # the step balancing truncation and noise, lengthened where the curvature is so weak
    # that it would leave the second difference within 100 noise levels
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = noise / np.abs(mu_a)
        h_b = np.maximum(ratio ** 0.25, np.sqrt(_SIGNAL * ratio))
    h_b = np.where(weak | ~np.isfinite(h_b), hmax, np.minimum(h_b, hmax))
    mu_b, second = curvature(h_b, every)
    measured = ~weak & np.isfinite(mu_b) & (np.abs(second) >= _ACCEPT * noise)
    H = np.zeros((d, d))
    H[np.diag_indices(d)] = np.where(measured, mu_b, 0.0)
    idx = np.flatnonzero(measured)
    pairs = [(i, j) for a, i in enumerate(idx) for j in idx[a + 1:]]
    if pairs:
        corners = []
        for i, j in pairs:
            hi, hj = h_b[i] * eye[i], h_b[j] * eye[j]
            corners += [x + hi + hj, x + hi - hj, x - hi + hj, x - hi - hj]
        v = values(np.array(corners)).reshape(-1, 4)
        for (i, j), (pp, pm, mp, mm) in zip(pairs, v, strict=True):
            H[i, j] = H[j, i] = (pp - pm - mp + mm) / (4.0 * h_b[i] * h_b[j])
    return HessianEstimate(hessian=H, steps=h_b, noise=noise, measured=measured,
                           n_evaluations=n_eval)
