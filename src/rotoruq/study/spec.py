"""The validated form of a study file: frozen dataclasses built by
:func:`rotoruq.study.schema.load_study`."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..params import Distribution, ParameterSpace

__all__ = ["Study", "StudyInfo", "ModelSpec", "ExternalSpec", "ParameterSpec", "DataSet",
           "ExecutorSpec", "StoreSpec", "StepSpec", "CorrelationSpec", "function_variables"]


@dataclass(frozen=True)
class StudyInfo:
    """``[study]``: name, seed (int), output directory (absolute), free-text description, the
    reference it belongs to (``reference = "thesis"``; None: a study of the user's own), and
    the share of failed evaluations a step may have before ``rotoruq run`` exits with code 3
    (``max_failed_share``, 0 to 1; a step without a successful evaluation always does)."""

    name: str
    seed: int
    output: Path
    description: str = ""
    reference: str | None = None
    max_failed_share: float = 0.5


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
    gradients: str = "finite_difference"


@dataclass(frozen=True)
class ModelSpec:
    """``[model]`` or a named ``[models.NAME]``: a rotor preset (``kind="preset"``, with
    ``discretization``: the rotor's ``n_stations`` / ``n_azimuth`` / ``n_harmonics`` where
    given; with ``flight`` the rotor in forward flight), an external driver
    (``kind="external"``) or one of Dakota's test functions (``kind="function"``:
    ``function``, its ``analysis_components`` in ``components``; its variables are
    :func:`function_variables`). ``name`` is "" for ``[model]``."""

    kind: str
    responses: tuple[str, ...]
    fixed: Mapping[str, float]
    preset: str | None = None
    preset_options: Mapping[str, Any] = field(default_factory=dict)
    external: ExternalSpec | None = None
    discretization: Mapping[str, int] = field(default_factory=dict)
    name: str = ""
    function: str | None = None
    components: tuple[str, ...] = ()
    #: a rotor in forward flight (:class:`~rotoruq.rotor.forward.ForwardRotorModel`): its
    #: ``inflow_model`` and ``trim`` ("" for every key not given); None: the hover rotor
    flight: Mapping[str, str] | None = None


def function_variables(model: ModelSpec, parameters: Sequence[ParameterSpec],
                       main: ModelSpec | None = None) -> tuple[str, ...]:
    """The variables of a Dakota test function model, in the order the function takes them
    (Dakota hands most of them over by position): the study's parameters in file order (by
    the model input each feeds), then the inputs ``[model]`` fixes (``main``, for a named
    model) and the model's own fixed inputs, in file order."""
    names: list[str] = []
    for n in [p.input or p.name for p in parameters] + [
            *(main.fixed if main is not None else ()), *model.fixed]:
        if n not in names:
            names.append(n)
    return tuple(names)


@dataclass(frozen=True)
class ParameterSpec:
    """``[parameters.NAME]``: a named distribution (``distribution`` plus its parameters)."""

    name: str
    kind: str
    params: Mapping[str, Any]  # numbers; a histogram's abscissas, counts: tuples of numbers
    distribution: Distribution
    line: int | None = None
    label: str = ""
    unit: str = ""
    input: str = ""  # the model input it feeds, when its name differs (``input = "..."``)


@dataclass(frozen=True)
class CorrelationSpec:
    """``[correlation]``: the x-space (Pearson) correlation of some parameters, as Dakota's
    ``uncertain_correlation_matrix``; parameters not listed are independent of all others.

    parameters : the names, in the order of the rows of ``matrix``. matrix : (k, k) rows,
    symmetric, unit diagonal, positive definite. line : of the ``[correlation]`` table.

    Examples
    --------
    >>> c = CorrelationSpec(("a", "b"), ((1.0, 0.3), (0.3, 1.0)))
    >>> c.matrix_for(("b", "x", "a"))
    array([[1. , 0. , 0.3],
           [0. , 1. , 0. ],
           [0.3, 0. , 1. ]])
    >>> c.matrix_for(("a", "x")) is None      # no correlated pair among these
    True
    """

    parameters: tuple[str, ...]
    matrix: tuple[tuple[float, ...], ...]
    line: int | None = None

    def matrix_for(self, names: Sequence[str], correlated: Sequence[str] | None = None
                   ) -> np.ndarray | None:
        """The correlation matrix (d, d) of ``names`` (identity outside the listed pairs), or
        None when no two of them are correlated. ``correlated``: the names the correlation
        applies to (default all of ``names``)."""
        names = list(names)
        keep = set(names if correlated is None else correlated)
        r = np.eye(len(names))
        idx = {n: i for i, n in enumerate(self.parameters)}
        for a, na in enumerate(names):
            for b, nb in enumerate(names):
                if a != b and na in idx and nb in idx and na in keep and nb in keep:
                    r[a, b] = self.matrix[idx[na]][idx[nb]]
        return None if np.array_equal(r, np.eye(len(names))) else r


