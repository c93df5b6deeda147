"""The Model protocol that every method calls, and small adapters.

A model maps a batch of input points to a batch of responses::

    model.names_in   -> tuple of d input names
    model.names_out  -> tuple of m response names
    model(x)         -> array (n, m) for x of shape (n, d)
    model.gradient(x)             (optional) -> array (n, m, d)
    model.evaluate(x)             (optional) -> EvalBatch with per-row failure reasons

A failed point returns NaN in its row and a reason in ``EvalBatch.failures``; it never raises
for the whole batch. Methods call :func:`evaluate` which accepts any object with the three
required members and checks the shape of what comes back.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from .errors import ModelShapeError, ParameterError

__all__ = ["Model", "EvalBatch", "FunctionModel", "FixedInputs", "evaluate", "align_inputs",
           "has_gradient"]


@runtime_checkable
class Model(Protocol):
    names_in: Sequence[str]
    names_out: Sequence[str]

    def __call__(self, x: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True)
class EvalBatch:
    """Responses of a batch.

    values : (n, m) array, NaN rows for failed points.
    failures : mapping row index -> reason (text) for each failed point.
    """

    values: np.ndarray
    failures: dict[int, str] = field(default_factory=dict)

    @property
    def ok(self) -> np.ndarray:
        """Boolean mask (n,) of rows that succeeded (no failure and all finite)."""
        mask = np.all(np.isfinite(self.values), axis=1)
        if self.failures:
            mask[list(self.failures)] = False
        return mask


class FunctionModel:
    """Wrap a vectorized Python function ``f(x: (n, d)) -> (n, m)`` as a Model.

    Parameters
    ----------
    func : callable
        Vectorized over the leading axis. May return shape (n,) for a single response.
    names_in, names_out : sequences of str
    gradient : callable, optional
        ``g(x: (n, d)) -> (n, m, d)``.
    """

    def __init__(
        self,
        func: Callable[[np.ndarray], np.ndarray],
        names_in: Sequence[str],
        names_out: Sequence[str] = ("f",),
        gradient: Callable[[np.ndarray], np.ndarray] | None = None,
    ):
        self.func = func
        self.names_in = tuple(names_in)
        self.names_out = tuple(names_out)
        self._gradient = gradient

    def __call__(self, x: np.ndarray) -> np.ndarray:
        x = np.atleast_2d(np.asarray(x, dtype=float))
        y = np.asarray(self.func(x), dtype=float)
        if y.ndim == 1 and len(self.names_out) == 1:
            y = y[:, None]
        return y

    def gradient(self, x: np.ndarray) -> np.ndarray:
        if self._gradient is None:
            raise NotImplementedError("this FunctionModel has no analytic gradient")
        x = np.atleast_2d(np.asarray(x, dtype=float))
        g = np.asarray(self._gradient(x), dtype=float)
        if g.ndim == 2 and len(self.names_out) == 1:
            g = g[:, None, :]
        return g

    def __getstate__(self):
        return self.__dict__

    def identity(self) -> dict:
        """The function's code (bytecode, constants, defaults, captured values) and names.

        Editing the function's body changes it, so stored results of the old function are not
        reused. Numbers, strings, tuples and arrays the function captures are covered; globals
        it reads and lists or dicts it captures are not: pass configuration as defaults or
        captured constants.
        """
        return {"func": _callable_identity(self.func),
                "gradient": None if self._gradient is None else _callable_identity(self._gradient)}

    def __repr__(self) -> str:
        return f"FunctionModel({getattr(self.func, '__name__', 'f')}, in={self.names_in})"


def _callable_identity(f) -> dict:
    code = getattr(f, "__code__", None)
    if code is None:
        ident = getattr(f, "identity", None)
        return {"object": ident() if callable(ident) else repr(f)}
    cells = []
    for c in getattr(f, "__closure__", None) or ():
        try:
            v = c.cell_contents
        except ValueError:  # an empty cell
            continue
        if isinstance(v, (list, dict, set)):
            continue  # mutable bookkeeping (call logs, caches), not configuration
        cells.append(_callable_identity(v) if callable(v) and hasattr(v, "__code__") else v)
    return {"name": f"{getattr(f, '__module__', '')}.{getattr(f, '__qualname__', '')}",
            "code": code.co_code.hex(), "consts": repr(code.co_consts), "names": code.co_names,
            "defaults": getattr(f, "__defaults__", None), "closure": cells}


class FixedInputs:
    """A model with some inputs held at fixed values: ``names_in`` are the others.

    ``FixedInputs(model, {"omega": 110.0})`` evaluates ``model`` with a column of 110.0 inserted
    for ``omega``. Analytic gradients drop the fixed columns; an external model's one-point
    runs (``run_one``), failure policy and identity are passed through, the fixed values joining
    the identity.
    """

    def __init__(self, model, fixed: Mapping[str, float]):
        self.model = model
        self.fixed = {str(k): float(v) for k, v in fixed.items()}
        unknown = [k for k in self.fixed if k not in model.names_in]
        if unknown:
            raise ParameterError(f"fixed inputs {unknown} are not inputs of {model!r}; its "
                                 f"inputs are {list(model.names_in)}")
        inner = tuple(model.names_in)
        self.names_in = tuple(n for n in inner if n not in self.fixed)
        self.names_out = tuple(model.names_out)
        self._free = np.array([inner.index(n) for n in self.names_in], dtype=int)
        self._fixed_cols = np.array([inner.index(n) for n in self.fixed], dtype=int)
        self._fixed_vals = np.array(list(self.fixed.values()), dtype=float)
        if callable(getattr(model, "run_one", None)):
            self.run_one = self._run_one
        if has_gradient(model):
            self.gradient = self._gradient

    def full(self, x: np.ndarray) -> np.ndarray:
        """Points (n, len(names_in)) -> the wrapped model's points with the fixed columns."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        out = np.empty((x.shape[0], len(self.model.names_in)))
        out[:, self._free] = x
        out[:, self._fixed_cols] = self._fixed_vals
        return out

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.evaluate(x).values

    def evaluate(self, x: np.ndarray) -> EvalBatch:
        return evaluate(self.model, self.full(x))

    def _run_one(self, x: np.ndarray, eval_id: str):
        return self.model.run_one(self.full(x)[0], eval_id)

    def _gradient(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(self.model.gradient(self.full(x)))[:, :, self._free]

    @property
    def failure_policy(self):
        return getattr(self.model, "failure_policy", None)

    def identity(self) -> dict:
        ident = getattr(self.model, "identity", None)
        return {"model": type(self.model).__qualname__,
                "config": ident() if callable(ident) else repr(self.model),
                "fixed": dict(sorted(self.fixed.items()))}

    def __repr__(self) -> str:
        return f"FixedInputs({self.model!r}, fixed={self.fixed})"


def has_gradient(model) -> bool:
    """True when the model offers an analytic gradient."""
    if isinstance(model, FunctionModel):
        return model._gradient is not None
    return callable(getattr(model, "gradient", None))


def evaluate(model, x: np.ndarray) -> EvalBatch:
    """Evaluate ``model`` on a batch and check the result.

    Rows that come back non-finite without a reason get the reason "non-finite response".
    Raises :class:`ModelShapeError` when the model returns the wrong shape.
    """
    x = np.atleast_2d(np.asarray(x, dtype=float))
    n = x.shape[0]
    m = len(model.names_out)
    if hasattr(model, "evaluate"):
        out = model.evaluate(x)
        values, failures = np.asarray(out.values, dtype=float), dict(out.failures)
    else:
        values, failures = np.asarray(model(x), dtype=float), {}
    if values.ndim == 1 and m == 1 and values.shape[0] == n:
        values = values[:, None]
    if values.shape != (n, m):
        raise ModelShapeError(
            f"model {model!r} returned shape {values.shape} for {n} points; "
            f"expected ({n}, {m}) for responses {tuple(model.names_out)}"
        )
    bad = ~np.all(np.isfinite(values), axis=1)
    for i in np.flatnonzero(bad):
        failures.setdefault(int(i), "non-finite response")
    return EvalBatch(values, failures)


def align_inputs(model, names: Sequence[str]) -> np.ndarray | None:
    """Column permutation that maps points ordered as ``names`` onto ``model.names_in``.

    Returns None when the orders already agree. Raises :class:`ParameterError` when the two
    sets of names differ, naming what is missing on each side.
    """
    names = tuple(names)
    model_names = tuple(model.names_in)
    if names == model_names:
        return None
    missing = [n for n in model_names if n not in names]
    extra = [n for n in names if n not in model_names]
    if missing or extra:
        parts = []
        if extra:
            parts.append(f"not inputs of the model: {extra}")
        if missing:
            parts.append(f"model inputs with no parameter: {missing}")
        raise ParameterError(
            "parameters and model inputs differ (" + "; ".join(parts) + f"); model inputs are "
            f"{list(model_names)}"
        )
    return np.array([names.index(n) for n in model_names])
