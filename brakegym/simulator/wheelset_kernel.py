"""Compiled step of the simulator with wheel-rail adhesion (numba; docs/adhesion.md).

The scheme of :class:`~.wheelsets.AdhesionSimulator`, written once more per train in compiled
loops: the disc states by RK4 over the step, each axle's discs sliding at their own wheel's speed;
the wheelsets and the train speed in linearly implicit Euler substeps (the arrow Jacobian solved by
its Schur complement). :class:`~.wheelsets_reference.NumpyAdhesionSimulator` is the same scheme in
numpy, the reference these kernels are tested against (``tests/test_adhesion.py``): the same
operations in the same order, so the two agree to round-off (the compiled fractional powers, exp
and arctan differ from numpy's by an ulp or so).

The physics is not written here: creep, Polach's law and the disc equations are the module-level
functions of :mod:`brakegym.physics`, registered for numba as :mod:`.kernel` does. A train's
arithmetic does not depend on the other trains, so the results are the same bit for bit on any
number of threads. The disk cache is stamped with every source the kernels reach, this file
included (:func:`.kernel.stamped_compiler`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numba
import numpy as np
from numba.extending import register_jitable

from ..physics.adhesion import (
    adhesion_coefficient,
    creep,
    creep_slope_at_fixed_friction,
    friction_coefficient,
    polach_shape,
    polach_shape_slope,
    stress_gradient,
)
from ..physics.elementary import select
from ..physics.friction import bounded_mu, clamp_force_term_per_s, friction_evolves, friction_rate_per_s
from ..physics.mechanics import effective_mu, running_resistance_N
from ..physics.pneumatics import clamp_force_from_pressure_N
from ..physics.thermal import (
    contact_conductance_W_per_K,
    film_conductance_W_per_K,
    heat_flows_W,
    temperature_rates_K_per_s,
)
from . import kernel
from .kernel import (
    AMBIENT_K,
    CALIPER_GAIN_N_PER_BAR,
    CALIPER_THRESHOLD_BAR,
    CLAMP_FORCE_COEFFICIENT_PER_S,
    CLAMP_FORCE_EXPONENT,
    CONDUCTANCE_MIN_W_PER_K,
    CONDUCTANCE_REFERENCE_TEMPERATURE_K,
    CONDUCTANCE_SLOPE_W_PER_K2,
    CONDUCTANCE_W_PER_K,
    DECAY_COEFFICIENT_PER_S,
    DECAY_EXPONENT,
    DISC_BODY_HEAT_CAPACITY_J_PER_K,
    DISCS_PER_AXLE,
    FRICTION_LAYER_HEAT_CAPACITY_J_PER_K,
    HEAT_FRACTION_INTO_DISC,
    MIN_SLIDING_SPEED_MPS,
    MU_MAX,
    MU_MIN,
    NOMINAL_RESISTANCE_A_N,
    NOMINAL_RESISTANCE_B_N_PER_MPS,
    NOMINAL_RESISTANCE_C_N_PER_MPS2,
    POWER_EXPONENT,
    RADIUS_RATIO,
    REFERENCE_CLAMP_FORCE_N,
    REFERENCE_POWER_W,
    REFERENCE_SLIDING_SPEED_MPS,
    REFERENCE_TEMPERATURE_K,
    RESISTANCE_A_N,
    RESISTANCE_B_N_PER_MPS,
    RESISTANCE_C_N_PER_MPS2,
    SURFACE_AREA_M2,
    SURFACE_EXPONENT,
    SURFACE_H0_W_PER_M2K,
    SURFACE_H_REF_W_PER_M2K,
    TEMPERATURE_COEFFICIENT_PER_S,
    TEMPERATURE_EXPONENT,
    VENTILATION_AREA_M2,
    VENTILATION_EXPONENT,
    VENTILATION_H0_W_PER_M2K,
    VENTILATION_H_REF_W_PER_M2K,
)
from .kernel_math import JIT_OPTIONS
from .state import (
    ANGULAR_SPEED,
    BRAKE_WORK,
    COOLING_HEAT,
    FRICTION_HEAT,
    MU,
    MU_DISTANCE,
    MU_EFF_DISTANCE,
    N_DISC_STATES,
    POSITION,
    RESISTANCE_WORK,
    SLIP_WORK,
    SPEED,
    T_DISC,
    T_FRIC,
)

# The adhesion equations, compiled where the kernels call them (the disc equations are registered
# by :mod:`.kernel`).
for _equation in (
    creep,
    friction_coefficient,
    stress_gradient,
    polach_shape,
    polach_shape_slope,
    adhesion_coefficient,
    creep_slope_at_fixed_friction,
):
    register_jitable(inline="always", **JIT_OPTIONS)(_equation)

_compiled = kernel.stamped_compiler(
    kernel.cache_sources_digest((*kernel.KERNEL_CACHE_SOURCES, Path(__file__).resolve()))
)


def _compiled_threaded(function):
    return _compiled(function, parallel=True)


#: The fewest trains per thread for which a batch is shared out over threads (a train's step
#: costs some 10 us, a thread's start some more).
TRAINS_PER_THREAD = 8

# Columns of the section table (S, N_LAW_PARAMETERS + A): Polach's parameters of each section's law,
# then from AXLE_CONDITIONING each axle's factor on the section's mu_0 (the rail's conditioning by
# the axles ahead, brakegym.physics.RailConditioning; exactly 1 without, so the same bits).
(
    STATIC_FRICTION,
    FRICTION_RATIO_AT_INFINITY,
    FRICTION_DECAY_S_PER_M,
    ADHESION_REDUCTION,
    SLIP_REDUCTION,
) = range(5)
N_LAW_PARAMETERS = 5
AXLE_CONDITIONING = N_LAW_PARAMETERS

# Rows of the per-train constants of the adhesion option (N_WHEELSET_CONSTANTS, B).
# STATIC_FRICTION_FACTOR scales every section's mu_0 for that train (its rail's scatter; 1: the rail's own).
MASS_KG, BODY_MASS_KG, WHEEL_LOAD_N, CREEP_STIFFNESS_N, STATIC_FRICTION_FACTOR = range(5)
N_WHEELSET_CONSTANTS = 5
# With load transfer (scheme[LOAD_TRANSFER] = 1) A more rows follow from AXLE_LOAD_GAIN: how much
# each axle's wheel load rises per m/s^2 of the train's deceleration (N s^2/m), then A rows from
# AXLE_LOAD_GAIN + A: each axle's wheel load at the end of the last step (N), written by the kernel.
AXLE_LOAD_GAIN = N_WHEELSET_CONSTANTS

# Entries of the scheme's parameter vector.
(
    STEP_S,
    N_SUBSTEPS,
    REGULARISATION_SPEED_MPS,
    WHEELSET_MASS_KG,
    WHEEL_RADIUS_M,
    LOAD_TRANSFER,
) = range(6)
N_SCHEME_PARAMETERS = 6


# ------------------------------------------------------------------------------------------------
# Wheel and rail


@numba.njit(**JIT_OPTIONS)
def _section_of(position_m, section_starts_m):
    """The section under ``position_m``: the last whose start is not beyond it (the first before
    the line's start), as ``RailSections.law_at`` finds it."""
    section = 0
    for index in range(1, section_starts_m.shape[0]):
        if section_starts_m[index] <= position_m:
            section = index
    return section


@numba.njit(**JIT_OPTIONS)
def _axle_laws(position_m, section_starts_m, axle_offsets_m, sections):
    """The section index under each axle (A,), the train at ``position_m``."""
    for axle in range(sections.shape[0]):
        sections[axle] = _section_of(position_m - axle_offsets_m[axle], section_starts_m)


@numba.njit(**JIT_OPTIONS)
def _creep_forces(
    speed_mps, wheel_speed_mps, wheel_load_N, stiffness_N, friction_factor, scheme, laws, sections, force_N, slope_N
):
    """Each axle's force on the rail, both wheels (N, retarding for creep > 0), and its slope
    dF/ds at fixed friction (N per unit creep), into ``force_N`` and ``slope_N`` (A,); every
    section's mu_0 times the train's ``friction_factor`` and the axle's conditioning factor."""
    regularisation = scheme[REGULARISATION_SPEED_MPS]
    for axle in range(force_N.shape[0]):
        law = laws[sections[axle]]
        u = wheel_speed_mps[axle]
        slip = speed_mps - u
        s = creep(speed_mps, u, regularisation)
        mu0 = law[STATIC_FRICTION] * friction_factor * law[AXLE_CONDITIONING + axle]
        ratio, decay = law[FRICTION_RATIO_AT_INFINITY], law[FRICTION_DECAY_S_PER_M]
        reduction_a, reduction_s = law[ADHESION_REDUCTION], law[SLIP_REDUCTION]
        coefficient = adhesion_coefficient(
            s, slip, wheel_load_N, stiffness_N, mu0, ratio, decay, reduction_a, reduction_s
        )
        force_N[axle] = 2.0 * (wheel_load_N * coefficient)
        slope_N[axle] = (2.0 * wheel_load_N) * creep_slope_at_fixed_friction(
            s, slip, wheel_load_N, stiffness_N, mu0, ratio, decay, reduction_a, reduction_s
        )


@numba.njit(**JIT_OPTIONS)
def _transferred_loads(speed_mps, force_N, loads, constants, wheel_load_N, stiffness_N):
    """Each axle's wheel load and creep stiffness (A,) at the train's deceleration
    (sum of F + F_R(v)) / M with the creep forces ``force_N`` (A,): the static load plus each
    axle's gain times the deceleration, the stiffness scaled as the Hertz semi-axes, with the cube
    root of the load (G pi a b c_11 / 4 goes as the load to the 2/3). Stored as the train's current
    loads."""
    n_axles = force_N.shape[0]
    force_sum = 0.0
    for axle in range(n_axles):
        force_sum += force_N[axle]
    resistance = running_resistance_N(
        speed_mps, constants[RESISTANCE_A_N], constants[RESISTANCE_B_N_PER_MPS], constants[RESISTANCE_C_N_PER_MPS2]
    )
    # A train at standstill does not decelerate (the resistance's A would read as a deceleration).
    deceleration = (force_sum + resistance) / loads[BODY_MASS_KG] if speed_mps > 0.0 else 0.0
    static_load, static_stiffness = loads[WHEEL_LOAD_N], loads[CREEP_STIFFNESS_N]
    for axle in range(n_axles):
        load = static_load + loads[AXLE_LOAD_GAIN + axle] * deceleration
        wheel_load_N[axle] = load
        stiffness_N[axle] = static_stiffness * (load / static_load) ** (2.0 / 3.0)
        loads[AXLE_LOAD_GAIN + n_axles + axle] = load


@numba.njit(**JIT_OPTIONS)
def _creep_forces_per_axle(
    speed_mps,
    wheel_speed_mps,
    axle_wheel_load_N,
    axle_stiffness_N,
    friction_factor,
    scheme,
    laws,
    sections,
    force_N,
    slope_N,
):
    """:func:`_creep_forces` with each axle at its own wheel load and creep stiffness (A,) (load
    transfer; the static loads keep :func:`_creep_forces`, whose loop this is)."""
    regularisation = scheme[REGULARISATION_SPEED_MPS]
    for axle in range(force_N.shape[0]):
        wheel_load_N, stiffness_N = axle_wheel_load_N[axle], axle_stiffness_N[axle]
        law = laws[sections[axle]]
        u = wheel_speed_mps[axle]
        slip = speed_mps - u
        s = creep(speed_mps, u, regularisation)
        mu0 = law[STATIC_FRICTION] * friction_factor * law[AXLE_CONDITIONING + axle]
        ratio, decay = law[FRICTION_RATIO_AT_INFINITY], law[FRICTION_DECAY_S_PER_M]
        reduction_a, reduction_s = law[ADHESION_REDUCTION], law[SLIP_REDUCTION]
        coefficient = adhesion_coefficient(
            s, slip, wheel_load_N, stiffness_N, mu0, ratio, decay, reduction_a, reduction_s
        )
        force_N[axle] = 2.0 * (wheel_load_N * coefficient)
        slope_N[axle] = (2.0 * wheel_load_N) * creep_slope_at_fixed_friction(
            s, slip, wheel_load_N, stiffness_N, mu0, ratio, decay, reduction_a, reduction_s
        )


@numba.njit(**JIT_OPTIONS)
def _transferred_creep_forces(
    speed_mps, wheel_speed_mps, friction_factor, scheme, laws, sections, loads, constants, work, force_N, slope_N
):
    """The creep forces and slopes (A,) with load transfer: at the wheel loads in hand
    (``work[WHEEL_LOAD]``, ``work[CREEP_STIFFNESS]``), then, with the loads taken to the
    deceleration these forces give (:func:`_transferred_loads`, explicit), again at the new loads."""
    wheel_load_N, stiffness_N = work[WHEEL_LOAD], work[CREEP_STIFFNESS]
    _creep_forces_per_axle(
        speed_mps, wheel_speed_mps, wheel_load_N, stiffness_N, friction_factor, scheme, laws, sections, force_N, slope_N
    )
    _transferred_loads(speed_mps, force_N, loads, constants, wheel_load_N, stiffness_N)
    _creep_forces_per_axle(
        speed_mps, wheel_speed_mps, wheel_load_N, stiffness_N, friction_factor, scheme, laws, sections, force_N, slope_N
    )


@numba.njit(**JIT_OPTIONS)
def _implicit_slope_N(slope_N, force_N, brake_N, speed_mps, wheel_speed_mps, scaled_speed_mps, mass_kg, delta_s):
    """The creep slope an axle's implicit substep takes: dF/ds at fixed friction, raised to the
    secant F / s where the wheel, moving towards the train's speed, would cross it within the
    substep (the train's speed held). Far out on the creep curve the tangent is next to flat and
    cannot see F change sign at s = 0: the substep then carries the wheel across the train's speed
    and the next one back, and near standstill the wheels chatter about the train instead of
    stopping it. With the secant the linearised force is zero no later than at s = 0."""
    slip = speed_mps - wheel_speed_mps
    s = slip / scaled_speed_mps
    rate = (force_N - brake_N) / mass_kg
    if s != 0.0 and rate * s > 0.0:
        change = delta_s * rate / (1.0 + delta_s * slope_N / (scaled_speed_mps * mass_kg))
        if (slip - change) * slip < 0.0:
            secant = force_N / s
            if secant > slope_N:
                return secant
    return slope_N


@numba.njit(**JIT_OPTIONS)
def _implicit_update(speed_mps, wheel_speed_mps, brake_N, force_N, slope_N, delta_s, scheme, loads, constants, out):
    """One linearly implicit Euler substep of one train: (I - delta J) dy = delta f(y) with the
    arrow Jacobian of the creep forces' slope (:func:`_implicit_slope_N`), solved by its Schur
    complement.
    New wheel speeds into ``out`` (A,), a wheel that would turn backwards held at 0 (locked by its
    brake); returns the new train speed. Between its two passes over the axles ``out`` holds each
    axle's slope, so that the substep neither allocates nor computes a slope twice."""
    regularisation, wheelset_mass = scheme[REGULARISATION_SPEED_MPS], scheme[WHEELSET_MASS_KG]
    body_mass = loads[BODY_MASS_KG]
    scaled = max(speed_mps, regularisation)
    resistance = running_resistance_N(
        speed_mps, constants[RESISTANCE_A_N], constants[RESISTANCE_B_N_PER_MPS], constants[RESISTANCE_C_N_PER_MPS2]
    )
    resistance_slope = constants[RESISTANCE_B_N_PER_MPS] + 2.0 * constants[RESISTANCE_C_N_PER_MPS2] * speed_mps
    force_sum, slope_sum, schur_sum, rate_sum = 0.0, 0.0, 0.0, 0.0
    for axle in range(out.shape[0]):
        slope = _implicit_slope_N(
            slope_N[axle],
            force_N[axle],
            brake_N[axle],
            speed_mps,
            wheel_speed_mps[axle],
            scaled,
            wheelset_mass,
            delta_s,
        )
        # ds/dv: 1 / v_reg below the regularisation speed, u / v^2 above it.
        per_speed = wheel_speed_mps[axle] / (scaled * scaled) if speed_mps > regularisation else 1.0 / scaled
        wheel_rate = (force_N[axle] - brake_N[axle]) / wheelset_mass
        wheel_by_train = slope * per_speed / wheelset_mass
        train_by_wheel = slope / (scaled * body_mass)
        pivot = 1.0 - delta_s * (-slope / (scaled * wheelset_mass))
        out[axle] = slope  # kept for the second pass, which overwrites it with the wheel speed
        force_sum += force_N[axle]
        slope_sum += slope * per_speed
        schur_sum += train_by_wheel * wheel_by_train / pivot
        rate_sum += train_by_wheel * wheel_rate / pivot
    train_rate = -(force_sum + resistance) / body_mass
    train_by_train = -(slope_sum + resistance_slope) / body_mass
    schur = 1.0 - delta_s * train_by_train - (delta_s * delta_s) * schur_sum
    train_change = (delta_s * train_rate + (delta_s * delta_s) * rate_sum) / schur
    for axle in range(out.shape[0]):
        slope = out[axle]
        per_speed = wheel_speed_mps[axle] / (scaled * scaled) if speed_mps > regularisation else 1.0 / scaled
        wheel_rate = (force_N[axle] - brake_N[axle]) / wheelset_mass
        wheel_by_train = slope * per_speed / wheelset_mass
        pivot = 1.0 - delta_s * (-slope / (scaled * wheelset_mass))
        change = delta_s * (wheel_rate + wheel_by_train * train_change) / pivot
        out[axle] = max(wheel_speed_mps[axle] + change, 0.0)
    return speed_mps + train_change


@numba.njit(**JIT_OPTIONS)
def _substep_powers(parameters, speed_mps, wheel_speed_mps, clamp_N, force_N, loads, constants, slip_power_W):
    """The integrands the substeps sum by the trapezoid rule: slip power per axle into
    ``slip_power_W`` (A,); returns the resistance power and mu_eff v (Eq. 15)."""
    force_sum, clamp_sum = 0.0, 0.0
    for axle in range(force_N.shape[0]):
        slip_power_W[axle] = force_N[axle] * (speed_mps - wheel_speed_mps[axle])
        force_sum += force_N[axle]
        clamp_sum += clamp_N[axle]
    resistance = running_resistance_N(
        speed_mps, constants[RESISTANCE_A_N], constants[RESISTANCE_B_N_PER_MPS], constants[RESISTANCE_C_N_PER_MPS2]
    )
    # Eq. 15 with m d, m the effective mass, d the body's deceleration.
    retarding = loads[MASS_KG] * (force_sum + resistance) / loads[BODY_MASS_KG]
    weighted_clamp = clamp_sum * (parameters[DISCS_PER_AXLE] * parameters[RADIUS_RATIO])
    nominal = running_resistance_N(
        speed_mps,
        constants[NOMINAL_RESISTANCE_A_N],
        constants[NOMINAL_RESISTANCE_B_N_PER_MPS],
        constants[NOMINAL_RESISTANCE_C_N_PER_MPS2],
    )
    return resistance * speed_mps, effective_mu(retarding, nominal, weighted_clamp) * speed_mps


@numba.njit(**JIT_OPTIONS)
def _clamp_forces(parameters, pressure_bar, clamp_N):
    """Clamp force per disc unit of each axle (A,) from its cylinder pressure (A,)."""
    gain, threshold = parameters[CALIPER_GAIN_N_PER_BAR], parameters[CALIPER_THRESHOLD_BAR]
    for axle in range(clamp_N.shape[0]):
        clamp_N[axle] = clamp_force_from_pressure_N(pressure_bar[axle], gain, threshold)


@numba.njit(**JIT_OPTIONS)
def _substep_pressures(fraction, stage_pressure_bar, train, pressure_bar):
    """The cylinder pressures (A,) at ``fraction`` of the step, on the parabola through the
    step's start, middle and end pressures (stage_pressure_bar (3, B, A))."""
    for axle in range(pressure_bar.shape[0]):
        start = stage_pressure_bar[0, train, axle]
        middle = stage_pressure_bar[1, train, axle]
        end = stage_pressure_bar[2, train, axle]
        pressure_bar[axle] = (
            start
            + fraction * (4.0 * middle - 3.0 * start - end)
            + fraction * fraction * 2.0 * (start + end - 2.0 * middle)
        )


# ------------------------------------------------------------------------------------------------
# Discs


@numba.njit(**JIT_OPTIONS)
def _film_conductances(parameters, sliding_mps):
    """h A of the friction surfaces and of the ventilation channels at ``sliding_mps`` (Eq. 10)."""
    reference = parameters[REFERENCE_SLIDING_SPEED_MPS]
    surface = film_conductance_W_per_K(
        sliding_mps,
        parameters[SURFACE_H0_W_PER_M2K],
        parameters[SURFACE_H_REF_W_PER_M2K],
        parameters[SURFACE_EXPONENT],
        parameters[SURFACE_AREA_M2],
        reference,
    )
    ventilation = film_conductance_W_per_K(
        sliding_mps,
        parameters[VENTILATION_H0_W_PER_M2K],
        parameters[VENTILATION_H_REF_W_PER_M2K],
        parameters[VENTILATION_EXPONENT],
        parameters[VENTILATION_AREA_M2],
        reference,
    )
    return surface, ventilation


@numba.njit(**JIT_OPTIONS)
def _mu_rate(parameters, mu, clamp_N, sliding_mps, friction_temperature_K, power_coefficient):
    """dmu/dt of Eq. 4 of one disc unit, 0 unless it is clamped and slides."""
    term = clamp_force_term_per_s(
        clamp_N,
        parameters[CLAMP_FORCE_COEFFICIENT_PER_S],
        parameters[CLAMP_FORCE_EXPONENT],
        parameters[REFERENCE_CLAMP_FORCE_N],
    )
    rate = friction_rate_per_s(
        mu,
        clamp_N,
        sliding_mps,
        friction_temperature_K,
        term,
        power_coefficient,
        parameters[POWER_EXPONENT],
        parameters[DECAY_COEFFICIENT_PER_S],
        parameters[DECAY_EXPONENT],
        parameters[TEMPERATURE_COEFFICIENT_PER_S],
        parameters[TEMPERATURE_EXPONENT],
        parameters[REFERENCE_POWER_W],
        parameters[REFERENCE_TEMPERATURE_K],
    )
    return select(friction_evolves(clamp_N, sliding_mps, parameters[MIN_SLIDING_SPEED_MPS]), rate, 0.0)


@numba.njit(**JIT_OPTIONS)
def _disc_rates(parameters, train, disc, wheel_speed_mps, speed_mps, clamp_N, power_coefficient, ambient_K, rates):
    """d/dt of one train's disc states ``disc`` (6, A, k) into ``rates`` (6, A, k), each axle's
    discs sliding at its wheel's speed (A,); returns the train's disc friction power, W."""
    ratio = parameters[RADIUS_RATIO]
    mu_min, mu_max = parameters[MU_MIN], parameters[MU_MAX]
    power = 0.0
    for axle in range(disc.shape[1]):
        sliding = max(wheel_speed_mps[axle], 0.0) * ratio
        surface, ventilation = _film_conductances(parameters, sliding)
        clamp = clamp_N[axle]
        for unit in range(disc.shape[2]):
            mu = bounded_mu(disc[MU, axle, unit], mu_min, mu_max)
            friction_temperature, disc_temperature = disc[T_FRIC, axle, unit], disc[T_DISC, axle, unit]
            friction_power = mu * clamp * sliding
            conductance = contact_conductance_W_per_K(
                0.5 * (friction_temperature + disc_temperature),
                parameters[CONDUCTANCE_W_PER_K],
                parameters[CONDUCTANCE_SLOPE_W_PER_K2],
                parameters[CONDUCTANCE_REFERENCE_TEMPERATURE_K],
                parameters[CONDUCTANCE_MIN_W_PER_K],
            )
            friction_W, surface_W, conduction_W, ventilation_W = heat_flows_W(
                friction_power,
                friction_temperature,
                disc_temperature,
                surface,
                ventilation,
                conductance,
                ambient_K,
                parameters[HEAT_FRACTION_INTO_DISC],
            )
            rates[T_FRIC, axle, unit], rates[T_DISC, axle, unit] = temperature_rates_K_per_s(
                friction_W,
                surface_W,
                conduction_W,
                ventilation_W,
                parameters[FRICTION_LAYER_HEAT_CAPACITY_J_PER_K],
                parameters[DISC_BODY_HEAT_CAPACITY_J_PER_K],
            )
            rates[MU, axle, unit] = _mu_rate(
                parameters, mu, clamp, sliding, friction_temperature, power_coefficient[axle, unit, train]
            )
            rates[MU_DISTANCE, axle, unit] = mu * speed_mps
            rates[FRICTION_HEAT, axle, unit] = friction_W
            rates[COOLING_HEAT, axle, unit] = surface_W + ventilation_W
            power += friction_power
    return power


# ------------------------------------------------------------------------------------------------
# The wheelsets and the train over one step

# Rows of a train's per-axle scratch (N_AXLE_WORK, A).
(
    WHEEL_SPEED,
    NEW_WHEEL_SPEED,
    FORCE,
    SLOPE,
    BRAKE,
    PRESSURE,
    CLAMP,
    SLIP_POWER,
    NEW_SLIP_POWER,
    WHEEL_LOAD,
    CREEP_STIFFNESS,
) = range(11)
N_AXLE_WORK = 11


@numba.njit(**JIT_OPTIONS)
def _brake_forces(parameters, mu_start, mu_rate, elapsed_s, clamp_N, brake_N):
    """sum over each axle's discs of mu F_C r_fric / r (A,), mu extrapolated from the step's start
    by ``elapsed_s`` with its first-stage rate."""
    for axle in range(brake_N.shape[0]):
        total = 0.0
        for unit in range(mu_start.shape[1]):
            total += (mu_start[axle, unit] + elapsed_s * mu_rate[axle, unit]) * clamp_N[axle]
        brake_N[axle] = total * parameters[RADIUS_RATIO]


@numba.njit(**JIT_OPTIONS)
def _substeps(
    parameters, scheme, train, rows, slip_work_J, mu_start, mu_rate, stage_pressure_bar, loads, constants, rail, work
):
    """The wheel speeds (``work[WHEEL_SPEED]`` in, at the step's end out), the train's rows
    ``rows`` (6,: speed, position, resistance work, mu_eff distance) and each axle's slip work
    (A,) over one step of a moving train, in linearly implicit Euler substeps; returns the wheel
    and train speeds at the step's middle and the fraction of the step at which the train
    stopped (nan if it did not)."""
    section_starts_m, laws, axle_offsets_m, sections = rail
    h, n = scheme[STEP_S], int(scheme[N_SUBSTEPS])
    delta = h / n
    u, u_new, force, slope = work[WHEEL_SPEED], work[NEW_WHEEL_SPEED], work[FORCE], work[SLOPE]
    pressure, clamp, slip_power, new_slip_power = work[PRESSURE], work[CLAMP], work[SLIP_POWER], work[NEW_SLIP_POWER]
    wheel_load, stiffness = loads[WHEEL_LOAD_N], loads[CREEP_STIFFNESS_N]
    transfer = scheme[LOAD_TRANSFER] != 0.0
    if transfer:  # the loads at the end of the last step
        for axle in range(u.shape[0]):
            load = loads[AXLE_LOAD_GAIN + u.shape[0] + axle]
            work[WHEEL_LOAD, axle] = load
            work[CREEP_STIFFNESS, axle] = stiffness * (load / wheel_load) ** (2.0 / 3.0)
    friction_factor = loads[STATIC_FRICTION_FACTOR]
    middle_speed, stop_fraction = rows[SPEED], math.nan
    middle_wheels = u.copy()
    _axle_laws(rows[POSITION], section_starts_m, axle_offsets_m, sections)
    if transfer:
        _transferred_creep_forces(
            rows[SPEED], u, friction_factor, scheme, laws, sections, loads, constants, work, force, slope
        )
    else:
        _creep_forces(rows[SPEED], u, wheel_load, stiffness, friction_factor, scheme, laws, sections, force, slope)
    _clamp_forces(parameters, stage_pressure_bar[0, train], clamp)
    resistance_power, mu_eff_speed = _substep_powers(
        parameters, rows[SPEED], u, clamp, force, loads, constants, slip_power
    )
    for j in range(n):
        fraction = (j + 1) * delta / h
        _substep_pressures(fraction, stage_pressure_bar, train, pressure)
        _clamp_forces(parameters, pressure, clamp)
        _brake_forces(parameters, mu_start, mu_rate, fraction * h, clamp, work[BRAKE])
        v0 = rows[SPEED]
        v_new = _implicit_update(v0, u, work[BRAKE], force, slope, delta, scheme, loads, constants, u_new)
        theta = 1.0
        stopped = v_new <= 0.0
        if stopped:
            theta = v0 / (v0 - v_new)
            v_new = 0.0
            u_new[:] = 0.0
        weight = 0.5 * delta * theta
        rows[POSITION] += weight * (v0 + v_new)
        _axle_laws(rows[POSITION], section_starts_m, axle_offsets_m, sections)
        if transfer:
            _transferred_creep_forces(
                v_new, u_new, friction_factor, scheme, laws, sections, loads, constants, work, force, slope
            )
        else:
            _creep_forces(v_new, u_new, wheel_load, stiffness, friction_factor, scheme, laws, sections, force, slope)
        new_resistance, new_mu_eff = _substep_powers(
            parameters, v_new, u_new, clamp, force, loads, constants, new_slip_power
        )
        rows[RESISTANCE_WORK] += weight * (resistance_power + new_resistance)
        rows[MU_EFF_DISTANCE] += weight * (mu_eff_speed + new_mu_eff)
        for axle in range(u.shape[0]):
            slip_work_J[axle] += weight * (slip_power[axle] + new_slip_power[axle])
            slip_power[axle] = new_slip_power[axle]
            u[axle] = u_new[axle]
        rows[SPEED] = v_new
        resistance_power, mu_eff_speed = new_resistance, new_mu_eff
        # A train that stopped stands still for the rest of the step (also at its middle).
        if 2 * (j + 1) == n or (stopped and 2 * (j + 1) < n):
            middle_speed = rows[SPEED]
            middle_wheels[:] = u
        if stopped:
            stop_fraction = (j + theta) / n
            break
    return middle_speed, middle_wheels, stop_fraction


@numba.njit(**JIT_OPTIONS)
def _advance(disc_start, rates, fraction_s, disc_stage):
    """disc_start + fraction_s * rates: the state at which the next RK4 stage is evaluated."""
    for row in range(disc_start.shape[0]):
        for axle in range(disc_start.shape[1]):
            for unit in range(disc_start.shape[2]):
                disc_stage[row, axle, unit] = disc_start[row, axle, unit] + fraction_s * rates[row, axle, unit]


@numba.njit(**JIT_OPTIONS)
def _finish_discs(parameters, train, step_s, share, disc_start, rates, disc_end):
    """RK4's weighted sum of the four stages into the train's column of ``disc_end`` (6, A, k, B),
    taken to ``share`` of the step (the stop instant), mu bounded."""
    sixth = step_s / 6.0
    for row in range(disc_start.shape[0]):
        for axle in range(disc_start.shape[1]):
            for unit in range(disc_start.shape[2]):
                change = sixth * (
                    rates[0, row, axle, unit]
                    + 2.0 * (rates[1, row, axle, unit] + rates[2, row, axle, unit])
                    + rates[3, row, axle, unit]
                )
                disc_end[row, axle, unit, train] = disc_start[row, axle, unit] + share * change
    for axle in range(disc_start.shape[1]):
        for unit in range(disc_start.shape[2]):
            disc_end[MU, axle, unit, train] = bounded_mu(
                disc_end[MU, axle, unit, train], parameters[MU_MIN], parameters[MU_MAX]
            )


@numba.njit(**JIT_OPTIONS)
def _step_train(
    train, moving, parameters, scheme, power_coefficient, constants, loads, rail, start, stage_pressure_bar, end
):
    """One step of the train ``train``, ``moving`` or standing (its discs cooling): ``start`` and
    ``end`` are the batch's (disc, train, wheelset) states; returns the fraction of the step at
    which it stopped (nan if it did not)."""
    disc_all, train_all, wheelset_all = start
    h, radius = scheme[STEP_S], scheme[WHEEL_RADIUS_M]
    n_axles, per_axle = disc_all.shape[1], disc_all.shape[2]
    disc0 = disc_all[:, :, :, train].copy()
    rates = np.empty((4, N_DISC_STATES, n_axles, per_axle))
    stage = np.empty_like(disc0)
    work = np.empty((N_AXLE_WORK, n_axles))
    clamp = np.empty((3, n_axles))
    mu_start = np.empty((n_axles, per_axle))
    for axle in range(n_axles):
        work[WHEEL_SPEED, axle] = wheelset_all[ANGULAR_SPEED, axle, train] * radius
        for unit in range(per_axle):
            mu_start[axle, unit] = bounded_mu(disc0[MU, axle, unit], parameters[MU_MIN], parameters[MU_MAX])
    for row in range(3):
        _clamp_forces(parameters, stage_pressure_bar[row, train], clamp[row])
    ambient = constants[AMBIENT_K]
    u_start, v_start = work[WHEEL_SPEED].copy(), train_all[SPEED, train]
    power1 = _disc_rates(parameters, train, disc0, u_start, v_start, clamp[0], power_coefficient, ambient, rates[0])
    rows, slip_work = train_all[:, train].copy(), wheelset_all[SLIP_WORK, :, train].copy()
    v_middle, u_middle, stop_fraction = v_start, u_start, math.nan
    if moving:
        v_middle, u_middle, stop_fraction = _substeps(
            parameters,
            scheme,
            train,
            rows,
            slip_work,
            mu_start,
            rates[0, MU],
            stage_pressure_bar,
            loads,
            constants,
            rail,
            work,
        )
    u_end, v_end = work[WHEEL_SPEED], rows[SPEED]
    _advance(disc0, rates[0], 0.5 * h, stage)
    power2 = _disc_rates(parameters, train, stage, u_middle, v_middle, clamp[1], power_coefficient, ambient, rates[1])
    _advance(disc0, rates[1], 0.5 * h, stage)
    power3 = _disc_rates(parameters, train, stage, u_middle, v_middle, clamp[1], power_coefficient, ambient, rates[2])
    _advance(disc0, rates[2], h, stage)
    power4 = _disc_rates(parameters, train, stage, u_end, v_end, clamp[2], power_coefficient, ambient, rates[3])
    # A train that stopped inside the step ends there: its discs are taken to the stop instant.
    share = 1.0 if math.isnan(stop_fraction) else stop_fraction
    disc_end, train_end, wheelset_end = end
    _finish_discs(parameters, train, h, share, disc0, rates, disc_end)
    rows[BRAKE_WORK] = train_all[BRAKE_WORK, train] + share * ((h / 6.0) * (power1 + 2.0 * (power2 + power3) + power4))
    train_end[:, train] = rows
    for axle in range(n_axles):
        wheelset_end[ANGULAR_SPEED, axle, train] = u_end[axle] / radius
        wheelset_end[SLIP_WORK, axle, train] = slip_work[axle]
    return stop_fraction


@numba.njit(**JIT_OPTIONS)
def _step_trains(first, end_train, arguments, start, moving, hold_standing, end, moving_end, stop_fraction):
    """:func:`adhesion_step` for the trains ``first`` ... ``end_train - 1``."""
    parameters, scheme, power_coefficient, train_constants, wheelset_constants, rail_table, stage_pressure_bar = (
        arguments
    )
    section_starts_m, laws, axle_offsets_m = rail_table
    sections = np.empty(start[0].shape[1], dtype=np.int64)
    rail = (section_starts_m, laws, axle_offsets_m, sections)
    for train in range(first, end_train):
        if hold_standing and not moving[train]:
            end[0][:, :, :, train] = start[0][:, :, :, train]
            end[1][:, train] = start[1][:, train]
            end[2][:, :, train] = start[2][:, :, train]
            stop_fraction[train] = math.nan
        else:
            stop_fraction[train] = _step_train(
                train,
                moving[train],
                parameters,
                scheme,
                power_coefficient,
                train_constants[:, train],
                wheelset_constants[:, train],
                rail,
                start,
                stage_pressure_bar,
                end,
            )
        moving_end[train] = moving[train] and math.isnan(stop_fraction[train])


@_compiled
def _adhesion_step_serial(arguments, start, moving, hold_standing, end, moving_end, stop_fraction):
    _step_trains(0, moving.shape[0], arguments, start, moving, hold_standing, end, moving_end, stop_fraction)


@_compiled_threaded
def _adhesion_step_threaded(n_threads, arguments, start, moving, hold_standing, end, moving_end, stop_fraction):
    """:func:`adhesion_step` on ``n_threads`` threads, each a consecutive run of trains."""
    n_trains = moving.shape[0]
    # Tuples of arrays do not enter a parallel loop's body: unpacked here, packed again inside it.
    parameters, scheme, power_coefficient, train_constants, wheelset_constants, rail, stage_pressure_bar = arguments
    section_starts_m, laws, axle_offsets_m = rail
    disc0, train0, wheelset0 = start
    disc1, train1, wheelset1 = end
    for thread in numba.prange(n_threads):
        first, end_train = thread * n_trains // n_threads, (thread + 1) * n_trains // n_threads
        _step_trains(
            first,
            end_train,
            (
                parameters,
                scheme,
                power_coefficient,
                train_constants,
                wheelset_constants,
                (section_starts_m, laws, axle_offsets_m),
                stage_pressure_bar,
            ),
            (disc0, train0, wheelset0),
            moving,
            hold_standing,
            (disc1, train1, wheelset1),
            moving_end,
            stop_fraction,
        )


def adhesion_step(arguments, start, moving, hold_standing, end, moving_end, stop_fraction) -> None:
    """One step of every train with wheel-rail adhesion (:class:`~.wheelsets.AdhesionSimulator`),
    on up to :func:`.kernel.kernel_threads` threads (one per ``TRAINS_PER_THREAD`` trains at least).

    ``arguments``: (plant parameters (:func:`.kernel.plant_parameters`), scheme parameters
    (N_SCHEME_PARAMETERS,), power coefficients (A, k, B), train constants (N_TRAIN_CONSTANTS, B),
    wheelset constants (N_WHEELSET_CONSTANTS, B; with load transfer 2 A rows more, see
    AXLE_LOAD_GAIN, the second A of them written at the step's end), the rail (section starts (S,), their laws
    (S, N_LAW_PARAMETERS), axle offsets behind the train's position (A,)), the cylinder pressures
    at the step's start, middle and end (3, B, A)). ``start`` and ``end``: the (disc, train,
    wheelset) states before and after the step. With ``hold_standing`` a train standing at the
    start keeps its state. Writes ``moving_end`` and ``stop_fraction`` (nan where no train
    stopped)."""
    n_threads = min(kernel.kernel_threads(), moving.shape[0] // TRAINS_PER_THREAD)
    if n_threads > 1:
        _adhesion_step_threaded(n_threads, arguments, start, moving, hold_standing, end, moving_end, stop_fraction)
    else:
        _adhesion_step_serial(arguments, start, moving, hold_standing, end, moving_end, stop_fraction)
