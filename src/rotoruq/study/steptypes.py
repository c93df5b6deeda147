"""The step-type registry: one :class:`StepType` record per ``type = "..."`` of a study file.

A record holds everything about its type: the option schema (keys, checkers, defaults), the
adapter that runs it (:mod:`rotoruq.study.steps`), what it hands to later steps, its
``--quick`` sample sizes, extra validation, and how the report renders its result (tables,
figures, warnings; :mod:`rotoruq.report.hooks`). Adding a step type is one call::

    register_step_type(StepType("my_step", run=run_my_step,
                                options={"n_samples": Option(integer(1), 100)},
                                tables=my_tables))

Option defaults of method parameters are read from the method's signature
(:data:`~rotoruq.study.options.SIGNATURE`): a study file and a Python call without that key
get the same value.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, NoReturn

from ..report import diagnostics, plots, steptables
from ..report.hooks import FiguresHook, Rendering, TablesHook, WarningsHook, register_rendering
from ..results import StepResult
from . import steps
from .options import (
    REQUIRED,
    SIGNATURE,
    Option,
    choice,
    integer,
    number,
    number_list,
    number_or_table,
    signature_default,
    string,
    table,
    table_or_string,
)
from .spec import ModelSpec
from .steps import StepContext

__all__ = ["StepType", "StepCheck", "STEP_TYPES", "register_step_type", "step_type",
           "run_step", "STATUS_INTERVAL", "DESIGNS"]

log = logging.getLogger(__name__)

#: Sampling designs (``design = ...``).
DESIGNS = ("lhs", "random", "sobol", "halton")


@dataclass(frozen=True, eq=False)
class StepCheck:
    """What a step type's ``check`` hook sees of one parsed step.

    options : the step's options, defaults filled in. model : the study's ``[model]``.
    responses : the step's ``responses`` selection (None: all). parameters : the study's
    parameter names. fail(key_path, expected, found) raises the file/line error for a key
    of this step. reference(ref, key, attrs) checks a ``"step.attr"`` reference to an
    earlier step. check_input(key_path, name) checks a model input name. numbers(table,
    key_path, what) checks a table of numbers.
    """

    options: Mapping[str, Any]
    model: ModelSpec
    responses: tuple[str, ...] | None
    parameters: tuple[str, ...]
    fail: Callable[..., NoReturn]
    reference: Callable[[str, str, tuple[str, ...]], tuple[str, str]]
    check_input: Callable[[tuple, str], None]
    numbers: Callable[[Mapping, tuple, str], dict[str, float]]


@dataclass(frozen=True, eq=False)
class StepType:
    """One step type.

    name : the ``type`` of a ``[[steps]]`` table. run : the adapter
        ``run(StepContext) -> StepResult``. options : key -> :class:`Option`.
    method : ``"module:function"`` whose signature gives the :data:`SIGNATURE` defaults.
    provides : attributes later steps may take (``"posterior"``, ``"calibrated"``,
        ``"samples"``) through ``from = "step.ATTR"`` / ``data = "step.ATTR"``.
    needs_data : the step takes observations (the study's only data set when it names none).
    quick : option -> upper bound under ``--quick``.
    check : extra validation ``check(StepCheck)`` after the options are read.
    tables, figures, warnings : the report's renderers (:class:`rotoruq.report.hooks.Rendering`).
    """

    name: str
    run: Callable[[StepContext], StepResult]
    options: Mapping[str, Option] = field(default_factory=dict)
    method: str | None = None
    provides: tuple[str, ...] = ()
    needs_data: bool = False
    quick: Mapping[str, int] = field(default_factory=dict)
    check: Callable[[StepCheck], None] | None = None
    tables: TablesHook | None = None
    figures: FiguresHook | None = None
    warnings: WarningsHook | None = None

    def default(self, key: str) -> Any:
        """Default of option ``key``: its own, or its method parameter's (:data:`REQUIRED`
        when that has none)."""
        opt = self.options[key]
        if opt.default is not SIGNATURE:
            return opt.default
        target = opt.method or self.method
        if target is None:
            raise LookupError(f"step type {self.name!r}: option {key!r} takes its default "
                              "from a method signature, but the step type names no method")
        return signature_default(target, opt.param or key)


STEP_TYPES: dict[str, StepType] = {}


def register_step_type(st: StepType) -> StepType:
    """Add (or replace) a step type: study files may use it, the runner runs it and the
    report renders its results with its hooks."""
    STEP_TYPES[st.name] = st
    register_rendering(st.name, Rendering(st.tables, st.figures, st.warnings))
    return st


def step_type(name: str) -> StepType:
    """The registered step type ``name`` (``KeyError`` when there is none)."""
    return STEP_TYPES[name]


#: Seconds between status lines of a running step (a silent terminal for minutes reads as a
#: hang).
STATUS_INTERVAL = 15.0


def run_step(ctx: StepContext) -> tuple[StepResult, float]:
    """Run the adapter of ``ctx.type``; returns the result and the wall time in s. While it
    runs, a status line goes to the log (INFO) every :data:`STATUS_INTERVAL` seconds."""
    from ..evaluation.progress import format_duration

    t0 = time.perf_counter()
    done = threading.Event()

    def status() -> None:
        while not done.wait(STATUS_INTERVAL):
            log.info("  %s: %s running, %s elapsed", ctx.name, ctx.type,
                     format_duration(time.perf_counter() - t0))

    watcher = None
    if log.isEnabledFor(logging.INFO):
        watcher = threading.Thread(target=status, name=f"status-{ctx.name}", daemon=True)
        watcher.start()
    try:
        res = STEP_TYPES[ctx.type].run(ctx)
    finally:
        done.set()
        if watcher is not None:
            watcher.join()
    return res, time.perf_counter() - t0


# ---------------------------------------------------------------------------------------------
# Checks of the built-in types
# ---------------------------------------------------------------------------------------------
def _check_targets(c: StepCheck) -> None:
    targets = c.options["targets"]
    if isinstance(targets, str):
        c.reference(targets, "targets", ("samples",))
        return
    allowed = c.responses or c.model.responses
    for r, v in targets.items():
        if r not in allowed:
            c.fail(("targets", r), f"targets keyed by responses ({', '.join(allowed)})", r)
        if (not isinstance(v, list) or len(v) != 2
                or not all(isinstance(x, int | float) and not isinstance(x, bool) for x in v)
                or v[1] <= 0):
            c.fail(("targets", r), f"{r} = [mean, std] with std > 0", repr(v))


def _check_sweep(c: StepCheck) -> None:
    sweep = c.options["sweep"]
    if sweep is None:
        return
    lengths = set()
    for k, v in sweep.items():
        c.check_input(("sweep", k), k)
        try:
            lengths.add(len(number_list(v)))
        except TypeError:
            c.fail(("sweep", k), f"{k} = [numbers] in sweep", repr(v))
    if len(lengths) != 1:
        c.fail(("sweep",), "sweep lists of equal length")
    if c.options["normalize_by"] is not None:
        c.numbers(c.options["normalize_by"], ("normalize_by",), "normalize_by")


def _check_intervals(c: StepCheck) -> None:
    for p in c.options["intervals"]:
        if p not in c.parameters:
            c.fail(("intervals", p), "intervals keyed by names from [parameters]", p)


def _check_pce(c: StepCheck) -> None:
    if c.options["n_samples"] is not None and c.options["estimator"] != "regression":
        c.fail(("n_samples",), "n_samples only with estimator = \"regression\" (quadrature "
               "and sparse grids choose their own points)", str(c.options["n_samples"]))


# ---------------------------------------------------------------------------------------------
# The built-in step types
# ---------------------------------------------------------------------------------------------
_SAMPLE = "rotoruq.methods.sampling:sample"
_LEAST_SQUARES = "rotoruq.methods.least_squares:least_squares"
_LEVELS = {"response_levels": Option(table, SIGNATURE),
           "probability_levels": Option(table, SIGNATURE)}

register_step_type(StepType(
    "sampling", steps.run_sampling, method=_SAMPLE, provides=("samples",),
    options={"n_samples": Option(integer(1), SIGNATURE),
             "design": Option(choice(*DESIGNS), SIGNATURE),
             "noise_std": Option(number_or_table, 0.0)},
    quick={"n_samples": 40},
    tables=steptables.sampling_tables, figures=plots.sampling_figures))

register_step_type(StepType(
    "sensitivity", steps.run_sensitivity, method="rotoruq.methods.sensitivity:sobol_indices",
    options={"n_samples": Option(integer(2), SIGNATURE),
             "design": Option(choice(*DESIGNS), SIGNATURE),
             "estimator": Option(choice("hybrid", "saltelli2010", "jansen", "janon"),
                                 SIGNATURE)},
    quick={"n_samples": 32},
    tables=steptables.sensitivity_tables, figures=plots.sensitivity_figures,
    warnings=diagnostics.sobol_warnings))

register_step_type(StepType(
    "mean_value", steps.run_mean_value, method="rotoruq.methods.reliability:mean_value",
    options=dict(_LEVELS), tables=steptables.mean_value_tables))

register_step_type(StepType(
    "reliability", steps.run_reliability, method="rotoruq.methods.reliability:mpp_search",
    options={"integration": Option(choice("first_order", "second_order"), SIGNATURE),
             **_LEVELS},
    tables=steptables.reliability_tables))

register_step_type(StepType(
    "pce", steps.run_pce, method="rotoruq.methods.pce:polynomial_chaos",
    options={"order": Option(integer(1), SIGNATURE),
             "estimator": Option(choice("quadrature", "sparse_grid", "regression"), SIGNATURE),
             "n_samples": Option(integer(1), SIGNATURE)},
    quick={"n_samples": 40}, check=_check_pce,
    tables=steptables.pce_tables, figures=plots.sensitivity_figures,
    warnings=diagnostics.sobol_warnings))

register_step_type(StepType(
    "evidence", steps.run_evidence, method="rotoruq.methods.evidence:evidence",
    options={"intervals": Option(table, REQUIRED),
             "n_samples": Option(integer(1), SIGNATURE),
             "response_levels": Option(table, SIGNATURE)},
    quick={"n_samples": 20}, check=_check_intervals, tables=steptables.evidence_tables))

register_step_type(StepType(
    "bayes_calibration", steps.run_bayes_calibration,
    method="rotoruq.methods.mcmc:calibrate_bayes", provides=("posterior",), needs_data=True,
    options={"sampler": Option(choice("dram", "mh", "dr", "am"), SIGNATURE),
             "n_samples": Option(integer(10), SIGNATURE),
             "burn_in": Option(integer(0), SIGNATURE),
             "emulator": Option(choice("gp", "none"), "gp"),
             "trend": Option(choice("constant", "linear", "reduced_quadratic", "quadratic"),
                             SIGNATURE, method="rotoruq.methods.surrogate:GaussianProcess"),
             "n_emulator_samples": Option(integer(2), SIGNATURE),
             "noise_std": Option(number_or_table, None),
             "proposal": Option(choice("hessian", "prior"), SIGNATURE,
                                param="proposal_covariance")},
    quick={"n_samples": 1800, "burn_in": 200, "n_emulator_samples": 60},
    tables=steptables.bayes_tables, figures=plots.bayes_figures,
    warnings=diagnostics.bayes_warnings))

register_step_type(StepType(
    "least_squares", steps.run_least_squares, method=_LEAST_SQUARES,
    provides=("calibrated",), needs_data=True,
    options={"optimizer": Option(choice("nl2sol", "trf", "lm"), SIGNATURE),
             "max_iterations": Option(integer(1), SIGNATURE),
             "max_function_evaluations": Option(integer(1), SIGNATURE),
             "tolerance": Option(number(positive=True, allow_zero=False), SIGNATURE),
             "noise_std": Option(number_or_table, None)},
    tables=steptables.least_squares_tables, warnings=diagnostics.least_squares_warnings))

register_step_type(StepType(
    "cuu", steps.run_cuu, method="rotoruq.methods.cuu:calibrate_under_uncertainty",
    provides=("calibrated",),
    options={"targets": Option(table_or_string, REQUIRED),
             "calibrate": Option(choice("std", "mean", "mean_std"), "std"),
             "inner": Option(choice("mean_value", "sampling", "pce"), SIGNATURE),
             "optimizer": Option(choice("nl2sol", "trf", "lm"), SIGNATURE),
             "max_iterations": Option(integer(1), SIGNATURE, method=_LEAST_SQUARES),
             "tolerance": Option(number(positive=True, allow_zero=False), SIGNATURE,
                                 method=_LEAST_SQUARES),
             "verify_samples": Option(integer(0), 0),
             "design": Option(choice(*DESIGNS), SIGNATURE, method=_SAMPLE)},
    quick={"verify_samples": 40}, check=_check_targets,
    tables=steptables.cuu_tables, figures=plots.cuu_figures,
    warnings=diagnostics.cuu_warnings))

register_step_type(StepType(
    "forward_check", steps.run_forward_check, method=_SAMPLE,
    options={"n_samples": Option(integer(1), SIGNATURE),
             "design": Option(choice(*DESIGNS), SIGNATURE),
             "sweep": Option(table, None),
             "match": Option(string(), None),
             "normalize_by": Option(table, None)},
    quick={"n_samples": 40}, check=_check_sweep,
    tables=steptables.forward_check_tables, figures=plots.forward_check_figures))
