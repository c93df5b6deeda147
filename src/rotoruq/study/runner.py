"""Run a study: steps in order, results written as they finish, unchanged steps reused.

>>> results = run_study("src/rotoruq/studies/quick.toml")                 # doctest: +SKIP
>>> results["forward"].get("mean/thrust")                     # doctest: +SKIP

Output directory (``[study] output``, or ``out=``)::

    study.toml  study.json  evaluations.sqlite  steps/<name>/...   (see rotoruq.results)

Re-running: each step's fingerprint hashes its spec, the model (with the code that computes
its answers), its distributions, data and seed, the code of its step type and methods, and
the fingerprints of the steps it takes from (:data:`IDENTITY_PARTS`; :func:`why_rerun` names
the part that changed). A step whose fingerprint matches the
saved one is loaded, not recomputed; model evaluations go through the evaluation store when
the evaluation layer provides one, so a changed step still reuses identical evaluations.
"""

from __future__ import annotations

import hashlib
import inspect
import json
import logging
import math
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import write_bytes
from ..errors import ParameterError
from ..evaluation.identity import (
    code_digest,
    code_parts,
    code_version,
    model_code_parts,
    model_identity,
)
from ..methods._common import one_blas_thread
from ..params import ParameterSpace
from ..results import (
    IncompleteStepError,
    StepResult,
    clean_partial_saves,
    load_step,
    save_step,
    save_study_info,
)
from ..steps import StepContext, run_step, step_type
from ..steps.bayes_calibration import sequential_prior
from ..steps.options import close_hint
from .console import gathered_messages
from .lock import results_lock
from .schema import load_study
from .spec import ModelSpec, StepSpec, Study, function_variables

__all__ = ["run_study", "StudyRun", "build_model", "build_model_factory", "step_options",
           "model_record", "spanwise_record", "why_rerun", "IDENTITY_PARTS", "step_code_parts",
           "step_references"]

log = logging.getLogger(__name__)

ModelFactory = Callable[..., Any]


@dataclass(frozen=True, eq=False)
class StudyRun:
    """Outcome of :func:`run_study`: the results by step name, the output directory and which
    steps were reused from a previous run. ``run["NAME"]`` is the result of step NAME.

    Attributes
    ----------
    study : Study
        The study that ran.
    out : Path
        The output directory (each step's results in a folder of its own).
    results : mapping of str to StepResult
        Step name -> its result, in the study's order.
    reused : tuple of str
        Steps whose saved result was reused (nothing they depend on changed).
    seconds : mapping of str to float
        Step name -> wall seconds it took in this run.
    skipped : tuple of str
        Steps neither named by ``only`` nor needed by one it names, without a saved result,
        and steps whose outside software (``needs = ["mbdyn"]``) is not found.
    skip_reasons : mapping of str to str
        Step name -> the reason, for the latter.
    """

    study: Study
    out: Path
    results: Mapping[str, StepResult]
    reused: tuple[str, ...] = ()
    seconds: Mapping[str, float] = field(default_factory=dict)
    #: steps neither named by ``only`` nor needed by one it names, without a saved result,
    #: and steps whose outside software (``needs``) is missing
    skipped: tuple[str, ...] = ()
    #: step name -> why it was skipped, for the steps skipped for a missing ``needs``
    skip_reasons: Mapping[str, str] = field(default_factory=dict)

    def __getitem__(self, name: str) -> StepResult:
        return self.results[name]


def build_model(study: Study, inputs: Sequence[str], responses: Sequence[str],
                fixed: Mapping[str, float], out: Path | None = None, *,
                model: str | None = None) -> Any:
    """The study's ``[model]`` (or, with ``model=NAME``, its ``[models.NAME]``) for one step
    (an object of the :class:`rotoruq.model.Model` protocol), without the evaluation store: a
    :class:`~rotoruq.rotor.model.RotorModel` (at the table's ``discretization``), or an
    :class:`~rotoruq.evaluation.external.ExternalModel` over ``inputs`` plus the fixed inputs
    (written into every parameters file), wrapped so that its inputs are ``inputs``, or one of
    Dakota's test functions (:func:`~rotoruq.testfunctions.dakota_function`) whose variables
    are :func:`~rotoruq.study.spec.function_variables`.

    A named model's own ``fixed`` values take precedence over ``fixed`` (the step's: the
    study's operating point). Parameters that feed a model input of another name
    (``[parameters.kp] input = "k_pitch_link"``) reach it through
    :class:`~rotoruq.evaluation.renamed.RenamedInputs`.

    Paths in an external model (words of ``command`` that name files, ``templates``,
    ``files``) are relative to the study file's folder; ``workdir`` is relative to the results
    folder ``out`` (default ``out/work``, ``out/work/NAME`` for a named model).
    """
    renamed = study.renamed_inputs
    if any(n in renamed for n in inputs) or any(k in renamed for k in fixed):
        from ..evaluation.renamed import RenamedInputs

        inner = build_model(study, [renamed.get(n, n) for n in inputs], responses,
                            {renamed.get(k, k): v for k, v in fixed.items()}, out, model=model)
        return RenamedInputs(inner, inputs)
    spec = study.model_spec(model)
    if model is not None:
        fixed = {**fixed, **spec.fixed}
    if spec.preset is not None:
        from ..rotor.model import RotorModel
        from ..rotor.presets import get_preset

        preset = get_preset(spec.preset, **dict(spec.preset_options))
        if spec.flight is not None:
            from ..rotor.forward import ForwardRotorModel

            flight: dict[str, Any] = dict(spec.flight)
            if flight.get("trim") == "none":
                flight["trim"] = None
            grid: dict[str, Any] = dict(spec.discretization)
            return ForwardRotorModel(preset, names_in=list(inputs), names_out=list(responses),
                                     fixed=dict(fixed), **flight, **grid)
        return RotorModel(preset, names_in=list(inputs), names_out=list(responses),
                          fixed=dict(fixed), **dict(spec.discretization))
    if spec.function is not None:
        from ..testfunctions import dakota_function

        variables = function_variables(spec, study.parameters, study.model if model else None)
        return dakota_function(spec.function, variables, spec.responses, spec.components,
                               fixed={k: v for k, v in fixed.items() if k not in inputs},
                               inputs=list(inputs), outputs=list(responses))
    from ..evaluation.external import ExternalModel, FileContract, WorkDirectory
    from ..model import FixedInputs

    ext = spec.external
    if ext is None:
        raise ParameterError(f"{study.path}: {_table(model)} needs preset = ... or "
                             "command = [...]")
    base = study.path.parent if study.path is not None else Path.cwd()
    out = Path(out) if out is not None else study.info.output

    def near_study(word: str) -> str:
        p = Path(word)
        if "{" in word or p.is_absolute() or not (base / p).exists():
            return word
        return str((base / p).absolute())

    policy: str | dict[str, list[float]]
    if ext.failure == "retry":
        policy = f"retry:{max(1, ext.retries)}"
    elif ext.failure == "recover":
        if ext.recover is None:
            raise ParameterError(f"{study.path}: {_table(model)} failure = \"recover\" needs "
                                 "recover = [one value per response]")
        policy = {"recover": list(ext.recover)}
    else:
        policy = ext.failure
    workdir = Path(ext.workdir) if ext.workdir else Path("work", *([model] if model else []))
    if not workdir.is_absolute():
        workdir = out / workdir
    names_in = list(inputs) + [n for n in fixed if n not in inputs]
    ext_model = ExternalModel(
        [near_study(w) for w in ext.command], names_in, list(responses),
        workdir=WorkDirectory(workdir, template_files=[base / t for t in ext.templates],
                              copy_files=[base / f for f in ext.files]),
        contract=FileContract(parameters_format=ext.parameters_format),
        timeout=ext.timeout, failure_policy=policy, gradients=ext.gradients,
        derivative_variables=list(inputs) or None,
    )
    fixed_here = {k: v for k, v in fixed.items() if k not in inputs}
    return FixedInputs(ext_model, fixed_here) if fixed_here else ext_model


