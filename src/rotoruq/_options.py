"""Option records of the entry points, and the deprecation of their old flat keywords.

An entry point with many options groups them into small frozen records (``calibrate_bayes``:
``ChainOptions``, ``EmulatorOptions``, ``NoiseModel``; ``least_squares``: ``Convergence``;
``ExternalModel``: ``WorkDirectory``, ``FileContract``). The flat keyword arguments they replace
keep working for one release through :func:`legacy_keywords`, each with a
``DeprecationWarning`` naming its new place. This module sits at the bottom of the import
layers (it imports nothing of rotoruq but :mod:`rotoruq.errors`), so that every layer can use it.

Examples
--------
>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class Limits:
...     max_iterations: int = 100
>>> MAPPING = legacy_mapping("limits", Limits)
>>> flat = legacy_keywords("solve", {"max_iterations": 5}, MAPPING, warn=False)
>>> flat
{'limits': {'max_iterations': 5}}
>>> with_fields(None, Limits, flat.get("limits"), "limits")
Limits(max_iterations=5)
"""

from __future__ import annotations

import dataclasses
import difflib
import warnings
from collections.abc import Iterable, Mapping
from typing import Any, TypeVar

from .errors import ParameterError

__all__ = ["fields_of", "legacy_mapping", "legacy_keywords", "with_fields"]

R = TypeVar("R")


def fields_of(cls: type) -> tuple[str, ...]:
    """The field names of the dataclass ``cls``, in order."""
    return tuple(f.name for f in dataclasses.fields(cls))


def legacy_mapping(parameter: str, cls: type, fields: Iterable[str] | None = None,
                   renamed: Mapping[str, str] | None = None) -> dict[str, tuple[str, str, str]]:
    """``{old keyword: (parameter, record class name, field)}`` for the ``fields`` of ``cls``
    (default: all) passed as ``parameter=cls(...)``; ``renamed`` maps an old keyword to a field
    of another name."""
    out = {f: (parameter, cls.__name__, f) for f in (fields_of(cls) if fields is None
                                                     else fields)}
    out.update({old: (parameter, cls.__name__, new) for old, new in (renamed or {}).items()})
    return out


def legacy_keywords(function: str, legacy: Mapping[str, Any],
                    mapping: Mapping[str, tuple[str, str, str]], *, warn: bool = True,
                    stacklevel: int = 3) -> dict[str, dict[str, Any]]:
    """Sort the deprecated flat keyword arguments ``legacy`` of ``function`` into the fields of
    its option records: ``{parameter: {field: value}}``.

    Each known one gives a ``DeprecationWarning`` naming its new place (``warn``; ``stacklevel``
    3 points at the caller of the function that calls this); an unknown one raises
    ``TypeError`` as Python does, with the closest name.

    Examples
    --------
    >>> mapping = {"burn_in": ("chains", "ChainOptions", "burn_in")}
    >>> legacy_keywords("calibrate_bayes", {"burn_in": 0}, mapping, warn=False)
    {'chains': {'burn_in': 0}}
    """
    out: dict[str, dict[str, Any]] = {}
    for key, value in legacy.items():
        if key not in mapping:
            close = difflib.get_close_matches(key, list(mapping), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise TypeError(f"{function}() got an unexpected keyword argument {key!r}{hint}")
        param, record, field = mapping[key]
        if warn:
            warnings.warn(f"{function}({key}=...) is deprecated and will be removed in the next "
                          f"release: pass {param}={record}({field}=...)",
                          DeprecationWarning, stacklevel=stacklevel)
        out.setdefault(param, {})[field] = value
    return out


def with_fields(record: R | None, cls: type[R], fields: Mapping[str, Any] | None,
                what: str) -> R:
    """``record`` (an instance of ``cls`` or None: the defaults) with ``fields`` replaced;
    raises :class:`~rotoruq.errors.ParameterError` when ``record`` is something else."""
    if record is None:
        return cls(**(fields or {}))
    if not isinstance(record, cls):
        raise ParameterError(f"{what} must be a {cls.__name__} or None, got {record!r}")
    return dataclasses.replace(record, **fields) if fields else record  # type: ignore[type-var]
