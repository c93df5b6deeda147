"""The GP emulator of a calibration, fitted on an LHS design of its prior: one home for the
calibration (:func:`~rotoruq.methods.mcmc.bayes.calibrate_bayes`) and its self-check
(:func:`~rotoruq.methods.mcmc.sbc.simulation_based_calibration`)."""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import EvaluationError
from ...params import ParameterSpace
from ..surrogate import GaussianProcess

__all__ = ["EmulatorBuild", "fit_on_prior"]


@dataclass(frozen=True, eq=False)
class EmulatorBuild:
    """A fitted emulator and its build runs.

    gp : the fitted copy. inputs (k, d), outputs (k, m) : the build runs that succeeded.
    n_evaluations : build runs spent (k plus the failed ones).
    """

    gp: GaussianProcess
    inputs: np.ndarray
    outputs: np.ndarray
    n_evaluations: int


def fit_on_prior(emulator: GaussianProcess, prior: ParameterSpace,
                 fn: Callable[[np.ndarray], np.ndarray], n_samples: int, *,
                 design_seed: Any, fit_seed: Any) -> EmulatorBuild:
    """Fit a copy of ``emulator`` on ``n_samples`` LHS points of ``prior`` through ``fn``.

    The caller's emulator stays unfitted; a copy without a seed of its own gets ``fit_seed``
    (so its optimizer restarts are reproducible). Build runs with a non-finite response are
    left out; fewer than d + 2 left is an error.

    Examples
    --------
    >>> from rotoruq.params import Uniform
    >>> prior = ParameterSpace([("a", Uniform(0, 1))])
    >>> b = fit_on_prior(GaussianProcess(), prior, lambda x: np.sin(3 * x), 12,
    ...                  design_seed=np.random.SeedSequence(0), fit_seed=1)
    >>> b.inputs.shape, b.n_evaluations
    ((12, 1), 12)
    """
    gp = copy.copy(emulator)
    if gp.seed is None:
        gp.seed = fit_seed
    x = prior.draw(int(n_samples), design="lhs", seed=np.random.default_rng(design_seed))
    y = np.asarray(fn(x), dtype=float)
    ok = np.all(np.isfinite(y), 1)
    if ok.sum() < prior.dim + 2:
        raise EvaluationError(f"only {int(ok.sum())} of {len(x)} emulator build evaluations "
                              "succeeded")
    gp.fit(x[ok], y[ok])
    return EmulatorBuild(gp, x[ok], y[ok], len(x))
