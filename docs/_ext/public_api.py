"""The API reference, grouped by task, from the package's public names (a Sphinx extension).

``GROUPS`` below is the one home of the grouping: every name of ``rotoruq._PUBLIC`` sits in
exactly one group, by its public name (``as_generator``, not ``rotoruq._rng.as_generator``),
and so does every name of a public subpackage's ``__all__`` that the top level does not
re-export, by its full name (``rotoruq.params.NatafModel``). ``tests/test_docs.py`` checks
both, and that no listed name goes through a private module.

Each group is one page, ``docs/api/<key>.rst``, whose whole text is ``.. rotoruq-api:: <key>``;
``docs/api/index.rst`` is ``.. rotoruq-api-index::``. The directives write the pages' content
when the docs are read: a title, the group's summary table and every name's full entry
(autodoc, numpydoc). Nothing is written into the source tree, so a build leaves
``git status`` clean; adding a public name means adding it to a group here (the test says
which name is missing), and adding a group means adding its two-line page.
"""

from __future__ import annotations

import importlib
import inspect
import sys
from dataclasses import dataclass

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

#: subpackages whose ``__all__`` is part of the public API (their names that the top level
#: does not re-export are documented under their full names)
SUBPACKAGES = ("rotoruq.params", "rotoruq.evaluation", "rotoruq.methods.mcmc", "rotoruq.mbdyn",
               "rotoruq.steps")

#: the public submodules among ``rotoruq._PUBLIC`` (``rq.errors``, ``rq.presets``): their own
#: ``__all__`` names that the top level does not re-export are documented after them
MODULES = {"errors": "rotoruq.errors", "presets": "rotoruq.rotor.presets"}


@dataclass(frozen=True)
class Group:
    """One page of the API reference: its title, a sentence saying what the names are for,
    and the names, in reading order (a function before its result and options)."""

    title: str
    intro: str
    names: tuple[str, ...]


