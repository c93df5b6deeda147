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
    n_samples = 20000                        # the same words as calibrate_bayes

    [[steps]]
    name = "forward"
    type = "sampling"
    from = "bayes.posterior"                 # distributions from an earlier step

The file is split along its seams: :mod:`~rotoruq.study.locator` (line numbers),
:mod:`~rotoruq.study.spec` (the dataclasses), :mod:`~rotoruq.study.options` (value checkers),
:mod:`~rotoruq.study.datafiles` (``[data]``), :mod:`rotoruq.steps` (the step types and their
options); this module parses the tables in order.

:func:`load_study` raises :class:`rotoruq.errors.InputFileError` naming the file, the line and
the expected form for every problem; unknown keys come with the closest valid key.
"""

from __future__ import annotations

import json
import re
import tomllib
from collections.abc import Mapping, Sequence
from functools import lru_cache
from pathlib import Path
from typing import NoReturn

import numpy as np

from ..errors import InputFileError, ParameterError
from ..params import DISTRIBUTIONS, ParameterSpace, distribution_keys, make_distribution
from ..safety import check_name
from ..steps import StepCheck, StepType, find_step_type, step_type, step_types
from ..steps.multifidelity import HF_LABEL
from .datafiles import parse_data, points_columns, points_file
from .options import (
    REQUIRED,
    Checker,
    Option,
    boolean,
    close_hint,
    integer,
    number,
    number_list,
    string,
    string_list,
    table,
)
from .spec import (
    CorrelationSpec,
    DataSet,
    ExecutorSpec,
    ExternalSpec,
    ModelSpec,
    ParameterSpec,
    StepSpec,
    StoreSpec,
    Study,
    StudyInfo,
    function_variables,
)

__all__ = ["load_study", "parse_study", "ModelInputs"]

TOP_KEYS = ("study", "model", "models", "parameters", "correlation", "data", "executor", "store",
            "steps")
CORRELATION_KEYS = ("parameters", "matrix")
STUDY_KEYS = ("name", "seed", "output", "description", "reference", "max_failed_share")
EXTERNAL_KEYS = ("command", "files", "templates", "parameters_format", "timeout", "failure",
                 "retries", "recover", "workdir", "gradients")
MODEL_KEYS = ("preset", "preset_options", "discretization", "responses", "fixed",
              "function", "components", "flight", *EXTERNAL_KEYS)
# [model] flight = {...}: the rotor in forward flight's options
FLIGHT_KEYS = ("inflow_model", "trim")
# RotorModel's discretization keywords a preset model may set.
DISCRETIZATION_KEYS = ("n_stations", "n_azimuth", "n_harmonics")

EXECUTOR_KEYS = ("kind", "workers", "scheduler")
STORE_KEYS = ("enabled", "path")
PARAM_META = ("distribution", "label", "unit", "input")
# [parameters.NAME] keys whose value is a list of numbers (a histogram's bins)
LIST_PARAMS = ("abscissas", "counts", "ordinates")
# the forms a distribution may be given in, when not simply all of its keys
DISTRIBUTION_FORMS = {
    "lognormal": "mean = <number>, std = <number> | mean = <number>, error_factor = <number> "
                 "| lambda = <number>, zeta = <number>; optional lower, upper",
    "histogram_bin": "abscissas = [<n + 1 numbers>], counts = [<n numbers>, 0] | "
                     "ordinates = [<n numbers>, 0]",
}

# Keys every [[steps]] table may have besides its type's options.
COMMON_STEP_KEYS: dict[str, Option] = {
    "name": Option(string(), None),
    "type": Option(string(), REQUIRED),
    "from": Option(string(), None),
    "parameters": Option(string_list, None),
    "responses": Option(string_list, None),
    "fixed": Option(table, None),
    "data": Option(string(), None),
    "title": Option(string(), ""),
    "seed": Option(integer(), None),
    "quick": Option(table, None),
    "distributions": Option(table, None),
    "needs": Option(string_list, None),
}
#: Outside software a step may need (its ``needs``): skipped with a note where missing.
STEP_NEEDS = ("mbdyn",)


def _rotor_responses(forward: bool = False) -> tuple[str, ...]:
    if forward:
        from ..rotor.forward import FORWARD_RESPONSES

        return tuple(FORWARD_RESPONSES)
    from ..rotor.model import RESPONSES

    return tuple(RESPONSES)


@lru_cache(maxsize=16)
def _rotor_inputs(preset: str, options: str, forward: bool = False) -> tuple[str, ...]:
    """Every input name a :class:`~rotoruq.rotor.model.RotorModel` (``forward``: a
    :class:`~rotoruq.rotor.forward.ForwardRotorModel`) of this preset accepts: the rotor's
    inputs and its airfoil's coefficient names (the rotor's own list)."""
    from ..rotor.forward import FORWARD_INPUTS
    from ..rotor.model import ROTOR_INPUTS, load_airfoil
    from ..rotor.presets import get_preset

    airfoil = load_airfoil(get_preset(preset, **json.loads(options)))
    extra = tuple(FORWARD_INPUTS) if forward else ()
    return tuple(ROTOR_INPUTS) + extra + tuple(airfoil.parameter_names)


class ModelInputs:
    """Checks model input names against the model: for a rotor preset, the names the rotor
    itself accepts (so ``cla_m075`` is valid exactly when the preset's airfoil has that Mach
    row); an external model accepts any name (its driver gets them all)."""

    def __init__(self, ck: Checker, model: ModelSpec, where: tuple = ("model",)):
        self.ck, self.model, self.where = ck, model, where

    @property
    def names(self) -> tuple[str, ...] | None:
        """The valid names (None: any)."""
        if self.model.kind != "preset":
            return None
        opts = json.dumps(dict(self.model.preset_options), sort_keys=True, default=str)
        try:
            return _rotor_inputs(self.model.preset, opts, self.model.flight is not None)
        except (ParameterError, TypeError) as exc:
            self.ck.fail(self.where + ("preset_options",), "options of the rotor preset "
                         f"{self.model.preset!r} ({exc})", opts)

    def check(self, where: tuple, name: str) -> None:
        names = self.names
        if names is not None and name not in names:
            self.ck.fail(where, f"an input of the rotor model {self.model.preset!r}: "
                         f"{', '.join(names)}{close_hint(name, names, 0.5)}", name)


def load_study(path: str | Path) -> Study:
    """Read and validate a study file. Raises :class:`InputFileError` (file, line, expected).

    Parameters
    ----------
    path : str or Path
        The study file (TOML, UTF-8).

    Returns
    -------
    Study
        The validated study.
    """
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
    except ValueError as exc:  # an integer of more than 4300 digits (Python's own limit)
        m = re.search(r"\d{4301,}", text)
        line = text[: m.start()].count("\n") + 1 if m else None
        raise InputFileError(path, line, "a number of at most 4300 digits",
                             str(exc).split(";")[0]) from None
    ck = Checker(path, text)
    base = path.parent if path.name != "<study>" else Path.cwd()
    ck.keys(doc, TOP_KEYS, (), "a study file")

    info = _parse_info(ck, doc, base, path)
    model = _parse_model(ck, doc)
    models = _parse_models(ck, doc, model)
    inputs = ModelInputs(ck, model)
    params = _parse_parameters(ck, doc, inputs)
    _check_model_inputs(ck, models, model, params)
    _check_function_models(ck, model, models, params)
    data = parse_data(ck, doc, base)
    executor, store = _parse_exec_store(ck, doc)
    correlation = _parse_correlation(ck, doc, params)
    steps = _parse_steps(ck, doc, inputs, params, data, models, base)
    _check_correlated_steps(ck, steps, correlation)
    return Study(path, info, model, params, data, executor, store, steps, text, models,
                 correlation=correlation)


def _parse_info(ck: Checker, doc: dict, base: Path, path: Path) -> StudyInfo:
    t = ck.table(doc.get("study", {}), ("study",), "[study]")
    ck.keys(t, STUDY_KEYS, ("study",), "[study]")
    name = ck.value(t, "name", (string(), path.stem), ("study",), "[study]")
    check_name(name, what="the study name", path=path, line=ck.loc.line("study", "name"))
    seed = ck.value(t, "seed", (integer(), 1), ("study",), "[study]")
    out = ck.value(t, "output", (string(), f"rotoruq-results/{name}"), ("study",), "[study]")
    desc = ck.value(t, "description", (string(), ""), ("study",), "[study]")
    ref = _parse_reference(ck, t, name, doc.get("model"))
    share = ck.value(t, "max_failed_share", (number(positive=True), 0.5), ("study",), "[study]")
    if share > 1:
        ck.fail(("study", "max_failed_share"), "a share of failed evaluations from 0 to 1 "
                "(0.5: more than half of a step's evaluations failed is an error)", str(share))
    out_path = Path(out)
    if not out_path.is_absolute():
        out_path = base / out_path
    return StudyInfo(name, seed, out_path, desc, ref, share)


def _parse_reference(ck: Checker, t: dict, name: str, model: object) -> str | None:
    """``[study] reference``: the study is one of a reference's (:mod:`rotoruq.reference`)
    only when it says so; its name and preset must then be one of the reference's studies."""
    from ..reference import NAMES
    from ..reference.studies import declaration_error

    if "reference" not in t:
        return None
    ref = ck.value(t, "reference", (string(), None), ("study",), "[study]")
    if ref not in NAMES:
        ck.fail(("study", "reference"), "reference = one of: " + ", ".join(
            f'"{n}"' for n in NAMES) + " (or no reference key: a study of your own)",
                repr(ref))
    preset = model.get("preset") if isinstance(model, dict) else None
    wrong = declaration_error(name, preset if isinstance(preset, str) else None)
    if wrong:
        ck.fail(("study", "reference"), *wrong)
    return ref


