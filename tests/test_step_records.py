"""Every step type saves a typed record (issue 25), and every record reads back equal from a
saved results folder: arrays bitwise with their dtypes and axes, names, numbers, flags and
text as they were (through :func:`rotoruq.results.save_step` / :func:`load_step`, the files
a results folder holds)."""

from __future__ import annotations

import types
import typing
from collections.abc import Mapping
from dataclasses import fields

import numpy as np
import pytest

from rotoruq.results import _DEFAULT_LABELS, StepRecord, StepResult, load_step, save_step
from rotoruq.steps import STEP_TYPES


def _records() -> list[type[StepRecord]]:
    """The concrete record types of the step modules (the base classes excepted)."""
    out, todo = [], list(StepRecord.__subclasses__())
    while todo:
        cls = todo.pop()
        todo.extend(cls.__subclasses__())
        if cls.__module__.startswith("rotoruq.steps") and cls.__name__ not in (
                "LevelsRecord", "MappingsRecord"):
            out.append(cls)
    return sorted(out, key=lambda c: c.__name__)


RECORDS = _records()


def _value(cls: type[StepRecord], name: str, hint, rng: np.random.Generator):
    """A value of field ``name`` of type ``hint``: random numbers (with NaN and inf, which
    records use for "not computed"), text with quotes and non-ASCII letters."""
    if name in cls.AXES:
        # an axis named by a field holds as many elements as the field's 3 names; one with
        # literal labels (bounds, level columns, moments) as many as those
        labels = {**_DEFAULT_LABELS, **cls.LABELS}
        shape = tuple(len(lab) if isinstance(labels.get(axis), tuple | list) else 3
                      for axis in cls.AXES[name] for lab in [labels.get(axis)])
        arr = rng.normal(size=shape)
        if arr.size > 2:
            arr.flat[0], arr.flat[1] = np.nan, np.inf
        return arr
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        return _value(cls, name, next(a for a in args if a is not type(None)), rng)
    if origin is tuple:
        if args == (str, ...):
            return ("a", "b'\"", "é")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(int(v) for v in rng.integers(0, 9, size=3))
        return tuple(_value(cls, name, a, rng) for a in args)
    if origin in (dict, Mapping) or hint in (dict, Mapping):
        return {"h_r": [0.5, 1.0], "x": [2.0, 3.0]}
    if hint is bool:
        return True
    if hint is int:
        return int(rng.integers(1, 100))
    if hint is float:
        return float(rng.normal())
    if hint is str:
        return "not identifiable: 'a' ~ \"b\" (é)"
    raise AssertionError(f"{cls.__name__}.{name}: no test value for {hint!r}")


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray):
        return (isinstance(b, np.ndarray) and a.dtype == b.dtype and a.shape == b.shape
                and a.tobytes() == b.tobytes())
    return type(a) is type(b) and a == b


def test_every_step_type_has_a_record():
    """Each registered step type's module (or the module it builds its result with) defines
    a record."""
    modules = {cls.__module__ for cls in RECORDS}
    missing = [name for name, st in STEP_TYPES.items() if st.run.__module__ not in modules]
    assert not missing, f"step types without a typed record: {missing}"


@pytest.mark.parametrize("cls", RECORDS, ids=lambda c: c.__name__)
def test_record_round_trips_through_a_results_folder(tmp_path, cls):
    hints = typing.get_type_hints(cls)
    rng = np.random.default_rng(len(cls.__name__))
    kwargs = {f.name: _value(cls, f.name, hints[f.name], rng) for f in fields(cls)}
    rec = cls(**kwargs)
    arrays, meta = rec.parts()
    assert set(arrays) == set(cls.AXES)
    save_step(StepResult("s", "t", {"k": 1.0}, arrays, meta=meta), tmp_path)
    back = cls.read(load_step(tmp_path / "steps" / "s"))
    for f in fields(cls):
        assert _same(getattr(back, f.name), kwargs[f.name]), f.name


@pytest.mark.parametrize("kind", ["sampling", "reliability", "evidence", "cuu", "least_squares",
                                  "forward_check", "multifidelity", "validation",
                                  "verification"])
def test_a_step_saved_before_its_record_shows_its_flat_view(tmp_path, kind):
    """A results folder written before the type had a record still reads: the report and
    ``show`` give its flat scalars with the reason, and its warnings and figures nothing
    (they have no record to read), instead of failing."""
    from rotoruq.render.figures import FigureContext
    from rotoruq.report.steptables import step_tables

    old = StepResult("old", kind, {"mean/y1": 1.5, "std/y1": 0.25},
                     {"outputs": np.ones((3, 1))},
                     meta={"responses": ["y1"], "columns": {"outputs": ["y1"]},
                           "dropped_correlation": ["a", "b", 0.9], "identifiable": False})
    res = load_step(save_step(old, tmp_path))
    (table,) = step_tables(res)
    assert table.rows == (("mean/y1", 1.5), ("std/y1", 0.25))
    assert f"saved without a {kind.title().replace('_', '')}Record" in table.note
    st = STEP_TYPES[kind]
    assert st.warnings is None or st.warnings(res, {}) == []
    assert st.figures is None or st.figures(res, FigureContext("s", {"old": res})) == []
