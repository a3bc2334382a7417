"""Compiled RK4 kernels of :class:`~brakegym.simulator.Simulator` (numba).

The physics is not written here: the equations are the module-level functions of
:mod:`brakegym.physics` (the same function objects the numpy code calls), registered below so
that numba compiles them where the kernels call them. What is here is the integration: trains in
tiles of up to 16, the four RK4 stages of a tile in small work arrays that stay in the cache, the
stop interpolation. The hot loop runs over every disc of every train of a tile with no reduction
and no call left in it, so LLVM vectorizes it (:mod:`.kernel_math` says how the
fractional powers are computed for that).

Two ways through a step, with the same code per tile:

- :func:`fused_rk4_steps`: whole steps in one call (several, with the brake cylinders' pressure
  model inside, for an environment's control step), for a simulator without extension hooks;
- :func:`stage_rates` once per RK4 stage, then :func:`finish_rk4_step`: for a simulator whose
  friction modifiers and extra forces (Python objects) are evaluated between the stages. They
  enter as arrays: a friction scale per disc and an extra force per train.

Compiled code is cached on disk (numba's ``cache=True``), so the compilation is paid once per
machine. Numba checks only the source file of the cached function for changes; the kernels here
inline code of other modules, so the cache stamp is widened to a digest of every source they can
reach (``_CACHE_SOURCES``): edit a physics formula and the kernels compile afresh.

No ``fastmath``: results must not depend on how LLVM vectorizes or reassociates.

Threads: :func:`fused_steps` shares a batch's tiles out over numba's threads
(:func:`fused_rk4_steps_threaded`, each thread a consecutive run of tiles that it takes through
all the steps of the call), up to :func:`kernel_threads` (every core unless
:func:`set_kernel_threads` says fewer). A train's arithmetic does not depend on its tile, so the
results are the same bit for bit on any number of threads. Campaign workers are forked processes
and run on one thread each: a thread pool does not survive a fork, and the processes already share
the cores.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numba
import numpy as np
from numba.core import caching
from numba.extending import register_jitable

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
from . import kernel_math, state
from .kernel_math import JIT_OPTIONS, choose, choose_integer
from .state import (
    BRAKE_WORK,
    COOLING_HEAT,
    EXTRA_WORK,
    FRICTION_HEAT,
    MU,
    MU_DISTANCE,
    MU_EFF_DISTANCE,
    N_DISC_STATES,
    N_TRAIN_STATES,
    POSITION,
    RESISTANCE_WORK,
    SPEED,
    T_DISC,
    T_FRIC,
    CylinderState,
)

# The equations, compiled where the kernels call them. Inlined into the caller by numba itself:
# LLVM's inliner leaves calls in place when a callee is large, and a call stops vectorization.
for _equation in (
    bounded_mu,
    friction_evolves,
    clamp_force_term_per_s,
    friction_rate_per_s,
    film_conductance_W_per_K,
    contact_conductance_W_per_K,
    heat_flows_W,
    temperature_rates_K_per_s,
    running_resistance_N,
    effective_mu,
    clamp_force_from_pressure_N,
):
    register_jitable(inline="always", **JIT_OPTIONS)(_equation)


# Entries of the plant parameter vector the kernels read (built by plant_parameters()).
(
    RADIUS_RATIO,
    DISCS_PER_AXLE,
    CALIPER_GAIN_N_PER_BAR,
    CALIPER_THRESHOLD_BAR,
    POWER_EXPONENT,
    DECAY_COEFFICIENT_PER_S,
    DECAY_EXPONENT,
    TEMPERATURE_COEFFICIENT_PER_S,
    TEMPERATURE_EXPONENT,
    CLAMP_FORCE_COEFFICIENT_PER_S,
    CLAMP_FORCE_EXPONENT,
    REFERENCE_POWER_W,
    REFERENCE_TEMPERATURE_K,
    REFERENCE_CLAMP_FORCE_N,
    MU_MIN,
    MU_MAX,
    MIN_SLIDING_SPEED_MPS,
    FRICTION_LAYER_HEAT_CAPACITY_J_PER_K,
    DISC_BODY_HEAT_CAPACITY_J_PER_K,
    CONDUCTANCE_W_PER_K,
    CONDUCTANCE_SLOPE_W_PER_K2,
    CONDUCTANCE_REFERENCE_TEMPERATURE_K,
    CONDUCTANCE_MIN_W_PER_K,
    HEAT_FRACTION_INTO_DISC,
    REFERENCE_SLIDING_SPEED_MPS,
    SURFACE_H0_W_PER_M2K,
    SURFACE_H_REF_W_PER_M2K,
    SURFACE_EXPONENT,
    SURFACE_AREA_M2,
    VENTILATION_H0_W_PER_M2K,
    VENTILATION_H_REF_W_PER_M2K,
    VENTILATION_EXPONENT,
    VENTILATION_AREA_M2,
) = range(33)
N_PLANT_PARAMETERS = 33

# Rows of the per-train constants (N_TRAIN_CONSTANTS, B) the kernels read (built by the simulator):
# one array instead of one argument each, so that a call unboxes fewer arguments. The running
# resistance (Eq. 14) is per train, the drawn one and the nominal one Eq. 15 uses.
(
    INVERSE_MASS_PER_KG,
    RESISTANCE_A_N,
    RESISTANCE_B_N_PER_MPS,
    RESISTANCE_C_N_PER_MPS2,
    NOMINAL_RESISTANCE_A_N,
    NOMINAL_RESISTANCE_B_N_PER_MPS,
    NOMINAL_RESISTANCE_C_N_PER_MPS2,
    AMBIENT_K,
) = range(8)
N_TRAIN_CONSTANTS = 8


def plant_parameters(plant) -> np.ndarray:
    """The plant's constants as the vector the kernels read (a ``brakegym.simulator.Plant``).
    Per-train values (mass, running resistance, ambient) and per-disc values are separate arrays."""
    friction, thermal = plant.friction, plant.thermal
    values = {
        RADIUS_RATIO: plant.radius_ratio,
        DISCS_PER_AXLE: plant.discs_per_axle,
        CALIPER_GAIN_N_PER_BAR: plant.caliper.gain_N_per_bar,
        CALIPER_THRESHOLD_BAR: plant.caliper.threshold_bar,
        POWER_EXPONENT: friction.power_exponent,
        DECAY_COEFFICIENT_PER_S: friction.decay_coefficient_per_s,
        DECAY_EXPONENT: friction.decay_exponent,
        TEMPERATURE_COEFFICIENT_PER_S: friction.temperature_coefficient_per_s,
        TEMPERATURE_EXPONENT: friction.temperature_exponent,
        CLAMP_FORCE_COEFFICIENT_PER_S: friction.clamp_force_coefficient_per_s,
        CLAMP_FORCE_EXPONENT: friction.clamp_force_exponent,
        REFERENCE_POWER_W: friction.reference_power_W,
        REFERENCE_TEMPERATURE_K: friction.reference_temperature_K,
        REFERENCE_CLAMP_FORCE_N: friction.reference_clamp_force_N,
        MU_MIN: friction.mu_min,
        MU_MAX: friction.mu_max,
        MIN_SLIDING_SPEED_MPS: friction.min_sliding_speed_mps,
        FRICTION_LAYER_HEAT_CAPACITY_J_PER_K: thermal.friction_layer_heat_capacity_J_per_K,
        DISC_BODY_HEAT_CAPACITY_J_PER_K: thermal.disc_body_heat_capacity_J_per_K,
        CONDUCTANCE_W_PER_K: thermal.conductance_W_per_K,
        CONDUCTANCE_SLOPE_W_PER_K2: thermal.conductance_slope_W_per_K2,
        CONDUCTANCE_REFERENCE_TEMPERATURE_K: thermal.conductance_reference_temperature_K,
        CONDUCTANCE_MIN_W_PER_K: thermal.conductance_min_W_per_K,
        HEAT_FRACTION_INTO_DISC: thermal.heat_fraction_into_disc,
        REFERENCE_SLIDING_SPEED_MPS: thermal.reference_sliding_speed_mps,
        SURFACE_H0_W_PER_M2K: thermal.surface.h0_W_per_m2K,
        SURFACE_H_REF_W_PER_M2K: thermal.surface.h_ref_W_per_m2K,
        SURFACE_EXPONENT: thermal.surface.exponent,
        SURFACE_AREA_M2: thermal.surface.area_m2,
        VENTILATION_H0_W_PER_M2K: thermal.ventilation.h0_W_per_m2K,
        VENTILATION_H_REF_W_PER_M2K: thermal.ventilation.h_ref_W_per_m2K,
        VENTILATION_EXPONENT: thermal.ventilation.exponent,
        VENTILATION_AREA_M2: thermal.ventilation.area_m2,
    }
    assert sorted(values) == list(range(N_PLANT_PARAMETERS)), "every kernel parameter set exactly once"
    parameters = np.empty(N_PLANT_PARAMETERS)
    for index, value in values.items():
        parameters[index] = value
    return parameters


# ------------------------------------------------------------------------------------------------
# Disk cache keyed on every source the kernels compile

_PACKAGE = Path(__file__).resolve().parent
_CACHE_SOURCES = (
    Path(__file__).resolve(),
    Path(kernel_math.__file__).resolve(),
    Path(state.__file__).resolve(),
    *sorted((_PACKAGE.parent / "physics").glob("*.py")),
)


#: The sources the kernels' disk cache is stamped with; kernels elsewhere that call into these add theirs.
KERNEL_CACHE_SOURCES = _CACHE_SOURCES


def cache_sources_digest(paths=_CACHE_SOURCES) -> str:
    """SHA-256 over the contents of ``paths``: the stamp of the kernels' disk cache."""
    digest = hashlib.sha256()
    for path in paths:
        digest.update(Path(path).name.encode())
        digest.update(Path(path).read_bytes())
    return digest.hexdigest()


