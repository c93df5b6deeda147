"""Uncertain parameters: marginal distributions (:mod:`.distributions`, :mod:`.interval`), the
Nataf model of correlated parameters (:mod:`.nataf`) and the :class:`ParameterSpace` that every
method draws points from and transforms into (:mod:`.space`)."""

from __future__ import annotations

from .catalog import DISTRIBUTIONS, distribution_keys, make_distribution
from .density import kernel_density
from .distributions import (
    Beta,
    Distribution,
    Exponential,
    Frechet,
    Gamma,
    Gumbel,
    HistogramBin,
    LogNormal,
    LogUniform,
    Normal,
    Triangular,
    TruncatedNormal,
    Uniform,
    Weibull,
)
from .interval import Interval
from .nataf import NatafModel, nataf_correlation, nataf_model
from .pairing import PAIRINGS, restricted_pairing
from .space import DESIGNS, ParameterSpace, unit_design

__all__ = [
    "Distribution",
    "Normal",
    "TruncatedNormal",
    "LogNormal",
    "Uniform",
    "LogUniform",
    "Beta",
    "Gamma",
    "Exponential",
    "Gumbel",
    "Weibull",
    "Triangular",
    "Frechet",
    "HistogramBin",
    "kernel_density",
    "Interval",
    "ParameterSpace",
    "DESIGNS",
    "unit_design",
    "PAIRINGS",
    "restricted_pairing",
    "NatafModel",
    "nataf_correlation",
    "nataf_model",
    "make_distribution",
    "distribution_keys",
    "DISTRIBUTIONS",
]
