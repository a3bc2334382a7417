"""exp, log and fractional powers for the compiled kernel, in straight-line arithmetic.

Why not libm: inside compiled code ``x ** y`` is a call to the C library's scalar ``pow`` (about
25 ns here), and llvmlite is built without Intel's vector math library, so LLVM cannot vectorize a
loop that calls it. Eq. 4 needs three fractional powers per disc and RK4 stage, which alone would
cost more than the whole step budget of a batch of 256 trains. The functions below use only
arithmetic, comparisons and bit casts, so LLVM vectorizes the kernel's loop over the discs of a
train (four or eight discs per instruction); they are accurate to 1 ulp (exp, log) and to a few
ulp for the powers of the model's range (``tests/test_kernel.py`` checks both).

They also make results independent of vectorization: a vector lane and the scalar remainder loop
do the same IEEE operations (no fused multiply-add without ``fastmath``), so a train's result does
not depend on its place in the batch.

:func:`brakegym.physics.elementary.fractional_power` and :func:`~brakegym.physics.elementary.select`
get their compiled implementations here (numba ``overload``); numpy code keeps numpy's.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic, overload

from .physics.elementary import fractional_power, select

# Every compiled function of brakegym uses numpy's error model: a division by zero gives inf or
# nan instead of raising, which removes the checks (and branches) that stop vectorization.
JIT_OPTIONS = {"error_model": "numpy", "nogil": True}


@intrinsic
def choose(typingctx, condition, value, otherwise):
    """``value if condition else otherwise`` for float64 as one LLVM ``select``: no branch, so
    loops stay vectorizable and numba's inliner has no control flow to rebuild."""
    if not isinstance(condition, types.Boolean):
        return None

    def codegen(context, builder, signature, args):
        condition_value, value_value, otherwise_value = args
        return builder.select(condition_value, value_value, otherwise_value)

    return types.float64(types.boolean, types.float64, types.float64), codegen


@intrinsic
def _choose_integer(typingctx, condition, value, otherwise):
    """:func:`choose` for int64."""

    def codegen(context, builder, signature, args):
        return builder.select(*args)

    return types.int64(types.boolean, types.int64, types.int64), codegen


@intrinsic
def _bits_of(typingctx, x):
    """The IEEE bits of a float64 as an int64 (a bit cast, free in machine code)."""

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return types.int64(types.float64), codegen


@intrinsic
def _float_of(typingctx, bits):
    """The float64 whose IEEE bits are ``bits``."""

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return types.float64(types.int64), codegen


# ln 2 split so that n * LN2_HIGH is exact for |n| < 2^11 (fdlibm's constants).
LN2_HIGH = 6.93147180369123816490e-01
LN2_LOW = 1.90821492927058770002e-10
INVERSE_LN2 = 1.44269504088896338700e00
# exp(x) overflows above EXP_OVERFLOW. Below EXP_FLUSH (e^-708 = 3.3e-308, near the smallest
# normal number) it is returned as 0: computing the subnormal results would put subnormal numbers
# through the multiplications, which costs a microcode assist (about 100 cycles) per operation,
# and powers of 0 (released brakes, standing trains) go through exp(-inf) all the time.
EXP_OVERFLOW = 710.0
EXP_FLUSH = -708.0
SMALLEST_NORMAL = 2.2250738585072014e-308
SUBNORMAL_SCALE = 18014398509481984.0  # 2^54
SQRT_HALF_BITS = 0x3FE6A09E667F3BCD  # the bits of sqrt(2) / 2
EXPONENT_FIELD = -(1 << 52)  # 0xFFF0000000000000 as int64: the sign and exponent bits
# log(1 + f) = f - f^2/2 + s (f^2/2 + R(s^2)), s = f / (2 + f): fdlibm's minimax coefficients.
LG1 = 6.666666666666735130e-01
LG2 = 3.999999999940941908e-01
LG3 = 2.857142874366239149e-01
LG4 = 2.222219843214978396e-01
LG5 = 1.818357216161805012e-01
LG6 = 1.531383769920937332e-01
LG7 = 1.479819860511658591e-01


@numba.njit(**JIT_OPTIONS)
def _power_of_two(n):
    """2^n for an integer n in [-1022, 1023]."""
    return _float_of((n + 1023) << 52)


