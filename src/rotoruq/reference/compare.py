"""Our values beside the thesis's: resolve every reference cell against saved results and
express each difference in the unit a reader needs (see :attr:`ComparedCell.diff_kind`).
The reference study's claims are checked in :mod:`rotoruq.reference.claims`."""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..report.tables import fmt
from ..results import StepResult
from .studies import STUDIES
from .tables import TABLES, ReferenceTable

__all__ = ["ComparedCell", "ComparedTable", "compare_tables", "resolve", "REFERENCE_STUDIES"]

# The reference studies and the preset each runs (kept under its former name).
REFERENCE_STUDIES = STUDIES

# Statistics already dimensionless and meaningful near zero: their difference is absolute.
_ABSOLUTE = {"S", "T", "nstd", "pp_nstd", "skewness", "kurtosis", "acceptance"}
# Beyond this relative size a percent difference says nothing (the reference is near zero).
_REL_MAX = 10.0

Results = Mapping[str, Mapping[str, StepResult]]  # study name -> step name -> result


@dataclass(frozen=True)
class ComparedCell:
    """Thesis value, ours (None when we have none), where ours comes from, and ``sigma``: the
    thesis's standard deviation of the same quantity when the cell is a mean (its row has a
    matching std column)."""

    thesis: float | None
    ours: float | None
    source: str | None
    sigma: float | None = None

    @property
    def diff(self) -> float | None:
        """ours - thesis, in the quantity's unit."""
        if self.thesis is None or self.ours is None:
            return None
        return self.ours - self.thesis

    @property
    def rel(self) -> float | None:
        """(ours - thesis) / |thesis| (None when the thesis value is 0)."""
        d = self.diff
        if d is None or self.thesis is None or self.thesis == 0:
            return None
        return d / abs(self.thesis)

    @property
    def diff_kind(self) -> str:
        """How the difference is best read: ``"sigma"`` (a mean, in the thesis's std devs),
        ``"absolute"`` (indices, std-dev counts, shape moments, or a reference near zero),
        ``"relative"`` (a reference well away from zero), ``""`` (nothing to compare)."""
        if self.diff is None:
            return ""
        stat = (self.source or "").split(":", 1)[-1].split("/")[0]
        if stat in _ABSOLUTE:
            return "absolute"
        if self.sigma is not None and self.sigma > 0:
            return "sigma"
        r = self.rel
        if r is None or abs(r) > _REL_MAX:
            return "absolute"
        return "relative"

    @property
    def diff_value(self) -> float | None:
        """The difference in the unit of :attr:`diff_kind` (relative as a fraction)."""
        k = self.diff_kind
        if k == "sigma" and self.diff is not None and self.sigma:
            return self.diff / self.sigma
        if k == "relative":
            return self.rel
        return self.diff

    def diff_text(self) -> str:
        k, v = self.diff_kind, self.diff_value
        if v is None:
            return fmt(None)
        if k == "sigma":
            return f"{v:+.2f} σ"
        if k == "relative":
            return f"{100 * v:+.1f} %"
        if k == "absolute":
            return f"{v:+.3g}" if v != 0 else "0"
        return fmt(None)


@dataclass(frozen=True)
class ComparedTable:
    ref: ReferenceTable
    rows: tuple[tuple[str, tuple[ComparedCell, ...]], ...]

    @property
    def n_ours(self) -> int:
        return sum(c.ours is not None for _, cells in self.rows for c in cells)

    @property
    def n_cells(self) -> int:
        return sum(c.thesis is not None for _, cells in self.rows for c in cells)


@lru_cache(maxsize=1)
def _measurements() -> dict[str, np.ndarray]:
    path = Path(__file__).resolve().parents[1] / "data" / "gvpm_measurements.csv"
    rows = [r for r in csv.reader(path.read_text().splitlines()) if r and not
            r[0].startswith("#")]
    return {h: np.array([float(r[i]) for r in rows[1:]]) for i, h in enumerate(rows[0])}


def resolve(source: str | None, steps: Mapping[str, StepResult],
            model_values: Mapping[str, float] | None = None) -> float | None:
    """Value of a reference cell's source (see :mod:`rotoruq.reference.tables`).

    ``model_values`` are the model properties the run recorded (``study.json`` ``model.values``:
    preset fields and nominal airfoil coefficients); a ``model:PRESET:NAME`` cell reads them,
    so the report never rebuilds the model.
    """
    if source is None:
        return None
    if source.startswith("model:"):
        _, _preset, name = source.split(":", 2)
        v = (model_values or {}).get(name)
        return None if v is None else float(v)
    if source.startswith("data:"):
        col, h = source[5:].split("@")
        m = _measurements()
        rows = np.flatnonzero(np.isclose(m["height_over_radius"], float(h)))
        return float(m[col][rows[0]]) if rows.size and col in m else None
    step, key = source.split(":", 1)
    res = steps.get(step)
    if res is None or key not in res.scalars:
        return None
    v = float(res.scalars[key])
    return v if math.isfinite(v) else None


def _sigma_columns(columns) -> dict[int, int]:
    """Mean column -> the std column of the same quantity ("Exp. mean" -> "Exp. std")."""
    low = [c.lower() for c in columns]
    out = {}
    for j, c in enumerate(low):
        if "mean" in c:
            twin = c.replace("mean", "std")
            if twin in low:
                out[j] = low.index(twin)
    return out


def compare_tables(results: Results,
                   model_values: Mapping[str, Mapping[str, float]] | None = None
                   ) -> list[ComparedTable]:
    """Every reference table with our values from ``results`` (study -> steps) and the model
    properties each study's run recorded (``model_values``: study -> name -> value)."""
    out = []
    model_values = model_values or {}
    for ref in TABLES:
        steps = results.get(ref.study, {})
        values = model_values.get(ref.study, {})
        twins = _sigma_columns(ref.columns)
        rows = []
        for lab, cells in ref.rows:
            row = []
            for j, (th, src) in enumerate(cells):
                sig = cells[twins[j]][0] if j in twins else None
                row.append(ComparedCell(th, resolve(src, steps, values), src, sig))
            rows.append((lab, tuple(row)))
        out.append(ComparedTable(ref, tuple(rows)))
    return out