def _parse_model(ck: Checker, doc: dict) -> ModelSpec:
    if "model" not in doc:
        ck.fail((), "a [model] table (preset = \"bo105\" or command = [...])")
    return _parse_model_table(ck, doc["model"], ("model",), "[model]")


def _parse_model_table(ck: Checker, t: object, w: tuple, what: str, name: str = "",
                       responses: tuple[str, ...] | None = None) -> ModelSpec:
    """``[model]``, or a named ``[models.NAME]`` (``name``) whose ``responses`` default to
    the study's (``responses``)."""
    t = ck.table(t, w, what)
    ck.keys(t, MODEL_KEYS, w, what)
    responses = ck.value(t, "responses", (string_list, REQUIRED if responses is None
                                          else responses), w, what)
    fixed = ck.value(t, "fixed", (table, {}), w, what) or {}
    fixed = ck.numbers(fixed, w + ("fixed",), f"{what} fixed")
    if "preset" in t and "command" in t:
        ck.fail(w + ("command",), f"either preset or command in {what}, not both")
    if "function" in t and ("preset" in t or "command" in t):
        other = "preset" if "preset" in t else "command"
        ck.fail(w + ("function",), f"one of preset, command or function in {what}, not "
                f"{other} and function")
    if "components" in t and "function" not in t:
        ck.fail(w + ("components",), "no 'components' without function = \"...\" (they are "
                "a Dakota test function's analysis_components)")
    if "function" in t:
        return _parse_function_model(ck, t, w, what, name, responses, fixed)
    if "preset" in t:
        from ..rotor.presets import PRESETS

        preset = ck.value(t, "preset", (string(tuple(PRESETS)), None), w, what)
        for key in EXTERNAL_KEYS:
            if key in t:
                ck.fail(w + (key,), f"no {key!r} with a rotor preset (it is for external drivers)")
        flight = None
        if "flight" in t:
            flight = ck.value(t, "flight", (table, {}), w, what) or {}
            ck.keys(flight, FLIGHT_KEYS, w + ("flight",), f"{what} flight")
            choices = {"inflow_model": ("glauert", "drees"),
                       "trim": ("none", "wind_tunnel", "hub_moments")}
            flight = {k: ck.value(flight, k, (string(choices[k]), None), w + ("flight",),
                                  f"{what} flight") for k in flight}
        rotor_responses = _rotor_responses(flight is not None)
        for r in responses:
            if r not in rotor_responses:
                ck.fail(w + ("responses",), f"rotor responses among {', '.join(rotor_responses)}"
                        f"{close_hint(r, rotor_responses)}", r)
        opts = ck.value(t, "preset_options", (table, {}), w, what) or {}
        disc = ck.value(t, "discretization", (table, {}), w, what) or {}
        ck.keys(disc, DISCRETIZATION_KEYS, w + ("discretization",), f"{what} discretization")
        disc = {k: ck.value(disc, k, (integer(1, 1000), None), w + ("discretization",),
                            f"{what} discretization") for k in disc}
        _check_grid(ck, preset, opts, disc, w + ("discretization",))
        spec = ModelSpec("preset", responses, fixed, preset=preset, preset_options=opts,
                         discretization=disc, name=name, flight=flight)
        inputs = ModelInputs(ck, spec, w)
        for k in fixed:
            inputs.check(w + ("fixed", k), k)
        return spec
    for key in ("discretization", "flight"):
        if key in t:
            ck.fail(w + (key,), f"no {key!r} with an external driver (it is for a rotor "
                    "preset)")
    if "command" not in t:
        ck.fail(w, f"preset = \"bo105\" | \"gvpm\", command = [\"driver\", ...] or "
                f"function = \"text_book\" (a Dakota test function) in {what}")
    cmd = ck.value(t, "command", (string_list, None), w, what)
    recover = t.get("recover")
    ext = ExternalSpec(
        command=cmd,
        files=ck.value(t, "files", (string_list, ()), w, what),
        templates=ck.value(t, "templates", (string_list, ()), w, what),
        parameters_format=ck.value(
            t, "parameters_format", (string(("standard", "aprepro")), "standard"), w, what
        ),
        timeout=ck.value(t, "timeout", (number(positive=True, allow_zero=False), None), w,
                          what),
        failure=ck.value(t, "failure", (string(("abort", "retry", "recover", "continue")),
                                         "abort"), w, what),
        retries=ck.value(t, "retries", (integer(0), 0), w, what),
        recover=None if recover is None else ck.value(t, "recover", (number_list, None), w,
                                                       what),
        workdir=ck.value(t, "workdir", (string(), None), w, what),
        gradients=ck.value(t, "gradients", (string(("finite_difference", "analytic")),
                                                  "finite_difference"), w, what),
    )
    return ModelSpec("external", responses, fixed, external=ext, name=name)


