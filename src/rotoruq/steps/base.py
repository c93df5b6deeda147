"""What a step type is: the :class:`StepType` record, the :class:`StepContext` its adapter
runs in, the :class:`StepCheck` its extra validation sees, and :func:`run_step`.

Each step type is one module of :mod:`rotoruq.steps` defining ``STEP = StepType(...)``; the
registry (:data:`rotoruq.steps.STEP_TYPES`) lists them. Option defaults of method parameters
are read from the method's signature (:data:`~rotoruq.steps.options.SIGNATURE`): a study file
and a Python call without that key get the same value.
"""

from __future__ import annotations

import logging
import math
import os
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, NoReturn

import numpy as np

from ..errors import ParameterError
from ..params import ParameterSpace
from ..render.figures import Figure, FigureContext
from ..render.tables import StepTable
from ..results import StepResult
from .options import SIGNATURE, Option, signature_default

__all__ = ["StepType", "StepCheck", "StepContext", "run_step", "STATUS_INTERVAL", "DESIGNS",
           "TablesHook", "FiguresHook", "WarningsHook",
           "SweepFiguresHook"]

log = logging.getLogger(__name__)

#: Sampling designs (``design = ...``).
DESIGNS = ("lhs", "random", "sobol", "halton")

TablesHook = Callable[[StepResult, Mapping[str, str]], list[StepTable]]
FiguresHook = Callable[[StepResult, FigureContext], list[Figure]]
#: ``sweep_figures(results, swept, values, context)``: figures of steps of one type that differ
#: in one fixed input ``swept`` (values increasing, one per result).
SweepFiguresHook = Callable[[Sequence[StepResult], str, Sequence[float], FigureContext],
                            list[Figure]]
WarningsHook = Callable[[StepResult, Mapping[str, str]], list[str]]


@dataclass
class StepContext:
    """Everything a step needs.

    Attributes
    ----------
    name : str
        The step's name (``[[steps]] name``), used in messages and log lines.
    type : str
        The step's type (a key of :data:`rotoruq.steps.STEP_TYPES`).
    options : mapping of str to object
        The step's options as read from the study file, defaults filled in.
    space : ParameterSpace
        The uncertain inputs of the step (priors / input distributions), d of them.
    responses : tuple of str
        The step's response names (m of them).
    fixed : mapping of str to float
        The other model inputs and their values, in the model's input units.
    make_model : callable
        ``make_model(inputs, responses, fixed) -> Model`` builds (store-backed) models, e.g.
        for sweeps over fixed inputs; a study with named models also takes ``model=NAME``.
    rng : numpy.random.Generator
        Random generator of this step: seeded by its ``seed`` option, else by the study's
        seed and the step's position.
    data : ndarray of shape (k, m), optional
        Observations of ``responses``, one row per observation (None when the step has no
        data).
    data_columns : mapping of str to ndarray
        Every column of the data set, column name -> values of shape (k,) (for sweeps and
        normalisation).
    targets : mapping of str to tuple of (float, float)
        Response -> (mean, std) targets in the response's units (CUU).
    source : StepResult, optional
        The saved result of the ``from`` step (None without one); a forward check uses its
        chain for the joint posterior predictive.
    previous : mapping of str to StepResult
        The saved results of the steps before this one, by name (references such as
        ``u_num = "verify.u_num"``).
    store : rotoruq.evaluation.store.Store, optional
        The study's evaluation store (None without one), which also keeps pieces computed
        once and reused by the identity of their setup (a Bayes step's self-check:
        ``Store.get_computed`` / ``put_computed``).
    """

    name: str
    type: str
    options: Mapping[str, Any]
    space: ParameterSpace
    responses: tuple[str, ...]
    fixed: Mapping[str, float]
    make_model: Callable[..., Any]
    rng: np.random.Generator
    data: np.ndarray | None = None
    data_columns: Mapping[str, np.ndarray] = field(default_factory=dict)
    targets: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    source: StepResult | None = None
    previous: Mapping[str, StepResult] = field(default_factory=dict)
    store: Any = None
    _built: dict[tuple, Any] = field(default_factory=dict, init=False, repr=False)

    def observations(self) -> np.ndarray:
        """The step's data (k, m); a step type that needs data declares ``needs_data``."""
        if self.data is None:
            raise ParameterError(f"step {self.name!r} ({self.type}) needs data = \"NAME\"")
        return self.data

    def model(self, fixed: Mapping[str, float] | None = None) -> Any:
        """The step's model (inputs ``space.names``, outputs ``responses``) with ``fixed``
        set over the step's fixed inputs. Built once per set of fixed values: asking again
        (a sweep point, a verification level seen before) gives the same model.

        Parameters
        ----------
        fixed : mapping of str to float, optional
            Fixed input name -> value, in the model's input units, that override or add to
            :attr:`fixed` (a sweep point, a verification level); None: the step's own.

        Returns
        -------
        Model
            The model built by :attr:`make_model` for those fixed values.
        """
        f = dict(self.fixed)
        f.update(fixed or {})
        key = tuple(sorted(f.items()))
        if key not in self._built:
            self._built[key] = self.make_model(self.space.names, self.responses, f)
        return self._built[key]