def _table(model: str | None) -> str:
    return "[model]" if model is None else f"[models.{model}]"


def build_model_factory(study: Study, store_path: Path | None = None,
                        out: Path | None = None) -> ModelFactory:
    """Model builder ``f(inputs, responses, fixed, model=None)`` for the study's ``[model]``
    and, by name, its ``[models.NAME]`` (see :func:`build_model`), wrapped in the evaluation
    layer's store-backed Evaluator when a store or a parallel executor is set. Each model
    has its own identity in the store (its configuration and code,
    :func:`~rotoruq.evaluation.identity.model_identity`): one model's runs are never served
    for another's.

    Examples
    --------
    >>> factory = build_model_factory(load_study("mf.toml"))          # doctest: +SKIP
    >>> lf = factory(["collective_deg"], ["thrust"], {}, model="coarse")  # doctest: +SKIP
    """

    def base(inputs, responses, fixed, model=None):
        return build_model(study, inputs, responses, fixed, out, model=model)

    return _with_store(base, study, store_path)


def _build(factory: Callable, inputs, responses, fixed, model: str | None):
    """``factory(inputs, responses, fixed)``, with ``model=`` for a named model: a Python
    ``model_factory`` that builds only ``[model]`` cannot build a named one."""
    if model is None:
        return factory(inputs, responses, fixed)
    try:
        params: Mapping[str, inspect.Parameter] = inspect.signature(factory).parameters
    except (TypeError, ValueError):
        params = {}
    if params and "model" not in params and not any(p.kind is p.VAR_KEYWORD
                                                    for p in params.values()):
        raise ParameterError(f"the model factory builds only [model]; the named model "
                             f"{model!r} needs a factory f(inputs, responses, fixed, model=NAME)")
    return factory(inputs, responses, fixed, model=model)


def _with_store(factory: ModelFactory, study: Study, store_path: Path | None) -> ModelFactory:
    """Evaluate through the evaluation layer: the SQLite store (reuse on re-run) and the
    ``[executor]`` (serial, processes, dask)."""
    ex = study.executor
    if (store_path is None or not study.store.enabled) and ex.kind == "serial":
        return factory
    from ..evaluation.evaluator import Evaluator
    from ..evaluation.executors import make_executor

    if ex.kind == "processes":
        executor = make_executor("processes", max_workers=ex.workers)
    elif ex.kind == "dask":
        executor = make_executor("dask", address=ex.scheduler)
    else:
        executor = make_executor("serial")

    def wrapped(inputs, responses, fixed, model=None):
        return Evaluator(_build(factory, inputs, responses, fixed, model), store=store_path,
                         executor=executor, study=study.info.name)

    return wrapped


def step_options(step: StepSpec, quick: bool) -> dict:
    """The step's options, reduced for ``quick`` runs (the step type's ``quick`` bounds, then
    ``quick = {...}`` from the study file)."""
    opts = dict(step.options)
    if quick:
        for k, v in step_type(step.type).quick.items():
            if opts.get(k) is not None:
                opts[k] = min(opts[k], v)
        opts.update(step.quick)
    return opts


