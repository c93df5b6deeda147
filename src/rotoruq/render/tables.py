"""A result table as plain data (:class:`StepTable`), and the small readers the step types'
table renderers share: a scalar or None, a display label, a step's responses and inputs."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from ..results import StepResult

__all__ = ["StepTable", "Cell", "make_table", "value", "label", "responses", "parameters",
           "moments_rows", "inputs_table", "levels_tables", "MOMENTS"]

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


def responses(res: StepResult) -> list[str]:
    """The step's response names (``meta["responses"]``)."""
    return list(res.meta.get("responses") or [])


def parameters(res: StepResult) -> list[str]:
    """The step's input names (``meta["parameters"]`` or ``meta["inputs"]``)."""
    return list(res.meta.get("parameters") or res.meta.get("inputs") or [])


MOMENTS = ("mean", "std", "skewness", "excess kurtosis")


def moments_rows(res: StepResult, names: Sequence[str], suffix: str = "", labels=None):
    """Rows name, mean, std, skewness, excess kurtosis of ``names`` (keys ``mean/<n><suffix>``
    and so on)."""
    labels = labels or {}
    return [[label(n, labels), value(res, f"mean/{n}{suffix}"), value(res, f"std/{n}{suffix}"),
             value(res, f"skewness/{n}{suffix}"), value(res, f"kurtosis/{n}{suffix}")]
            for n in names]


def inputs_table(res: StepResult, labels) -> StepTable:
    """The step's input distributions (``input_mean/``, ``input_std/``, bounds)."""
    return make_table("Input distributions", ("input", "mean", "std", "lower", "upper"),
                      [[label(p, labels), value(res, f"input_mean/{p}"),
                        value(res, f"input_std/{p}"), value(res, f"input_lower/{p}"),
                        value(res, f"input_upper/{p}")] for p in parameters(res)])


def levels_tables(res: StepResult, whats: Sequence[str], title: str) -> list[StepTable]:
    """One table per response of per-level values ``<what>/<response>/<i>``."""
    out = []
    for r in responses(res):
        n = max([int(k.rsplit("/", 1)[1]) + 1 for k in res.scalars
                 if k.split("/")[0] in whats and k.split("/")[1] == r] or [0])
        if n == 0:
            continue
        present = [w for w in whats if f"{w}/{r}/0" in res.scalars]
        out.append(make_table(f"{title}: {r}", ("level", *[w.replace("_", " ") for w in present]),
                              [[i + 1, *[value(res, f"{w}/{r}/{i}") for w in present]]
                               for i in range(n)]))
    return out
