"""The report parts the Sobol-index step types share (``sensitivity`` and ``pce``): the
tornado figure and the negligible-variance warning. Kept apart from either step's module so
that each one's fingerprint covers its own method only."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..render.figures import (
    Figure,
    FigureContext,
    SobolIndices,
    beside_label,
    beside_sobol,
    sobol_sweep,
    tornado,
)
from ..results import RecordError, StepResult

__all__ = ["sensitivity_figures", "sensitivity_sweep_figures", "sobol_warnings",
           "NEGLIGIBLE_CV", "spread", "sobol_of"]

# A response whose std is below this fraction of |mean| has negligible variance: its Sobol
# indices split up numerical noise and mean nothing physically.
NEGLIGIBLE_CV = 1e-4


def spread(mean: np.ndarray, std: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(cv, negligible)`` (m,) of responses with means ``mean`` and stds ``std``: the
    coefficient of variation std / |mean| (inf at a zero mean) and whether it is below
    :data:`NEGLIGIBLE_CV`.

    Examples
    --------
    >>> cv, neg = spread(np.array([100.0, 2.0]), np.array([1e-3, 0.5]))
    >>> cv.tolist(), neg.tolist()
    ([1e-05, 0.25], [True, False])
    """
    mean, std = np.asarray(mean, dtype=float), np.asarray(std, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        cv = np.where(mean != 0, std / np.abs(mean), np.inf)
    return cv, cv < NEGLIGIBLE_CV


def sobol_of(res: StepResult) -> tuple[SobolIndices, np.ndarray, np.ndarray] | None:
    """The Sobol indices of a sensitivity or pce step with each response's std and CV
    ``(indices, std, cv)``; None for a step saved without its record."""
    from .pce import PceRecord
    from .sensitivity import SensitivityRecord

    try:
        if res.type == "pce":
            pce = PceRecord.read(res)
            std = np.asarray(pce.std, dtype=float)
            cv, neg = spread(pce.mean, std)
            return SobolIndices(pce.names_in, pce.names_out, pce.main, pce.total,
                                negligible=neg), std, cv
        rec = SensitivityRecord.read(res)
    except RecordError:
        return None
    std = np.sqrt(np.maximum(rec.variance, 0.0))
    cv, neg = spread(rec.mean, std)
    return SobolIndices(rec.names_in, rec.names_out, rec.main, rec.total, rec.main_ci,
                        rec.total_ci, neg), std, cv


def sensitivity_figures(res: StepResult, ctx: FigureContext) -> list[Figure]:
    """Tornado of main/total indices (sensitivity and pce steps), with the main indices the
    report's application gives for this step beside them (``ctx.beside``)."""
    got = sobol_of(res)
    if got is None:
        return []
    return tornado(res, got[0], ctx.labels, ctx.units, beside_sobol(ctx, res.name),
                   beside_label(ctx))


def sensitivity_sweep_figures(results: Sequence[StepResult], swept: str,
                              values: Sequence[float], ctx: FigureContext) -> list[Figure]:
    """Sobol indices and each response's mean +- std against the one fixed input ``swept``
    the steps differ in (sensitivity and pce steps with the same inputs and responses)."""
    got = [sobol_of(res) for res in results]
    if any(g is None for g in got):
        return []
    sobols = [g[0] for g in got if g is not None]
    if len({(s.names_in, s.names_out) for s in sobols}) != 1:
        return []
    mean = np.array([_means(res) for res in results])
    std = np.array([g[1] for g in got if g is not None])
    return sobol_sweep(swept, values, [res.name for res in results], sobols, mean, std,
                       ctx.labels, ctx.units)


def _means(res: StepResult) -> np.ndarray:
    from .pce import PceRecord
    from .sensitivity import SensitivityRecord

    rec = PceRecord.read(res) if res.type == "pce" else SensitivityRecord.read(res)
    return np.asarray(rec.mean, dtype=float)


def sobol_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    """Sobol indices of a response with negligible variance (sensitivity, pce)."""
    got = sobol_of(res)
    if got is None:
        return []
    sobol, std, cv = got
    negligible = sobol.negligible
    if negligible is None:
        return []
    return [f"{res.name}: {r} has negligible variance (std {std[k]:.3g}, {cv[k]:.1e} of "
            "its mean): its Sobol indices split up numerical noise"
            for k, r in enumerate(sobol.names_out) if negligible[k]]