def _step_space(study: Study, step: StepSpec, previous: Mapping[str, StepResult]
                ) -> tuple[ParameterSpace, dict[str, float]]:
    """Uncertain inputs of a step and the inputs it fixes.

    The step's parameters (when not listed: those of the ``from`` step, else all of the
    study's, plus the step's own ``distributions``) take their distributions from
    ``from`` where it provides them (a calibration taking an earlier calibration's
    posterior: the density of its chain, :func:`~rotoruq.steps.bayes_calibration.
    sequential_prior`), else from ``[parameters]``; the step's own
    ``distributions`` take precedence over both. Parameters of the study or
    of the ``from`` step that the step does not use are fixed at their means.
    """
    source = {}
    if step.source is not None:
        earlier = previous[step.source[0]]
        source = earlier.distribution_objects()
        if (step.type == earlier.type == "bayes_calibration" and step.source[1] == "posterior"
                and "chain" in earlier.arrays):  # sequential calibration keeps the shape
            source = {**source, **sequential_prior(earlier)}
    own = {p.name: p.distribution for p in step.distributions}
    if step.parameters is not None:
        names = list(step.parameters)
    elif source:
        names = list(source) + [n for n in own if n not in source]
    else:
        names = list(study.parameter_names) + [n for n in own if n not in
                                               study.parameter_names]
    dists = []
    for n in names:
        if n in own:
            dists.append((n, own[n]))
        elif n in source:
            dists.append((n, source[n]))
        else:
            dists.append((n, study.parameter(n).distribution))
    fixed = dict(study.model.fixed)
    for p in study.parameters:
        if p.name not in names:
            fixed[p.name] = p.distribution.mean
    for n, d in source.items():
        if n not in names:
            fixed[n] = d.mean
    fixed.update(step.fixed)
    for n in names:
        fixed.pop(n, None)
    corr = None
    if study.correlation is not None:  # not for distributions taken from an earlier step
        corr = study.correlation.matrix_for(names, [n for n in names if n in own or
                                                    n not in source])
        if corr is not None and not step_type(step.type).correlated:
            raise ParameterError(
                f"step {step.name!r} (line {step.line}): a {step.type} step assumes independent "
                f"inputs, and the [correlation] table (line {study.correlation.line}) "
                "correlates its parameters; list uncorrelated ones with parameters = [...] or "
                "drop the correlation")
    return ParameterSpace(dists, correlation=corr), fixed


def _step_data(study: Study, step: StepSpec, responses, previous):
    """(observations (k, m) or None, all columns of the data set)."""
    if step.data is None:
        return None, {}
    if "." in step.data:
        src = previous[step.data.split(".")[0]]
        cols = {c: src.column("outputs", c) for c in src.columns("outputs")}
    else:
        cols = dict(study.data[step.data].columns)
    if step.type == "forward_check":
        return None, cols
    missing = [r for r in responses if r not in cols]
    if missing:
        raise ParameterError(
            f"step {step.name!r}: data {step.data!r} has no column for {missing}; it has "
            f"{list(cols)}")
    return np.column_stack([cols[r] for r in responses]), cols


def _step_targets(step: StepSpec, options, previous) -> dict[str, tuple[float, float]]:
    t = options.get("targets")
    if t is None:
        return {}
    if isinstance(t, str):
        src = previous[t.split(".")[0]]
        out = {}
        for c in src.columns("outputs"):
            v = src.column("outputs", c)
            v = v[np.isfinite(v)]
            out[c] = (float(np.mean(v)), float(np.std(v, ddof=1)))
        return out
    return {r: (float(v[0]), float(v[1])) for r, v in t.items()}


def _json_default(o: Any) -> Any:
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    if isinstance(o, float) and not math.isfinite(o):
        return repr(o)
    return repr(o)


def _digest(obj: Any) -> str:
    text = json.dumps(obj, sort_keys=True, default=_json_default)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


#: What a step's fingerprint is made of (saved as ``meta["identity"]``; ``rotoruq show
#: RESULTS --why-rerun`` names the part that changed).
IDENTITY_PARTS = {
    "spec": "the step's table in the study file, its options, seed, position or --quick",
    "inputs": "the step's input distributions, their correlation or fixed inputs",
    "data": "the step's data",
    "model": "the model (its configuration or the code computing its answers)",
    "code": "the code computing the step (its step module and methods)",
    "upstream": "a step it takes from",
}


def unmet_needs(step: StepSpec) -> str:
    """Why ``step`` cannot run here: the outside software of its ``needs`` that is not found
    ("" when all is there). MBDyn is looked up as the MBDyn driver does
    (:func:`~rotoruq.mbdyn.solver.find_mbdyn` with the build tool's install)."""
    for need in step.needs:
        if need == "mbdyn":
            from ..mbdyn.solver import MBDynNotFoundError, find_mbdyn

            try:
                find_mbdyn(build_prefix=True)
            except MBDynNotFoundError as exc:
                return f"needs MBDyn, not found here: {exc}"
    return ""


def _named_models(options: Mapping) -> tuple[str, ...]:
    """The ``[models.NAME]`` a step uses: its option ``models`` (a list of names) and its
    ``high_fidelity`` (a name)."""
    names = options.get("models")
    hf = options.get("high_fidelity")
    return ((tuple(names) if isinstance(names, (list, tuple)) else ())
            + ((hf,) if isinstance(hf, str) else ()))


def _model_doc(spec: ModelSpec) -> dict:
    """A model table as its step's identity digests it: the fields added with
    ``[models.NAME]`` (its name, a rotor's discretization) only where set, so that the
    fingerprints of steps saved before them still match."""
    doc = asdict(spec)
    del doc["name"]
    if not doc["discretization"]:
        del doc["discretization"]
    if doc["flight"] is None:
        del doc["flight"]
    if doc["external"] is not None and doc["external"]["gradients"] == "finite_difference":
        del doc["external"]["gradients"]
    return doc


#: The study file's names for the fields of a step's spec (the rest are the field's own).
_SPEC_NAMES = {"source": "from", "quick": "quick options"}


def _short(value: Any) -> str:
    """``value`` as compact JSON, or a digest when that is long (a reason stays a line)."""
    text = json.dumps(value, sort_keys=True, default=_json_default)
    return text if len(text) <= 100 else f"(digest {_digest(value)[:12]})"


def _spec_keys(spec: Mapping[str, Any]) -> dict[str, str]:
    """The spec part of a step's identity key by key, named as the study file names them,
    each value as short JSON: :func:`why_rerun` names the keys that changed, with their old
    and new values."""
    keys: dict[str, Any] = {}
    for k, v in spec["step"].items():
        if k != "options":
            keys[_SPEC_NAMES.get(k, k)] = v
    for k, v in spec["options"].items():
        keys[k if k not in keys else f"option {k}"] = v
    keys["[model]"] = spec["model"]
    keys["[models]"] = spec.get("models")
    keys["[study] seed"] = spec["seed"]
    keys["position in the study"] = spec["index"]
    keys["--quick"] = spec["quick"]
    return {k: _short(v) for k, v in keys.items()}


