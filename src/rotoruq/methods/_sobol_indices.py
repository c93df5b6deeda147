"""The indices part of a Sobol' result, shared by :class:`~rotoruq.methods.sensitivity.SobolResult`
and the sensitivity step's record (a module of its own, light to import: the step types import
it without the method)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

__all__ = ["SobolIndices"]


@dataclass(frozen=True, eq=False)
class SobolIndices:
    """Main and total Sobol' indices with their intervals, and the axis names of each array
    (``AXES``, read by a step record that saves them).

    Attributes
    ----------
    names_in, names_out : tuple of str
        The d input and m response names.
    main, total : ndarray of shape (m, d)
        First-order and total-effect indices.
    main_ci, total_ci : ndarray of shape (m, d, 2)
        Their intervals (lower, upper bound).
    """

    AXES: ClassVar[dict[str, tuple[str, ...]]] = {
        "main": ("response", "input"), "total": ("response", "input"),
        "main_ci": ("response", "input", "bound"), "total_ci": ("response", "input", "bound")}

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    main: np.ndarray
    total: np.ndarray
    main_ci: np.ndarray
    total_ci: np.ndarray
