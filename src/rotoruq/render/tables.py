"""A result table as plain data (:class:`StepTable`), and the small readers the step types'
table renderers share: a scalar or None, a display label, a step's responses and inputs."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..results import StepResult
from .figures import UNKNOWN_UNIT, unit_of

__all__ = ["StepTable", "Cell", "make_table", "value", "label", "responses",
           "parameters", "cell", "moments_rows", "inputs_table", "levels_tables",
           "level_mapping_tables", "LEVEL_COLUMNS", "MOMENTS",
           "with_unit", "cv_or_none", "CV_MIN_MEAN_OVER_STD"]

Cell = float | str | None


@dataclass(frozen=True)
class StepTable:
    """title; columns (header of each column, the first names the rows); rows of cells
    (floats, text or None for "not available"); note: how to read it."""

    title: str
    columns: tuple[str, ...]
    rows: tuple[tuple[Cell, ...], ...]
    note: str = ""

    def as_dict(self) -> dict:
        def clean(v):
            if isinstance(v, float) and not math.isfinite(v):
                return None if math.isnan(v) else repr(v)
            return v

        return {"title": self.title, "columns": list(self.columns),
                "rows": [[clean(v) for v in r] for r in self.rows], "note": self.note}


def make_table(title, columns, rows, note="") -> StepTable:
    """A :class:`StepTable` from any sequences."""
    return StepTable(title, tuple(columns), tuple(tuple(r) for r in rows), note)


def value(res: StepResult, key: str) -> float | None:
    """Scalar ``key`` of ``res`` as a float, None when the step did not save it."""
    v = res.scalars.get(key)
    return None if v is None else float(v)




def label(p: str, labels: Mapping[str, str]) -> str:
    """Display label of name ``p``."""
    return labels.get(p) or p


def with_unit(name: str, labels: Mapping[str, str] | None = None,
              units: Mapping[str, str] | None = None) -> str:
    """Display label of ``name`` with its unit, ``"thrust [N]"``; the label alone when the
    unit is not known (a model's own response) or the name is a derived one such as
    ``noisy_thrust`` (then the unit of ``thrust``).

    Parameters
    ----------
    name : str
        Input or response name.
    labels, units : mapping, optional
        Display labels and units by name (a study file's ``label`` and ``unit``).

    Returns
    -------
    str
        ``"<label> [<unit>]"`` or ``"<label>"``.

    Examples
    --------
    >>> with_unit("thrust"), with_unit("k_pitch_link", {"k_pitch_link": "K_p"})
    ('thrust [N]', 'K_p [N]')
    >>> with_unit("y1")
    'y1'
    """
    base = name[len("noisy_"):] if name.startswith("noisy_") else name
    u = unit_of(base, units)
    text = label(name, labels or {})
    return text if u == UNKNOWN_UNIT else f"{text} [{u}]"


#: The coefficient of variation std / |mean| is printed only where |mean| is at least this
#: fraction of std: below it the mean is zero within its spread, and the ratio (656, 1930 in
#: an earlier report) measures how close to zero the mean happens to fall, not the spread.
CV_MIN_MEAN_OVER_STD = 1e-2


def cv_or_none(mean: float, std: float) -> float | None:
    """The coefficient of variation std / |mean| [-], or None (not printed) when |mean| is
    below :data:`CV_MIN_MEAN_OVER_STD` times std (a mean that is zero within its spread).

    Parameters
    ----------
    mean, std : float
        Mean and standard deviation of one quantity (same unit).

    Returns
    -------
    float or None

    Examples
    --------
    >>> cv_or_none(25.0, 1.0)
    0.04
    >>> cv_or_none(1e-4, 1.0) is None
    True
    >>> cv_or_none(3.0, 0.0)
    0.0
    """
    mean, std = float(mean), float(std)
    if not (math.isfinite(mean) and math.isfinite(std)):
        return None
    if abs(mean) < CV_MIN_MEAN_OVER_STD * std or (mean == 0.0):
        return None
    return std / abs(mean)


def responses(res: StepResult) -> list[str]:
    """The step's response names (``meta["responses"]``)."""
    return list(res.meta.get("responses") or [])


def parameters(res: StepResult) -> list[str]:
    """The step's input names (``meta["parameters"]`` or ``meta["inputs"]``)."""
    return list(res.meta.get("parameters") or res.meta.get("inputs") or [])


MOMENTS = ("mean", "std", "skewness", "excess kurtosis")


def cell(v: float) -> float | None:
    """A record's number as a table cell: None ("not available") for NaN, the record's mark
    of a value the step did not compute."""
    v = float(v)
    return None if math.isnan(v) else v


def moments_rows(names: Sequence[str], moments: np.ndarray, labels=None):
    """Rows name [unit of mean and std], mean, std, skewness, excess kurtosis of ``names``
    from ``moments`` (4, len(names)) in :data:`MOMENTS` order (NaN: not computed)."""
    labels = labels or {}
    return [[with_unit(n, labels), *[cell(moments[i, j]) for i in range(4)]]
            for j, n in enumerate(names)]


def inputs_table(names: Sequence[str], mean: np.ndarray, std: np.ndarray, lower: np.ndarray,
                 upper: np.ndarray, labels) -> StepTable:
    """The step's input distributions: mean, std and bounds (d,) of each input (NaN bounds:
    unbounded)."""
    return make_table("Input distributions", ("input", "mean", "std", "lower", "upper"),
                      [[with_unit(p, labels), cell(mean[j]), cell(std[j]), cell(lower[j]),
                        cell(upper[j])] for j, p in enumerate(names)])


def levels_tables(names: Sequence[str], quantities: Sequence[str], values: np.ndarray,
                  counts: np.ndarray, title: str) -> list[StepTable]:
    """One table per response of per-level values: ``values`` (quantity, response, level)
    with ``counts`` (quantity, response) levels each (0: the quantity was not computed for
    that response); rows past a quantity's count are empty cells."""
    out = []
    for k, r in enumerate(names):
        present = [q for q in range(len(quantities)) if counts[q, k] > 0]
        if not present:
            continue
        n = max(int(counts[q, k]) for q in present)
        out.append(make_table(f"{title}: {with_unit(r)}",
                              ("level", *[quantities[q].replace("_", " ") for q in present]),
                              [[i + 1, *[float(values[q, k, i]) if i < counts[q, k] else None
                                         for q in present]] for i in range(n)]))
    return out


#: Dakota's headings of a level mapping's columns (methods.levels.COLUMNS; spelled out so that
#: rendering does not import the methods).
LEVEL_COLUMNS = ("Response Level", "Probability Level", "Reliability Index",
                 "General Rel Index")


def level_mapping_tables(names: Sequence[str], values: np.ndarray, kinds: np.ndarray,
                         distribution: str, note: str = "") -> list[StepTable]:
    """Dakota's "Level mappings" tables, one per response with levels: ``values`` (response,
    level, column) rows of response level, probability, reliability and generalized
    reliability index (NaN: not computed, an empty cell), ``kinds`` (response, level) the
    requested column of each row (-1 past the response's count); ``distribution`` "cdf" or
    "ccdf" names the table as Dakota does."""
    what = ("Cumulative Distribution Function (CDF)" if distribution == "cdf" else
            "Complementary Cumulative Distribution Function (CCDF)")
    out = []
    for k, r in enumerate(names):
        rows = [[None if math.isnan(v) else float(v) for v in values[k, i]]
                for i in range(kinds.shape[1]) if kinds[k, i] >= 0]
        if rows:
            out.append(make_table(f"Level mappings: {what} for {with_unit(r)}",
                                  LEVEL_COLUMNS, rows, note))
    return out