def _identity_parts(study: Study, step: StepSpec, space: ParameterSpace, fixed, options,
                    data, previous, quick: bool, model_id: str, code: str) -> dict:
    """The parts of a step's identity, each a digest (see :data:`IDENTITY_PARTS`)."""
    refs = [step.source[0]] if step.source else []
    for ref in (step.data, options.get("targets"), options.get("u_num")):
        if isinstance(ref, str) and "." in ref:
            refs.append(ref.split(".")[0])
    # needs: where the step can run, not what it computes
    spec = {"step": {k: v for k, v in asdict(step).items()
                     if k not in ("line", "index", "needs")},
            "options": options, "model": _model_doc(study.model),
            "seed": study.info.seed, "index": step.index, "quick": quick}
    if _named_models(options):
        spec["models"] = {n: _model_doc(study.model_spec(n)) for n in _named_models(options)}
    return {
        "spec": _digest(spec),
        # not part of the fingerprint (it is the spec's digest): what why_rerun names
        "spec_keys": _spec_keys(spec),
        "inputs": _digest({"space": [(n, d.describe()) for n, d in
                                     zip(space.names, space.distributions, strict=True)],
                           "fixed": dict(sorted(fixed.items())),
                           # only when correlated: the fingerprints of independent inputs stay
                           **({} if space.correlation is None else
                              {"correlation": np.asarray(space.correlation).tolist()})}),
        "data": _digest(None if data is None else np.asarray(data).tolist()),
        "model": model_id,
        "code": code,
        "upstream": {r: previous[r].fingerprint for r in refs},
    }


class _FailureCount:
    """A step's model that counts its failed evaluations by reason (saved as
    ``meta["failed_evaluations"]``: the report's provenance and ``rotoruq show`` list them).
    Everything else is the wrapped model's."""

    def __init__(self, model, counts: Counter[str]):
        self._model, self._counts = model, counts

    def __getattr__(self, name):
        from ..model import has_gradient

        if name == "gradient" and not has_gradient(self._model):
            raise AttributeError(name)
        if name == "evaluate_gradient":  # a driver's gradient runs fail like any evaluation
            joint = getattr(self._model, name)

            def counted(x):
                got = joint(x)
                self._counts.update(got.failures.values())
                return got

            return counted
        return getattr(self._model, name)

    def evaluate(self, x):
        from ..model import evaluate

        batch = evaluate(self._model, x)
        self._counts.update(batch.failures.values())
        return batch

    def __call__(self, x):
        return self.evaluate(x).values


def _counting_failures(factory: ModelFactory, counts: Counter[str]) -> ModelFactory:
    def make(inputs, responses, fixed, model=None):
        return _FailureCount(_build(factory, inputs, responses, fixed, model), counts)

    return make


def _seed(study: Study, step: StepSpec, options) -> np.random.Generator:
    if options.get("seed") is not None:
        return np.random.default_rng(options["seed"])
    return np.random.default_rng(np.random.SeedSequence([study.info.seed, step.index]))


def run_study(
    study: Study | str | Path,
    *,
    out: str | Path | None = None,
    quick: bool = False,
    model_factory: ModelFactory | None = None,
    only: Sequence[str] | None = None,
    jobs: int = 1,
) -> StudyRun:
    """Run the steps of ``study`` in order and write their results.

    Parameters
    ----------
    study : Study, or path of a study file.
    out : output directory (default: the study's ``[study] output``).
    quick : reduce sample sizes (each step type's ``quick`` bounds and each step's
        ``quick = {...}``).
    model_factory : ``f(inputs, responses, fixed) -> Model`` replacing the ``[model]`` table
        (for Python models; tests); with a keyword ``model=NAME`` (None for ``[model]``) it
        also replaces the ``[models.NAME]`` tables.
    only : run only these steps; the others are loaded from an earlier run where saved
        (whatever their fingerprint), else skipped (:attr:`StudyRun.skipped`). A step one of
        them takes from must be saved or named too.
    jobs : steps run at once, each in a worker process (not forked from this one) as soon
        as the steps it takes from are done; the numbers are the same bits as one after the
        other (each step's seed is the study's seed and its position). Default 1. The steps
        of a study with a ``model_factory``, an external model or a parallel ``[executor]``
        run one after the other whatever ``jobs`` says (logged).

    Notes
    -----
    Progress (a line per step, a status line every ``steps.STATUS_INTERVAL`` s while a step
    runs) goes to the ``rotoruq.study`` loggers at INFO; the CLI shows it on stderr.
    """
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ValueError(f"jobs must be an integer >= 1, got {jobs!r}")
    if not isinstance(study, Study):
        study = load_study(study)
    out = Path(out) if out is not None else study.info.output
    with results_lock(out, "run") as lock:
        if lock.taken_over and lock.taken_over.get("pid"):
            log.warning("[%s] taking over %s from a run that stopped (PID %s on %s)",
                        study.info.name, out, lock.taken_over.get("pid"),
                        lock.taken_over.get("host", "?"))
        clean_partial_saves(out)
        # LAPACK on one thread: the same seed gives the same bits at any BLAS thread count
        with one_blas_thread():
            return _run_locked(study, out, quick, model_factory, only, jobs)


@dataclass(frozen=True, eq=False)
class _Planned:
    """One step as the runner sees it before running: its context parts and identity."""

    step: StepSpec
    options: dict
    space: ParameterSpace
    fixed: dict
    responses: list
    data: Any
    columns: Any
    parts: dict
    fingerprint: str
    model_code: dict
    step_code: dict
    spec_keys: dict


def step_code_parts(type_name: str) -> dict[str, str]:
    """The code part of the fingerprint of a step of type ``type_name``: :func:`code_parts` of
    its :attr:`~rotoruq.steps.base.StepType.code_modules` (its module, the modules it lists in
    ``modules``, and what they import within rotoruq).

    Examples
    --------
    >>> parts = step_code_parts("pce")
    >>> "rotoruq/steps/pce.py" in parts, "rotoruq/methods/levels.py" in parts
    (True, True)
    """
    return code_parts(step_type(type_name).code_modules)


