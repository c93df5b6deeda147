"""Study files: TOML -> validated, frozen dataclasses.

A study file declares the model, the uncertain parameters, the data and an ordered list of
steps::

    [study]
    name = "quick"
    seed = 1
    output = "rotoruq-results/quick"       # relative to the study file

    [model]
    preset = "gvpm"                          # or: command = ["python", "driver.py"] (external)
    responses = ["thrust", "power"]
    fixed = { collective_deg = 5.4, height_over_radius = 4.0 }

    [parameters.cla_m03]
    distribution = "normal"
    mean = 0.108
    std = 5.4e-3

    [data.measured]
    file = "gvpm_measurements.csv"           # or inline columns: thrust = [25.68, ...]
    select = { height_over_radius = 4.0 }

    [[steps]]
    name = "bayes"
    type = "bayes_calibration"
    data = "measured"

    [[steps]]
    name = "forward"
    type = "sampling"
    from = "bayes.posterior"                 # distributions from an earlier step

:func:`load_study` raises :class:`rotoruq.errors.InputFileError` naming the file, the line and
the expected form for every problem; unknown keys come with the closest valid key.
"""

from __future__ import annotations

import csv
import difflib
import math
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputFileError, ParameterError
from ..params import DISTRIBUTIONS, Distribution, ParameterSpace, make_distribution
from ..rotor.model import RESPONSES, ROTOR_INPUTS

__all__ = [
    "STEP_TYPES",
    "ROTOR_RESPONSES",
    "Study",
    "StudyInfo",
    "ModelSpec",
    "ExternalSpec",
    "ParameterSpec",
    "DataSet",
    "ExecutorSpec",
    "StoreSpec",
    "StepSpec",
    "load_study",
    "parse_study",
    "rotor_input_names",
    "is_rotor_input",
]

ROTOR_RESPONSES = RESPONSES
_ROTOR_INPUTS = ROTOR_INPUTS
# Airfoil perturbations exist at every Mach row of the table: cla_m03, cl0_m00, cd0_m04 ...
_AIRFOIL_INPUT = re.compile(r"^(cla|cl0|cd0|cda|cda2)_m\d\d$")


def rotor_input_names() -> tuple[str, ...]:
    """Input names of the rotor model (from :mod:`rotoruq.rotor` when it lists them)."""
    try:  # the rotor module is the authority when it publishes its vocabulary
        from ..rotor import model as rotor_model

        names = getattr(rotor_model, "ROTOR_INPUTS", None)
        if names:
            return tuple(names)
    except ImportError:
        pass
    return _ROTOR_INPUTS


def is_rotor_input(name: str) -> bool:
    return name in rotor_input_names() or name in _ROTOR_INPUTS or bool(_AIRFOIL_INPUT.match(name))


# ---------------------------------------------------------------------------------------------
# Where things are in the file: tomllib reports no positions for semantic errors.
# ---------------------------------------------------------------------------------------------
_HEADER_ARRAY = re.compile(r"^\s*\[\[\s*([^\]]+?)\s*\]\]")
_HEADER_TABLE = re.compile(r"^\s*\[\s*([^\]]+?)\s*\]")
_BARE = r"""(?:[A-Za-z0-9_\-]+|"[^"]*"|'[^']*')"""
_KEY = re.compile(rf"^\s*({_BARE}(?:\s*\.\s*{_BARE})*)\s*=")
_INLINE_KEY = re.compile(r"""[{,]\s*([A-Za-z0-9_\-]+|"[^"]*")\s*=""")


def _split_key(text: str) -> tuple[str, ...]:
    parts = re.findall(r"""[A-Za-z0-9_\-]+|"[^"]*"|'[^']*'""", text)
    return tuple(p.strip("\"'") for p in parts)


