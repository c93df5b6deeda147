"""A model whose inputs go by other names: a study's parameter ``kp`` feeding the rotor's
``k_pitch_link`` (``[parameters.kp] input = "k_pitch_link"``, the study-file form of the
driver's ``--map``)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..model import EvalBatch, Model, evaluate, has_gradient

__all__ = ["RenamedInputs"]


class RenamedInputs:
    """``model`` with its inputs renamed: ``names_in[k]`` is the name of
    ``model.names_in[k]`` (same order, same values; outputs, gradients, one-point runs and the
    failure policy pass through).

    Its identity is the wrapped model's (configuration and code) plus the names, so the
    store and step fingerprints tell it apart from the model under its own names.

    Examples
    --------
    >>> import numpy as np
    >>> from rotoruq.model import FunctionModel
    >>> inner = FunctionModel(lambda x: 2.0 * x, ["k_pitch_link"], ["y"])
    >>> m = RenamedInputs(inner, ["kp"])
    >>> m.names_in, m(np.array([[3.0]])).tolist()
    (('kp',), [[6.0]])
    """

    def __init__(self, model: Model, names_in: Sequence[str]) -> None:
        self.model: Any = model
        self.names_in = tuple(str(n) for n in names_in)
        if len(self.names_in) != len(model.names_in) or len(set(self.names_in)) < len(
                self.names_in):
            raise ParameterError(f"{len(model.names_in)} distinct names for the inputs "
                                 f"{list(model.names_in)}, got {list(self.names_in)}")
        self.names_out = tuple(model.names_out)
        inner: Any = model  # run_one, gradient: optional members
        if callable(getattr(inner, "run_one", None)):
            self.run_one = inner.run_one
        if has_gradient(inner):
            self.gradient = inner.gradient
            if callable(getattr(inner, "evaluate_gradient", None)):
                self.evaluate_gradient = inner.evaluate_gradient

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.evaluate(x).values

    def evaluate(self, x: np.ndarray) -> EvalBatch:
        return evaluate(self.model, x)

    @property
    def failure_policy(self):
        return getattr(self.model, "failure_policy", None)

    def identity(self) -> dict:
        from .identity import model_identity

        return {"model": model_identity(self.model),
                "names": dict(zip(self.names_in, self.model.names_in, strict=True))}

    def __repr__(self) -> str:
        return f"RenamedInputs({self.model!r}, names_in={list(self.names_in)})"