def _plan_step(study: Study, step: StepSpec, results: Mapping[str, StepResult], quick: bool,
               probe_factory: Callable, identities: dict) -> _Planned:
    options = step_options(step, quick)
    space, fixed = _step_space(study, step, results)
    responses = list(step.responses or study.model.responses)
    data, columns = _step_data(study, step, responses, results)
    ids, model_code = [], {}
    for name in (None, *_named_models(options)):
        key = (name, tuple(space.names), tuple(responses), tuple(sorted(fixed.items())))
        if key not in identities:
            probe = _build(probe_factory, list(space.names), list(responses), dict(fixed), name)
            identities[key] = (model_identity(probe), model_code_parts(probe))
            close = getattr(probe, "close", None)
            if callable(close):
                close()
        ids.append(identities[key][0] if name is None else f"{name}={identities[key][0]}")
        model_code.update(identities[key][1])
    model_id = " + ".join(ids)
    step_code = step_code_parts(step.type)
    parts = _identity_parts(study, step, space, fixed, options, data, results, quick,
                            model_id, code_digest(step_code))
    spec_keys = parts.pop("spec_keys")
    return _Planned(step, options, space, fixed, responses, data, columns, parts,
                    _digest(parts), model_code, step_code, spec_keys)


def _run_locked(study: Study, out: Path, quick: bool, model_factory: ModelFactory | None,
                only: Sequence[str] | None, jobs: int = 1) -> StudyRun:
    if study.path.is_file():
        write_bytes(out / "study.toml", study.path.read_bytes())
    store_path = out / study.store.path if study.store.enabled else None
    factory = model_factory or build_model_factory(study, store_path, out)
    computed_store = None
    if store_path is not None:
        from ..evaluation.store import Store

        computed_store = Store(store_path)
    probe_factory = model_factory or partial(build_model, study, out=out)

    results: dict[str, StepResult] = {}
    reused, seconds, skipped = [], {}, []
    skip_reasons: dict[str, str] = {}
    identities: dict = {}
    needed = _needed_by(study, only)
    n_steps = len(study.steps)
    to_run: list[tuple[str, StepSpec]] = []
    for i_step, step in enumerate(study.steps, 1):
        # "[study] 3/12 sobol": where the run is, on every progress line of the step
        at = f"[{study.info.name}] {i_step}/{n_steps} {step.name}"
        folder = out / "steps" / step.name
        if only is not None and step.name not in only:
            saved = _saved(study, step, folder)
            if saved is not None:
                results[step.name] = saved
                reused.append(step.name)
                log.info("%s: reused (%s)", at, step.type)
            elif step.name in needed:
                users = ", ".join(needed[step.name])
                raise ParameterError(
                    f"step {step.name!r} has no saved result, and {users} (in --only) takes "
                    f"from it: add it, --only {' '.join([step.name, *only])}")
            else:
                skipped.append(step.name)
                log.info("%s: skipped (not in --only, no saved result)", at)
            continue
        missing = unmet_needs(step)
        if missing:
            skipped.append(step.name)
            skip_reasons[step.name] = missing
            log.info("%s: skipped (%s)", at, missing)
            continue
        to_run.append((at, step))
    _write_study_json(study, out, quick, skip_reasons)

    def planned(at: str, step: StepSpec) -> _Planned | None:
        """The step's plan, None when its saved result is reused (then in ``results``)."""
        plan = _plan_step(study, step, results, quick, probe_factory, identities)
        saved = _saved(study, step, out / "steps" / step.name)
        if saved is not None and saved.fingerprint == plan.fingerprint:
            results[step.name] = saved
            reused.append(step.name)
            log.info("%s: reused (%s)", at, step.type)
            return None
        log.info("%s: running %s (%s -> %s)", at, step.type, ", ".join(plan.space.names),
                 ", ".join(plan.responses))
        return plan

    def finished(at: str, res: StepResult, dt: float, lines: list[str]) -> None:
        results[res.name] = res
        seconds[res.name] = dt
        log.info("%s: done in %.1f s", at, dt)
        for line in lines:  # the methods' messages, under their step
            log.info("  %s: %s", at, line)

    why_serial = _why_serial(study, model_factory) if jobs > 1 else "one job"
    if why_serial is None and len(to_run) > 1:
        _run_parallel(study, out, quick, to_run, jobs, planned, finished, results)
    else:
        if jobs > 1 and why_serial:
            log.info("[%s] the steps run one after the other: %s", study.info.name, why_serial)
        for at, step in to_run:
            plan = planned(at, step)
            if plan is not None:
                finished(at, *_execute(study, plan, out, factory, computed_store, results, at))
    order = {s.name: i for i, s in enumerate(study.steps)}
    results = dict(sorted(results.items(), key=lambda kv: order[kv[0]]))
    return StudyRun(study, out, results, tuple(sorted(reused, key=order.__getitem__)),
                    dict(sorted(seconds.items(), key=lambda kv: order[kv[0]])), tuple(skipped),
                    skip_reasons)


