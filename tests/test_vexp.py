"""The emulator's own exponential (``methods/_vexp.py``) and the GP mean's fixed-order sum.

The exponential is checked against the correctly rounded value (``decimal`` at 40 digits, the
same reference on every platform): within one unit in the last place over the whole range,
subnormal results included, and exact at the special values. The weighted sum of the GP mean
(``_gp_mean._dot8``) is checked bit for bit against the order it documents.
"""

from __future__ import annotations

import decimal
import math

import numba as nb
import numpy as np
import pytest

from rotoruq.methods._gp_mean import _dot8
from rotoruq.methods._vexp import exp_into


@nb.njit(cache=False)
def _exp_array(x):
    out = np.empty_like(x)
    exp_into(x, out)
    return out


@nb.njit(cache=False)
def _dot(a, b):
    return _dot8(a, b, a.shape[0])


def _ulps_from_exact(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """|y - exp(x)| in units of the last place of the correctly rounded exp(x) (decimal)."""
    ctx = decimal.Context(prec=40)
    out = np.empty(x.size)
    for k, (xi, yi) in enumerate(zip(x.tolist(), y.tolist(), strict=True)):
        exact = ctx.exp(decimal.Decimal(xi))
        rounded = float(exact)
        ulp = math.ulp(rounded) if rounded > 0.0 else 5e-324
        out[k] = float(abs(decimal.Decimal(yi) - exact) / decimal.Decimal(ulp))
    return out


def test_exp_is_within_one_ulp_of_the_correctly_rounded_value():
    rng = np.random.default_rng(0)
    x = np.concatenate([
        rng.uniform(-745.0, 709.7, 3000),        # the whole finite range
        -0.5 * rng.uniform(0.0, 6.0, 3000) ** 2,  # a squared-exponential kernel's arguments
        rng.uniform(-745.1, -708.4, 500),        # subnormal results
        rng.uniform(-1e-12, 1e-12, 200),         # near 0
        np.array([-0.5, -1.0, 1.0, 709.78, -708.39, -745.13]),
    ])
    err = _ulps_from_exact(x, _exp_array(x))
    assert err.max() <= 1.0, (err.max(), x[err.argmax()])
    # most are the correctly rounded value itself
    assert np.mean(err <= 0.5) > 0.85


def test_exp_special_values():
    x = np.array([0.0, -0.0, -np.inf, np.inf, np.nan, -746.0, -1e300, 710.0, 1e300, 709.78])
    y = _exp_array(x)
    assert y[0] == 1.0 and y[1] == 1.0
    assert y[2] == 0.0 and y[5] == 0.0 and y[6] == 0.0
    assert y[3] == np.inf and y[7] == np.inf and y[8] == np.inf
    assert np.isnan(y[4])
    assert np.isfinite(y[9]) and y[9] > 1.79e308
    # the smallest subnormal is reached, not flushed to zero
    assert _exp_array(np.array([-745.1]))[0] == 5e-324


def test_exp_is_the_same_in_place_and_element_by_element():
    x = -0.5 * np.random.default_rng(1).uniform(0.0, 4.0, 1003) ** 2
    whole = _exp_array(x)
    one_by_one = np.array([_exp_array(x[k:k + 1])[0] for k in range(x.size)])
    np.testing.assert_array_equal(whole, one_by_one)


def _dot8_reference(a: np.ndarray, b: np.ndarray) -> float:
    sums = [0.0] * 8
    n = len(a)
    m = n - n % 8
    for i in range(m):
        sums[i % 8] += float(a[i]) * float(b[i])
    for i in range(m, n):
        sums[0] += float(a[i]) * float(b[i])
    s0, s1, s2, s3, s4, s5, s6, s7 = sums
    return ((s0 + s4) + (s1 + s5)) + ((s2 + s6) + (s3 + s7))


@pytest.mark.parametrize("n", [0, 1, 7, 8, 9, 40, 501])
def test_the_gp_means_weighted_sum_keeps_its_documented_order(n):
    rng = np.random.default_rng(n)
    # weights of both signs and many magnitudes: another order gives other bits
    a = rng.standard_normal(n) * 10.0 ** rng.integers(-3, 6, n)
    b = rng.random(n)
    got = _dot(a, b)
    assert got == _dot8_reference(a, b)
    if n:
        assert abs(got - math.fsum(a * b)) <= 1e-12 * np.abs(a * b).sum()
