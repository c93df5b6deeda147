"""The Model protocol that every method calls, and small adapters.

A model maps a batch of input points to a batch of responses::

    model.names_in   -> tuple of d input names
    model.names_out  -> tuple of m response names
    model(x)         -> array (n, m) for x of shape (n, d)
    model.gradient(x)             (optional) -> array (n, m, d)
    model.evaluate_gradient(x)    (optional, with gradient) -> Gradient: values and gradient
                                  from one evaluation per point, failures with reasons
    model.evaluate(x)             (optional) -> EvalBatch with per-row failure reasons

A failed point returns NaN in its row and a reason in ``EvalBatch.failures``; it never raises
for the whole batch. Methods call :func:`evaluate` which accepts any object with the three
required members and checks the shape of what comes back.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, cast, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike

from .errors import ModelShapeError, ParameterError

__all__ = ["Model", "EvalBatch", "FunctionModel", "FixedInputs", "evaluate", "align_inputs",
           "has_gradient", "FD_STEP", "Gradient", "finite_difference", "model_gradient",
           "check_gradient_option"]

#: The one default finite-difference step, relative: input i of point x moves by
#: ``FD_STEP * max(|x_i|, scale_i)``. Central differences then err by about
#: ``FD_STEP**2`` (truncation) plus ``eps / FD_STEP`` ~ 2e-10 (round-off), relative; forward
#: differences by about ``FD_STEP``.
FD_STEP: float = 1e-6

GRADIENT_OPTIONS = ("auto", "analytic", "finite_difference")

#: a ``gradient=`` option: one of :data:`GRADIENT_OPTIONS` or ``g(x: (n, d)) -> (n, m, d)``
GradientOption = str | Callable[[np.ndarray], np.ndarray]


@runtime_checkable
class Model(Protocol):
    """What every method calls (module doc); ``gradient`` and ``evaluate`` are optional."""

    @property
    def names_in(self) -> Sequence[str]:
        """The input names, in the order of the columns of ``x`` (d of them)."""
        ...

    @property
    def names_out(self) -> Sequence[str]:
        """The response names, in the order of the columns of the result (m of them)."""
        ...

    def __call__(self, x: np.ndarray) -> np.ndarray: ...


#: the Parameters and Returns of every ``evaluate(x)`` that returns an :class:`EvalBatch`
#: (:meth:`~rotoruq.evaluation.evaluator.Evaluator.evaluate`,
#: :meth:`~rotoruq.evaluation.external.ExternalModel.evaluate`), filled in with
#: :func:`rotoruq._docs.fill_doc`
EVALUATE_BATCH_DOC = """
Parameters
----------
x : array_like of shape (n, d) or (d,)
    Points, columns in ``names_in`` order.

Returns
-------
EvalBatch
    ``values`` (n, m), NaN rows for failed points, and the reason of each failure.
"""


@dataclass(frozen=True, eq=False)
class EvalBatch:
    """Responses of a batch.

    Parameters
    ----------
    values : ndarray of shape (n, m)
        The responses of the n points, in the model's units; NaN rows for failed points.
    failures : dict of int to str, optional
        Row index -> reason (text) for each failed point (default: none failed).
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
        """The analytic gradient ``g(x)``, shape (n, m, d): d response / d input.

        Parameters
        ----------
        x : array_like of shape (n, d) or (d,)
            Points, columns in ``names_in`` order.

        Raises
        ------
        NotImplementedError
            When the model was made without ``gradient``.
        """
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

    def __init__(self, model: Model, fixed: Mapping[str, float]) -> None:
        self.model: Any = model  # run_one, gradient, failure_policy: optional members
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
            if callable(getattr(model, "evaluate_gradient", None)):
                self.evaluate_gradient = self._evaluate_gradient

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
        g = np.asarray(self.model.gradient(self.full(x)), dtype=float)
        if g.ndim == 2:  # one response: (n, d)
            g = g[:, None, :]
        return g[:, :, self._free]

    def _evaluate_gradient(self, x: np.ndarray) -> Gradient:
        g = self.model.evaluate_gradient(self.full(x))
        return Gradient(g.values, np.asarray(g.gradient)[:, :, self._free],
                        np.asarray(g.steps)[:, self._free], g.n_evaluations, dict(g.failures))

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


def has_gradient(model: Model) -> bool:
    """True when the model offers an analytic gradient."""
    if isinstance(model, FunctionModel):
        return model._gradient is not None
    return callable(getattr(model, "gradient", None))