def _execute(study: Study, plan: _Planned, out: Path, factory: ModelFactory, computed_store,
             results: Mapping[str, StepResult], at: str
             ) -> tuple[StepResult, float, list[str]]:
    """Run one planned step and save it: its result, wall seconds and the methods'
    messages gathered while it ran."""
    step = plan.step
    failed: Counter[str] = Counter()
    ctx = StepContext(
        name=step.name, type=step.type, options=plan.options, space=plan.space,
        responses=tuple(plan.responses), fixed=plan.fixed,
        make_model=_counting_failures(factory, failed),
        rng=_seed(study, step, plan.options), data=plan.data, data_columns=plan.columns,
        targets=_step_targets(step, plan.options, results),
        source=results[step.source[0]] if step.source else None,
        previous=dict(results), store=computed_store,
    )
    try:
        with gathered_messages() as gathered:
            res, dt = run_step(step_type(step.type).run, ctx, at)
    except ParameterError as exc:
        raise _at_step(exc, study, step) from exc
    meta = dict(res.meta)
    meta.update(failed_evaluations={"count": sum(failed.values()),
                                    "reasons": dict(failed.most_common(20)),
                                    # the first failure met (a Counter keeps that order)
                                    "first": next(iter(failed), None)})
    meta.update(seconds=dt, title=step.title, parameters=list(plan.space.names),
                responses=list(plan.responses), fixed=plan.fixed, options=plan.options,
                source=".".join(step.source) if step.source else None,
                model_identity=plan.parts["model"], code_version=code_version(),
                identity=plan.parts, spec_keys=plan.spec_keys, code_files=plan.step_code,
                model_code_files=plan.model_code,
                input_distributions={n: d.describe() for n, d in
                                     zip(plan.space.names, plan.space.distributions,
                                         strict=True)})
    res = StepResult(res.name, res.type, res.scalars, res.arrays, res.distributions, meta,
                     fingerprint=plan.fingerprint)
    export_chains(res, save_step(res, out))
    return res, dt, gathered.lines()


def _why_serial(study: Study, model_factory: ModelFactory | None) -> str | None:
    """Why a study's steps cannot run in worker processes (None: they can)."""
    if model_factory is not None:
        return "a Python model_factory is not sent to other processes"
    if any(study.model_spec(n).external is not None for n in (None, *study.models)):
        return "an external model numbers its evaluations' folders in one process"
    if study.executor.kind != "serial":
        return f"the [executor] ({study.executor.kind}) already runs evaluations in parallel"
    return None


#: A worker process's model factory and computed store per (study file, results folder).
_WORKER: dict[tuple[str, str], tuple[ModelFactory, Any]] = {}


def _execute_in_worker(study: Study, plan: _Planned, out: Path,
                       results: Mapping[str, StepResult], at: str
                       ) -> tuple[StepResult, float, list[str]]:
    """:func:`_execute` in a worker process of :func:`_run_parallel` (LAPACK on one thread,
    as in :func:`run_study`)."""
    key = (str(study.path), str(out))
    if key not in _WORKER:
        store_path = out / study.store.path if study.store.enabled else None
        store = None
        if store_path is not None:
            from ..evaluation.store import Store

            store = Store(store_path)
        _WORKER[key] = (build_model_factory(study, store_path, out), store)
    factory, store = _WORKER[key]
    with one_blas_thread():
        return _execute(study, plan, out, factory, store, results, at)


def _worker_logging(level: int | None) -> None:
    """A step's worker prints its progress lines as the run's process does."""
    if level is not None:
        from .console import configure_logging

        configure_logging()
        logging.getLogger("rotoruq").setLevel(level)


def _run_parallel(study: Study, out: Path, quick: bool, to_run: list[tuple[str, StepSpec]],
                  jobs: int, planned: Callable, finished: Callable,
                  results: dict[str, StepResult]) -> None:
    """Run the steps ``to_run`` on ``jobs`` worker processes (forked by a fork server,
    :func:`~rotoruq.study.workers.worker_context`), each as soon as the steps it takes from
    (:func:`step_references`) are done, in the study's order among those ready. Each
    step's numbers are a function of its inputs and its own seed (the study's seed and the
    step's position), so they are the same bits as one after the other."""
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    from .console import printing_level
    from .workers import worker_context

    waiting = list(to_run)
    running: dict[Any, tuple[str, StepSpec]] = {}
    # not forked from this process (a fork would copy its BLAS and numba locks): from a
    # fork server that imported this module, and with it numpy and the step types
    with worker_context((__name__,)) as ctx, ProcessPoolExecutor(
            min(jobs, len(to_run)), mp_context=ctx, initializer=_worker_logging,
            initargs=(printing_level(),)) as pool:
        try:
            while waiting or running:
                for item in list(waiting):
                    at, step = item
                    if any(r not in results for r in step_references(study, step)):
                        continue
                    waiting.remove(item)
                    plan = planned(at, step)
                    if plan is not None:
                        running[pool.submit(_execute_in_worker, study, plan, out,
                                            dict(results), at)] = item
                if not running:
                    if waiting:  # cannot happen: every reference is an earlier step
                        raise ParameterError(f"steps {[s.name for _, s in waiting]} wait for "
                                             "steps that do not run")
                    break
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                order = [s.name for s in study.steps]
                for future in sorted(done, key=lambda f: order.index(running[f][1].name)):
                    at, _ = running.pop(future)
                    finished(at, *future.result())
        except BaseException:
            pool.shutdown(wait=True, cancel_futures=True)
            raise


def _saved(study: Study, step: StepSpec, folder: Path) -> StepResult | None:
    """The step's saved result, None when there is none or it is incomplete (a warning)."""
    if not (folder / "result.json").is_file():
        return None
    try:
        return load_step(folder)
    except IncompleteStepError as exc:
        log.warning("[%s] %s: saved result is incomplete (%s); running it again",
                    study.info.name, step.name, exc)
        return None


def step_references(study: Study, step: StepSpec) -> list[str]:
    """The earlier steps ``step`` takes from: its ``from``, a ``data = "STEP.samples"`` and
    any option naming ``"STEP.ATTR"`` (``targets``, ``u_num``, ...)."""
    names = {s.name for s in study.steps}
    refs = [step.source[0]] if step.source else []
    for ref in (step.data, *step.options.values()):
        if isinstance(ref, str) and "." in ref and ref.split(".")[0] in names:
            refs.append(ref.split(".")[0])
    return [r for r in dict.fromkeys(refs) if r != step.name]


