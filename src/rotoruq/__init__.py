"""rotoruq: verification, validation and calibration under uncertainty of helicopter rotor models.

The public API is re-exported here; see README.md for a tour.
"""

from __future__ import annotations

from . import errors
from ._rng import as_generator
from .errors import EvaluationError, InputFileError, ParameterError, RotoruqError
from .model import EvalBatch, FunctionModel, Model, evaluate
from .params import (
    Beta,
    Exponential,
    Gamma,
    Gumbel,
    LogNormal,
    LogUniform,
    Normal,
    ParameterSpace,
    Triangular,
    TruncatedNormal,
    Uniform,
    Weibull,
    make_distribution,
)

__version__ = "0.1.0"

__all__ = [
    "__version__",
    "errors",
    "as_generator",
    "EvaluationError",
    "InputFileError",
    "ParameterError",
    "RotoruqError",
    "EvalBatch",
    "FunctionModel",
    "Model",
    "evaluate",
    "Beta",
    "Exponential",
    "Gamma",
    "Gumbel",
    "LogNormal",
    "LogUniform",
    "Normal",
    "ParameterSpace",
    "Triangular",
    "TruncatedNormal",
    "Uniform",
    "Weibull",
    "make_distribution",
]

# --- rotor (issue 2) ---
from .rotor import presets
from .rotor.aero import LinearAirfoil
from .rotor.model import RESPONSES, ROTOR_INPUTS, RotorModel
from .rotor.presets import RotorPreset, get_preset

__all__ += ["presets", "LinearAirfoil", "RESPONSES", "ROTOR_INPUTS", "RotorModel",
            "RotorPreset", "get_preset"]

from .rotor.airfoil import Airfoil, AirfoilFit, fit_airfoil, write_perturbed_c81  # noqa: E402
from .rotor.c81 import C81Block, C81Table, read_c81, write_c81  # noqa: E402

__all__ += ["Airfoil", "AirfoilFit", "fit_airfoil", "write_perturbed_c81", "C81Block",
            "C81Table", "read_c81", "write_c81"]
# --- methods: forward UQ and sensitivity (issue 3) ---
from .methods.evidence import EvidenceResult, evidence  # noqa: E402
from .methods.pce import PCEResult, polynomial_chaos  # noqa: E402
from .methods.reliability import (  # noqa: E402
    MeanValueResult,
    MPPResult,
    mean_value,
    mean_value_from_gradient,
    mpp_search,
)
from .methods.sampling import (  # noqa: E402
    ResponseStatistics,
    SamplingResult,
    refine,
    response_statistics,
    sample,
)
from .methods.sensitivity import SobolResult, sobol_indices  # noqa: E402
from .params import Interval  # noqa: E402

__all__ += [
    "Interval",
    "MeanValueResult",
    "mean_value",
    "mean_value_from_gradient",
    "MPPResult",
    "mpp_search",
    "SamplingResult",
    "ResponseStatistics",
    "sample",
    "refine",
    "response_statistics",
    "SobolResult",
    "sobol_indices",
    "PCEResult",
    "polynomial_chaos",
    "EvidenceResult",
    "evidence",
]
# --- methods: surrogates and Bayes (issue 4) ---
from .methods.mcmc import BayesResult, calibrate_bayes, continue_chain  # noqa: E402
from .methods.surrogate import GaussianProcess, LeaveOneOut  # noqa: E402

__all__ += ["BayesResult", "calibrate_bayes", "continue_chain", "GaussianProcess", "LeaveOneOut"]
# --- methods: least squares and CUU (issue 5) ---
from .methods.cuu import CUUCheck, CUUResult, calibrate_under_uncertainty, check_cuu  # noqa: E402
from .methods.least_squares import (  # noqa: E402
    CalibrationResult,
    LeastSquaresResult,
    calibrate,
    least_squares,
)

__all__ += [
    "CUUCheck",
    "CUUResult",
    "CalibrationResult",
    "LeastSquaresResult",
    "calibrate",
    "calibrate_under_uncertainty",
    "check_cuu",
    "least_squares",
]
# --- evaluation layer (issue 6) ---
from .evaluation import (  # noqa: E402
    DaskExecutor,
    Evaluator,
    ExternalModel,
    ProcessExecutor,
    SerialExecutor,
    Store,
    fill_template,
    read_parameters,
    read_results,
    write_parameters,
    write_results,
)

__all__ += [
    "DaskExecutor",
    "Evaluator",
    "ExternalModel",
    "ProcessExecutor",
    "SerialExecutor",
    "Store",
    "fill_template",
    "read_parameters",
    "read_results",
    "write_parameters",
    "write_results",
]
# --- study and report (issue 7) ---
from .report.html import write_report  # noqa: E402
from .results import StepResult, load_results  # noqa: E402
from .study.runner import StudyRun, run_study  # noqa: E402
from .study.schema import load_study  # noqa: E402
from .study.spec import Study  # noqa: E402

__all__ += ["Study", "StudyRun", "StepResult", "load_study", "load_results", "run_study",
            "write_report"]