# Taken when this module is imported: the code compiled in this process is the code read now.
_SOURCES_DIGEST = cache_sources_digest()


def stamped_compiler(sources_digest: str):
    """A decorator like ``numba.njit(cache=True, parallel=...)`` whose disk cache is stamped with
    ``sources_digest`` (:func:`cache_sources_digest` of every source the function can reach)
    instead of numba's stamp of the function's own file: the compiled code is taken from the cache
    only while none of those sources changed."""

    class SourcesStamp:
        def get_source_stamp(self):
            return sources_digest

    # numba's own file-backed locators (NUMBA_CACHE_DIR, the package's __pycache__, the user's
    # cache directory), each with the widened stamp.
    locators = [
        type(f"PhysicsSources{base.__name__}", (SourcesStamp, base), {})
        for base in (caching.UserProvidedCacheLocator, caching.InTreeCacheLocator, caching.UserWideCacheLocator)
    ]
    cache_impl = type("StampedCacheImpl", (caching.CompileResultCacheImpl,), {"_locator_classes": locators})
    cache = type("StampedCache", (caching.FunctionCache,), {"_impl_class": cache_impl})

    def compiled(function, parallel=False):
        dispatcher = numba.njit(parallel=parallel, **JIT_OPTIONS)(function)
        dispatcher._cache = cache(function)  # what Dispatcher.enable_caching() does for cache=True
        return dispatcher

    return compiled


#: ``numba.njit(cache=True)`` with the cache stamp of every physics source.
_compiled = stamped_compiler(_SOURCES_DIGEST)


def _compiled_threaded(function):
    """:func:`_compiled` for a kernel whose ``numba.prange`` loop runs on numba's threads."""
    return _compiled(function, parallel=True)


# ------------------------------------------------------------------------------------------------
# Building blocks on a tile of trains (not inlined: each is compiled once and shared by the kernels)

# Trains are integrated in tiles of up to this many. Inside a tile the disc values lie in one
# flat row per state, slot (axle * k + disc) * n_tile + train, so the hot loop runs over all discs
# of all trains of the tile: 16 slots for a single train, 256 for a full tile, and LLVM vectorizes
# it either way. A tile's work arrays stay in the L1/L2 cache. Vector lanes and the scalar
# remainder do the same IEEE operations, so a train's result does not depend on its tile or its
# place in the batch.
TRAINS_PER_TILE = 16


# The copies between the batch and a tile index a view that starts at the tile's first train, not
# the batch at ``tile_start + t``: LLVM cannot tell that ``tile_start + t`` is not negative, so
# numba's wraparound of negative indices stays in the loop, lane by lane, and the copy runs as
# scalar loads or stores. Indices from 0 never wrap, and the copy is one vector load and store.


@numba.njit(**JIT_OPTIONS)
def _gather_discs(states, tile_start, n_tile, tile):
    """Disc values (R, A, k, B) of the tile's trains into slots ``tile`` (R, A * k * T)."""
    n_axles, per_axle = states.shape[1], states.shape[2]
    for row in range(states.shape[0]):
        for axle in range(n_axles):
            for disc in range(per_axle):
                first = (axle * per_axle + disc) * n_tile
                trains = states[row, axle, disc, tile_start : tile_start + n_tile]
                for t in range(n_tile):
                    tile[row, first + t] = trains[t]


@numba.njit(**JIT_OPTIONS)
def _scatter_discs(tile, tile_start, n_tile, states):
    n_axles, per_axle = states.shape[1], states.shape[2]
    for row in range(states.shape[0]):
        for axle in range(n_axles):
            for disc in range(per_axle):
                first = (axle * per_axle + disc) * n_tile
                trains = states[row, axle, disc, tile_start : tile_start + n_tile]
                for t in range(n_tile):
                    trains[t] = tile[row, first + t]


@numba.njit(**JIT_OPTIONS)
def _gather_trains(values, tile_start, n_tile, tile):
    """Train values (R, B) of the tile's trains into ``tile`` (R, T)."""
    for row in range(values.shape[0]):
        trains = values[row, tile_start : tile_start + n_tile]
        for t in range(n_tile):
            tile[row, t] = trains[t]


