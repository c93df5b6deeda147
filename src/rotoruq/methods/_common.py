"""Helpers shared by the forward-UQ methods: batched evaluation in a space's column order,
finite-difference gradients on one batch, and response-level bookkeeping."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence

import numpy as np

from ..errors import EvaluationError, ParameterError
from ..model import EvalBatch, align_inputs, evaluate, has_gradient

__all__ = ["eval_space", "gradient_at", "levels_per_response", "nan_rows_warning"]


def eval_space(model, space, x: np.ndarray) -> EvalBatch:
    """Evaluate ``model`` on points ordered as ``space.names`` (columns permuted as needed)."""
    perm = align_inputs(model, space.names)
    x = np.atleast_2d(np.asarray(x, dtype=float))
    return evaluate(model, x if perm is None else x[:, perm])


def analytic_gradient(model, space, x: np.ndarray) -> np.ndarray:
    """``model.gradient`` at points ordered as ``space.names``; returns (n, m, d) in that order."""
    perm = align_inputs(model, space.names)
    x = np.atleast_2d(np.asarray(x, dtype=float))
    g = np.asarray(model.gradient(x if perm is None else x[:, perm]), dtype=float)
    n, m, d = x.shape[0], len(model.names_out), space.dim
    if g.ndim == 2 and m == 1:
        g = g[:, None, :]
    if g.shape != (n, m, d):
        from ..errors import ModelShapeError

        raise ModelShapeError(f"model gradient returned shape {g.shape}; expected ({n}, {m}, {d})")
    if perm is None:
        return g
    out = np.empty_like(g)
    out[:, :, perm] = g
    return out


def fd_steps(x0: np.ndarray, scale: np.ndarray, fd_step: float) -> np.ndarray:
    """Relative steps ``fd_step * max(|x0|, scale)`` (scale: std or another length)."""
    h = fd_step * np.maximum(np.abs(x0), np.asarray(scale, dtype=float))
    return np.where(h > 0, h, fd_step)


def forward_jacobian(f, x, fx=None, *, rel_step, scale, upper=np.inf) -> np.ndarray:
    """Forward-difference Jacobian (m, p) of a batched ``f: (k, p) -> (k, m)`` at ``x`` (p,).

    Steps ``rel_step * max(|x|, scale)``, taken backward where the forward point would pass
    ``upper``; all columns in ONE call of ``f`` (with ``x`` itself first when ``fx`` is None).
    The representable step (x + h) - x is used in the quotient.
    """
    x = np.asarray(x, dtype=float)
    p = x.size
    h = rel_step * np.maximum(np.abs(x), scale)
    h = np.where(x + h > upper, -h, h)
    X = np.repeat(x[None, :], p, axis=0)
    X[np.arange(p), np.arange(p)] += h
    h = X[np.arange(p), np.arange(p)] - x
    if fx is None:
        F = f(np.vstack([x[None, :], X]))
        fx, F = F[0], F[1:]
    else:
        F = f(X)
    return ((F - fx[None, :]) / h[:, None]).T


def gradient_at(
    model,
    space,
    x0: np.ndarray,
    *,
    gradient: str = "auto",
    fd_step: float = 1e-6,
    scale: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Value (m,) and gradient (m, d) of the model at one point ``x0`` (space order).

    gradient : "auto" (analytic when the model has one, else finite differences),
        "analytic" or "fd" (central differences, the 2d+1 points in ONE batched call).
    Returns (value, gradient, number of model evaluations). Raises EvaluationError if a
    needed point fails.
    """
    x0 = np.asarray(x0, dtype=float).ravel()
    d = x0.size
    mode = gradient.lower()
    if mode not in ("auto", "analytic", "fd", "numerical"):
        raise ParameterError(f"gradient must be 'auto', 'analytic' or 'fd', got {gradient!r}")
    use_analytic = mode == "analytic" or (mode == "auto" and has_gradient(model))
    if mode == "analytic" and not has_gradient(model):
        raise ParameterError("gradient='analytic' but the model has no gradient method")
    if use_analytic:
        batch = eval_space(model, space, x0[None, :])
        if batch.failures:
            raise EvaluationError(f"evaluation at {x0} failed: {batch.failures[0]}")
        g = analytic_gradient(model, space, x0[None, :])[0]
        return batch.values[0], g, 1
    h = fd_steps(x0, space.std if scale is None else scale, fd_step)
    pts = np.repeat(x0[None, :], 2 * d + 1, axis=0)
    idx = np.arange(d)
    pts[1 + idx, idx] += h
    pts[1 + d + idx, idx] -= h
    batch = eval_space(model, space, pts)
    if batch.failures:
        rows = sorted(batch.failures)
        raise EvaluationError(
            f"finite-difference gradient at {x0}: {len(rows)} of {2 * d + 1} evaluations "
            f"failed (first: row {rows[0]}: {batch.failures[rows[0]]})"
        )
    v = batch.values
    g = (v[1 : d + 1] - v[d + 1 :]).T / (2.0 * h)
    return v[0], g, 2 * d + 1


def levels_per_response(levels, names_out: Sequence[str], what: str) -> dict[str, np.ndarray]:
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
