"""Epistemic variables: :class:`Interval`, one or more intervals with basic probability
assignments (BPAs).

Methods that need a density treat an Interval as the BPA-weighted mixture of uniform densities
over its intervals (Dakota does the same when it samples them); the evidence method
(:mod:`rotoruq.methods.evidence`) uses the intervals themselves.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import ParameterError
from .distributions import _finite, _freeze, _ordered, _PiecewiseDensity

__all__ = ["Interval"]


@dataclass(frozen=True)
class Interval(_PiecewiseDensity):
    """Epistemic variable: intervals ``[(lo_1, hi_1), ...]`` with basic probability assignments.

    As a density (for sampling, u-space transforms, moments) the variable is the BPA-weighted
    mixture of uniform densities over the intervals.

    Parameters
    ----------
    intervals : sequence of (float, float)
        The (lower, upper) pairs, in the variable's units; they may overlap or nest. Stored
        as a tuple of pairs.
    bpa : sequence of float, optional
        The basic probability assignment of each interval, each > 0, summing to 1 (within
        1e-8). Default: equal weights. Stored as a tuple.
    """

    intervals: Sequence[Sequence[float]]
    bpa: Sequence[float] | None = None
    _edges: np.ndarray = field(init=False, repr=False, compare=False)
    _dens: np.ndarray = field(init=False, repr=False, compare=False)
    _cdfk: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        try:
            iv = np.array(self.intervals, dtype=float).reshape(-1, 2)
        except (TypeError, ValueError):
            raise ParameterError(
                f"Interval: intervals must be (lower, upper) pairs, got {self.intervals!r}"
            ) from None
        if iv.shape[0] == 0:
            raise ParameterError("Interval: at least one interval is needed")
        for lo, hi in iv:
            _finite("lower", lo, "Interval")
            _finite("upper", hi, "Interval")
            _ordered(lo, hi, "Interval")
        if self.bpa is None:
            w = np.full(iv.shape[0], 1.0 / iv.shape[0])
        else:
            w = np.array(self.bpa, dtype=float).ravel()
            if w.shape[0] != iv.shape[0]:
                raise ParameterError(
                    f"Interval: {iv.shape[0]} intervals but {w.shape[0]} BPA values"
                )
            if np.any(~np.isfinite(w)) or np.any(w <= 0):
                raise ParameterError(f"Interval: BPA values must be > 0, got {w.tolist()}")
            if abs(w.sum() - 1.0) > 1e-8:
                raise ParameterError(f"Interval: BPA values must sum to 1, got {w.sum()!r}")
        object.__setattr__(self, "intervals", tuple(map(tuple, iv.tolist())))
        object.__setattr__(self, "bpa", tuple(w.tolist()))
        # piecewise-linear mixture CDF on the sorted breakpoints
        knots = np.unique(iv.ravel())
        dens = np.zeros(knots.size - 1)
        for (lo, hi), wk in zip(iv, w, strict=True):
            inside = (knots[:-1] >= lo) & (knots[1:] <= hi)
            dens[inside] += wk / (hi - lo)
        cdf = np.concatenate([[0.0], np.cumsum(dens * np.diff(knots))])
        cdf /= cdf[-1]
        _freeze(self, None)
        object.__setattr__(self, "_edges", knots)
        object.__setattr__(self, "_dens", dens)
        object.__setattr__(self, "_cdfk", cdf)

    @property
    def dist(self) -> Interval:
        return self

    @property
    def moments(self) -> tuple[float, float]:
        """(mean, std) of the BPA-weighted mixture of uniform densities."""
        iv = np.array(self.intervals)
        w = np.asarray(self.bpa, dtype=float)
        mean = float(np.dot(w, iv.mean(axis=1)))
        m2 = np.dot(w, (iv[:, 0] ** 2 + iv[:, 0] * iv[:, 1] + iv[:, 1] ** 2) / 3.0)
        return mean, float(np.sqrt(max(m2 - mean**2, 0.0)))

    def cdf(self, x: Any) -> np.ndarray:
        return np.asarray(np.interp(x, self._edges, self._cdfk, left=0.0, right=1.0))

    # the upper tail is measured from the knot above (exact near the upper bound)
    def sf(self, x: Any) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        t, s = self._edges, 1.0 - self._cdfk
        k = self._bin(x)
        out = s[k + 1] + (t[k + 1] - x) * self._dens[k]
        return np.where(x < t[0], 1.0, np.where(x >= t[-1], 0.0, out))

    def isf(self, q: Any) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        t, s = self._edges, 1.0 - self._cdfk
        # segment k with s[k+1] <= q < s[k] (s decreasing); flat pieces are skipped
        k = np.clip(s.size - 1 - np.searchsorted(s[::-1], q, side="right"), 0, s.size - 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            out = t[k + 1] - (q - s[k + 1]) / self._dens[k]
        return np.where((q < 0) | (q > 1), np.nan, out)

    def ppf(self, q: Any) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        c, t = self._cdfk, self._edges
        # segment k with c[k] < q <= c[k+1]: flat pieces (gaps between intervals) are skipped
        k = np.clip(np.searchsorted(c, q, side="left") - 1, 0, c.size - 2)
        out = t[k] + (q - c[k]) / (c[k + 1] - c[k]) * (t[k + 1] - t[k])
        return np.where((q < 0) | (q > 1), np.nan, out)

    def describe(self) -> dict[str, Any]:
        return {"kind": "interval", "intervals": list(self.intervals),
                "bpa": list(self.bpa or ())}
