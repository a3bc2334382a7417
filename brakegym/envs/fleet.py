"""The batch of trains behind every brakegym environment, and the task interface.

:class:`TrainFleet` holds N trains of one vehicle in one :class:`~brakegym.simulator.Simulator`:
it restarts any subset of them (new speed, load, friction draw, disc temperatures), turns the
policy's actions into per-axle cylinder pressure commands, runs the physics substeps of one
control step and measures what the train's sensors would report. A
:class:`~brakegym.envs.task.BrakeTask` adds what one task draws, observes and rewards. The single
and the vector environments (:mod:`brakegym.envs.env`) are thin shells around these two, so that
the physics of a control step exists once, vectorised.
"""

from __future__ import annotations

import dataclasses
import operator
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import config as cfg
from ..effects import RunningResistanceEffect, apply_effects, load_effects
from ..plants import (
    brake_cylinder,
    train_plant,
    train_scatter,
    valve_of_axle,
    wheel_rail_adhesion,
    wsp_valve,
)
from ..simulator import BatchConditions, CommandedPressure, Simulator
from ..simulator.pressure import ValvedPressure
from ..simulator.state import MU, POSITION, SPEED, T_DISC, T_FRIC
from ..simulator.wheelsets import AdhesionSimulator
from ..units import ZERO_CELSIUS_K, kmh_to_mps
from .config import BrakeEnvConfig
from .options import option_values

# What info reports per disc, in this order: consecutive rows of the simulator's packed disc state,
# so that one slice takes them all.
REPORTED_DISC_STATES = slice(MU, T_DISC + 1)
#: Episode keys are drawn below this bound (so that key + control step stays an int64 sample
#: number of the counter-based streams, :mod:`brakegym.reliability.streams`).
EPISODE_KEY_LIMIT = 2**62
# Streams of the keyed episode draws of the ``wheel_rail`` fleets, the episode's initial speed, load
# and disc temperature, and its friction scatter (TrainScatter.draw_for_samples).
EPISODE_DRAW_STREAM, FRICTION_DRAW_STREAM = 1, 2
if (T_FRIC, T_DISC) != (MU + 1, MU + 2):
    raise ImportError(
        f"brakegym.envs expects mu, T_fric, T_disc as consecutive disc states, not rows {MU, T_FRIC, T_DISC}"
    )


@dataclass
class Episodes:
    """Per-train episode bookkeeping, arrays of length N."""

    step: np.ndarray  # control steps taken in this episode
    load_index: np.ndarray  # index into the vehicle's loads
    initial_speed_mps: np.ndarray
    mass_kg: np.ndarray
    peak_jerk_mps3: np.ndarray
    peak_friction_temperature_C: np.ndarray


def _write_rows(batch: BatchConditions, index: np.ndarray, rows: BatchConditions) -> None:
    """The applications ``index`` of ``batch`` (arrays over the batch, in place) set to ``rows``."""
    for field in dataclasses.fields(BatchConditions):
        getattr(batch, field.name)[index] = getattr(rows, field.name)


