"""The emulator of a calibration, fitted on an LHS design of its prior: one home for the
calibration (:func:`~rotoruq.methods.mcmc.bayes.calibrate_bayes`) and its self-check
(:func:`~rotoruq.methods.mcmc.sbc.simulation_based_calibration`).

A :class:`~rotoruq.methods.surrogate.GaussianProcess` is fitted on ``n_samples`` LHS points
of the prior. A :class:`~rotoruq.methods.cokriging.CoKriging` gets a nested design: the same
``n_samples`` high-fidelity points (the same points a GaussianProcess would get from the same
seed), and for each cheaper model those points plus an LHS of the prior drawn from the same
stream up to its ``n_low`` (the cheapest model's design holds every dearer model's points).
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import numpy as np

from ...errors import EvaluationError, ParameterError
from ...params import ParameterSpace
from ..cokriging import CoKriging
from ..surrogate import GaussianProcess

__all__ = ["EmulatorBuild", "fit_on_prior"]

Emulator = GaussianProcess | CoKriging
E = TypeVar("E", bound=GaussianProcess | CoKriging)


@dataclass(frozen=True, eq=False)
class EmulatorBuild(Generic[E]):
    """A fitted emulator and its build runs.

    gp : the fitted copy. inputs (k, d), outputs (k, m) : the (high-fidelity) build runs that
    succeeded. n_evaluations : high-fidelity build runs spent (k plus the failed ones).
    n_low_fidelity : with a CoKriging, runs of each low-fidelity model (cheapest first).
    """

    gp: E
    inputs: np.ndarray
    outputs: np.ndarray
    n_evaluations: int
    n_low_fidelity: tuple[int, ...] = ()


def fit_on_prior(emulator: E, prior: ParameterSpace,
                 fn: Callable[[np.ndarray], np.ndarray], n_samples: int, *,
                 design_seed: Any, fit_seed: Any,
                 low_fidelity: Sequence[Callable[[np.ndarray], np.ndarray]] = ()
                 ) -> EmulatorBuild[E]:
    """Fit a copy of ``emulator`` on ``n_samples`` LHS points of ``prior`` through ``fn``.

    The caller's emulator stays unfitted; a copy without a seed of its own gets ``fit_seed``
    (so its optimizer restarts are reproducible). Build runs with a non-finite response are
    left out; fewer than d + 2 left is an error. A CoKriging also needs ``low_fidelity``:
    one function per cheaper model (cheapest first), (k, d) points in prior order to (k, m)
    responses like ``fn``; its nested design is in the module doc.

    Examples
    --------
    >>> from rotoruq.params import Uniform
    >>> prior = ParameterSpace([("a", Uniform(0, 1))])
    >>> b = fit_on_prior(GaussianProcess(), prior, lambda x: np.sin(3 * x), 12,
    ...                  design_seed=np.random.SeedSequence(0), fit_seed=1)
    >>> b.inputs.shape, b.n_evaluations
    ((12, 1), 12)
    >>> from rotoruq.model import FunctionModel
    >>> lf = FunctionModel(lambda x: 0.5 * np.sin(3 * x) + x, ["a"], ["y"])
    >>> b = fit_on_prior(CoKriging(low_fidelity=lf, n_low=20, seed=0), prior,
    ...                  lambda x: np.sin(3 * x), 6, design_seed=np.random.SeedSequence(0),
    ...                  fit_seed=1, low_fidelity=[lf])
    >>> b.n_evaluations, b.n_low_fidelity, [x.shape for x, _ in b.gp.training_data]
    (6, (20,), [(20, 1), (6, 1)])
    """
    gp = copy.copy(emulator)
    if gp.seed is None:
        gp.seed = fit_seed
    if isinstance(gp, CoKriging):
        sizes = gp.design_sizes(int(n_samples))
        if len(low_fidelity) != len(sizes):
            raise ParameterError(f"CoKriging has {len(sizes)} low-fidelity models; "
                                 f"{len(low_fidelity)} functions were given to evaluate them")
    rng = np.random.default_rng(design_seed)
    x = prior.draw(int(n_samples), design="lhs", seed=rng)
    y = np.asarray(fn(x), dtype=float)
    ok = _succeeded(y, prior.dim, "emulator build")
    if not isinstance(gp, CoKriging):
        gp.fit(x[ok], y[ok])
        return EmulatorBuild(gp, x[ok], y[ok], len(x))
    # nested: each cheaper design is the dearer one's points plus LHS points up to its size
    Xs, Ys = [x[ok]], [y[ok]]
    pts, n_low = x, list[int]()
    for t in range(len(sizes) - 1, -1, -1):
        extra = sizes[t] - len(pts)
        if extra > 0:
            pts = np.vstack([pts, prior.draw(extra, design="lhs", seed=rng)])
        y_t = np.asarray(low_fidelity[t](pts), dtype=float)
        ok_t = _succeeded(y_t, prior.dim, f"low-fidelity model {t} build")
        Xs.insert(0, pts[ok_t])
        Ys.insert(0, y_t[ok_t])
        n_low.insert(0, len(pts))
    gp.fit(Xs, Ys)
    return EmulatorBuild(gp, x[ok], y[ok], len(x), tuple(n_low))


def _succeeded(y: np.ndarray, d: int, what: str) -> np.ndarray:
    """Rows of y with finite responses; fewer than d + 2 is an error."""
    ok = np.all(np.isfinite(y), 1)
    if ok.sum() < d + 2:
        raise EvaluationError(f"only {int(ok.sum())} of {len(y)} {what} evaluations "
                              "succeeded")
    return ok
