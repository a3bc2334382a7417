"""exp, log and fractional powers for the compiled kernel, in straight-line arithmetic.

Why not libm: inside compiled code ``x ** y`` is a call to the C library's scalar ``pow`` (about
25 ns here), and llvmlite is built without Intel's vector math library, so LLVM cannot vectorize a
loop that calls it. Eq. 4 needs three fractional powers per disc and RK4 stage, which alone would
cost more than the whole step budget of a batch of 256 trains. The functions below use only
arithmetic, comparisons, bit casts, explicit fused multiply-adds and a division, no lookup table
(a table lookup in a vector loop is a gather, which LLVM does not emit on CPUs where gathers are
slow, AMD Zen among them), so LLVM vectorizes the kernel's loop over the discs of a train on any
AVX2 machine; exp, log and the powers are accurate to 1 ulp (``tests/test_kernel.py``).

They also make results independent of vectorization: a vector lane and the scalar remainder loop
do the same IEEE operations (fused multiply-adds only where written, never contracted by
``fastmath``), so a train's result does not depend on its place in the batch.

:func:`brakegym.physics.elementary.fractional_power` and :func:`~brakegym.physics.elementary.select`
get their compiled implementations here (numba ``overload``); numpy code keeps numpy's.
"""

from __future__ import annotations

import math

import numba
from llvmlite import ir
from numba import types
from numba.extending import intrinsic, overload

