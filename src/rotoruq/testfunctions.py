"""Dakota's built-in test functions (``interface direct analysis_drivers = 'NAME'``) as models.

A Dakota deck that names one of Dakota's own test functions runs here as it stands:
:func:`dakota_function` builds a :class:`DakotaFunction`, a batched
:class:`~rotoruq.model.Model` that computes what Dakota 6.24's direct interface computes, with
the analytic gradient where Dakota has one. The formulas follow Dakota's sources
(``src/TestDriverInterface.cpp``; the system-interface programs ``test/steel_section.cpp`` and
``test/portal_frame.cpp``); the implementation is numpy, vectorised over rows.

How the inputs reach the function follows Dakota too:

- most functions take the continuous variables **by position** (``x[0], x[1], ...`` in the
  order the deck declares them); the names are labels only;
- ``cantilever``, ``mod_cantilever``, ``rosenbrock``, ``modified_rosenbrock``,
  ``short_column`` and ``sobol_ishigami`` read their variables **by descriptor** (Dakota's
  ``VARIABLES_MAP`` view): the deck must call them ``w t R E X Y``, ``x1 x2``, ``b h P M Y``
  or ``x1 x2 x3``, in any order (Dakota rejects any other label).

The number of responses is the deck's: ``text_book`` gives the objective only, or the
objective and one or two constraints; ``rosenbrock`` gives the objective or two least-squares
residuals; and so on (:data:`FUNCTIONS` says what each accepts).

``FUNCTIONS`` maps each name to a :class:`FunctionInfo` (counts, labels, gradient,
``analysis_components``) that a deck translator or a study file checker can query without
building a model.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .errors import ParameterError

__all__ = ["FUNCTIONS", "FunctionInfo", "DakotaFunction", "dakota_function"]

# (x (n, d) in the function's own order, m responses, component) -> (values (n, m),
# gradient (n, m, d) or None)
_Kernel = Callable[[np.ndarray, int, str, bool], tuple[np.ndarray, np.ndarray | None]]


@dataclass(frozen=True)
class FunctionInfo:
    """What one of Dakota's test functions takes and gives.

    Parameters
    ----------
    name : str
        The ``analysis_drivers`` name.
    summary : str
        One line: what it computes.
    n_inputs : int or None
        The exact number of continuous variables, or None when several counts are accepted
        (``inputs`` says which).
    inputs : str
        The accepted variables, in words (for messages and the docs).
    responses : str
        The accepted responses, in words.
    has_gradient : bool
        Whether Dakota (and so the model) has an analytic gradient.
    labels : tuple of tuple of str
        For functions that read variables by descriptor: the accepted label sets, in the
        function's own order (``cantilever`` takes ``w t R E X Y`` or ``R E X Y``). Empty for
        functions that take them by position.
    components : tuple of str
        The accepted ``analysis_components`` (the first is Dakota's default); empty when the
        function takes none.
    """

    name: str
    summary: str
    n_inputs: int | None
    inputs: str
    responses: str
    has_gradient: bool
    labels: tuple[tuple[str, ...], ...] = ()
    components: tuple[str, ...] = ()

    def response_counts(self, n_inputs: int) -> tuple[int, ...] | None:
        """The numbers of responses accepted with ``n_inputs`` variables (None: any >= 1)."""
        return _RESPONSE_COUNTS[self.name](n_inputs)

    def input_problem(self, names_in: Sequence[str]) -> str | None:
        """What the inputs should be, in words, when ``names_in`` is not accepted; else None."""
        names = tuple(names_in)
        if self.labels:
            if any(set(names) == set(ls) and len(names) == len(ls) for ls in self.labels):
                return None
            sets = " or ".join(", ".join(ls) for ls in self.labels)
            return (f"the variables of {self.name!r} named as Dakota reads them (by descriptor):"
                    f" {sets}")
        ok = _INPUT_COUNTS[self.name](len(names))
        return None if ok else f"{self.inputs} for {self.name!r}"

    def response_problem(self, n_inputs: int, n_responses: int) -> str | None:
        """What the number of responses should be, in words, when not accepted; else None."""
        counts = self.response_counts(n_inputs)
        if counts is None:
            return None if n_responses >= 1 else f"at least 1 response for {self.name!r}"
        if n_responses in counts:
            return None
        return f"{self.responses} for {self.name!r} (with {n_inputs} variables)"

    def component_problem(self, components: Sequence[str]) -> str | None:
        """What ``analysis_components`` should be, in words, when not accepted; else None."""
        comps = tuple(components)
        if not comps:
            return None
        if not self.components:
            return f"no analysis_components for {self.name!r}"
        if len(comps) == 1 and comps[0] in self.components:
            return None
        return f"one analysis component of {self.name!r}: {', '.join(self.components)}"


class DakotaFunction:
    """One of Dakota's test functions as a batched model (build it with
    :func:`dakota_function`).

    ``model(x)`` maps ``x`` (n, len(names_in)) to (n, len(names_out)) and, when Dakota has
    one, ``model.gradient(x)`` gives (n, len(names_out), len(names_in)). A point where
    Dakota's function is undefined (a damped oscillator that is not under-damped) is a NaN
    row, a failure of that point only.

    Parameters
    ----------
    name : str
        The function's Dakota name, a key of :data:`FUNCTIONS`.
    variables : sequence of str
        The deck's continuous variables, in the deck's order (the function reads them by
        position, or by descriptor for the functions that have labels).
    responses : sequence of str
        The deck's responses, in order.
    components : sequence of str, optional
        The deck's ``analysis_components`` (for the functions that take one).
    fixed : mapping of str to float, optional
        Values of the variables that are not inputs of the model.
    inputs : sequence of str, optional
        The model's inputs ``names_in``, any order (default: the variables not in
        ``fixed``).
    outputs : sequence of str, optional
        The model's outputs ``names_out`` (default: all responses).
    """

    def __init__(self, name: str, variables: Sequence[str], responses: Sequence[str],
                 components: Sequence[str] = (), *, fixed: Mapping[str, float] | None = None,
                 inputs: Sequence[str] | None = None,
                 outputs: Sequence[str] | None = None) -> None:
        info = _info(name)
        self.name = name
        self.info = info
        self.variables = tuple(str(n) for n in variables)
        self.responses = tuple(str(n) for n in responses)
        self.components = tuple(str(c) for c in components)
        for problem in (info.input_problem(self.variables),
                        info.response_problem(len(self.variables), len(self.responses)),
                        info.component_problem(self.components)):
            if problem is not None:
                raise ParameterError(f"Dakota test function {name!r}: expected {problem}; "
                                     f"got variables {list(self.variables)} and "
                                     f"{len(self.responses)} response(s)"
                                     + (f", components {list(self.components)}"
                                        if self.components else ""))
        self.fixed = {str(k): float(v) for k, v in (fixed or {}).items()}
        self.names_in = tuple(str(n) for n in inputs) if inputs is not None else tuple(
            v for v in self.variables if v not in self.fixed)
        self.names_out = tuple(str(n) for n in outputs) if outputs is not None else (
            self.responses)
        unknown = [n for n in (*self.names_in, *self.fixed) if n not in self.variables]
        unset = [v for v in self.variables if v not in self.names_in and v not in self.fixed]
        if unknown or unset or len(set(self.names_in)) < len(self.names_in):
            raise ParameterError(f"Dakota test function {name!r} of the variables "
                                 f"{list(self.variables)}: inputs {list(self.names_in)} and "
                                 f"fixed {sorted(self.fixed)} must give each variable once"
                                 + (f"; not variables: {unknown}" if unknown else "")
                                 + (f"; without a value: {unset}" if unset else ""))
        bad = [r for r in self.names_out if r not in self.responses]
        if bad:
            raise ParameterError(f"Dakota test function {name!r}: outputs {bad} are not among "
                                 f"its responses {list(self.responses)}")
        self._in = np.array([self.variables.index(n) for n in self.names_in], dtype=int)
        self._out = np.array([self.responses.index(r) for r in self.names_out], dtype=int)
        self._component = self.components[0] if self.components else (
            info.components[0] if info.components else "")
        # the deck's column of each of the function's own variables (label functions), None
        # for Dakota's local default value (cantilever's w, t)
        self._order: tuple[int | None, ...] | None = None
        if info.labels:
            self._order = tuple(self.variables.index(v) if v in self.variables else None
                                for v in info.labels[0])
        if info.has_gradient:
            self.gradient = self._gradient

    def _own(self, x: np.ndarray) -> np.ndarray:
        """Points (n, len(names_in)) -> the function's own variables, in its order."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        if x.ndim != 2 or x.shape[1] != len(self.names_in):
            raise ParameterError(f"{self!r}: points of shape (n, {len(self.names_in)}) "
                                 f"expected, got {x.shape}")
        full = np.empty((len(x), len(self.variables)))
        full[:, self._in] = x
        for k, v in self.fixed.items():
            full[:, self.variables.index(k)] = v
        if self._order is None:
            return full
        return np.column_stack([full[:, i] if i is not None else
                                np.full(len(x), _LABEL_DEFAULTS[self.name])
                                for i in self._order])

    def __call__(self, x: np.ndarray) -> np.ndarray:
        y, _ = _KERNELS[self.name](self._own(x), len(self.responses), self._component, False)
        return y[:, self._out]

    def _gradient(self, x: np.ndarray) -> np.ndarray:
        """Analytic gradient (n, len(names_out), len(names_in))."""
        own = self._own(x)
        _, g = _KERNELS[self.name](own, len(self.responses), self._component, True)
        assert g is not None
        if self._order is not None:  # back to the deck's variable order
            deck = np.zeros((len(own), len(self.responses), len(self.variables)))
            for k, i in enumerate(self._order):
                if i is not None:
                    deck[:, :, i] = g[:, :, k]
            g = deck
        return g[:, self._out][:, :, self._in]

    def identity(self) -> dict:
        """The function, its components, the deck's variables and responses, what is fixed."""
        return {"function": self.name, "components": list(self.components),
                "variables": list(self.variables), "responses": list(self.responses),
                "fixed": dict(sorted(self.fixed.items()))}

    def __repr__(self) -> str:
        comp = f", components={list(self.components)}" if self.components else ""
        return (f"DakotaFunction({self.name!r}, in={self.names_in}, out={self.names_out}"
                f"{comp})")


