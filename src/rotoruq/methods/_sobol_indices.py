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
    """The index fields of :class:`~rotoruq.methods.sensitivity.SobolResult` (documented
    there: names, main and total indices, their intervals) and the axis names of each array
    (``AXES``), shared with the sensitivity step's record."""

    AXES: ClassVar[dict[str, tuple[str, ...]]] = {
        "main": ("response", "input"), "total": ("response", "input"),
        "main_ci": ("response", "input", "bound"), "total_ci": ("response", "input", "bound")}

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    main: np.ndarray
    total: np.ndarray
    main_ci: np.ndarray
    total_ci: np.ndarray
