"""Helpers several step adapters share: moments of sampled columns, the input distributions'
summary, added measurement noise, per-response noise levels, and a saved record or None."""

from __future__ import annotations

import inspect
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from .._lazy import lazy_module
from ..errors import ParameterError
from ..params import ParameterSpace
from ..render.tables import StepTable, level_mapping_tables, levels_tables
from ..results import RecordError, StepRecord, StepResult
from .base import StepCheck, StepContext
from .options import SIGNATURE, Option, choice, table

if TYPE_CHECKING:
    from scipy import stats
else:
    stats = lazy_module("scipy.stats")

__all__ = ["named_model", "deferred_writes", "chain_on_model", "column_moments", "input_arrays",
           "noise", "per_response", "saved_record", "MOMENT_KEYS", "LevelsRecord", "levels_arrays",
           "LEVEL_OPTIONS", "LEVEL_TABLES", "MappingsRecord", "check_levels",
           "level_request_of", "mapping_fields"]

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


@contextmanager
def deferred_writes(model: Any, seconds: float = 1.0) -> Iterator[None]:
    """Within the block, a store-backed ``model`` commits its evaluations at most every
    ``seconds`` (:meth:`rotoruq.evaluation.evaluator.Evaluator.deferred_writes`): for a
    Markov chain on the model itself, thousands of calls of a few points each. Any other
    model is used as it is."""
    defer = getattr(model, "deferred_writes", None)
    with defer(seconds) if callable(defer) else nullcontext():
        yield


@contextmanager
def chain_on_model(model: Any, seconds: float = 1.0) -> Iterator[None]:
    """Within the block, Markov chains run on ``model`` itself: a store-backed in-process
    model is evaluated without the store
    (:meth:`rotoruq.evaluation.evaluator.Evaluator.unstored`: its proposals are not worth a
    row each), an external solver commits its evaluations at most every ``seconds``
    (:func:`deferred_writes`). Any other model is used as it is."""
    unstored = getattr(model, "unstored", None)
    with deferred_writes(model, seconds), unstored() if callable(unstored) else nullcontext():
        yield


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
    # the flat view: ``<quantity>/<response>/<level index>``
    FLAT = {"values": "", "counts": None}
    LABELS = {"quantity": "quantities"}

    names_out: tuple[str, ...]
    quantities: tuple[str, ...]
    values: np.ndarray
    counts: np.ndarray

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


# ---------------------------------------------------------------------------------------------
# Level mappings (Dakota's response / probability / reliability / generalized reliability
# levels): the options, their study-file check, the record fields and tables
# ---------------------------------------------------------------------------------------------
_LEVELS = "rotoruq.methods.levels:level_request"
#: The level tables (response -> list of numbers) a step type with level mappings takes.
LEVEL_TABLES = ("response_levels", "probability_levels", "reliability_levels",
                "gen_reliability_levels")
#: The options of level mappings: the four level tables, ``distribution`` (what a probability
#: is: ``"cdf"`` P(g <= z) or ``"ccdf"`` P(g > z)) and ``compute`` (what response levels map
#: to), defaults from :func:`rotoruq.methods.levels.level_request`.
LEVEL_OPTIONS = {
    **{k: Option(table, SIGNATURE, method=_LEVELS) for k in LEVEL_TABLES},
    "distribution": Option(choice("cdf", "ccdf"), SIGNATURE, method=_LEVELS),
    "compute": Option(choice("probabilities", "reliabilities", "gen_reliabilities"), SIGNATURE,
                      method=_LEVELS)}
#: The mapping keys on the flat view, in :data:`rotoruq.methods.levels.KINDS` order.
_COLUMN_KEYS = ("response", "probability", "reliability", "gen_reliability")


