"""Evaluation layer: the Model protocol, Dakota files, external drivers, store, executors."""

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
from .external import ExternalModel
from .model import EvalBatch, FunctionModel, Model, align_inputs, evaluate, has_gradient
from .store import EvalRecord, Store
from .templates import fill_template, fill_template_file

__all__ = [
    "EvalBatch",
    "FunctionModel",
    "Model",
    "align_inputs",
    "evaluate",
    "has_gradient",
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
    "EvalRecord",
    "Store",
    "fill_template",
    "fill_template_file",
]
