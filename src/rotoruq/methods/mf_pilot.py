"""Predicted variances that account for the pilot's uncertainty.

The weights of a multi-fidelity estimator come from the pilot's covariance, not the true
one, so its variance exceeds what the pilot predicts: the plug-in prediction
``V(w_hat; C_hat)`` of weights ``w_hat`` fitted to ``C_hat`` evaluated at ``C_hat`` is
optimistic (about 1.15-1.5x with a 20-point pilot and three models). The estimate stays
unbiased (the pilot is not reused), so over fresh pilots the estimator's variance is
``E[V(w_hat; C)]``: the weights' variance under the true covariance.

:func:`bootstrap_variance` estimates that by the bootstrap optimism correction (Efron 1983,
"Estimating the error rate of a prediction rule", JASA 78(382)): resample the pilot's rows,
fit the weights ``w_b`` to the resampled covariance ``C_b`` and measure the optimism
``V(w_b; C_emp) - V(w_b; C_b)`` (in the bootstrap world the pilot's empirical distribution
is the truth, its covariance ``C_emp = (n - 1) / n C_hat``, the mean of the resamples'
``C_b``); the corrected prediction is ``V(w_hat; C_hat)`` plus its mean. An estimator with no
fitted weights (model 0 alone) gets no correction. The allocation stays the one
optimised on the pilot (re-optimising it per resample would cost a search each).

:func:`pilot_too_small` states the rule for the warning: control variates with estimated
coefficients inflate the variance by about ``(n - 2) / (n - q - 2)`` for ``q`` controls and
``n`` points (Lavenberg, Welch 1981, "A perspective on the use of control variables to
increase the efficiency of Monte Carlo simulations", Management Science 27(3)); with ``q = K -
1`` low-fidelity models the pilot is too small when that exceeds 1.1, ``n < 11 (K - 1) + 2``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["bootstrap_variance", "pilot_too_small", "min_pilot"]


def min_pilot(K: int) -> int:
    """Fewest pilot points for K models by the rule of the module doc, ``11 (K - 1) + 2``.

    Examples
    --------
    >>> min_pilot(3)
    24
    """
    return 11 * (K - 1) + 2 if K > 1 else 2


def pilot_too_small(n_pilot: int, K: int) -> str | None:
    """The warning for a pilot of ``n_pilot`` points over K models, or None when it is large
    enough (:func:`min_pilot`).

    Examples
    --------
    >>> pilot_too_small(50, 3) is None
    True
    >>> print(pilot_too_small(20, 3))  # doctest: +NORMALIZE_WHITESPACE
    multifidelity pilot: 20 points for 3 models; the weights' error inflates the estimator
    variance by about (n - 2) / (n - K - 1) = 1.12 > 1.1 (Lavenberg and Welch 1981): use
    n_pilot >= 24
    """
    if n_pilot >= min_pilot(K):
        return None
    q = K - 1
    factor = (n_pilot - 2) / (n_pilot - q - 2) if n_pilot > q + 2 else float("inf")
    return (f"multifidelity pilot: {n_pilot} points for {K} models; the weights' error "
            f"inflates the estimator variance by about (n - 2) / (n - K - 1) = {factor:.3g} "
            f"> 1.1 (Lavenberg and Welch 1981): use n_pilot >= {min_pilot(K)}")


def bootstrap_variance(Y: np.ndarray, weights: Callable[[np.ndarray], np.ndarray],
                       variance: Callable[[np.ndarray, np.ndarray, bool], np.ndarray],
                       n_boot: int, rng: np.random.Generator) -> tuple[float, float]:
    """Plug-in and bootstrap-corrected predicted variance of an estimator fitted on a pilot.

    Parameters
    ----------
    Y : ndarray of shape (n, K)
        The pilot: every model's response at each of n points.
    weights : callable
        ``weights(Ys)`` -> the estimator's weights fitted to each pilot of the stack ``Ys``
        (B, n, K), stacked on a first axis of length B.
    variance : callable
        ``variance(W, Ys, population)`` -> (B,) the variance of the estimator with weights
        ``W[b]`` when the models' moments are those of the pilot ``Ys[b]`` (``Ys`` of shape
        (B, n, K) or (1, n, K), one pilot for every weight): its unbiased sample moments,
        or with ``population`` those of its empirical distribution (covariance divided by n,
        not n - 1).
    n_boot : int
        Resamples (0 returns the plug-in twice).
    rng : numpy.random.Generator
        The resampling's random numbers.

    Returns
    -------
    tuple of float
        ``(plug_in, corrected)``, corrected >= 0.

    Examples
    --------
    The sample mean of model 0 has no fitted weights: on average no optimism.

    >>> import numpy as np
    >>> Y = np.random.default_rng(0).normal(size=(30, 1))
    >>> def var(W, Ys, population):
    ...     v = Ys[:, :, 0].var(axis=1, ddof=0 if population else 1) / 30
    ...     return np.broadcast_to(v, (len(W),))
    >>> p, c = bootstrap_variance(Y, lambda Ys: np.zeros((len(Ys), 0)), var, 400,
    ...                           np.random.default_rng(1))
    >>> bool(abs(c / p - 1) < 0.02)
    True
    """
    plug = float(variance(weights(Y[None]), Y[None], False)[0])
    if n_boot <= 0:
        return plug, plug
    n = Y.shape[0]
    Yb = Y[rng.integers(0, n, (n_boot, n))]
    Wb = weights(Yb)
    optimism = variance(Wb, Y[None], True) - variance(Wb, Yb, False)
    return plug, max(plug + float(np.mean(optimism)), 0.0)