GROUPS: dict[str, Group] = {
    "parameters": Group(
        "Parameters and distributions",
        "Uncertain inputs: the distributions (Dakota's catalog), the parameter space that joins "
        "them (correlation by a Nataf model, designs, transforms) and the random-number seeds "
        "every method takes.",
        ("ParameterSpace", "Normal", "LogNormal", "Uniform", "LogUniform", "TruncatedNormal",
         "Triangular", "Exponential", "Beta", "Gamma", "Gumbel", "Frechet", "Weibull",
         "HistogramBin", "kernel_density", "Interval", "make_distribution",
         "as_generator",
         "rotoruq.params.Distribution", "rotoruq.params.DISTRIBUTIONS",
         "rotoruq.params.distribution_keys", "rotoruq.params.DESIGNS",
         "rotoruq.params.unit_design", "rotoruq.params.PAIRINGS",
         "rotoruq.params.restricted_pairing", "rotoruq.params.NatafModel",
         "rotoruq.params.nataf_model", "rotoruq.params.nataf_correlation")),
    "models": Group(
        "Models and the rotor",
        "What the methods evaluate: the model protocol and its wrappers, the hover rotor model "
        "and the rotor in forward flight (presets, discretization, airfoils and c81 tables) "
        "and Dakota's test functions.",
        ("Model", "FunctionModel", "EvalBatch", "evaluate", "RotorModel", "ForwardRotorModel",
         "ROTOR_INPUTS",
         "RESPONSES", "RotorDiscretization", "RotorPreset", "get_preset", "presets",
         "LinearAirfoil", "Airfoil", "AirfoilFit", "fit_airfoil", "write_perturbed_c81",
         "C81Table", "C81Block", "read_c81", "write_c81", "dakota_function", "DakotaFunction",
         "FUNCTIONS")),
    "sampling": Group(
        "Sampling and sensitivity",
        "Forward propagation by sampling (LHS, random, Sobol and Halton designs), the "
        "statistics of a sample, and variance-based sensitivity indices.",
        ("sample", "SamplingResult", "refine", "response_statistics", "ResponseStatistics",
         "sobol_indices", "SobolResult")),
    "reliability": Group(
        "Reliability, expansions and epistemic uncertainty",
        "Probabilities of response levels (mean value, most probable point, importance "
        "sampling), polynomial chaos expansions, and interval / evidence propagation of "
        "epistemic inputs.",
        ("mean_value", "mean_value_from_gradient", "MeanValueResult", "mpp_search",
         "MPPResult", "importance_sampling", "ImportanceSamplingResult", "polynomial_chaos",
         "PCEResult", "evidence", "EvidenceResult", "box_extremes")),
    "surrogates": Group(
        "Surrogates",
        "Gaussian-process (Kriging) and multi-fidelity co-Kriging emulators: each is a model "
        "once fitted.",
        ("GaussianProcess", "LeaveOneOut", "CoKriging")),
    "calibration": Group(
        "Calibration",
        "Bayesian calibration (MCMC, emulators, noise models, model discrepancy and its "
        "self-check), deterministic least squares, and calibration under uncertainty.",
        ("calibrate_bayes", "BayesResult", "continue_chain", "NoiseModel", "ChainOptions",
         "EmulatorOptions", "rotoruq.methods.mcmc.RefineConfig",
         "rotoruq.methods.mcmc.EmulatorAdequacy", "rotoruq.methods.mcmc.SamplerConfig",
         "rotoruq.methods.mcmc.SAMPLERS", "rotoruq.methods.mcmc.SamplerState",
         "rotoruq.methods.mcmc.run_chains", "rotoruq.methods.mcmc.GaussianLikelihood",
         "rotoruq.methods.mcmc.effective_sample_size", "rotoruq.methods.mcmc.split_rhat",
         "rotoruq.methods.mcmc.mser_warm_up", "rotoruq.methods.mcmc.WarmUp",
         "simulation_based_calibration", "SBCResult", "calibrate_with_discrepancy",
         "DiscrepancyResult", "Discrepancy", "predict_with_discrepancy",
         "DiscrepancyPrediction", "calibrate", "CalibrationResult", "least_squares", "Convergence",
         "LeastSquaresResult", "calibrate_under_uncertainty", "CUUResult", "check_cuu",
         "CUUCheck")),
    "validation": Group(
        "Verification and validation",
        "Solution verification (grid convergence index, discretization studies) and "
        "validation against measurements (comparison error, validation uncertainty, area "
        "metric).",
        ("grid_convergence_index", "GCIResult", "verify_discretization", "VerificationResult",
         "validate", "ValidationResult", "comparison_error", "ComparisonError",
         "area_metric", "pooled_area_metric", "PooledAreaMetric")),
    "multifidelity": Group(
        "Multi-fidelity",
        "Monte Carlo estimators that spend a budget over models of different cost and "
        "fidelity: moments and Sobol indices.",
        ("multifidelity_sample", "MultifidelityResult", "LinearAdaptation",
         "multifidelity_sobol", "MultifidelitySobolResult")),
    "evaluation": Group(
        "Evaluation layer and external solvers",
        "Running models at scale: the evaluator, its executors and its evaluation store, "
        "external solvers through Dakota's file contract, and the MBDyn driver.",
        ("Evaluator", "rotoruq.evaluation.as_evaluator", "rotoruq.evaluation.EvalStats",
         "SerialExecutor", "ProcessExecutor", "DaskExecutor", "rotoruq.evaluation.Executor",
         "rotoruq.evaluation.make_executor", "Store", "rotoruq.evaluation.EvalRecord",
         "ExternalModel", "WorkDirectory", "FileContract", "fill_template",
         "rotoruq.evaluation.fill_template_file",
         "read_parameters", "write_parameters", "rotoruq.evaluation.ParametersFile",
         "read_results", "write_results", "rotoruq.evaluation.ResultsFile",
         "rotoruq.mbdyn.run_case", "rotoruq.mbdyn.CaseSettings", "rotoruq.mbdyn.TEMPLATES",
         "rotoruq.mbdyn.template_values", "rotoruq.mbdyn.rigid_equivalent",
         "rotoruq.mbdyn.run_mbdyn", "rotoruq.mbdyn.MBDynRun", "rotoruq.mbdyn.find_mbdyn",
         "rotoruq.mbdyn.read_rotor_output", "rotoruq.mbdyn.hub_loads",
         "rotoruq.mbdyn.HubLoads")),
    "studies": Group(
        "Studies and results",
        "Study files and their runs (steps, reuse of earlier results), the saved results, and "
        "the HTML report.",
        ("load_study", "Study", "run_study", "StudyRun", "why_rerun", "step_types",
         "rotoruq.steps.STEP_TYPES", "rotoruq.steps.StepType", "rotoruq.steps.step_type",
         "rotoruq.steps.find_step_type", "rotoruq.steps.ENTRY_POINT_GROUP",
         "rotoruq.steps.StepContext", "rotoruq.steps.StepCheck", "rotoruq.steps.run_step",
         "load_results", "StepResult", "StepRecord", "write_report")),
    "errors": Group(
        "Errors",
        "Every error rotoruq raises on purpose derives from ``RotoruqError`` and from the "
        "built-in exception that fits it (``ValueError`` for a bad input, ``RuntimeError`` for "
        "a failed evaluation, ``OSError`` for a fault of the evaluation store, ...), so an "
        "``except`` clause written for either catches it.",
        ("RotoruqError", "ParameterError", "InputFileError", "EvaluationError", "errors",
         "rotoruq.mbdyn.MBDynError", "rotoruq.mbdyn.MBDynNotFoundError",
         "rotoruq.steps.UnknownStepTypeError")),
}


