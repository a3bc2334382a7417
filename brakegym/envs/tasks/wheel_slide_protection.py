"""``brakegym/WheelSlideProtection-v0``: command the wheel-slide protection (WSP) valves of an
emergency stop on a rail of low adhesion, to stop as short as possible without sliding the wheels.

The trains run with wheel-rail adhesion (docs/adhesion.md, the config's ``wheel_rail``: the rail in
one condition throughout, e.g. ``low``, or a line of sections such as ``low_patch``; the valve set,
one valve per axle or per bogie). Each episode draws the initial speed (``initial_speed_kmh``), the
load, the discs' friction scatter (``setup``), with ``wheel_rail.rail_scatter`` its own rail (every
section's mu_0 times a lognormal factor of mean 1 and the condition's relative sigma; on a line the
largest of its sections'), and a coast (``coast_s``, rounded to control steps) after which the
brake control asks for the pressure of ``brake_mode`` (emergency) in every cylinder; the agent then
commands the valves between that pressure and the cylinders at ``policy_frequency_hz`` (50 Hz, the
20 ms step of a brake control unit). Every quantity of an
episode, the sensor noise included, is drawn from the episode's own key, so that a train's episode
is the same whatever the batch it runs in.

Action
------
``MultiDiscrete([3] * valves)``: per valve 0 dump (the cylinder vents at the valve's dump rate),
1 hold (shut off), 2 apply (the valve at rest: the cylinder refills to the brake control's
pressure). That is VALVE_DUMP, VALVE_HOLD, VALVE_APPLY of :mod:`brakegym.physics.pneumatics`
plus one; anything else raises ``ValueError``. The reference controller, no WSP and a trained
policy are controllers of this one kind (:mod:`brakegym.agents.wsp_policy`).

Observation
-----------
What a brake control unit measures, ``Box(-5, 5, (5 axles + 3,), float32)``, no true train speed:
each axle's wheel speed from its speed sensor (Gaussian noise ``wheel_speed_noise_mps``, rounded
to ``wheel_speed_resolution_mps``) over 50 m/s; each axle's speed relative to the fastest,
(u_i - max u) / max(max u, 1 m/s); each axle's deceleration over the last control step from those
readings, over 10 m/s^2; each cylinder pressure (noise ``sensor_noise.pressure_bar``) over the
vehicle's maximum pressure; each axle's slip against the reference speed,
(v_ref - u_i) / max(v_ref, 1 m/s); the train's deceleration from its sensor (noise
``sensor_noise.decel_mps2``) over 2 m/s^2; the brake control's pressure demand for the coming
step over the maximum pressure; the reference speed over 50 m/s. The reference speed is the
brake control unit's estimate of the train speed: the fastest wheel, falling no faster than
1.3 m/s^2 (:class:`BcuFeatures`). Each column is clipped to [-5, 5]. :func:`bcu_observation`
computes it from a :class:`~brakegym.wheel_slide.BcuMeasurement`, here and for a trained policy
run by :func:`~brakegym.wheel_slide.wsp_train_stops`.

Reward terms
------------
``adhesion``: the train's deceleration over the step over g (the adhesion the rails deliver; its
greedy maximum is the shortest stop), per step, times ``reward.adhesion_per_g``;
``distance``: -``reward.distance_per_km`` per km travelled; ``slide``: -``reward.slide_per_MJ``
per MJ of slide energy (the creep forces' work on the slip speed, sum over the axles of
F_i (v - u_i) dt); ``locked``: -``reward.locked_per_axle_s`` per second of each locked axle
(wheel below 5 % of the train speed above 1 m/s, :data:`brakegym.wheel_slide.LOCKED_SPEED_RATIO`),
divided by the number of axles.

Termination: standstill; truncation at ``max_episode_time_s``. Success: standstill with no axle
locked longer than ``success_max_locked_time_s`` at a stretch.

Info: ``braking_distance_m`` (from the brake demand on), ``slide_energy_MJ``,
``max_locked_time_s`` (the longest stretch of any axle), ``ideal_braking_distance_m`` (on a
rail in one condition: the train's speed at the demand times the cylinders' dead time, plus the
integral of v dv / a_max(v), a_max the rail's peak adhesion at each speed over the body mass with
the running resistance, on the episode's own rail; a lower bound of every stop; NaN on a line of
sections), ``brake_demand_s`` (the drawn coast) and ``rail_friction_factor`` (the episode's factor
on the rail's mu_0, 1 without ``rail_scatter``). Reset options ``coast_s`` and
``rail_friction_factor`` fix the coast and the rail's factor.

Version history: v0, initial release.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import Field, model_validator

from ... import config as cfg
from ..config import BrakeEnvConfig, Range
from ..task import BrakeTask, Outcome, copies, of_train

if TYPE_CHECKING:
    from ...wheel_slide import BcuMeasurement
    from ..fleet import TrainFleet

STANDARD_GRAVITY_MPS2 = 9.80665
# Scales of the observation columns (wheel speeds, wheel decelerations, train deceleration).
WHEEL_SPEED_SCALE_MPS = 50.0
WHEEL_DECELERATION_SCALE_MPS2 = 10.0
TRAIN_DECELERATION_SCALE_MPS2 = 2.0
#: Every observation column is clipped to +- this.
OBSERVATION_BOUND = 5.0
#: The brake control unit's reference speed falls no faster than this (as the reference WSP's,
#: configs/agents/wsp.yaml; ASSUMED there).
REFERENCE_DECELERATION_MPS2 = 1.3
#: Below this speed the relative wheel speeds divide by it.
MIN_REFERENCE_SPEED_MPS = 1.0
#: Streams of the task's keyed draws (the coast, the rail's factor) and of the sensor noise,
#: derived from the fleet's episode keys (:mod:`brakegym.envs.fleet`).
COAST_STREAM, NOISE_STREAM, RAIL_STREAM = 11, 12, 13
#: The peak-adhesion table's speeds reach this multiple of the fastest initial speed. A rail whose
#: mu_0 is f times the nominal one has at speed v the nominal law's peak at f v, times f
#: (:func:`adhesion_limited_distance_m`), so the table serves factors up to this.
PEAK_TABLE_SPEED_RANGE = 3.0
#: The brake force of the adhesion-limited stop is the peak adhesion times this. The table's creep
#: grid finds each peak at most one grid step below the true one, and the interpolation between
#: its speeds errs by far less; 0.5 % up makes the distance a bound from below.
PEAK_ADHESION_MARGIN = 1.005
#: Points of the adhesion-limited stop's integral over the speed.
IDEAL_SPEED_POINTS = 200


def adhesion_limited_distance_m(
    speed_mps: float,
    axle_friction_factors: np.ndarray,
    peak_speeds_mps: np.ndarray,
    peak_adhesion: np.ndarray,
    mass_kg: float,
    body_mass_kg: float,
    resistance: cfg.RunningResistance,
) -> float:
    """The distance from ``speed_mps`` to standstill braked at the rail's peak adhesion under
    every axle at every speed (times :data:`PEAK_ADHESION_MARGIN`), with the running resistance,
    the train's mass ``mass_kg`` on the rail and its body mass ``body_mass_kg`` to decelerate (the
    wheelsets brake their own inertia): the integral of v m_body / F(v) dv from 0.05 m/s.

    ``peak_adhesion`` is the nominal rail's peak at ``peak_speeds_mps``;
    ``axle_friction_factors`` each axle's factor on the nominal mu_0 (the episode's rail times
    the rail's conditioning by the axles ahead; one factor stands for every axle). Polach's law
    with mu_0 times f has at speed v f times the nominal law's peak at f v: the creep s = f s'
    turns its force into f times the nominal one at creep s' and slip speed s' (f v) (tested in
    tests/test_adhesion.py). Beyond the table's last speed its last peak stands, which is at least
    the true one (the peak falls with the speed)."""
    if speed_mps <= 0.05:
        return 0.0
    speeds = np.linspace(0.05, speed_mps, IDEAL_SPEED_POINTS)
    factors = np.asarray(axle_friction_factors, dtype=float).reshape(-1, 1)
    peak = np.mean(factors * np.interp(factors * speeds, peak_speeds_mps, peak_adhesion), axis=0)
    force_N = PEAK_ADHESION_MARGIN * peak * mass_kg * STANDARD_GRAVITY_MPS2
    force_N += resistance.A_N + resistance.B_N_per_mps * speeds + resistance.C_N_per_mps2 * speeds**2
    integrand = speeds * body_mass_kg / force_N
    return float(np.sum(0.5 * (integrand[1:] + integrand[:-1]) * np.diff(speeds)))


class WspRewardWeights(cfg.StrictModel):
    """Weights of the WheelSlideProtection reward terms (module documentation)."""

    adhesion_per_g: float = Field(ge=0)
    distance_per_km: float = Field(ge=0)
    slide_per_MJ: float = Field(ge=0)
    locked_per_axle_s: float = Field(ge=0)


class WheelSlideProtectionConfig(BrakeEnvConfig):
    """The WSP task: an emergency stop on a rail of low adhesion, the WSP valves commanded."""

    reward: WspRewardWeights  # type: ignore[assignment]
    brake_mode: str = Field(min_length=1)
    coast_s: Range
    success_max_locked_time_s: float = Field(ge=0)

    @model_validator(mode="after")
    def _needs_rail(self) -> WheelSlideProtectionConfig:
        if self.wheel_rail is None:
            raise ValueError("the WSP task needs wheel_rail (a rail condition or line, and the WSP valves)")
        if self.coast_s.low < 0:
            raise ValueError(f"coast_s.low = {self.coast_s.low} must not be negative")
        return self


def bcu_observation(
    measurement: BcuMeasurement,
    previous_wheel_speed_mps: np.ndarray,
    reference_speed_mps: np.ndarray,
    control_step_s: float,
    max_pressure_bar: float,
    out: np.ndarray,
) -> None:
    """The observation of the WSP task (module documentation) from what the brake control unit
    measures now, the wheel speeds it read one control step before and its reference speed
    (:class:`BcuFeatures`), written into ``out`` (B, 5 axles + 3)."""
    wheels = measurement.wheel_speed_mps
    axles = wheels.shape[1]
    fastest = wheels.max(axis=1, keepdims=True)
    reference = reference_speed_mps[:, None]
    out[:, :axles] = wheels / WHEEL_SPEED_SCALE_MPS
    out[:, axles : 2 * axles] = (wheels - fastest) / np.maximum(fastest, MIN_REFERENCE_SPEED_MPS)
    out[:, 2 * axles : 3 * axles] = (previous_wheel_speed_mps - wheels) / (
        control_step_s * WHEEL_DECELERATION_SCALE_MPS2
    )
    out[:, 3 * axles : 4 * axles] = measurement.cylinder_pressure_bar / max_pressure_bar
    out[:, 4 * axles : 5 * axles] = (reference - wheels) / np.maximum(reference, MIN_REFERENCE_SPEED_MPS)
    out[:, 5 * axles] = measurement.deceleration_mps2 / TRAIN_DECELERATION_SCALE_MPS2
    out[:, 5 * axles + 1] = measurement.demand_bar.mean(axis=1) / max_pressure_bar
    out[:, 5 * axles + 2] = reference_speed_mps / WHEEL_SPEED_SCALE_MPS
    np.clip(out, -OBSERVATION_BOUND, OBSERVATION_BOUND, out=out)


class BcuFeatures:
    """What a brake control unit keeps between control steps for the observation of
    ``n_trains`` trains: the wheel speeds read one step before and a reference speed, the fastest
    wheel but falling no faster than ``REFERENCE_DECELERATION_MPS2`` (when every wheel slides
    together the fastest one is slower than the train; the reference WSP's estimate,
    ``configs/agents/wsp.yaml``). Observing the same control step again (the vector env observes
    once more after restarting trains) starts from the state before that step's first reading."""

    def __init__(self, n_trains: int, n_axles: int, control_step_s: float, max_pressure_bar: float) -> None:
        self.control_step_s, self.max_pressure_bar = float(control_step_s), float(max_pressure_bar)
        self.previous_wheel_speed_mps = np.full((n_trains, n_axles), np.nan)
        self.reference_speed_mps = np.full(n_trains, np.nan)
        self.step = np.full(n_trains, -1, dtype=np.int64)
        self._before = (self.previous_wheel_speed_mps.copy(), self.reference_speed_mps.copy())

    def restart(self, index: np.ndarray) -> None:
        """Trains ``index`` start anew: their next reading is their first."""
        self.previous_wheel_speed_mps[index] = np.nan
        self.reference_speed_mps[index] = np.nan
        self.step[index] = -1

    def observe(self, measurement: BcuMeasurement, step: np.ndarray, out: np.ndarray) -> None:
        """The observation (:func:`bcu_observation`) of ``measurement`` at each train's control
        ``step`` into ``out``, and the state moved on to it."""
        again = step == self.step
        previous = np.where(again[:, None], self._before[0], self.previous_wheel_speed_mps)
        reference = np.where(again, self._before[1], self.reference_speed_mps)
        self._before = (previous.copy(), reference.copy())
        wheels = np.asarray(measurement.wheel_speed_mps, dtype=float)
        fastest = wheels.max(axis=1)
        unread = np.isnan(reference)
        previous[unread] = wheels[unread]
        floor = reference - REFERENCE_DECELERATION_MPS2 * self.control_step_s
        reference = np.where(unread, fastest, np.maximum(fastest, floor))
        bcu_observation(measurement, previous, reference, self.control_step_s, self.max_pressure_bar, out)
        self.previous_wheel_speed_mps = wheels.copy()
        self.reference_speed_mps = reference
        self.step = np.array(step, dtype=np.int64, copy=True)