def dakota_function(name: str, names_in: Sequence[str], names_out: Sequence[str],
                    components: Sequence[str] = (), *, fixed: Mapping[str, float] | None = None,
                    inputs: Sequence[str] | None = None,
                    outputs: Sequence[str] | None = None) -> DakotaFunction:
    """The model of Dakota's direct test function ``name``.

    Parameters
    ----------
    name : str
        Dakota's ``analysis_drivers`` name, a key of :data:`FUNCTIONS`.
    names_in : sequence of str, length d
        The deck's continuous variables in the deck's order. Dakota hands them to most
        functions by position; for the functions of :attr:`FunctionInfo.labels` by
        descriptor, so there they must be the function's own names.
    names_out : sequence of str, length m
        The deck's responses; their number selects what the function returns (for
        ``text_book``: 1 objective, 2 adds the first constraint, 3 both).
    components : sequence of str, optional
        Dakota's ``analysis_components`` (``gerstner``: ``iso1`` ... ``aniso3``; ``genz``:
        ``os1`` ... ``cp3``).
    fixed : mapping of str to float, optional
        Values of variables that are not inputs of the model.
    inputs : sequence of str, optional
        The model's inputs, in any order (default: the variables not in ``fixed``).
    outputs : sequence of str, optional
        The responses the model returns, a subset of ``names_out`` in any order (default:
        all). Their number does not change what the function computes.

    Returns
    -------
    DakotaFunction
        ``model(x (n, d)) -> (n, m)``; ``model.gradient(x) -> (n, m, d)`` where Dakota has an
        analytic gradient (d inputs, m outputs).

    Raises
    ------
    ParameterError
        An unknown name (listing the known ones), or variables, responses or components the
        function does not accept (saying what it accepts).

    Examples
    --------
    >>> import numpy as np
    >>> tb = dakota_function("text_book", ["x1", "x2"], ["f", "c1", "c2"])
    >>> tb(np.array([[2.0, 3.0]]))
    array([[17. ,  2.5,  8. ]])
    >>> tb.gradient(np.array([[2.0, 3.0]]))[0]
    array([[ 4. , 32. ],
           [ 4. , -0.5],
           [-0.5,  6. ]])
    >>> c1 = dakota_function("text_book", ["x1", "x2"], ["f", "c1", "c2"], fixed={"x1": 2.0},
    ...                      outputs=["c1"])
    >>> c1.names_in, c1(np.array([[3.0]]))
    (('x2',), array([[2.5]]))
    """
    return DakotaFunction(name, names_in, names_out, components, fixed=fixed, inputs=inputs,
                          outputs=outputs)


