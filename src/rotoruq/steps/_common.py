"""Helpers several step adapters share: moments of sampled columns, the input distributions'
summary, added measurement noise, per-response noise levels, and a saved record or None."""

from __future__ import annotations

import inspect
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from scipy import stats

from ..errors import ParameterError
from ..params import ParameterSpace
from ..render.tables import StepTable, levels_tables
from ..results import RecordError, StepRecord, StepResult
from .base import StepContext

__all__ = ["named_model", "column_moments", "stats_scalars", "input_arrays", "input_scalars",
           "noise", "per_response", "saved_record", "MOMENT_KEYS", "LevelsRecord", "levels_arrays"]

R = TypeVar("R", bound=StepRecord)

#: The statistics of :func:`column_moments`, in its row order (their scalar key prefixes).
MOMENT_KEYS = ("mean", "std", "skewness", "kurtosis")


def column_moments(values: np.ndarray) -> np.ndarray:
    """Mean, std (ddof=1), skewness and excess kurtosis (both bias-corrected) of each column
    of ``values`` (n, m) over its finite entries: shape (4, m), rows in :data:`MOMENT_KEYS`
    order. NaN where a column has fewer than 2 finite values (all four) or fewer than 4 or no
    spread (skewness and kurtosis).

    Examples
    --------
    >>> import numpy as np
    >>> column_moments(np.array([[1.0, 5.0], [3.0, np.nan]])).round(3).tolist()
    [[2.0, nan], [1.414, nan], [nan, nan], [nan, nan]]
    """
    out = np.full((4, values.shape[1]), np.nan)
    for j in range(values.shape[1]):
        v = values[:, j]
        v = v[np.isfinite(v)]
        if v.size < 2:
            continue
        out[0, j] = float(np.mean(v))
        out[1, j] = float(np.std(v, ddof=1))
        if v.size > 3 and np.std(v) > 0:
            out[2, j] = float(stats.skew(v, bias=False))
            out[3, j] = float(stats.kurtosis(v, bias=False))
    return out


def stats_scalars(prefix_names: Sequence[str], values: np.ndarray, suffix: str = "",
                  moments: np.ndarray | None = None) -> dict:
    """The flat view of :func:`column_moments` (or of ``moments``, its result for
    ``values``): ``mean/<name><suffix>``, ``std/...``, ``skewness/...``, ``kurtosis/...`` of
    each column, leaving out what it could not compute."""
    mom = column_moments(values) if moments is None else moments
    return {f"{key}/{name}{suffix}": float(mom[i, j])
            for j, name in enumerate(prefix_names)
            for i, key in enumerate(MOMENT_KEYS) if not np.isnan(mom[i, j])}


def input_arrays(space: ParameterSpace) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                 np.ndarray]:
    """Mean, std, lower and upper bound (d,) of each input distribution (bounds NaN unless
    both are finite), for a record's ``input_mean``, ``input_std``, ``input_lower``,
    ``input_upper``."""
    mean = np.array([d.mean for d in space.distributions], dtype=float)
    std = np.array([d.std for d in space.distributions], dtype=float)
    lower, upper = np.full(len(mean), np.nan), np.full(len(mean), np.nan)
    for j, d in enumerate(space.distributions):
        lo, hi = d.bounds
        if np.isfinite(lo) and np.isfinite(hi):
            lower[j], upper[j] = lo, hi
    return mean, std, lower, upper


def input_scalars(space: ParameterSpace) -> dict:
    """The flat view of :func:`input_arrays`: ``input_mean/``, ``input_std/`` and, for
    bounded inputs, ``input_lower/``, ``input_upper/`` of each input."""
    mean, std, lower, upper = input_arrays(space)
    out = {}
    for j, name in enumerate(space.names):
        out[f"input_mean/{name}"] = float(mean[j])
        out[f"input_std/{name}"] = float(std[j])
        if not np.isnan(lower[j]):
            out[f"input_lower/{name}"] = float(lower[j])
            out[f"input_upper/{name}"] = float(upper[j])
    return out


