"""Evaluation layer: Dakota files, external drivers, the store, executors (the Model protocol is
:mod:`rotoruq.model`)."""

from .dakota_files import (
    ParametersFile,
    ResultsFile,
    read_parameters,
    read_results,
    write_parameters,
    write_results,
)
from .evaluator import EvalStats, Evaluator, as_evaluator
from .executors import DaskExecutor, Executor, ProcessExecutor, SerialExecutor, make_executor
from .external import ExternalModel, FileContract, WorkDirectory
from .store import EvalRecord, Store
from .templates import fill_template, fill_template_file

__all__ = [
    "ParametersFile",
    "ResultsFile",
    "read_parameters",
    "read_results",
    "write_parameters",
    "write_results",
    "EvalStats",
    "Evaluator",
    "as_evaluator",
    "DaskExecutor",
    "Executor",
    "ProcessExecutor",
    "SerialExecutor",
    "make_executor",
    "ExternalModel",
    "FileContract",
    "WorkDirectory",
    "EvalRecord",
    "Store",
    "fill_template",
    "fill_template_file",
]
