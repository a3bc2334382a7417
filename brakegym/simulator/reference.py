"""The numpy reference integration of the simulator: readable, slow, and what the compiled kernel
is tested and benchmarked against."""

from __future__ import annotations

import numpy as np

from ..physics.mechanics import brake_force_N, effective_mu
from .hooks import extra_force_N, friction_scale
from .integrator import Simulator, StepRecord
from .state import (
    BRAKE_WORK,
    COOLING_HEAT,
    EXTRA_WORK,
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


class NumpyReferenceSimulator(Simulator):
    """The same model as :class:`Simulator`, integrated with numpy array operations only.

    Readable and slow (about 60 array passes per RK4 stage): the reference the compiled kernels
    are tested against (``tests/test_kernel.py``) and benchmarked against
    (``benchmarks/bench_step.py``). Same interface and results within rounding.
    """

    def _forces(
        self, time_s: float, disc: np.ndarray, train: np.ndarray, clamp_force: np.ndarray
    ) -> tuple[np.ndarray, ...]:
        """Friction force per disc and the train forces at one state."""
        plant = self.plant
        mu = plant.friction.bounded(disc[MU])
        context = (
            self.context_at(time_s, disc, train, clamp_force) if self.extra_forces or self.friction_modifiers else None
        )
        effective = mu * friction_scale(self.friction_modifiers, context) if self.friction_modifiers else mu  # type: ignore[arg-type]
        friction_force = effective * clamp_force
        brake = brake_force_N(friction_force, plant.friction_radius_m, plant.wheel_radius_m)
        resistance = plant.running_resistance.force_N(train[SPEED], self.resistance_A_N)
        extra = extra_force_N(self.extra_forces, context, self.n_trains) if self.extra_forces else np.zeros_like(brake)  # type: ignore[arg-type]
        return mu, friction_force, brake, resistance, extra

    def rates(
        self, time_s: float, disc: np.ndarray, train: np.ndarray, clamp_force: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The time derivatives of the packed states ``disc`` and ``train`` with the clamp force
        ``clamp_force`` (A, 1, B): the right-hand side of the model."""
        plant = self.plant
        speed = train[SPEED]
        # Stages may overshoot past standstill inside the stopping step: the forces extrapolate
        # smoothly there (for the stop interpolation), the sliding speed does not go negative.
        sliding = np.maximum(speed, 0.0) * plant.radius_ratio
        mu, friction_force, brake, resistance, extra = self._forces(time_s, disc, train, clamp_force)
        friction_power = friction_force * sliding
        flows = plant.thermal.heat_flows(friction_power, disc[T_FRIC], disc[T_DISC], sliding, self.ambient_K)
        d_disc = np.empty_like(disc)
        # mu is bounded once, in _forces.
        d_disc[MU] = plant.friction.rate_of_bounded_mu_per_s(
            mu, clamp_force, sliding, disc[T_FRIC], self.power_coefficient
        )
        d_disc[T_FRIC], d_disc[T_DISC] = plant.thermal.temperature_rates_K_per_s(flows)
        d_disc[MU_DISTANCE] = mu * speed
        d_disc[FRICTION_HEAT] = flows.friction_W
        d_disc[COOLING_HEAT] = flows.surface_W + flows.ventilation_W

        total = brake + resistance + extra
        d_train = np.empty_like(train)
        d_train[SPEED] = np.where(self.moving, -total * self.inverse_mass_per_kg, 0.0)
        d_train[POSITION] = speed
        d_train[BRAKE_WORK] = brake * speed
        d_train[RESISTANCE_WORK] = resistance * speed
        d_train[EXTRA_WORK] = extra * speed
        # Eq. 15 with the actual retarding force; it is only integrated after the clamp force
        # has reached 95 % of its nominal value.
        weighted_clamp = clamp_force.sum(axis=(0, 1)) * (plant.discs_per_axle * plant.radius_ratio)
        nominal_resistance = self.nominal_running_resistance.force_N(speed)
        d_train[MU_EFF_DISTANCE] = effective_mu(total, nominal_resistance, weighted_clamp) * speed
        return d_disc, d_train

    def step(self, n_steps: int = 1) -> StepRecord:
        """Advance every train by ``n_steps`` steps, one at a time."""
        if n_steps < 1:
            raise ValueError(f"n_steps = {n_steps}: must be at least 1")
        for _ in range(n_steps):
            record = self._step_once()
        return record

    def _step_once(self) -> StepRecord:
        h = self.step_s
        t = self.time_s
        p_start, p_mid, p_end = self.pressure.stage_pressures_bar()
        f_start, f_mid, f_end = (self.clamp_force_N(p) for p in (p_start, p_mid, p_end))
        disc0, train0 = self.disc, self.train

        k1d, k1t = self.rates(t, disc0, train0, f_start)
        k2d, k2t = self.rates(t + 0.5 * h, disc0 + 0.5 * h * k1d, train0 + 0.5 * h * k1t, f_mid)
        k3d, k3t = self.rates(t + 0.5 * h, disc0 + 0.5 * h * k2d, train0 + 0.5 * h * k2t, f_mid)
        k4d, k4t = self.rates(t + h, disc0 + h * k3d, train0 + h * k3t, f_end)
        disc1 = disc0 + (h / 6.0) * (k1d + 2.0 * (k2d + k3d) + k4d)
        train1 = train0 + (h / 6.0) * (k1t + 2.0 * (k2t + k3t) + k4t)

        stop_fraction = np.full(self.n_trains, np.nan)
        stopping = self.moving & (train1[SPEED] <= 0.0)
        if stopping.any():
            v0 = train0[SPEED, stopping]
            v1 = train1[SPEED, stopping]
            theta = v0 / (v0 - v1)
            stop_fraction[stopping] = theta
            # The deceleration is nearly constant over one step, so speed falls linearly to
            # zero at theta and the distance grows by the area of that triangle.
            disc1[..., stopping] = disc0[..., stopping] + theta * (disc1[..., stopping] - disc0[..., stopping])
            train1[:, stopping] = train0[:, stopping] + theta * (train1[:, stopping] - train0[:, stopping])
            train1[POSITION, stopping] = train0[POSITION, stopping] + 0.5 * v0 * theta * h
            train1[SPEED, stopping] = 0.0
            self.stop_time_s[stopping] = t + theta * h
        disc1[MU] = self.plant.friction.bounded(disc1[MU])
        if self.hold_standing_trains:
            held = ~self.moving
            disc1[..., held] = disc0[..., held]
            train1[:, held] = train0[:, held]
        record = StepRecord(t, disc0, train0, f_start, f_end, stop_fraction)
        return self.finish_step(record, disc1, train1, self.moving & ~stopping)

    def deceleration_mps2(self) -> np.ndarray:
        clamp_force = self.clamp_force_N(self.pressure.pressure_bar)
        _, _, brake, resistance, extra = self._forces(self.time_s, self.disc, self.train, clamp_force)
        return np.where(self.moving, (brake + resistance + extra) * self.inverse_mass_per_kg, 0.0)