def _info(name: str) -> FunctionInfo:
    try:
        return FUNCTIONS[name]
    except KeyError:
        import difflib

        close = difflib.get_close_matches(name, list(FUNCTIONS), n=1, cutoff=0.6)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ParameterError(f"unknown Dakota test function {name!r}{hint}; known: "
                             f"{', '.join(FUNCTIONS)}") from None


# ------------------------------------------------------------------------------------------
# kernels: x (n, d) in the function's own variable order, m responses, component, gradient?
# ------------------------------------------------------------------------------------------

def _text_book_parts(x: np.ndarray, m: int, want: Sequence[int], grad: bool):
    n, d = x.shape
    y = np.zeros((n, m))
    g = np.zeros((n, m, d)) if grad else None
    x0 = x[:, 0]
    x1 = x[:, 1] if d > 1 else None
    for k in want:
        if k == 0:
            y[:, 0] = np.sum((x - 1.0) ** 4, axis=1)
            if g is not None:
                g[:, 0, :] = 4.0 * (x - 1.0) ** 3
        elif k == 1:
            y[:, 1] = x0 * x0 - (0.5 * x1 if x1 is not None else 0.0)
            if g is not None:
                g[:, 1, 0] = 2.0 * x0
                if d > 1:
                    g[:, 1, 1] = -0.5
        else:
            y[:, 2] = -0.5 * x0 + (x1 * x1 if x1 is not None else 0.0)
            if g is not None:
                g[:, 2, 0] = -0.5
                if d > 1:
                    assert x1 is not None
                    g[:, 2, 1] = 2.0 * x1
    return y, g


def _text_book(x, m, comp, grad):
    return _text_book_parts(x, m, range(m), grad)


def _text_book_k(k: int) -> _Kernel:
    def kernel(x, m, comp, grad):
        return _text_book_parts(x, m, (k,), grad)
    return kernel


def _text_book_ouu(x, m, comp, grad):
    n, d = x.shape
    split = 2 + (d - 2) // 2
    a = x[:, 2:split] - 10.0 * x[:, [0]]
    b = x[:, split:] - 10.0 * x[:, [1]]
    y = np.zeros((n, m))
    y[:, 0] = np.sum(a ** 4, axis=1) + np.sum(b ** 4, axis=1)
    if m > 1:
        y[:, 1] = x[:, 0] * (x[:, 2] ** 2 - 0.5 * x[:, 3])
    if m > 2:
        y[:, 2] = x[:, 1] * (x[:, 3] ** 2 - 0.5 * x[:, 2])
    if not grad:
        return y, None
    g = np.zeros((n, m, d))
    g[:, 0, 0] = -40.0 * np.sum(a ** 3, axis=1)
    g[:, 0, 1] = -40.0 * np.sum(b ** 3, axis=1)
    g[:, 0, 2:split] = 4.0 * a ** 3
    g[:, 0, split:] = 4.0 * b ** 3
    if m > 1:
        g[:, 1, 0] = x[:, 2] ** 2 - 0.5 * x[:, 3]
        g[:, 1, 2] = 2.0 * x[:, 0] * x[:, 2]
        g[:, 1, 3] = -0.5 * x[:, 0]
    if m > 2:
        g[:, 2, 1] = x[:, 3] ** 2 - 0.5 * x[:, 2]
        g[:, 2, 2] = -0.5 * x[:, 1]
        g[:, 2, 3] = 2.0 * x[:, 1] * x[:, 3]
    return y, g


def _rosenbrock(x, m, comp, grad):
    x1, x2 = x[:, 0], x[:, 1]
    f1, f2 = x2 - x1 * x1, 1.0 - x1
    n = len(x)
    if m == 1:
        y = (100.0 * f1 * f1 + f2 * f2)[:, None]
        g = np.stack([-400.0 * f1 * x1 - 2.0 * f2, 200.0 * f1], axis=1)[:, None, :]
    else:
        y = np.column_stack([10.0 * f1, f2])
        g = np.zeros((n, 2, 2))
        g[:, 0, 0], g[:, 0, 1], g[:, 1, 0] = -20.0 * x1, 10.0, -1.0
    return y, (g if grad else None)


