"""What an evaluation's answer depends on, as one digest.

An evaluation is reused from the store (and a study step from its saved results) only when
everything that can change its answer is the same: the model's class, its full configuration
(``model.identity()``: preset contents, airfoil table, fixed inputs, solver options, or for an
external model its command, templates and files by content) and the code that computes it
(:func:`code_version`: rotoruq's version plus a digest of its source and data files).

>>> from rotoruq.evaluation.identity import model_identity
>>> model_identity(model)                                    # doctest: +SKIP
'rotoruq.rotor.model.RotorModel|collective_deg->thrust|3f9a0c...'

The digest is computed once per model object (hashing costs a few milliseconds for a rotor
preset); per evaluation, the store key is only the bytes of the input vector.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["code_version", "digest", "file_sha256", "model_identity"]

_PACKAGE = Path(__file__).resolve().parent.parent
# Folders whose code cannot change a model's answer or a step's numbers.
_NOT_ANSWER = ("report",)


@lru_cache(maxsize=1)
def code_version() -> str:
    """rotoruq's version and a digest of the package's source and data files.

    Any edit to the code that computes answers (a fix in the rotor solver, a method, the study
    steps) changes it, so results computed by other code are never served. The report package
    is left out: it only presents numbers.
    """
    from .. import __version__

    h = hashlib.sha256()
    for p in sorted(_PACKAGE.rglob("*")):
        rel = p.relative_to(_PACKAGE)
        if (not p.is_file() or rel.parts[0] in _NOT_ANSWER or "__pycache__" in rel.parts
                or p.suffix in (".pyc", ".pyo")):
            continue
        h.update(rel.as_posix().encode())
        h.update(b"\0")
        h.update(p.read_bytes())
        h.update(b"\0")
    return f"{__version__}+{h.hexdigest()[:16]}"


def file_sha256(path: str | Path) -> str:
    """sha256 hex digest of a file's bytes, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(1 << 20):
            h.update(block)
    return h.hexdigest()


def _plain(o):
    """JSON-able form of configuration values (arrays by their bytes' digest)."""
    if isinstance(o, Mapping):
        return {str(k): _plain(v) for k, v in sorted(o.items(), key=lambda kv: str(kv[0]))}
    if isinstance(o, (list, tuple)):
        return [_plain(v) for v in o]
    if isinstance(o, np.ndarray):
        a = np.ascontiguousarray(o)
        return {"array": list(a.shape), "dtype": str(a.dtype),
                "sha256": hashlib.sha256(a.tobytes()).hexdigest()}
    if isinstance(o, (np.floating, float)):
        o = float(o)
        return o if math.isfinite(o) else repr(o)
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.bool_,)):
        return bool(o)
    if isinstance(o, Path):
        return str(o)
    if o is None or isinstance(o, (str, int, bool)):
        return o
    ident = getattr(o, "identity", None)
    if callable(ident):
        return {"class": _qualname(o), "identity": _plain(ident())}
    return repr(o)


def digest(obj: Any) -> str:
    """sha256 hex digest of a configuration (nested mappings, sequences, numbers, arrays)."""
    text = json.dumps(_plain(obj), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def _qualname(o) -> str:
    t = type(o)
    return f"{t.__module__}.{t.__qualname__}"


def model_identity(model: Any) -> str:
    """Text that tells models apart in the store and in step fingerprints.

    ``class|inputs->responses|digest``, where the digest covers the class, the model's
    ``identity()`` (its full configuration) and :func:`code_version`. A model without an
    ``identity()`` method is identified by its class and ``repr`` only: give your own models
    one if their configuration can change between runs. An Evaluator is identified by the model
    it wraps.
    """
    inner = getattr(model, "model_id", None)
    if isinstance(inner, str) and hasattr(model, "store"):
        return inner
    ident = getattr(model, "identity", None)
    if callable(ident):
        config = ident()
    elif isinstance(ident, str):
        config = ident
    else:
        config = repr(model)
    doc = {"class": _qualname(model), "config": config, "code": code_version(),
           "in": list(model.names_in), "out": list(model.names_out)}
    return (f"{_qualname(model)}|{','.join(model.names_in)}->{','.join(model.names_out)}"
            f"|{digest(doc)[:24]}")
