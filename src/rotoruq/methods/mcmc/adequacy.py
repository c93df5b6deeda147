"""Is the emulator good where the posterior is? Its error against the data noise, and where to
add model runs.

The emulator's error matters relative to what the data can resolve: the noise standard
deviation of the experiments' mean per response, ``sqrt(diag(P^-1))`` with ``P`` the summed
noise precision (the noise std itself with one experiment). Two ratios per response:

* ``loo_ratio``: leave-one-out RMSE of the emulator over its build design (the prior) divided
  by that noise std;
* ``posterior_ratio``: root mean Kriging variance over posterior draws, square-rooted, divided
  by that noise std: the emulator's own estimate of its error where the posterior is.

:func:`~rotoruq.methods.mcmc.calibrate_bayes` warns when a ``posterior_ratio`` exceeds
:data:`WARN_RATIO` and, with ``refine=RefineConfig(...)``, adds model runs at the posterior
draws where the emulator's std relative to the noise is largest until every ratio is below
``target_ratio`` or the run budget is spent.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import ParameterError

__all__ = ["RefineConfig", "EmulatorAdequacy", "WARN_RATIO"]

# Above this the emulator's error is a third of the noise or more: a mean-only posterior
# (emulator_variance=False) is then over-confident by >= 5 % in std per response
# (1 / sqrt(1 + 0.3^2) = 0.958), and with the variance on the posterior is visibly widened by
# the emulator rather than by the data.
WARN_RATIO = 0.3
# posterior draws on which the ratio is measured and refinement candidates are chosen
N_CHECK_DRAWS = 400


@dataclass(frozen=True)
class RefineConfig:
    """Adaptive refinement of an emulator over the posterior.

    Parameters
    ----------
    n_samples : int, optional
        The most model runs added in all, the run budget (default 40).
    target_ratio : float, optional
        Stop when every response's ``posterior_ratio`` is below this (default 0.1: the
        emulator's error a tenth of the noise).
    batch : int, optional
        Runs added per round (default 5; each round refits the GP and reruns the chains).
    """

    n_samples: int = 40
    target_ratio: float = 0.1
    batch: int = 5

    def __post_init__(self):
        if int(self.n_samples) < 1 or int(self.batch) < 1:
            raise ParameterError(f"RefineConfig needs n_samples >= 1 and batch >= 1, got "
                                 f"{self.n_samples} and {self.batch}")
        if not (np.isfinite(self.target_ratio) and self.target_ratio > 0):
            raise ParameterError(f"RefineConfig target_ratio must be > 0, got "
                                 f"{self.target_ratio!r}")


@dataclass(frozen=True, eq=False)
class EmulatorAdequacy:
    """The emulator's error against the data noise, per response.

    Attributes
    ----------
    names_out : tuple of str
        The m calibrated responses.
    noise_std : ndarray of shape (m,)
        Noise std of the experiments' mean, data units.
    loo_ratio : ndarray of shape (m,)
        Leave-one-out RMSE over ``noise_std`` (over the final build design).
    posterior_ratio : ndarray of shape (m,)
        RMS Kriging std over posterior draws, over ``noise_std`` (final chains).
    runs_added : tuple of int
        Model runs added by each refinement round (empty without refinement).
    posterior_ratio_per_round : ndarray of shape (rounds + 1, m) or None
        ``posterior_ratio`` before each round and at the end.
    target_ratio : float or None
        The refinement target (None without refinement).
    """

    names_out: tuple[str, ...]
    noise_std: np.ndarray
    loo_ratio: np.ndarray
    posterior_ratio: np.ndarray
    runs_added: tuple[int, ...] = ()
    posterior_ratio_per_round: np.ndarray | None = None
    target_ratio: float | None = None

    @property
    def n_added(self) -> int:
        """Model runs added by refinement in all."""
        return int(sum(self.runs_added))


def noise_std_of_mean(lik_pack: tuple) -> np.ndarray:
    """sqrt(diag(P^-1)) (m,) from a :class:`.likelihood.GaussianLikelihood` pack."""
    return np.sqrt(np.diag(lik_pack[5]))


def check_draws(theta_chains: np.ndarray) -> np.ndarray:
    """Up to :data:`N_CHECK_DRAWS` distinct posterior draws, evenly spaced over the pooled
    chains (c, n, d) -> (k, d) (no randomness: the same chains give the same draws)."""
    flat = theta_chains.reshape(-1, theta_chains.shape[-1])
    idx = np.unique(np.linspace(0, flat.shape[0] - 1, min(N_CHECK_DRAWS, flat.shape[0]))
                    .astype(int))
    return np.unique(flat[idx], axis=0)


def posterior_ratio(var: np.ndarray, noise_sd: np.ndarray) -> np.ndarray:
    """RMS emulator std over draws divided by the noise std, var (k, m) -> (m,)."""
    return np.sqrt(np.mean(var, axis=0)) / noise_sd


def pick_runs(draws: np.ndarray, var: np.ndarray, noise_sd: np.ndarray, k: int) -> np.ndarray:
    """The k draws (k, d) with the largest emulator std relative to the noise (the worst
    response at each draw), greedily spread: a pick's Kriging variance is zero after the
    refit, so draws nearer to an earlier pick than to any other candidate's nearest
    neighbour are skipped while others remain."""
    score = np.max(np.sqrt(var) / noise_sd, axis=1)
    order = np.argsort(-score, kind="stable")
    span = draws.max(0) - draws.min(0)
    span = np.where(span > 0, span, 1.0)
    u = draws / span
    # typical spacing of the draws: median distance to the nearest other draw
    if len(u) > 1:
        d2 = ((u[:, None, :] - u[None, :, :]) ** 2).sum(-1)
        np.fill_diagonal(d2, np.inf)
        spacing = float(np.median(np.sqrt(d2.min(1))))
    else:
        spacing = 0.0
    picked: list[int] = []
    for i in order:
        if len(picked) == k:
            break
        if all(np.sqrt(((u[i] - u[j]) ** 2).sum()) > 3.0 * spacing for j in picked):
            picked.append(int(i))
    for i in order:  # too few far apart: fill with the next best
        if len(picked) == k:
            break
        if int(i) not in picked:
            picked.append(int(i))
    return draws[np.array(picked, dtype=int)]