def _parse_function_model(ck: Checker, t: dict, w: tuple, what: str, name: str,
                          responses: tuple[str, ...], fixed: Mapping[str, float]) -> ModelSpec:
    """``function = "text_book"``: one of Dakota's test functions (rotoruq.testfunctions);
    its variables and responses are checked once the parameters are known
    (:func:`_check_function_models`)."""
    from ..testfunctions import FUNCTIONS

    fn = ck.value(t, "function", (string(tuple(FUNCTIONS)), None), w, what)
    for key in (*EXTERNAL_KEYS, "preset_options", "discretization", "flight"):
        if key in t:
            ck.fail(w + (key,), f"no {key!r} with a Dakota test function (function = ...)")
    comps = tuple(ck.value(t, "components", (string_list, ()), w, what))
    problem = FUNCTIONS[fn].component_problem(comps)
    if problem is not None:
        ck.fail(w + ("components",), problem, ", ".join(comps))
    return ModelSpec("function", responses, fixed, function=fn, components=comps, name=name)


def _check_function_models(ck: Checker, model: ModelSpec, models: Mapping[str, ModelSpec],
                           params: tuple[ParameterSpec, ...]) -> None:
    """A Dakota test function takes the study's parameters and fixed inputs as its variables
    (by position, or by name for those Dakota reads by descriptor) and gives as many responses
    as it can for them."""
    from ..testfunctions import FUNCTIONS

    for spec in (model, *models.values()):
        if spec.function is None:
            continue
        w = ("models", spec.name) if spec.name else ("model",)
        info = FUNCTIONS[spec.function]
        variables = function_variables(spec, params, model if spec.name else None)
        problem = info.input_problem(variables)
        if problem is not None:
            ck.fail(w + ("function",), f"{problem} (its variables are the study's parameters, "
                    "then the fixed inputs)", ", ".join(variables) or "no variables")
        problem = info.response_problem(len(variables), len(spec.responses))
        if problem is not None:
            ck.fail(w + ("responses",), problem,
                    f"{len(spec.responses)}: {', '.join(spec.responses)}")