def full_name(name: str) -> str:
    """``rotoruq.NAME`` for a top-level public name, the name itself for a full one."""
    return name if name.startswith("rotoruq.") else f"rotoruq.{name}"


def resolve(name: str):
    """The object a group's name stands for."""
    module, _, attr = full_name(name).rpartition(".")
    return getattr(importlib.import_module(module), attr)


def _indent(lines: list[str], prefix: str = "   ") -> list[str]:
    return [prefix + ln if ln else "" for ln in lines]


def data_doc(name: str) -> list[str]:
    """The ``#:`` documentation comment of a public constant, from the module that defines it
    (a constant has no docstring of its own; its type's docstring is not its documentation)."""
    from sphinx.pycode import ModuleAnalyzer

    obj = resolve(name)
    attr = name.rpartition(".")[2]
    candidates = [m for m in list(sys.modules.values())
                  if getattr(m, "__name__", "").startswith("rotoruq")
                  and vars(m).get(attr) is obj]
    for module in sorted(candidates, key=lambda m: m.__name__):
        try:
            docs = ModuleAnalyzer.for_module(module.__name__).find_attr_docs()
        except Exception:  # noqa: BLE001 (a module without source: look further)
            continue
        if ("", attr) in docs:
            return [ln for ln in docs["", attr] if ln is not None]
    return []


def _short_value(obj) -> bool:
    return isinstance(obj, str | int | float | tuple) and len(repr(obj)) <= 120


def data_docstring(app, what, name, obj, options, lines):  # noqa: ARG001 (Sphinx's signature)
    """A public constant's documentation is its ``#:`` comment, in its entry and in the
    summary tables (where autodoc would show its type's docstring, ``Built-in immutable
    sequence.``)."""
    if what == "data" and name.startswith("rotoruq."):
        lines[:] = data_doc(name) or ([] if lines == (inspect.getdoc(type(obj)) or "")
                                      .splitlines() else lines)


def _skipped_bases(cls: type) -> str:
    """The bases outside rotoruq (``object``, ``Exception``, ``tuple``...): their members are
    not the class's documentation."""
    return ", ".join(dict.fromkeys(k.__name__ for k in cls.__mro__
                                   if not k.__module__.startswith("rotoruq")))