def evaluate(model: Model, x: ArrayLike) -> EvalBatch:
    """Evaluate ``model`` on a batch and check the result.

    Parameters
    ----------
    model : Model
        Any object of the Model protocol (``names_in``, ``names_out``, batched call).
    x : array_like, shape (n, d)
        One point per row, columns in ``model.names_in`` order, in the inputs' own units.

    Returns
    -------
    EvalBatch
        ``values`` (n, m) in ``model.names_out`` order and ``failures`` (row -> reason).
        Rows that come back non-finite without a reason get the reason "non-finite
        response".

    Raises
    ------
    ModelShapeError
        When the model returns the wrong shape.

    Examples
    --------
    A model of 2 inputs and 1 response on 3 points (``x`` (n, d), ``values`` (n, m)); a point
    whose response is not finite is a failure with its reason, not an error:

    >>> import numpy as np
    >>> model = FunctionModel(lambda x: x[:, :1] * x[:, 1:], ["a", "b"], ["y"])
    >>> batch = evaluate(model, np.array([[1.0, 2.0], [3.0, 4.0], [0.5, np.nan]]))
    >>> batch.values[:2, 0].tolist()
    [2.0, 12.0]
    >>> batch.failures
    {2: 'non-finite response'}
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


def align_inputs(model: Model, names_in: Sequence[str]) -> np.ndarray | None:
    """Column permutation that maps points ordered as ``names_in`` onto ``model.names_in``.

    Returns None when the orders already agree. Raises :class:`ParameterError` when the two
    sets of names differ, naming what is missing on each side.
    """
    names = tuple(names_in)
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


@dataclass(frozen=True, eq=False)
class Gradient:
    """Values and first derivatives of a batched function at ``n`` points.

    values : (n, m) the function at the points themselves.
    gradient : (n, m, d) ``d values[:, j] / d x[:, i]``, in the units of values per input unit.
    steps : (n, d) the steps actually taken (representable: ``(x + h) - x``; negative where a
        forward step was turned back at an upper bound); zeros for an analytic gradient.
    n_evaluations : points evaluated, the points themselves included.
    failures : point index -> reason, for each point whose value or a stencil point failed
        (its row of ``values`` or ``gradient`` holds NaN).
    """

    values: np.ndarray
    gradient: np.ndarray
    steps: np.ndarray
    n_evaluations: int
    failures: dict[int, str] = field(default_factory=dict)


def _values_and_failures(out) -> tuple[np.ndarray, dict[int, str]]:
    if isinstance(out, EvalBatch):
        return np.asarray(out.values, dtype=float), dict(out.failures)
    values = np.asarray(out, dtype=float)
    return (values[:, None] if values.ndim == 1 else values), {}


def finite_difference(
    f: Callable[[np.ndarray], np.ndarray | EvalBatch],
    x: np.ndarray,
    *,
    fd_step: float = FD_STEP,
    scale: float | np.ndarray = 0.0,
    central: bool = True,
    upper: float | np.ndarray = np.inf,
    values: np.ndarray | None = None,
) -> Gradient:
    """Finite-difference gradient of a batched ``f: (k, d) -> (k, m)`` at ``n`` points.

    Every stencil point of every point goes to ``f`` in ONE call, point by point: the point
    itself (unless its ``values`` are given), then ``x + h_i e_i`` for each input i, then (central)
    ``x - h_i e_i``. ``f`` may return an array ``(k, m)`` (or ``(k,)`` for one response) or an
    :class:`EvalBatch`; a non-finite or failed row fails its point, not the call.

    Parameters
    ----------
    x : (n, d) or (d,) points.
    fd_step : relative step; input i moves by ``h_i = fd_step * max(|x_i|, scale_i)`` (by
        ``fd_step`` itself where that is 0). Default :data:`FD_STEP`.
    scale : scalar or (d,) typical size of each input (e.g. its standard deviation), in input
        units: the step does not shrink below ``fd_step * scale`` near 0.
    central : central differences (2d stencil points, error ~ h^2), else forward (d points,
        error ~ h; taken backward where ``x + h`` would pass ``upper``).
    values : (n, m) ``f(x)`` when already known (the points themselves are then not
        evaluated again).

    Returns
    -------
    Gradient
    """
    x = np.asarray(x, dtype=float)
    x2 = np.atleast_2d(x)
    n, d = x2.shape
    h = fd_step * np.maximum(np.abs(x2), np.asarray(scale, dtype=float))
    h = np.where(h > 0, h, fd_step)
    if not central:
        h = np.where(x2 + h > upper, -h, h)
    idx = np.arange(d)
    with_center = values is None
    blocks = [x2[:, None, :]] if with_center else []
    plus = np.repeat(x2[:, None, :], d, axis=1)
    plus[:, idx, idx] += h
    blocks.append(plus)
    if central:
        minus = np.repeat(x2[:, None, :], d, axis=1)
        minus[:, idx, idx] -= h
        blocks.append(minus)
    stencil = np.concatenate(blocks, axis=1)  # (n, s, d)
    s = stencil.shape[1]
    out, reasons = _values_and_failures(f(stencil.reshape(n * s, d)))
    m = out.shape[1]
    F = out.reshape(n, s, m)
    f0 = F[:, 0] if with_center else np.asarray(values, dtype=float).reshape(n, m)
    Fp = F[:, int(with_center): int(with_center) + d]
    if central:
        Fm = F[:, int(with_center) + d:]
        dx = plus[:, idx, idx] - minus[:, idx, idx]
        steps = 0.5 * dx
    else:
        Fm = f0[:, None, :]
        dx = plus[:, idx, idx] - x2
        steps = dx
    grad = np.transpose(Fp - Fm, (0, 2, 1)) / dx[:, None, :]
    failures: dict[int, str] = {}
    bad = ~np.all(np.isfinite(F), axis=2)
    for i in np.flatnonzero(bad.any(axis=1)):
        rows = np.flatnonzero(bad[i])
        first = reasons.get(int(i * s + rows[0]), "non-finite response")
        failures[int(i)] = (f"finite-difference stencil at {x2[i]}: {rows.size} of {s} "
                            f"evaluations failed (first: {first})")
    return Gradient(values=f0, gradient=grad, steps=steps, n_evaluations=n * s,
                    failures=failures)


def check_gradient_option(gradient: GradientOption, model: Model | None = None
                          ) -> str | Callable[[np.ndarray], np.ndarray]:
    """Validate a ``gradient`` option; returns "analytic", "finite_difference" or the callable.

    ``"auto"`` resolves to "analytic" when ``model`` has an analytic gradient, else to
    "finite_difference". Raises :class:`ParameterError` for anything else, and for
    "analytic" with a model that has no gradient.
    """
    if callable(gradient):
        return gradient
    if gradient not in GRADIENT_OPTIONS:
        raise ParameterError(f"gradient must be 'auto', 'analytic', 'finite_difference' or a "
                             f"callable, got {gradient!r}")
    offered = model is not None and has_gradient(model)
    if gradient == "analytic" and not offered:
        raise ParameterError("gradient='analytic' but the model has no gradient method")
    if gradient == "auto":
        return "analytic" if offered else "finite_difference"
    return gradient


def model_gradient(
    model: Model,
    x: ArrayLike,
    *,
    gradient: GradientOption = "auto",
    fd_step: float = FD_STEP,
    scale: float | np.ndarray = 0.0,
    names_in: Sequence[str] | None = None,
) -> Gradient:
    """Responses and their gradient of ``model`` at points ``x``, in one batched evaluation.

    x : (n, d) or (d,) points, columns ordered as ``names_in`` (default ``model.names_in``).
    gradient : "auto" (the model's own gradient if it has one, else finite differences),
        "analytic", "finite_difference" (central, :func:`finite_difference`) or a callable
        ``g(x: (n, d)) -> (n, m, d)`` in the order of ``names_in``. A model's own gradient
        comes from its ``evaluate_gradient`` when it has one (an external driver's analytic
        gradients: values and gradient from ONE evaluation per point), else from
        ``evaluate`` then ``gradient``.
    fd_step, scale : see :func:`finite_difference`.

    Returns a :class:`Gradient` with ``gradient`` (n, m, d) in the order of ``names_in``.
    Failed points are reported in ``failures``, never raised.
    """
    mode = check_gradient_option(gradient, model)
    x2 = np.atleast_2d(np.asarray(x, dtype=float))
    perm = None if names_in is None else align_inputs(model, names_in)
    n, d = x2.shape
    m = len(model.names_out)

    def run(X: np.ndarray) -> EvalBatch:
        return evaluate(model, X if perm is None else X[:, perm])

    if mode == "finite_difference":
        return finite_difference(run, x2, fd_step=fd_step, scale=scale)
    joint = None if callable(mode) else getattr(model, "evaluate_gradient", None)
    if callable(joint):
        got = joint(x2 if perm is None else x2[:, perm])
        values, g = np.asarray(got.values, dtype=float), np.asarray(got.gradient, dtype=float)
        if values.shape != (n, m) or g.shape != (n, m, d):
            raise ModelShapeError(f"evaluate_gradient of {model!r} gave values {values.shape} "
                                  f"and gradient {g.shape}; expected ({n}, {m}) and "
                                  f"({n}, {m}, {d})")
        if perm is not None:
            g = g[:, :, np.argsort(perm)]
        failures = dict(got.failures)
        for i in np.flatnonzero(~(np.all(np.isfinite(g), axis=(1, 2))
                                  & np.all(np.isfinite(values), axis=1))):
            failures.setdefault(int(i), "non-finite gradient")
        return Gradient(values=values, gradient=g, steps=np.zeros((n, d)), n_evaluations=n,
                        failures=failures)
    batch = run(x2)
    if callable(mode):
        g = np.asarray(mode(x2), dtype=float)
    else:
        g = np.asarray(cast(Any, model).gradient(x2 if perm is None else x2[:, perm]),
                       dtype=float)
    if g.ndim == 2 and m == 1:
        g = g[:, None, :]
    if g.shape != (n, m, d):
        raise ModelShapeError(f"gradient of {model!r} has shape {g.shape}; expected "
                              f"({n}, {m}, {d})")
    if perm is not None and not callable(mode):
        g = g[:, :, np.argsort(perm)]
    failures = dict(batch.failures)
    for i in np.flatnonzero(~np.all(np.isfinite(g), axis=(1, 2))):
        failures.setdefault(int(i), "non-finite gradient")
    return Gradient(values=batch.values, gradient=g, steps=np.zeros((n, d)), n_evaluations=n,
                    failures=failures)
