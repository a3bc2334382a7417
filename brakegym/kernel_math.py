"""exp, log and fractional powers for the compiled kernel, in straight-line arithmetic.

Why not libm: inside compiled code ``x ** y`` is a call to the C library's scalar ``pow`` (about
25 ns here), and llvmlite is built without Intel's vector math library, so LLVM cannot vectorize a
loop that calls it. Eq. 4 needs three fractional powers per disc and RK4 stage, which alone would
cost more than the whole step budget of a batch of 256 trains. The functions below use only
arithmetic, comparisons, bit casts, explicit fused multiply-adds and lookups in small tables, so
LLVM vectorizes the kernel's loop over the discs of a train (four discs per instruction, the
lookups as gathers); exp, log and the powers are accurate to 1 ulp (``tests/test_kernel.py``).

They also make results independent of vectorization: a vector lane and the scalar remainder loop
do the same IEEE operations (fused multiply-adds only where written, never contracted by
``fastmath``), so a train's result does not depend on its place in the batch.

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


@intrinsic
def fused_multiply_add(typingctx, a, b, c):
    """a * b + c rounded once (IEEE fusedMultiplyAdd, LLVM's ``llvm.fma``): the same result on
    every machine and in every vector lane, so unlike fastmath's contraction it keeps results
    deterministic. One instruction where the CPU has FMA (this machine: AVX2 and AVX-512); a
    correctly rounded library call elsewhere."""
    if not all(isinstance(t, (types.Float, types.Integer)) for t in (a, b, c)):
        return None

    def codegen(context, builder, signature, args):
        double = ir.DoubleType()
        function = builder.module.declare_intrinsic("llvm.fma", [double], ir.FunctionType(double, [double] * 3))
        return builder.call(function, [context.cast(builder, v, t, types.float64) for v, t in zip(args, signature.args)])

    return types.float64(types.float64, types.float64, types.float64), codegen


# Both functions are table-driven (the approach of ARM's optimized-routines exp and log): a
# table of 128 entries turns each into a short polynomial without a division, and the table
# lookups vectorize as gathers. The tables are computed here, to 40 digits with the standard
# library's decimal arithmetic, then rounded once to float64.
TABLE_BITS = 7
TABLE_SIZE = 1 << TABLE_BITS


def _tables() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    from decimal import Decimal, localcontext

    def float_of_bits(bits: int) -> float:
        return float(np.int64(bits).view(np.float64))

    with localcontext() as context:
        context.prec = 40
        ln2 = Decimal(2).ln()
        # exp: 2^(i/128) rounded, and the relative error of that rounding (added to the
        # polynomial, so the table's rounding does not reach the result).
        exp_scale, exp_tail = np.empty(TABLE_SIZE), np.empty(TABLE_SIZE)
        for i in range(TABLE_SIZE):
            exact = (ln2 * i / TABLE_SIZE).exp()
            exp_scale[i] = float(exact)
            exp_tail[i] = float((exact - Decimal(exp_scale[i])) / Decimal(exp_scale[i]))
        # log: the mantissa range [LOG_OFFSET, 2 LOG_OFFSET) in 128 intervals by the top 7 bits of
        # the mantissa; per interval 1/c near its centre and -ln(1/c) in two parts. 1/c is 1
        # exactly on the interval holding 1, so that ln x near 1 is the polynomial alone.
        log_inverse, log_high, log_low = np.empty(TABLE_SIZE), np.empty(TABLE_SIZE), np.empty(TABLE_SIZE)
        for i in range(TABLE_SIZE):
            low = float_of_bits(LOG_OFFSET_BITS + (i << (52 - TABLE_BITS)))
            high = float_of_bits(LOG_OFFSET_BITS + ((i + 1) << (52 - TABLE_BITS)))
            inverse = 1.0 if low <= 1.0 < high else float(2 / (Decimal(low) + Decimal(high)))
            exact = -Decimal(inverse).ln()
            log_inverse[i] = inverse
            log_high[i] = float(exact)
            log_low[i] = float(exact - Decimal(log_high[i]))
    return exp_scale.view(np.int64).copy(), exp_tail, log_inverse, log_high, log_low


# ln 2 split so that n * LN2_HIGH is exact for |n| < 2^11 (fdlibm's constants).
LN2_HIGH = 6.93147180369123816490e-01
LN2_LOW = 1.90821492927058770002e-10
# exp(x) overflows above EXP_OVERFLOW. Below EXP_FLUSH (e^-708 = 3.3e-308, near the smallest
# normal number) it is returned as 0: computing the subnormal results would put subnormal numbers
# through the multiplications, which costs a microcode assist (about 100 cycles) per operation,
# and powers of 0 (released brakes, standing trains) go through exp(-inf) all the time.
EXP_OVERFLOW = 710.0
EXP_FLUSH = -708.0
TABLE_PER_LN2 = TABLE_SIZE / 0.6931471805599453
ROUNDING_SHIFT = 6755399441055744.0  # 1.5 * 2^52: adding it rounds to an integer in the low bits
ROUNDING_SHIFT_BITS = 0x4338000000000000
SMALLEST_NORMAL = 2.2250738585072014e-308
SUBNORMAL_SCALE = 18014398509481984.0  # 2^54
LOG_OFFSET_BITS = 0x3FE6900900000000  # about sqrt(2) / 2: mantissas are taken in [this, 2 this)
EXPONENT_FIELD = -(1 << 52)  # 0xFFF0000000000000 as int64: the sign and exponent bits
EXP_SCALE_BITS, EXP_SCALE_TAIL, LOG_INVERSE, LOG_HIGH, LOG_LOW = _tables()


@numba.njit(**JIT_OPTIONS)
def _power_of_two(n):
    """2^n for an integer n in [-1022, 1023]."""
    return _float_of((n + 1023) << 52)


@numba.njit(**JIT_OPTIONS)
def _exp_with_tail(x, tail):
    """e^(x + tail) for x not nan and |tail| below an ulp or so of x (see :func:`exp`)."""
    # Clamp first so that the integer conversion below never sees nan or a huge value.
    clamped = choose(x > EXP_FLUSH, x, EXP_FLUSH)
    clamped = choose(clamped < EXP_OVERFLOW, clamped, EXP_OVERFLOW)
    # x = (n / 128) ln2 + r with |r| <= ln2 / 256; e^x = 2^(n // 128) 2^((n % 128) / 128) e^r,
    # the middle factor from the table, e^r by its Taylor series to r^5 (the next term is below
    # 1e-18 of the result on that interval).
    shifted = fused_multiply_add(clamped, TABLE_PER_LN2, ROUNDING_SHIFT)
    n = _bits_of(shifted) - ROUNDING_SHIFT_BITS
    n_float = shifted - ROUNDING_SHIFT
    r = fused_multiply_add(n_float, -(LN2_LOW / TABLE_SIZE), fused_multiply_add(n_float, -(LN2_HIGH / TABLE_SIZE), clamped))
    r = r + tail
    index = n & (TABLE_SIZE - 1)
    scale = _float_of(EXP_SCALE_BITS[index])
    r2 = r * r
    polynomial = fused_multiply_add(
        r2,
        fused_multiply_add(r2, fused_multiply_add(r, 1.0 / 120.0, 1.0 / 24.0), fused_multiply_add(r, 1.0 / 6.0, 0.5)),
        r,
    )
    mantissa = fused_multiply_add(scale, EXP_SCALE_TAIL[index] + polynomial, scale)
    # 2^k in two factors, each a normal number, so that results near overflow are rounded
    # once, at the last multiplication.
    k = n >> TABLE_BITS
    half = k >> 1
    result = (mantissa * _power_of_two(half)) * _power_of_two(k - half)
    return choose(x > EXP_FLUSH, result, 0.0)


@numba.njit(**JIT_OPTIONS)
def _exp_of_number(x):
    """e^x for x not nan (see :func:`exp`)."""
    return _exp_with_tail(x, 0.0)


@numba.njit(**JIT_OPTIONS)
def exp(x):
    """e^x, within 1 ulp; above 709.78 inf, below -708 zero, nan stays nan."""
    return choose(x == x, _exp_of_number(x), x)


@numba.njit(**JIT_OPTIONS)
def _log_parts_of_positive(x):
    """ln x as an unevaluated sum (high, low), |low| below an ulp of high, for 0 < x < inf (see
    :func:`log`); any other x gives some finite numbers."""
    subnormal = x < SMALLEST_NORMAL
    bits = _bits_of(choose(subnormal, x * SUBNORMAL_SCALE, x))
    # x = 2^k z with z in [LOG_OFFSET, 2 LOG_OFFSET), without a branch: offsetting the bits moves
    # the exponent boundary there; the top mantissa bits of the offset bits pick the interval.
    shifted = bits - LOG_OFFSET_BITS
    index = (shifted >> (52 - TABLE_BITS)) & (TABLE_SIZE - 1)
    k = numba.float64((shifted >> 52) - _choose_integer(subnormal, 54, 0))
    z = _float_of(bits - (shifted & EXPONENT_FIELD))
    # ln z = ln(z / c) - ln(1 / c) with z / c = 1 + r, |r| < 1/128; the fused multiply-add makes
    # r exact but for one rounding far below the ulp of the result.
    r = fused_multiply_add(z, LOG_INVERSE[index], -1.0)
    k_ln2 = k * LN2_HIGH
    # k ln2 + ln c + r summed with the rounding errors kept (exact two-sums: |k ln2| >= 0.69
    # exceeds |ln c| <= 0.35 unless k = 0, where the first sum is exact anyway).
    first = k_ln2 + LOG_HIGH[index]
    first_error = (k_ln2 - first) + LOG_HIGH[index]
    second = first + r
    second_error = (first - second) + r
    # ln(1 + r) - r to r^7.
    polynomial = (r * r) * fused_multiply_add(
        r,
        fused_multiply_add(
            r,
            fused_multiply_add(r, fused_multiply_add(r, fused_multiply_add(r, 1.0 / 7.0, -1.0 / 6.0), 0.2), -0.25),
            1.0 / 3.0,
        ),
        -0.5,
    )
    low = ((first_error + second_error) + fused_multiply_add(k, LN2_LOW, LOG_LOW[index])) + polynomial
    high = second + low
    return high, (second - high) + low


@numba.njit(**JIT_OPTIONS)
def _log_of_positive(x):
    """ln x for 0 < x < inf (see :func:`log`); any other x gives some finite number."""
    return _log_parts_of_positive(x)[0]


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
        # e^(y ln x) with ln x in two parts and y ln x split exactly by a fused multiply-add, so
        # the error of the power stays within 1 ulp however large |y ln x| is. The cores skip the
        # special cases, handled once here: x = 0, inf, nan, negative.
        high, low = _log_parts_of_positive(base)
        product = exponent * high
        tail = fused_multiply_add(exponent, high, -product) + exponent * low
        # A product that overflowed leaves a nan tail; the clamp in the exponential handles inf.
        result = _exp_with_tail(product, choose(product - product == 0.0, tail, 0.0))
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