@numba.njit(**JIT_OPTIONS)
def _per_slot(n_discs, n_tile, per_train, slots):
    """A value per train (T,) repeated for each of its discs (A * k * T,)."""
    for disc in range(n_discs):
        for t in range(n_tile):
            slots[disc * n_tile + t] = per_train[t]


@numba.njit(**JIT_OPTIONS)
def _clamp_of_tile(
    parameters,
    pressure_bar,
    tile_start,
    n_tile,
    per_axle,
    axle_clamp_N,
    axle_clamp_term,
    clamp_N,
    clamp_term,
    weighted_clamp_N,
):
    """From the cylinder pressures (B, A) of the tile's trains: the clamp force of each axle
    (spec Section 4) and Eq. 4's clamp-force term (it depends on the clamp force alone, so it is
    evaluated per axle) into ``axle_clamp_N`` and ``axle_clamp_term`` (A * T,), both per disc slot
    into ``clamp_N`` and ``clamp_term`` (S,), and sum over discs of (r_fric / r_wheel) F_C,
    Eq. 15's denominator, into ``weighted_clamp_N`` (T,)."""
    n_axles = pressure_bar.shape[1]
    gain, threshold = parameters[CALIPER_GAIN_N_PER_BAR], parameters[CALIPER_THRESHOLD_BAR]
    for axle in range(n_axles):
        for t in range(n_tile):
            pressure = pressure_bar[tile_start + t, axle]
            axle_clamp_N[axle * n_tile + t] = clamp_force_from_pressure_N(pressure, gain, threshold)
    coefficient, exponent = parameters[CLAMP_FORCE_COEFFICIENT_PER_S], parameters[CLAMP_FORCE_EXPONENT]
    reference = parameters[REFERENCE_CLAMP_FORCE_N]
    clamped = False
    for index in range(n_axles * n_tile):
        if axle_clamp_N[index] > 0.0:
            clamped = True
            break
    for index in range(n_axles * n_tile):
        # Released brakes (no clamp force anywhere in the tile) need no powers: the term is 0.
        axle_clamp_term[index] = (
            clamp_force_term_per_s(axle_clamp_N[index], coefficient, exponent, reference) if clamped else 0.0
        )
    for t in range(n_tile):
        weighted_clamp_N[t] = 0.0
    for axle in range(n_axles):
        for t in range(n_tile):
            weighted_clamp_N[t] += axle_clamp_N[axle * n_tile + t]
    weight = parameters[DISCS_PER_AXLE] * parameters[RADIUS_RATIO]
    for t in range(n_tile):
        weighted_clamp_N[t] *= weight
    for axle in range(n_axles):
        for disc in range(per_axle):
            first = (axle * per_axle + disc) * n_tile
            for t in range(n_tile):
                clamp_N[first + t] = axle_clamp_N[axle * n_tile + t]
                clamp_term[first + t] = axle_clamp_term[axle * n_tile + t]