def _modified_rosenbrock(x, m, comp, grad):
    x1, x2 = x[:, 0], x[:, 1]
    f1, f2 = x2 - x1 * x1, 1.0 - x1
    arg = 2.0 * np.pi * x1 + x2
    f3 = np.sin(arg)
    n = len(x)
    if m == 1:
        y = (100.0 * f1 * f1 + f2 * f2 + f3 * f3)[:, None]
        s2 = np.sin(2.0 * arg)
        g = np.stack([-400.0 * f1 * x1 - 2.0 * f2 + 2.0 * np.pi * s2, 200.0 * f1 + s2],
                     axis=1)[:, None, :]
    else:
        y = np.column_stack([10.0 * f1, f2, f3])
        g = np.zeros((n, 3, 2))
        g[:, 0, 0], g[:, 0, 1], g[:, 1, 0] = -20.0 * x1, 10.0, -1.0
        g[:, 2, 0], g[:, 2, 1] = 2.0 * np.pi * np.cos(arg), np.cos(arg)
    return y, (g if grad else None)


def _generalized_rosenbrock(x, m, comp, grad):
    n, d = x.shape
    xi, xn = x[:, :-1], x[:, 1:]
    f1, f2 = xn - xi * xi, 1.0 - xi
    g = np.zeros((n, m, d)) if grad else None
    if m == 1:
        y = np.sum(100.0 * f1 * f1 + f2 * f2, axis=1)[:, None]
        if g is not None:
            g[:, 0, :-1] += -400.0 * f1 * xi - 2.0 * f2
            g[:, 0, 1:] += 200.0 * f1
        return y, g
    y = np.empty((n, m))
    y[:, 0::2], y[:, 1::2] = 10.0 * f1, f2
    if g is not None:
        i = np.arange(d - 1)
        g[:, 2 * i, i] = -20.0 * xi
        g[:, 2 * i, i + 1] = 10.0
        g[:, 2 * i + 1, i] = -1.0
    return y, g


def _extended_rosenbrock(x, m, comp, grad):
    n, d = x.shape
    xo, xe = x[:, 0::2], x[:, 1::2]   # x_{2i-1}, x_{2i} (1-based)
    f1, f2 = xe - xo * xo, 1.0 - xo
    g = np.zeros((n, m, d)) if grad else None
    if m == 1:
        y = np.sum(100.0 * f1 * f1 + f2 * f2, axis=1)[:, None]
        if g is not None:
            g[:, 0, 0::2] = -400.0 * f1 * xo - 2.0 * f2
            g[:, 0, 1::2] = 200.0 * f1
        return y, g
    y = np.empty((n, m))
    y[:, 0::2], y[:, 1::2] = 10.0 * f1, f2
    if g is not None:
        i = np.arange(0, d, 2)
        g[:, i, i] = -20.0 * xo
        g[:, i, i + 1] = 10.0
        g[:, i + 1, i] = -1.0
    return y, g


_GERSTNER = {  # component -> (form, x coefficient, y coefficient, xy coefficient)
    "iso1": (1, 10.0, 10.0, 0.0), "iso2": (2, 1.0, 1.0, 1.0), "iso3": (3, 10.0, 10.0, 0.0),
    "aniso1": (1, 1.0, 10.0, 0.0), "aniso2": (2, 1.0, 10.0, 10.0),
    "aniso3": (3, 10.0, 5.0, 0.0),
}


def _gerstner(x, m, comp, grad):
    form, cx, cy, cxy = _GERSTNER[comp]
    a, b = x[:, 0], x[:, 1]
    if form == 1:
        ea, eb = np.exp(-a * a), np.exp(-b * b)
        y = cx * ea + cy * eb
        g = (-2.0 * a * cx * ea, -2.0 * b * cy * eb)
    elif form == 2:
        exy = cxy * np.exp(a * b)
        y = cx * np.exp(a) + cy * np.exp(b) + exy
        g = (cx * np.exp(a) + exy * b, cy * np.exp(b) + exy * a)
    else:
        y = np.exp(-cx * a * a - cy * b * b)
        g = (-2.0 * a * cx * y, -2.0 * b * cy * y)
    return y[:, None], (np.stack(g, axis=1)[:, None, :] if grad else None)


def _scalable_gerstner(x, m, comp, grad):
    form, c_even, c_odd, c_inter = _GERSTNER[comp]
    n, d = x.shape
    c = np.where(np.arange(d) % 2 == 1, c_odd, c_even)
    gr = np.zeros((n, 1, d))
    if form == 1:
        e = np.exp(-x * x)
        y = np.sum(c * e, axis=1)
        gr[:, 0, :] = -2.0 * x * c * e
    elif form == 2:
        y = np.sum(c * np.exp(x), axis=1)
        gr[:, 0, :] = c * np.exp(x)
        # odd i (0-based) couple with i - 1
        odd = np.arange(1, d, 2)
        exy = c_inter * np.exp(x[:, odd] * x[:, odd - 1])
        y = y + np.sum(exy, axis=1)
        gr[:, 0, odd] += x[:, odd - 1] * exy
        gr[:, 0, odd - 1] += x[:, odd] * exy
    else:
        y = np.exp(-np.sum(c * x * x, axis=1))
        gr[:, 0, :] = -2.0 * x * c * y[:, None]
    return y[:, None], (gr if grad else None)