class TrainFleet:
    """N trains of ``config.vehicle`` with their brakes, stepped together.

    Actions are per control group in [-1, 1] and map linearly to 0..``max_cylinder_pressure_bar``;
    values outside [-1, 1] are clipped to it (as the action space documents), NaN or a wrong shape
    is refused.

    With an effect set (``config.effects``) every train runs the modified model: the effects are
    applied to each train's episode (its mass, drawn at reset, sets a gradient's force and the
    adhesion limit; a running-resistance effect replaces the nominal coefficients, the set-up's
    drawn scatter of A still added), and the sensor effects act on what :meth:`measure` reports: a
    speed-sensor scale on the speed, the deceleration derived from it and the odometry
    (:meth:`odometry_m`), a temperature-sensor lag on the disc temperatures (exact first-order lag
    for a temperature linear within the control step, the sensor at rest with its disc at reset).
    """

    def __init__(self, config: BrakeEnvConfig, n_trains: int):
        if n_trains < 1:
            raise ValueError(f"n_trains = {n_trains}: need at least one train")
        self.config = config
        self.n_trains = n_trains
        self.vehicle: cfg.Vehicle = cfg.load("vehicles", config.vehicle)
        self.material = cfg.load("materials", self.vehicle.material)
        self.scatter = train_scatter(self.vehicle, cfg.load("setups", config.setup))
        self.nominal_plant = train_plant(self.vehicle)
        self.cylinder = brake_cylinder(cfg.load("pneumatics", config.actuation))
        self.max_pressure_bar = self.vehicle.max_cylinder_pressure_bar
        self.vehicle_loads = list(self.vehicle.loads)
        self.control_step_s = config.control_step_s
        self.substeps = config.substeps

        axles = self.nominal_plant.n_axles
        if config.control_groups == "train":
            self.group_of_axle = np.zeros(axles, dtype=np.int64)
        elif config.control_groups == "bogie":
            self.group_of_axle = np.arange(axles) // self.vehicle.axles_per_bogie
        else:
            self.group_of_axle = np.arange(axles)
        self.n_groups = int(self.group_of_axle.max()) + 1

        self.pressure = CommandedPressure([self.cylinder] * n_trains, axles, config.physics_step_s)
        # With wheel-rail adhesion, the cylinders sit behind WSP valves and every wheelset turns on
        # its own; each episode then draws from its own key (see restart).
        self.adhesion = None
        self.rail: cfg.RailCondition | cfg.Line | None = None
        self.valve_of_axle = np.zeros(0, dtype=np.int64)
        self.episode_key = np.zeros(n_trains, dtype=np.int64)
        if config.wheel_rail is not None:
            option = config.wheel_rail
            rail = (
                cfg.load("rail_conditions", option.rail_condition)
                if option.rail_condition is not None
                else cfg.load("lines", option.line)
            )
            self.rail = rail
            self.adhesion = wheel_rail_adhesion(self.vehicle, rail, option.load_transfer)
            if option.rail_scatter:
                # Each episode's factor is written into the simulator's row at restart (the task
                # draws it); ones here make the simulator scale the rail's law by that row.
                self.adhesion = dataclasses.replace(self.adhesion, static_friction_factor=(1.0,) * n_trains)
            valves = cfg.load("wsp_valves", option.wsp_valves)
            self.valve_of_axle = valve_of_axle(self.vehicle, valves)
            self.pressure = ValvedPressure(self.pressure, wsp_valve(valves), self.valve_of_axle)
        self.n_valves = int(self.valve_of_axle.max()) + 1 if len(self.valve_of_axle) else 0
        ambient_K = self.vehicle.ambient_temperature_C + ZERO_CELSIUS_K
        disc_shape = (n_trains, *self.nominal_plant.disc_shape)
        # Trains start at standstill until their first reset gives them a speed.
        idle = BatchConditions(
            mass_kg=np.full(n_trains, self.vehicle.mass_kg(config.loads[0])),
            initial_speed_mps=np.zeros(n_trains),
            initial_mu=np.full(disc_shape, self.material.initial_mu),
            power_coefficient_per_s=np.full(disc_shape, self.material.power_coefficient_per_s),
            running_resistance_A_N=np.full(n_trains, self.vehicle.running_resistance.A_N),
            initial_friction_temperature_K=np.full(disc_shape, ambient_K),
            initial_disc_temperature_K=np.full(disc_shape, ambient_K),
            ambient_temperature_K=np.full(n_trains, ambient_K),
        )
        if self.adhesion is not None:
            if config.effects is not None:
                raise ValueError(f"environment {config.name!r}: effects do not run with wheel_rail")
            self.effects = []
            self.plant = self.nominal_plant
            self.sim = AdhesionSimulator(self.plant, idle, self.pressure, self.adhesion, step_s=config.physics_step_s)
        elif config.effects is None:
            self.effects: list = []
            self.plant = self.nominal_plant
            self.sim = Simulator(self.plant, idle, self.pressure, step_s=config.physics_step_s)
        else:
            self.effects = load_effects(config.effects)
            # Each train's episode draws without effects (its mass, drawn resistance), from which
            # the effects' hooks are rebuilt at every restart.
            self.episode_conditions = dataclasses.replace(
                idle, **{f.name: np.array(getattr(idle, f.name)) for f in dataclasses.fields(BatchConditions)}
            )
            model = self._effected(idle)
            # A running-resistance effect's B and C hold for every episode: the plant carries them.
            self.plant = model.plant
            self.sim = Simulator(
                self.plant,
                model.conditions,
                self.pressure,
                step_s=config.physics_step_s,
                extra_forces=model.forces_on_train(),
                friction_modifiers=model.friction_modifiers,
                nominal_running_resistance=self.nominal_plant.running_resistance,
            )
        # The sensor effects (see the class docstring); None where they are absent, which keeps
        # measure() free of them.
        self.speed_scale: np.ndarray | None = None
        self.temperature_lag_s: np.ndarray | None = None
        self.episodes = Episodes(
            step=np.zeros(n_trains, dtype=np.int64),
            load_index=np.zeros(n_trains, dtype=np.int64),
            initial_speed_mps=np.zeros(n_trains),
            mass_kg=idle.mass_kg.copy(),
            peak_jerk_mps3=np.zeros(n_trains),
            peak_friction_temperature_C=np.zeros(n_trains),
        )
        self.started = np.zeros(n_trains, dtype=bool)
        self.deceleration_mps2 = np.zeros(n_trains)  # mean over the last control step
        self.jerk_mps3 = np.zeros(n_trains)  # change of that mean per control step, 0 on the first
        self.hottest_friction_temperature_C = np.zeros(n_trains)
        self.overrun = np.zeros(n_trains, dtype=bool)
        instrumented = config.instrumented_disc - 1
        self.observed_discs = (
            np.arange(self.plant.n_discs) if config.observed_temperatures == "all" else np.array([instrumented])
        )
        # Rows of the (discs, N) temperature layout that are measured; a slice when all are, so
        # that measuring copies nothing first.
        self._observed_rows = slice(None) if config.observed_temperatures == "all" else self.observed_discs
        # Columns of measure(): speed, deceleration, pressure per axle, observed temperatures.
        self.n_measured_channels = 2 + axles + len(self.observed_discs)
        noise = config.sensor_noise
        self._noise_per_channel = np.concatenate(
            [
                [noise.speed_mps, noise.decel_mps2],
                np.full(self.plant.n_axles, noise.pressure_bar),
                np.full(len(self.observed_discs), noise.temperature_C),
            ]
        )
        self._lagged_temperature_C = np.zeros((n_trains, len(self.observed_discs)))
        self._true_temperature_C = np.zeros((n_trains, len(self.observed_discs)))
        if self.effects:
            self._set_sensors(model.sensors)

    def _effected(self, conditions: BatchConditions):
        """The effects applied to a batch of episode draws (an ``EffectedModel``)."""
        model = apply_effects(self.nominal_plant, conditions, self.effects)
        if any(isinstance(effect, RunningResistanceEffect) for effect in self.effects):
            # The effect sets the running resistance; each train still scatters around it.
            drawn_deviation_N = np.asarray(conditions.running_resistance_A_N) - self.vehicle.running_resistance.A_N
            model.conditions = dataclasses.replace(
                model.conditions,
                running_resistance_A_N=np.asarray(model.conditions.running_resistance_A_N) + drawn_deviation_N,
            )
        return model

    def _set_sensors(self, sensors) -> None:
        n = self.n_trains
        speed_scale = np.broadcast_to(np.asarray(sensors.speed_scale, dtype=float), (n,))
        lag_s = np.broadcast_to(np.asarray(sensors.temperature_lag_s, dtype=float), (n,))
        self.speed_scale = speed_scale.copy() if np.any(speed_scale != 1.0) else None
        self.temperature_lag_s = lag_s[:, None].copy() if np.any(lag_s > 0.0) else None

    # -------------------------------------------------------------------------------------------
    def restart(self, index: np.ndarray, rng: np.random.Generator, options: Mapping[str, Any]) -> None:
        """Start new episodes for the trains ``index``: draw (or take from ``options``) the initial
        speed, load, friction scatter and disc temperatures, and release their brakes."""
        n = len(index)
        config, vehicle = self.config, self.vehicle
        scatter = self.scatter
        if "setup" in options:
            scatter = train_scatter(vehicle, cfg.load("setups", str(options["setup"])))
        if self.adhesion is None:
            # Every draw happens whatever the options fix, so that fixing one quantity leaves the
            # random stream (and so every other quantity) of a seed unchanged.
            speed_kmh = rng.uniform(config.initial_speed_kmh.low, config.initial_speed_kmh.high, n)
            load_index = rng.integers(0, len(config.loads), n)
            temperature_C = rng.uniform(
                config.initial_disc_temperature_C.low, config.initial_disc_temperature_C.high, n
            )
            friction, resistance_A_N = scatter.draw(rng, n)
        else:
            speed_kmh, load_index, temperature_C, friction, resistance_A_N = self._keyed_draws(index, rng, scatter)

        if "initial_speed_kmh" in options:
            speed_kmh = option_values(options["initial_speed_kmh"], n, "initial_speed_kmh")
            if np.any(~(speed_kmh > 0)):
                raise ValueError(f"reset option 'initial_speed_kmh' = {options['initial_speed_kmh']}: must be positive")
        load_names = [config.loads[i] for i in load_index]
        if "load" in options:
            load = options["load"]
            if load not in vehicle.loads:
                raise ValueError(
                    f"reset option 'load' = {load!r}: loads of {vehicle.name!r} are {sorted(vehicle.loads)}"
                )
            load_names = [load] * n

        disc_shape = (n, *self.plant.disc_shape)
        friction_K = np.broadcast_to((temperature_C + ZERO_CELSIUS_K)[:, None, None], disc_shape).copy()
        disc_K = friction_K.copy()
        if config.carry_over_thermal_state:
            carried = self.started[index]
            friction_K[carried] = self.sim.to_external(self.sim.disc[T_FRIC])[index[carried]].reshape(
                -1, *self.plant.disc_shape
            )
            disc_K[carried] = self.sim.to_external(self.sim.disc[T_DISC])[index[carried]].reshape(
                -1, *self.plant.disc_shape
            )
        if "initial_disc_temperature_C" in options:
            fixed = (
                option_values(options["initial_disc_temperature_C"], n, "initial_disc_temperature_C") + ZERO_CELSIUS_K
            )
            friction_K[:] = fixed[:, None, None]
            disc_K[:] = fixed[:, None, None]

        mass_kg = np.array([vehicle.mass_kg(load) for load in load_names])
        conditions = BatchConditions(
            mass_kg=mass_kg,
            initial_speed_mps=kmh_to_mps(speed_kmh),
            initial_mu=friction.initial_mu,
            power_coefficient_per_s=friction.power_coefficient_per_s,
            running_resistance_A_N=resistance_A_N,
            initial_friction_temperature_K=friction_K,
            initial_disc_temperature_K=disc_K,
            ambient_temperature_K=np.full(n, vehicle.ambient_temperature_C + ZERO_CELSIUS_K),
        )
        if self.effects:
            # The restarted trains' own model, then every train's hooks from its current episode.
            _write_rows(self.episode_conditions, index, conditions)
            conditions = self._effected(conditions).conditions
            model = self._effected(self.episode_conditions)
            self.sim.extra_forces, self.sim.friction_modifiers = (
                tuple(model.forces_on_train()),
                tuple(model.friction_modifiers),
            )
            self._set_sensors(model.sensors)
        self.sim.reset_trains(index, conditions)
        self.pressure.reset_trains(index, 0.0)
        if self.temperature_lag_s is not None:
            observed_C = self._observed_temperature_C()[index]
            self._lagged_temperature_C[index] = observed_C
            self._true_temperature_C[index] = observed_C

        episodes = self.episodes
        episodes.step[index] = 0
        episodes.load_index[index] = [self.vehicle_loads.index(load) for load in load_names]
        episodes.initial_speed_mps[index] = kmh_to_mps(speed_kmh)
        episodes.mass_kg[index] = mass_kg
        episodes.peak_jerk_mps3[index] = 0.0
        episodes.peak_friction_temperature_C[index] = friction_K.reshape(n, -1).max(axis=1) - ZERO_CELSIUS_K
        self.deceleration_mps2[index] = 0.0
        self.overrun[index] = False
        self.started[index] = True

    def _keyed_draws(self, index: np.ndarray, rng: np.random.Generator, scatter):
        """The episode draws of a ``wheel_rail`` fleet: one key per restarted train from ``rng``,
        then every quantity of the episode from counter-based streams of that key alone, so that
        a train's episode is the same whatever the batch it runs in (the first key of a seed is
        the same for a batch of 1 or of 8). The task and the sensors draw from the key too."""
        # Imported here: scipy (which the streams need) would add to every environment's start.
        from ..reliability.streams import derived_seed, uniforms

        config = self.config
        keys = rng.integers(0, EPISODE_KEY_LIMIT, len(index))
        self.episode_key[index] = keys
        u = uniforms(derived_seed(0, EPISODE_DRAW_STREAM), keys, 3)
        speeds, temperatures = config.initial_speed_kmh, config.initial_disc_temperature_C
        speed_kmh = speeds.low + (speeds.high - speeds.low) * u[:, 0]
        load_index = np.minimum((u[:, 1] * len(config.loads)).astype(np.int64), len(config.loads) - 1)
        temperature_C = temperatures.low + (temperatures.high - temperatures.low) * u[:, 2]
        friction, resistance_A_N = scatter.draw_for_samples(derived_seed(0, FRICTION_DRAW_STREAM), keys)
        return speed_kmh, load_index, temperature_C, friction, resistance_A_N

    # -------------------------------------------------------------------------------------------
    def commands_bar(self, actions: np.ndarray) -> np.ndarray:
        """Per-axle cylinder pressure commands (N, axles) from actions (N, groups) in [-1, 1]."""
        actions = np.asarray(actions, dtype=float)
        if actions.shape != (self.n_trains, self.n_groups):
            raise ValueError(
                f"action shape {actions.shape} does not match ({self.n_trains} trains, {self.n_groups} "
                f"control groups of '{self.config.control_groups}')"
            )
        if not np.isfinite(actions).all():
            bad = np.argwhere(~np.isfinite(actions))[0]
            raise ValueError(
                f"action of train {bad[0]}, group {bad[1]} is {actions[tuple(bad)]}: actions must be finite"
            )
        # Clip, shift and scale per group in one scratch array, then spread the groups to their
        # axles: elementwise, so the same numbers as scaling per axle, with fewer numpy calls.
        per_group_bar = np.maximum(actions, -1.0)
        np.minimum(per_group_bar, 1.0, out=per_group_bar)
        per_group_bar += 1.0
        per_group_bar *= 0.5 * self.max_pressure_bar
        return per_group_bar[:, self.group_of_axle]

    def advance(self, actions: np.ndarray) -> None:
        """One control step: set the commands, run the physics substeps, update the measures."""
        self.pressure.set_command(self.commands_bar(actions))
        self._run_control_step()

    def advance_valves(self, command_bar: np.ndarray, valves: np.ndarray) -> None:
        """One control step of a ``wheel_rail`` fleet: the brake control's pressure command per
        axle (N, axles) and the WSP valve commands (N, valves), each VALVE_DUMP, VALVE_HOLD or
        VALVE_APPLY (:mod:`brakegym.physics.pneumatics`)."""
        if self.adhesion is None:
            raise RuntimeError(f"environment {self.config.name!r} has no WSP valves (its config has no wheel_rail)")
        self.pressure.set_command(command_bar)
        self.pressure.set_valves(valves)
        self._run_control_step()

    def _run_control_step(self) -> None:
        sim = self.sim
        speed_before = sim.train[SPEED].copy()
        sim.step(self.substeps)
        # What a brake control unit derives from its speed sensor: the mean deceleration of the
        # control step. A train that stopped inside the step decelerated over part of it only.
        previous_deceleration = self.deceleration_mps2
        stop_time_s = sim.stop_time_s
        if np.isnan(stop_time_s).all():
            # No train at standstill (the usual case): all decelerated over the whole step.
            self.deceleration_mps2 = (speed_before - sim.train[SPEED]) / self.control_step_s
        else:
            elapsed = np.where(np.isnan(stop_time_s), self.control_step_s, 0.0)
            stopped_now = ~np.isnan(stop_time_s) & (speed_before > 0)
            if stopped_now.any():
                elapsed[stopped_now] = np.maximum(stop_time_s[stopped_now] - (sim.time_s - self.control_step_s), 1e-9)
            self.deceleration_mps2 = np.divide(
                speed_before - sim.train[SPEED], elapsed, out=np.zeros(self.n_trains), where=elapsed > 0
            )
        episodes = self.episodes
        episodes.step += 1
        # The first step's change from rest is the brake's onset, not jerk.
        jerk = np.abs(self.deceleration_mps2 - previous_deceleration) / self.control_step_s
        self.jerk_mps3 = np.where(episodes.step == 1, 0.0, jerk)
        np.maximum(episodes.peak_jerk_mps3, self.jerk_mps3, out=episodes.peak_jerk_mps3)
        if self.temperature_lag_s is not None:
            self._lag_temperature_sensors()
        self.hottest_friction_temperature_C = sim.disc[T_FRIC].reshape(-1, self.n_trains).max(axis=0) - ZERO_CELSIUS_K
        np.maximum(
            episodes.peak_friction_temperature_C,
            self.hottest_friction_temperature_C,
            out=episodes.peak_friction_temperature_C,
        )

    def _observed_temperature_C(self) -> np.ndarray:
        """(N, observed discs), the true friction-surface temperatures the sensors see."""
        return self.sim.disc[T_FRIC].reshape(-1, self.n_trains)[self._observed_rows].T - ZERO_CELSIUS_K

    def _lag_temperature_sensors(self) -> None:
        """tau dy/dt = u - y over the control step h, exact for u linear within it (as
        :func:`brakegym.recordings.measurement.first_order_lag`):
        y' = u' + a (y - u) - (u' - u) tau (1 - a) / h, a = exp(-h / tau); tau = 0 gives y' = u'."""
        h, tau = self.control_step_s, self.temperature_lag_s
        with np.errstate(divide="ignore"):
            decay = np.exp(-h / tau)
        new_C = self._observed_temperature_C()
        change = new_C - self._true_temperature_C
        self._lagged_temperature_C = (
            new_C + decay * (self._lagged_temperature_C - self._true_temperature_C) - change * (tau * (1.0 - decay) / h)
        )
        self._true_temperature_C = new_C

    # -------------------------------------------------------------------------------------------
    @property
    def speed_mps(self) -> np.ndarray:
        return self.sim.train[SPEED]

    @property
    def position_m(self) -> np.ndarray:
        return self.sim.train[POSITION]

    def odometry_m(self) -> np.ndarray:
        """Distance travelled as the train's odometry counts it (a speed-sensor scale scales it)."""
        position = self.sim.train[POSITION]
        return position if self.speed_scale is None else self.speed_scale * position

    @property
    def standstill(self) -> np.ndarray:
        return ~self.sim.moving

    @property
    def time_s(self) -> np.ndarray:
        return self.episodes.step * self.control_step_s

    def friction_temperature_C(self) -> np.ndarray:
        """(N, discs), the friction-surface temperature T_fric."""
        return self.sim.to_external(self.sim.disc[T_FRIC]) - ZERO_CELSIUS_K

    def measure(self, draws: np.ndarray, out: np.ndarray) -> dict[str, np.ndarray]:
        """The sensor channels with noise, written into ``out`` (N, ``n_measured_channels``):
        speed, deceleration, cylinder pressures (N, axles) and the observed disc temperatures
        (N, observed discs); ``draws`` are standard-normal numbers (N, channels + 1), the last
        column for the distance sensor. Returns the channels by name (views of ``out``) and
        ``distance_noise_m``."""
        noise = self.config.sensor_noise
        n, axles = self.n_trains, self.plant.n_axles
        pressure = slice(2, 2 + axles)
        temperature = slice(2 + axles, self.n_measured_channels)
        out[:, 0] = self.sim.train[SPEED]
        out[:, 1] = self.deceleration_mps2
        if self.speed_scale is not None:  # the deceleration is derived from the speed sensor
            out[:, :2] *= self.speed_scale[:, None]
        out[:, pressure] = self.pressure.pressure_bar
        if self.temperature_lag_s is None:
            np.subtract(
                self.sim.disc[T_FRIC].reshape(-1, n)[self._observed_rows].T, ZERO_CELSIUS_K, out=out[:, temperature]
            )
        else:
            out[:, temperature] = self._lagged_temperature_C
        # true value + noise standard deviation * draw, for all channels in one go.
        out += draws[:, :-1] * self._noise_per_channel
        return {
            "speed_mps": out[:, 0],
            "decel_mps2": out[:, 1],
            "pressure_bar": out[:, pressure],
            "temperature_C": out[:, temperature],
            "distance_noise_m": noise.distance_m * draws[:, -1],
        }

    def physical_state(self, train: int | None = None) -> dict[str, Any]:
        """The true state, for analysis (``info``): per-disc mu and temperatures, position, ...
        Arrays over the trains (copies), or with ``train`` that train's entries: numpy scalars and
        per-axle or per-disc rows (copies), without building the arrays of all trains first."""
        sim, n, pressure = self.sim, self.n_trains, self.pressure
        # mu, T_fric and T_disc (consecutive rows of the packed disc state) in one copy:
        # (3, N, discs) over the trains, (3, discs) for one train.
        per_disc = sim.disc[REPORTED_DISC_STATES].reshape(3, -1, n)
        if train is None:
            per_train = per_axle = operator.methodcaller("copy")
            per_disc = per_disc.transpose(0, 2, 1).copy()
        else:
            per_train = operator.itemgetter(train)  # a numpy scalar holds its value, not a view
            per_axle = lambda values: values[train].copy()  # noqa: E731
            per_disc = per_disc[:, :, train].copy()
        per_disc[1:] -= ZERO_CELSIUS_K
        mu, friction_C, disc_C = per_disc
        return {
            "time_s": per_train(self.time_s),
            "speed_mps": per_train(sim.train[SPEED]),
            "position_m": per_train(sim.train[POSITION]),
            "deceleration_mps2": per_train(self.deceleration_mps2),
            "cylinder_pressure_bar": per_axle(pressure.pressure_bar),
            "command_bar": per_axle(pressure.command_bar),
            "mu": mu,
            "friction_temperature_C": friction_C,
            "disc_temperature_C": disc_C,
            "mass_kg": per_train(self.episodes.mass_kg),
        }
