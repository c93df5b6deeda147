"""The saved form of a step's outcome, shared by the runner (writes) and the report (reads).

A step saves its numbers once, as a typed record (:class:`StepRecord`: named arrays with
their axis names, names, plain numbers). A :class:`StepResult` holds that record's arrays and
description, the other arrays of the step (samples, chains), the distributions it hands to
later steps (posterior / calibrated) and JSON metadata. Its flat view
(:attr:`StepResult.scalars`: ``"mean/thrust"``, ``"S/thrust/cla_m03"``, ``"nstd/power@2"``)
is derived from the record's own axis names (:func:`flat_view`), never written by hand. On
disk::

    <out>/steps/<name>/result.json     name, type, fingerprint, record, distributions, meta
    <out>/steps/<name>/<array>.npy     every array, plus <array>.csv when it has named columns
                                       (a Markov chain's CSV, ``chain.csv``, starts with a
                                       ``chain`` column: 0, 1, ... per row)
    <out>/study.json                   the study: name, description, seed, quick, step order,
                                       parameters (labels, units) and the model's record
                                       (``model.values``, ``model.curves``; see
                                       :func:`rotoruq.study.runner.model_record`)

``rotoruq show --csv`` writes the flat view. Folders saved by earlier versions (schema 1,
flat scalars in ``result.json`` and ``scalars.csv``) still load; their scalars are read as
saved.

Saves are atomic (see :func:`save_step`) and loads check every file against the sha256 that
``result.json`` records, and ``result.json`` itself against its ``checksum`` (the sha256 of its
canonical form, which holds those of the other files): a half-saved or hand-edited step is never
trusted, the runner computes it again. A results folder may come from
someone else: every file is read without following a symlink, arrays never unpickle
(``allow_pickle=False``), and a file rotoruq did not write (tampered, foreign, pointing
outside its step folder) raises :class:`ForeignStepFileError` naming it.
"""

from __future__ import annotations

import difflib
import hashlib
import io
import json
import math
import os
import shutil
import time
import uuid
from collections.abc import Mapping, Sequence
from dataclasses import MISSING, dataclass, field, fields
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Self

import numpy as np

from .atomic import fsync_dir, make_temp_dir, write_text
from .errors import RotoruqError
from .params import Distribution, make_distribution
from .safety import (
    ForeignFileError,
    UnsafePathError,
    check_name,
    name_problem,
    no_symlink,
    open_nofollow,
    read_nofollow,
    real_dir,
)

__all__ = ["StepResult", "save_step", "load_step", "load_results", "dist_to_dict",
           "dict_to_dist", "IncompleteStepError", "clean_partial_saves", "STUDY_INFO",
           "save_study_info", "load_study_info", "is_study_dir", "SCHEMA_VERSION",
           "StepRecord", "RecordError", "ForeignStepFileError", "DamagedStep",
           "set_aside_damaged_steps", "study_infos"]

#: Version of the saved step format. 1: ``result.json`` records it, and a step may carry a
#: typed record (:class:`StepRecord`, ``meta["record"]``). 2: the record is the saved form;
#: ``result.json`` keeps as ``scalars`` only numbers outside it, the flat view is derived
#: (:func:`flat_view`) and ``scalars.csv`` is no longer written. A folder saved by a newer
#: format is refused with the version it needs; older ones load.
SCHEMA_VERSION = 2

#: The file of a study output folder that describes the study (see the module docstring).
STUDY_INFO = "study.json"