def _log_ratio(x, m, comp, grad):
    a, b = x[:, 0], x[:, 1]
    g = np.stack([1.0 / b, -a / (b * b)], axis=1)[:, None, :] if grad else None
    return (a / b)[:, None], g


def _short_column(x, m, comp, grad):
    b, h, P, M, Y = x.T
    n = len(x)
    ls = 1.0 - 4.0 * M / (b * h * h * Y) - P * P / (b * b * h * h * Y * Y)
    y = ls[:, None] if m == 1 else np.column_stack([b * h, ls])
    if not grad:
        return y, None
    g = np.zeros((n, m, 5))
    b2, h2, P2, Y2 = b * b, h * h, P * P, Y * Y
    k = m - 1
    g[:, k, 0] = 4.0 * M / (b2 * h2 * Y) + 2.0 * P2 / (b2 * b * h2 * Y2)
    g[:, k, 1] = 8.0 * M / (b * h2 * h * Y) + 2.0 * P2 / (b2 * h2 * h * Y2)
    g[:, k, 2] = -2.0 * P / (b2 * h2 * Y2)
    g[:, k, 3] = -4.0 / (b * h2 * Y)
    g[:, k, 4] = 4.0 * M / (b * h2 * Y2) + 2.0 * P2 / (b2 * h2 * Y2 * Y)
    if m == 2:
        g[:, 0, 0], g[:, 0, 1] = h, b
    return y, g


def _cantilever_common(x, m, grad, modified: bool):
    w, t, R, E, X, Y = x.T
    n = len(x)
    D0, L = 2.2535, 100.0
    w2, t2 = w * w, t * t
    stress = 600.0 * Y / w / t2 + 600.0 * X / w2 / t
    D1 = 4.0 * L ** 3 / E / (w * t)
    D2 = (Y / t2) ** 2 + (X / w2) ** 2
    if modified:
        D3, D4 = D1 / np.sqrt(D2), D1 * np.sqrt(D2)
        c1, c2 = stress - R, D4 - D0
    else:
        D3, D4 = D1 / np.sqrt(D2) / D0, D1 * np.sqrt(D2) / D0
        c1, c2 = stress / R - 1.0, D4 - 1.0
    cols = [c1, c2] if m == 2 else [w * t, c1, c2]
    y = np.column_stack(cols)
    if not grad:
        return y, None
    g = np.zeros((n, m, 6))
    i1, i2 = m - 2, m - 1
    if m == 3:
        g[:, 0, 0], g[:, 0, 1] = t, w
    s = 1.0 if modified else R  # the stress constraint is divided by R unless modified
    g[:, i1, 0] = -600.0 * (Y / t + 2.0 * X / w) / w2 / t / s
    g[:, i1, 1] = -600.0 * (2.0 * Y / t + X / w) / w / t2 / s
    g[:, i1, 2] = -1.0 if modified else -stress / (R * R)
    g[:, i1, 4] = 600.0 / w2 / t / s
    g[:, i1, 5] = 600.0 / w / t2 / s
    g[:, i2, 0] = -D3 * 2.0 * X * X / w2 / w2 / w - D4 / w
    g[:, i2, 1] = -D3 * 2.0 * Y * Y / t2 / t2 / t - D4 / t
    g[:, i2, 3] = -D4 / E
    g[:, i2, 4] = D3 * X / w2 / w2
    g[:, i2, 5] = D3 * Y / t2 / t2
    return y, g


def _cantilever(x, m, comp, grad):
    return _cantilever_common(x, m, grad, modified=False)


def _mod_cantilever(x, m, comp, grad):
    return _cantilever_common(x, m, grad, modified=True)


def _sobol_ishigami(x, m, comp, grad):
    pi = np.pi
    s1, s2 = np.sin(2.0 * pi * x[:, 0] - pi), np.sin(2.0 * pi * x[:, 1] - pi)
    u3 = 2.0 * pi * x[:, 2] - pi
    y = (1.0 + 0.1 * u3 ** 4) * s1 + 7.0 * s2 ** 2
    if not grad:
        return y[:, None], None
    g = np.stack([2.0 * pi * (1.0 + 0.1 * u3 ** 4) * np.cos(2.0 * pi * x[:, 0] - pi),
                  28.0 * pi * s2 * np.cos(2.0 * pi * x[:, 1] - pi),
                  0.8 * u3 ** 3 * s1], axis=1)
    return y[:, None], g[:, None, :]


def _sobol_rational(x, m, comp, grad):
    a, b = x[:, 0] + 0.5, x[:, 1] + 0.5
    y = b ** 4 / a ** 2
    g = np.stack([-2.0 * b ** 4 / a ** 3, 4.0 * b ** 3 / a ** 2], axis=1)[:, None, :]
    return y[:, None], (g if grad else None)


_SOBOL_G_A = np.array([0.0, 1.0, 2.0, 4.0, 8.0, 99.0, 99.0, 99.0, 99.0, 99.0])


def _sobol_g_function(x, m, comp, grad):
    n, d = x.shape
    a = _SOBOL_G_A[:d]
    fac = (np.abs(4.0 * x - 2.0) + a) / (1.0 + a)
    y = 2.0 * np.prod(fac, axis=1)
    if not grad:
        return y[:, None], None
    g = np.zeros((n, 1, d))
    for i in range(d):
        # d/dx_i of 2 |4 x_i - 2| / (1 + a_i) is +-8 / (1 + a_i); 0 at the kink, as Dakota
        slope = np.where(4.0 * x[:, i] > 2.0, 8.0, -8.0) / (1.0 + a[i])
        others = np.prod(np.delete(fac, i, axis=1), axis=1)
        g[:, 0, i] = np.where(4.0 * x[:, i] == 2.0, 0.0, slope * others)
    return y[:, None], g