def _check_grid(ck: Checker, preset: str, opts: Mapping, disc: Mapping[str, int],
                where: tuple) -> None:
    """The rotor's own rule on its station and azimuth counts (rotor.geometry.blade_grid)."""
    from ..rotor.geometry import blade_grid
    from ..rotor.presets import get_preset

    counts = {k: v for k, v in disc.items() if k in ("n_stations", "n_azimuth")}
    if not counts:
        return
    try:
        blade_grid(get_preset(preset, **dict(opts)), **counts)
    except ValueError as exc:
        ck.fail(where, f"a discretization the rotor accepts ({exc})",
                ", ".join(f"{k} = {v}" for k, v in counts.items()))
    except (ParameterError, TypeError):
        return  # bad preset options: ModelInputs names them


def _parse_models(ck: Checker, doc: dict, model: ModelSpec) -> dict[str, ModelSpec]:
    """``[models.NAME]``: named models (same keys as ``[model]``; ``responses`` default to
    ``[model]``'s and must include them)."""
    t = ck.table(doc.get("models", {}), ("models",), "[models]")
    out = {}
    for name, spec in t.items():
        w = ("models", name)
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_\-]*", name) or name == HF_LABEL:
            ck.fail(w, "a model name made of letters, digits, '_' and '-' (not "
                    f"{HF_LABEL!r}: the report's name for [model])", repr(name))
        out[name] = _parse_model_table(ck, spec, w, f"[models.{name}]", name, model.responses)
    return out


def _check_model_responses(ck: Checker, doc: dict, opts: Mapping,
                           models: Mapping[str, ModelSpec], model: ModelSpec,
                           step_responses: Sequence[str] | None, what: str) -> None:
    """Each ``[models.NAME]`` a step runs (its ``models`` and ``high_fidelity``) gives the
    step's responses (its ``responses``, else the study's)."""
    names = list(opts.get("models") or ()) + ([opts["high_fidelity"]]
                                              if opts.get("high_fidelity") else [])
    needed = list(step_responses) if step_responses else list(model.responses)
    whose = (f"the responses of {what}" if step_responses else "the study's responses")
    for name in names:
        m = models.get(name)
        if m is None:
            continue
        missing = [r for r in needed if r not in m.responses]
        if missing:
            spec = (doc.get("models") or {}).get(name) or {}
            key = ("models", name) + (("responses",) if "responses" in spec else ())
            ck.fail(key, f"responses of [models.{name}] that include {whose} "
                    f"({', '.join(needed)}); missing {', '.join(missing)}",
                    ", ".join(m.responses))


def _check_model_inputs(ck: Checker, models: Mapping[str, ModelSpec], model: ModelSpec,
                        params: tuple[ParameterSpec, ...]) -> None:
    """A named rotor model takes every study parameter and every input [model] fixes (it is
    evaluated at the same points); a named model fixes no uncertain input."""
    for name, m in models.items():
        w = ("models", name)
        for p in params:
            if p.name in m.fixed:
                ck.fail(w + ("fixed", p.name), f"{p.name!r} either fixed in [models.{name}] or "
                        "uncertain in [parameters], not both")
        valid = ModelInputs(ck, m, w).names
        if valid is None:
            continue
        for n in [p.name for p in params] + [k for k in model.fixed if k not in m.fixed]:
            if n not in valid:
                ck.fail(w + ("preset",), f"a rotor preset whose model takes every input of the "
                        f"study ({n!r} is not an input of [models.{name}]: it takes "
                        f"{', '.join(valid)})", m.preset)


def _parse_parameters(ck: Checker, doc: dict, inputs: ModelInputs,
                      where: tuple = ("parameters",), renamed: Mapping[str, str] | None = None
                      ) -> tuple[ParameterSpec, ...]:
    model = inputs.model
    t = doc.get("parameters", {}) if where == ("parameters",) else doc
    t = ck.table(t, where, "[parameters]")
    out = []
    for name, spec in t.items():
        w = where + (name,)
        spec = ck.table(spec, w, f"[parameters.{name}]")
        target = _model_input(ck, t, name, spec, w, inputs, renamed)
        if name in model.fixed and where == ("parameters",):
            ck.fail(w, f"{name!r} either fixed in [model] or uncertain in [parameters], not both")
        if "distribution" not in spec:
            ck.fail(w, f"distribution = \"normal\" | \"uniform\" | ... in [parameters.{name}]")
        kind = spec["distribution"]
        if not isinstance(kind, str) or kind.lower() not in DISTRIBUTIONS:
            ck.fail(w + ("distribution",),
                    f"a distribution among {', '.join(sorted(DISTRIBUTIONS))}"
                    f"{close_hint(str(kind).lower(), list(DISTRIBUTIONS))}", repr(kind))
        fields = list(distribution_keys(kind))
        aliases = {"mu": "mean", "sigma": "std"}
        allowed = list(PARAM_META) + [aliases.get(f, f) for f in fields] + fields
        ck.keys(spec, allowed, w, f"[parameters.{name}] ({kind})")
        params = {k: v for k, v in spec.items() if k not in PARAM_META}
        lists = {k: _number_list(ck, params.pop(k), w + (k,), f"[parameters.{name}] {k}")
                 for k in LIST_PARAMS if k in params}
        params = ck.numbers(params, w, f"[parameters.{name}]")
        try:
            dist = make_distribution(kind, **params, **lists)
        except ParameterError as exc:
            bad = next((k for k in ("std", "sigma", "zeta", "error_factor", "lower", "upper",
                                    "counts", "ordinates", "abscissas") if k in spec), None)
            where = w + (bad,) if bad else w
            form = _distribution_form(kind.lower(), fields)
            ck.fail(where, f"a valid {kind} distribution ({form}): {exc}",
                    ", ".join([f"{k} = {v:g}" for k, v in params.items()]
                              + [f"{k} = {list(v)}" for k, v in lists.items()]))
        out.append(ParameterSpec(
            name, kind.lower(), {**params, **lists}, dist, ck.loc.line(*w),
            label=str(spec.get("label", "")), unit=str(spec.get("unit", "")),
            input=target if target != name else "",
        ))
    return tuple(out)