def entry(name: str) -> list[str]:
    """The reST of one name's full entry, under its public (full) name."""
    obj, full = resolve(name), full_name(name)
    if inspect.ismodule(obj):
        top = set(importlib.import_module("rotoruq").__all__)
        lines = [f".. automodule:: {obj.__name__}", "",
                 f"``rq.{name}`` is the module :mod:`{obj.__name__}`; the names it adds to "
                 f"the ones above:", ""]
        for member in getattr(obj, "__all__", ()):
            if member not in top:
                lines += entry(f"{obj.__name__}.{member}")
        return lines
    if inspect.isclass(obj):
        return [f".. autoclass:: {full}", "   :members:",
                f"   :inherited-members: {_skipped_bases(obj)}", ""]
    if callable(obj):
        return [f".. autofunction:: {full}", ""]
    lines = [f".. autodata:: {full}"] + ([] if _short_value(obj) else ["   :no-value:"])
    return lines + [""]


def summary_table(names: tuple[str, ...]) -> list[str]:
    lines = [".. currentmodule:: rotoruq", "", ".. autosummary::", ""]
    for name in names:
        if inspect.ismodule(resolve(name)):
            continue  # a module's entry follows the table; it has no one-line summary
        lines.append("   " + full_name(name).removeprefix("rotoruq."))
    return lines + [""]


def group_page(key: str) -> str:
    """The reST text of one group's page."""
    group = GROUPS[key]
    lines = [group.title, "=" * len(group.title), "", group.intro, ""]
    lines += summary_table(group.names)
    for name in group.names:
        lines += ["", "----", ""] + entry(name)
    return "\n".join(lines) + "\n"


INDEX_INTRO = """\
API reference
=============

The public names of ``rotoruq``, grouped by task. A short name (``sample``) is imported from
the top level (``import rotoruq as rq; rq.sample``), where every name loads on first use; a
full name (``rotoruq.params.NatafModel``) is imported from its subpackage. Every parameter of
a function, class or method is described in its entry (``tests/test_docstrings.py`` checks,
and names the few that are still waiting).
"""


def index_page() -> str:
    """The reST text of the API reference's first page: the groups and their names."""
    lines = INDEX_INTRO.splitlines() + ["", ".. toctree::", "   :hidden:", ""]
    lines += [f"   {key}" for key in GROUPS] + [""]
    for key, group in GROUPS.items():
        shown = [f":mod:`rq.{n} <{resolve(n).__name__}>`" if inspect.ismodule(resolve(n))
                 else f":obj:`{full_name(n).removeprefix('rotoruq.')} <{full_name(n)}>`"
                 for n in group.names]
        lines += [f":doc:`{group.title} <{key}>`", f"   {group.intro}", "",
                  "   " + ", ".join(shown), ""]
    return "\n".join(lines) + "\n"


class _Generated(SphinxDirective):
    def _parse(self, text: str) -> list[nodes.Node]:
        node = nodes.Element()
        source = self.get_source_info()[0]
        content = StringList(text.splitlines(), source=f"{source} (generated by public_api)")
        nested_parse_with_titles(self.state, content, node)
        return node.children


class ApiGroup(_Generated):
    """``.. rotoruq-api:: KEY``: the page of group KEY of ``GROUPS``."""

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        key = self.arguments[0]
        if key not in GROUPS:
            raise self.error(f"no API group {key!r} in docs/_ext/public_api.py GROUPS; "
                             f"have {', '.join(GROUPS)}")
        return self._parse(group_page(key))


class ApiIndex(_Generated):
    """``.. rotoruq-api-index::``: the first page of the API reference."""

    def run(self) -> list[nodes.Node]:
        return self._parse(index_page())


def setup(app):
    app.add_directive("rotoruq-api", ApiGroup)
    app.add_directive("rotoruq-api-index", ApiIndex)
    app.connect("autodoc-process-docstring", data_docstring)
    return {"parallel_read_safe": True}
