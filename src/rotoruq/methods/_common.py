"""Helpers shared by the forward-UQ methods: batched evaluation in a space's column order and
response-level bookkeeping, and the one BLAS thread under which a seed gives the same bits.
(Gradients: :func:`rotoruq.model.model_gradient`.)"""

from __future__ import annotations

import warnings
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ParameterError
from ..model import EvalBatch, Model, align_inputs, evaluate

if TYPE_CHECKING:
    from ..params import ParameterSpace

__all__ = ["eval_space", "levels_per_response", "nan_rows_warning", "names_or_default",
           "one_blas_thread"]


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the block with BLAS and LAPACK on one thread (threadpoolctl), restored after.

    LAPACK's factorizations split their reductions between threads: with OpenBLAS on two
    threads a 300 x 300 Cholesky (potrf), triangular inverse (trtri) or LU solve (getrf)
    differs in the last bits from one thread (matrix products, gemm and gemv, do not), and a
    Markov chain fed by them drifts apart from the first row (issue 35). Everything whose bits
    a seed promises runs inside this block: :meth:`GaussianProcess.fit`, ``compiled`` and
    ``loo``, and every step of a study (``rotoruq.study.runner``). The rotor's and the
    self-check's numba threads are not touched: each row, each replication, is computed by
    one thread whatever their number.

    Examples
    --------
    >>> import numpy as np
    >>> a = np.eye(3) * 4.0
    >>> with one_blas_thread():
    ...     c = np.linalg.cholesky(a)
    >>> float(c[0, 0])
    2.0
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield


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