_BARNES_A = np.array([75.196, -3.8112, 0.12694, -2.0567e-3, 1.0345e-5, -6.8306, 0.030234,
                      -1.28134e-3, 3.5256e-5, -2.266e-7, 0.25645, -3.4604e-3, 1.3514e-5,
                      -28.106, -5.2375e-6, -6.3e-8, 7.0e-10, 3.4054e-4, -1.6638e-6, -2.8673,
                      0.0005])


def _barnes(x, m, comp, grad):
    n, d = x.shape
    a = np.tile(_BARNES_A, (n, 1))
    a[:, 23 - d:] = x[:, 2:]   # the trailing coefficients are the uncertain variables
    a = a.T
    x1, x2 = x[:, 0], x[:, 1]
    x12, x1s, x2s = x1 * x2, x1 * x1, x2 * x2
    e = np.exp(a[20] * x12)
    f = (a[0] + a[1] * x1 + a[2] * x1s + a[3] * x1s * x1 + a[4] * x1s * x1s
         + a[5] * x2 + a[6] * x12 + a[7] * x1 * x12 + a[8] * x12 * x1s
         + a[9] * x2 * x1s * x1s + a[10] * x2s + a[11] * x2 * x2s + a[12] * x2s * x2s
         + a[13] / (x2 + 1.0) + a[14] * x2s * x1s + a[15] * x1 * x1s * x2s
         + a[16] * x12 * x2s * x1s + a[17] * x1 * x2s + a[18] * x12 * x2s + a[19] * e)
    y = np.column_stack([f, x12 / 700.0 - 1.0, x2 / 5.0 - x1s / 625.0,
                         (x2 / 50.0 - 1.0) ** 2 - x1 / 500.0 + 0.11])
    if not grad:
        return y, None
    g = np.zeros((n, 4, d))   # Dakota gives the derivatives by x1 and x2 only
    g[:, 0, 0] = (a[1] + 2.0 * a[2] * x1 + 3.0 * a[3] * x1s + 4.0 * a[4] * x1s * x1
                  + a[6] * x2 + 2.0 * a[7] * x12 + 3.0 * a[8] * x2 * x1s
                  + 4.0 * a[9] * x12 * x1s + 2.0 * a[14] * x2s * x1 + 3.0 * a[15] * x1s * x2s
                  + 3.0 * a[16] * x2 * x2s * x1s + a[17] * x2s + a[18] * x2 * x2s
                  + a[19] * a[20] * x2 * e)
    g[:, 0, 1] = (a[5] + a[6] * x1 + a[7] * x1s + a[8] * x1 * x1s + a[9] * x1s * x1s
                  + 2.0 * a[10] * x2 + 3.0 * a[11] * x2s + 4.0 * a[12] * x2 * x2s
                  - a[13] / (x2 + 1.0) ** 2 + 2.0 * a[14] * x2 * x1s
                  + 2.0 * a[15] * x1 * x1s * x2 + 3.0 * a[16] * x1 * x2s * x1s
                  + 2.0 * a[17] * x12 + 3.0 * a[18] * x1 * x2s + a[19] * a[20] * x1 * e)
    g[:, 1, 0], g[:, 1, 1] = x2 / 700.0, x1 / 700.0
    g[:, 2, 0], g[:, 2, 1] = -2.0 * x1 / 625.0, 0.2
    g[:, 3, 0], g[:, 3, 1] = -1.0 / 500.0, 2.0 * (x2 / 50.0 - 1.0) / 50.0
    return y, g


def _bayes_linear(x, m, comp, grad):
    return np.sum(x, axis=1)[:, None], None


_GENZ = {"os1": (0, 0, 4.5), "os2": (1, 0, 4.5), "os3": (2, 0, 4.5),
         "cp1": (0, 1, 0.25), "cp2": (1, 1, 0.25), "cp3": (2, 1, 0.25)}


def _genz(x, m, comp, grad):
    coeff_type, form, factor = _GENZ[comp]
    d = x.shape[1]
    k = np.arange(d, dtype=float)
    if coeff_type == 0:
        c = (k + 0.5) / d
    elif coeff_type == 1:
        c = 1.0 / (k + 1.0) ** 2
    else:
        c = np.exp((k + 1.0) * np.log(1e-8) / d)
    c = c * (factor / np.sum(c))
    s = x @ c
    y = np.cos(s) if form == 0 else (1.0 + s) ** (-(d + 1.0))   # the phase 2 pi w is 0
    return y[:, None], None


def _damped_oscillator(x, m, comp, grad):
    n, d = x.shape
    p = np.tile([0.0, 0.035, 0.1, 1.0, 0.5, 0.0], (n, 1))   # b k F w x0 v0
    p[:, :d] = x
    b, k, F, w, x0, v0 = p.T
    kw, bw, gam = k - w * w, b * w, b / 2.0
    zeta2 = bw * bw + kw * kw
    zeta = np.sqrt(zeta2)
    with np.errstate(invalid="ignore", divide="ignore"):
        phi = np.arctan(-bw / kw) + np.where(kw / zeta2 < 0, np.pi, 0.0)
        sqrtk = np.sqrt(k)
        wd = sqrtk * np.sqrt(1.0 - gam * gam / k)
        B1, B2 = -F * bw / zeta2, F * kw / zeta2
        A1 = x0 - B1
        A2 = (v0 + gam * A1 - w * B2) / wd
        times = (20.0 / m) * np.arange(1, m + 1)
        tt = times[None, :]
        y = (F / zeta)[:, None] * np.sin(w[:, None] * tt + phi[:, None]) + np.exp(
            -gam[:, None] * tt) * (A1[:, None] * np.cos(wd[:, None] * tt)
                                   + A2[:, None] * np.sin(wd[:, None] * tt))
    y[~(sqrtk > gam)] = np.nan   # Dakota stops: not an under-damped oscillator
    return y, None


