"""``[data.NAME]`` tables of a study file: CSV files (bundled ones found in ``rotoruq/data``)
or inline columns, as :class:`~rotoruq.study.spec.DataSet`."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..errors import InputFileError
from .options import Checker, number_list, string, string_list, table
from .spec import DataSet

__all__ = ["parse_data", "DATA_KEYS"]

DATA_KEYS = ("file", "select", "columns")


def parse_data(ck: Checker, doc: dict, base: Path) -> dict[str, DataSet]:
    """``[data.NAME]`` tables: a CSV file (``file``, ``select``, ``columns``) or inline columns."""
    t = ck.table(doc.get("data", {}), ("data",), "[data]")
    out = {}
    for name, spec in t.items():
        w = ("data", name)
        spec = ck.table(spec, w, f"[data.{name}] (a table: file = \"x.csv\" or inline columns)")
        if "file" in spec:
            ck.keys(spec, DATA_KEYS, w, f"[data.{name}]")
            rel = ck.value(spec, "file", (string(), None), w, f"[data.{name}]")
            fpath = _resolve_data_path(rel, base)
            if fpath is None:
                ck.fail(w + ("file",), f"an existing CSV file (looked in {base} and the bundled "
                        "rotoruq/data)", rel)
            cols = _read_csv(ck, fpath, w)
            select = ck.value(spec, "select", (table, {}), w, f"[data.{name}]") or {}
            select = ck.numbers(select, w + ("select",), f"[data.{name}] select")
            mask = np.ones(len(next(iter(cols.values()))), bool)
            for k, v in select.items():
                if k not in cols:
                    ck.fail(w + ("select", k), f"a column of {fpath.name}: {', '.join(cols)}", k)
                mask &= np.isclose(cols[k], v)
            if not mask.any():
                ck.fail(w + ("select",), f"a selection matching at least one row of {fpath.name}")
            cols = {k: v[mask] for k, v in cols.items()}
            keep = ck.value(spec, "columns", (string_list, None), w, f"[data.{name}]")
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
                value = [v] if isinstance(v, int | float) and not isinstance(v, bool) else v
                try:
                    cols[k] = np.asarray(number_list(value))
                except TypeError:
                    ck.fail(w + (k,), f"file = \"data.csv\" or inline columns (name = [numbers])"
                            f" in [data.{name}]", repr(v))
            lengths = {len(v) for v in cols.values()}
            if len(lengths) > 1:
                ck.fail(w, f"columns of equal length in [data.{name}]",
                        ", ".join(f"{k}: {len(v)}" for k, v in cols.items()))
            if not cols:
                ck.fail(w, f"at least one column in [data.{name}]")
            out[name] = DataSet(name, cols, "inline")
    return out


def _resolve_data_path(rel: str, base: Path) -> Path | None:
    p = Path(rel)
    candidates = [p] if p.is_absolute() else [base / p]
    if not p.is_absolute():
        candidates.append(Path(__file__).resolve().parents[1] / "data" / p)
    for c in candidates:
        if c.is_file():
            return c
    return None


def _read_csv(ck: Checker, fpath: Path, where: tuple) -> dict[str, np.ndarray]:
    with fpath.open(newline="", encoding="utf-8") as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].lstrip().startswith("#")]
    if len(rows) < 2:
        raise InputFileError(fpath, 1, "a header row and at least one data row")
    header = [h.strip() for h in rows[0]]
    # line numbers: count comment lines too, so recompute positions from the raw file
    raw_lines = fpath.read_text(encoding="utf-8").splitlines()
    data_lines = [i + 1 for i, r in enumerate(raw_lines) if r.strip() and not
                  r.lstrip().startswith("#")][1:]
    cols: dict[str, list[float]] = {h: [] for h in header}
    for row, lineno in zip(rows[1:], data_lines, strict=False):
        if len(row) != len(header):
            raise InputFileError(fpath, lineno, f"{len(header)} comma-separated values",
                                 ",".join(row))
        for h, v in zip(header, row, strict=True):
            try:
                cols[h].append(float(v))
            except ValueError:
                raise InputFileError(fpath, lineno, f"a number in column {h!r}", v) from None
    return {h: np.asarray(v) for h, v in cols.items()}
