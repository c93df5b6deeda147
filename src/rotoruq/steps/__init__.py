"""The step types a study file can run: one module per type, one registry.

Each module of this package holds everything about its type: the option schema, the run
adapter (``run(StepContext) -> StepResult``, calling the method), the report's tables,
figures and warnings, and ``STEP = StepType(...)`` tying them together. :data:`STEP_TYPES`
below lists them explicitly; the study layer reads it to parse and run steps, the report to
render them. Nothing is registered by import side effects.

A new step type is one module plus one line:

* in rotoruq: ``steps/my_step.py`` defining ``STEP`` and ``my_step`` in the import and the
  tuple below;
* outside rotoruq (a plugin, or a test): a module defining ``STEP`` and an entry point in
  the group ``rotoruq.steps`` naming it (``my_step = "my_package.my_step:STEP"`` under
  ``[project.entry-points."rotoruq.steps"]``). :func:`step_types` adds those after the
  built-in types; a plugin may not replace a built-in type.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from functools import cache
from types import MappingProxyType

from ..errors import RotoruqError
from . import (
    bayes_calibration,
    cuu,
    evidence,
    forward_check,
    least_squares,
    mean_value,
    multifidelity,
    pce,
    reliability,
    sampling,
    sensitivity,
    validation,
    verification,
)
from .base import StepCheck, StepContext, StepType, run_step

__all__ = ["STEP_TYPES", "ENTRY_POINT_GROUP", "StepType", "StepContext", "StepCheck",
           "UnknownStepTypeError", "step_types", "step_type", "find_step_type", "run_step"]

#: The built-in step types, in the order the documentation lists them.
STEP_TYPES: Mapping[str, StepType] = MappingProxyType({m.STEP.name: m.STEP for m in (
    sampling, sensitivity, mean_value, reliability, pce, evidence, bayes_calibration,
    least_squares, cuu, forward_check, verification, validation, multifidelity)})

#: Entry-point group of step types outside rotoruq (each entry: ``name = "module:STEP"``).
ENTRY_POINT_GROUP = "rotoruq.steps"


class UnknownStepTypeError(RotoruqError, KeyError):
    """A step type name that neither rotoruq nor an installed plugin defines."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


@cache
def _plugins() -> Mapping[str, StepType]:
    from importlib.metadata import entry_points

    out: dict[str, StepType] = {}
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        st = ep.load()
        if not isinstance(st, StepType):
            raise TypeError(f"entry point {ep.name} = {ep.value!r} in {ENTRY_POINT_GROUP}: "
                            f"expected a StepType, found {type(st).__name__}")
        if st.name != ep.name:
            raise ValueError(f"entry point {ep.name} = {ep.value!r} in {ENTRY_POINT_GROUP}: "
                             f"its StepType is named {st.name!r}")
        if st.name in STEP_TYPES:
            raise ValueError(f"entry point {ep.value!r} in {ENTRY_POINT_GROUP} redefines the "
                             f"built-in step type {st.name!r}")
        out[st.name] = st
    return MappingProxyType(out)


def step_types() -> Mapping[str, StepType]:
    """Every step type: the built-in ones, then those of installed plugins."""
    plugins = _plugins()
    return MappingProxyType({**STEP_TYPES, **plugins}) if plugins else STEP_TYPES


def find_step_type(name: str) -> StepType | None:
    """The step type ``name``, None when there is none (an old or foreign result's type).

    Parameters
    ----------
    name : str
        A step type name, as :func:`step_type` takes it.

    Returns
    -------
    StepType or None
        That step type; None when neither rotoruq nor a plugin defines it.

    See Also
    --------
    step_type : The same look-up, raising on an unknown name.
    """
    return STEP_TYPES.get(name) or _plugins().get(name)


def step_type(name: str) -> StepType:
    """The step type ``name``; raises :class:`UnknownStepTypeError` listing the known ones.

    Parameters
    ----------
    name : str
        A step type name (a step's ``type``: ``"sampling"``, ``"pce"``, ...), built-in or of
        an installed plugin.

    Returns
    -------
    StepType
        That step type.

    Raises
    ------
    UnknownStepTypeError
        Neither rotoruq nor an installed plugin defines ``name``; the message names the
        closest known type and lists them all.

    Examples
    --------
    >>> from rotoruq.steps import step_type
    >>> step_type("pce").method
    'rotoruq.methods.pce:polynomial_chaos'
    >>> step_type("sensitivty")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    rotoruq.steps.UnknownStepTypeError: unknown step type 'sensitivty' (did you mean ...
    """
    st = find_step_type(name)
    if st is None:
        known = list(step_types())
        close = difflib.get_close_matches(name, known, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise UnknownStepTypeError(f"unknown step type {name!r}{hint}; known: "
                                   + ", ".join(known))
    return st