def check_levels(c: StepCheck, tables: Sequence[str] = LEVEL_TABLES,
                 compute: Sequence[str] = ("probabilities", "reliabilities",
                                           "gen_reliabilities")) -> None:
    """The study-file check of level mappings: each of ``tables`` keyed by the step's
    responses with a list of numbers (probabilities in [0, 1]); ``compute`` one of
    ``compute`` and, other than probabilities, with response levels."""
    o = c.options
    allowed = tuple(c.responses or c.model.responses)
    for key in LEVEL_TABLES:
        tbl = o.get(key)
        if tbl is None:
            continue
        if key not in tables:
            c.fail((key,), f"no {key} in a step of this type (it takes "
                   f"{', '.join(tables)})", key)
        for r, v in tbl.items():
            if r not in allowed:
                c.fail((key, r), f"{key} keyed by the step's responses ({', '.join(allowed)})",
                       r)
            vals = v if isinstance(v, list) else [v]
            if not vals or not all(isinstance(x, int | float) and not isinstance(x, bool)
                                   and np.isfinite(x) for x in vals):
                c.fail((key, r), f"{r} = [level, ...], a list of finite numbers", repr(v))
            if key == "probability_levels" and any(not 0 <= x <= 1 for x in vals):
                c.fail((key, r), "probability levels from 0 to 1", repr(v))
    comp = o.get("compute", "probabilities")
    if comp not in compute:
        c.fail(("compute",), f"compute = {' or '.join(repr(x) for x in compute)} in a step of "
               "this type", comp)
    if comp != "probabilities" and o.get("response_levels") is None:
        c.fail(("compute",), "compute with response_levels (it says what response levels map "
               "to)", comp)


def level_request_of(ctx: StepContext) -> Any:
    """The step's :class:`~rotoruq.methods.levels.LevelRequest` from its level options, None
    when it asks for no level."""
    from ..methods.levels import level_request

    o = ctx.options
    if all(o.get(k) is None for k in LEVEL_TABLES):
        return None
    return level_request(ctx.responses, **{k: o.get(k) for k in LEVEL_TABLES},
                         distribution=o.get("distribution", "cdf"),
                         compute=o.get("compute", "probabilities"))


def _no_mappings() -> np.ndarray:
    return np.zeros((0, 0, 4))


def _no_kinds() -> np.ndarray:
    return np.zeros((0, 0), dtype=int)


@dataclass(frozen=True, eq=False)
class MappingsRecord(StepRecord):
    """Base of the records of step types with level mappings (keyword fields, so a subclass
    declares its own fields as before; a record saved before they existed reads as none).

    level_mappings (m, L, 4) : each response's rows of response level, probability,
    reliability and generalized reliability index, as Dakota prints them (NaN: not
    computed); level_kinds (m, L) : the requested column of each row (0 response, 1
    probability, 2 reliability, 3 generalized reliability level; -1 past its count);
    level_distribution : "cdf" or "ccdf"; level_compute : what response levels map to.
    A subclass extends ``AXES``, ``FLAT`` and ``LABELS`` with its own
    (``{**MappingsRecord.AXES, ...}``).
    """

    AXES = {"level_mappings": ("response", "level", "column"),
            "level_kinds": ("response", "level")}
    # the flat view: ``level/<response>/<row>/<column>`` of every computed cell (columns
    # ``response``, ``probability``, ``reliability``, ``gen_reliability``)
    FLAT = {"level_mappings": "level", "level_kinds": None}
    LABELS = {"column": _COLUMN_KEYS}

    level_mappings: np.ndarray = field(default_factory=_no_mappings, kw_only=True)
    level_kinds: np.ndarray = field(default_factory=_no_kinds, kw_only=True)
    level_distribution: str = field(default="cdf", kw_only=True)
    level_compute: str = field(default="probabilities", kw_only=True)

    def mapping_tables(self, names_out: Sequence[str], note: str = "") -> list[StepTable]:
        """Dakota's "Level mappings" tables of the record (none without levels)."""
        if self.level_kinds.size == 0:
            return []
        return level_mapping_tables(names_out, self.level_mappings, self.level_kinds,
                                    self.level_distribution, note)


def mapping_fields(mappings: Any) -> dict[str, Any]:
    """The :class:`MappingsRecord` keyword fields of a
    :class:`~rotoruq.methods.levels.LevelMappings` (none for None)."""
    if mappings is None:
        return {}
    values, kinds = mappings.arrays()
    return {"level_mappings": values, "level_kinds": kinds,
            "level_distribution": mappings.distribution, "level_compute": mappings.compute}


