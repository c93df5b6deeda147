"""Helpers several step adapters share: moments of sampled columns, the input distributions'
summary, added measurement noise and per-response noise levels."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from scipy import stats

from ..params import ParameterSpace
from .base import StepContext

__all__ = ["stats_scalars", "input_scalars", "noise", "per_response"]


def stats_scalars(prefix_names: Sequence[str], values: np.ndarray, suffix: str = "") -> dict:
    """mean/std/skewness/kurtosis of each column (ddof=1, bias-corrected, excess kurtosis)."""
    out = {}
    for j, name in enumerate(prefix_names):
        v = values[:, j]
        v = v[np.isfinite(v)]
        if v.size < 2:
            continue
        out[f"mean/{name}{suffix}"] = float(np.mean(v))
        out[f"std/{name}{suffix}"] = float(np.std(v, ddof=1))
        if v.size > 3 and np.std(v) > 0:
            out[f"skewness/{name}{suffix}"] = float(stats.skew(v, bias=False))
            out[f"kurtosis/{name}{suffix}"] = float(stats.kurtosis(v, bias=False))
    return out


def input_scalars(space: ParameterSpace) -> dict:
    """``input_mean/``, ``input_std/`` and, for bounded inputs, ``input_lower/``,
    ``input_upper/`` of each input."""
    out = {}
    for name, d in zip(space.names, space.distributions, strict=True):
        out[f"input_mean/{name}"] = d.mean
        out[f"input_std/{name}"] = d.std
        lo, hi = d.bounds
        if np.isfinite(lo) and np.isfinite(hi):
            out[f"input_lower/{name}"] = lo
            out[f"input_upper/{name}"] = hi
    return out


def noise(ctx: StepContext, noise_std, shape) -> np.ndarray:
    """Gaussian noise of shape ``shape`` (n, m) with std ``noise_std`` (a number or a table
    per response; zeros without one), drawn from the step's generator."""
    if not noise_std:
        return np.zeros(shape)
    if isinstance(noise_std, Mapping):
        sd = np.array([float(noise_std.get(r, 0.0)) for r in ctx.responses])
    else:
        sd = np.full(shape[1], float(noise_std))
    return ctx.rng.normal(size=shape) * sd


def per_response(value, responses):
    """A table of per-response values as an array in ``responses`` order (else unchanged)."""
    if value is None or not isinstance(value, Mapping):
        return value
    return np.array([float(value[r]) for r in responses])
