"""The simulator with wheel-rail adhesion in numpy: readable, slow, and what the compiled kernel
(:mod:`.wheelset_kernel`) is tested and benchmarked against, as :mod:`.reference` is for the
simulator without adhesion. The scheme is docs/adhesion.md's; :class:`NumpyAdhesionSimulator` has
the interface and, within round-off, the results of :class:`~.wheelsets.AdhesionSimulator`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..physics import PolachLaw
from ..physics.adhesion import creep
from ..physics.mechanics import effective_mu
from .integrator import StepRecord
from .state import (
    ANGULAR_SPEED,
    BRAKE_WORK,
    COOLING_HEAT,
    FRICTION_HEAT,
    MU,
    MU_DISTANCE,
    MU_EFF_DISTANCE,
    POSITION,
    RESISTANCE_WORK,
    SLIP_WORK,
    SPEED,
    T_DISC,
    T_FRIC,
)
from .wheelsets import AdhesionSimulator


@dataclass
class _Substeps:
    """The trajectory of the fast states over one step, as the disc RK4 needs it."""

    wheel_speed_mps: np.ndarray  # (3, A, B): at t, t + h/2, t + h
    speed_mps: np.ndarray  # (3, B)
    train_end: np.ndarray  # train rows at t + h (the disc work row still to add)
    slip_work_end_J: np.ndarray  # (A, B)
    stop_fraction: np.ndarray  # (B,), nan where no train stopped


class NumpyAdhesionSimulator(AdhesionSimulator):
    """:class:`~.wheelsets.AdhesionSimulator` stepped in numpy array operations (without load
    transfer: the compiled kernel alone has it)."""

    def __init__(self, plant, conditions, pressure, adhesion, *args, **kwargs) -> None:
        if adhesion.load_transfer is not None:
            raise ValueError(
                "NumpyAdhesionSimulator: load transfer is not in the numpy reference; use AdhesionSimulator"
            )
        super().__init__(plant, conditions, pressure, adhesion, *args, **kwargs)

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
        law = self.rail_law_at(train[POSITION])
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
            law = self.rail_law_at(train[POSITION])
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
        slope at fixed friction (the falling friction, slow, stays explicit), raised to the secant
        F / s where the wheel would cross the train's speed within the substep; a wheel that would
        turn backwards is locked by its brake (u = 0)."""
        plant, adhesion = self.plant, self.adhesion
        force, slope = self._creep_force_and_slope(speed_mps, wheel_speed_mps, law)
        scaled_speed = np.maximum(speed_mps, adhesion.regularisation_speed_mps)
        # Where the wheel, moving towards the train's speed, would cross it within the substep, the
        # slope is raised to the secant F / s (the kernel's _implicit_slope_N says why).
        slip = speed_mps - wheel_speed_mps
        s = slip / scaled_speed
        rate = (force - brake_force_N) / self.wheelset_mass_kg
        change = delta_s * rate / (1.0 + delta_s * slope / (scaled_speed * self.wheelset_mass_kg))
        crossing = (s != 0.0) & (rate * s > 0.0) & ((slip - change) * slip < 0.0)
        slope = np.where(crossing, np.maximum(slope, force / np.where(crossing, s, 1.0)), slope)
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