from ..physics.elementary import fractional_power, select

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
def choose_integer(typingctx, condition, value, otherwise):
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
def _shift_right_logical(typingctx, bits, amount):
    """``bits >> amount`` filling with zeros, for int64: AVX2 has this shift for vectors, not the
    arithmetic one (numba's ``>>`` on int64), so a loop that needs it still vectorizes."""
    if not (isinstance(bits, types.Integer) and isinstance(amount, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        value = context.cast(builder, args[0], signature.args[0], types.int64)
        return builder.lshr(value, context.cast(builder, args[1], signature.args[1], types.int64))

    return types.int64(types.int64, types.int64), codegen


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
        return builder.call(
            function, [context.cast(builder, v, t, types.float64) for v, t in zip(args, signature.args)]
        )

    return types.float64(types.float64, types.float64, types.float64), codegen


# Each function is inlined by numba itself (``inline="always"``), not left to LLVM's inliner,
# which keeps the call when a callee is this large: a call in a loop stops its vectorization.
#
# Both functions use no lookup table: a table lookup in a vectorized loop is a gather, and LLVM's
# cost model takes gathers as slow on CPUs such as AMD Zen (where they are), so a loop with a
# table-driven exp or log stays scalar there. Polynomials, a division and bit casts vectorize on
# every AVX2 machine.

# ln 2 split so that n * LN2_HIGH is exact for |n| < 2^11 (fdlibm's constants).
LN2_HIGH = 6.93147180369123816490e-01
LN2_LOW = 1.90821492927058770002e-10
INVERSE_LN2 = 1.4426950408889634
# exp(x) overflows above EXP_OVERFLOW. Below EXP_FLUSH (e^-708 = 3.3e-308, near the smallest
# normal number) it is returned as 0: computing the subnormal results would put subnormal numbers
# through the multiplications, which costs a microcode assist (about 100 cycles) per operation,
# and powers of 0 (released brakes, standing trains) go through exp(-inf) all the time.
EXP_OVERFLOW = 710.0
EXP_FLUSH = -708.0
ROUNDING_SHIFT = 6755399441055744.0  # 1.5 * 2^52: adding it rounds to an integer in the low bits
ROUNDING_SHIFT_BITS = 0x4338000000000000
# An integer m in [0, 2^52) in the low bits of 2^52 is the float 2^52 + m: int64 to float64 with
# an integer add and a subtraction (AVX2 has no int64 conversion for vectors).
TWO_TO_52_BITS = 0x4330000000000000
TWO_TO_52 = 4503599627370496.0
EXPONENT_BIAS = 1023
SMALLEST_NORMAL = 2.2250738585072014e-308
SUBNORMAL_SCALE = 18014398509481984.0  # 2^54
LOG_OFFSET_BITS = 0x3FE6A09E667F3BCD  # sqrt(2) / 2: mantissas are taken in [this, 2 this)
EXPONENT_FIELD = -(1 << 52)  # 0xFFF0000000000000 as int64: the sign and exponent bits
# 1/k! for e^r - 1 - r - r^2/2 = r^3 (1/3! + r (1/4! + ...)), to r^13: on |r| <= ln2 / 2 the first
# term left out, r^14 / 14!, is below 5e-18 (0.05 ulp of the result).
EXP_TAYLOR = tuple(1.0 / math.factorial(k) for k in range(3, 14))
# 2 / (2 j + 1) for ln z = 2 s + s^3 (2/3 + s^2 (2/5 + ...)), s = (z - 1) / (z + 1), to s^21: for
# z in [sqrt(2)/2, sqrt(2)), |s| <= 0.172 and the first term left out is below 2^-62 of the result.
LOG_ATANH = tuple(2.0 / (2 * j + 1) for j in range(1, 11))


@numba.njit(inline="always", **JIT_OPTIONS)
def _power_of_two(n):
    """2^n for an integer n in [-1022, 1023]."""
    return _float_of((n + 1023) << 52)


@numba.njit(inline="always", **JIT_OPTIONS)
def _exp_with_tail(x, tail):
    """e^(x + tail) for x not nan and |tail| below an ulp or so of x (see :func:`exp`)."""
    # Clamp first so that the integer conversion below never sees nan or a huge value.
    clamped = choose(x > EXP_FLUSH, x, EXP_FLUSH)
    clamped = choose(clamped < EXP_OVERFLOW, clamped, EXP_OVERFLOW)
    # x = n ln2 + r with |r| <= ln2 / 2; e^x = 2^n e^r. n LN2_HIGH is exact and so is the first
    # difference (the two are close); the low part of ln2 and the tail go into r_low, and the
    # rounding of r = r_high + r_low is kept in r_error.
    shifted = fused_multiply_add(clamped, INVERSE_LN2, ROUNDING_SHIFT)
    n = _bits_of(shifted) - ROUNDING_SHIFT_BITS
    n_float = shifted - ROUNDING_SHIFT
    r_high = fused_multiply_add(n_float, -LN2_HIGH, clamped)
    r_low = fused_multiply_add(n_float, -LN2_LOW, tail)
    r = r_high + r_low
    r_error = (r_high - r) + r_low
    c = EXP_TAYLOR
    r2 = r * r
    # Estrin's scheme: independent halves, a shorter dependency chain than Horner's.
    high = fused_multiply_add(r, c[9] + r * c[10], c[8])
    high = fused_multiply_add(r2, high, fused_multiply_add(r, c[7], c[6]))
    low = fused_multiply_add(r2, fused_multiply_add(r, c[5], c[4]), fused_multiply_add(r, c[3], c[2]))
    cubic = fused_multiply_add(r2 * r2, high, low)
    cubic = fused_multiply_add(r2, cubic, fused_multiply_add(r, c[1], c[0]))
    # e^r - 1 = r + r^2/2 + r^3 (...), plus the error of r times e^r (close enough to 1 there).
    expm1 = fused_multiply_add(r2, fused_multiply_add(r, cubic, 0.5), r) + r_error
    mantissa = 1.0 + expm1
    # 2^n in two factors, each a normal number, so that results near overflow are rounded once,
    # at the last multiplication; the first is n / 2 rounded by the same shift as n.
    half = _bits_of(fused_multiply_add(n_float, 0.5, ROUNDING_SHIFT)) - ROUNDING_SHIFT_BITS
    result = (mantissa * _power_of_two(half)) * _power_of_two(n - half)
    return choose(x > EXP_FLUSH, result, 0.0)


@numba.njit(inline="always", **JIT_OPTIONS)
def _exp_of_number(x):
    """e^x for x not nan (see :func:`exp`)."""
    return _exp_with_tail(x, 0.0)


@numba.njit(inline="always", **JIT_OPTIONS)
def exp(x):
    """e^x, within 1 ulp; above 709.78 inf, below -708 zero, nan stays nan."""
    return choose(x == x, _exp_of_number(x), x)


@numba.njit(inline="always", **JIT_OPTIONS)
def _log_parts_of_positive(x):
    """ln x as an unevaluated sum (high, low), |low| below an ulp of high, for 0 < x < inf (see
    :func:`log`); any other x gives some finite numbers."""
    subnormal = x < SMALLEST_NORMAL
    bits = _bits_of(choose(subnormal, x * SUBNORMAL_SCALE, x))
    # x = 2^k z with z in [sqrt(2)/2, sqrt(2)), without a branch: offsetting the bits moves the
    # exponent boundary there.
    shifted = bits - LOG_OFFSET_BITS
    # k + 1023 is the exponent field of shifted + 1023 * 2^52, which is positive for every
    # positive x: a logical shift takes it out.
    biased_k = _shift_right_logical(shifted + (EXPONENT_BIAS << 52), 52)
    k = (_float_of(TWO_TO_52_BITS + biased_k) - (TWO_TO_52 + EXPONENT_BIAS)) - choose(subnormal, 54.0, 0.0)
    z = _float_of(bits - (shifted & EXPONENT_FIELD))
    # ln z = 2 atanh(s), s = f / (2 + f), f = z - 1 (exact). s in two parts: the denominator's
    # rounding and the quotient's remainder (exact by a fused multiply-add) give s_low.
    f = z - 1.0
    denominator = 2.0 + f
    denominator_error = (2.0 - denominator) + f
    s = f / denominator
    remainder = fused_multiply_add(-s, denominator, f) - s * denominator_error
    s_low = remainder / denominator
    t = s * s
    c = LOG_ATANH
    t2 = t * t
    series = fused_multiply_add(t, c[9], c[8])
    series = fused_multiply_add(t2, series, fused_multiply_add(t, c[7], c[6]))
    series = fused_multiply_add(t2, series, fused_multiply_add(t, c[5], c[4]))
    series = fused_multiply_add(t2, series, fused_multiply_add(t, c[3], c[2]))
    series = fused_multiply_add(t2, series, fused_multiply_add(t, c[1], c[0]))
    # k ln2 + 2 s summed with the rounding error kept (an exact two-sum: |k ln2| >= 0.69 exceeds
    # |2 s| <= 0.35 unless k = 0, where the sum is exact anyway); the small terms go to low.
    k_ln2 = k * LN2_HIGH
    two_s = 2.0 * s
    first = k_ln2 + two_s
    first_error = (k_ln2 - first) + two_s
    low = first_error + fused_multiply_add(k, LN2_LOW, fused_multiply_add(s * t, series, 2.0 * s_low))
    high = first + low
    return high, (first - high) + low


@numba.njit(inline="always", **JIT_OPTIONS)
def _log_of_positive(x):
    """ln x for 0 < x < inf (see :func:`log`); any other x gives some finite number."""
    return _log_parts_of_positive(x)[0]


@numba.njit(inline="always", **JIT_OPTIONS)
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
