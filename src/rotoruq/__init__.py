"""rotoruq: verification, validation and calibration under uncertainty of helicopter rotor models.

The public API is re-exported here; see README.md for a tour. The names are loaded on first use
(PEP 562 module ``__getattr__``), so ``import rotoruq`` and importing one layer (say
``rotoruq.rotor.hover``) do not load the others.
"""

from __future__ import annotations

import importlib

# typing.TYPE_CHECKING without importing typing (10 ms of the driver's start-up)
TYPE_CHECKING = False
if TYPE_CHECKING:
    from typing import Any

__version__ = "0.1.0"

# THE list of public names: name -> the module that defines it (relative to this package); a
# public submodule names itself. `__all__` is its keys, `__getattr__` loads from it, and the
# TYPE_CHECKING imports at the end name the same set (tests/test_public_api.py checks; run
# `python tests/test_public_api.py` to rewrite that block after editing this one).
_PUBLIC: dict[str, str] = {
    "errors": ".errors",
    "presets": ".rotor.presets",
    "as_generator": "._rng",
    "EvaluationError": ".errors",
    "InputFileError": ".errors",
    "ParameterError": ".errors",
    "RotoruqError": ".errors",
    "EvalBatch": ".model",
    "FunctionModel": ".model",
    "Model": ".model",
    "evaluate": ".model",
    "Beta": ".params",
    "Exponential": ".params",
    "Frechet": ".params",
    "Gamma": ".params",
    "Gumbel": ".params",
    "HistogramBin": ".params",
    "Interval": ".params",
    "kernel_density": ".params",
    "LogNormal": ".params",
    "LogUniform": ".params",
    "Normal": ".params",
    "ParameterSpace": ".params",
    "Triangular": ".params",
    "TruncatedNormal": ".params",
    "Uniform": ".params",
    "Weibull": ".params",
    "make_distribution": ".params",
    "LinearAirfoil": ".rotor.aero",
    "RESPONSES": ".rotor.model",
    "ROTOR_INPUTS": ".rotor.model",
    "RotorModel": ".rotor.model",
    "ForwardRotorModel": ".rotor.forward",
    "RotorDiscretization": ".rotor.discretization",
    "RotorPreset": ".rotor.presets",
    "get_preset": ".rotor.presets",
    "Airfoil": ".rotor.airfoil",
    "AirfoilFit": ".rotor.airfoil",
    "fit_airfoil": ".rotor.airfoil",
    "write_perturbed_c81": ".rotor.airfoil",
    "C81Block": ".rotor.c81",
    "C81Table": ".rotor.c81",
    "read_c81": ".rotor.c81",
    "write_c81": ".rotor.c81",
    "EvidenceResult": ".methods.evidence",
    "evidence": ".methods.evidence",
    "CoKriging": ".methods.cokriging",
    "MultifidelityResult": ".methods.multifidelity",
    "LinearAdaptation": ".methods.multifidelity",
    "multifidelity_sample": ".methods.multifidelity",
    "MultifidelitySobolResult": ".methods.multifidelity_sobol",
    "multifidelity_sobol": ".methods.multifidelity_sobol",
    "PCEResult": ".methods.pce",
    "polynomial_chaos": ".methods.pce",
    "MeanValueResult": ".methods.reliability",
    "MPPResult": ".methods.reliability",
    "mean_value": ".methods.reliability",
    "mean_value_from_gradient": ".methods.reliability",
    "mpp_search": ".methods.reliability",
    "ResponseStatistics": ".methods.sampling",
    "SamplingResult": ".methods.sampling",
    "refine": ".methods.sampling",
    "response_statistics": ".methods.sampling",
    "sample": ".methods.sampling",
    "SobolResult": ".methods.sensitivity",
    "sobol_indices": ".methods.sensitivity",
    "ValidationResult": ".methods.validation",
    "ComparisonError": ".methods.validation",
    "validate": ".methods.validation",
    "comparison_error": ".methods.validation",
    "area_metric": ".methods.validation",
    "pooled_area_metric": ".methods.validation",
    "PooledAreaMetric": ".methods.validation",
    "GCIResult": ".methods.verification",
    "VerificationResult": ".methods.verification",
    "grid_convergence_index": ".methods.verification",
    "verify_discretization": ".methods.verification",
    "BayesResult": ".methods.mcmc",
    "calibrate_bayes": ".methods.mcmc",
    "continue_chain": ".methods.mcmc",
    "ChainOptions": ".methods.mcmc",
    "EmulatorOptions": ".methods.mcmc",
    "NoiseModel": ".methods.mcmc",
    "SBCResult": ".methods.mcmc.sbc",
    "simulation_based_calibration": ".methods.mcmc.sbc",
    "Discrepancy": ".methods.mcmc.discrepancy",
    "DiscrepancyPrediction": ".methods.mcmc.discrepancy",
    "DiscrepancyResult": ".methods.mcmc.discrepancy",
    "calibrate_with_discrepancy": ".methods.mcmc.discrepancy",
    "predict_with_discrepancy": ".methods.mcmc.discrepancy",
    "GaussianProcess": ".methods.surrogate",
    "ImportanceSamplingResult": ".methods.importance",
    "importance_sampling": ".methods.importance",
    "box_extremes": ".methods.ego",
    "LeaveOneOut": ".methods.surrogate",
    "CUUCheck": ".methods.cuu",
    "CUUResult": ".methods.cuu",
    "calibrate_under_uncertainty": ".methods.cuu",
    "check_cuu": ".methods.cuu",
    "CalibrationResult": ".methods.least_squares",
    "Convergence": ".methods.least_squares",
    "LeastSquaresResult": ".methods.least_squares",
    "calibrate": ".methods.least_squares",
    "least_squares": ".methods.least_squares",
    "DaskExecutor": ".evaluation",
    "Evaluator": ".evaluation",
    "ExternalModel": ".evaluation",
    "FileContract": ".evaluation",
    "WorkDirectory": ".evaluation",
    "ProcessExecutor": ".evaluation",
    "SerialExecutor": ".evaluation",
    "Store": ".evaluation",
    "fill_template": ".evaluation",
    "read_parameters": ".evaluation",
    "read_results": ".evaluation",
    "write_parameters": ".evaluation",
    "write_results": ".evaluation",
    "write_report": ".report.html",
    "StepResult": ".results",
    "StepRecord": ".results",
    "load_results": ".results",
    "step_types": ".steps",
    "StudyRun": ".study.runner",
    "run_study": ".study.runner",
    "why_rerun": ".study.runner",
    "Study": ".study.spec",
    "load_study": ".study.schema",
    "FUNCTIONS": ".testfunctions",
    "DakotaFunction": ".testfunctions",
    "dakota_function": ".testfunctions",
}
__all__ = ["__version__", *_PUBLIC]


