"""Option schemas of step types: value checkers and the :class:`Option` record.

A checker is ``check(value) -> normalised value`` and raises ``TypeError("<expected form>")``
for a bad value; the study file's :class:`~rotoruq.study.options.Checker` adds the file, the
key, the table and the line.
"""

from __future__ import annotations

import dataclasses
import difflib
import importlib
import inspect
import math
import typing
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cache
from typing import Any

__all__ = ["Option", "REQUIRED", "SIGNATURE", "integer", "number", "choice",
           "string", "string_list", "number_list", "table", "table_or_string",
           "number_or_table", "boolean", "signature_default", "close_hint", "Check"]


class _Marker:
    def __init__(self, name: str):
        self.name = name

    def __repr__(self) -> str:
        return self.name


#: An option without default: the study file must give it.
REQUIRED: Any = _Marker("REQUIRED")
#: The default is that of the method's own parameter (its signature: one place).
SIGNATURE: Any = _Marker("SIGNATURE")

Check = Callable[[Any], Any]


@dataclass(frozen=True, eq=False)
class Option:
    """One key of a study-file table.

    check : the value checker. default : a value, :data:`REQUIRED` or :data:`SIGNATURE`.
    param : for :data:`SIGNATURE`, the parameter of ``method`` whose default applies (default:
        the key itself). method : ``"module:function"`` whose signature holds that default
        (default: the step type's method). A parameter without default makes the option
        required.
    """

    check: Check
    default: Any = None
    param: str | None = None
    method: str | None = None


@cache
def _signature(target: str) -> inspect.Signature:
    module, name = target.split(":")
    return inspect.signature(getattr(importlib.import_module(module), name))


@cache
def _record_defaults(target: str) -> dict[str, list[Any]]:
    """field -> defaults of that field in the option records (dataclasses) that the
    parameters of ``target`` take, read from their annotations (``convergence: Convergence |
    None``); an annotation that does not resolve at run time is skipped."""
    module_name, name = target.split(":")
    module = importlib.import_module(module_name)
    space = vars(module)
    out: dict[str, list[Any]] = {}
    for p in _signature(target).parameters.values():
        ann = p.annotation
        if isinstance(ann, str):
            try:
                ann = eval(ann, space)  # what typing.get_type_hints does, one parameter
            except Exception:  # an annotation for type checkers only
                continue
        for cls in (*typing.get_args(ann), ann):
            if isinstance(cls, type) and dataclasses.is_dataclass(cls):
                for f in dataclasses.fields(cls):
                    if f.default is not dataclasses.MISSING:
                        out.setdefault(f.name, []).append(f.default)
    return out


def signature_default(target: str, param: str) -> Any:
    """Default of parameter ``param`` of ``target`` (``"module:function"``), or of the field
    ``param`` of the option record one of its parameters takes (``least_squares(convergence=
    Convergence(tolerance=...))``); :data:`REQUIRED` when it has none. Raises ``LookupError``
    when the function has no such parameter or record field, or records disagree on it.

    Examples
    --------
    >>> signature_default("rotoruq.methods.least_squares:least_squares", "optimizer")
    'nl2sol'
    >>> signature_default("rotoruq.methods.least_squares:least_squares", "tolerance")
    0.0001
    """
    params = _signature(target).parameters
    if param not in params:
        found = _record_defaults(target).get(param, [])
        if found and all(d == found[0] for d in found):
            return found[0]
        why = "option records disagree on" if found else "has no parameter"
        fields = list(_record_defaults(target))
        also = f"; its option records: {', '.join(fields)}" if fields else ""
        raise LookupError(f"{target} {why} {param!r} (it has {', '.join(params)}{also})")
    default = params[param].default
    return REQUIRED if default is inspect.Parameter.empty else default


def integer(minimum: int = 0, maximum: int = 2**63 - 1) -> Check:
    def check(v: Any) -> int:
        if isinstance(v, bool) or not isinstance(v, int) or v < minimum:
            raise TypeError(f"an integer >= {minimum}")
        if v > maximum:
            raise TypeError(f"an integer from {minimum} to {maximum}")
        return v

    return check


def number(positive: bool = False, allow_zero: bool = True) -> Check:
    def check(v: Any) -> float:
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise TypeError("a finite number")
        if positive and (v < 0 or (v == 0 and not allow_zero)):
            raise TypeError("a number > 0" if not allow_zero else "a number >= 0")
        return float(v)

    return check


def string(choices: Sequence[str] | None = None) -> Check:
    def check(v: Any) -> str:
        if not isinstance(v, str):
            raise TypeError("a string" + (f" (one of {', '.join(choices)})" if choices else ""))
        if choices is not None and v.lower() not in choices:
            raise TypeError(f"one of {', '.join(repr(c) for c in choices)}")
        return v.lower() if choices is not None else v

    return check


def choice(*choices: str) -> Check:
    """One of ``choices`` (case-insensitive; returned in lower case)."""
    return string(choices)


def string_list(v: Any) -> tuple[str, ...]:
    if isinstance(v, str):
        return (v,)
    if not isinstance(v, list) or not all(isinstance(s, str) for s in v):
        raise TypeError("a list of strings")
    return tuple(v)


def number_list(v: Any) -> tuple[float, ...]:
    if not isinstance(v, list) or not all(
        isinstance(s, int | float) and not isinstance(s, bool) for s in v
    ):
        raise TypeError("a list of numbers")
    return tuple(float(s) for s in v)


def table(v: Any) -> dict:
    if not isinstance(v, dict):
        raise TypeError("a table { key = value, ... }")
    return dict(v)


def table_or_string(v: Any) -> dict | str:
    if isinstance(v, str):
        return v
    return table(v)


def number_or_table(v: Any) -> float | dict[str, float]:
    """A number >= 0, or a table of them (one per response)."""
    if isinstance(v, dict):
        for x in v.values():
            number(positive=True)(x)
        return {k: float(x) for k, x in v.items()}
    return number(positive=True)(v)


def boolean(v: Any) -> bool:
    if not isinstance(v, bool):
        raise TypeError("true or false")
    return v


def close_hint(word: str, choices: Sequence[str], cutoff: float = 0.6) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``choices``, else ``""``."""
    close = difflib.get_close_matches(word, list(choices), n=1, cutoff=cutoff)
    return f" (did you mean {close[0]!r}?)" if close else ""