def _distribution_form(kind: str, fields: list[str]) -> str:
    """How a distribution is written in ``[parameters.NAME]`` (for messages)."""
    return DISTRIBUTION_FORMS.get(kind, ", ".join(f"{f} = <number>" for f in fields))


def _number_list(ck: Checker, value: object, where: tuple, what: str) -> tuple[float, ...]:
    if (not isinstance(value, list) or not value
            or any(isinstance(v, bool) or not isinstance(v, int | float) for v in value)):
        ck.fail(where, f"a list of numbers for {what}", repr(value))
    return tuple(float(v) for v in value)


def _model_input(ck: Checker, t: Mapping, name: str, spec: Mapping, w: tuple,
                 inputs: ModelInputs, renamed: Mapping[str, str] | None) -> str:
    """The model input parameter ``name`` feeds: ``input = "..."`` in ``[parameters]`` (the
    study-file form of the driver's ``--map``), else its own name (a step's
    ``distributions`` follow the study's renaming)."""
    if renamed is not None:  # a step's distributions
        if "input" in spec:
            ck.fail(w + ("input",), f"input = ... only in [parameters.{name}]", spec["input"])
        target = renamed.get(name, name)
        inputs.check(w, target)
        return target
    if "input" not in spec:
        inputs.check(w, name)
        return name
    target = spec["input"]
    if not isinstance(target, str) or not target:
        ck.fail(w + ("input",), "input = \"<model input name>\"", repr(target))
    inputs.check(w + ("input",), target)
    for other, ospec in t.items():
        if other == name:
            continue
        theirs = ospec.get("input", other) if isinstance(ospec, dict) else other
        if target in (other, theirs):
            ck.fail(w + ("input",), f"a model input that no other parameter feeds "
                    f"([parameters.{other}] does)", target)
    if target in inputs.model.fixed:
        ck.fail(w + ("input",), f"an input not fixed in [model] ({target!r} is)", target)
    return target


def _parse_correlation(ck: Checker, doc: dict, params: tuple[ParameterSpec, ...]
                       ) -> CorrelationSpec | None:
    """``[correlation]``: ``parameters = [names of [parameters.NAME]]`` and ``matrix`` (their
    x-space correlation: symmetric, unit diagonal, positive definite, reachable with their
    marginals through the Nataf model)."""
    if "correlation" not in doc:
        return None
    w = ("correlation",)
    what = "[correlation]"
    t = ck.table(doc["correlation"], w, what)
    ck.keys(t, CORRELATION_KEYS, w, what)
    for key in CORRELATION_KEYS:
        if key not in t:
            ck.fail(w, f"{key} = [...] in {what} (parameters = [\"a\", \"b\"], matrix = "
                    "[[1.0, 0.3], [0.3, 1.0]])")
    names = ck.value(t, "parameters", (string_list, REQUIRED), w, what)
    known = [p.name for p in params]
    for n in names:
        if n not in known:
            ck.fail(w + ("parameters",), f"names of [parameters.NAME] tables in the parameters "
                    f"of {what} ({', '.join(known) or 'none defined'}){close_hint(n, known)}", n)
        if names.count(n) > 1:
            ck.fail(w + ("parameters",), f"each parameter once in the parameters of {what}", n)
    if len(names) < 2:
        ck.fail(w + ("parameters",), f"at least two parameters in {what}", repr(list(names)))
    rows = t["matrix"]
    k = len(names)
    where = w + ("matrix",)
    if (not isinstance(rows, list) or len(rows) != k
            or any(not isinstance(r, list) or len(r) != k for r in rows)):
        ck.fail(where, f"a {k} x {k} matrix (a list of {k} rows of {k} numbers, one per "
                f"parameter of {what})", _shape(rows))
    for row in rows:
        for v in row:
            if isinstance(v, bool) or not isinstance(v, int | float) or not np.isfinite(v):
                ck.fail(where, f"numbers in the matrix of {what}", repr(v))
    r = np.array(rows, dtype=float)
    for i, j in zip(*np.nonzero(r != r.T), strict=True):
        ck.fail(where, f"a symmetric matrix in {what}: row {i + 1}, column {j + 1} "
                f"({names[i]}, {names[j]}) is {r[i, j]:g} but ({names[j]}, {names[i]}) is "
                f"{r[j, i]:g}")
    for i in range(k):
        if r[i, i] != 1.0:
            ck.fail(where, f"a unit diagonal in the matrix of {what} (a correlation matrix)",
                    f"{r[i, i]:g} for {names[i]}")
    off = np.abs(r - np.eye(k)).max()
    lam = float(np.linalg.eigvalsh(r).min())
    if off >= 1.0 or lam <= 1e-12:
        ck.fail(where, f"a positive definite matrix in {what} (correlations strictly between "
                "-1 and 1 that are consistent with each other)",
                f"smallest eigenvalue {lam:.3g}")
    spec = CorrelationSpec(tuple(names), tuple(tuple(row) for row in r.tolist()),
                           ck.loc.line(*w))
    by_name = {p.name: p.distribution for p in params}
    try:
        ParameterSpace([(n, by_name[n]) for n in names], correlation=r)
    except ParameterError as exc:
        ck.fail(where, f"correlations the marginals of {', '.join(names)} can reach (Nataf): "
                f"{exc}")
    return spec


