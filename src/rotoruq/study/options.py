"""The study file's :class:`Checker`: turns a bad value into an
:class:`~rotoruq.errors.InputFileError` naming the file, the line and the expected form.

The option schemas themselves (:class:`~rotoruq.steps.options.Option` and the value checkers)
belong to the step types (:mod:`rotoruq.steps.options`); they are re-exported here for the
study-file parser.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NoReturn

from ..errors import InputFileError
from ..steps.options import (
    REQUIRED,
    SIGNATURE,
    Check,
    Option,
    boolean,
    choice,
    close_hint,
    integer,
    number,
    number_list,
    number_or_table,
    signature_default,
    string,
    string_list,
    table,
    table_or_string,
)
from .locator import Locator

__all__ = ["Option", "REQUIRED", "SIGNATURE", "Checker", "integer", "number", "choice",
           "string", "string_list", "number_list", "table", "table_or_string",
           "number_or_table", "boolean", "signature_default", "close_hint"]


class Checker:
    """Validates the tables of one study file; every failure names the file and line."""

    def __init__(self, path: Path, text: str):
        self.path = path
        self.loc = Locator(text)

    def fail(self, where: tuple, expected: str, found: str | None = None) -> NoReturn:
        raise InputFileError(self.path, self.loc.line(*where), expected, found)

    def keys(self, tbl: Mapping, allowed: Sequence[str], where: tuple, what: str) -> None:
        for key in tbl:
            if key not in allowed:
                self.fail(where + (key,), f"one of the keys of {what}: {', '.join(allowed)}"
                          f"{close_hint(key, allowed, 0.5)}", key)

    def table(self, value: Any, where: tuple, what: str) -> dict:
        if not isinstance(value, dict):
            self.fail(where, f"{what} to be a table", repr(value))
        return value

    def option(self, tbl: Mapping, key: str, spec: Option, where: tuple, what: str,
               default: Any = None) -> Any:
        """The checked value of ``tbl[key]``, else ``default`` (:data:`REQUIRED`: fail)."""
        if key not in tbl:
            if default is REQUIRED:
                self.fail(where, f"{what} to define {key!r}", None)
            return default
        try:
            return spec.check(tbl[key])
        except TypeError as exc:
            self.fail(where + (key,), f"{key!r} of {what} to be {exc}", repr(tbl[key]))

    def value(self, tbl: Mapping, key: str, spec: tuple[Check, Any], where: tuple,
              what: str) -> Any:
        """:meth:`option` for a key with a fixed default: ``spec = (check, default)``."""
        check, default = spec
        return self.option(tbl, key, Option(check, default), where, what, default)

    def numbers(self, tbl: Mapping, where: tuple, what: str) -> dict[str, float]:
        """Every value of ``tbl`` as a float (bools and strings rejected)."""
        out = {}
        for k, v in tbl.items():
            if isinstance(v, bool) or not isinstance(v, int | float):
                self.fail(where + (k,), f"a number for {k!r} in {what}", repr(v))
            out[k] = float(v)
        return out