@dataclass(frozen=True, eq=False)
class StepResult:
    """Outcome of one study step.

    Attributes
    ----------
    name : str
        The step's name (its ``[steps.<name>]`` table and its folder ``steps/<name>``).
    type : str
        The step's type (``"sampling"``, ``"sobol"``, ...; see :mod:`rotoruq.steps`).
    scalars : mapping of str to float
        Flat mapping key -> value: the view of the step's record derived by
        :func:`flat_view`, with the keys given to the constructor kept beside it (numbers
        outside any record, or the scalars of a folder saved before records). Key forms:
        ``stat/name`` (e.g. ``mean/thrust``), ``index/response/input``
        (``S/thrust/cla_m03``) and ``...@label`` for a sweep point. Values are in the units
        of the response or input they describe (indices are dimensionless).
    arrays : mapping of str to ndarray
        Named arrays, e.g. ``inputs`` of shape (n, d), ``outputs`` of shape (n, m),
        ``chain`` of shape (N, d); the record's array fields among them.
    distributions : mapping of str to dict
        Parameter name -> distribution description (``{"kind": "normal", "mu": ...,
        "sigma": ...}``, see :func:`dist_to_dict`) offered to later steps as
        ``posterior``/``calibrated``.
    meta : mapping of str to object
        JSON-serialisable details: ``columns`` (array name -> column names), names, number of
        evaluations, wall time (s), failures, notes, and the record (``"record"``).
    fingerprint : str
        Digest of what the step's numbers depend on (its spec, model, distributions, data,
        seed and code), set by the study runner to tell whether a saved step can be reused;
        ``""`` for a result built by hand.
    """

    name: str
    type: str
    scalars: Mapping[str, float] = field(default_factory=dict)
    arrays: Mapping[str, np.ndarray] = field(default_factory=dict)
    distributions: Mapping[str, dict] = field(default_factory=dict)
    meta: Mapping[str, Any] = field(default_factory=dict)
    fingerprint: str = ""

    def __post_init__(self) -> None:
        derived = self._flat
        if derived:
            object.__setattr__(self, "scalars", {**derived, **self.scalars})

    @cached_property
    def _flat(self) -> dict[str, float]:
        # the flat view of the record, derived once: the constructor merges it into
        # ``scalars`` and saving leaves it out again (``own_scalars``)
        return flat_view(self.meta, self.arrays)

    def own_scalars(self) -> dict[str, float]:
        """The scalars that the flat view of the record does not give (what ``result.json``
        keeps as ``scalars``)."""
        derived = self._flat
        return {k: v for k, v in self.scalars.items()
                if k not in derived or not _same(derived[k], v)}

    def get(self, key: str, default: float | None = None) -> float:
        """Scalar ``key``. A key the step did not save raises ``KeyError`` naming the closest
        saved keys (a typo such as ``"men/y1"`` must not read as NaN), unless ``default`` is
        given.

        Parameters
        ----------
        key : str
            A key of :attr:`scalars` (``"mean/thrust"``, ``"S/thrust/cla_m03"``, ...).
        default : float, optional
            Returned when the step saved no scalar ``key``; None (the default) raises.

        Returns
        -------
        float
            The scalar, in the units of the quantity it describes.

        Raises
        ------
        KeyError
            No scalar ``key`` and no ``default``.

        Examples
        --------
        >>> res = StepResult("s", "sampling", {"mean/y1": 2.0, "std/y1": 0.5})
        >>> res.get("mean/y1"), res.get("skewness/y1", float("nan"))
        (2.0, nan)
        >>> res.get("men/y1")
        Traceback (most recent call last):
        ...
        KeyError: "step 's' saved no scalar 'men/y1' (did you mean 'mean/y1'?)"
        """
        if key in self.scalars:
            return float(self.scalars[key])
        if default is not None:
            return float(default)
        close = difflib.get_close_matches(key, list(self.scalars), n=3)
        hint = f" (did you mean {', '.join(repr(c) for c in close)}?)" if close else ""
        raise KeyError(f"step {self.name!r} saved no scalar {key!r}{hint}")

    def columns(self, array: str) -> list[str]:
        """Names of the columns of a 2-D array (``meta["columns"]``).

        Parameters
        ----------
        array : str
            Name of an array of :attr:`arrays` (``"inputs"``, ``"outputs"``, ...).

        Returns
        -------
        list of str
            Its column names, in order; empty when the step saved none for it.
        """
        return list(self.meta.get("columns", {}).get(array, []))

    def column(self, array: str, name: str) -> np.ndarray:
        """One named column of a 2-D array.

        Parameters
        ----------
        array : str
            Name of a 2-D array of :attr:`arrays` with named columns (see :meth:`columns`).
        name : str
            The column's name (an input or response name).

        Returns
        -------
        ndarray of shape (n,)
            The column, in the units of that input or response.

        Raises
        ------
        ValueError
            The array has no column ``name`` (or the step saved no named columns for it).
        """
        cols = self.columns(array)
        return np.asarray(self.arrays[array])[:, cols.index(name)]

    def distribution_objects(self) -> dict[str, Distribution]:
        """The distributions the step hands to later steps, by parameter name."""
        return {k: dict_to_dist(v) for k, v in self.distributions.items()}

    def input_distributions(self) -> dict[str, Distribution]:
        """The distributions of the step's inputs as the runner recorded them, by name
        (empty for a step saved without them)."""
        return {k: dict_to_dist(v)
                for k, v in (self.meta.get("input_distributions") or {}).items()}


def _same(a: float, b: float) -> bool:
    a, b = float(a), float(b)
    return a == b or (math.isnan(a) and math.isnan(b))


def _part(label: str) -> str:
    # a sweep point (``@2``) or a grid (``#0``) joins its key without a slash, as in
    # ``nstd/power@2``; so does an empty label (a step without a sweep): ``nstd/power``
    return label if label[:1] in "@#" else "/" + label


def _suffix(part: str) -> bool:
    return part.startswith(("@", "#"))