@dataclass(frozen=True, eq=False)
class StepCheck:
    """What a step type's ``check`` hook sees of one parsed step.

    Key paths (``key_path``) are tuples of keys and indices relative to the step's table,
    e.g. ``("points",)`` or ``("couple", "rpm")``.

    Attributes
    ----------
    options : mapping of str to object
        The step's options, defaults filled in.
    model : rotoruq.study.spec.ModelSpec
        The study's ``[model]`` (``responses``, ``inputs``, ...).
    responses : tuple of str or None
        The step's ``responses`` selection (None: all).
    parameters : tuple of str
        The study's parameter names.
    fail : callable
        ``fail(key_path, expected, found=None)`` raises the file/line error
        (:class:`~rotoruq.errors.InputFileError`) for a key of this step: what was expected
        and what the file has.
    reference : callable
        ``reference(ref, key, attrs) -> (step, attr)`` checks a ``"step.attr"`` reference
        given under ``key`` to an earlier step that provides ``attr``, one of ``attrs``.
    check_input : callable
        ``check_input(key_path, name)`` checks that ``name`` is an input of the model.
    numbers : callable
        ``numbers(table, key_path, what) -> dict`` checks that every value of ``table`` is a
        number and returns them as floats (``what`` names the table in the error).
    """

    options: Mapping[str, Any]
    model: Any
    responses: tuple[str, ...] | None
    parameters: tuple[str, ...]
    fail: Callable[..., NoReturn]
    reference: Callable[[str, str, tuple[str, ...]], tuple[str, str]]
    check_input: Callable[[tuple, str], None]
    numbers: Callable[[Mapping, tuple, str], dict[str, float]]


@dataclass(frozen=True, eq=False)
class StepType:
    """One step type.

    Parameters
    ----------
    name : str
        The ``type`` of a ``[[steps]]`` table.
    run : callable
        The adapter ``run(StepContext) -> StepResult`` (it calls the method; study logic of
        the type lives in a function of its own).
    options : mapping of str to Option
        Option key -> :class:`Option` (its checker and default).
    method : str, optional
        ``"module:function"`` whose signature gives the :data:`SIGNATURE` defaults.
    provides : tuple of str
        Attributes later steps may take (``"posterior"``, ``"calibrated"``, ``"samples"``)
        through ``from = "step.ATTR"`` / ``data = "step.ATTR"``.
    needs_data : bool
        The step takes observations (the study's only data set when it names none).
    data_optional : bool
        With ``needs_data``, a study without any data set runs the step without data
        (``ctx.data`` None; ``least_squares``: the responses are the residuals).
    quick : mapping of str to int
        Option -> upper bound under ``--quick`` (a sample count, an iteration count).
    check : callable, optional
        Extra validation ``check(StepCheck)`` after the options are read.
    tables : callable, optional
        ``tables(result, labels) -> list`` of :class:`~rotoruq.render.tables.StepTable`.
    figures : callable, optional
        ``figures(result, context) -> list`` of :class:`~rotoruq.render.figures.Figure`
        (``context``: a :class:`~rotoruq.render.figures.FigureContext`).
    warnings : callable, optional
        ``warnings(result, labels) -> list`` of warning sentences. Each of ``tables``,
        ``figures`` and ``warnings`` may be None (the report then shows a key/value table,
        no figures, no warnings).
    modules : tuple of str
        Modules whose code computes this type's numbers beyond what the type's own module
        imports (its adapter's imports, also those inside functions, are followed already):
        each, and what it imports within rotoruq, enters the code part of the step's
        fingerprint (:attr:`code_modules`, read by ``study.runner``), so an edit of one
        re-runs the steps of the types that list it and no other. A plugin lists its own
        helper modules here by import name.
    correlated : bool
        The type's method honours a correlated input space (``ParameterSpace`` with a
        ``correlation``: a study file's ``[correlation]`` table). A type without it refuses
        correlated inputs (the study file fails naming the step and the table) instead of
        ignoring the correlation.
    sweep_figures : callable, optional
        ``sweep_figures(results, swept, values, context) -> list`` of figures: the report
        calls it for steps of this type that differ only in one fixed input ``swept``
        (values increasing; e.g. Sobol indices against the advance ratio). None: no such
        figures.
    """

    name: str
    run: Callable[[StepContext], StepResult]
    options: Mapping[str, Option] = field(default_factory=dict)
    method: str | None = None
    provides: tuple[str, ...] = ()
    needs_data: bool = False
    data_optional: bool = False
    quick: Mapping[str, int] = field(default_factory=dict)
    check: Callable[[StepCheck], None] | None = None
    tables: TablesHook | None = None
    figures: FiguresHook | None = None
    warnings: WarningsHook | None = None
    modules: tuple[str, ...] = ()
    correlated: bool = False
    sweep_figures: SweepFiguresHook | None = None

    @property
    def code_modules(self) -> tuple[str, ...]:
        """The modules whose source, with what each imports within rotoruq, is the code part
        of this type's fingerprint: the adapter's module, then :attr:`modules`.

        Examples
        --------
        >>> from rotoruq.steps import step_type
        >>> step_type("mean_value").code_modules
        ('rotoruq.steps.mean_value', 'rotoruq.methods.levels')
        """
        return (self.run.__module__, *self.modules)

    def default(self, key: str) -> Any:
        """Default of option ``key``: its own, or its method parameter's (:data:`REQUIRED`
        when that has none).

        Parameters
        ----------
        key : str
            An option key of :attr:`options`.

        Returns
        -------
        object
            The option's default value, or :data:`REQUIRED`.

        Raises
        ------
        KeyError
            The type has no option ``key``.
        LookupError
            The default comes from a method signature but the type names no method, or the
            method has no such parameter.
        """
        opt = self.options[key]
        if opt.default is not SIGNATURE:
            return opt.default
        target = opt.method or self.method
        if target is None:
            raise LookupError(f"step type {self.name!r}: option {key!r} takes its default "
                              "from a method signature, but the step type names no method")
        return signature_default(target, opt.param or key)


