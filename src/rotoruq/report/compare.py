"""Our values beside the thesis's: resolve every reference cell against saved results, and
check the reference study's claims (which hold for us, which held for the thesis)."""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..study.results import StepResult
from .reference import TABLES, ReferenceTable

__all__ = ["ComparedCell", "ComparedTable", "Claim", "compare_tables", "claims", "resolve"]

Results = Mapping[str, Mapping[str, StepResult]]  # study name -> step name -> result


@dataclass(frozen=True)
class ComparedCell:
    """Thesis value, ours (None when we have none) and ours - thesis, relative to |thesis|."""

    thesis: float | None
    ours: float | None
    source: str | None

    @property
    def diff(self) -> float | None:
        if self.thesis is None or self.ours is None:
            return None
        return self.ours - self.thesis

    @property
    def rel(self) -> float | None:
        d = self.diff
        if d is None or self.thesis == 0:
            return None
        return d / abs(self.thesis)


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


@dataclass(frozen=True)
class Claim:
    """A statement of the reference study; ``ours``/``thesis`` are k-of-n counts (None when
    it cannot be checked: the steps did not run)."""

    text: str
    ours: tuple[int, int] | None
    thesis: tuple[int, int] | None
    detail: str = ""

    @property
    def holds(self) -> bool | None:
        if self.ours is None:
            return None
        return self.ours[0] == self.ours[1]


@lru_cache(maxsize=4)
def _model_values(preset: str) -> dict[str, float]:
    out: dict[str, float] = {}
    try:
        from ..rotor.presets import get_preset

        p = get_preset(preset)
        for k, v in vars(p).items():
            if isinstance(v, int | float) and not isinstance(v, bool):
                out[k] = float(v)
    except Exception:  # noqa: BLE001 - a preset we cannot build just leaves cells empty
        return out
    try:
        from ..rotor.model import load_airfoil

        out.update(load_airfoil(p).nominal_values())
    except Exception:  # noqa: BLE001
        pass
    return out


@lru_cache(maxsize=1)
def _measurements() -> dict[str, np.ndarray]:
    path = Path(__file__).resolve().parents[1] / "data" / "gvpm_measurements.csv"
    rows = [r for r in csv.reader(path.read_text().splitlines()) if r and not
            r[0].startswith("#")]
    return {h: np.array([float(r[i]) for r in rows[1:]]) for i, h in enumerate(rows[0])}


def resolve(source: str | None, steps: Mapping[str, StepResult]) -> float | None:
    """Value of a reference cell's source (see :mod:`rotoruq.report.reference`)."""
    if source is None:
        return None
    if source.startswith("model:"):
        _, preset, name = source.split(":", 2)
        return _model_values(preset).get(name)
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


def compare_tables(results: Results) -> list[ComparedTable]:
    """Every reference table with our values from ``results`` (study -> steps)."""
    out = []
    for ref in TABLES:
        steps = results.get(ref.study, {})
        rows = tuple((lab, tuple(ComparedCell(th, resolve(src, steps), src)
                                 for th, src in cells)) for lab, cells in ref.rows)
        out.append(ComparedTable(ref, rows))
    return out


def _count(values, pred) -> tuple[int, int] | None:
    vals = [v for v in values if v is not None]
    if not vals or len(vals) < len(values):
        return None
    return sum(bool(pred(v)) for v in vals), len(vals)


def _col(t: ComparedTable, j: int, which: str) -> list:
    return [getattr(cells[j], which) for _, cells in t.rows]


def claims(tables: list[ComparedTable]) -> list[Claim]:
    """The reference study's main claims, checked on our results and on the thesis's."""
    by = {t.ref.number: t for t in tables}
    out = []

    t = by["3.9"]
    def rel_err(which):
        real, cal = _col(t, 0, which), _col(t, 2, which)
        if any(v is None for v in real + cal):
            return [None] * len(real)
        return [abs(c - r) / abs(r) for r, c in zip(real, cal, strict=True)]
    out.append(Claim("Bo105 Bayes calibration: posterior means within 2 % of the true means "
                     "(table 3.9)", _count(rel_err("ours"), lambda e: e <= 0.02),
                     _count(rel_err("thesis"), lambda e: e <= 0.02)))

    t = by["3.6"]
    def top(which):
        v = _col(t, 0, which)
        if any(x is None for x in v):
            return None
        return (int(np.argmax(v) == 0), 1)
    out.append(Claim("Bo105 mixed sensitivity: C_La(0.3) has the largest main index of the "
                     "mean thrust (table 3.6)", top("ours"), top("thesis")))

    for num, what in (("3.11", "mixed"), ("3.13", "aerodynamic")):
        t = by[num]
        def std_err(which, t=t):
            target = _col(t, 1, which)
            got = _col(t, 3, which)
            if any(v is None for v in target + got):
                return [None] * len(target)
            return [abs(g - s) / abs(s) for s, g in zip(target, got, strict=True)]
        out.append(Claim(f"Bo105 CUU ({what}): load std devs reproduced within 5 % "
                         f"(table {num})", _count(std_err("ours"), lambda e: e <= 0.05),
                         _count(std_err("thesis"), lambda e: e <= 0.05)))

    for num, where in (("4.12", "at 4R"), ("4.16", "at 2R"), ("4.17", "at 1R")):
        t = by[num]
        out.append(Claim(f"GVPM: measured loads within one posterior-predictive std {where} "
                         f"(table {num})", _count(_col(t, 3, "ours"), lambda v: v <= 1.0),
                         _count(_col(t, 3, "thesis"), lambda v: v <= 1.0)))

    t = by["4.14"]
    def cuu4(which):
        target, got = _col(t, 1, which), _col(t, 2, which)
        if any(v is None for v in target + got):
            return [None] * len(target)
        return [abs(g - s) / abs(s) for s, g in zip(target, got, strict=True)]
    out.append(Claim("GVPM CUU on the commands: load std devs within 10 % of the targets "
                     "(table 4.14)", _count(cuu4("ours"), lambda e: e <= 0.10),
                     _count(cuu4("thesis"), lambda e: e <= 0.10)))

    for num, name in (("4.18", "C_T"), ("4.19", "C_Q")):
        t = by[num]
        def monotone(which, t=t):
            m = _col(t, 0, which)  # rows 4R, 3R, 2R, 1R
            if any(v is None for v in m):
                return None
            return (int(m[3] > m[2] > m[0]), 1)
        out.append(Claim(f"Ground effect: model {name} ratio grows from 4R to 2R to 1R "
                         f"(table {num})", monotone("ours"), monotone("thesis")))
        out.append(Claim(f"Ground effect: measured {name} ratio within 3 model std devs at "
                         f"every height (table {num}, figure 4.3{5 if name == 'C_T' else 6})",
                         _count(_col(t, 3, "ours"), lambda v: v <= 3.0),
                         _count(_col(t, 3, "thesis"), lambda v: v <= 3.0)))
    return out
