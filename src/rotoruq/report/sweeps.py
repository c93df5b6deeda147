"""Steps of one type that differ in one fixed input: a sweep the report draws against it.

A study that runs the same step type at several values of one fixed input (Sobol indices at
advance ratios 0.1, 0.2 and 0.3) asks how the results move with that input. The run records
each step's own fixed inputs (``study.json`` ``step_fixed``); :func:`find_sweeps` groups the
steps whose fixed inputs have the same names and differ in exactly one numeric value, and
the step type's ``sweep_figures`` renderer draws them against it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from ..render.figures import Figure, FigureContext
from ..results import StepResult
from ..steps import find_step_type
from .plots import step_figures

__all__ = ["Sweep", "find_sweeps", "sweep_figures"]


@dataclass(frozen=True)
class Sweep:
    """Steps of type ``type`` (names in ``steps``) at the values ``values`` (increasing) of
    the fixed input ``swept``, equal in every other fixed input."""

    type: str
    swept: str
    steps: tuple[str, ...]
    values: tuple[float, ...]


def find_sweeps(types: Mapping[str, str], fixed: Mapping[str, Mapping[str, float]]
                ) -> list[Sweep]:
    """The sweeps among a study's steps.

    Parameters
    ----------
    types : mapping of str to str
        Step name -> step type, in the study's order.
    fixed : mapping of str to mapping of str to float
        Step name -> the fixed inputs the step sets itself (``study.json`` ``step_fixed``).

    Returns
    -------
    list of Sweep
        One per group of two or more steps of one type whose fixed inputs have the same
        names and differ in exactly one, with a distinct number at each step.

    Examples
    --------
    >>> find_sweeps({"a": "sensitivity", "b": "sensitivity", "c": "sampling"},
    ...             {"a": {"mu": 0.2, "h": 1.0}, "b": {"mu": 0.1, "h": 1.0}, "c": {"mu": 0.3}})
    [Sweep(type='sensitivity', swept='mu', steps=('b', 'a'), values=(0.1, 0.2))]
    """
    groups: dict[tuple[str, tuple[str, ...]], list[str]] = {}
    for name, typ in types.items():
        keys = tuple(sorted((fixed.get(name) or {}).keys()))
        if keys:
            groups.setdefault((typ, keys), []).append(name)
    out = []
    for (typ, keys), names in groups.items():
        if len(names) < 2:
            continue
        differ = [k for k in keys if len({_number(fixed[n][k]) for n in names}) > 1]
        if len(differ) != 1:
            continue
        values = [v for n in names if (v := _number(fixed[n][differ[0]])) is not None]
        if len(values) != len(names) or len(set(values)) != len(values):
            continue
        order = sorted(range(len(names)), key=values.__getitem__)
        out.append(Sweep(typ, differ[0], tuple(names[i] for i in order),
                         tuple(values[i] for i in order)))
    return out


def _number(v: object) -> float | None:
    if isinstance(v, bool) or not isinstance(v, int | float):
        return None
    return float(v)


def sweep_figures(steps: Mapping[str, StepResult], types: Mapping[str, str],
                  fixed: Mapping[str, Mapping[str, float]], ctx: FigureContext
                  ) -> list[Figure]:
    """The figures of every sweep among ``steps`` whose step type draws sweeps (its
    ``sweep_figures`` renderer); steps not saved (a failed run) leave their sweep out."""
    figs: list[Figure] = []
    for sw in find_sweeps(types, fixed):
        st = find_step_type(sw.type)
        if st is None or st.sweep_figures is None or any(s not in steps for s in sw.steps):
            continue
        hook = st.sweep_figures
        results = [steps[s] for s in sw.steps]

        def draw(_res: StepResult, c: FigureContext, hook=hook, results=results,
                 sw=sw) -> list[Figure]:
            return hook(results, sw.swept, sw.values, c)

        figs += step_figures(draw, results[0], ctx)
    return figs