#: Seconds between status lines of a running step (a silent terminal for minutes reads as a
#: hang); the environment variable ``ROTORUQ_STATUS_INTERVAL`` sets another (a CI log that
#: wants fewer lines, a test that wants one soon).
STATUS_INTERVAL = 15.0


def _status_interval() -> float:
    text = os.environ.get("ROTORUQ_STATUS_INTERVAL", "")
    try:
        value = float(text)
    except ValueError:
        return STATUS_INTERVAL
    return value if math.isfinite(value) and value > 0 else STATUS_INTERVAL


def run_step(run: Callable[[StepContext], StepResult], ctx: StepContext,
             label: str | None = None) -> tuple[StepResult, float]:
    """Run the adapter ``run`` on ``ctx``; returns the result and the wall time in s. While it
    runs, a status line goes to the log (INFO) every :data:`STATUS_INTERVAL` seconds, with
    the phase under way (:mod:`rotoruq._progress`) unless a bar on the terminal shows it.

    Parameters
    ----------
    run : callable
        The step type's adapter, ``run(StepContext) -> StepResult`` (:attr:`StepType.run`).
    ctx : StepContext
        The step to run.
    label : str, optional
        The step as the status line names it (the runner's ``[study] 3/12 sobol``); default
        the step's name.

    Returns
    -------
    result : StepResult
        What ``run`` returned.
    seconds : float
        Wall time of the run, in s.
    """
    from .._progress import LOGGER, bar_on_terminal
    from ..evaluation.progress import format_duration

    t0 = time.perf_counter()
    done = threading.Event()
    phases = _Phases()

    def status() -> None:
        interval = _status_interval()
        while not done.wait(interval):
            under_way = phases.text()
            if under_way and bar_on_terminal():
                continue  # the bar on the terminal says it
            log.info("  %s: %s running, %s elapsed%s", label or ctx.name, ctx.type,
                     format_duration(time.perf_counter() - t0),
                     f" ({under_way})" if under_way else "")

    watcher = None
    progress = logging.getLogger(LOGGER)
    if log.isEnabledFor(logging.INFO):
        progress.addHandler(phases)
        watcher = threading.Thread(target=status, name=f"status-{ctx.name}", daemon=True)
        watcher.start()
    try:
        res = run(ctx)
    finally:
        done.set()
        if watcher is not None:
            watcher.join()
            progress.removeHandler(phases)
    return res, time.perf_counter() - t0


class _Phases(logging.Handler):
    """The phases (:mod:`rotoruq._progress`) under way in a running step, for its status
    line: ``"4 chains 3000/7200 (42 %)"``."""

    def __init__(self) -> None:
        super().__init__()
        self.states: dict[str, Any] = {}
        self.lock_ = threading.Lock()

    def emit(self, record: logging.LogRecord) -> None:
        state = getattr(record, "progress", None)
        if state is None:
            return
        with self.lock_:
            if state.finished:
                self.states.pop(state.name, None)
            else:
                self.states[state.name] = state

    def text(self) -> str:
        with self.lock_:
            return ", ".join(p.text() for p in self.states.values() if p.total != 0)