def _needed_by(study: Study, only: Sequence[str] | None) -> dict[str, list[str]]:
    """Steps not in ``only`` that a step in it takes from, directly or through another:
    {needed step: [steps of ``only`` needing it]}. Unknown names in ``only`` are an error."""
    if only is None:
        return {}
    names = [s.name for s in study.steps]
    for n in only:
        if n not in names:
            raise ParameterError(f"--only {n}: no such step in {study.path} (its steps: "
                                 f"{', '.join(names)}){close_hint(n, names)}")
    by_name = {s.name: s for s in study.steps}
    needed: dict[str, list[str]] = {}
    for n in only:
        todo, seen = list(step_references(study, by_name[n])), set()
        while todo:
            r = todo.pop()
            if r in seen:
                continue
            seen.add(r)
            if r not in only:
                needed.setdefault(r, []).append(repr(n))
            todo.extend(step_references(study, by_name[r]))
    return needed


def _at_step(exc: ParameterError, study: Study, step: StepSpec) -> ParameterError:
    """A step's bad input found while it runs (e.g. data without repeats and no stated
    measurement uncertainty), named by the study file and the line of its ``[[steps]]``."""
    text = str(exc)
    if str(study.path) in text or step.line is None:
        return exc
    named = text.startswith(f"step {step.name!r}")
    return ParameterError(f"{study.path}, line {step.line}: " + (
        text if named else f"step {step.name!r}: {text}"))


def export_chains(res: StepResult, folder: Path) -> Path | None:
    """Write a Bayes step's chains next to its saved arrays for other tools:
    ``chains.nc`` (arviz ``InferenceData`` layout) when xarray and h5netcdf are installed,
    else the documented ``chains.npz`` of :func:`rotoruq.methods.mcmc.export.write_chains`.
    None for a step without chains."""
    import importlib.util

    from ..methods.mcmc.export import write_chains

    n_chains = res.meta.get("n_chains")
    if "chain" not in res.arrays or not n_chains:
        return None
    names = res.columns("chain")
    chains = np.asarray(res.arrays["chain"]).reshape(int(n_chains), -1, len(names))
    lp = res.arrays.get("log_posterior")
    netcdf = all(importlib.util.find_spec(m) is not None for m in ("xarray", "h5netcdf", "h5py"))
    return write_chains(folder / ("chains.nc" if netcdf else "chains.npz"), chains, names,
                        None if lp is None else np.asarray(lp),
                        attrs={"step": res.name, "sampler": str(res.meta.get("options", {})
                                                                .get("sampler", ""))})


def _changed_files(saved: Mapping[str, str], now: Mapping[str, str]) -> list[str]:
    return sorted(k for k in set(saved) | set(now) if saved.get(k) != now.get(k))


def why_rerun(out: str | Path, model_factory: ModelFactory | None = None
              ) -> dict[str, list[str]]:
    """For each step of the study saved in ``out``: why ``rotoruq run`` would run it again
    (empty: its saved result would be reused).

    The study is read from the file the run was started with (``study.json`` records it;
    where it is gone, from the copy ``out/study.toml``, whose relative paths may then not
    resolve), ``--quick`` from ``study.json``; each step's identity (:data:`IDENTITY_PARTS`)
    is computed as a run would, from the saved results of the steps before it, and compared
    part by part with the one its result recorded. A code part names the changed files.

    Parameters
    ----------
    out : str or Path
        A results folder written by ``rotoruq run`` (or :func:`run_study`).
    model_factory : callable, optional
        The ``model_factory`` the run was made with (a Python model replacing the study's
        ``[model]``), so that its identity is compared too.

    Returns
    -------
    dict of str to list of str
        Step name -> the reasons it would run again (empty: reused).

    Examples
    --------
    >>> why_rerun("rotoruq-results/quick")                       # doctest: +SKIP
    {'sensitivity': [], 'mean_value': [],
     'forward': ['code: rotoruq/methods/sampling.py changed']}
    """
    from ..errors import InputFileError
    from ..results import load_results, load_study_info

    out = Path(out)
    info = load_study_info(out)
    origin = Path(info.get("study_file") or out / "study.toml")
    path = origin if origin.is_file() else out / "study.toml"
    if not path.is_file():
        raise InputFileError(out, None, "a results folder written by `rotoruq run` (with the "
                             "study.toml it copies)")
    study = load_study(path)
    quick = bool(info.get("quick", False))
    damaged: dict[str, str] = {}
    saved = load_results(out, incomplete=damaged)
    probe_factory = model_factory or partial(build_model, study, out=out)
    identities: dict = {}
    reasons: dict[str, list[str]] = {}
    for step in study.steps:
        if step.name in damaged:
            reasons[step.name] = [f"its saved result is incomplete ({damaged[step.name]})"]
            continue
        if any(r not in saved for r in ([step.source[0]] if step.source else [])):
            reasons[step.name] = ["a step it takes from has no saved result"]
            continue
        plan = _plan_step(study, step, saved, quick, probe_factory, identities)
        old = saved.get(step.name)
        if old is None:
            reasons[step.name] = ["no saved result"]
            continue
        if old.fingerprint == plan.fingerprint:
            reasons[step.name] = []
            continue
        was = old.meta.get("identity")
        if not isinstance(was, Mapping):
            reasons[step.name] = ["saved by an older rotoruq (no identity parts recorded)"]
            continue
        why = []
        for part, what in IDENTITY_PARTS.items():
            if was.get(part) == plan.parts[part]:
                continue
            if part == "code":
                files = _changed_files(old.meta.get("code_files") or {}, plan.step_code)
                why.append(f"code: {', '.join(files) or what} changed")
            elif part == "model":
                files = _changed_files(old.meta.get("model_code_files") or {},
                                       plan.model_code)
                why.append(f"model: {'code ' + ', '.join(files) if files else what} changed")
            elif part == "upstream":
                steps = [r for r, f in plan.parts["upstream"].items()
                         if (was.get("upstream") or {}).get(r) != f or reasons.get(r)]
                why.append(f"upstream: {', '.join(steps) or what} changed")
            elif part == "spec" and isinstance(old.meta.get("spec_keys"), Mapping):
                before, now = old.meta["spec_keys"], plan.spec_keys
                changed = [f"{k} {before.get(k, 'unset')} -> {now.get(k, 'unset')}"
                           for k in sorted(set(before) | set(now))
                           if before.get(k) != now.get(k)]
                why.append(f"spec: {'; '.join(changed) or what} changed")
            else:
                why.append(f"{part}: {what} changed")
        for r in plan.parts["upstream"]:
            if reasons.get(r) and not any(w.startswith("upstream") for w in why):
                why.append(f"upstream: {r} runs again")
        reasons[step.name] = why
    return reasons