class Locator:
    """Maps key paths of a TOML document to 1-based line numbers.

    Paths are tuples such as ``("parameters", "kp", "std")`` or ``("steps", 2, "from")``
    (array-of-tables entries are indexed from 0). :meth:`line` falls back to the longest
    known prefix, so any path gets the line of the nearest enclosing table.
    """

    def __init__(self, text: str):
        self.lines: dict[tuple, int] = {}
        counts: dict[tuple, int] = {}
        current: tuple = ()
        in_string = False
        for no, raw in enumerate(text.splitlines(), start=1):
            if raw.count('"""') % 2 == 1 or raw.count("'''") % 2 == 1:
                in_string = not in_string
                if not in_string:
                    continue
            if in_string:
                continue
            line = raw.split("#", 1)[0] if '"' not in raw and "'" not in raw else raw
            m = _HEADER_ARRAY.match(line)
            if m:
                base = self._in_array(_split_key(m.group(1)), counts)
                idx = counts.get(base, 0)
                counts[base] = idx + 1
                current = base + (idx,)
                self.lines.setdefault(current, no)
                continue
            m = _HEADER_TABLE.match(line)
            if m:
                current = self._in_array(_split_key(m.group(1)), counts)
                self.lines.setdefault(current, no)
                continue
            m = _KEY.match(line)
            if m:
                key = current + _split_key(m.group(1))
                self.lines.setdefault(key, no)
                rest = line[m.end():]
                if "{" in rest:
                    for k in _INLINE_KEY.findall(rest[rest.index("{"):]):
                        self.lines.setdefault(key + (k.strip("\"'"),), no)

    @staticmethod
    def _in_array(parts: tuple, counts: dict) -> tuple:
        """``[steps.x]`` after ``[[steps]]`` belongs to the last ``steps`` entry."""
        for k in range(len(parts) - 1, 0, -1):
            head = parts[:k]
            if head in counts:
                return head + (counts[head] - 1,) + parts[k:]
        return parts

    def line(self, *path) -> int | None:
        path = tuple(path)
        while path:
            if path in self.lines:
                return self.lines[path]
            path = path[:-1]
        return None


# ---------------------------------------------------------------------------------------------
# Result dataclasses
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StudyInfo:
    """``[study]``: name, seed (int), output directory (absolute), free-text description."""

    name: str
    seed: int
    output: Path
    description: str = ""


@dataclass(frozen=True)
class ExternalSpec:
    """An external solver driven through Dakota's fork contract (``driver params results``)."""

    command: tuple[str, ...]
    files: tuple[str, ...] = ()
    templates: tuple[str, ...] = ()
    parameters_format: str = "standard"
    timeout: float | None = None
    failure: str = "abort"
    retries: int = 0
    recover: tuple[float, ...] | None = None
    workdir: str | None = None


@dataclass(frozen=True)
class ModelSpec:
    """``[model]``: a rotor preset (``kind="preset"``) or an external driver."""

    kind: str
    responses: tuple[str, ...]
    fixed: Mapping[str, float]
    preset: str | None = None
    preset_options: Mapping[str, Any] = field(default_factory=dict)
    external: ExternalSpec | None = None


@dataclass(frozen=True)
class ParameterSpec:
    """``[parameters.NAME]``: a named distribution (``distribution`` plus its parameters)."""

    name: str
    kind: str
    params: Mapping[str, float]
    distribution: Distribution
    line: int | None = None
    label: str = ""
    unit: str = ""