@numba.njit(**JIT_OPTIONS)
def _rates_of_tile(
    parameters,
    n_discs,
    n_tile,
    disc,
    speed_mps,
    moving,
    clamp_N,
    clamp_term,
    weighted_clamp_N,
    friction_scale,
    extra_force_N,
    power_coefficient,
    ambient_K,
    constants,
    disc_rates,
    train_rates,
    stage,
    train_work,
    slot_work,
):
    """Time derivatives of the tile's disc states ``disc`` (6, S) and train states at the speeds
    ``speed_mps`` (T,), into row ``stage`` of ``disc_rates`` (4, 6, S) and ``train_rates``
    (4, 6, T). Per-slot inputs (S,): clamp force and term, friction scale, power coefficient,
    ambient temperature; per-train inputs (T,) and ``constants`` (N_TRAIN_CONSTANTS, T).
    ``train_work`` (4 arrays (T,)) and ``slot_work`` (10 arrays (S,))
    are scratch. The same as ``NumpyReferenceSimulator._rates``."""
    n_slots = n_discs * n_tile
    ratio = parameters[RADIUS_RATIO]
    sliding, surface_conductance, ventilation_conductance, friction_sum = (
        train_work[0],
        train_work[1],
        train_work[2],
        train_work[3],
    )
    # Read once, before the loops: inside them LLVM could not tell the parameters apart from the
    # stores to the work arrays, and would neither hoist the loads nor vectorize.
    surface_h0, surface_h_ref = parameters[SURFACE_H0_W_PER_M2K], parameters[SURFACE_H_REF_W_PER_M2K]
    surface_exponent, surface_area = parameters[SURFACE_EXPONENT], parameters[SURFACE_AREA_M2]
    ventilation_h0, ventilation_h_ref = parameters[VENTILATION_H0_W_PER_M2K], parameters[VENTILATION_H_REF_W_PER_M2K]
    ventilation_exponent, ventilation_area = parameters[VENTILATION_EXPONENT], parameters[VENTILATION_AREA_M2]
    reference_sliding = parameters[REFERENCE_SLIDING_SPEED_MPS]
    for t in range(n_tile):
        # Stages may overshoot past standstill inside the stopping step: the forces extrapolate
        # smoothly there (for the stop interpolation), the sliding speed does not go negative.
        v_fric = choose(speed_mps[t] > 0.0, speed_mps[t], 0.0) * ratio
        sliding[t] = v_fric
        surface_conductance[t] = film_conductance_W_per_K(
            v_fric, surface_h0, surface_h_ref, surface_exponent, surface_area, reference_sliding
        )
        ventilation_conductance[t] = film_conductance_W_per_K(
            v_fric, ventilation_h0, ventilation_h_ref, ventilation_exponent, ventilation_area, reference_sliding
        )
    speed_of_slot, sliding_of_slot = slot_work[0], slot_work[1]
    surface_of_slot, ventilation_of_slot, friction_force = slot_work[2], slot_work[3], slot_work[4]
    _per_slot(n_discs, n_tile, speed_mps, speed_of_slot)
    _per_slot(n_discs, n_tile, sliding, sliding_of_slot)
    _per_slot(n_discs, n_tile, surface_conductance, surface_of_slot)
    _per_slot(n_discs, n_tile, ventilation_conductance, ventilation_of_slot)

    # Read once: inside the loop LLVM could not tell them apart from the stores to the arrays.
    mu_min, mu_max = parameters[MU_MIN], parameters[MU_MAX]
    min_sliding = parameters[MIN_SLIDING_SPEED_MPS]
    power_exponent = parameters[POWER_EXPONENT]
    decay_coefficient, decay_exponent = parameters[DECAY_COEFFICIENT_PER_S], parameters[DECAY_EXPONENT]
    temperature_coefficient = parameters[TEMPERATURE_COEFFICIENT_PER_S]
    temperature_exponent = parameters[TEMPERATURE_EXPONENT]
    reference_power, reference_temperature = parameters[REFERENCE_POWER_W], parameters[REFERENCE_TEMPERATURE_K]
    conductance, conductance_slope = parameters[CONDUCTANCE_W_PER_K], parameters[CONDUCTANCE_SLOPE_W_PER_K2]
    conductance_reference = parameters[CONDUCTANCE_REFERENCE_TEMPERATURE_K]
    conductance_min = parameters[CONDUCTANCE_MIN_W_PER_K]
    fraction_into_disc = parameters[HEAT_FRACTION_INTO_DISC]
    friction_layer_capacity = parameters[FRICTION_LAYER_HEAT_CAPACITY_J_PER_K]
    disc_body_capacity = parameters[DISC_BODY_HEAT_CAPACITY_J_PER_K]

    # The loop stores into separate arrays (rows of one array at a distance unknown to LLVM would
    # keep it from vectorizing), copied into the rows of ``disc_rates`` after it.
    friction_temperature_rate, disc_temperature_rate, mu_distance_rate = slot_work[5], slot_work[6], slot_work[7]
    friction_heat_rate, cooling_heat_rate = slot_work[8], slot_work[9]
    for slot in range(n_slots):
        mu = bounded_mu(disc[MU, slot], mu_min, mu_max)
        friction_temperature = disc[T_FRIC, slot]
        disc_temperature = disc[T_DISC, slot]
        clamp = clamp_N[slot]
        v_fric = sliding_of_slot[slot]
        force = mu * friction_scale[slot] * clamp
        friction_force[slot] = force
        friction_W, surface_W, conduction_W, ventilation_W = heat_flows_W(
            force * v_fric,
            friction_temperature,
            disc_temperature,
            surface_of_slot[slot],
            ventilation_of_slot[slot],
            contact_conductance_W_per_K(
                0.5 * (friction_temperature + disc_temperature),
                conductance,
                conductance_slope,
                conductance_reference,
                conductance_min,
            ),
            ambient_K[slot],
            fraction_into_disc,
        )
        d_friction_temperature, d_disc_temperature = temperature_rates_K_per_s(
            friction_W, surface_W, conduction_W, ventilation_W, friction_layer_capacity, disc_body_capacity
        )
        friction_temperature_rate[slot] = d_friction_temperature
        disc_temperature_rate[slot] = d_disc_temperature
        mu_distance_rate[slot] = mu * speed_of_slot[slot]
        friction_heat_rate[slot] = friction_W
        cooling_heat_rate[slot] = surface_W + ventilation_W
    for row, rates in (
        (T_FRIC, friction_temperature_rate),
        (T_DISC, disc_temperature_rate),
        (MU_DISTANCE, mu_distance_rate),
        (FRICTION_HEAT, friction_heat_rate),
        (COOLING_HEAT, cooling_heat_rate),
    ):
        for slot in range(n_slots):
            disc_rates[stage, row, slot] = rates[slot]

    # Eq. 4 in a loop of its own, skipped when no disc of the tile slides under clamp force
    # (standing trains, released brakes): its three powers are most of the work of a stage.
    # Counted without an early exit, so that the scan vectorizes.
    evolving_slots = 0
    for slot in range(n_slots):
        evolving_slots += choose_integer(friction_evolves(clamp_N[slot], sliding_of_slot[slot], min_sliding), 1, 0)
    if evolving_slots > 0:
        # Into a scratch array of its own (free again: its rates were copied above), not into
        # the row of disc_rates, for the same reason as the loop above.
        mu_rate = slot_work[5]
        friction_temperature = disc[T_FRIC]
        for slot in range(n_slots):
            mu = bounded_mu(disc[MU, slot], mu_min, mu_max)
            clamp = clamp_N[slot]
            v_fric = sliding_of_slot[slot]
            rate = friction_rate_per_s(
                mu,
                clamp,
                v_fric,
                friction_temperature[slot],
                clamp_term[slot],
                power_coefficient[slot],
                power_exponent,
                decay_coefficient,
                decay_exponent,
                temperature_coefficient,
                temperature_exponent,
                reference_power,
                reference_temperature,
            )
            mu_rate[slot] = select(friction_evolves(clamp, v_fric, min_sliding), rate, 0.0)
        for slot in range(n_slots):
            disc_rates[stage, MU, slot] = mu_rate[slot]
    else:
        for slot in range(n_slots):
            disc_rates[stage, MU, slot] = 0.0

    # Each train's discs summed in their order, apart from the loop above (a floating-point sum
    # inside it would not vectorize): deterministic.
    for t in range(n_tile):
        friction_sum[t] = 0.0
    for disc_index in range(n_discs):
        for t in range(n_tile):
            friction_sum[t] += friction_force[disc_index * n_tile + t]
    for t in range(n_tile):
        speed = speed_mps[t]
        brake = friction_sum[t] * ratio
        resistance = running_resistance_N(
            speed,
            constants[RESISTANCE_A_N, t],
            constants[RESISTANCE_B_N_PER_MPS, t],
            constants[RESISTANCE_C_N_PER_MPS2, t],
        )
        total = brake + resistance + extra_force_N[t]
        train_rates[stage, SPEED, t] = choose(moving[t], -total * constants[INVERSE_MASS_PER_KG, t], 0.0)
        train_rates[stage, POSITION, t] = speed
        train_rates[stage, BRAKE_WORK, t] = brake * speed
        train_rates[stage, RESISTANCE_WORK, t] = resistance * speed
        train_rates[stage, EXTRA_WORK, t] = extra_force_N[t] * speed
        nominal_resistance = running_resistance_N(
            speed,
            constants[NOMINAL_RESISTANCE_A_N, t],
            constants[NOMINAL_RESISTANCE_B_N_PER_MPS, t],
            constants[NOMINAL_RESISTANCE_C_N_PER_MPS2, t],
        )
        train_rates[stage, MU_EFF_DISTANCE, t] = effective_mu(total, nominal_resistance, weighted_clamp_N[t]) * speed


@numba.njit(**JIT_OPTIONS)
def _advance_tile(
    n_slots, n_tile, disc_start, train_start, disc_rates, train_rates, stage, fraction_of_step, disc_stage, speed_mps
):
    """The state at which the next stage is evaluated: start + fraction_of_step * the rates of
    ``stage`` (of the train states only the speed enters the rates)."""
    for row in range(N_DISC_STATES):
        for slot in range(n_slots):
            disc_stage[row, slot] = disc_start[row, slot] + fraction_of_step * disc_rates[stage, row, slot]
    for t in range(n_tile):
        speed_mps[t] = train_start[SPEED, t] + fraction_of_step * train_rates[stage, SPEED, t]