def observation_columns(n_axles: int) -> list[tuple[str, float, float]]:
    """Names and bounds of :func:`bcu_observation`'s columns for ``n_axles`` axles."""
    names = [f"wheel_speed_{axle + 1}" for axle in range(n_axles)]
    names += [f"relative_wheel_speed_{axle + 1}" for axle in range(n_axles)]
    names += [f"wheel_deceleration_{axle + 1}" for axle in range(n_axles)]
    names += [f"pressure_{axle + 1}" for axle in range(n_axles)]
    names += [f"slip_{axle + 1}" for axle in range(n_axles)]
    names += ["train_deceleration", "brake_demand", "reference_speed"]
    return [(name, -OBSERVATION_BOUND, OBSERVATION_BOUND) for name in names]


class WheelSlideProtection(BrakeTask):
    """The WSP valves of an emergency stop on a rail of low adhesion (see the module documentation)."""

    env_id = "brakegym/WheelSlideProtection-v0"
    name = "wheel_slide_protection"
    config_model = WheelSlideProtectionConfig
    metric = ("braking_distance_m", "m")
    options = ("coast_s", "rail_friction_factor")
    action_kind = "valves"
    common_observations = False
    stress_quantities = ("slide_energy_MJ", "max_locked_time_s")
    config: WheelSlideProtectionConfig

    def __init__(self, config: WheelSlideProtectionConfig, fleet: TrainFleet):
        super().__init__(config, fleet)
        # Imported here: the task module stays light for `import brakegym`.
        from ...physics.pneumatics import VALVE_APPLY
        from ...wheel_slide import LOCKED_MIN_TRAIN_SPEED_MPS, LOCKED_SPEED_RATIO, BcuMeasurement

        self._measurement_type = BcuMeasurement
        self._locked_ratio, self._locked_min_speed_mps = LOCKED_SPEED_RATIO, LOCKED_MIN_TRAIN_SPEED_MPS
        self.valve_offset = VALVE_APPLY - 2  # action 2 is apply
        n, axles = self.n, fleet.plant.n_axles
        self.n_axles = axles
        vehicle = fleet.vehicle
        self.demand_by_load_bar = np.array(
            [vehicle.brake_pressure_bar(config.brake_mode, load) for load in fleet.vehicle_loads]
        )
        self.dead_time_s = cfg.load("pneumatics", config.actuation).dead_time_s
        self.demand_bar = np.zeros(n)  # each train's pressure demand once the brake is asked for
        self.demand_step = np.zeros(n, dtype=np.int64)
        self.position_at_demand_m = np.zeros(n)
        self.speed_at_demand_mps = np.zeros(n)
        self.previous_position_m = np.zeros(n)
        self.previous_slip_work_J = np.zeros(n)
        self.locked_current_s = np.zeros((n, axles))
        self.locked_longest_s = np.zeros((n, axles))
        self.features = BcuFeatures(n, axles, fleet.control_step_s, fleet.max_pressure_bar)
        self.measurement: BcuMeasurement | None = None
        self.peak_adhesion_table = self._peak_adhesion_table()
        # Each axle's factor on the nominal mu_0 from the rail's conditioning (one section).
        self.axle_conditioning = fleet.adhesion.axle_conditioning(axles)[0]
        self.ideal_braking_distance_m = np.full(n, np.nan)
        self.rail_friction_factor = np.ones(n)

    # -------------------------------------------------------------------------------------------
    def _peak_adhesion_table(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(speeds (S,), the nominal rail's peak adhesion at each per load (loads, S)), the speeds
        up to :data:`PEAK_TABLE_SPEED_RANGE` times the fastest initial speed, on a rail in one
        condition; None on a line of sections."""
        fleet = self.fleet
        adhesion = fleet.adhesion
        if fleet.config.wheel_rail.rail_condition is None:
            return None
        top_mps = PEAK_TABLE_SPEED_RANGE * 1.05 * fleet.config.initial_speed_kmh.high / 3.6
        speeds = np.linspace(0.05, top_mps, 3 * IDEAL_SPEED_POINTS)
        peaks = []
        for load in fleet.vehicle_loads:
            wheel_load_N = fleet.vehicle.mass_kg(load) * STANDARD_GRAVITY_MPS2 / (2 * self.n_axles)
            stiffness_N = adhesion.contact.creep_stiffness_N(wheel_load_N)
            peaks.append(adhesion.law.peak_adhesion(speeds, wheel_load_N, stiffness_N, n_creeps=2001)[0])
        return speeds, np.array(peaks)

    def restart(self, index: np.ndarray, rng: np.random.Generator, options: Mapping[str, Any]) -> None:
        from ...reliability.streams import derived_seed, uniforms

        fleet, config = self.fleet, self.config
        keys = fleet.episode_key[index]
        u = uniforms(derived_seed(0, COAST_STREAM), keys, 1)[:, 0]
        coast_s = config.coast_s.low + (config.coast_s.high - config.coast_s.low) * u
        if "coast_s" in options:
            from ..options import option_values

            coast_s = option_values(options["coast_s"], len(index), "coast_s")
            if np.any(~(coast_s >= 0)):
                raise ValueError(f"reset option 'coast_s' = {options['coast_s']}: must not be negative")
        self.demand_step[index] = np.round(coast_s / fleet.control_step_s).astype(np.int64)
        self._set_rail(index, keys, options)
        self.demand_bar[index] = self.demand_by_load_bar[fleet.episodes.load_index[index]]
        self.position_at_demand_m[index] = 0.0
        self.speed_at_demand_mps[index] = fleet.speed_mps[index]
        self._set_ideal(index)
        self.previous_position_m[index] = 0.0
        self.previous_slip_work_J[index] = 0.0
        self.locked_current_s[index] = 0.0
        self.locked_longest_s[index] = 0.0
        self.features.restart(index)

    # -------------------------------------------------------------------------------------------
    def observation_columns(self) -> list[tuple[str, float, float]]:
        return observation_columns(self.n_axles)

    def _demand_now_bar(self) -> np.ndarray:
        """The brake control's demand per axle for the coming step (N, axles)."""
        active = self.fleet.episodes.step >= self.demand_step
        return np.repeat(np.where(active, self.demand_bar, 0.0)[:, None], self.n_axles, axis=1)

    def measure(self, out: np.ndarray) -> None:
        from ...reliability.streams import derived_seed, standard_normals

        fleet, option, noise = self.fleet, self.config.wheel_rail, self.config.sensor_noise
        axles = self.n_axles
        # Noise drawn per train from its episode key and control step: batch-independent.
        normals = standard_normals(
            derived_seed(0, NOISE_STREAM), fleet.episode_key + fleet.episodes.step, 2 * axles + 1
        )
        wheels = fleet.sim.wheel_speed_mps.T + option.wheel_speed_noise_mps * normals[:, :axles]
        if option.wheel_speed_resolution_mps > 0:
            wheels = np.round(wheels / option.wheel_speed_resolution_mps) * option.wheel_speed_resolution_mps
        measurement = self._measurement_type(
            wheel_speed_mps=wheels,
            cylinder_pressure_bar=fleet.pressure.pressure_bar + noise.pressure_bar * normals[:, axles : 2 * axles],
            deceleration_mps2=fleet.deceleration_mps2 + noise.decel_mps2 * normals[:, 2 * axles],
            demand_bar=self._demand_now_bar(),
            train_speed_mps=fleet.speed_mps.copy(),
        )
        self.features.observe(measurement, fleet.episodes.step, out)
        self.measurement = measurement

    # -------------------------------------------------------------------------------------------
    def advance_fleet(self, actions: np.ndarray) -> None:
        fleet = self.fleet
        actions = np.asarray(actions)
        if actions.shape != (self.n, fleet.n_valves):
            raise ValueError(f"action shape {actions.shape} does not match ({self.n} trains, {fleet.n_valves} valves)")
        valves = actions.astype(np.int64)
        if np.any(valves != actions) or np.any((valves < 0) | (valves > 2)):
            raise ValueError(f"valve actions must be 0 (dump), 1 (hold) or 2 (apply), got {np.unique(actions)}")
        starting = fleet.episodes.step == self.demand_step
        if starting.any():
            self.position_at_demand_m[starting] = fleet.position_m[starting]
            self.speed_at_demand_mps[starting] = fleet.speed_mps[starting]
            self._set_ideal(np.flatnonzero(starting))
        fleet.advance_valves(self._demand_now_bar(), valves + self.valve_offset)

    def slip_work_J(self) -> np.ndarray:
        """Each train's slide energy so far (the slip work summed over its axles), J."""
        from ...simulator.state import SLIP_WORK

        per_axle = self.fleet.sim.wheelset[SLIP_WORK]
        # Added axle by axle: numpy's sum over the axles would take another order for another
        # number of trains, and a train's numbers would depend on its batch.
        total = per_axle[0].copy()
        for axle in range(1, len(per_axle)):
            total += per_axle[axle]
        return total

    def judge(self) -> Outcome:
        config, fleet = self.config, self.fleet
        weights = config.reward
        dt = fleet.control_step_s
        speed = fleet.speed_mps
        running = ~fleet.standstill & (speed > self._locked_min_speed_mps)
        locked = (fleet.sim.wheel_speed_mps.T < self._locked_ratio * speed[:, None]) & running[:, None]
        self.locked_current_s = np.where(locked, self.locked_current_s + dt, 0.0)
        np.maximum(self.locked_longest_s, self.locked_current_s, out=self.locked_longest_s)
        travelled = fleet.position_m - self.previous_position_m
        self.previous_position_m = fleet.position_m.copy()
        slip_work = self.slip_work_J()
        slide_J = slip_work - self.previous_slip_work_J
        self.previous_slip_work_J = slip_work
        standstill = fleet.standstill
        success = standstill & (self.locked_longest_s.max(axis=1) <= config.success_max_locked_time_s)
        terms = {
            "adhesion": weights.adhesion_per_g * fleet.deceleration_mps2 / STANDARD_GRAVITY_MPS2,
            "distance": -weights.distance_per_km * travelled / 1000.0,
            "slide": -weights.slide_per_MJ * slide_J / 1e6,
            "locked": -weights.locked_per_axle_s * dt * locked.sum(axis=1) / self.n_axles,
        }
        return Outcome(terms, standstill, success)

    def _set_rail(self, index: np.ndarray, keys: np.ndarray, options: Mapping[str, Any]) -> None:
        """Each restarted train's factor on its rail's mu_0: drawn from its episode key with
        ``wheel_rail.rail_scatter`` (lognormal, mean 1, as
        :func:`brakegym.plants.rail_friction_factor_for_samples` draws a campaign's), else 1; the
        reset option ``rail_friction_factor`` fixes it. Written into the simulator's per-train
        row, which the compiled step reads."""
        from ...physics import static_friction_factor
        from ...plants import rail_static_friction_relative_sigma
        from ...reliability.streams import derived_seed, standard_normals

        fleet = self.fleet
        factor = np.ones(len(index))
        if self.config.wheel_rail.rail_scatter:
            normals = standard_normals(derived_seed(0, RAIL_STREAM), keys, 1)[:, 0]
            factor = static_friction_factor(rail_static_friction_relative_sigma(fleet.rail), normals)
        if "rail_friction_factor" in options:
            from ..options import option_values

            factor = option_values(options["rail_friction_factor"], len(index), "rail_friction_factor")
            if not np.all(np.isfinite(factor) & (factor > 0)):
                raise ValueError(
                    f"reset option 'rail_friction_factor' = {options['rail_friction_factor']}: must be positive"
                )
            if np.any(factor != 1.0) and fleet.adhesion.static_friction_factor is None:
                raise ValueError(
                    f"reset option 'rail_friction_factor' = {options['rail_friction_factor']}: environment "
                    f"{self.config.name!r} runs every train on the rail as configured (wheel_rail.rail_scatter: false)"
                )
        self.rail_friction_factor[index] = factor
        fleet.sim.static_friction_factor[index] = factor

    def _set_ideal(self, index: np.ndarray) -> None:
        """The adhesion-limited lower bound of the stops of trains ``index`` (module
        documentation), from their speed at the brake demand, on each one's rail."""
        if self.peak_adhesion_table is None:
            self.ideal_braking_distance_m[index] = np.nan
            return
        fleet = self.fleet
        vehicle = fleet.vehicle
        speeds, peaks = self.peak_adhesion_table
        wheelsets_kg = self.n_axles * fleet.adhesion.wheelset_inertia_kgm2 / vehicle.wheel_radius_m**2
        for train in index:
            load = fleet.episodes.load_index[train]
            mass_kg = vehicle.mass_kg(fleet.vehicle_loads[load])
            speed = self.speed_at_demand_mps[train]
            braking = adhesion_limited_distance_m(
                speed,
                self.rail_friction_factor[train] * self.axle_conditioning,
                speeds,
                peaks[load],
                mass_kg,
                mass_kg - wheelsets_kg,
                vehicle.running_resistance,
            )
            self.ideal_braking_distance_m[train] = speed * self.dead_time_s + braking

    def episode_info(self, train: int | None = None) -> dict[str, Any]:
        fleet = self.fleet
        demanded = fleet.episodes.step > self.demand_step
        info = {
            "braking_distance_m": np.where(demanded, fleet.position_m - self.position_at_demand_m, 0.0),
            "slide_energy_MJ": self.slip_work_J() / 1e6,
            "max_locked_time_s": self.locked_longest_s.max(axis=1),
            "ideal_braking_distance_m": self.ideal_braking_distance_m,
            "brake_demand_s": self.demand_step * fleet.control_step_s,
            "rail_friction_factor": self.rail_friction_factor,
        }
        return copies(info) if train is None else of_train(info, train)
