"""Helpers shared by the forward-UQ methods: batched evaluation in a space's column order and
response-level bookkeeping. (Gradients: :func:`rotoruq.model.model_gradient`.)"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ParameterError
from ..model import EvalBatch, Model, align_inputs, evaluate

if TYPE_CHECKING:
    from ..params import ParameterSpace

__all__ = ["eval_space", "levels_per_response", "nan_rows_warning", "names_or_default"]


def names_or_default(names: Sequence[str] | None, n: int, prefix: str) -> tuple[str, ...]:
    """``names`` as a tuple, or ``<prefix>0``, ``<prefix>1``, ... (n of them) for None."""
    return tuple(names) if names is not None else tuple(f"{prefix}{k}" for k in range(n))


def eval_space(model: Model, space: ParameterSpace, x: ArrayLike) -> EvalBatch:
    """Evaluate ``model`` on points ordered as ``space.names`` (columns permuted as needed)."""
    perm = align_inputs(model, space.names)
    x = np.atleast_2d(np.asarray(x, dtype=float))
    return evaluate(model, x if perm is None else x[:, perm])


def levels_per_response(levels: Any, names_out: Sequence[str], what: str) -> dict[str, np.ndarray]:
    """Normalise level specifications to ``{response name: 1-D array}``.

    Accepts None (no levels), a scalar or 1-D sequence (same levels for every response), a
    mapping name -> levels, or a sequence of m sequences (one per response).
    """
    names_out = tuple(names_out)
    if levels is None:
        return {n: np.empty(0) for n in names_out}
    if isinstance(levels, Mapping):
        unknown = [k for k in levels if k not in names_out]
        if unknown:
            raise ParameterError(f"{what}: unknown responses {unknown}; valid: {list(names_out)}")
        return {n: np.atleast_1d(np.asarray(levels.get(n, []), dtype=float)) for n in names_out}
    if (
        isinstance(levels, Sequence)
        and len(levels) == len(names_out)
        and len(levels) > 0
        and all(isinstance(v, Sequence | np.ndarray) for v in levels)
    ):
        return {
            n: np.atleast_1d(np.asarray(v, dtype=float))
            for n, v in zip(names_out, levels, strict=True)
        }
    arr = np.atleast_1d(np.asarray(levels, dtype=float))
    if arr.ndim != 1:
        raise ParameterError(f"{what}: expected a 1-D sequence or a mapping per response")
    return {n: arr.copy() for n in names_out}


def nan_rows_warning(n_dropped: int, n_total: int, where: str) -> None:
    if n_dropped:
        warnings.warn(
            f"{where}: {n_dropped} of {n_total} evaluations failed or returned NaN; "
            "they are left out of the statistics",
            RuntimeWarning,
            stacklevel=3,
        )