@numba.njit(**JIT_OPTIONS)
def _finish_tile(
    parameters,
    time_s,
    step_s,
    tile_start,
    n_discs,
    n_tile,
    disc_start,
    train_start,
    disc_rates,
    train_rates,
    moving,
    hold_standing,
    disc_end,
    train_end,
    stop_fraction,
    stop_time_s,
    moving1,
):
    """RK4's weighted sum of the four stages' rates into ``disc_end`` (6, S) and ``train_end``
    (6, T), the stop inside the step and the mu bound, for the trains ``tile_start`` ...
    ``tile_start + n_tile - 1``; sets their ``stop_fraction``, ``stop_time_s`` and ``moving1``.
    With ``hold_standing`` a train that stood still at the start of the step keeps its state."""
    n_slots = n_discs * n_tile
    sixth = step_s / 6.0
    for row in range(N_DISC_STATES):
        for slot in range(n_slots):
            disc_end[row, slot] = disc_start[row, slot] + sixth * (
                disc_rates[0, row, slot]
                + 2.0 * (disc_rates[1, row, slot] + disc_rates[2, row, slot])
                + disc_rates[3, row, slot]
            )
    for row in range(N_TRAIN_STATES):
        for t in range(n_tile):
            train_end[row, t] = train_start[row, t] + sixth * (
                train_rates[0, row, t]
                + 2.0 * (train_rates[1, row, t] + train_rates[2, row, t])
                + train_rates[3, row, t]
            )
    for t in range(n_tile):
        train = tile_start + t
        if moving[t] and train_end[SPEED, t] <= 0.0:
            v0 = train_start[SPEED, t]
            theta = v0 / (v0 - train_end[SPEED, t])
            # The deceleration is nearly constant over one step, so speed falls linearly to zero
            # at theta and the distance grows by the area of that triangle.
            for row in range(N_DISC_STATES):
                for disc in range(n_discs):
                    slot = disc * n_tile + t
                    disc_end[row, slot] = disc_start[row, slot] + theta * (disc_end[row, slot] - disc_start[row, slot])
            for row in range(N_TRAIN_STATES):
                train_end[row, t] = train_start[row, t] + theta * (train_end[row, t] - train_start[row, t])
            train_end[POSITION, t] = train_start[POSITION, t] + 0.5 * v0 * theta * step_s
            train_end[SPEED, t] = 0.0
            stop_fraction[train] = theta
            stop_time_s[train] = time_s + theta * step_s
            moving1[train] = False
        else:
            stop_fraction[train] = np.nan
            moving1[train] = moving[t]
    mu_min, mu_max = parameters[MU_MIN], parameters[MU_MAX]
    for slot in range(n_slots):
        disc_end[MU, slot] = bounded_mu(disc_end[MU, slot], mu_min, mu_max)
    if hold_standing:
        for t in range(n_tile):
            if not moving[t]:
                _hold_train(t, n_discs, n_tile, disc_start, train_start, disc_end, train_end)


@numba.njit(**JIT_OPTIONS)
def _hold_train(t, n_discs, n_tile, disc_start, train_start, disc_end, train_end):
    """Train ``t`` of the tile ends the step as it started it."""
    for row in range(N_DISC_STATES):
        for disc in range(n_discs):
            disc_end[row, disc * n_tile + t] = disc_start[row, disc * n_tile + t]
    for row in range(N_TRAIN_STATES):
        train_end[row, t] = train_start[row, t]


# ------------------------------------------------------------------------------------------------
# Kernels


@numba.njit(**JIT_OPTIONS)
def _cylinders_over_step(
    step, first_train, end_train, history, dead_steps, half_lag, full_lag, pressure_bar, command_bar, stage_pressure_bar
):
    """:func:`commanded_pressures` for the trains ``first_train`` ... ``end_train - 1``."""
    slots = history.shape[0]
    n_axles = command_bar.shape[1]
    here = step % slots
    for train in range(first_train, end_train):
        for axle in range(n_axles):
            history[here, train, axle] = command_bar[train, axle]
    for train in range(first_train, end_train):
        target_row = (step - dead_steps[train]) % slots
        for axle in range(n_axles):
            target = history[target_row, train, axle]
            pressure = pressure_bar[train, axle]
            gap = pressure - target
            stage_pressure_bar[0, train, axle] = pressure
            stage_pressure_bar[1, train, axle] = target + gap * half_lag[train]
            stage_pressure_bar[2, train, axle] = target + gap * full_lag[train]


@_compiled
def commanded_pressures(step, history, dead_steps, half_lag, full_lag, pressure_bar, command_bar, stage_pressure_bar):
    """The brake cylinders of :class:`~brakegym.simulator.pressure.CommandedPressure` over one step
    (the dead time and lag of spec Section 4, written once: the class calls this too): store
    ``command_bar`` (B, A) in the ring ``history`` at ``step``, and write the pressures at the
    start, middle and end of the step into ``stage_pressure_bar`` (3, B, A)."""
    _cylinders_over_step(
        step,
        0,
        command_bar.shape[0],
        history,
        dead_steps,
        half_lag,
        full_lag,
        pressure_bar,
        command_bar,
        stage_pressure_bar,
    )