def saved_record(kind: type[R], res: StepResult) -> R | None:
    """The ``kind`` record saved with ``res``, None for a result saved before its type had
    one (its tables say so; a warning hook then has nothing to read)."""
    try:
        return kind.read(res)
    except RecordError:
        return None


def noise(ctx: StepContext, noise_std, shape) -> np.ndarray:
    """Gaussian noise of shape ``shape`` (n, m) with std ``noise_std`` (a number or a table
    per response; zeros without one), drawn from the step's generator."""
    if not noise_std:
        return np.zeros(shape)
    if isinstance(noise_std, Mapping):
        sd = np.array([float(noise_std.get(r, 0.0)) for r in ctx.responses])
    else:
        sd = np.full(shape[1], float(noise_std))
    return ctx.rng.normal(size=shape) * sd


def named_model(ctx: StepContext, name: str):
    """The study's ``[models.NAME]`` model ``name`` on the step's inputs, responses and fixed
    inputs (``ctx.make_model(..., model=NAME)``); a clear error when the runner's factory
    builds only ``[model]``."""
    params = inspect.signature(ctx.make_model).parameters
    if "model" not in params and not any(p.kind is p.VAR_KEYWORD for p in params.values()):
        raise ParameterError(
            f"step {ctx.name!r}: the model {name!r} needs a model factory that builds named "
            "models (make_model(inputs, responses, fixed, model=NAME)); this study runner "
            "builds only [model]")
    return ctx.make_model(ctx.space.names, ctx.responses, dict(ctx.fixed), model=name)


def per_response(value, responses):
    """A table of per-response values as an array in ``responses`` order (else unchanged)."""
    if value is None or not isinstance(value, Mapping):
        return value
    return np.array([float(value[r]) for r in responses])


@dataclass(frozen=True, eq=False)
class LevelsRecord(StepRecord):
    """Base of the records of per-level results (reliability, evidence): m responses,
    q quantities, up to L levels.

    names_out (m); quantities (q) : what each row of ``values`` holds (``"response_levels"``,
    ``"cdf_probability"``, ...); values (q, m, L) : each quantity's values over the levels
    of each response, NaN past its count; counts (q, m) : the levels of each (0: not
    computed for that response).
    """

    AXES = {"values": ("quantity", "response", "level"), "counts": ("quantity", "response")}

    names_out: tuple[str, ...]
    quantities: tuple[str, ...]
    values: np.ndarray
    counts: np.ndarray

    def scalars(self) -> dict[str, float]:
        """The flat view: ``<quantity>/<response>/<level index>``."""
        return {f"{q}/{r}/{i}": float(self.values[a, k, i])
                for k, r in enumerate(self.names_out) for a, q in enumerate(self.quantities)
                for i in range(int(self.counts[a, k]))}

    def tables(self, title: str) -> list[StepTable]:
        """One table per response of its levels."""
        return levels_tables(self.names_out, self.quantities, self.values, self.counts, title)


def levels_arrays(result: object, quantities: Sequence[str], responses: Sequence[str]
                  ) -> tuple[np.ndarray, np.ndarray]:
    """``values`` (q, m, L) and ``counts`` (q, m) of a :class:`LevelsRecord` from a method
    result whose attribute of each quantity maps response -> values over the levels (a
    missing attribute or response: count 0)."""
    def one(q: str, r: str) -> np.ndarray:
        v = (getattr(result, q, None) or {}).get(r)
        return np.zeros(0) if v is None else np.atleast_1d(np.asarray(v, dtype=float))

    got = [[one(q, r) for r in responses] for q in quantities]
    counts = np.array([[a.size for a in row] for row in got], dtype=int).reshape(
        len(quantities), len(responses))
    values = np.full((len(quantities), len(responses), int(counts.max(initial=0))), np.nan)
    for i, row in enumerate(got):
        for k, a in enumerate(row):
            values[i, k, :a.size] = a
    return values, counts