@numba.njit(**JIT_OPTIONS)
def _exp_of_number(x):
    """e^x for x not nan (see :func:`exp`)."""
    # Clamp first so that the integer conversion below never sees nan or a huge value.
    clamped = choose(x > EXP_FLUSH, x, EXP_FLUSH)
    clamped = choose(clamped < EXP_OVERFLOW, clamped, EXP_OVERFLOW)
    # x = n ln2 + r with |r| <= ln2 / 2, then e^r by its Taylor series to r^13 (the next term is
    # below 1e-18 on that interval) and e^x = e^r 2^n. The series is summed in Estrin's scheme:
    # four dependent multiply-adds instead of thirteen (Horner), which keeps the vector units busy.
    n_float = np.floor(clamped * INVERSE_LN2 + 0.5)
    r = (clamped - n_float * LN2_HIGH) - n_float * LN2_LOW
    r2 = r * r
    r4 = r2 * r2
    r8 = r4 * r4
    high = ((1.0 / 40320.0) + r * (1.0 / 362880.0)) + r2 * ((1.0 / 3628800.0) + r * (1.0 / 39916800.0))
    high = high + r4 * ((1.0 / 479001600.0) + r * (1.0 / 6227020800.0))
    middle = r4 * (((1.0 / 24.0) + r * (1.0 / 120.0)) + r2 * ((1.0 / 720.0) + r * (1.0 / 5040.0))) + r8 * high
    # Smallest terms first, 1 last: the sum keeps the low bits of r.
    p = 1.0 + (r + (r2 * ((1.0 / 2.0) + r * (1.0 / 6.0)) + middle))
    # 2^n in two factors, each a normal number, so that results near overflow are rounded
    # once, at the last multiplication.
    n = numba.int64(n_float)
    half = n >> 1
    result = (p * _power_of_two(half)) * _power_of_two(n - half)
    return choose(x > EXP_FLUSH, result, 0.0)


@numba.njit(**JIT_OPTIONS)
def exp(x):
    """e^x, within 1 ulp; above 709.78 inf, below -708 zero, nan stays nan."""
    return choose(x == x, _exp_of_number(x), x)


@numba.njit(**JIT_OPTIONS)
def _log_of_positive(x):
    """ln x for 0 < x < inf (see :func:`log`); any other x gives some finite number."""
    subnormal = x < SMALLEST_NORMAL
    bits = _bits_of(choose(subnormal, x * SUBNORMAL_SCALE, x))
    # x = 2^k m with m in [sqrt(2)/2, sqrt(2)), so that f = m - 1 is small, without a branch:
    # offsetting the bits by those of sqrt(2)/2 moves the exponent boundary there (musl's log).
    shifted = bits - SQRT_HALF_BITS
    k = numba.float64((shifted >> 52) - _choose_integer(subnormal, 54, 0))
    f = _float_of(bits - (shifted & EXPONENT_FIELD)) - 1.0
    s = f / (2.0 + f)
    z = s * s
    w = z * z
    odd = w * (LG2 + w * (LG4 + w * LG6))
    even = z * (LG1 + w * (LG3 + w * (LG5 + w * LG7)))
    r = even + odd
    half_f_squared = 0.5 * f * f
    return k * LN2_HIGH - ((half_f_squared - (s * (half_f_squared + r) + k * LN2_LOW)) - f)


@numba.njit(**JIT_OPTIONS)
def log(x):
    """Natural logarithm, within 1 ulp; log(0) = -inf, log(inf) = inf, negative or nan -> nan."""
    result = choose(x > 0.0, _log_of_positive(x), choose(x == 0.0, -math.inf, math.nan))
    return choose(x < math.inf, result, x)  # inf stays inf, nan stays nan


@overload(fractional_power, jit_options=JIT_OPTIONS, inline="always")
def _compiled_fractional_power(base, exponent):
    if not (isinstance(base, types.Float) and isinstance(exponent, (types.Float, types.Integer))):
        return None

    def power(base, exponent):
        # e^(y ln x): the error of ln x is scaled by |y ln x| (below 10 in this model, so a few
        # ulp). The cores skip the special cases, handled once here: x = 0, inf, nan, negative.
        result = _exp_of_number(exponent * _log_of_positive(base))
        at_zero = choose(exponent > 0.0, 0.0, choose(exponent < 0.0, math.inf, 1.0))
        at_infinity = choose(exponent > 0.0, math.inf, choose(exponent < 0.0, 0.0, 1.0))
        result = choose(base > 0.0, result, choose(base == 0.0, at_zero, math.nan))
        result = choose(base < math.inf, result, choose(base == math.inf, at_infinity, math.nan))
        result = choose(exponent != 0.0, result, 1.0)
        return choose(exponent == exponent, result, math.nan)

    return power


@overload(select, jit_options=JIT_OPTIONS)
def _compiled_select(condition, value, otherwise):
    if not isinstance(condition, types.Boolean):
        return None

    def choose_value(condition, value, otherwise):
        return choose(condition, value, otherwise)

    return choose_value