@numba.njit(**JIT_OPTIONS)
def _fused_tiles(
    first_tile,
    end_tile,
    parameters,
    first_step,
    n_steps,
    step_s,
    power_coefficient,
    constants,
    friction_scale,
    extra_force_N,
    disc0,
    train0,
    moving0,
    hold_standing,
    cylinders,
    stage_pressure_bar,
    discs,
    trains,
    movings,
    stop_fraction,
    stop_time_s,
    clamp_N,
):
    """The steps of :func:`fused_rk4_steps` for the trains of tiles ``first_tile`` ...
    ``end_tile - 1``: each tile runs all ``n_steps`` before the next starts, and writes only its
    own trains' entries, so that tiles may run on different threads."""
    n_axles, per_axle, n_trains = disc0.shape[1], disc0.shape[2], disc0.shape[3]
    n_discs = n_axles * per_axle
    tile = min(TRAINS_PER_TILE, n_trains)
    slots = n_discs * tile
    disc_start = np.empty((N_DISC_STATES, slots))
    disc_stage = np.empty((N_DISC_STATES, slots))
    disc_end = np.empty((N_DISC_STATES, slots))
    disc_rates = np.empty((4, N_DISC_STATES, slots))
    train_start = np.empty((N_TRAIN_STATES, tile))
    train_end = np.empty((N_TRAIN_STATES, tile))
    train_rates = np.empty((4, N_TRAIN_STATES, tile))
    per_train = np.empty((N_TRAIN_CONSTANTS, tile))
    stage_speed = np.empty(tile)
    moving = np.empty(tile, dtype=np.bool_)
    axle_clamp_N = np.empty((3, n_axles * tile))
    axle_clamp_term = np.empty((3, n_axles * tile))
    slot_clamp_N = np.empty((3, slots))
    clamp_term = np.empty((3, slots))
    weighted_clamp_N = np.empty((3, tile))
    per_slot = np.empty((2, slots))  # power coefficient, ambient
    slot_friction_scale = np.empty((1, slots))
    tile_extra_force_N = np.empty((1, tile))
    # Separate arrays, not rows of one: LLVM vectorizes loops over distinct arrays (checking at
    # run time that they do not overlap) but not over rows of one array at unknown distances.
    train_work = (np.empty(tile), np.empty(tile), np.empty(tile), np.empty(tile))
    slot_work = (
        np.empty(slots),
        np.empty(slots),
        np.empty(slots),
        np.empty(slots),
        np.empty(slots),
        np.empty(slots),
        np.empty(slots),
        np.empty(slots),
        np.empty(slots),
        np.empty(slots),
    )
    history, dead_steps, half_lag, full_lag, cylinder_pressure_bar, command_bar = cylinders
    commanded = history.shape[0] > 0
    power_per_disc = power_coefficient.reshape(1, n_axles, per_axle, n_trains)
    friction_scale_per_disc = friction_scale.reshape(1, n_axles, per_axle, n_trains)
    extra_force_per_train = extra_force_N.reshape(1, n_trains)

    buffers = discs.shape[0]
    for tile_index in range(first_tile, end_tile):
        tile_start = tile_index * tile
        n_tile = min(tile, n_trains - tile_start)
        n_slots = n_discs * n_tile
        _gather_discs(power_per_disc, tile_start, n_tile, per_slot)
        _gather_discs(friction_scale_per_disc, tile_start, n_tile, slot_friction_scale)
        _gather_trains(extra_force_per_train, tile_start, n_tile, tile_extra_force_N)
        _gather_trains(constants, tile_start, n_tile, per_train)
        _per_slot(n_discs, n_tile, per_train[AMBIENT_K], per_slot[1])
        for n in range(n_steps):
            step = first_step + n
            time_s = step * step_s
            disc_in = disc0 if n == 0 else discs[(n - 1) % buffers]
            train_in = train0 if n == 0 else trains[(n - 1) % buffers]
            moving_in = moving0 if n == 0 else movings[(n - 1) % buffers]
            disc_out, train_out, moving_out = discs[n % buffers], trains[n % buffers], movings[n % buffers]
            first_pressure_row = 0
            if commanded:
                _cylinders_over_step(
                    step,
                    tile_start,
                    tile_start + n_tile,
                    history,
                    dead_steps,
                    half_lag,
                    full_lag,
                    cylinder_pressure_bar,
                    command_bar,
                    stage_pressure_bar,
                )
                for train in range(tile_start, tile_start + n_tile):
                    for axle in range(n_axles):
                        cylinder_pressure_bar[train, axle] = stage_pressure_bar[2, train, axle]
            else:
                first_pressure_row = 2 * n
            _gather_discs(disc_in, tile_start, n_tile, disc_start)
            _gather_trains(train_in, tile_start, n_tile, train_start)
            for t in range(n_tile):
                moving[t] = moving_in[tile_start + t]
                stage_speed[t] = train_start[SPEED, t]
            for moment in range(3):
                _clamp_of_tile(
                    parameters,
                    stage_pressure_bar[first_pressure_row + moment],
                    tile_start,
                    n_tile,
                    per_axle,
                    axle_clamp_N[moment],
                    axle_clamp_term[moment],
                    slot_clamp_N[moment],
                    clamp_term[moment],
                    weighted_clamp_N[moment],
                )
            if n == n_steps - 1:
                for axle in range(n_axles):
                    for t in range(n_tile):
                        clamp_N[0, axle, 0, tile_start + t] = axle_clamp_N[0, axle * n_tile + t]
                        clamp_N[1, axle, 0, tile_start + t] = axle_clamp_N[2, axle * n_tile + t]
            if hold_standing:
                tile_moves = False
                for t in range(n_tile):
                    tile_moves = tile_moves or moving[t]
                if not tile_moves:
                    # Every train of the tile held: the stage rates are not needed.
                    for t in range(n_tile):
                        stop_fraction[tile_start + t] = np.nan
                        moving_out[tile_start + t] = False
                    _scatter_discs(disc_start, tile_start, n_tile, disc_out)
                    for row in range(N_TRAIN_STATES):
                        for t in range(n_tile):
                            train_out[row, tile_start + t] = train_start[row, t]
                    continue

            # Stage s is evaluated at the state advanced by stage s - 1's rates, with the clamp
            # force of the start (s = 0), the middle (1, 2) or the end (3) of the step.
            for stage in range(4):
                moment = (stage + 1) // 2
                if stage == 0:
                    state = disc_start
                else:
                    fraction = step_s if stage == 3 else 0.5 * step_s
                    _advance_tile(
                        n_slots,
                        n_tile,
                        disc_start,
                        train_start,
                        disc_rates,
                        train_rates,
                        stage - 1,
                        fraction,
                        disc_stage,
                        stage_speed,
                    )
                    state = disc_stage
                _rates_of_tile(
                    parameters,
                    n_discs,
                    n_tile,
                    state,
                    stage_speed,
                    moving,
                    slot_clamp_N[moment],
                    clamp_term[moment],
                    weighted_clamp_N[moment],
                    slot_friction_scale[0],
                    tile_extra_force_N[0],
                    per_slot[0],
                    per_slot[1],
                    per_train,
                    disc_rates,
                    train_rates,
                    stage,
                    train_work,
                    slot_work,
                )
            _finish_tile(
                parameters,
                time_s,
                step_s,
                tile_start,
                n_discs,
                n_tile,
                disc_start,
                train_start,
                disc_rates,
                train_rates,
                moving,
                hold_standing,
                disc_end,
                train_end,
                stop_fraction,
                stop_time_s,
                moving_out,
            )
            _scatter_discs(disc_end, tile_start, n_tile, disc_out)
            for row in range(N_TRAIN_STATES):
                for t in range(n_tile):
                    train_out[row, tile_start + t] = train_end[row, t]


