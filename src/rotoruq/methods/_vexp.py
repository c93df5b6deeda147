"""An exponential the compiler vectorizes: ``exp`` of every element of an array in one loop of
plain arithmetic (numba).

A GP emulator's mean at one point is a sum of ``n`` correlations ``exp(-h_i^2 / 2)`` per
response: on a chain's every step, hundreds of exponentials. ``math.exp`` in compiled code is
a call into the C library per element (about 4 ns here, most of an emulator evaluation);
written as a range reduction, a polynomial and an exponent put together from integer bits,
the loop compiles to SIMD instructions (about 4 elements at a time). The result is within one
unit in the last place of the correctly rounded exponential, and it is the same bits on every
machine (no C library in it), where the C library's ``exp`` differs between libraries.

Method (as fdlibm's ``exp``, with a Taylor polynomial in place of its rational one):
``x = k ln2 + r``, ``k = round(x / ln2)``, ``|r| <= ln2 / 2`` (``ln2`` split in two parts so
that ``k ln2_hi`` is exact), ``exp(r) = 1 + (r + r^2 P(r))`` with ``P`` the Taylor series to
degree 13 (truncation below 0.04 ulp), times ``2^k`` built from its bits (in two factors
when the result is subnormal, so that it is rounded once).
"""

from __future__ import annotations

import math

import numba as nb
from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from .. import _numba_cache  # noqa: F401  (the cache keyed by what the kernels compile in)

__all__ = ["exp1", "exp_into"]

_LOG2E = 1.4426950408889634
_LN2_HI = 6.93147180369123816490e-01  # ln 2's high bits: k * _LN2_HI is exact for |k| < 2^20
_LN2_LO = 1.90821492927058770002e-10
# 1/k! for k = 2..13
_C2, _C3, _C4, _C5, _C6, _C7, _C8, _C9, _C10, _C11, _C12, _C13 = (
    1.0 / math.factorial(k) for k in range(2, 14))
_TWO_M54 = 2.0 ** -54
_SHIFTER = 6755399441055744.0  # 1.5 2^52: x + _SHIFTER rounds x to an integer in its low bits
_SHIFTER_BITS = 0x4338000000000000


@intrinsic
def _float_as_bits(typingctx, value):
    """The int64 of a float64's IEEE bits (a bitcast: no conversion)."""
    sig = types.int64(types.float64)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return sig, codegen


@intrinsic
def _bits_as_float(typingctx, bits):
    """The float64 whose IEEE bits are the int64 ``bits`` (a bitcast: no conversion)."""
    sig = types.float64(types.int64)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return sig, codegen


@nb.njit(cache=True, nogil=True, inline="always")
def exp1(x: float) -> float:
    """exp(x) of one float64 (see :func:`exp_into`), inlined into the compiled loop that
    calls it, which the compiler then vectorizes."""
    # clamped to where the result is 0 or inf already (NaN is put back at the end); k by the
    # shifter trick: the sum's low bits are round(x / ln2), with no float-to-integer conversion
    xc = x if x > -746.0 else -746.0
    xc = xc if xc < 710.0 else 710.0
    t = xc * _LOG2E + _SHIFTER
    k = t - _SHIFTER
    ki = _float_as_bits(t) - _SHIFTER_BITS
    r = (xc - k * _LN2_HI) - k * _LN2_LO
    # P(r) = sum_k r^(k-2) / k! (k = 2..13) by Estrin's scheme: a short dependency chain
    r2 = r * r
    r4 = r2 * r2
    b0 = (_C2 + _C3 * r) + (_C4 + _C5 * r) * r2
    b1 = (_C6 + _C7 * r) + (_C8 + _C9 * r) * r2
    b2 = (_C10 + _C11 * r) + (_C12 + _C13 * r) * r2
    p = (b0 + b1 * r4) + b2 * (r4 * r4)
    e = 1.0 + (r + r2 * p)
    # outside the normal exponents, 2^k in two factors: a subnormal result as
    # 2^(k + 54) 2^-54, so that the product rounds once, in the last multiplication (the first
    # is exact); k = 1024 (x just below log(DBL_MAX)) as 2^1023 2
    small = ki < -1022
    big = ki > 1023
    kk = ki + 54 if small else (ki - 1 if big else ki)
    post = _TWO_M54 if small else (2.0 if big else 1.0)
    y = (e * _bits_as_float((kk + 1023) << 52)) * post
    return x if x != x else y


@nb.njit(cache=True, nogil=True, inline="always")
def exp_into(x, out) -> None:
    """``out[i] = exp(x[i])`` for 1-d float64 arrays of the same length (``out`` may be
    ``x``), within one ulp of the correctly rounded value; 0 below about -745.13, inf above
    about 709.78, NaN for NaN.

    Examples
    --------
    >>> import numpy as np
    >>> from numba import njit
    >>> @njit
    ... def exp_array(x):
    ...     out = np.empty_like(x)
    ...     exp_into(x, out)
    ...     return out
    >>> x = np.linspace(-700.0, 700.0, 101)
    >>> bool(np.all(np.abs(exp_array(x) / np.exp(x) - 1.0) < 5e-16))
    True
    """
    for i in range(x.shape[0]):
        out[i] = exp1(x[i])