@dataclass(frozen=True, eq=False)
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
    for this step; ``options`` holds the type-specific options with defaults filled in;
    ``needs`` names outside software the step runs (``"mbdyn"``): where it is missing the
    step is skipped with the reason (:attr:`~rotoruq.study.runner.StudyRun.skip_reasons`).
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
    needs: tuple[str, ...] = ()


@dataclass(frozen=True, eq=False)
class Study:
    """A validated study (:func:`~rotoruq.load_study` reads one from its file).

    Attributes
    ----------
    path : Path
        The study file (relative paths in it are relative to its folder).
    info : StudyInfo
        The ``[study]`` table: name, seed, output folder, description, reference.
    model : ModelSpec
        The ``[model]`` table: a preset of the built-in rotor or an external command.
    parameters : tuple of ParameterSpec
        The ``[parameters.NAME]`` tables, ordered as in the file.
    data : mapping of str to DataSet
        The ``[data.NAME]`` tables: measured responses by configuration.
    executor : ExecutorSpec
        The ``[executor]`` table: serial, processes or dask.
    store : StoreSpec
        The ``[store]`` table: the evaluation store's file.
    steps : tuple of StepSpec
        The ``[[steps]]``, in order.
    text : str
        The file's text (copied into the results folder).
    models : mapping of str to ModelSpec
        The named ``[models.NAME]`` tables (the low-fidelity models of a ``multifidelity``
        step, the cheaper models of a co-kriging emulator).
    correlation : CorrelationSpec or None
        The ``[correlation]`` table (None: independent parameters).
    """

    path: Path
    info: StudyInfo
    model: ModelSpec
    parameters: tuple[ParameterSpec, ...]
    data: Mapping[str, DataSet]
    executor: ExecutorSpec
    store: StoreSpec
    steps: tuple[StepSpec, ...]
    text: str = ""
    models: Mapping[str, ModelSpec] = field(default_factory=dict)
    correlation: CorrelationSpec | None = None

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """The parameters' names, in the file's order."""
        return tuple(p.name for p in self.parameters)

    @property
    def renamed_inputs(self) -> dict[str, str]:
        """Parameter name -> the model input it feeds, for parameters named otherwise."""
        return {p.name: p.input for p in self.parameters if p.input}

    def parameter(self, name: str) -> ParameterSpec:
        """The parameter ``name``'s table.

        Parameters
        ----------
        name : str
            A parameter name; another raises :class:`~rotoruq.ParameterError`.
        """
        for p in self.parameters:
            if p.name == name:
                return p
        raise ParameterError(f"study {self.info.name!r} has no parameter {name!r}")

    def space(self, names_in: Sequence[str] | None = None) -> ParameterSpace:
        """ParameterSpace of the named parameters, in the given order, with their
        ``[correlation]``.

        Parameters
        ----------
        names_in : sequence of str, optional
            The parameters to include (default: all, in the file's order).
        """
        names = self.parameter_names if names_in is None else tuple(names_in)
        corr = None if self.correlation is None else self.correlation.matrix_for(names)
        return ParameterSpace([(n, self.parameter(n).distribution) for n in names],
                              correlation=corr)

    def model_spec(self, name: str | None = None) -> ModelSpec:
        """``[model]`` (``name`` None) or the named ``[models.NAME]``.

        Parameters
        ----------
        name : str, optional
            A name of :attr:`models` (default None: ``[model]``).
        """
        if name is None:
            return self.model
        try:
            return self.models[name]
        except KeyError:
            raise ParameterError(f"study {self.info.name!r} has no model {name!r} (named "
                                 f"models: {', '.join(self.models) or 'none'})") from None

    def step(self, name: str) -> StepSpec:
        """The step ``name``'s table.

        Parameters
        ----------
        name : str
            A step name; another raises :class:`~rotoruq.ParameterError`.
        """
        for s in self.steps:
            if s.name == name:
                return s
        raise ParameterError(f"study {self.info.name!r} has no step {name!r}")
