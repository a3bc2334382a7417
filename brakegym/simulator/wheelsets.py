"""The simulator with wheel-rail adhesion: each wheelset turns on its own and creeps on the rail
(docs/adhesion.md; issue 16). An option, off by default: :class:`AdhesionSimulator` is a separate
path in numpy, so :class:`~.integrator.Simulator` and its compiled kernel are untouched.

Per step of h: the disc states (mu, temperatures, heat integrals) and the disc friction work by
RK4, as without adhesion but with each axle's sliding speed omega r_fric; the wheelsets and the
train speed in n substeps by the linearly implicit Euler method, whose Jacobian (an arrow: each
wheel speed couples only to the train speed) is solved by a Schur complement. The substeps give
the RK4 stages the wheel speeds at t, t + h/2 and t + h. docs/adhesion.md says why.

Wheel speeds are kept as u = omega r (m/s) inside; :data:`WHEELSET_STATES` names the rows of
:attr:`AdhesionSimulator.wheelset`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..physics import PolachLaw, RailSections, RunningResistanceLaw, WheelRailContact
from ..physics.adhesion import creep
from ..physics.mechanics import effective_mu
from ..units import STANDARD_GRAVITY_MPS2
from .integrator import Simulator, StepRecord
from .plant import BatchConditions, Plant
from .pressure import PressureSource
from .state import (
    BRAKE_WORK,
    COOLING_HEAT,
    FRICTION_HEAT,
    MU,
    MU_DISTANCE,
    MU_EFF_DISTANCE,
    POSITION,
    RESISTANCE_WORK,
    SPEED,
    T_DISC,
    T_FRIC,
)

# Rows of the packed per-axle state (rows, axles, trains).
WHEELSET_STATES = (
    "angular_speed_rad_per_s",  # omega of the wheelset
    "slip_work_J",  # integral of F_creep (v - omega r) dt: the work of the treads sliding on the rail
)
ANGULAR_SPEED, SLIP_WORK = range(len(WHEELSET_STATES))

#: Below this train speed the creep divides by it instead of v (ASSUMED, docs/adhesion.md).
DEFAULT_REGULARISATION_SPEED_MPS = 0.5
#: Longest wheelset substep (docs/adhesion.md: converged to 0.5 % against a tenth of it).
DEFAULT_MAX_SUBSTEP_S = 0.01


@dataclass(frozen=True)
class WheelRailAdhesion:
    """What the adhesion option adds to a plant: the rail's creep-force law (one for the whole
    line, or :class:`~brakegym.physics.adhesion.RailSections`), the wheels' contact, the inertia
    of each wheelset about its axis, the creep's regularisation speed, the longest wheelset
    substep, and how far behind the train's position each axle runs (m, one per axle; all at the
    train's position if not given), which decides when each axle enters a section."""

    law: PolachLaw | RailSections
    contact: WheelRailContact
    wheelset_inertia_kgm2: float
    regularisation_speed_mps: float = DEFAULT_REGULARISATION_SPEED_MPS
    max_substep_s: float = DEFAULT_MAX_SUBSTEP_S
    axle_offsets_m: tuple[float, ...] | None = None

    def law_at(self, position_m: np.ndarray) -> PolachLaw:
        """The creep-force law under each axle, train positions ``position_m`` (B,): the law
        itself on a uniform rail, else parameter arrays (A, B)."""
        if isinstance(self.law, PolachLaw):
            return self.law
        offsets = np.zeros(1) if self.axle_offsets_m is None else np.asarray(self.axle_offsets_m)
        return self.law.law_at(position_m[None, :] - offsets[:, None])

    def substeps(self, step_s: float) -> int:
        """Substeps per step: an even number (the RK4 stages need the middle), none longer than
        ``max_substep_s``."""
        n = math.ceil(step_s / self.max_substep_s - 1e-9)
        return n + (n % 2)


@dataclass
class _Substeps:
    """The trajectory of the fast states over one step, as the disc RK4 needs it."""

    wheel_speed_mps: np.ndarray  # (3, A, B): at t, t + h/2, t + h
    speed_mps: np.ndarray  # (3, B)
    train_end: np.ndarray  # train rows at t + h (the disc work row still to add)
    slip_work_end_J: np.ndarray  # (A, B)
    stop_fraction: np.ndarray  # (B,), nan where no train stopped