@numba.njit(**JIT_OPTIONS)
def _tiles(n_trains):
    """How many tiles ``n_trains`` trains take."""
    return -(-n_trains // TRAINS_PER_TILE)


@_compiled
def fused_rk4_steps(
    parameters,
    first_step,
    n_steps,
    step_s,
    power_coefficient,
    constants,
    friction_scale,
    extra_force_N,
    disc0,
    train0,
    moving0,
    hold_standing,
    cylinders,
    stage_pressure_bar,
    discs,
    trains,
    movings,
    stop_fraction,
    stop_time_s,
    clamp_N,
):
    """``n_steps`` RK4 steps of every train, with extension hooks only where they are constant
    (a friction scale per disc ``friction_scale`` (A, k, B), an extra retarding force per train
    ``extra_force_N`` (B,)), in one call.

    Reads the states ``disc0`` (6, A, k, B), ``train0`` (6, B), ``moving0`` (B,). The cylinder
    pressures come from ``cylinders``, a :class:`~.state.CylinderState` (a ``CommandedPressure``'s),
    which the steps advance in place (its pressure too); or, where its history is empty (H = 0),
    from ``stage_pressure_bar`` (2 n_steps + 1, B, A), the prescribed pressures at every half step
    (step n at rows 2n, 2n + 1, 2n + 2: its start, middle and end). Step n writes the states
    ``discs[n % S]``, ``trains[n % S]``, ``movings[n % S]`` for S buffers (two to keep only the
    last state, one for a single step, ``n_steps`` to keep every step's), and
    the last step the stop fraction (nan if none) and the clamp forces at its start and end into
    ``clamp_N`` (2, A, 1, B); sets ``stop_time_s`` of the trains that stop. Time is
    ``(first_step + n) * step_s`` at the start of step n, as the simulator counts it. With
    ``hold_standing`` a train standing still at the start of a step keeps its state (a tile of
    standing trains is not integrated at all)."""
    _fused_tiles(
        0,
        _tiles(disc0.shape[3]),
        parameters,
        first_step,
        n_steps,
        step_s,
        power_coefficient,
        constants,
        friction_scale,
        extra_force_N,
        disc0,
        train0,
        moving0,
        hold_standing,
        cylinders,
        stage_pressure_bar,
        discs,
        trains,
        movings,
        stop_fraction,
        stop_time_s,
        clamp_N,
    )


@_compiled_threaded
def fused_rk4_steps_threaded(
    n_threads,
    parameters,
    first_step,
    n_steps,
    step_s,
    power_coefficient,
    constants,
    friction_scale,
    extra_force_N,
    disc0,
    train0,
    moving0,
    hold_standing,
    cylinders,
    stage_pressure_bar,
    discs,
    trains,
    movings,
    stop_fraction,
    stop_time_s,
    clamp_N,
):
    """:func:`fused_rk4_steps` with the tiles shared out over ``n_threads`` threads, each a
    consecutive run of tiles. A train's arithmetic is the same whichever thread runs it."""
    n_tiles = _tiles(disc0.shape[3])
    for thread in numba.prange(n_threads):
        _fused_tiles(
            thread * n_tiles // n_threads,
            (thread + 1) * n_tiles // n_threads,
            parameters,
            first_step,
            n_steps,
            step_s,
            power_coefficient,
            constants,
            friction_scale,
            extra_force_N,
            disc0,
            train0,
            moving0,
            hold_standing,
            cylinders,
            stage_pressure_bar,
            discs,
            trains,
            movings,
            stop_fraction,
            stop_time_s,
            clamp_N,
        )


# The most threads fused_steps() uses: numba's count (NUMBA_NUM_THREADS, all cores by default)
# until set_kernel_threads() says otherwise. Campaign workers run with 1: they are forked processes
# that already share the cores, and a thread pool does not survive a fork.
_max_threads = numba.config.NUMBA_NUM_THREADS


def set_kernel_threads(n_threads: int) -> None:
    """Let the fused kernel use at most ``n_threads`` threads in this process (1: a single
    core). Results are the same bit for bit whatever the count."""
    global _max_threads
    if not 1 <= n_threads <= numba.config.NUMBA_NUM_THREADS:
        raise ValueError(f"kernel threads {n_threads}: need 1 ... {numba.config.NUMBA_NUM_THREADS} (NUMBA_NUM_THREADS)")
    _max_threads = n_threads


def kernel_threads() -> int:
    """The most threads the fused kernel uses in this process."""
    return _max_threads


def fused_steps(*arguments) -> None:
    """:func:`fused_rk4_steps` (same arguments) on one thread per tile of trains, at most
    :func:`kernel_threads`: a batch of one tile runs on the calling thread."""
    n_threads = min(_max_threads, int(_tiles(arguments[8].shape[3])))
    if n_threads > 1:
        fused_rk4_steps_threaded(n_threads, *arguments)
    else:
        fused_rk4_steps(*arguments)


@_compiled
def stage_rates(
    parameters,
    disc,
    train,
    moving0,
    pressure_bar,
    friction_scale,
    extra_force_N,
    power_coefficient,
    constants,
    disc_rates,
    train_rates,
):
    """Rates of one RK4 stage for the simulator with hooks: states ``disc`` (6, A, k, B) and
    ``train`` (6, B), the stage's cylinder pressures (B, A), the hooks' friction scale (A, k, B)
    and extra force (B,), the per-train ``constants`` (N_TRAIN_CONSTANTS, B); writes
    ``disc_rates`` (6, A, k, B) and ``train_rates`` (6, B)."""
    n_axles, per_axle, n_trains = disc.shape[1], disc.shape[2], disc.shape[3]
    n_discs = n_axles * per_axle
    tile = min(TRAINS_PER_TILE, n_trains)
    slots = n_discs * tile
    state = np.empty((N_DISC_STATES, slots))
    rates = np.empty((1, N_DISC_STATES, slots))
    train_of_tile = np.empty((N_TRAIN_STATES, tile))
    rates_of_train = np.empty((1, N_TRAIN_STATES, tile))
    per_train = np.empty((N_TRAIN_CONSTANTS, tile))
    extra_of_tile = np.empty(tile)
    moving = np.empty(tile, dtype=np.bool_)
    axle_clamp_N = np.empty(n_axles * tile)
    axle_clamp_term = np.empty(n_axles * tile)
    clamp_N = np.empty(slots)
    clamp_term = np.empty(slots)
    weighted_clamp_N = np.empty(tile)
    per_slot = np.empty((3, slots))  # power coefficient, friction scale, ambient
    train_work = (np.empty(tile), np.empty(tile), np.empty(tile), np.empty(tile))
    slot_work = (
        np.empty(slots),
        np.empty(slots),
        np.empty(slots),
        np.empty(slots),
        np.empty(slots),
        np.empty(slots),
        np.empty(slots),
        np.empty(slots),
        np.empty(slots),
        np.empty(slots),
    )
    per_disc = np.empty((2, n_axles, per_axle, n_trains))
    per_disc[0] = power_coefficient
    per_disc[1] = friction_scale
    for tile_start in range(0, n_trains, tile):
        n_tile = min(tile, n_trains - tile_start)
        _gather_discs(disc, tile_start, n_tile, state)
        _gather_trains(train, tile_start, n_tile, train_of_tile)
        _gather_discs(per_disc, tile_start, n_tile, per_slot)
        _gather_trains(constants, tile_start, n_tile, per_train)
        _per_slot(n_discs, n_tile, per_train[AMBIENT_K], per_slot[2])
        for t in range(n_tile):
            moving[t] = moving0[tile_start + t]
            extra_of_tile[t] = extra_force_N[tile_start + t]
        _clamp_of_tile(
            parameters,
            pressure_bar,
            tile_start,
            n_tile,
            per_axle,
            axle_clamp_N,
            axle_clamp_term,
            clamp_N,
            clamp_term,
            weighted_clamp_N,
        )
        _rates_of_tile(
            parameters,
            n_discs,
            n_tile,
            state,
            train_of_tile[SPEED],
            moving,
            clamp_N,
            clamp_term,
            weighted_clamp_N,
            per_slot[1],
            extra_of_tile,
            per_slot[0],
            per_slot[2],
            per_train,
            rates,
            rates_of_train,
            0,
            train_work,
            slot_work,
        )
        _scatter_discs(rates[0], tile_start, n_tile, disc_rates)
        for row in range(N_TRAIN_STATES):
            for t in range(n_tile):
                train_rates[row, tile_start + t] = rates_of_train[0, row, t]


@_compiled
def finish_rk4_step(
    parameters,
    time_s,
    step_s,
    disc0,
    train0,
    moving0,
    hold_standing,
    disc_stage_rates,
    train_stage_rates,
    disc1,
    train1,
    moving1,
    stop_fraction,
    stop_time_s,
):
    """The end of a staged step: the four stages' rates (4, 6, A, k, B) and (4, 6, B) combined
    as in :func:`fused_rk4_steps`, with the same stop interpolation and ``hold_standing``."""
    n_axles, per_axle, n_trains = disc0.shape[1], disc0.shape[2], disc0.shape[3]
    n_discs = n_axles * per_axle
    tile = min(TRAINS_PER_TILE, n_trains)
    slots = n_discs * tile
    disc_start = np.empty((N_DISC_STATES, slots))
    disc_end = np.empty((N_DISC_STATES, slots))
    disc_rates = np.empty((4, N_DISC_STATES, slots))
    train_start = np.empty((N_TRAIN_STATES, tile))
    train_end = np.empty((N_TRAIN_STATES, tile))
    train_rates = np.empty((4, N_TRAIN_STATES, tile))
    moving = np.empty(tile, dtype=np.bool_)
    all_disc_rates = disc_stage_rates.reshape(4 * N_DISC_STATES, n_axles, per_axle, n_trains)
    all_train_rates = train_stage_rates.reshape(4 * N_TRAIN_STATES, n_trains)
    for tile_start in range(0, n_trains, tile):
        n_tile = min(tile, n_trains - tile_start)
        _gather_discs(disc0, tile_start, n_tile, disc_start)
        _gather_trains(train0, tile_start, n_tile, train_start)
        _gather_discs(all_disc_rates, tile_start, n_tile, disc_rates.reshape(4 * N_DISC_STATES, slots))
        _gather_trains(all_train_rates, tile_start, n_tile, train_rates.reshape(4 * N_TRAIN_STATES, tile))
        for t in range(n_tile):
            moving[t] = moving0[tile_start + t]
        _finish_tile(
            parameters,
            time_s,
            step_s,
            tile_start,
            n_discs,
            n_tile,
            disc_start,
            train_start,
            disc_rates,
            train_rates,
            moving,
            hold_standing,
            disc_end,
            train_end,
            stop_fraction,
            stop_time_s,
            moving1,
        )
        _scatter_discs(disc_end, tile_start, n_tile, disc1)
        for row in range(N_TRAIN_STATES):
            for t in range(n_tile):
                train1[row, tile_start + t] = train_end[row, t]


@_compiled
def deceleration_mps2(parameters, disc, train, moving, clamp_N, friction_scale, extra_force_N, constants, out):
    """Deceleration of each train at the given state (positive while slowing, 0 at standstill):
    the forces of ``_rates_of_tile`` without the rates. ``clamp_N`` is (A, 1, B)."""
    n_axles, per_axle, n_trains = disc.shape[1], disc.shape[2], disc.shape[3]
    mu_min, mu_max = parameters[MU_MIN], parameters[MU_MAX]
    for train_index in range(n_trains):
        friction_sum = 0.0
        for axle in range(n_axles):
            for k in range(per_axle):
                mu = bounded_mu(disc[MU, axle, k, train_index], mu_min, mu_max)
                friction_sum += mu * friction_scale[axle, k, train_index] * clamp_N[axle, 0, train_index]
        speed = train[SPEED, train_index]
        resistance = running_resistance_N(
            speed,
            constants[RESISTANCE_A_N, train_index],
            constants[RESISTANCE_B_N_PER_MPS, train_index],
            constants[RESISTANCE_C_N_PER_MPS2, train_index],
        )
        total = friction_sum * parameters[RADIUS_RATIO] + resistance + extra_force_N[train_index]
        out[train_index] = choose(moving[train_index], total * constants[INVERSE_MASS_PER_KG, train_index], 0.0)


def warm_up(n_axles: int = 1, discs_per_axle: int = 1) -> None:
    """Load (or, the first time on a machine, compile) every kernel in this process, by running
    each once on a single stationary train.

    Campaigns call it before forking their workers: the workers then inherit the loaded code
    instead of each paying numba's start-up and the cache load (seconds)."""
    disc = np.zeros((N_DISC_STATES, n_axles, discs_per_axle, 1))
    disc[MU] = 0.35
    disc[T_FRIC] = disc[T_DISC] = 293.15
    train = np.zeros((N_TRAIN_STATES, 1))
    moving = np.zeros(1, dtype=np.bool_)
    per_train = np.ones(1)
    constants = np.ones((N_TRAIN_CONSTANTS, 1))
    per_disc = np.ones((n_axles, discs_per_axle, 1))
    pressure = np.zeros((1, n_axles))
    clamp = np.zeros((n_axles, 1, 1))
    parameters = np.ones(N_PLANT_PARAMETERS)
    steps = 2
    discs, trains = np.empty((2, *disc.shape)), np.empty((2, *train.shape))
    movings = np.empty((2, 1), dtype=np.bool_)
    stop_fraction, stop_time = np.empty(1), np.full(1, np.nan)
    for history_length in (0, 2):  # given stage pressures, and the commanded cylinders
        cylinders = CylinderState(
            np.zeros((history_length, 1, n_axles)),
            np.zeros(1, dtype=np.int64),
            per_train,
            per_train,
            pressure.copy(),
            pressure.copy(),
        )
        fused_rk4_steps(
            parameters,
            0,
            steps,
            0.1,
            per_disc,
            constants,
            per_disc,
            np.zeros(1),
            disc,
            train,
            moving,
            False,
            cylinders,
            np.zeros((3, 1, n_axles)),
            discs,
            trains,
            movings,
            stop_fraction,
            stop_time,
            np.zeros((2, n_axles, 1, 1)),
        )
    disc_rates, train_rates = np.empty((4, *disc.shape)), np.empty((4, *train.shape))
    for stage in range(4):
        stage_rates(
            parameters,
            disc,
            train,
            moving,
            pressure,
            per_disc,
            per_train,
            per_disc,
            constants,
            disc_rates[stage],
            train_rates[stage],
        )
    finish_rk4_step(
        parameters,
        0.0,
        0.1,
        disc,
        train,
        moving,
        False,
        disc_rates,
        train_rates,
        discs[0],
        trains[0],
        movings[0],
        stop_fraction,
        stop_time,
    )
    deceleration_mps2(parameters, disc, train, moving, clamp, per_disc, per_train, constants, np.empty(1))


__all__ = [
    "commanded_pressures",
    "fused_steps",
    "kernel_threads",
    "set_kernel_threads",
    "deceleration_mps2",
    "finish_rk4_step",
    "fused_rk4_steps",
    "fused_rk4_steps_threaded",
    "plant_parameters",
    "stage_rates",
    "warm_up",
]
