"""``[data.NAME]`` tables of a study file: CSV or Dakota tabular files (bundled ones found in
``rotoruq/data``) or inline columns, as :class:`~rotoruq.study.spec.DataSet`.

A file is read by :func:`rotoruq.evaluation.tabular.read_table` (the one home of the parsing):
a Dakota tabular file (annotated or custom_annotated, told by its ``%`` header; freeform with
``format = "dakota"`` and ``columns = [...]`` naming every column) or a CSV file.

Measured numbers are checked when the study is read: ``nan`` and ``inf`` are refused with the
file and line unless the table says ``allow_nonfinite = true``; a number beyond float range
(``1e400``) or of more than ``MAX_NUMBER_CHARS`` characters always is. A ``select`` matching
no row lists the values its columns hold. (The columns the steps use are checked by
:mod:`rotoruq.study.schema`, which knows the steps.)
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..evaluation.dakota_files import read_text
from ..evaluation.tabular import (
    FORMATS,
    TabularData,
    parse_csv,
    parse_tabular,
    read_table,
    table_format,
)
from .options import Checker, boolean, number_list, string, string_list, table
from .spec import DataSet

__all__ = ["parse_data", "DATA_KEYS", "resolve_data_path", "read_data_file", "points_file",
           "points_columns"]

DATA_KEYS = ("file", "format", "select", "columns", "allow_nonfinite")


def _nonfinite_hint(name: str) -> str:
    return (f" (nan and inf are refused: set allow_nonfinite = true in [data.{name}] to keep "
            "them as missing values)")


def parse_data(ck: Checker, doc: dict, base: Path) -> dict[str, DataSet]:
    """``[data.NAME]`` tables: a CSV or Dakota tabular file (``file``, ``format``, ``select``,
    ``columns``, ``allow_nonfinite``) or inline columns (and ``allow_nonfinite``)."""
    t = ck.table(doc.get("data", {}), ("data",), "[data]")
    out = {}
    for name, spec in t.items():
        w = ("data", name)
        spec = ck.table(spec, w, f"[data.{name}] (a table: file = \"x.csv\" or inline columns)")
        allow = ck.value(spec, "allow_nonfinite", (boolean, False), w, f"[data.{name}]")
        hint = None if allow else _nonfinite_hint(name)
        if "file" in spec:
            ck.keys(spec, DATA_KEYS, w, f"[data.{name}]")
            rel = ck.value(spec, "file", (string(), None), w, f"[data.{name}]")
            fpath = resolve_data_path(rel, base)
            if fpath is None:
                ck.fail(w + ("file",), f"an existing CSV file or Dakota tabular file (looked in "
                        f"{base} and the bundled rotoruq/data)", rel)
            fmt = ck.value(spec, "format", (string(FORMATS), None), w, f"[data.{name}]")
            keep = ck.value(spec, "columns", (string_list, None), w, f"[data.{name}]")
            tab = read_data_file(ck, fpath, fmt, keep, w, nonfinite=hint)
            cols = {k: tab.values[:, j] for j, k in enumerate(tab.names)}
            select = ck.value(spec, "select", (table, {}), w, f"[data.{name}]") or {}
            select = ck.numbers(select, w + ("select",), f"[data.{name}] select")
            mask = np.ones(len(next(iter(cols.values()))), bool)
            for k, v in select.items():
                if k not in cols:
                    ck.fail(w + ("select", k), f"a column of {fpath.name}: {', '.join(cols)}", k)
                mask &= np.isclose(cols[k], v)
            if not mask.any():
                present = "; ".join(f"{k} has {_values(cols[k])}" for k in select)
                ck.fail(w + ("select",), f"a selection matching at least one row of "
                        f"{fpath.name} ({present})", ", ".join(f"{k} = {v:g}"
                                                               for k, v in select.items()))
            cols = {k: v[mask] for k, v in cols.items()}
            if keep is not None:
                for k in keep:
                    if k not in cols:
                        ck.fail(w + ("columns",), f"columns of {fpath.name}: {', '.join(cols)}",
                                k)
                cols = {k: cols[k] for k in keep}
            out[name] = DataSet(name, cols, str(fpath))
        else:
            cols = {}
            for k, v in spec.items():
                if k == "allow_nonfinite":
                    continue
                value = [v] if isinstance(v, int | float) and not isinstance(v, bool) else v
                try:
                    cols[k] = np.asarray(number_list(value))
                except TypeError:
                    ck.fail(w + (k,), f"file = \"data.csv\" or inline columns (name = [numbers])"
                            f" in [data.{name}]", repr(v))
                bad = np.flatnonzero(~np.isfinite(cols[k]))
                if bad.size and not allow:
                    ck.fail(w + (k,), f"finite numbers in column {k!r}{hint}",
                            f"{cols[k][bad[0]]} (value {bad[0] + 1})")
            lengths = {len(v) for v in cols.values()}
            if len(lengths) > 1:
                ck.fail(w, f"columns of equal length in [data.{name}]",
                        ", ".join(f"{k}: {len(v)}" for k, v in cols.items()))
            if not cols:
                ck.fail(w, f"at least one column in [data.{name}]")
            out[name] = DataSet(name, cols, "inline")
    return out


def resolve_data_path(rel: str, base: Path) -> Path | None:
    """The file ``rel`` names: relative to the study's folder ``base``, else a bundled data
    file of ``rotoruq/data``; None when neither exists."""
    p = Path(rel)
    candidates = [p] if p.is_absolute() else [base / p]
    if not p.is_absolute():
        candidates.append(Path(__file__).resolve().parents[1] / "data" / p)
    for c in candidates:
        if c.is_file():
            return c
    return None


def read_data_file(ck: Checker, fpath: Path, fmt: str | None, columns: tuple[str, ...] | None,
                   where: tuple, *, nonfinite: str | None = "") -> TabularData:
    """Read a study's table file (CSV or Dakota tabular; ``fmt`` None: told by a ``%``
    header). A Dakota file without a header (freeform) takes its column names from
    ``columns``; without them, the study line ``where`` says so. Numbers are checked
    (``strict`` of :func:`~rotoruq.evaluation.tabular.parse_csv`): ``nan`` and ``inf`` are
    refused with the hint ``nonfinite`` unless it is None."""
    text = read_text(fpath, "table file")
    found = table_format(text)
    if (fmt or found) == "csv":
        return parse_csv(text, fpath, strict=True, nonfinite=nonfinite)
    if found != "dakota":
        if columns is None:
            ck.fail(where, f"columns = [...] naming every column of {fpath.name} (a Dakota "
                    "tabular file without a '%' header: freeform)")
        return parse_tabular(text, fpath, names=columns, strict=True, nonfinite=nonfinite)
    return parse_tabular(text, fpath, strict=True, nonfinite=nonfinite)


def _values(col: np.ndarray, most: int = 12) -> str:
    """The distinct values of a column, in words (at most ``most``)."""
    u = np.unique(col[np.isfinite(col)])
    shown = ", ".join(f"{v:g}" for v in u[:most])
    return (shown + f", ... ({u.size} values)" if u.size > most else shown) or "no number"


def points_file(ck: Checker, rel: str, base: Path, where: tuple) -> dict[str, str]:
    """A step's ``points = "file"`` (given points, read by the step when it runs): the file
    relative to the study's folder, checked now to be a readable table (a Dakota tabular
    file with its ``%`` header or a CSV file; errors name its line). Returns ``{"file":
    <absolute path>, "sha256": <digest of its bytes>}``: the digest enters the step's
    fingerprint, so an edited points file re-runs the step."""
    fpath = Path(rel) if Path(rel).is_absolute() else base / rel
    if not fpath.is_file():
        ck.fail(where, f"an existing points file (a Dakota tabular or CSV file; looked in "
                f"{base})", rel)
    read_data_file(ck, fpath, None, None, where)
    return {"file": str(fpath.resolve()),
            "sha256": hashlib.sha256(fpath.read_bytes()).hexdigest()}


def points_columns(points: dict[str, str], names: Sequence[str]) -> None:
    """Check, when the study is read, that a points file (from :func:`points_file`) has a
    column for each of the step's inputs ``names``: the error names the file, its header line
    and the missing inputs (the step checks again, and each point's support, when it runs)."""
    read_table(points["file"]).require(list(names), "the step's inputs")