class AdhesionSimulator(Simulator):
    """:class:`~.integrator.Simulator` with wheel-rail adhesion (docs/adhesion.md), in numpy.

    The train mass of the conditions is the paper's effective mass, with the wheelsets' rotation
    in it; here the wheelsets carry their inertia themselves and the body mass is
    m - n_axles J / r^2. Each wheel presses on the rail with the static share of the weight. No
    extension hooks. The wheelsets start rolling with the train.
    """

    def __init__(
        self,
        plant: Plant,
        conditions: BatchConditions,
        pressure: PressureSource,
        adhesion: WheelRailAdhesion,
        step_s: float = 0.1,
        nominal_running_resistance: RunningResistanceLaw | None = None,
    ) -> None:
        super().__init__(plant, conditions, pressure, step_s, nominal_running_resistance=nominal_running_resistance)
        self.adhesion = adhesion
        self.n_substeps = adhesion.substeps(self.step_s)
        self.wheelset_mass_kg = adhesion.wheelset_inertia_kgm2 / plant.wheel_radius_m**2
        self.wheelset = np.zeros((len(WHEELSET_STATES), plant.n_axles, self.n_trains))
        self._set_train_loads(np.arange(self.n_trains))

    def _set_train_loads(self, index: np.ndarray) -> None:
        """Body mass, wheel loads and wheel speeds of the trains ``index`` from their mass and
        speed."""
        plant = self.plant
        if not hasattr(self, "body_mass_kg"):
            self.body_mass_kg = np.empty(self.n_trains)
            self.wheel_load_N = np.empty(self.n_trains)
            self.creep_stiffness_N = np.empty(self.n_trains)
        body = self.mass_kg[index] - plant.n_axles * self.wheelset_mass_kg
        if np.any(body <= 0):
            raise ValueError(
                f"wheelset inertia {self.adhesion.wheelset_inertia_kgm2} kg m^2 on {plant.n_axles} axles "
                f"outweighs a train mass of {self.mass_kg[index].min()} kg"
            )
        self.body_mass_kg[index] = body
        self.wheel_load_N[index] = self.mass_kg[index] * STANDARD_GRAVITY_MPS2 / (2 * plant.n_axles)
        self.creep_stiffness_N[index] = self.adhesion.contact.creep_stiffness_N(self.wheel_load_N[index])
        self.wheelset[:, :, index] = 0.0
        self.wheelset[ANGULAR_SPEED][:, index] = self.train[SPEED, index] / plant.wheel_radius_m

    def reset_trains(self, index: np.ndarray, conditions: BatchConditions) -> None:
        super().reset_trains(index, conditions)
        self._set_train_loads(np.asarray(index, dtype=np.int64))

    @property
    def has_hooks(self) -> bool:
        return False

    @property
    def wheel_speed_mps(self) -> np.ndarray:
        """omega r of each axle (A, B)."""
        return self.wheelset[ANGULAR_SPEED] * self.plant.wheel_radius_m

    # ----------------------------------------------------------------------------------------
    # Forces

    def creep_force_N(self, speed_mps: np.ndarray, wheel_speed_mps: np.ndarray, law: PolachLaw) -> np.ndarray:
        """Force of each axle's two wheels on the rail (A, B), retarding the train when the wheel
        turns slower than it runs; ``law`` from :meth:`WheelRailAdhesion.law_at`."""
        slip = speed_mps - wheel_speed_mps
        s = creep(speed_mps, wheel_speed_mps, self.adhesion.regularisation_speed_mps)
        return 2.0 * law.creep_force_N(s, slip, self.wheel_load_N, self.creep_stiffness_N)

    def _creep_force_and_slope(self, speed_mps: np.ndarray, wheel_speed_mps: np.ndarray, law: PolachLaw):
        """The axle forces (A, B) and their slope dF/ds at fixed friction (A, B), N per unit creep."""
        slip = speed_mps - wheel_speed_mps
        s = creep(speed_mps, wheel_speed_mps, self.adhesion.regularisation_speed_mps)
        force = 2.0 * law.creep_force_N(s, slip, self.wheel_load_N, self.creep_stiffness_N)
        slope = (
            2.0
            * self.wheel_load_N
            * law.creep_slope_at_fixed_friction(s, slip, self.wheel_load_N, self.creep_stiffness_N)
        )
        return force, slope

    def _brake_force_at_wheel_N(self, mu: np.ndarray, clamp_force_N: np.ndarray) -> np.ndarray:
        """sum over each axle's discs of mu F_C r_fric / r (A, B): the brake torque over the
        wheel radius."""
        return (mu * clamp_force_N).sum(axis=1) * self.plant.radius_ratio

    # ----------------------------------------------------------------------------------------
    # The disc states: RK4 over the step

    def _disc_rates(
        self, disc: np.ndarray, wheel_speed_mps: np.ndarray, speed_mps: np.ndarray, clamp_force_N: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """d/dt of the packed disc states and the disc friction power of each train (B,), the
        discs sliding at their own wheel's speed."""
        plant = self.plant
        sliding = (np.maximum(wheel_speed_mps, 0.0) * plant.radius_ratio)[:, None, :]
        mu = plant.friction.bounded(disc[MU])
        friction_power = mu * clamp_force_N * sliding
        flows = plant.thermal.heat_flows(friction_power, disc[T_FRIC], disc[T_DISC], sliding, self.ambient_K)
        rates = np.empty_like(disc)
        rates[MU] = plant.friction.rate_of_bounded_mu_per_s(
            mu, clamp_force_N, sliding, disc[T_FRIC], self.power_coefficient
        )
        rates[T_FRIC], rates[T_DISC] = plant.thermal.temperature_rates_K_per_s(flows)
        rates[MU_DISTANCE] = mu * speed_mps
        rates[FRICTION_HEAT] = flows.friction_W
        rates[COOLING_HEAT] = flows.surface_W + flows.ventilation_W
        return rates, friction_power.sum(axis=(0, 1))

    def _step_once(self) -> StepRecord:
        h, t = self.step_s, self.time_s
        pressures = self.pressure.stage_pressures_bar()
        f_start, f_mid, f_end = (self.clamp_force_N(p) for p in pressures)
        disc0, train0, moving0 = self.disc, self.train, self.moving
        held = ~moving0 if self.hold_standing_trains else np.zeros_like(moving0)

        k1, power1 = self._disc_rates(disc0, self.wheel_speed_mps, train0[SPEED], f_start)
        fast = self._substeps(k1[MU], pressures)
        u, v = fast.wheel_speed_mps, fast.speed_mps
        k2, power2 = self._disc_rates(disc0 + 0.5 * h * k1, u[1], v[1], f_mid)
        k3, power3 = self._disc_rates(disc0 + 0.5 * h * k2, u[1], v[1], f_mid)
        k4, power4 = self._disc_rates(disc0 + h * k3, u[2], v[2], f_end)
        disc_change = (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
        disc_work = (h / 6.0) * (power1 + 2.0 * (power2 + power3) + power4)
        # A train that stopped inside the step ends there: its discs are taken to the stop instant
        # (as the simulator without adhesion does), the disc work alike.
        share = np.where(np.isnan(fast.stop_fraction), 1.0, fast.stop_fraction)
        disc1 = disc0 + share * disc_change
        disc1[MU] = self.plant.friction.bounded(disc1[MU])
        train1 = fast.train_end
        train1[BRAKE_WORK] = train0[BRAKE_WORK] + share * disc_work
        wheelset1 = np.empty_like(self.wheelset)
        wheelset1[ANGULAR_SPEED] = u[2] / self.plant.wheel_radius_m
        wheelset1[SLIP_WORK] = fast.slip_work_end_J

        disc1[..., held] = disc0[..., held]
        train1[:, held] = train0[:, held]
        wheelset1[..., held] = self.wheelset[..., held]
        self.wheelset = wheelset1
        stopping = ~np.isnan(fast.stop_fraction)
        self.stop_time_s[stopping] = t + fast.stop_fraction[stopping] * h
        record = StepRecord(t, disc0, train0, f_start, f_end, fast.stop_fraction)
        return self.finish_step(record, disc1, train1, moving0 & ~stopping)

    def step(self, n_steps: int = 1) -> StepRecord:
        """Advance every train by ``n_steps`` steps, one at a time."""
        if n_steps < 1:
            raise ValueError(f"n_steps = {n_steps}: must be at least 1")
        for _ in range(n_steps):
            record = self._step_once()
        return record

    def trajectory(self, n_steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self._trajectory_stepwise(n_steps)

    # ----------------------------------------------------------------------------------------
    # The wheelsets and the train: linearly implicit substeps

    def _substeps(self, mu_rate_per_s: np.ndarray, pressures) -> _Substeps:
        """The wheel speeds, the train speed and the train integrals over the coming step, in
        :attr:`n_substeps` linearly implicit Euler substeps. The brake torque takes mu
        extrapolated with its rate at the step's start and the cylinder pressures interpolated
        (quadratically) through the step's start, middle and end."""
        h, n = self.step_s, self.n_substeps
        delta = h / n
        train = self.train.copy()
        u = self.wheel_speed_mps.copy()
        slip_work = self.wheelset[SLIP_WORK].copy()
        active = self.moving.copy()
        mu0 = self.plant.friction.bounded(self.disc[MU])
        p_start, p_mid, p_end = pressures
        wheel_speeds = np.empty((3, *u.shape))
        speeds = np.empty((3, self.n_trains))
        wheel_speeds[0], speeds[0] = u, train[SPEED]
        stop_fraction = np.full(self.n_trains, np.nan)
        law = self.adhesion.law_at(train[POSITION])
        powers = self._substep_powers(train[SPEED], u, p_start, law)
        for j in range(n):
            tau = (j + 1) * delta / h  # the substep's end, as a fraction of the step
            pressure = (
                p_start + tau * (4.0 * p_mid - 3.0 * p_start - p_end) + tau**2 * 2.0 * (p_start + p_end - 2.0 * p_mid)
            )
            brake_N = self._brake_force_at_wheel_N(mu0 + (tau * h) * mu_rate_per_s, self.clamp_force_N(pressure))
            v0 = train[SPEED].copy()
            u_new, v_new = self._linearly_implicit_update(v0, u, brake_N, delta, law)
            stops = active & (v_new <= 0.0)
            theta = np.where(stops, v0 / np.where(stops, v0 - v_new, 1.0), 1.0)
            v_new = np.where(stops, 0.0, v_new)
            u_new = np.where(stops, 0.0, u_new)
            weight = np.where(active, 0.5 * delta * theta, 0.0)
            train[POSITION] += weight * (v0 + v_new)
            law = self.adhesion.law_at(train[POSITION])
            new_powers = self._substep_powers(v_new, u_new, pressure, law)
            train[RESISTANCE_WORK] += weight * (powers["resistance"] + new_powers["resistance"])
            train[MU_EFF_DISTANCE] += weight * (powers["mu_eff"] + new_powers["mu_eff"])
            slip_work += weight * (powers["slip"] + new_powers["slip"])
            train[SPEED] = np.where(active, v_new, train[SPEED])
            u = np.where(active, u_new, u)
            stop_fraction = np.where(stops, (j + theta) / n, stop_fraction)
            active &= ~stops
            powers = new_powers
            if 2 * (j + 1) == n:
                wheel_speeds[1], speeds[1] = u, train[SPEED]
        wheel_speeds[2], speeds[2] = u, train[SPEED]
        return _Substeps(wheel_speeds, speeds, train, slip_work, stop_fraction)

    def _substep_powers(
        self, speed_mps: np.ndarray, wheel_speed_mps: np.ndarray, pressure_bar: np.ndarray, law: PolachLaw
    ) -> dict:
        """The integrands the substeps sum by the trapezoid rule: slip power per axle (A, B),
        resistance power and mu_eff v (B,)."""
        force = self.creep_force_N(speed_mps, wheel_speed_mps, law)
        resistance = self.plant.running_resistance.force_N(speed_mps, self.resistance_A_N)
        # Eq. 15 with m d, m the effective mass, d the body's deceleration.
        retarding = self.mass_kg * (force.sum(axis=0) + resistance) / self.body_mass_kg
        weighted_clamp = self.clamp_force_N(pressure_bar).sum(axis=(0, 1)) * (
            self.plant.discs_per_axle * self.plant.radius_ratio
        )
        nominal = self.nominal_running_resistance.force_N(speed_mps)
        return {
            "slip": force * (speed_mps - wheel_speed_mps),
            "resistance": resistance * speed_mps,
            "mu_eff": effective_mu(retarding, nominal, weighted_clamp) * speed_mps,
        }

    def _linearly_implicit_update(
        self,
        speed_mps: np.ndarray,
        wheel_speed_mps: np.ndarray,
        brake_force_N: np.ndarray,
        delta_s: float,
        law: PolachLaw,
    ) -> tuple[np.ndarray, np.ndarray]:
        """One linearly implicit Euler substep of the wheel speeds u (A, B) and the train speed v
        (B,): (I - delta J) dy = delta f(y). The Jacobian J is the arrow of the creep forces'
        slope at fixed friction (the falling friction, slow, stays explicit); a wheel that would
        turn backwards is locked by its brake (u = 0)."""
        plant, adhesion = self.plant, self.adhesion
        force, slope = self._creep_force_and_slope(speed_mps, wheel_speed_mps, law)
        scaled_speed = np.maximum(speed_mps, adhesion.regularisation_speed_mps)
        # ds/dv: 1 / v_reg below the regularisation speed, u / v^2 above it.
        creep_per_speed = np.where(
            speed_mps > adhesion.regularisation_speed_mps, wheel_speed_mps / scaled_speed**2, 1.0 / scaled_speed
        )
        wheel_rate = (force - brake_force_N) / self.wheelset_mass_kg
        resistance = plant.running_resistance.force_N(speed_mps, self.resistance_A_N)
        train_rate = -(force.sum(axis=0) + resistance) / self.body_mass_kg
        wheel_by_wheel = -slope / (scaled_speed * self.wheelset_mass_kg)  # <= 0
        wheel_by_train = slope * creep_per_speed / self.wheelset_mass_kg
        train_by_wheel = slope / (scaled_speed * self.body_mass_kg)
        resistance_slope = (
            plant.running_resistance.B_N_per_mps + 2.0 * plant.running_resistance.C_N_per_mps2 * speed_mps
        )
        train_by_train = -((slope * creep_per_speed).sum(axis=0) + resistance_slope) / self.body_mass_kg
        wheel_pivot = 1.0 - delta_s * wheel_by_wheel
        schur = (
            1.0 - delta_s * train_by_train - delta_s**2 * (train_by_wheel * wheel_by_train / wheel_pivot).sum(axis=0)
        )
        train_change = (
            delta_s * train_rate + delta_s**2 * (train_by_wheel * wheel_rate / wheel_pivot).sum(axis=0)
        ) / schur
        wheel_change = delta_s * (wheel_rate + wheel_by_train * train_change) / wheel_pivot
        return np.maximum(wheel_speed_mps + wheel_change, 0.0), speed_mps + train_change

    # ----------------------------------------------------------------------------------------
    def deceleration_mps2(self) -> np.ndarray:
        """The train body's deceleration at the current state, m/s^2 (0 standing)."""
        law = self.adhesion.law_at(self.train[POSITION])
        force = self.creep_force_N(self.train[SPEED], self.wheel_speed_mps, law).sum(axis=0)
        resistance = self.plant.running_resistance.force_N(self.train[SPEED], self.resistance_A_N)
        return np.where(self.moving, (force + resistance) / self.body_mass_kg, 0.0)

    def kinetic_energy_J(self) -> np.ndarray:
        """1/2 M v^2 + sum over the wheelsets of 1/2 J omega^2, per train."""
        wheels = 0.5 * self.adhesion.wheelset_inertia_kgm2 * (self.wheelset[ANGULAR_SPEED] ** 2).sum(axis=0)
        return 0.5 * self.body_mass_kg * self.train[SPEED] ** 2 + wheels