def __getattr__(name: str) -> Any:
    if name not in _PUBLIC:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module = importlib.import_module(_PUBLIC[name], __name__)
    # a public submodule (rq.errors, rq.presets) is the module itself
    is_module = module.__name__.rpartition(".")[2] == name and name not in vars(module)
    value = module if is_module else getattr(module, name)
    globals()[name] = value  # later look-ups skip __getattr__
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


if TYPE_CHECKING:  # the same names, eagerly, for type checkers and IDEs
    from . import errors as errors
    from ._rng import as_generator as as_generator
    from .errors import EvaluationError as EvaluationError
    from .errors import InputFileError as InputFileError
    from .errors import ParameterError as ParameterError
    from .errors import RotoruqError as RotoruqError
    from .evaluation import DaskExecutor as DaskExecutor
    from .evaluation import Evaluator as Evaluator
    from .evaluation import ExternalModel as ExternalModel
    from .evaluation import FileContract as FileContract
    from .evaluation import ProcessExecutor as ProcessExecutor
    from .evaluation import SerialExecutor as SerialExecutor
    from .evaluation import Store as Store
    from .evaluation import WorkDirectory as WorkDirectory
    from .evaluation import fill_template as fill_template
    from .evaluation import read_parameters as read_parameters
    from .evaluation import read_results as read_results
    from .evaluation import write_parameters as write_parameters
    from .evaluation import write_results as write_results
    from .methods.cokriging import CoKriging as CoKriging
    from .methods.cuu import CUUCheck as CUUCheck
    from .methods.cuu import CUUResult as CUUResult
    from .methods.cuu import calibrate_under_uncertainty as calibrate_under_uncertainty
    from .methods.cuu import check_cuu as check_cuu
    from .methods.ego import box_extremes as box_extremes
    from .methods.evidence import EvidenceResult as EvidenceResult
    from .methods.evidence import evidence as evidence
    from .methods.importance import ImportanceSamplingResult as ImportanceSamplingResult
    from .methods.importance import importance_sampling as importance_sampling
    from .methods.least_squares import CalibrationResult as CalibrationResult
    from .methods.least_squares import Convergence as Convergence
    from .methods.least_squares import LeastSquaresResult as LeastSquaresResult
    from .methods.least_squares import calibrate as calibrate
    from .methods.least_squares import least_squares as least_squares
    from .methods.mcmc import BayesResult as BayesResult
    from .methods.mcmc import ChainOptions as ChainOptions
    from .methods.mcmc import EmulatorOptions as EmulatorOptions
    from .methods.mcmc import NoiseModel as NoiseModel
    from .methods.mcmc import calibrate_bayes as calibrate_bayes
    from .methods.mcmc import continue_chain as continue_chain
    from .methods.mcmc.discrepancy import Discrepancy as Discrepancy
    from .methods.mcmc.discrepancy import DiscrepancyPrediction as DiscrepancyPrediction
    from .methods.mcmc.discrepancy import DiscrepancyResult as DiscrepancyResult
    from .methods.mcmc.discrepancy import calibrate_with_discrepancy as calibrate_with_discrepancy
    from .methods.mcmc.discrepancy import predict_with_discrepancy as predict_with_discrepancy
    from .methods.mcmc.sbc import SBCResult as SBCResult
    from .methods.mcmc.sbc import simulation_based_calibration as simulation_based_calibration
    from .methods.multifidelity import LinearAdaptation as LinearAdaptation
    from .methods.multifidelity import MultifidelityResult as MultifidelityResult
    from .methods.multifidelity import multifidelity_sample as multifidelity_sample
    from .methods.multifidelity_sobol import MultifidelitySobolResult as MultifidelitySobolResult
    from .methods.multifidelity_sobol import multifidelity_sobol as multifidelity_sobol
    from .methods.pce import PCEResult as PCEResult
    from .methods.pce import polynomial_chaos as polynomial_chaos
    from .methods.reliability import MeanValueResult as MeanValueResult
    from .methods.reliability import MPPResult as MPPResult
    from .methods.reliability import mean_value as mean_value
    from .methods.reliability import mean_value_from_gradient as mean_value_from_gradient
    from .methods.reliability import mpp_search as mpp_search
    from .methods.sampling import ResponseStatistics as ResponseStatistics
    from .methods.sampling import SamplingResult as SamplingResult
    from .methods.sampling import refine as refine
    from .methods.sampling import response_statistics as response_statistics
    from .methods.sampling import sample as sample
    from .methods.sensitivity import SobolResult as SobolResult
    from .methods.sensitivity import sobol_indices as sobol_indices
    from .methods.surrogate import GaussianProcess as GaussianProcess
    from .methods.surrogate import LeaveOneOut as LeaveOneOut
    from .methods.validation import ComparisonError as ComparisonError
    from .methods.validation import PooledAreaMetric as PooledAreaMetric
    from .methods.validation import ValidationResult as ValidationResult
    from .methods.validation import area_metric as area_metric
    from .methods.validation import comparison_error as comparison_error
    from .methods.validation import pooled_area_metric as pooled_area_metric
    from .methods.validation import validate as validate
    from .methods.verification import GCIResult as GCIResult
    from .methods.verification import VerificationResult as VerificationResult
    from .methods.verification import grid_convergence_index as grid_convergence_index
    from .methods.verification import verify_discretization as verify_discretization
    from .model import EvalBatch as EvalBatch
    from .model import FunctionModel as FunctionModel
    from .model import Model as Model
    from .model import evaluate as evaluate
    from .params import Beta as Beta
    from .params import Exponential as Exponential
    from .params import Frechet as Frechet
    from .params import Gamma as Gamma
    from .params import Gumbel as Gumbel
    from .params import HistogramBin as HistogramBin
    from .params import Interval as Interval
    from .params import LogNormal as LogNormal
    from .params import LogUniform as LogUniform
    from .params import Normal as Normal
    from .params import ParameterSpace as ParameterSpace
    from .params import Triangular as Triangular
    from .params import TruncatedNormal as TruncatedNormal
    from .params import Uniform as Uniform
    from .params import Weibull as Weibull
    from .params import kernel_density as kernel_density
    from .params import make_distribution as make_distribution
    from .report.html import write_report as write_report
    from .results import StepRecord as StepRecord
    from .results import StepResult as StepResult
    from .results import load_results as load_results
    from .rotor import presets as presets
    from .rotor.aero import LinearAirfoil as LinearAirfoil
    from .rotor.airfoil import Airfoil as Airfoil
    from .rotor.airfoil import AirfoilFit as AirfoilFit
    from .rotor.airfoil import fit_airfoil as fit_airfoil
    from .rotor.airfoil import write_perturbed_c81 as write_perturbed_c81
    from .rotor.c81 import C81Block as C81Block
    from .rotor.c81 import C81Table as C81Table
    from .rotor.c81 import read_c81 as read_c81
    from .rotor.c81 import write_c81 as write_c81
    from .rotor.discretization import RotorDiscretization as RotorDiscretization
    from .rotor.forward import ForwardRotorModel as ForwardRotorModel
    from .rotor.model import RESPONSES as RESPONSES
    from .rotor.model import ROTOR_INPUTS as ROTOR_INPUTS
    from .rotor.model import RotorModel as RotorModel
    from .rotor.presets import RotorPreset as RotorPreset
    from .rotor.presets import get_preset as get_preset
    from .steps import step_types as step_types
    from .study.runner import StudyRun as StudyRun
    from .study.runner import run_study as run_study
    from .study.runner import why_rerun as why_rerun
    from .study.schema import load_study as load_study
    from .study.spec import Study as Study
    from .testfunctions import FUNCTIONS as FUNCTIONS
    from .testfunctions import DakotaFunction as DakotaFunction
    from .testfunctions import dakota_function as dakota_function