def _shape(rows: object) -> str:
    if not isinstance(rows, list):
        return repr(rows)
    return f"{len(rows)} rows of " + ", ".join(
        str(len(r)) if isinstance(r, list) else repr(r) for r in rows)


def _check_correlated_steps(ck: Checker, steps: tuple[StepSpec, ...],
                            correlation: CorrelationSpec | None) -> None:
    """A step whose type ignores correlated inputs (``StepType.correlated`` False) may not
    get two correlated parameters of ``[correlation]`` (steps taking their distributions
    ``from`` an earlier step are checked when they run)."""
    if correlation is None:
        return
    for st in steps:
        typ = step_type(st.type)
        if typ.correlated or st.source is not None:
            continue
        names = list(st.parameters) if st.parameters is not None else [
            *correlation.parameters, *(d.name for d in st.distributions)]
        if correlation.matrix_for(names) is not None:
            ok = ", ".join(sorted(t.name for t in step_types().values() if t.correlated))
            ck.fail(("steps", st.index, "type"),
                    f"a step type that honours correlated inputs ({ok}) for step {st.name!r}: "
                    f"a {typ.name} step assumes independent inputs, and the [correlation] table "
                    f"(line {correlation.line}) correlates its parameters "
                    f"{', '.join(n for n in correlation.parameters if n in names)}; list "
                    "uncorrelated ones with parameters = [...] or drop the correlation",
                    typ.name)


def _parse_exec_store(ck: Checker, doc: dict) -> tuple[ExecutorSpec, StoreSpec]:
    t = ck.table(doc.get("executor", {}), ("executor",), "[executor]")
    ck.keys(t, EXECUTOR_KEYS, ("executor",), "[executor]")
    w = ("executor",)
    ex = ExecutorSpec(
        kind=ck.value(t, "kind", (string(("serial", "processes", "dask")), "serial"), w,
                       "[executor]"),
        workers=ck.value(t, "workers", (integer(1), None), w, "[executor]"),
        scheduler=ck.value(t, "scheduler", (string(), None), w, "[executor]"),
    )
    t = ck.table(doc.get("store", {}), ("store",), "[store]")
    ck.keys(t, STORE_KEYS, ("store",), "[store]")
    st = StoreSpec(
        enabled=ck.value(t, "enabled", (boolean, True), ("store",), "[store]"),
        path=ck.value(t, "path", (string(), "evaluations.sqlite"), ("store",), "[store]"),
    )
    return ex, st


def _step_options(ck: Checker, s: dict, st: StepType, w: tuple, what: str) -> dict:
    """The type's options of one step: given values checked, the others at their defaults
    (the method's signature for method parameters)."""
    opts = {}
    for key, opt in st.options.items():
        default = st.default(key)
        opts[key] = ck.option(s, key, opt, w, what, default)
    return opts