@dataclass(frozen=True)
class DataSet:
    """``[data.NAME]``: columns of observations, each an array of shape (k,)."""

    name: str
    columns: Mapping[str, np.ndarray]
    source: str

    @property
    def n(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0

    def matrix(self, names: Sequence[str]) -> np.ndarray:
        """Observations as an array (k, len(names)) in the order of ``names``."""
        missing = [n for n in names if n not in self.columns]
        if missing:
            raise ParameterError(
                f"data set {self.name!r} has no column(s) {missing}; it has {list(self.columns)}"
            )
        return np.column_stack([self.columns[n] for n in names])


@dataclass(frozen=True)
class ExecutorSpec:
    """``[executor]``: ``kind`` in serial / processes / dask; ``workers``; dask ``scheduler``."""

    kind: str = "serial"
    workers: int | None = None
    scheduler: str | None = None


@dataclass(frozen=True)
class StoreSpec:
    """``[store]``: SQLite evaluation store (``path`` relative to the output dir)."""

    enabled: bool = True
    path: str = "evaluations.sqlite"


@dataclass(frozen=True)
class StepSpec:
    """One ``[[steps]]`` entry.

    ``source`` is the ``from`` reference as ``(step, attribute)``; ``parameters`` /
    ``responses`` restrict the study's sets (None: all); ``distributions`` replaces (or adds)
    the distributions of some inputs for this step only; ``fixed`` adds fixed model inputs
    for this step; ``options`` holds the type-specific options with defaults filled in.
    """

    name: str
    type: str
    index: int
    options: Mapping[str, Any]
    source: tuple[str, str] | None = None
    parameters: tuple[str, ...] | None = None
    responses: tuple[str, ...] | None = None
    fixed: Mapping[str, float] = field(default_factory=dict)
    data: str | None = None
    title: str = ""
    quick: Mapping[str, Any] = field(default_factory=dict)
    line: int | None = None
    distributions: tuple[ParameterSpec, ...] = ()


@dataclass(frozen=True)
class Study:
    """A validated study. ``parameters`` is ordered as in the file."""

    path: Path
    info: StudyInfo
    model: ModelSpec
    parameters: tuple[ParameterSpec, ...]
    data: Mapping[str, DataSet]
    executor: ExecutorSpec
    store: StoreSpec
    steps: tuple[StepSpec, ...]
    text: str = ""

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    def parameter(self, name: str) -> ParameterSpec:
        for p in self.parameters:
            if p.name == name:
                return p
        raise ParameterError(f"study {self.info.name!r} has no parameter {name!r}")

    def space(self, names: Sequence[str] | None = None) -> ParameterSpace:
        """ParameterSpace of the named parameters (all when None), in the given order."""
        names = self.parameter_names if names is None else tuple(names)
        return ParameterSpace([(n, self.parameter(n).distribution) for n in names])

    def step(self, name: str) -> StepSpec:
        for s in self.steps:
            if s.name == name:
                return s
        raise ParameterError(f"study {self.info.name!r} has no step {name!r}")


# ---------------------------------------------------------------------------------------------
# Key schemas. Each option: (checker, default). ``_REQUIRED`` marks options without default.
# ---------------------------------------------------------------------------------------------
_REQUIRED = object()


def _int(minimum: int = 0, maximum: int = 2**63 - 1):
    def check(v):
        if isinstance(v, bool) or not isinstance(v, int) or v < minimum:
            raise TypeError(f"an integer >= {minimum}")
        if v > maximum:
            raise TypeError(f"an integer from {minimum} to {maximum}")
        return v

    return check


def _num(positive: bool = False, allow_zero: bool = True):
    def check(v):
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise TypeError("a finite number")
        if positive and (v < 0 or (v == 0 and not allow_zero)):
            raise TypeError("a number > 0" if not allow_zero else "a number >= 0")
        return float(v)

    return check


def _str(choices: Sequence[str] | None = None):
    def check(v):
        if not isinstance(v, str):
            raise TypeError("a string" + (f" (one of {', '.join(choices)})" if choices else ""))
        if choices is not None and v.lower() not in choices:
            raise TypeError(f"one of {', '.join(repr(c) for c in choices)}")
        return v.lower() if choices is not None else v

    return check


def _strlist(v):
    if isinstance(v, str):
        return (v,)
    if not isinstance(v, list) or not all(isinstance(s, str) for s in v):
        raise TypeError("a list of strings")
    return tuple(v)


def _numlist(v):
    if not isinstance(v, list) or not all(
        isinstance(s, int | float) and not isinstance(s, bool) for s in v
    ):
        raise TypeError("a list of numbers")
    return tuple(float(s) for s in v)


def _table(v):
    if not isinstance(v, dict):
        raise TypeError("a table { key = value, ... }")
    return dict(v)


def _table_or_str(v):
    if isinstance(v, str):
        return v
    return _table(v)


def _num_or_table(v):
    if isinstance(v, dict):
        for x in v.values():
            _num(positive=True)(x)
        return {k: float(x) for k, x in v.items()}
    return _num(positive=True)(v)


def _bool(v):
    if not isinstance(v, bool):
        raise TypeError("true or false")
    return v


_SAMPLING_METHODS = ("lhs", "random", "sobol", "halton")

_COMMON_STEP_KEYS = {
    "name": (_str(), None),
    "type": (_str(), _REQUIRED),
    "from": (_str(), None),
    "parameters": (_strlist, None),
    "responses": (_strlist, None),
    "fixed": (_table, None),
    "data": (_str(), None),
    "title": (_str(), ""),
    "seed": (_int(), None),
    "quick": (_table, None),
    "distributions": (_table, None),
}

STEP_TYPES: dict[str, dict[str, tuple]] = {
    "sampling": {
        "n": (_int(1), 100),
        "method": (_str(_SAMPLING_METHODS), "lhs"),
        "noise_std": (_num_or_table, 0.0),
    },
    "sensitivity": {
        "n": (_int(2), 200),
        "method": (_str(_SAMPLING_METHODS), "lhs"),
    },
    "mean_value": {
        "response_levels": (_table, None),
        "probability_levels": (_table, None),
    },
    "reliability": {
        "integration": (_str(("form", "sorm")), "form"),
        "response_levels": (_table, None),
        "probability_levels": (_table, None),
    },
    "pce": {
        "order": (_int(1), 2),
        "n": (_int(1), None),
    },
    "evidence": {
        "intervals": (_table, _REQUIRED),
        "n": (_int(1), 100),
        "response_levels": (_table, None),
    },
    "bayes_calibration": {
        "sampler": (_str(("dram", "mh", "dr", "am")), "dram"),
        "chain_samples": (_int(10), 100_000),
        "burn_in": (_int(0), 5_000),
        "emulator": (_str(("gp", "none")), "gp"),
        "trend": (_str(("constant", "linear", "reduced_quadratic", "quadratic")),
                  "reduced_quadratic"),
        "build_samples": (_int(2), 500),
        "noise_std": (_num_or_table, None),
        "proposal": (_str(("hessian", "prior")), "hessian"),
    },
    "least_squares": {
        "max_iterations": (_int(1), 100),
        "max_function_evaluations": (_int(1), 1000),
        "convergence_tolerance": (_num(positive=True, allow_zero=False), 1e-4),
        "noise_std": (_num_or_table, None),
    },
    "cuu": {
        "targets": (_table_or_str, _REQUIRED),
        "calibrate": (_str(("std", "mean", "mean_std")), "std"),
        "inner": (_str(("mean_value", "sampling", "pce")), "mean_value"),
        "max_iterations": (_int(1), 100),
        "convergence_tolerance": (_num(positive=True, allow_zero=False), 1e-4),
        "verify_samples": (_int(0), 0),
        "method": (_str(_SAMPLING_METHODS), "lhs"),
    },
    "forward_check": {
        "n": (_int(1), 500),
        "method": (_str(_SAMPLING_METHODS), "lhs"),
        "sweep": (_table, None),
        "match": (_str(), None),
        "normalize_by": (_table, None),
    },
}

# What a step result offers to later steps through ``from = "step.ATTR"`` / ``data = "step.ATTR"``
_PROVIDES = {
    "bayes_calibration": ("posterior",),
    "cuu": ("calibrated",),
    "least_squares": ("calibrated",),
    "sampling": ("samples",),
}

_TOP_KEYS = ("study", "model", "parameters", "data", "executor", "store", "steps")
_STUDY_KEYS = ("name", "seed", "output", "description")
_MODEL_KEYS = (
    "preset", "preset_options", "responses", "fixed",
    "command", "files", "templates", "parameters_format", "timeout", "failure", "retries",
    "recover", "workdir",
)
_DATA_KEYS = ("file", "select", "columns")
_EXECUTOR_KEYS = ("kind", "workers", "scheduler")
_STORE_KEYS = ("enabled", "path")
_PARAM_META = ("distribution", "label", "unit")


# ---------------------------------------------------------------------------------------------
class _Checker:
    def __init__(self, path: Path, text: str):
        self.path = path
        self.loc = Locator(text)

    def fail(self, where: tuple, expected: str, found: str | None = None):
        raise InputFileError(self.path, self.loc.line(*where), expected, found)

    def keys(self, table: Mapping, allowed: Sequence[str], where: tuple, what: str):
        for key in table:
            if key not in allowed:
                close = difflib.get_close_matches(key, list(allowed), n=1, cutoff=0.5)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                self.fail(
                    where + (key,),
                    f"one of the keys of {what}: {', '.join(allowed)}{hint}",
                    key,
                )

    def table(self, value, where: tuple, what: str) -> dict:
        if not isinstance(value, dict):
            self.fail(where, f"{what} to be a table", repr(value))
        return value

    def option(self, table: Mapping, key: str, spec: tuple, where: tuple, what: str):
        check, default = spec
        if key not in table:
            if default is _REQUIRED:
                self.fail(where, f"{what} to define {key!r}", None)
            return default
        try:
            return check(table[key])
        except TypeError as exc:
            self.fail(where + (key,), f"{key!r} of {what} to be {exc}", repr(table[key]))


def load_study(path: str | Path) -> Study:
    """Read and validate a study file. Raises :class:`InputFileError` (file, line, expected)."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputFileError(path, None, "an existing study file", "no such file") from None
    except IsADirectoryError:
        raise InputFileError(path, None, "a study file", "a directory") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise InputFileError(path, line, "UTF-8 text",
                             f"byte 0x{raw[exc.start]:02x} that is not UTF-8") from None
    return parse_study(text, path)


def parse_study(text: str, path: str | Path = "<study>") -> Study:
    """Validate a study given as TOML text. ``path`` anchors relative paths and messages."""
    path = Path(path)
    try:
        doc = tomllib.loads(text)
    except RecursionError:
        raise InputFileError(path, None, "TOML nested at most a few hundred levels deep",
                             "deeper nesting") from None
    except tomllib.TOMLDecodeError as exc:
        m = re.search(r"line (\d+)", str(exc))
        line = int(m.group(1)) if m else None
        reason = re.sub(r"\s*\(at line \d+, column \d+\)", "", str(exc))
        raise InputFileError(path, line, "valid TOML", reason) from None
    ck = _Checker(path, text)
    base = path.parent if path.name != "<study>" else Path.cwd()
    ck.keys(doc, _TOP_KEYS, (), "a study file")

    info = _parse_info(ck, doc, base, path)
    model = _parse_model(ck, doc)
    params = _parse_parameters(ck, doc, model)
    data = _parse_data(ck, doc, base)
    executor, store = _parse_exec_store(ck, doc)
    steps = _parse_steps(ck, doc, model, params, data)
    return Study(path, info, model, params, data, executor, store, steps, text)


def _parse_info(ck: _Checker, doc: dict, base: Path, path: Path) -> StudyInfo:
    t = ck.table(doc.get("study", {}), ("study",), "[study]")
    ck.keys(t, _STUDY_KEYS, ("study",), "[study]")
    name = ck.option(t, "name", (_str(), path.stem), ("study",), "[study]")
    seed = ck.option(t, "seed", (_int(), 1), ("study",), "[study]")
    out = ck.option(t, "output", (_str(), f"rotoruq-results/{name}"), ("study",), "[study]")
    desc = ck.option(t, "description", (_str(), ""), ("study",), "[study]")
    out_path = Path(out)
    if not out_path.is_absolute():
        out_path = base / out_path
    return StudyInfo(name, seed, out_path, desc)


def _parse_model(ck: _Checker, doc: dict) -> ModelSpec:
    if "model" not in doc:
        ck.fail((), "a [model] table (preset = \"bo105\" or command = [...])")
    t = ck.table(doc["model"], ("model",), "[model]")
    ck.keys(t, _MODEL_KEYS, ("model",), "[model]")
    w = ("model",)
    responses = ck.option(t, "responses", (_strlist, _REQUIRED), w, "[model]")
    fixed = ck.option(t, "fixed", (_table, {}), w, "[model]") or {}
    fixed = _numbers(ck, fixed, w + ("fixed",), "[model] fixed")
    if "preset" in t and "command" in t:
        ck.fail(w + ("command",), "either preset or command in [model], not both")
    if "preset" in t:
        preset = ck.option(t, "preset", (_str(("bo105", "gvpm")), None), w, "[model]")
        for key in _MODEL_KEYS[4:]:
            if key in t:
                ck.fail(w + (key,), f"no {key!r} with a rotor preset (it is for external drivers)")
        for r in responses:
            if r not in ROTOR_RESPONSES:
                close = difflib.get_close_matches(r, ROTOR_RESPONSES, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                ck.fail(w + ("responses",), f"rotor responses among {', '.join(ROTOR_RESPONSES)}"
                        f"{hint}", r)
        for k in fixed:
            if not is_rotor_input(k):
                _unknown_input(ck, w + ("fixed", k), k)
        opts = ck.option(t, "preset_options", (_table, {}), w, "[model]") or {}
        return ModelSpec("preset", responses, fixed, preset=preset, preset_options=opts)
    if "command" not in t:
        ck.fail(w, "preset = \"bo105\" | \"gvpm\" or command = [\"driver\", ...] in [model]")
    cmd = ck.option(t, "command", (_strlist, None), w, "[model]")
    recover = t.get("recover")
    ext = ExternalSpec(
        command=cmd,
        files=ck.option(t, "files", (_strlist, ()), w, "[model]"),
        templates=ck.option(t, "templates", (_strlist, ()), w, "[model]"),
        parameters_format=ck.option(
            t, "parameters_format", (_str(("standard", "aprepro")), "standard"), w, "[model]"
        ),
        timeout=ck.option(t, "timeout", (_num(positive=True, allow_zero=False), None), w,
                          "[model]"),
        failure=ck.option(t, "failure", (_str(("abort", "retry", "recover", "continue")),
                                         "abort"), w, "[model]"),
        retries=ck.option(t, "retries", (_int(0), 0), w, "[model]"),
        recover=None if recover is None else ck.option(t, "recover", (_numlist, None), w,
                                                       "[model]"),
        workdir=ck.option(t, "workdir", (_str(), None), w, "[model]"),
    )
    return ModelSpec("external", responses, fixed, external=ext)


def _numbers(ck: _Checker, table: Mapping, where: tuple, what: str) -> dict[str, float]:
    out = {}
    for k, v in table.items():
        if isinstance(v, bool) or not isinstance(v, int | float):
            ck.fail(where + (k,), f"a number for {k!r} in {what}", repr(v))
        out[k] = float(v)
    return out


def _unknown_input(ck: _Checker, where: tuple, name: str):
    names = list(rotor_input_names()) + ["cla_m03", "cl0_m03", "cd0_m03"]
    close = difflib.get_close_matches(name, names, n=1, cutoff=0.5)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    ck.fail(where, "an input of the rotor model: " + ", ".join(_ROTOR_INPUTS)
            + ", cla_mNN, cl0_mNN, cd0_mNN" + hint, name)


def _parse_parameters(ck: _Checker, doc: dict, model: ModelSpec,
                      where: tuple = ("parameters",)) -> tuple[ParameterSpec, ...]:
    t = doc.get("parameters", {}) if where == ("parameters",) else doc
    t = ck.table(t, where, "[parameters]")
    out = []
    for name, spec in t.items():
        w = where + (name,)
        spec = ck.table(spec, w, f"[parameters.{name}]")
        if model.kind == "preset" and not is_rotor_input(name):
            _unknown_input(ck, w, name)
        if name in model.fixed and where == ("parameters",):
            ck.fail(w, f"{name!r} either fixed in [model] or uncertain in [parameters], not both")
        if "distribution" not in spec:
            ck.fail(w, f"distribution = \"normal\" | \"uniform\" | ... in [parameters.{name}]")
        kind = spec["distribution"]
        if not isinstance(kind, str) or kind.lower() not in DISTRIBUTIONS:
            close = difflib.get_close_matches(str(kind).lower(), list(DISTRIBUTIONS), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            ck.fail(w + ("distribution",),
                    f"a distribution among {', '.join(sorted(DISTRIBUTIONS))}{hint}", repr(kind))
        cls = DISTRIBUTIONS[kind.lower()]
        import inspect

        fields = [p for p in inspect.signature(cls).parameters]
        aliases = {"mu": "mean", "sigma": "std"}
        allowed = list(_PARAM_META) + [aliases.get(f, f) for f in fields] + fields
        ck.keys(spec, allowed, w, f"[parameters.{name}] ({kind})")
        params = {k: v for k, v in spec.items() if k not in _PARAM_META}
        params = _numbers(ck, params, w, f"[parameters.{name}]")
        try:
            dist = make_distribution(kind, **params)
        except ParameterError as exc:
            bad = next((k for k in ("std", "sigma", "lower", "upper") if k in params), None)
            where = w + (bad,) if bad else w
            form = ", ".join(f"{aliases.get(f, f)} = <number>" for f in fields)
            ck.fail(where, f"a valid {kind} distribution ({form}): {exc}",
                    ", ".join(f"{k} = {v:g}" for k, v in params.items()))
        out.append(ParameterSpec(
            name, kind.lower(), params, dist, ck.loc.line(*w),
            label=str(spec.get("label", "")), unit=str(spec.get("unit", "")),
        ))
    return tuple(out)


def _parse_data(ck: _Checker, doc: dict, base: Path) -> dict[str, DataSet]:
    t = ck.table(doc.get("data", {}), ("data",), "[data]")
    out = {}
    for name, spec in t.items():
        w = ("data", name)
        spec = ck.table(spec, w, f"[data.{name}] (a table: file = \"x.csv\" or inline columns)")
        if "file" in spec:
            ck.keys(spec, _DATA_KEYS, w, f"[data.{name}]")
            rel = ck.option(spec, "file", (_str(), None), w, f"[data.{name}]")
            fpath = _resolve_data_path(rel, base)
            if fpath is None:
                ck.fail(w + ("file",), f"an existing CSV file (looked in {base} and the bundled "
                        "rotoruq/data)", rel)
            cols = _read_csv(ck, fpath, w)
            select = ck.option(spec, "select", (_table, {}), w, f"[data.{name}]") or {}
            select = _numbers(ck, select, w + ("select",), f"[data.{name}] select")
            mask = np.ones(len(next(iter(cols.values()))), bool)
            for k, v in select.items():
                if k not in cols:
                    ck.fail(w + ("select", k), f"a column of {fpath.name}: {', '.join(cols)}", k)
                mask &= np.isclose(cols[k], v)
            if not mask.any():
                ck.fail(w + ("select",), f"a selection matching at least one row of {fpath.name}")
            cols = {k: v[mask] for k, v in cols.items()}
            keep = ck.option(spec, "columns", (_strlist, None), w, f"[data.{name}]")
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
                if isinstance(v, int | float) and not isinstance(v, bool):
                    v = [v]
                try:
                    cols[k] = np.asarray(_numlist(v))
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


def _read_csv(ck: _Checker, fpath: Path, where: tuple) -> dict[str, np.ndarray]:
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


def _parse_exec_store(ck: _Checker, doc: dict) -> tuple[ExecutorSpec, StoreSpec]:
    t = ck.table(doc.get("executor", {}), ("executor",), "[executor]")
    ck.keys(t, _EXECUTOR_KEYS, ("executor",), "[executor]")
    w = ("executor",)
    ex = ExecutorSpec(
        kind=ck.option(t, "kind", (_str(("serial", "processes", "dask")), "serial"), w,
                       "[executor]"),
        workers=ck.option(t, "workers", (_int(1), None), w, "[executor]"),
        scheduler=ck.option(t, "scheduler", (_str(), None), w, "[executor]"),
    )
    t = ck.table(doc.get("store", {}), ("store",), "[store]")
    ck.keys(t, _STORE_KEYS, ("store",), "[store]")
    st = StoreSpec(
        enabled=ck.option(t, "enabled", (_bool, True), ("store",), "[store]"),
        path=ck.option(t, "path", (_str(), "evaluations.sqlite"), ("store",), "[store]"),
    )
    return ex, st


def _parse_steps(ck, doc, model: ModelSpec, params, data) -> tuple[StepSpec, ...]:
    raw = doc.get("steps", [])
    if not isinstance(raw, list) or not all(isinstance(s, dict) for s in raw):
        ck.fail(("steps",), "[[steps]] tables (an array of tables)")
    if not raw:
        ck.fail((), "at least one [[steps]] entry")
    pnames = [p.name for p in params]
    # names first, so that `from` can say "defined later" or "circular"
    names: list[str] = []
    for i, s in enumerate(raw):
        w = ("steps", i)
        if "type" not in s:
            ck.fail(w, f"type = one of {', '.join(STEP_TYPES)} in [[steps]] #{i + 1}")
        typ = s["type"]
        if not isinstance(typ, str) or typ not in STEP_TYPES:
            close = difflib.get_close_matches(str(typ), list(STEP_TYPES), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            ck.fail(w + ("type",), f"a step type among {', '.join(STEP_TYPES)}{hint}", str(typ))
        name = s.get("name", typ)
        if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_\-]*", name):
            ck.fail(w + ("name",), "a step name made of letters, digits, '_' and '-'", repr(name))
        if name in names:
            ck.fail(w + ("name",), f"a unique step name (there is already a step {name!r}; "
                    "give this one name = \"...\")", name)
        names.append(name)
    steps = []
    for i, s in enumerate(raw):
        w = ("steps", i)
        typ = s["type"]
        name = names[i]
        what = f"step {name!r} ({typ})"
        allowed = list(_COMMON_STEP_KEYS) + list(STEP_TYPES[typ])
        ck.keys(s, allowed, w, what)
        opts = {k: ck.option(s, k, spec, w, what) for k, spec in STEP_TYPES[typ].items()}
        common = {k: ck.option(s, k, spec, w, what) for k, spec in _COMMON_STEP_KEYS.items()}
        if common["seed"] is not None:
            opts["seed"] = common["seed"]
        source = None
        if common["from"] is not None:
            source = _check_ref(ck, raw, names, i, common["from"], "from", ("posterior",
                                                                              "calibrated"))
        data_ref = common["data"]
        if data_ref is not None:
            if "." in data_ref:
                _check_ref(ck, raw, names, i, data_ref, "data", ("samples",))
            elif data_ref not in data:
                close = difflib.get_close_matches(data_ref, list(data), n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                ck.fail(w + ("data",), "the name of a [data.NAME] table "
                        f"({', '.join(data) or 'none defined'}) or \"step.samples\"{hint}",
                        data_ref)
        elif typ in ("bayes_calibration", "least_squares"):
            if len(data) == 1:
                data_ref = next(iter(data))
            else:
                ck.fail(w, f"data = \"NAME\" in {what} (data sets: {', '.join(data) or 'none'})")
        sel_p = common["parameters"]
        known = pnames + [n for st in raw if isinstance(st.get("distributions"), dict)
                          for n in st["distributions"] if n not in pnames]
        if sel_p is not None:
            for p in sel_p:
                if p not in known:
                    close = difflib.get_close_matches(p, known, n=1)
                    hint = f" (did you mean {close[0]!r}?)" if close else ""
                    ck.fail(w + ("parameters",), f"names from [parameters] ({', '.join(known)})"
                            f"{hint}", p)
        sel_r = common["responses"]
        if sel_r is not None:
            valid_r = ROTOR_RESPONSES if model.kind == "preset" else model.responses
            for r in sel_r:
                if r not in valid_r:
                    close = difflib.get_close_matches(r, valid_r, n=1)
                    hint = f" (did you mean {close[0]!r}?)" if close else ""
                    ck.fail(w + ("responses",), f"responses of the model "
                            f"({', '.join(valid_r)}){hint}", r)
        fixed = _numbers(ck, common["fixed"] or {}, w + ("fixed",), f"{what} fixed")
        if model.kind == "preset":
            for k in fixed:
                if not is_rotor_input(k):
                    _unknown_input(ck, w + ("fixed", k), k)
        if typ == "bayes_calibration" and opts["burn_in"] >= opts["chain_samples"]:
            ck.fail(w + ("burn_in",), "burn_in < chain_samples "
                    f"({opts['chain_samples']})", str(opts["burn_in"]))
        if typ == "cuu":
            if isinstance(opts["targets"], str):
                _check_ref(ck, raw, names, i, opts["targets"], "targets", ("samples",))
            else:
                _check_targets(ck, opts["targets"], w + ("targets",), model, sel_r)
        if typ == "forward_check":
            _check_sweep(ck, opts, w, model)
        if typ == "evidence":
            for p in opts["intervals"]:
                if p not in pnames:
                    ck.fail(w + ("intervals", p), "intervals keyed by names from [parameters]", p)
        dists = ()
        if common["distributions"] is not None:
            dists = _parse_parameters(ck, common["distributions"], model, w + ("distributions",))
        steps.append(StepSpec(
            name=name, type=typ, index=i, options=opts, source=source, parameters=sel_p,
            distributions=dists,
            responses=sel_r, fixed=fixed, data=data_ref, title=common["title"],
            quick=common["quick"] or {}, line=ck.loc.line(*w),
        ))
    if not pnames and any(s.type != "forward_check" or s.source is None for s in steps):
        ck.fail(("parameters",), "at least one [parameters.NAME] table")
    return tuple(steps)


def _check_ref(ck, raw, names, i, ref, key, attrs) -> tuple[str, str]:
    w = ("steps", i, key)
    m = re.fullmatch(r"([A-Za-z_][A-Za-z0-9_\-]*)\.([a-z_]+)", ref)
    if not m:
        ck.fail(w, f"{key} = \"STEP.{'|'.join(attrs)}\"", ref)
    target, attr = m.groups()
    if target not in names:
        close = difflib.get_close_matches(target, names, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        ck.fail(w, f"{key} = \"STEP.ATTR\" naming an earlier step ({', '.join(names[:i])})"
                f"{hint}", ref)
    # follow the chain of `from` references to report cycles as such
    chain = [names[i]]
    j = names.index(target)
    while True:
        chain.append(names[j])
        if names[j] == names[i]:
            ck.fail(w, "references to earlier steps only; circular reference "
                    + " -> ".join(chain), ref)
        nxt = raw[j].get("from") or raw[j].get("data")
        if not isinstance(nxt, str) or "." not in nxt or nxt.split(".")[0] not in names:
            break
        j = names.index(nxt.split(".")[0])
        if len(chain) > len(names) + 1:
            break
    if names.index(target) >= i:
        ck.fail(w, f"a reference to an earlier step; {target!r} is step #{names.index(target) + 1}"
                f" (line {ck.loc.line('steps', names.index(target))}), after or at this one", ref)
    typ = raw[names.index(target)]["type"]
    provides = _PROVIDES.get(typ, ())
    if attr not in attrs or attr not in provides:
        ck.fail(w, f"{key} = \"{target}.<attr>\" with <attr> one of "
                f"{', '.join(a for a in attrs if a in provides) or '(none)'} "
                f"(step {target!r} is a {typ} step)", ref)
    return target, attr


def _check_targets(ck, targets: Mapping, w, model: ModelSpec, sel_r):
    allowed = sel_r or model.responses
    for r, v in targets.items():
        if r not in allowed:
            ck.fail(w + (r,), f"targets keyed by responses ({', '.join(allowed)})", r)
        if (not isinstance(v, list) or len(v) != 2
                or not all(isinstance(x, int | float) and not isinstance(x, bool) for x in v)
                or v[1] <= 0):
            ck.fail(w + (r,), f"{r} = [mean, std] with std > 0", repr(v))


def _check_sweep(ck, opts, w, model: ModelSpec):
    sweep = opts["sweep"]
    if sweep is None:
        return
    lengths = set()
    for k, v in sweep.items():
        if model.kind == "preset" and not is_rotor_input(k):
            _unknown_input(ck, w + ("sweep", k), k)
        try:
            lengths.add(len(_numlist(v)))
        except TypeError:
            ck.fail(w + ("sweep", k), f"{k} = [numbers] in sweep", repr(v))
    if len(lengths) != 1:
        ck.fail(w + ("sweep",), "sweep lists of equal length")
    if opts["normalize_by"] is not None:
        _numbers(ck, opts["normalize_by"], w + ("normalize_by",), "normalize_by")