def _steel_section(x, m, comp, grad):
    Z, Fy = x[:, 0], x[:, 1]
    g = np.stack([Fy, Z], axis=1)[:, None, :] if grad else None
    return (Fy * Z - 1140.0)[:, None], g


_PORTAL = np.array([1.0, 2.0, 2.0, 1.0, -5.0, -5.0])


def _portal_frame(x, m, comp, grad):
    g = np.tile(_PORTAL, (len(x), 1, 1)) if grad else None
    return (x @ _PORTAL)[:, None], g


# ------------------------------------------------------------------------------------------
# the registry
# ------------------------------------------------------------------------------------------

_TB_OUT = "1 (objective f), 2 (f, c1) or 3 (f, c1, c2) responses"

#: Dakota's test functions (its ``analysis_drivers`` names) -> what each takes and gives
#: (:class:`FunctionInfo`); :func:`dakota_function` makes a model of one.
FUNCTIONS: dict[str, FunctionInfo] = {f.name: f for f in (
    FunctionInfo("text_book", "f = sum (x_i - 1)^4; c1 = x1^2 - x2/2; c2 = x2^2 - x1/2",
                 None, "any number of variables (>= 1)", _TB_OUT, True),
    FunctionInfo("text_book1", "text_book's objective only (response 1; others 0)",
                 None, "any number of variables (>= 1)", "1 to 3 responses", True),
    FunctionInfo("text_book2", "text_book's first constraint only (response 2; others 0)",
                 None, "any number of variables (>= 1)", "2 or 3 responses", True),
    FunctionInfo("text_book3", "text_book's second constraint only (response 3; others 0)",
                 None, "any number of variables (>= 1)", "3 responses", True),
    FunctionInfo("text_book_ouu", "text_book for design under uncertainty: 2 design "
                 "variables d1 d2, then uncertain ones split between them",
                 None, "an even number of variables >= 4", _TB_OUT, True),
    FunctionInfo("rosenbrock", "f = 100 (x2 - x1^2)^2 + (1 - x1)^2, or the residuals "
                 "10 (x2 - x1^2), 1 - x1", 2, "x1, x2 (by descriptor)",
                 "1 (objective) or 2 (least-squares residuals) responses", True,
                 labels=(("x1", "x2"),)),
    FunctionInfo("modified_rosenbrock", "rosenbrock plus sin(2 pi x1 + x2)^2 (residual "
                 "sin(2 pi x1 + x2))", 2, "x1, x2 (by descriptor)",
                 "1 (objective) or 3 (least-squares residuals) responses", True,
                 labels=(("x1", "x2"),)),
    FunctionInfo("generalized_rosenbrock", "sum over i of 100 (x_{i+1} - x_i^2)^2 + "
                 "(1 - x_i)^2 (coupled)", None, "any number of variables (>= 2)",
                 "1 (objective) or 2 (d - 1) (least-squares residuals) responses", True),
    FunctionInfo("extended_rosenbrock", "sum of d/2 uncoupled 2-D rosenbrock functions",
                 None, "an even number of variables", "1 (objective) or d (least-squares "
                 "residuals) responses", True),
    FunctionInfo("cantilever", "cantilever beam: area w t, stress/R - 1, displacement/D0 - 1",
                 None, "w, t, R, E, X, Y or R, E, X, Y (w = t = 2.5) (by descriptor)",
                 "2 (stress, displacement) or 3 (area, stress, displacement) responses", True,
                 labels=(("w", "t", "R", "E", "X", "Y"), ("R", "E", "X", "Y"))),
    FunctionInfo("mod_cantilever", "cantilever beam, unscaled limit states: area, "
                 "stress - R, displacement - D0", None,
                 "w, t, R, E, X, Y or R, E, X, Y (w = t = 2.5) (by descriptor)",
                 "2 (stress, displacement) or 3 (area, stress, displacement) responses", True,
                 labels=(("w", "t", "R", "E", "X", "Y"), ("R", "E", "X", "Y"))),
    FunctionInfo("short_column", "short column limit state 1 - 4M/(b h^2 Y) - "
                 "P^2/(b h Y)^2, optionally after the area b h", 5,
                 "b, h, P, M, Y (by descriptor)",
                 "1 (limit state) or 2 (area, limit state) responses", True,
                 labels=(("b", "h", "P", "M", "Y"),)),
    FunctionInfo("log_ratio", "f = x1 / x2", 2, "2 variables", "1 response", True),
    FunctionInfo("steel_section", "g = F_y Z - 1140 (x1 = Z, x2 = F_y); Dakota's "
                 "test/steel_section program", 2, "2 variables", "1 response", True),
    FunctionInfo("portal_frame", "g = x1 + 2 x2 + 2 x3 + x4 - 5 x5 - 5 x6; Dakota's "
                 "test/portal_frame program", 6, "6 variables", "1 response", True),
    FunctionInfo("gerstner", "iso1/aniso1: a e^(-x^2) + b e^(-y^2); iso2/aniso2: a e^x + b "
                 "e^y + c e^(xy); iso3/aniso3: e^(-a x^2 - b y^2)", 2, "2 variables",
                 "1 response", True, components=tuple(_GERSTNER)),
    FunctionInfo("scalable_gerstner", "gerstner in d variables (coefficients alternate "
                 "between even and odd variables)", None, "any number of variables (>= 1)",
                 "1 response", True, components=tuple(_GERSTNER)),
    FunctionInfo("sobol_ishigami", "(1 + 0.1 (2 pi x3 - pi)^4) sin(2 pi x1 - pi) + "
                 "7 sin^2(2 pi x2 - pi)", 3, "x1, x2, x3 (by descriptor)", "1 response", True,
                 labels=(("x1", "x2", "x3"),)),
    FunctionInfo("sobol_rational", "f = (x2 + 1/2)^4 / (x1 + 1/2)^2", 2, "2 variables",
                 "1 response", True),
    FunctionInfo("sobol_g_function", "f = 2 prod (|4 x_i - 2| + a_i) / (1 + a_i), a = 0 1 2 "
                 "4 8 99 ...", None, "1 to 10 variables", "1 response", True),
    FunctionInfo("barnes", "Barnes' polynomial objective and 3 constraints (x1, x2 design; "
                 "optional trailing coefficients a_i uncertain)", None,
                 "2 to 23 variables", "4 responses (f, g1, g2, g3)", True),
    FunctionInfo("bayes_linear", "f = sum x_i", None, "1 to 500 variables", "1 response",
                 False),
    FunctionInfo("genz", "Genz oscillatory (os1-os3: cos(c . x)) or corner peak (cp1-cp3: "
                 "(1 + c . x)^-(d+1))", None, "any number of variables (>= 1)", "1 response",
                 False, components=tuple(_GENZ)),
    FunctionInfo("damped_oscillator", "displacement of a damped, forced oscillator at m "
                 "equal times up to t = 20 (variables b k F w x0 v0, trailing ones default "
                 "0.035 0.1 1 0.5 0)", None, "1 to 6 variables", "any number of responses "
                 "(>= 1)", False),
)}