def flat_view(meta: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> dict[str, float]:
    """The flat scalars of a step, derived from its saved record and its inputs.

    Each array field of the record (``meta["record"]``) gives one key per element: the
    field's flat name (:attr:`StepRecord.FLAT`, else the field name; ``""``: the labels
    alone) followed by the label of the element on each axis (:attr:`StepRecord.LABELS`:
    the names field of that axis, or the labels themselves; the index when the axis has
    none). A label starting with ``@`` (a sweep point) or ``#`` (a grid) ends the key,
    joined without a slash, whatever the place of its axis (``nstd/power@2`` of an array
    over (point, response)); an empty label adds nothing. A NaN element (not computed) has
    no key. Plain numbers of the record give one
    key each. The input distributions the runner records
    (``meta["input_distributions"]``) give ``input_mean/``, ``input_std/`` and, when both
    bounds are finite, ``input_lower/`` and ``input_upper/`` of each input.

    Parameters
    ----------
    meta : mapping
        A step's ``meta`` (its ``"record"`` entry as written by :meth:`StepRecord.parts`).
    arrays : mapping of str to ndarray
        The step's arrays (the record's array fields among them).

    Returns
    -------
    dict of str to float
        Key -> value; empty when the step has neither a record nor input distributions.

    Examples
    --------
    >>> import numpy as np
    >>> meta = {"record": {"type": "R", "version": 1, "fields": {"names_out": ["T", "P"],
    ...         "names_in": ["a"], "confidence": 0.9},
    ...         "axes": {"S": ["response", "input"]}, "labels": {}, "flat": {}}}
    >>> flat_view(meta, {"S": np.array([[0.25], [0.5]])})
    {'S/T/a': 0.25, 'S/P/a': 0.5, 'confidence': 0.9}
    >>> meta = {"record": {"type": "R", "version": 1, "fields": {"names_out": ["T"],
    ...         "labels": ["@4", "@2"]}, "axes": {"nstd": ["point", "response"]},
    ...         "labels": {"point": "labels"}, "flat": {}}}
    >>> flat_view(meta, {"nstd": np.array([[0.5], [np.nan]])})
    {'nstd/T@4': 0.5}
    """
    out: dict[str, float] = {}
    rec = meta.get("record")
    if isinstance(rec, Mapping) and isinstance(rec.get("fields"), Mapping):
        plain = rec["fields"]
        labels = {**_DEFAULT_LABELS, **(rec.get("labels") or {})}
        flat = rec.get("flat") or {}
        for name, axes in (rec.get("axes") or {}).items():
            key = flat.get(name, name)
            if key is None or name not in arrays:
                continue
            arr = np.asarray(arrays[name])
            if arr.dtype.kind not in "biuf" or arr.ndim != len(axes):
                continue
            names = []
            for axis, n in zip(axes, arr.shape, strict=True):
                lab = labels.get(axis)
                lab = plain.get(lab) if isinstance(lab, str) else lab
                if isinstance(lab, list | tuple) and lab:
                    if len(lab) != n:
                        break  # labels that do not fit (a record not written by rotoruq)
                    names.append([_part(str(x)) for x in lab])
                else:
                    names.append([f"/{j}" for j in range(n)])
            if len(names) != arr.ndim:
                continue
            for idx in np.ndindex(arr.shape):
                v = float(arr[idx])
                if not math.isnan(v):  # not computed (a level past its count, no emulator)
                    # the sweep point or grid ends the key whatever the place of its axis
                    k = key + "".join(sorted((names[a][i] for a, i in enumerate(idx)),
                                             key=_suffix))
                    out[k if key else k.lstrip("/")] = v
        for name, v in plain.items():
            key = flat.get(name, name)
            if key and isinstance(v, int | float) and not math.isnan(v):  # a bool: 0 or 1
                out[key] = float(v)
    dists = meta.get("input_distributions")
    if isinstance(dists, Mapping):
        for p, d in dists.items():
            try:
                dist = dict_to_dist(d)
            except Exception:  # noqa: BLE001 - a description this version cannot rebuild
                continue
            out[f"input_mean/{p}"], out[f"input_std/{p}"] = float(dist.mean), float(dist.std)
            lo, hi = dist.bounds
            if np.isfinite(lo) and np.isfinite(hi):
                out[f"input_lower/{p}"], out[f"input_upper/{p}"] = float(lo), float(hi)
    return out


#: The axis names every record labels the same way (a record's :attr:`StepRecord.LABELS`
#: adds to them): inputs and parameters by ``names_in``, responses by ``names_out``.
_DEFAULT_LABELS: dict[str, Any] = {"input": "names_in", "parameter": "names_in",
                                   "response": "names_out", "bound": ["lo", "hi"]}


class RecordError(RotoruqError, LookupError):
    """A saved step carries no record of the type asked for, or one of a newer version."""


@dataclass(frozen=True, eq=False)
class StepRecord:
    """Base of the typed records of step types: the step's numbers as named fields with
    their shapes and axis names, saved through one generic serializer.

    A subclass declares its fields: arrays (``np.ndarray``, each with its axis names in
    :attr:`AXES`), names (``tuple[str, ...]``) and plain numbers or text. :meth:`parts` gives
    the arrays and the ``meta["record"]`` entry of a :class:`StepResult`; :meth:`read` builds
    the record back from a saved result; :func:`flat_view` derives the result's flat scalars
    from the saved record (``rotoruq show --csv``, the reference tables). Reading an unknown
    attribute raises with the closest field names.

    Examples
    --------
    >>> import numpy as np
    >>> from dataclasses import dataclass
    >>> @dataclass(frozen=True, eq=False)
    ... class MomentsRecord(StepRecord):
    ...     AXES = {"mean": ("response",)}
    ...     names_out: tuple[str, ...]
    ...     mean: np.ndarray
    >>> rec = MomentsRecord(("thrust",), np.array([1.5]))
    >>> arrays, meta = rec.parts()
    >>> back = MomentsRecord.read(StepResult("m", "moments", arrays=arrays, meta=meta))
    >>> back.names_out, back.mean.tolist(), back.index("response", "thrust")
    (('thrust',), [1.5], 0)
    >>> back.maen
    Traceback (most recent call last):
    ...
    AttributeError: MomentsRecord has no field 'maen' (did you mean 'mean'?)
    """

    #: field -> axis names of an array field (its dimensions, in order).
    AXES: ClassVar[Mapping[str, tuple[str, ...]]] = {}
    #: axis -> the field that names its elements, or the names themselves (added to
    #: ``input``/``parameter`` -> ``names_in``, ``response`` -> ``names_out``, ``bound`` ->
    #: ``lo``, ``hi``); the keys of the flat view (:func:`flat_view`).
    LABELS: ClassVar[Mapping[str, str | tuple[str, ...]]] = {}
    #: field -> its name in the flat view when not its own (None: left out of the view).
    FLAT: ClassVar[Mapping[str, str | None]] = {}
    #: Version of this record type; :meth:`read` refuses newer saved ones.
    VERSION: ClassVar[int] = 1

    if not TYPE_CHECKING:  # mypy sees the declared fields only, and flags a typo itself
        def __getattr__(self, name: str) -> Any:
            if name.startswith("__"):
                raise AttributeError(name)
            known = [f.name for f in fields(self)]
            close = difflib.get_close_matches(name, known, n=1)
            hint = (f" (did you mean {close[0]!r}?)" if close
                    else f" (fields: {', '.join(known)})")
            raise AttributeError(f"{type(self).__name__} has no field {name!r}{hint}")

    def parts(self) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """``(arrays, meta)`` to put into a :class:`StepResult`."""
        arrays: dict[str, np.ndarray] = {}
        plain: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in self.AXES:
                v = np.asarray(v)
                if v.size == 0 and v.ndim != len(self.AXES[f.name]):
                    v = v.reshape((0,) * len(self.AXES[f.name]))  # none, whatever its shape
                if v.ndim != len(self.AXES[f.name]):
                    raise ValueError(f"{type(self).__name__}.{f.name}: expected "
                                     f"{len(self.AXES[f.name])} axes "
                                     f"({', '.join(self.AXES[f.name])}), found shape {v.shape}")
                arrays[f.name] = v
            else:
                plain[f.name] = list(v) if isinstance(v, tuple) else v
        labels = {**_DEFAULT_LABELS, **self.LABELS}
        for name, arr in arrays.items():
            if arr.size == 0:  # none (a level mapping not asked for): nothing to label
                continue
            for axis, n in zip(self.AXES[name], arr.shape, strict=True):
                lab = labels.get(axis)
                lab = plain.get(lab) if isinstance(lab, str) else lab
                # no names recorded (a field added since, left empty): the view uses indices
                if isinstance(lab, list | tuple) and lab and len(lab) != n:
                    raise ValueError(f"{type(self).__name__}.{name}: its {axis} axis has {n} "
                                     f"elements but {len(lab)} labels ({labels[axis]!r}); "
                                     "give the axis its own name (LABELS)")
        return arrays, {"record": {
            "type": type(self).__name__, "version": self.VERSION, "fields": plain,
            "axes": {k: list(a) for k, a in self.AXES.items()},
            "labels": {k: (v if isinstance(v, str) else list(v))
                       for k, v in self.LABELS.items()},
            "flat": dict(self.FLAT)}}

    def index(self, axis: str, label: str) -> int:
        """Position of ``label`` on ``axis`` (see :attr:`LABELS`; an example in the class's
        docstring); a label the record does not hold raises ``KeyError`` naming those it
        does.

        Parameters
        ----------
        axis : str
            An axis name of :attr:`AXES` (``"response"``, ``"input"``, ``"point"``, ...).
        label : str
            The name of one element on that axis (a response name, an input name, ...).

        Returns
        -------
        int
            Its index along that axis of the record's arrays.
        """
        lab = {**_DEFAULT_LABELS, **self.LABELS}.get(axis)
        names = list(getattr(self, lab) if isinstance(lab, str) else lab or ())
        if label not in names:
            raise KeyError(f"{type(self).__name__}: no {axis} {label!r} (it has "
                           f"{', '.join(map(str, names)) or 'none'})")
        return names.index(label)

    @classmethod
    def read(cls, res: StepResult) -> Self:
        """The record saved with ``res``; :class:`RecordError` when it has none (a result
        of an older rotoruq) or one of a newer version.

        Parameters
        ----------
        res : StepResult
            A step's result, saved with a record of this class (``meta["record"]`` and the
            record's arrays, as :meth:`parts` gives them).

        Returns
        -------
        StepRecord
            The record of this class rebuilt from ``res``; a field added to the class since
            it was saved takes its default.
        """
        rec = res.meta.get("record")
        if not isinstance(rec, Mapping) or rec.get("type") != cls.__name__:
            raise RecordError(f"step {res.name!r} ({res.type}) was saved without a "
                              f"{cls.__name__} (by a rotoruq older than results schema "
                              f"{SCHEMA_VERSION}): run the step again")
        if not isinstance(rec.get("version", 0), int):
            raise RecordError(f"not written by rotoruq: step {res.name!r} (its {cls.__name__} "
                              "version is not a number); remove it or re-run the step")
        if int(rec.get("version", 0)) > cls.VERSION:
            raise RecordError(f"step {res.name!r}: {cls.__name__} version {rec['version']} "
                              f"needs a newer rotoruq (this one reads up to {cls.VERSION})")
        saved = rec.get("fields")

        def foreign(why: str) -> RecordError:
            return RecordError(f"not written by rotoruq: step {res.name!r} ({why}); remove it "
                               "or re-run the step")

        if not isinstance(saved, Mapping):
            raise foreign(f"its {cls.__name__} has no fields")
        kwargs: dict[str, Any] = {}
        for f in fields(cls):
            if (f.default is not MISSING or f.default_factory is not MISSING) and (
                    f.name not in (res.arrays if f.name in cls.AXES else saved)):
                continue  # a field added since (with its default): a record saved before it
            if f.name in cls.AXES:
                if f.name not in res.arrays:
                    raise foreign(f"its {cls.__name__} lacks the array {f.name!r}")
                arr = np.asarray(res.arrays[f.name])
                if arr.ndim != len(cls.AXES[f.name]):
                    raise foreign(f"{cls.__name__}.{f.name} has {arr.ndim} axes, not "
                                  f"{len(cls.AXES[f.name])}")
                kwargs[f.name] = arr
            else:
                if f.name not in saved:
                    raise foreign(f"its {cls.__name__} lacks the field {f.name!r}")
                v = saved[f.name]
                kwargs[f.name] = tuple(v) if isinstance(v, list) else v
        return cls(**kwargs)


def dist_to_dict(dist: Distribution) -> dict:
    d = dist.describe()
    return {k: (float(v) if isinstance(v, int | float) else v) for k, v in d.items()}


def dict_to_dist(d: Mapping) -> Distribution:
    params = {k: v for k, v in d.items() if k != "kind"}
    return make_distribution(d["kind"], **params)


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return _jsonable(obj.item())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None if math.isnan(obj) else ("inf" if obj > 0 else "-inf")
    if isinstance(obj, Path):
        return str(obj)
    return obj


def _unjson_scalar(v) -> float:
    if v is None:
        return math.nan
    if v == "inf":
        return math.inf
    if v == "-inf":
        return -math.inf
    return float(v)


class IncompleteStepError(RotoruqError):
    """A saved step is missing files or they do not match what its ``result.json`` records
    (a save interrupted before the atomic rename, or files changed by hand)."""


class ForeignStepFileError(ForeignFileError, IncompleteStepError):
    """A file of a saved step that rotoruq did not write: a pickled or malformed ``.npy``,
    a ``result.json`` of the wrong shape or listing files outside its folder. The runner
    treats it as an incomplete step (it runs the step again); ``show`` and ``report`` stop
    with one line naming the file."""


def save_step(result: StepResult, directory: str | Path) -> Path:
    """Write ``result`` under ``directory/steps/<name>/``; returns that folder.

    The step is written whole into a temporary folder (every file flushed to disk, then
    ``result.json`` with the sha256 of every other file and its own ``checksum``, see
    :func:`load_step`), which then replaces the old folder
    by rename. A reader finds the old step, the new step or none: never a mix. Folders and
    files get the user's umask; ``steps/`` and the old step folder must be real folders
    (:class:`~rotoruq.safety.UnsafePathError` naming a symlink).
    """
    check_name(result.name, what="a step name")
    for name in result.arrays:
        check_name(name, what=f"an array name of step {result.name!r}")
    Path(directory).mkdir(parents=True, exist_ok=True)
    steps = real_dir(Path(directory) / "steps", create=True)
    folder = steps / result.name
    if folder.is_symlink() or folder.exists():
        real_dir(folder)
    tmp = make_temp_dir(steps, f".tmp-{result.name}.")
    try:
        files: dict[str, str] = {}

        def put(name: str, write) -> None:
            files[name] = _write_synced(tmp / name, write)

        for name, arr in result.arrays.items():
            arr = np.asarray(arr)
            put(f"{name}.npy", lambda fh, arr=arr: np.save(fh, arr))
            cols = result.columns(name)
            if arr.ndim == 2 and len(cols) == arr.shape[1]:
                chain = _chain_index(result, name, arr.shape[0])
                put(f"{name}.csv", lambda fh, arr=arr, cols=cols, chain=chain:
                    _write_csv(fh, arr, cols, chain=chain))
        doc = {
            "schema": SCHEMA_VERSION,
            "name": result.name,
            "type": result.type,
            "fingerprint": result.fingerprint,
            "scalars": _jsonable(result.own_scalars()),
            "distributions": _jsonable(dict(result.distributions)),
            "meta": _jsonable(dict(result.meta)),
            "arrays": sorted(result.arrays),
            "files": files,
        }
        # the checksum covers the document as a reader parses it back
        doc["checksum"] = _checksum(json.loads(json.dumps(doc)))
        _write_synced(tmp / "result.json",
                      lambda fh: fh.write(json.dumps(doc, indent=1).encode("utf-8")))
        fsync_dir(tmp)
        old = None
        if folder.exists():
            old = steps / f".old-{result.name}.{uuid.uuid4().hex[:8]}"
            os.replace(folder, old)
        os.replace(tmp, folder)
        fsync_dir(steps)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return folder


def _checksum(doc: Mapping[str, Any]) -> str:
    """sha256 of a ``result.json`` document without its ``checksum``, in a canonical form
    (sorted keys, no spaces, ASCII): a change of layout keeps it, a change of any value
    (a number, a type, a file's sha256) does not."""
    body = {k: v for k, v in doc.items() if k != "checksum"}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(text.encode("ascii")).hexdigest()


class _Hashing(io.RawIOBase):
    """A binary file that also feeds what is written to a sha256."""

    def __init__(self, fh) -> None:
        self.fh, self.sha = fh, hashlib.sha256()

    def writable(self) -> bool:
        return True

    def write(self, b) -> int:
        self.sha.update(b)
        return self.fh.write(b)


def _write_synced(path: Path, write) -> str:
    """Write a new file of a step's temporary folder (never through a link: ``O_EXCL``),
    flush it to disk, and return its sha256. No rename of its own: the folder is renamed
    whole once every file is synced (and the folder itself)."""
    fd = open_nofollow(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    with os.fdopen(fd, "wb") as fh:
        out = _Hashing(fh)
        write(out)
        fh.flush()
        os.fsync(fh.fileno())
    return out.sha.hexdigest()


def _chain_index(result: StepResult, name: str, n_rows: int) -> np.ndarray | None:
    """The chain (0, 1, ...) of each row of a Markov chain array saved chain after chain
    (``chain`` or ``<x>_chain`` of a step whose ``meta["n_chains"]`` divides its rows), for
    the ``chain`` column of its CSV copy; None for any other array."""
    n_chains = result.meta.get("n_chains")
    if not (name == "chain" or name.endswith("_chain")) or not isinstance(n_chains, int) \
            or n_chains < 1 or n_rows % n_chains:
        return None
    return np.repeat(np.arange(n_chains), n_rows // n_chains)


def _write_csv(fh, arr: np.ndarray, cols: Sequence[str], rows_per_block: int = 8192,
               chain: np.ndarray | None = None) -> None:
    """A 2-D array as CSV under a header of column names, each value in its shortest form
    that reads back to the same float (``repr``), after a first ``chain`` column of integers
    when ``chain`` (one per row) is given. One format operation per block of rows:
    ``np.savetxt`` formats row by row, which took seconds for the 100k-row chains."""
    fh.write((",".join((["chain"] if chain is not None else []) + list(cols)) + "\n").encode())
    if arr.dtype.kind not in "biuf":
        np.savetxt(fh, arr if chain is None else np.column_stack([chain, arr]), delimiter=",",
                   fmt="%s")
        return
    arr = arr.astype(float, copy=False)
    row = ("%d," if chain is not None else "") + ",".join(["%r"] * arr.shape[1]) + "\n"
    for start in range(0, arr.shape[0], rows_per_block):
        block = arr[start:start + rows_per_block]
        if chain is not None:
            block = np.column_stack([chain[start:start + rows_per_block], block]).astype(object)
            block[:, 0] = block[:, 0].astype(int)
        fh.write((row * block.shape[0] % tuple(block.ravel().tolist())).encode())


def clean_partial_saves(directory: str | Path) -> list[Path]:
    """Remove temporary folders left by saves that were interrupted; returns what was removed.
    Call it only while holding the results folder's lock."""
    steps = Path(directory) / "steps"
    removed: list[Path] = []
    if not steps.is_dir() or steps.is_symlink():
        return removed
    for p in sorted(steps.glob(".tmp-*")) + sorted(steps.glob(".old-*")):
        shutil.rmtree(p, ignore_errors=True)
        removed.append(p)
    return removed


@dataclass(frozen=True, eq=False)
class DamagedStep:
    """A saved step that did not load, moved aside by :func:`set_aside_damaged_steps`.

    name : the step's name.
    problem : why it did not load (the message of its :class:`IncompleteStepError`).
    moved_to : where its folder is now (``steps/.damaged-<name>.<UTC time>``).
    """

    name: str
    problem: str
    moved_to: Path


def set_aside_damaged_steps(directory: str | Path) -> list[DamagedStep]:
    """Move every saved step of ``directory`` that :func:`load_step` does not accept (missing
    or changed files, a changed ``result.json``, a file rotoruq did not write) to
    ``steps/.damaged-<name>.<UTC time>``: never deleted, no longer read (readers skip folders
    whose name starts with a dot), computed again by the next run. Intact steps stay. Call it
    only while holding the results folder's lock.

    Returns
    -------
    list of DamagedStep
        The steps moved aside, by name.

    Examples
    --------
    >>> import tempfile
    >>> out = Path(tempfile.mkdtemp())
    >>> step = save_step(StepResult("lhs", "sampling", {"mean/y1": 2.0}), out)
    >>> set_aside_damaged_steps(out)
    []
    >>> _ = (step / "result.json").write_text("{}")
    >>> [(d.name, d.moved_to.name.startswith(".damaged-lhs.")) for d in
    ...  set_aside_damaged_steps(out)]
    [('lhs', True)]
    >>> load_results(out)
    {}
    """
    steps = Path(directory) / "steps"
    if not (steps.is_symlink() or steps.exists()):
        return []
    moved: list[DamagedStep] = []
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    for p in sorted(real_dir(steps).iterdir()):
        if (p.name.startswith(".") or p.is_symlink() or not p.is_dir()
                or not os.path.lexists(p / "result.json")):
            continue
        try:
            load_step(p)
            continue
        except (IncompleteStepError, UnsafePathError) as exc:
            problem = str(exc)
        aside = steps / f".damaged-{p.name}.{stamp}"
        k = 1
        while os.path.lexists(aside):
            k += 1
            aside = steps / f".damaged-{p.name}.{stamp}-{k}"
        os.replace(p, aside)
        moved.append(DamagedStep(p.name, problem, aside))
    if moved:
        fsync_dir(steps)
    return moved


# the entries of a step's meta that the runner writes and the report and `show` read
_META_KINDS: dict[str, type | tuple[type, ...]] = {
    "columns": dict, "seconds": (int, float), "n_evaluations": int, "title": str,
    "parameters": list, "responses": list, "fixed": dict, "options": dict, "source": str,
    "record": dict, "identity": dict, "input_distributions": dict,
}


def load_step(folder: str | Path) -> StepResult:
    """Read a saved step; raises :class:`IncompleteStepError` when it is not whole or changed
    since it was saved (a file against the sha256 ``result.json`` records, ``result.json``
    against its own ``checksum``; a step saved without them counts as not whole),
    :class:`ForeignStepFileError` naming a file rotoruq did not write, and
    :class:`~rotoruq.safety.UnsafePathError` naming a symlink.

    Examples
    --------
    >>> import json, tempfile
    >>> out = Path(tempfile.mkdtemp())
    >>> step = save_step(StepResult("lhs", "sampling", {"mean/y1": 2.0}), out)
    >>> load_step(step).get("mean/y1")
    2.0
    >>> doc = json.loads((step / "result.json").read_text())
    >>> doc["scalars"]["mean/y1"] = 3.0
    >>> _ = (step / "result.json").write_text(json.dumps(doc))
    >>> load_step(step)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    rotoruq.results.IncompleteStepError: .../lhs/result.json: changed since the step was saved...
    """
    folder = Path(folder)
    where = folder / "result.json"
    try:
        raw = read_nofollow(where)
    except FileNotFoundError:
        raise IncompleteStepError(f"{where}: missing") from None
    try:
        doc = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise IncompleteStepError(f"{where}: not a complete JSON document ({exc})") from None
    if not isinstance(doc, dict) or not {"name", "type", "scalars"} <= set(doc):
        raise IncompleteStepError(f"{where}: expected a step result with name, type, scalars")
    shapes = {"name": str, "type": str, "scalars": dict, "files": dict, "arrays": list,
              "meta": dict, "distributions": dict, "fingerprint": str, "schema": int,
              "checksum": str}
    for key, kind in shapes.items():
        if key in doc and doc[key] is not None and not isinstance(doc[key], kind):
            raise ForeignStepFileError(where, f"{key!r} is a {type(doc[key]).__name__}, "
                                       f"not a {kind.__name__}")
    for key, kinds in _META_KINDS.items():
        v = (doc.get("meta") or {}).get(key)
        if v is not None and (not isinstance(v, kinds) or isinstance(v, bool)):
            raise ForeignStepFileError(where, f"meta {key!r} is a {type(v).__name__}")
    columns = (doc.get("meta") or {}).get("columns") or {}
    if not all(isinstance(c, list) and all(isinstance(x, str) for x in c)
               for c in columns.values()):
        raise ForeignStepFileError(where, "meta 'columns' holds something else than names")
    if name_problem(doc["name"]) or name_problem(doc["type"]) or doc["name"] != folder.name:
        raise ForeignStepFileError(where, f"step name {doc['name']!r} in folder "
                                   f"{folder.name!r}")
    if int(doc.get("schema", 0) or 0) > SCHEMA_VERSION:
        raise RecordError(f"{where}: saved in results schema {doc['schema']}; this rotoruq "
                          f"reads up to schema {SCHEMA_VERSION}: upgrade rotoruq")
    files = doc.get("files")
    if files is None:
        raise IncompleteStepError(f"{where}: saved without file checksums (an older or "
                                  "interrupted save)")
    data: dict[str, bytes] = {}
    for name, sha in files.items():
        if name_problem(name) or name == "result.json" or not isinstance(sha, str):
            raise ForeignStepFileError(where, f"it lists a file {name!r} outside its folder")
        p = folder / name
        try:
            data[name] = read_nofollow(p)
        except FileNotFoundError:
            raise IncompleteStepError(f"{p}: missing or changed since the step was "
                                      "saved") from None
        if hashlib.sha256(data[name]).hexdigest() != sha:
            raise IncompleteStepError(f"{p}: missing or changed since the step was saved")
    arrays = {}
    for n in doc.get("arrays") or []:
        if not isinstance(n, str) or f"{n}.npy" not in data:
            raise ForeignStepFileError(where, f"it lists an array {n!r} that is not one of "
                                       "its files")
        arrays[n] = _load_npy(folder / f"{n}.npy", data[f"{n}.npy"])
    try:
        scalars = {k: _unjson_scalar(v) for k, v in doc["scalars"].items()}
    except (TypeError, ValueError) as exc:
        raise ForeignStepFileError(where, f"a scalar that is not a number: {exc}") from None
    # last, so that a file rotoruq did not write is named as such by the checks above
    if doc.get("checksum") is None:
        raise IncompleteStepError(f"{where}: saved without a checksum (by an older rotoruq or "
                                  "an interrupted save)")
    if _checksum(doc) != doc["checksum"]:
        raise IncompleteStepError(f"{where}: changed since the step was saved (its checksum "
                                  "does not match its contents)")
    return StepResult(
        name=doc["name"],
        type=doc["type"],
        scalars=scalars,
        arrays=arrays,
        distributions=doc.get("distributions") or {},
        meta=doc.get("meta") or {},
        fingerprint=doc.get("fingerprint") or "",
    )


def _load_npy(path: Path, raw: bytes) -> np.ndarray:
    """An array saved by :func:`save_step`: plain numbers, booleans or text, never objects
    (a pickle is refused, never run)."""
    try:
        arr = np.load(io.BytesIO(raw), allow_pickle=False)
    except (ValueError, OSError, EOFError) as exc:
        raise ForeignStepFileError(path, f"not a plain numpy array: {exc}") from None
    if not isinstance(arr, np.ndarray) or arr.dtype.kind not in "biufcUSM":
        raise ForeignStepFileError(path, f"an array of {getattr(arr, 'dtype', type(arr))}")
    return arr


def save_study_info(directory: str | Path, info: Mapping[str, Any]) -> Path:
    """Write ``directory/study.json`` atomically; returns its path."""
    path = Path(directory) / STUDY_INFO
    write_text(path, json.dumps(_jsonable(dict(info)), indent=1, default=str))
    return path


def is_study_dir(directory: str | Path) -> bool:
    """Whether ``directory`` is a study output folder (it holds ``study.json``)."""
    p = Path(directory) / STUDY_INFO
    return p.is_file() or p.is_symlink()


def load_study_info(directory: str | Path) -> dict[str, Any]:
    """``directory/study.json`` as a dict (``{}`` when the folder has none); a symlink is
    :class:`~rotoruq.safety.UnsafePathError`, anything but a JSON object
    :class:`ForeignStepFileError`."""
    path = Path(directory) / STUDY_INFO
    try:
        raw = read_nofollow(path)
    except FileNotFoundError:
        return {}
    try:
        doc = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise ForeignStepFileError(path, f"not JSON: {exc}") from None
    if not isinstance(doc, dict):
        raise ForeignStepFileError(path, "not a JSON object")
    return doc


def study_infos(folders: Sequence[str | Path]) -> dict[str, tuple[Path, dict[str, Any]]]:
    """``study name -> (folder, study.json)`` of study output folders, in the order given (a
    folder given twice counts once). Two folders of one study name raise
    :class:`~rotoruq.errors.InputFileError` naming both ``study.json`` files: the report keys
    its sections by study name, and one of the two would otherwise be dropped in silence.

    Examples
    --------
    >>> import tempfile
    >>> a, b = Path(tempfile.mkdtemp()), Path(tempfile.mkdtemp())
    >>> _ = save_study_info(a, {"name": "ext"}), save_study_info(b, {"name": "ext"})
    >>> list(study_infos([a, a]))
    ['ext']
    >>> study_infos([a, b])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    rotoruq.errors.InputFileError: .../study.json: expected a study name of its own: study \
'ext' is also in .../study.json (report the two folders one at a time, or give one study \
another [study] name and run it again)
    """
    from .errors import InputFileError

    found: dict[str, tuple[Path, dict[str, Any]]] = {}
    seen: set[Path] = set()
    for folder in map(Path, folders):
        if folder.resolve() in seen:
            continue
        seen.add(folder.resolve())
        info = load_study_info(folder)
        name = info.get("name")
        if not isinstance(name, str):
            raise ForeignStepFileError(folder / STUDY_INFO, "its 'name' is not a text")
        if name in found:
            other = found[name][0] / STUDY_INFO
            raise InputFileError(folder / STUDY_INFO, None,
                                 f"a study name of its own: study {name!r} is also in {other} "
                                 "(report the two folders one at a time, or give one study "
                                 "another [study] name and run it again)")
        found[name] = (folder, info)
    return found


def load_results(directory: str | Path, *, incomplete: dict[str, str] | None = None
                 ) -> dict[str, StepResult]:
    """All saved steps of one study output directory, in the order they were run. Every
    step folder must be a real folder (a symlink raises
    :class:`~rotoruq.safety.UnsafePathError` naming it).

    A step that does not load (:class:`IncompleteStepError`: a checksum that does not match,
    a file missing) raises, unless ``incomplete`` is a dict: the step is then left out and
    ``incomplete[name]`` says why (what ``rotoruq run`` would do: run it again).

    Parameters
    ----------
    directory : str or Path
        A study output folder (the one holding ``study.json`` and ``steps/``).
    incomplete : dict of str to str, optional
        Filled with step name -> why it did not load, for each step left out; None (the
        default) raises on the first such step instead.

    Returns
    -------
    dict of str to StepResult
        Step name -> its result, in the order of ``study.json``'s ``steps`` (steps it does
        not list last, by name).
    """
    directory = Path(directory)
    order = load_study_info(directory).get("steps", [])
    if not isinstance(order, list):
        raise ForeignStepFileError(directory / STUDY_INFO, "'steps' is not a list")
    steps = directory / "steps"
    found: dict[str, Path] = {}
    if steps.is_symlink() or steps.exists():
        for p in sorted(real_dir(steps).iterdir()):
            if p.name.startswith("."):
                continue
            no_symlink(p)
            if p.is_dir() and os.path.lexists(p / "result.json"):
                found[p.name] = p
    names = [n for n in order if n in found] + sorted(set(found) - set(order))
    if incomplete is None:
        return {n: load_step(found[n]) for n in names}
    out: dict[str, StepResult] = {}
    for n in names:
        try:
            out[n] = load_step(found[n])
        except IncompleteStepError as exc:
            incomplete[n] = str(exc)
    return out