def _parse_steps(ck: Checker, doc: dict, inputs: ModelInputs,
                 params: tuple[ParameterSpec, ...], data: dict[str, DataSet],
                 models: Mapping[str, ModelSpec], base: Path = Path()
                 ) -> tuple[StepSpec, ...]:
    model = inputs.model
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
            ck.fail(w, f"type = one of {', '.join(step_types())} in [[steps]] #{i + 1}")
        typ = s["type"]
        if not isinstance(typ, str) or find_step_type(typ) is None:
            known = list(step_types())
            ck.fail(w + ("type",), f"a step type among {', '.join(known)}"
                    f"{close_hint(str(typ), known)}", str(typ))
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
        st = step_type(s["type"])
        name = names[i]
        what = f"step {name!r} ({st.name})"
        ck.keys(s, list(COMMON_STEP_KEYS) + list(st.options), w, what)
        common = {k: ck.option(s, k, opt, w, what, opt.default)
                  for k, opt in COMMON_STEP_KEYS.items()}
        opts = _step_options(ck, s, st, w, what)
        _check_model_names(ck, opts, models, w, what)
        if isinstance(opts.get("points"), str):  # a file of given points, near the study
            opts["points"] = points_file(ck, opts["points"], base, w + ("points",))
        quick = common["quick"] or {}
        ck.keys(quick, list(st.options), w + ("quick",), f"quick = {{...}} of {what}")
        quick = {k: ck.option(quick, k, st.options[k], w + ("quick",),
                              f"quick = {{...}} of {what}") for k in quick}
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
                ck.fail(w + ("data",), "the name of a [data.NAME] table "
                        f"({', '.join(data) or 'none defined'}) or \"step.samples\""
                        f"{close_hint(data_ref, list(data))}", data_ref)
        elif st.needs_data:
            if len(data) == 1:
                data_ref = next(iter(data))
            elif not (st.data_optional and not data):
                ck.fail(w, f"data = \"NAME\" in {what} (data sets: {', '.join(data) or 'none'})")
        sel_p = common["parameters"]
        known = pnames + [n for other in raw if isinstance(other.get("distributions"), dict)
                          for n in other["distributions"] if n not in pnames]
        if sel_p is not None:
            for p in sel_p:
                if p not in known:
                    ck.fail(w + ("parameters",), f"names from [parameters] ({', '.join(known)})"
                            f"{close_hint(p, known)}", p)
        sel_r = common["responses"]
        if sel_r is not None:
            valid_r = (_rotor_responses(model.flight is not None) if model.kind == "preset"
                       else model.responses)
            for r in sel_r:
                if r not in valid_r:
                    ck.fail(w + ("responses",), f"responses of the model "
                            f"({', '.join(valid_r)}){close_hint(r, valid_r)}", r)
        _check_model_responses(ck, doc, opts, models, model, sel_r, what)
        for need in common["needs"] or ():
            if need not in STEP_NEEDS:
                ck.fail(w + ("needs",), f"outside software among {', '.join(STEP_NEEDS)}"
                        f"{close_hint(str(need), list(STEP_NEEDS))}", str(need))
        fixed = ck.numbers(common["fixed"] or {}, w + ("fixed",), f"{what} fixed")
        for k in fixed:
            inputs.check(w + ("fixed", k), k)
        if st.check is not None:
            st.check(_step_check(ck, raw, names, i, inputs, opts, sel_r, tuple(pnames)))
        dists: tuple[ParameterSpec, ...] = ()
        if common["distributions"] is not None:
            dists = _parse_parameters(ck, common["distributions"], inputs,
                                      w + ("distributions",),
                                      {p.name: p.input for p in params if p.input})
        if data_ref in data:
            _check_data_columns(ck, w + (("data",) if "data" in s else ()), st, opts,
                                data[data_ref], sel_r, model.responses, what)
        if isinstance(opts.get("points"), dict) and source is None:  # its inputs are known
            points_columns(opts["points"], sel_p or [*pnames, *(d.name for d in dists
                                                                if d.name not in pnames)])
        steps.append(StepSpec(
            name=name, type=st.name, index=i, options=opts, source=source, parameters=sel_p,
            distributions=dists,
            responses=sel_r, fixed=fixed, data=data_ref, title=common["title"],
            quick=quick, line=ck.loc.line(*w), needs=tuple(common["needs"] or ()),
        ))
    if not pnames and any(s.type != "forward_check" or s.source is None for s in steps):
        ck.fail(("parameters",), "at least one [parameters.NAME] table")
    _check_data_used_once(ck, raw, steps, model, data)
    return tuple(steps)


def _check_data_columns(ck: Checker, where: tuple, st: StepType, opts: Mapping,
                        data: DataSet, responses: tuple[str, ...] | None,
                        model_responses: Sequence[str], what: str) -> None:
    """The columns a step reads from its ``[data.NAME]`` table are there, when the study is
    read (not after the steps before it ran): its responses (a ``forward_check`` compares
    those the data has, at least one), the column matching its conditions (``match``, else
    the first key of ``sweep`` or ``conditions``), ``normalize_by``'s, a discrepancy's
    ``configuration`` and the columns of ``couple``. The error names the file and the columns
    it has."""
    cols = list(data.columns)
    used = list(responses or model_responses)
    need: list[str] = []
    if st.name != "forward_check" or responses is not None:
        need += used
    elif used and not any(r in cols for r in used):
        need += used
    grid = opts.get("sweep") or opts.get("conditions")
    match = opts.get("match") or (next(iter(grid)) if isinstance(grid, Mapping) and grid
                                  else None)
    if isinstance(match, str) and isinstance(grid, Mapping):
        need.append(match)
    if isinstance(opts.get("normalize_by"), Mapping):
        need += list(opts["normalize_by"])
    if opts.get("discrepancy") and isinstance(opts.get("configuration"), str):
        need.append(opts["configuration"])
    if isinstance(opts.get("couple"), Mapping):
        need += [c for c in opts["couple"].values() if isinstance(c, str)]
    missing = [c for c in dict.fromkeys(need) if c not in cols]
    if missing:
        source = data.source if data.source == "inline" else Path(data.source).name
        ck.fail(where, f"data {data.name!r} ({source}) to have the columns {what} reads: "
                f"{', '.join(dict.fromkeys(need))}; it has {', '.join(cols)}",
                "no column " + ", ".join(missing))


def _check_model_names(ck: Checker, opts: Mapping, models: Mapping[str, ModelSpec], w: tuple,
                       what: str) -> None:
    """A step option ``models`` (a list of names) and ``high_fidelity`` (a name) name
    ``[models.NAME]`` tables."""
    known = list(models)
    hf = opts.get("high_fidelity")
    if isinstance(hf, str) and hf not in known:
        defined = ", ".join(known) or f"none; add a [models.{hf}] table"
        ck.fail(w + ("high_fidelity",), f"the name of a [models.NAME] table as the "
                f"high_fidelity of {what} (defined: {defined}){close_hint(hf, known)}", hf)
    names = opts.get("models")
    if not isinstance(names, (list, tuple)):
        return
    for n in names:
        if n not in known:
            defined = ", ".join(known) or f"none; add a [models.{n}] table"
            ck.fail(w + ("models",), f"names of [models.NAME] tables in the models of {what} "
                    f"(defined: {defined}){close_hint(str(n), known)}", str(n))


