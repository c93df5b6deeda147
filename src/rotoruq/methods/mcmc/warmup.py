"""The warm-up of a Markov chain from its own draws: the MSER-5 rule (White 1997).

A chain started away from the bulk of its target drifts before it settles; draws of the drift
bias every summary taken over the chain. A fixed burn-in guesses how long the drift lasts;
the Marginal Standard Error Rule measures it: for every candidate truncation point ``k`` it
takes the squared standard error of the mean of the draws after ``k`` (their variance over
the number left, ``sum (x_j - mean)^2 / (n - k)^2``) and picks the ``k`` that minimises it.
Cutting drift shrinks the variance faster than losing draws grows the error; cutting
stationary draws does not. MSER-5 applies the rule to the means of batches of 5 draws (less
noise in the statistic, a truncation point every 5 draws).

The search stops at half the chain (White, Cobb and Spratt 2000): near the end of a chain the
statistic is taken over a handful of draws and its minimum says nothing. A truncation point
at that cap means the chain did not settle within the first half: the rule's answer is then
a lower bound, and :attr:`WarmUp.settled` is False.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ...errors import ParameterError

__all__ = ["WarmUp", "mser_warm_up", "BATCH"]

#: Draws per batch of the MSER-5 rule.
BATCH = 5
#: Fewest batches the rule is taken over (below it the statistic is noise).
MIN_BATCHES = 4


@dataclass(frozen=True, eq=False)
class WarmUp:
    """The MSER-5 warm-up of one set of chains (:func:`mser_warm_up`).

    Attributes
    ----------
    steps : int
        Draws to drop at the start of every chain: the largest truncation point over the
        chains and parameters (a multiple of the batch size).
    per_series : ndarray of shape (n_chains, d)
        The truncation point of each chain and parameter, draws.
    cap : int
        The largest truncation point the rule considers (half of each chain, in whole
        batches), draws.
    settled : bool
        No chain and parameter had its truncation point at ``cap`` (where it did, the
        chain had not settled within its first half and ``steps`` is a lower bound).
    """

    steps: int
    per_series: np.ndarray
    cap: int
    settled: bool


def _mser_point(z: np.ndarray, k_max: int) -> int:
    """The number of leading batches (0..k_max) that minimises the MSER statistic of the
    batch means ``z`` (b,); the first of equal minima."""
    b = z.shape[0]
    c = z - z.mean()  # centred: the running sums below lose no digits to a large mean
    s1 = np.cumsum(c[::-1])[::-1][: k_max + 1]  # sum of z[k:] - mean, k = 0..k_max
    s2 = np.cumsum((c * c)[::-1])[::-1][: k_max + 1]
    left = b - np.arange(k_max + 1, dtype=float)
    stat = np.maximum(s2 - s1 * s1 / left, 0.0) / (left * left)
    return int(np.argmin(stat))


def mser_warm_up(chains: ArrayLike, *, batch: int = BATCH) -> WarmUp:
    """The MSER warm-up of chains (White 1997): the truncation point minimising the
    marginal standard error of the mean of what is left, largest over chains and parameters.

    Parameters
    ----------
    chains : array_like of shape (n_draws,), (n_draws, d) or (n_chains, n_draws, d)
        Draws in chain order, any units; every value finite.
    batch : int, optional
        Draws per batch mean (default 5: MSER-5). A trailing part batch is left out of the
        statistic.

    Returns
    -------
    WarmUp
        The warm-up in draws (a multiple of ``batch``, at most ``cap`` = half of the whole
        batches of a chain), per chain and parameter, and whether every series settled
        before the cap.

    Raises
    ------
    ParameterError
        When ``chains`` has another shape, a non-finite value, fewer than
        ``4 * batch`` draws per chain or ``batch`` < 1.

    Examples
    --------
    A chain that starts 20 standard deviations off and relaxes with AR(1) coefficient 0.9:
    the drift lasts about 50 steps (20 x 0.9^50 < 0.11); a stationary chain needs none.

    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> x = np.empty(2000); x[0] = 20.0
    >>> for t in range(1, 2000):
    ...     x[t] = 0.9 * x[t - 1] + np.sqrt(1 - 0.81) * rng.standard_normal()
    >>> w = mser_warm_up(x)
    >>> 30 <= w.steps <= 120, w.cap, w.settled
    (True, 1000, True)
    >>> mser_warm_up(rng.standard_normal((4, 1000, 2))).steps < 100
    True
    """
    batch = int(batch)
    if batch < 1:
        raise ParameterError(f"mser_warm_up: batch must be >= 1; got {batch}")
    x = np.asarray(chains, dtype=float)
    if x.ndim == 1:
        x = x[None, :, None]
    elif x.ndim == 2:
        x = x[None]
    if x.ndim != 3:
        raise ParameterError(f"mser_warm_up: chains must have shape (n_draws,), (n_draws, d) "
                             f"or (n_chains, n_draws, d); got shape {np.shape(chains)}")
    c, n, d = x.shape
    b = n // batch
    if b < MIN_BATCHES or c < 1 or d < 1:
        raise ParameterError(f"mser_warm_up: need at least {MIN_BATCHES * batch} draws per "
                             f"chain (MSER-{batch} takes {MIN_BATCHES} batches of {batch} at "
                             f"least), 1 chain and 1 parameter; got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ParameterError("mser_warm_up: chains hold non-finite values (NaN or inf)")
    z = x[:, : b * batch].reshape(c, b, batch, d).mean(2)  # (c, b, d)
    k_max = b // 2
    points = np.array([[_mser_point(z[i, :, j], k_max) for j in range(d)] for i in range(c)],
                      dtype=np.int64)
    return WarmUp(steps=int(points.max()) * batch, per_series=points * batch,
                  cap=k_max * batch, settled=bool(np.all(points < k_max)))
