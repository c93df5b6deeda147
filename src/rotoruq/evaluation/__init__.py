"""Evaluation layer: the Model protocol, Dakota files, external drivers, store, executors."""

from .model import EvalBatch, FunctionModel, Model, align_inputs, evaluate, has_gradient

__all__ = ["EvalBatch", "FunctionModel", "Model", "align_inputs", "evaluate", "has_gradient"]