def _check_data_used_once(ck: Checker, raw: list, steps: list[StepSpec], model,
                          data: Mapping[str, DataSet]) -> None:
    """Each observation calibrates once: a step calibrating (a type with a ``reuse_data``
    option) responses it shares with an earlier step it conditions on (through its chain of
    ``from``), on rows holding the same values, fails naming both lines, both data sets and the
    rows, unless it says ``reuse_data = true`` (the report then states it). Rows are compared
    by content (:func:`_same_rows`), so a second ``[data.NAME]`` table over the same file, a
    copy of the CSV or inline columns repeating the numbers are caught as surely as the same
    name. Alternative calibrations of the same data that do not condition on each other (with
    and without a discrepancy, say) are comparisons, not reuse."""
    by_name = {st.name: st for st in steps}

    def upstream(st: StepSpec) -> set[str]:
        names: set[str] = set()
        while st.source is not None and st.source[0] not in names:
            names.add(st.source[0])
            st = by_name[st.source[0]]
        return names

    seen: list[tuple[StepSpec, set[str]]] = []
    for st in steps:
        if "reuse_data" not in step_type(st.type).options or st.data is None:
            continue
        resp = set(st.responses or model.responses)
        before = upstream(st)
        for earlier, used in seen:
            assert earlier.data is not None  # only steps with data are seen
            both = sorted(resp & used)
            if earlier.name not in before or not both or st.options.get("reuse_data"):
                continue
            if st.data in data and earlier.data in data:
                rows = _same_rows(data[st.data], data[earlier.data], both)
                if not rows:
                    continue
                where = f" (rows {_row_list(rows)})"
            elif st.data == earlier.data:  # a step's samples: known by name when read
                where = ""
            else:
                continue
            key = ("data",) if "data" in raw[st.index] else ()
            same = ("" if st.data == earlier.data else
                    f"; data set {st.data!r}{_source(data.get(st.data))} holds the same "
                    f"values{where} as data set {earlier.data!r}"
                    f"{_source(data.get(earlier.data))}, compared row by row")
            ck.fail(("steps", st.index, *key),
                    f"data not calibrated before: step {earlier.name!r} (line "
                    f"{earlier.line}) already calibrates {', '.join(both)} of data set "
                    f"{earlier.data!r}{same}. Calibrate the new observations only (e.g. "
                    f"responses = [...] and from = \"{earlier.name}.posterior\" to condition "
                    "on the earlier step), or set reuse_data = true to count them twice on "
                    "purpose (the report states it)",
                    f"step {st.name!r} calibrating {', '.join(both)} of {st.data!r}{where} "
                    "again")
        seen.append((st, resp))


def _same_rows(later: DataSet, earlier: DataSet, responses: Sequence[str]) -> list[int]:
    """Rows of ``later`` (0-based) equal, in every column both data sets have, to a row of
    ``earlier``, when the columns both have include some of ``responses`` (bit for bit: a
    copy, an alias or a subset of the same measurements, not merely close numbers)."""
    common = [c for c in later.columns if c in earlier.columns]
    if not any(r in common for r in responses):
        return []

    def keys(d: DataSet) -> list[bytes]:
        m = np.ascontiguousarray(d.matrix(common), dtype=np.float64) + 0.0  # -0.0 == 0.0
        return [row.tobytes() for row in m]

    known = set(keys(earlier))
    return [i for i, k in enumerate(keys(later)) if k in known]


def _row_list(rows: Sequence[int]) -> str:
    """0-based row indices as 1-based ranges, ``1-3, 7``."""
    parts: list[str] = []
    start = prev = rows[0]
    for r in [*rows[1:], None]:
        if r is not None and r == prev + 1:
            prev = r
            continue
        parts.append(f"{start + 1}" if start == prev else f"{start + 1}-{prev + 1}")
        if r is not None:
            start = prev = r
    return ", ".join(parts)


def _source(d: DataSet | None) -> str:
    return "" if d is None or d.source == "inline" else f" ({Path(d.source).name})"


def _step_check(ck: Checker, raw: list, names: list[str], i: int, inputs: ModelInputs,
                opts: dict, responses: tuple[str, ...] | None, parameters: tuple[str, ...]
                ) -> StepCheck:
    """The view of step ``i`` that its type's ``check`` hook gets (key paths relative to the
    step)."""
    w = ("steps", i)

    def fail(key: tuple, expected: str, found: str | None = None) -> NoReturn:
        ck.fail(w + tuple(key), expected, found)

    def reference(ref: str, key: str, attrs: tuple[str, ...]) -> tuple[str, str]:
        return _check_ref(ck, raw, names, i, ref, key, attrs)

    def check_input(key: tuple, name: str) -> None:
        inputs.check(w + tuple(key), name)

    def numbers(tbl: Mapping, key: tuple, what: str) -> dict[str, float]:
        return ck.numbers(tbl, w + tuple(key), what)

    return StepCheck(opts, inputs.model, responses, parameters, fail, reference, check_input,
                     numbers)


def _check_ref(ck: Checker, raw: list, names: list[str], i: int, ref: str, key: str,
               attrs: tuple[str, ...]) -> tuple[str, str]:
    w = ("steps", i, key)
    m = re.fullmatch(r"([A-Za-z_][A-Za-z0-9_\-]*)\.([a-z_]+)", ref)
    if not m:
        ck.fail(w, f"{key} = \"STEP.{'|'.join(attrs)}\"", ref)
    target, attr = m.groups()
    if target not in names:
        ck.fail(w, f"{key} = \"STEP.ATTR\" naming an earlier step ({', '.join(names[:i])})"
                f"{close_hint(target, names)}", ref)
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
    provides = step_type(typ).provides
    if attr not in attrs or attr not in provides:
        ck.fail(w, f"{key} = \"{target}.<attr>\" with <attr> one of "
                f"{', '.join(a for a in attrs if a in provides) or '(none)'} "
                f"(step {target!r} is a {typ} step)", ref)
    return target, attr
