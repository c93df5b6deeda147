"""Dakota's tabular data files, read and written.

Dakota writes (``environment tabular_data``) and reads (``import_points_file``,
``import_build_points_file``) three layouts; Dakota 6.24 writes them so::

    annotated (the default)
    %eval_id interface x1             P=W            f
    1        NO_ID      1              2              1

    custom_annotated [header] [eval_id] [interface]   (any of the three parts)
    %eval_id x1             P=W            f
    1        1              2              1

    freeform (numbers only)
                 1              2              1

A header line starts with ``%``; its words name the columns, ``eval_id`` and ``interface``
being Dakota's own. Values are separated by white space; the interface column holds a word
(``NO_ID`` or the deck's ``id_interface``). :func:`read_tabular` returns the named columns as
a :class:`TabularData`; :func:`write_tabular` writes any of the layouts with 17 significant
digits, so a float64 survives the round trip. Parsing is linear in the file size and every
malformed row raises :class:`~rotoruq.errors.InputFileError` naming the file and line.

This module is the one home of reading tables of numbers: :func:`read_table` reads a Dakota
tabular file or a CSV file (a header row of names, ``#`` comment lines), telling them apart
by the ``%`` header (a study's ``[data.NAME]`` tables and given points read through it).
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputFileError, ParameterError
from .dakota_files import _is_number, check_label, read_text
from .store import Store

__all__ = ["TabularData", "read_tabular", "parse_tabular", "format_tabular", "write_tabular",
           "export_store", "LAYOUTS", "FORMATS", "read_table", "parse_csv", "table_format"]

#: the layouts of Dakota's tabular files
LAYOUTS = ("annotated", "custom_annotated", "freeform")
#: the formats :func:`read_table` reads
FORMATS = ("csv", "dakota")
#: the longest word read as a number where numbers are checked (``strict``): a float64 needs
#: at most 24 characters; a longer word is a pasted mistake, not a measurement
MAX_NUMBER_CHARS = 100
_NONFINITE = {"nan", "inf", "infinity"}


@dataclass(frozen=True, eq=False)
class TabularData:
    """Content of a tabular file.

    names : labels of the data columns (variables then responses, as in the file; not
        ``eval_id`` or ``interface``).
    values : (n, k) the data columns, float.
    eval_id : (n,) evaluation ids, or None when the file has no such column.
    interface : the interface id of each row, or None when the file has no such column.
    layout : "annotated" (header with eval_id and interface), "custom_annotated", "freeform"
        or "csv" (read by :func:`parse_csv`).
    path : the file read (None for text parsed without one).
    header_line : the 1-based line of the header (None without a header).
    lines : (n,) the 1-based line of each row in the file (None when not read from text).
    """

    names: tuple[str, ...]
    values: np.ndarray
    eval_id: np.ndarray | None = None
    interface: tuple[str, ...] | None = None
    layout: str = "annotated"
    path: str | None = None
    header_line: int | None = None
    lines: tuple[int, ...] | None = None

    def __len__(self) -> int:
        return int(self.values.shape[0])

    def __getitem__(self, name: str) -> np.ndarray:
        """The column ``name``, (n,)."""
        return self.columns([name])[:, 0]

    def columns(self, names: Sequence[str]) -> np.ndarray:
        """The columns ``names``, in that order: (n, len(names))."""
        missing = [n for n in names if n not in self.names]
        if missing:
            raise ParameterError(f"columns {missing} are not in the tabular data; it has "
                                 f"{list(self.names)}")
        return self.values[:, [self.names.index(n) for n in names]]

    def require(self, names: Sequence[str], what: str = "the columns") -> np.ndarray:
        """The columns ``names`` (n, len(names)); a missing one raises
        :class:`~rotoruq.errors.InputFileError` naming the file, its header line and the
        missing names (``what`` says what they are for)."""
        missing = [n for n in names if n not in self.names]
        if missing:
            raise InputFileError(self.path, self.header_line,
                                 f"a column for each of {what} {', '.join(names)} (missing: "
                                 f"{', '.join(missing)})", "columns " + " ".join(self.names))
        return self.columns(names)

    def line(self, row: int) -> int | None:
        """The file line of row ``row`` (0-based), None when unknown."""
        return None if self.lines is None else self.lines[row]


def _float(word: str, path, lineno: int, what: str, strict: bool = False,
           nonfinite: str | None = None) -> float:
    """``word`` as a float. ``strict``: a word longer than :data:`MAX_NUMBER_CHARS` and a
    number beyond float range (``1e400``) are refused; a written ``nan`` or ``inf`` too,
    unless ``nonfinite`` is None (else it is the hint the error ends with)."""
    if strict and len(word) > MAX_NUMBER_CHARS:
        raise InputFileError(path, lineno, f"{what} of at most {MAX_NUMBER_CHARS} characters",
                             f"{word[:20]}... ({len(word)} characters)")
    try:
        v = float(word)
    except ValueError:
        raise InputFileError(path, lineno, what, word) from None
    if strict and not math.isfinite(v):
        if word.strip().lstrip("+-").lower() not in _NONFINITE:
            raise InputFileError(path, lineno, f"{what} within float range (magnitude below "
                                 "1.8e308)", word)
        if nonfinite is not None:
            raise InputFileError(path, lineno, f"{what} that is finite{nonfinite}", word)
    return v


def parse_tabular(text: str, path: str | os.PathLike | None = None, *,
                  names: Sequence[str] | None = None, strict: bool = False,
                  nonfinite: str | None = None) -> TabularData:
    """Parse the text of a tabular file (the layout is detected; see :func:`read_tabular`).
    ``strict``, ``nonfinite``: see :func:`parse_csv`."""
    lines = [(k, raw.split()) for k, raw in enumerate(text.splitlines(), 1) if raw.strip()]
    if not lines:
        raise InputFileError(path, None, "a Dakota tabular file", "an empty file")
    head_ln, first = lines[0]
    has_id = has_if = False
    if first[0].startswith("%"):
        cols = [first[0][1:], *first[1:]] if first[0] != "%" else first[1:]
        if not cols:
            raise InputFileError(path, head_ln, "column names after '%'", "none")
        has_id = cols[0] == "eval_id"
        rest = cols[1:] if has_id else cols
        has_if = bool(rest) and rest[0] == "interface"
        data_names = rest[1:] if has_if else rest
        for special in ("eval_id", "interface"):
            if special in data_names:
                raise InputFileError(path, head_ln, f"'{special}' only as a leading column",
                                     " ".join(first))
        if names is not None and list(names) != list(data_names):
            raise InputFileError(path, head_ln, f"the columns {list(names)}",
                                 str(list(data_names)))
        layout = "annotated" if has_id and has_if else "custom_annotated"
        rows = lines[1:]
    else:
        rows = lines
        width = len(first)
        if names is None:
            raise InputFileError(path, head_ln, "a '%' header naming the columns (a freeform "
                                 "file has none: pass names=)", " ".join(first[:4]))
        data_names = list(names)
        if width == len(data_names) + 1:  # custom_annotated eval_id without a header
            has_id = True
        elif width == len(data_names) + 2 and not _is_number(first[1]):
            has_id = has_if = True
        layout = "freeform" if not (has_id or has_if) else "custom_annotated"
    if len(set(data_names)) < len(data_names):
        raise InputFileError(path, head_ln, "distinct column names", str(list(data_names)))
    lead = int(has_id) + int(has_if)
    width = lead + len(data_names)
    values = np.empty((len(rows), len(data_names)))
    ids = np.empty(len(rows), dtype=np.int64) if has_id else None
    ifaces = []
    row_lines = tuple(ln for ln, _ in rows)
    for i, (ln, words) in enumerate(rows):
        if len(words) != width:
            raise InputFileError(path, ln, f"{width} columns ({'eval_id ' if has_id else ''}"
                                 f"{'interface ' if has_if else ''}{' '.join(data_names)})",
                                 f"{len(words)} columns")
        if ids is not None:
            w = words[0]
            if not (w.isascii() and w.isdigit()):
                raise InputFileError(path, ln, "an integer eval_id", w)
            ids[i] = int(w)
        if has_if:
            ifaces.append(words[int(has_id)])
        values[i] = [_float(w, path, ln, f"a number in column {n!r}", strict, nonfinite)
                     for w, n in zip(words[lead:], data_names, strict=True)]
    return TabularData(tuple(data_names), values, ids, tuple(ifaces) if has_if else None,
                       layout, None if path is None else str(path),
                       head_ln if first[0].startswith("%") else None, row_lines)


def parse_csv(text: str, path: str | os.PathLike | None = None, *, strict: bool = False,
              nonfinite: str | None = None) -> TabularData:
    """Parse a CSV table: a header row of column names, then rows of numbers; blank lines and
    lines starting with ``#`` are skipped. Every malformed row raises
    :class:`~rotoruq.errors.InputFileError` naming the file and line.

    ``strict`` (measured data): a number beyond float range (``1e400``) or longer than
    :data:`MAX_NUMBER_CHARS` characters is refused, and so is a written ``nan`` or ``inf``
    unless ``nonfinite`` is None (else the error ends with it: how to allow them).

    Examples
    --------
    >>> t = parse_csv("# measured\\nthrust,power\\n1.5,2\\n\\n3,4e1\\n", "m.csv")
    >>> t.names, t.values.tolist(), t.lines
    (('thrust', 'power'), [[1.5, 2.0], [3.0, 40.0]], (3, 5))
    >>> parse_csv("thrust\\n1e400\\n", "m.csv", strict=True)
    Traceback (most recent call last):
    ...
    rotoruq.errors.InputFileError: m.csv, line 2: expected a number ... float range ...
    """
    rows = [(k, next(csv.reader([raw]))) for k, raw in enumerate(text.splitlines(), 1)
            if raw.strip() and not raw.lstrip().startswith("#")]
    if len(rows) < 2:
        raise InputFileError(path, rows[0][0] if rows else 1,
                             "a header row and at least one data row",
                             f"{len(rows)} non-comment row(s)")
    head_ln, header = rows[0][0], [h.strip() for h in rows[0][1]]
    if len(set(header)) < len(header) or not all(header):
        raise InputFileError(path, head_ln, "distinct, non-empty column names",
                             ",".join(header))
    values = np.empty((len(rows) - 1, len(header)))
    for i, (ln, row) in enumerate(rows[1:]):
        if len(row) != len(header):
            raise InputFileError(path, ln, f"{len(header)} comma-separated values",
                                 ",".join(row))
        values[i] = [_float(v, path, ln, f"a number in column {h!r}", strict, nonfinite)
                     for h, v in zip(header, row, strict=True)]
    return TabularData(tuple(header), values, layout="csv",
                       path=None if path is None else str(path), header_line=head_ln,
                       lines=tuple(ln for ln, _ in rows[1:]))


def table_format(text: str) -> str:
    """"dakota" when the first non-blank line is a Dakota ``%`` header, else "csv" (a
    freeform Dakota file has no header: name its format)."""
    first = next((raw.lstrip() for raw in text.splitlines() if raw.strip()), "")
    return "dakota" if first.startswith("%") else "csv"


def read_table(path: str | os.PathLike, *, format: str | None = None,
               names: Sequence[str] | None = None) -> TabularData:
    """Read a table of numbers: a Dakota tabular file or a CSV file.

    Parameters
    ----------
    path : the file.
    format : "dakota" or "csv"; None detects it (:func:`table_format`: a ``%`` header is
        Dakota's).
    names : Dakota files only: the column names of a file without a header (freeform), else
        checked against the header (see :func:`read_tabular`).

    Returns
    -------
    TabularData
        ``layout`` is "csv" for a CSV file; ``lines`` give each row's line in the file.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> d = Path(tempfile.mkdtemp())
    >>> _ = (d / "a.dat").write_text("%eval_id interface x f\\n1 NO_ID 0.5 2\\n")
    >>> _ = (d / "b.csv").write_text("x,f\\n0.5,2\\n")
    >>> [read_table(d / n).values.tolist() for n in ("a.dat", "b.csv")]
    [[[0.5, 2.0]], [[0.5, 2.0]]]
    """
    text = read_text(path, "table file")
    fmt = table_format(text) if format is None else format
    if fmt not in FORMATS:
        raise ParameterError(f"format must be one of {FORMATS}, got {format!r}")
    if fmt == "csv":
        if names is not None:
            raise ParameterError("names= is for a Dakota file without a header; a CSV file "
                                 "names its columns in its header row")
        return parse_csv(text, path)
    return parse_tabular(text, path, names=names)


def _column_name(name) -> str:
    """A column label: a word (Dakota splits on white space; labels like ``P=W`` are fine)."""
    if (not isinstance(name, str) or not name or name.startswith("%")
            or any(c.isspace() or not c.isprintable() for c in name)):
        raise ParameterError(f"column name {name!r} must be a non-empty word without white "
                             "space or control characters, not starting with '%'")
    return name


def read_tabular(path: str | os.PathLike, *, names: Sequence[str] | None = None
                 ) -> TabularData:
    """Read a Dakota tabular file (annotated, custom_annotated or freeform; detected).

    Parameters
    ----------
    path : the file.
    names : the data columns' names. Required for a file without a header (freeform, or
        custom_annotated without ``header``); checked against the header otherwise.

    Returns
    -------
    TabularData

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> p = Path(tempfile.mkdtemp()) / "t.dat"
    >>> _ = p.write_text("%eval_id interface x1 P=W f\\n1 NO_ID 1 2 3\\n2 NO_ID 4 5 6\\n")
    >>> t = read_tabular(p)
    >>> t.names, t["P=W"].tolist(), t.eval_id.tolist(), t.interface
    (('x1', 'P=W', 'f'), [2.0, 5.0], [1, 2], ('NO_ID', 'NO_ID'))
    """
    return parse_tabular(read_text(path, "Dakota tabular file"), path, names=names)


def format_tabular(names: Sequence[str], values: np.ndarray, *, layout: str = "annotated",
                   header: bool | None = None, eval_id: bool | None = None,
                   interface: str | None = "NO_ID") -> str:
    """Text of a tabular file (see :func:`write_tabular`)."""
    if layout not in LAYOUTS:
        raise ParameterError(f"layout must be one of {LAYOUTS}, got {layout!r}")
    names = [_column_name(n) for n in names]
    if len(set(names)) < len(names):
        raise ParameterError(f"column names must be distinct, got {names}")
    values = np.atleast_2d(np.asarray(values, dtype=float))
    if values.shape[1] != len(names):
        raise ParameterError(f"{values.shape[1]} columns of values for {len(names)} names")
    if layout == "annotated":
        header, eval_id = True, True
        if interface is None:
            interface = "NO_ID"
    elif layout == "freeform":
        header, eval_id, interface = False, False, None
    else:
        header = True if header is None else header
        eval_id = True if eval_id is None else eval_id
    if interface is not None:
        check_label(interface, "interface id")
        if _is_number(interface):
            raise ParameterError(f"interface id {interface!r} looks like a number; Dakota "
                                 "could not tell it from a value")
    cols = (["eval_id"] if eval_id else []) + (["interface"] if interface else []) + names
    out = []
    if header:
        out.append("%" + " ".join(f"{c:<23}" for c in cols).rstrip())
    for k, row in enumerate(values, 1):
        lead = ([f"{k:<23}"] if eval_id else []) + ([f"{interface:<23}"] if interface else [])
        out.append(" ".join(lead + [f"{v:23.16e}" for v in row]))
    return "\n".join(out) + "\n"


def write_tabular(path: str | os.PathLike, names: Sequence[str], values: np.ndarray, *,
                  layout: str = "annotated", header: bool | None = None,
                  eval_id: bool | None = None, interface: str | None = "NO_ID") -> Path:
    """Write a Dakota tabular file that Dakota's ``import_points_file`` reads.

    Parameters
    ----------
    path : the file.
    names : column labels, in the order of the columns of ``values``.
    values : (n, k) data; written with 17 significant digits.
    layout : "annotated" (``%eval_id interface <names>``), "custom_annotated" (``header``,
        ``eval_id`` and ``interface`` chosen, each defaulting to on) or "freeform" (numbers
        only).
    interface : the interface id written in the interface column (None: no such column, in
        the custom_annotated layout).

    Returns
    -------
    Path
        ``path``, written through a temporary file beside it and renamed.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> p = write_tabular(Path(tempfile.mkdtemp()) / "t.dat", ["x", "f"], [[1.0, 2.0]])
    >>> read_tabular(p).values.tolist()
    [[1.0, 2.0]]
    """
    path = Path(path)
    text = format_tabular(names, values, layout=layout, header=header, eval_id=eval_id,
                          interface=interface)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(path)
    return path


def export_store(store: Store | str | os.PathLike, path: str | os.PathLike, *,
                 columns: Sequence[str] | None = None, fixed: Mapping[str, float] | None = None,
                 inputs_only: bool = False, interface: str | None = "NO_ID",
                 layout: str = "annotated", study: str | None = None,
                 inputs: Sequence[str] | None = None, outputs: Sequence[str] | None = None,
                 include_failed: bool = False) -> Path:
    """Write a store's evaluations as a Dakota tabular file, columns named and ordered.

    Dakota reads a points file by position, so the columns must be in the order of the deck's
    variables: ``columns`` gives it.

    Parameters
    ----------
    store : a :class:`~rotoruq.evaluation.store.Store` or the path of its file.
    path : the tabular file to write.
    columns : input (and optionally response) names in the order wanted; inputs left out are
        not written. Default: the model's input order (the stored inputs, then ``fixed``).
        Responses not named follow the inputs in the stored order (none with
        ``inputs_only``).
    fixed : inputs held fixed in the run (e.g. a study's ``[model] fixed``): written as
        constant columns.
    inputs_only : write no response column (a points file for ``import_points_file``).
    interface : the interface id of the rows (``NO_ID`` is Dakota's default; None for none).
    layout : "annotated", "custom_annotated" or "freeform" (see :func:`write_tabular`).
    study : only the evaluations of this study name.
    inputs, outputs : the input (and response) names of the evaluations to export, when the
        store holds evaluations of several models (the error lists them; two steps of one
        study asking the same model for different responses differ only by ``outputs``).
    include_failed : failed evaluations as rows of ``nan`` responses (default: left out).

    Returns
    -------
    Path
        ``path``, one row per exported evaluation (written by :func:`write_tabular`).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from rotoruq.evaluation.store import NewRecord, Store
    >>> d = Path(tempfile.mkdtemp())
    >>> s = Store(d / "e.sqlite")
    >>> _ = s.add([NewRecord(np.array([1.0, 2.0]), np.array([3.0]))], study="s", model="m",
    ...           names_in=["a", "b"], names_out=["f"])
    >>> p = export_store(s, d / "t.dat", columns=["b", "c", "a"], fixed={"c": 9.0})
    >>> read_tabular(p).names, read_tabular(p).values.tolist()
    (('b', 'c', 'a', 'f'), [[2.0, 9.0, 1.0, 3.0]])
    """
    st = store if isinstance(store, Store) else Store(store)
    recs = st.records(study=study)
    if outputs is None:  # a driver's stored gradients (model "<id>#gradient") only on request
        recs = [r for r in recs if not r.model.endswith("#gradient")]
    if not include_failed:
        recs = [r for r in recs if r.outputs is not None and r.status != "failed"]
    groups: dict[tuple, list] = {}
    for r in recs:
        groups.setdefault((r.names_in, r.names_out), []).append(r)
    for names, at in ((inputs, 0), (outputs, 1)):
        if names is not None:
            groups = {k: v for k, v in groups.items() if sorted(k[at]) == sorted(names)}
    where = f" of study {study!r}" if study else ""
    if not groups:
        raise ParameterError(f"no evaluations{where} to export from {st.path}"
                             + (f" with inputs {list(inputs)}" if inputs is not None else "")
                             + (f" with outputs {list(outputs)}" if outputs is not None else ""))
    if len(groups) > 1:
        listing = "; ".join(f"{len(v)} with inputs {','.join(k[0])} -> {','.join(k[1])}"
                            for k, v in groups.items())
        raise ParameterError(f"the store holds evaluations of several models ({listing}): "
                             "choose one by its inputs and outputs (--inputs, --outputs)")
    (names_in, names_out), rows = next(iter(groups.items()))
    fixed = {str(k): float(v) for k, v in (fixed or {}).items() if k not in names_in}
    table: dict[str, np.ndarray] = {n: np.array([r.inputs[i] for r in rows])
                                    for i, n in enumerate(names_in)}
    table.update({k: np.full(len(rows), v) for k, v in fixed.items()})
    outs = {n: np.array([np.nan if r.outputs is None else r.outputs[j] for r in rows])
            for j, n in enumerate(names_out)}
    all_inputs = list(names_in) + list(fixed)
    if columns is None:
        cols = all_inputs
    else:
        cols = list(columns)
        unknown = [c for c in cols if c not in table and c not in outs]
        if unknown:
            raise ParameterError(f"columns {unknown} are neither inputs {all_inputs} nor "
                                 f"responses {list(names_out)} of the stored evaluations")
        if inputs_only and any(c in outs for c in cols):
            raise ParameterError(f"inputs_only, but the columns {cols} name responses")
    if not inputs_only and not any(c in outs for c in cols):
        cols += list(names_out)
    data = np.column_stack([table[c] if c in table else outs[c] for c in cols])
    return write_tabular(path, cols, data, layout=layout, interface=interface)