def _ANY(d: int) -> bool:
    return d >= 1


_INPUT_COUNTS: dict[str, Callable[[int], bool]] = {
    "text_book": _ANY, "text_book1": _ANY, "text_book2": _ANY, "text_book3": _ANY,
    "text_book_ouu": lambda d: d >= 4 and d % 2 == 0,
    "rosenbrock": lambda d: d == 2, "modified_rosenbrock": lambda d: d == 2,
    "generalized_rosenbrock": lambda d: d >= 2,
    "extended_rosenbrock": lambda d: d >= 2 and d % 2 == 0,
    "cantilever": lambda d: d in (4, 6), "mod_cantilever": lambda d: d in (4, 6),
    "short_column": lambda d: d == 5, "log_ratio": lambda d: d == 2,
    "steel_section": lambda d: d == 2, "portal_frame": lambda d: d == 6,
    "gerstner": lambda d: d == 2, "scalable_gerstner": _ANY,
    "sobol_ishigami": lambda d: d == 3, "sobol_rational": lambda d: d == 2,
    "sobol_g_function": lambda d: 1 <= d <= 10, "barnes": lambda d: 2 <= d <= 23,
    "bayes_linear": lambda d: 1 <= d <= 500, "genz": _ANY,
    "damped_oscillator": lambda d: 1 <= d <= 6,
}


def _ONE(d: int) -> tuple[int, ...]:
    return (1,)


_RESPONSE_COUNTS: dict[str, Callable[[int], tuple[int, ...] | None]] = {
    "text_book": lambda d: (1, 2, 3), "text_book1": lambda d: (1, 2, 3),
    "text_book2": lambda d: (2, 3), "text_book3": lambda d: (3,),
    "text_book_ouu": lambda d: (1, 2, 3),
    "rosenbrock": lambda d: (1, 2), "modified_rosenbrock": lambda d: (1, 3),
    "generalized_rosenbrock": lambda d: (1, 2 * (d - 1)),
    "extended_rosenbrock": lambda d: (1, d),
    "cantilever": lambda d: (2, 3), "mod_cantilever": lambda d: (2, 3),
    "short_column": lambda d: (1, 2), "log_ratio": _ONE, "steel_section": _ONE,
    "portal_frame": _ONE, "gerstner": _ONE, "scalable_gerstner": _ONE,
    "sobol_ishigami": _ONE, "sobol_rational": _ONE, "sobol_g_function": _ONE,
    "barnes": lambda d: (4,), "bayes_linear": _ONE, "genz": _ONE,
    "damped_oscillator": lambda d: None,
}
_KERNELS: dict[str, _Kernel] = {
    "text_book": _text_book, "text_book1": _text_book_k(0), "text_book2": _text_book_k(1),
    "text_book3": _text_book_k(2), "text_book_ouu": _text_book_ouu,
    "rosenbrock": _rosenbrock, "modified_rosenbrock": _modified_rosenbrock,
    "generalized_rosenbrock": _generalized_rosenbrock,
    "extended_rosenbrock": _extended_rosenbrock, "cantilever": _cantilever,
    "mod_cantilever": _mod_cantilever, "short_column": _short_column,
    "log_ratio": _log_ratio, "steel_section": _steel_section, "portal_frame": _portal_frame,
    "gerstner": _gerstner, "scalable_gerstner": _scalable_gerstner,
    "sobol_ishigami": _sobol_ishigami, "sobol_rational": _sobol_rational,
    "sobol_g_function": _sobol_g_function, "barnes": _barnes, "bayes_linear": _bayes_linear,
    "genz": _genz, "damped_oscillator": _damped_oscillator,
}
# the local value Dakota gives a labelled variable the deck leaves out (cantilever's w, t)
_LABEL_DEFAULTS = {"cantilever": 2.5, "mod_cantilever": 2.5}