def model_record(study: Study) -> dict:
    """What the report needs to know about the model, so that it never builds one.

    For a rotor preset: ``values``, the preset's numeric fields and the airfoil's nominal
    (fitted) coefficients by input name (the thesis tables quote some of them); ``curves``,
    the digitized Fradenburgh ground-effect thrust ratio T/T_inf on H/R in [0.8, 4.2] (200
    points); for a hover study with airfoil lift slopes among its parameters, ``spanwise``
    (:func:`spanwise_record`). An external model records nothing.
    """
    if study.model.preset is None:
        return {}
    from ..rotor.ground_effect import fradenburgh_thrust_ratio
    from ..rotor.model import load_airfoil
    from ..rotor.presets import get_preset

    preset = get_preset(study.model.preset, **dict(study.model.preset_options))
    values = {k: float(v) for k, v in vars(preset).items()
              if isinstance(v, int | float) and not isinstance(v, bool)}
    values.update(load_airfoil(preset).nominal_values())
    h = np.linspace(0.8, 4.2, 200)
    curves = {"fradenburgh_thrust_ratio": {
        "height_over_radius": h.tolist(),
        "thrust_ratio": np.asarray(fradenburgh_thrust_ratio(h), dtype=float).tolist()}}
    out: dict = {"values": values, "curves": curves}
    lift = [p.input or p.name for p in study.parameters
            if (p.input or p.name).startswith("cla_") and (p.input or p.name) in values]
    if lift and study.model.flight is None:
        out["spanwise"] = spanwise_record(study, lift)
    return out


def spanwise_record(study: Study, lift: Sequence[str]) -> dict:
    """The section loads behind a lift slope's effect on the thrust, at the study's nominal
    point (the model's fixed inputs, every other parameter at its mean): per station ``r``,
    ``w`` [m], ``mach``, ``alpha_deg`` [deg], ``thrust_per_span`` [N/m], and for each lift
    slope in ``lift`` the direct thrust derivative ``thrust_derivative`` [N per 1/deg] with
    the inflow and blade motion held (``station_derivative``: per station [N/m per 1/deg]).
    When some section's pitch is negative there (collective + twist < 0), ``no_negative_pitch``
    gives the same derivatives at the twist that makes the tip pitch zero (its
    ``twist_deg``): whether the ranking of the lift slopes needs the negative pitch. The
    report's reasons read it (:func:`rotoruq.reference.causes.sensitivity_causes`); the run
    records it so the report never builds a model."""
    from ..rotor.model import ROTOR_INPUTS, RotorModel, load_airfoil
    from ..rotor.presets import get_preset

    name = study.model.preset
    if name is None:
        raise ParameterError(f"{study.path}: spanwise loads need a rotor preset")
    base = get_preset(name, **dict(study.model.preset_options))
    known = set(ROTOR_INPUTS) | set(load_airfoil(base).parameter_names)
    means = {p.input or p.name: float(p.distribution.mean) for p in study.parameters
             if (p.input or p.name) in known}
    fixed = {k: v for k, v in study.model.fixed.items() if k in known}

    def at(twist: float | None) -> dict:
        opts = dict(study.model.preset_options)
        if twist is not None:
            opts["twist_deg"] = twist
        preset = get_preset(name, **opts)
        model = RotorModel(preset, names_in=list(lift), names_out=["thrust"],
                           fixed={k: v for k, v in {**means, **fixed}.items()
                                  if k not in lift}, **dict(study.model.discretization))
        sec = model.section_loads([[means[p] for p in lift]], derivatives=lift)
        w = sec["w"]
        rec = {"r": sec["r"].tolist(), "w": w.tolist(),
               "mach": sec["mach"][0].tolist(), "alpha_deg": sec["alpha_deg"][0].tolist(),
               "thrust_per_span": sec["thrust_per_span"][0].tolist(),
               "thrust_derivative": {p: float(np.sum(sec[f"d_thrust_per_span/{p}"][0] * w))
                                     for p in lift},
               "station_derivative": {p: sec[f"d_thrust_per_span/{p}"][0].tolist()
                                      for p in lift},
               "twist_deg": float(preset.twist_deg), "failure": str(sec["failure"][0])}
        return rec

    out = {"inputs": {**means, **fixed}, **at(None)}
    coll = float({**means, **fixed}.get("collective_deg", np.nan))
    if np.isfinite(coll) and coll > 0 and coll + out["twist_deg"] < 0:
        out["no_negative_pitch"] = at(-coll)
    return out


def _write_study_json(study: Study, out: Path, quick: bool,
                      skip_reasons: Mapping[str, str]) -> None:
    doc = {
        "name": study.info.name,
        "description": study.info.description,
        "reference": study.info.reference,
        "seed": study.info.seed,
        "quick": quick,
        "study_file": str(study.path.resolve()) if study.path.is_file() else None,
        "model": {"kind": study.model.kind, "preset": study.model.preset,
                  "responses": list(study.model.responses), "fixed": dict(study.model.fixed),
                  **model_record(study)},
        "parameters": {p.name: {"kind": p.kind, **p.params, "label": p.label, "unit": p.unit}
                       for p in study.parameters},
        "steps": [s.name for s in study.steps],
        "step_types": {s.name: s.type for s in study.steps},
        "titles": {s.name: s.title for s in study.steps},
        # each step's own fixed inputs: the report draws steps of one type that differ in
        # one of them against it (rotoruq.report.sweeps)
        "step_fixed": {s.name: dict(s.fixed) for s in study.steps if s.fixed},
        # steps this run skipped for outside software it did not find, with the reason: the
        # report says so in their place (rotoruq.report.skipped)
        "skipped": dict(skip_reasons),
    }
    save_study_info(out, doc)
