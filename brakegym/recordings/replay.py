"""Replay: simulate a recording from its own inputs, and compare every measured channel.

Inputs taken from the recording: the initial speed (first speed sample, over the speed sensor's
scale when an effect says it is off), the measured cylinder pressure of every axle (as measured,
not clipped: the caliper's dead band handles readings near zero), the initial disc temperature
(``initial_disc_C``, else the first ``T_disc_C`` sample), the ambient temperature and the mass
(load or ``mass_kg``). Friction is nominal (DS: the material's mu_0 and a on every disc), the
running resistance nominal. Effects (:mod:`.effects`) and the initial speed and disc temperature
(nuisance parameters of a fit) can be overridden.

The time grid: the simulator integrates with its fixed step and :mod:`.measurement` interpolates
the states to the recording's own sample instants, so uneven sampling costs nothing. The step is
``REPLAY_STEP_S`` = 0.1 s, not the campaigns' 0.2 s: a replay is compared sample by sample with
sensor noise of 0.03 m/s and 0.02 m/s^2, and against a 0.05 s reference of a 120 km/h stop,
0.2 s left systematic errors of that size (speed 0.015 m/s, deceleration 0.04 m/s^2 and disc
temperature 0.07 K between grid points at brake onset, 0.3 m of stop distance) that a diagnosis
would read as an effect; 0.1 s leaves 0.003 m/s, 0.0002 m/s^2, 0.02 K and 0.06 m, a tenth of the
noise, at twice the cost. The pressure
traces are resampled onto the half-step grid, the only instants at which RK4 evaluates them:
each recording then sees exactly the linear interpolation of its own samples, and a batch of
recordings with different sample instants shares one simulator run.

A missing pressure sample (blank cell) is bridged by the same linear interpolation between the
samples around it; before the first and after the last sample the pressure is held.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import pandas as pd

from .. import config as cfg
from ..applications import MAX_STOP_TIME_S
from ..effects import Effect, EffectedModel, apply_effects
from ..effects.hooks import GradientProfileForce
from ..physics.scatter import FrictionDraw
from ..plants import train_plant
from ..simulator import BatchConditions, PrescribedPressure, PressureSource, Simulator
from ..simulator.state import FRICTION_HEAT, MU, T_FRIC
from ..simulator.state import POSITION as POSITION_STATE
from ..simulator.state import SPEED as SPEED_STATE
from ..units import STANDARD_GRAVITY_MPS2, ZERO_CELSIUS_K
from .columns import DECEL, DISC_TEMPERATURE, POSITION, SPEED, TIME
from .format import Recording
from .measurement import GridTrajectory, MeasurementModel
from .metadata import GradientProfile
from .problems import RecordingError

CHANNELS = (SPEED, DECEL, DISC_TEMPERATURE, POSITION)
REPLAY_STEP_S = 0.1
HALF_SPEED_SQUARED = "half_speed_squared_m2ps2"  # v^2 / 2, compared over distance
# Below this measured speed a train counts as standing (sensor noise is a few cm/s).
STANDSTILL_SPEED_MPS = 0.1


def simulate_grid(
    model: EffectedModel,
    pressure: PressureSource,
    step_s: float,
    finished: Callable[[Simulator], bool],
    before_step: Callable[[Simulator], None] | None = None,
    max_time_s: float = MAX_STOP_TIME_S,
    simulator_class: type[Simulator] = Simulator,
) -> GridTrajectory:
    """Run ``model`` from t = 0 until ``finished(sim)`` and keep the states at every step.
    ``before_step(sim)`` may set commands (a :class:`~brakegym.applications.CommandSchedule`);
    ``simulator_class`` integrates (the compiled simulator, or the numpy reference)."""
    sim = model.simulator(pressure, step_s, simulator_class)
    discs, trains, decels, pressures = [], [], [], []

    def keep() -> None:
        discs.append(sim.disc.copy())
        trains.append(sim.train.copy())
        decels.append(sim.deceleration_mps2())
        pressures.append(np.array(sim.pressure.pressure_bar, dtype=float))

    keep()
    while not finished(sim):
        if sim.time_s > max_time_s:
            raise RuntimeError(f"simulation still running after {max_time_s} s")
        if before_step is not None:
            before_step(sim)
        sim.step()
        keep()
    return _grid(sim, step_s, np.stack(discs), np.stack(trains), np.stack(decels), np.stack(pressures))


def simulate_steps(model: EffectedModel, pressure: PrescribedPressure, step_s: float, n_steps: int) -> GridTrajectory:
    """:func:`simulate_grid` for ``n_steps`` steps of a prescribed pressure: the same numbers,
    with the steps in one compiled call where no hook depends on the state (a replay's fit runs
    thousands of these, and one Python call per step would be most of its time)."""
    sim = model.simulator(pressure, step_s)
    if sim.has_hooks or n_steps < 1:
        return simulate_grid(model, pressure, step_s, finished=lambda s: s.step_index >= n_steps)
    if (n_steps - 1) * step_s > MAX_STOP_TIME_S:  # where simulate_grid's loop would stop
        raise RuntimeError(f"simulation still running after {MAX_STOP_TIME_S} s")
    pressures = pressure.half_step_pressures_bar(n_steps)[0::2]  # (n_steps + 1, B, A), at the steps
    discs, trains, movings = sim.trajectory(n_steps)
    decels = np.stack([sim.deceleration_at_mps2(*state) for state in zip(discs, trains, movings, pressures)])
    return _grid(sim, step_s, discs, trains, decels, pressures)


def _grid(
    sim: Simulator, step_s: float, discs: np.ndarray, trains: np.ndarray, decels: np.ndarray, pressures: np.ndarray
) -> GridTrajectory:
    """The grid series from the states at every step: discs (T, 6, A, k, B), trains (T, 6, B),
    decelerations (T, B), cylinder pressures (T, B, A)."""
    n_rows, n_discs = len(discs), sim.plant.n_discs
    return GridTrajectory(
        time_s=np.arange(sim.step_index + 1) * step_s,
        speed_mps=np.ascontiguousarray(trains[:, SPEED_STATE]),
        position_m=np.ascontiguousarray(trains[:, POSITION_STATE]),
        decel_mps2=decels,
        friction_temperature_K=np.ascontiguousarray(discs[:, T_FRIC]).reshape(n_rows, n_discs, -1),
        friction_heat_J=np.ascontiguousarray(discs[:, FRICTION_HEAT]).reshape(n_rows, n_discs, -1),
        clamp_force_N=np.ascontiguousarray(sim.plant.caliper.clamp_force_N(pressures).transpose(0, 2, 1)),
        pressure_bar=np.ascontiguousarray(pressures.transpose(0, 2, 1)),
        mu=sim.plant.friction.bounded(discs[:, MU]).reshape(n_rows, n_discs, -1),
        stop_time_s=sim.stop_time_s.copy(),
    )


def add_gradient_profiles(model: EffectedModel, profiles: Sequence[GradientProfile | None]) -> None:
    """Put each run's known gradient profile (None: level) into ``model``: the force of the
    section under the train among its extra forces (where the measurement model finds it for the
    accelerometer, which does not see it). Nothing changes where no run has a profile."""
    if all(profile is None for profile in profiles):
        return
    if len(profiles) != model.n_trains:
        raise ValueError(f"{len(profiles)} gradient profiles for {model.n_trains} runs: need one each")
    sections = max(len(p.start_m) for p in profiles if p is not None)
    starts = np.full((model.n_trains, sections), np.inf)
    gradients = np.zeros((model.n_trains, sections))
    starts[:, 0] = 0.0
    for b, profile in enumerate(profiles):
        if profile is not None:
            starts[b, : len(profile.start_m)] = profile.start_m
            gradients[b, : len(profile.gradient_permil)] = profile.gradient_permil
    weight_N = np.broadcast_to(np.asarray(model.gravitational_mass_kg, dtype=float), (model.n_trains,))
    model.extra_forces.append(GradientProfileForce(weight_N * STANDARD_GRAVITY_MPS2, starts, gradients))


def bridged_pressures_bar(recording: Recording) -> np.ndarray:
    """The recording's pressures (samples, axles) with missing samples bridged linearly."""
    time = recording.time_s - recording.time_s[0]
    pressures = recording.pressures_bar.copy()
    for axle in range(pressures.shape[1]):
        missing = np.isnan(pressures[:, axle])
        if missing.any():
            pressures[missing, axle] = np.interp(time[missing], time[~missing], pressures[~missing, axle])
    return pressures


@dataclass
class Replay:
    """A recording simulated from its own inputs.

    ``channels``: the recording's channels as its sensors would report the simulation, at its
    sample instants (``time_s`` first), as arrays; ``simulated`` is the same as a DataFrame.
    ``states``: true simulated states at the same instants, the axes along which to locate a
    mismatch. Times are on the recording's clock. The DataFrames and the states are made when
    first asked for: a fit replays thousands of times and reads only ``channels``.
    """

    recording: Recording
    channels: dict[str, np.ndarray]
    stop_time_s: float  # simulated standstill on the recording's clock; nan if it did not stop
    initial_speed_mps: float  # true initial speed used
    initial_disc_C: float
    measurement: MeasurementModel

    @cached_property
    def simulated(self) -> pd.DataFrame:
        return pd.DataFrame(self.channels)

    @cached_property
    def states(self) -> pd.DataFrame:
        time = self.recording.time_s
        return _states(self.measurement, time - time[0], time, self.recording.metadata.instrumented_disc)

    def at(self, time_s: np.ndarray) -> dict[str, np.ndarray]:
        """Simulated channels at any instants of the recording's clock."""
        return self.measurement.channels(np.asarray(time_s, dtype=float) - self.recording.time_s[0])


def replay(
    recording: Recording,
    effects: Sequence[Effect] = (),
    initial_speed_mps: float | None = None,
    initial_disc_C: float | None = None,
    step_s: float = REPLAY_STEP_S,
) -> Replay:
    """Simulate one recording; see :func:`replay_batch`."""
    return replay_batch(
        [recording],
        effects,
        None if initial_speed_mps is None else [initial_speed_mps],
        None if initial_disc_C is None else [initial_disc_C],
        step_s,
    )[0]


def replay_batch(
    recordings: Sequence[Recording],
    effects: Sequence[Effect] = (),
    initial_speed_mps: Sequence[float] | np.ndarray | None = None,
    initial_disc_C: Sequence[float] | np.ndarray | None = None,
    step_s: float = REPLAY_STEP_S,
    friction_draw: FrictionDraw | None = None,
    running_resistance_deviation_N: np.ndarray | None = None,
) -> list[Replay]:
    """Simulate recordings of one vehicle in one batch, with ``effects`` switched on (their
    parameters scalars, or one value per recording).

    ``initial_speed_mps`` (true speed) and ``initial_disc_C``, one value per recording (nan: the
    recording's own), override the initial state. ``friction_draw`` (per disc, shape
    (recordings, axles, discs per axle)) replaces the material's nominal mu_0 and a, and
    ``running_resistance_deviation_N`` (one per recording) is added to the running resistance's A
    after the effects (a set-wide ``running_resistance`` effect included): a drawn scatter, as a
    campaign draws it, or an application's own deviation, as the diagnosis fits it. A
    recording's known gradient profile (its metadata's ``gradient_profile``, or its run's part
    of ``line_gradient_profile``) is part of the model, not an effect.
    """
    if not recordings:
        raise ValueError("replay_batch needs at least one recording")
    vehicle = recordings[0].vehicle
    for recording in recordings[1:]:
        if recording.vehicle != vehicle:
            raise ValueError(
                f"{recording.name}: vehicle {recording.vehicle.name!r} differs from {recordings[0].name}'s "
                f"{vehicle.name!r}; replay recordings of different vehicles in separate batches"
            )
    n = len(recordings)
    plant = train_plant(vehicle)
    material = cfg.load("materials", vehicle.material)
    disc_shape = (n, *plant.disc_shape)

    overrides_T = _overrides(initial_disc_C, n, "initial_disc_C")
    initial_C = np.empty(n)
    for b, recording in enumerate(recordings):
        value = overrides_T[b] if np.isfinite(overrides_T[b]) else recording.initial_disc_C
        if value is None:
            raise RecordingError(
                f"{recording.name}: no initial disc temperature: give 'initial_disc_C' in the metadata or a "
                f"{DISC_TEMPERATURE} sample on the first line"
            )
        initial_C[b] = value
    if friction_draw is None:
        friction_draw = FrictionDraw(
            np.full(disc_shape, material.initial_mu), np.full(disc_shape, material.power_coefficient_per_s)
        )
    if (
        np.shape(friction_draw.initial_mu) != disc_shape
        or np.shape(friction_draw.power_coefficient_per_s) != disc_shape
    ):
        raise ValueError(f"friction_draw: per-disc arrays of shape {disc_shape} expected for {n} recordings")
    if running_resistance_deviation_N is None:
        running_resistance_deviation_N = np.zeros(n)
    if np.shape(running_resistance_deviation_N) != (n,):
        raise ValueError(f"running_resistance_deviation_N: one value per recording ({n}) expected")
    conditions = BatchConditions(
        mass_kg=np.array([r.mass_kg for r in recordings]),
        initial_speed_mps=np.zeros(n),
        initial_mu=np.asarray(friction_draw.initial_mu, dtype=float),
        power_coefficient_per_s=np.asarray(friction_draw.power_coefficient_per_s, dtype=float),
        running_resistance_A_N=np.full(n, vehicle.running_resistance.A_N),
        initial_friction_temperature_K=np.broadcast_to((initial_C + ZERO_CELSIUS_K)[:, None, None], disc_shape).copy(),
        initial_disc_temperature_K=np.broadcast_to((initial_C + ZERO_CELSIUS_K)[:, None, None], disc_shape).copy(),
        ambient_temperature_K=np.array([r.metadata.ambient_C + ZERO_CELSIUS_K for r in recordings]),
    )
    model = apply_effects(
        plant,
        conditions,
        effects,
        line_position_at_start_m=np.array([r.metadata.line_position_m or 0.0 for r in recordings]),
        line_direction_sign=np.array([r.metadata.line_direction_sign for r in recordings]),
    )
    add_gradient_profiles(model, [r.metadata.run_gradient_profile for r in recordings])
    resistance_A_N = np.asarray(model.conditions.running_resistance_A_N, dtype=float)
    deviation_N = np.asarray(running_resistance_deviation_N, dtype=float)
    model.conditions = dataclasses.replace(model.conditions, running_resistance_A_N=resistance_A_N + deviation_N)

    # The true initial speed: the first speed sample seen through the (possibly scaled) sensor.
    overrides_v = _overrides(initial_speed_mps, n, "initial_speed_mps")
    scale = np.broadcast_to(model.sensors.speed_scale, (n,))
    initial_v = np.empty(n)
    for b, recording in enumerate(recordings):
        if np.isfinite(overrides_v[b]):
            initial_v[b] = overrides_v[b]
        elif np.isnan(recording.speed_mps[0]):
            raise RecordingError(
                f"{recording.name}: line {recording.line_of(0)}: the first {SPEED} sample is blank; replay needs "
                "the initial speed (or pass initial_speed_mps)"
            )
        else:
            initial_v[b] = recording.speed_mps[0] / scale[b]
    if np.any(initial_v < 0):
        raise ValueError(f"initial speeds {initial_v[initial_v < 0]} must not be negative")
    model.conditions = dataclasses.replace(model.conditions, initial_speed_mps=initial_v)

    duration = max(float(r.time_s[-1] - r.time_s[0]) for r in recordings)
    n_steps = int(np.ceil(duration / step_s - 1e-9))
    knots = np.arange(2 * n_steps + 1) * (0.5 * step_s)
    trace = np.empty((len(knots), n, plant.n_axles))
    for b, recording in enumerate(recordings):
        time = recording.time_s - recording.time_s[0]
        pressures = bridged_pressures_bar(recording)
        for axle in range(plant.n_axles):
            trace[:, b, axle] = np.interp(knots, time, pressures[:, axle])
    pressure = PrescribedPressure(knots, trace, step_s)
    grid = simulate_steps(model, pressure, step_s, n_steps)

    replays = []
    for b, recording in enumerate(recordings):
        meta = recording.metadata
        measurement = MeasurementModel(grid, b, model, meta.decel_source, meta.instrumented_disc)
        time = recording.time_s
        relative = time - time[0]
        replays.append(
            Replay(
                recording=recording,
                channels={TIME: time, **measurement.channels(relative)},
                stop_time_s=float(grid.stop_time_s[b] + time[0]),
                initial_speed_mps=float(initial_v[b]),
                initial_disc_C=float(initial_C[b]),
                measurement=measurement,
            )
        )
    return replays


def _overrides(values: Sequence[float] | np.ndarray | None, n: int, what: str) -> np.ndarray:
    if values is None:
        return np.full(n, np.nan)
    array = np.asarray(values, dtype=float)
    if array.shape != (n,):
        raise ValueError(f"{what}: expected one value per recording ({n}), got shape {array.shape}")
    return array


def _states(measurement: MeasurementModel, relative: np.ndarray, time: np.ndarray, disc: int | None) -> pd.DataFrame:
    grid, b = measurement.grid, measurement.index
    speed, position, decel = measurement.kinematics(relative)
    heat = grid.friction_heat_J[:, :, b]
    states = {
        TIME: time,
        "true_speed_mps": speed,
        "true_position_m": position,
        "true_decel_mps2": decel,
        "time_since_start_s": relative,
        "clamp_force_kN": measurement.disc_state(grid.clamp_force_N[:, :, b].mean(axis=1), relative) * 1e-3,
        "mu_mean": measurement.disc_state(grid.mu[:, :, b].mean(axis=1), relative),
        "friction_heat_MJ_per_disc": measurement.disc_state(heat.mean(axis=1), relative) * 1e-6,
    }
    if disc is not None:
        states["T_fric_C"] = measurement.surface_temperature_C(relative)
        states["instrumented_disc_heat_MJ"] = measurement.disc_state(heat[:, disc - 1], relative) * 1e-6
    return pd.DataFrame(states)


# ------------------------------------------------------------------------------------------------
# Comparison


def _rms(values: np.ndarray) -> float:
    valid = values[~np.isnan(values)]
    return float(np.sqrt(np.mean(valid**2))) if valid.size else float("nan")


def _integral(time_s: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Cumulative trapezoid integral of ``values`` over ``time_s`` using the samples that are not
    missing (gaps bridged linearly), evaluated at every instant; nan before the first sample."""
    valid = ~np.isnan(values)
    out = np.full(len(time_s), np.nan)
    if valid.sum() < 2:
        return out
    t, v = time_s[valid], values[valid]
    cumulative = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    inside = time_s >= t[0]
    out[inside] = np.interp(time_s[inside], t, cumulative)
    return out


def standstill_index(speed_mps: np.ndarray, threshold_mps: float = STANDSTILL_SPEED_MPS) -> int | None:
    """First sample from which the (measured) speed stays below ``threshold_mps`` after moving;
    None when the recording does not end standing still."""
    valid = np.flatnonzero(~np.isnan(speed_mps))
    moving = valid[speed_mps[valid] >= threshold_mps]
    if moving.size == 0:
        return None
    after = valid[valid > moving[-1]]
    return int(after[0]) if after.size else None


def measured_distance_m(recording: Recording) -> np.ndarray:
    """The recording's distance travelled: its ``position_m`` channel, else the integral of its
    speed."""
    position = recording.channel(POSITION)
    if position is not None:
        return position
    return _integral(recording.time_s, recording.speed_mps)


@dataclass
class Comparison:
    """Measured minus simulated, per channel, in time and over distance.

    ``residuals``: at every sample (``time_s`` first), nan where a sample is missing.
    ``distance_residuals``: at the samples before standstill, each compared with the simulation at
    the instant it had covered the same (measured) distance, indexed by ``position_m``; ``time_s``
    there is how much later the measurement reached that distance, ``half_speed_squared_m2ps2``
    the residual of v^2 / 2 (smooth up to standstill, unlike speed). Traces that stop at different
    instants leave spikes at the end in time, not over distance.
    """

    replay: Replay
    residuals: pd.DataFrame
    rms: dict[str, float]
    distance_residuals: pd.DataFrame
    distance_rms: dict[str, float]
    stop_distance_measured_m: float
    stop_distance_simulated_m: float

    @property
    def stop_distance_error_m(self) -> float:
        """Simulated minus measured distance to standstill."""
        return self.stop_distance_simulated_m - self.stop_distance_measured_m


def compare(replayed: Replay) -> Comparison:
    """Residuals of every channel the recording has."""
    recording = replayed.recording
    channels = [c for c in CHANNELS if c in recording.data.columns and c in replayed.simulated.columns]
    residuals = {TIME: recording.time_s}
    for channel in channels:
        residuals[channel] = recording.channel(channel) - replayed.simulated[channel].to_numpy()
    residual_frame = pd.DataFrame(residuals)

    # Over distance: the simulation at the instant it had covered each sample's distance.
    measurement = replayed.measurement
    t0 = recording.time_s[0]
    distance = measured_distance_m(recording)
    stop = standstill_index(recording.speed_mps)
    # The moving samples: up to the last one before standstill.
    rows = np.arange(len(recording) if stop is None else stop)
    rows = rows[~np.isnan(distance[rows])]
    grid_t = measurement.grid.time_s
    sim_stop = measurement.stop_time_s
    moving_t = grid_t if not np.isfinite(sim_stop) else np.append(grid_t[grid_t < sim_stop], sim_stop)
    sim_distance = measurement.channels(moving_t)[POSITION]
    # Strictly increasing while moving; a train standing at the start has nothing to invert.
    keep = np.concatenate([[True], np.diff(sim_distance) > 0])
    moving_t, sim_distance = moving_t[keep], sim_distance[keep]
    # Both distances count from the start of the recording (spec), so no alignment is needed.
    sim_time = np.interp(distance[rows], sim_distance, moving_t) if moving_t.size > 1 else np.zeros(len(rows))
    at_distance = measurement.channels(sim_time)
    if np.isfinite(sim_stop):
        # Where the simulation stopped short of a distance, compare with the deceleration it had
        # while still moving, not with standstill: otherwise the end leaves a step-sized spike.
        just_before = np.minimum(sim_time, np.nextafter(sim_stop, -np.inf))
        at_distance[DECEL] = measurement.channels(just_before).get(DECEL, at_distance.get(DECEL))
    by_distance = {POSITION: distance[rows], TIME: (recording.time_s[rows] - t0) - sim_time}
    for channel in channels:
        if channel != POSITION:
            by_distance[channel] = recording.channel(channel)[rows] - at_distance[channel]
    # Speed over distance is steep near standstill (dv/dx = -decel / v): a few cm of distance
    # error make large speed residuals on the last samples. Half the squared speed, the integral
    # of the deceleration over distance, stays smooth to the end.
    by_distance[HALF_SPEED_SQUARED] = 0.5 * (recording.speed_mps[rows] ** 2 - at_distance[SPEED] ** 2)
    distance_frame = pd.DataFrame(by_distance)

    measured_stop = float(distance[stop]) if stop is not None else float("nan")
    simulated_stop = (
        float(measurement.channels(np.array([sim_stop]))[POSITION][0]) if np.isfinite(sim_stop) else float("nan")
    )
    return Comparison(
        replay=replayed,
        residuals=residual_frame,
        rms={c: _rms(residual_frame[c].to_numpy()) for c in channels},
        distance_residuals=distance_frame,
        distance_rms={c: _rms(distance_frame[c].to_numpy()) for c in distance_frame.columns if c != POSITION},
        stop_distance_measured_m=measured_stop,
        stop_distance_simulated_m=simulated_stop,
    )


# ------------------------------------------------------------------------------------------------
# Kinematic consistency of the measured channels


@dataclass
class KinematicConsistency:
    """How well the measured channels agree with each other, model-free.

    Speed against deceleration, while moving: v(t) = v0 - gain * integral(decel) - offset * t.
    An accelerometer on a gradient gives offset = g x gradient (it does not see the slope, the
    speed does); a speed sensor with a wheel-diameter error gives gain = scale against an
    accelerometer. Position against speed: x(t) = x0 + gain * integral(v); a wheel-diameter
    error scales both, so the gain stays 1 there. ``*_rms`` are the residuals of these fits;
    nan where a channel is missing.
    """

    decel_gain: float
    decel_offset_mps2: float
    speed_vs_decel_rms_mps: float
    speed_vs_decel_samples: int
    position_gain: float
    position_vs_speed_rms_m: float
    position_vs_speed_samples: int


def kinematic_consistency(recording: Recording, standstill_mps: float = STANDSTILL_SPEED_MPS) -> KinematicConsistency:
    time, speed = recording.time_s, recording.speed_mps
    nan = float("nan")
    decel_fit: tuple[float, float, float, int] = (nan, nan, nan, 0)
    decel = recording.channel(DECEL)
    if decel is not None:
        stop = standstill_index(speed, standstill_mps)
        moving = np.arange(len(time)) <= (len(time) - 1 if stop is None else stop)
        integral = _integral(time, np.where(moving, decel, np.nan))
        use = moving & ~np.isnan(speed) & ~np.isnan(integral)
        if use.sum() >= 4:
            design = np.column_stack([np.ones(use.sum()), -integral[use], -(time[use] - time[0])])
            coefficients, *_ = np.linalg.lstsq(design, speed[use], rcond=None)
            residual = speed[use] - design @ coefficients
            decel_fit = (float(coefficients[1]), float(coefficients[2]), _rms(residual), int(use.sum()))
    position_fit: tuple[float, float, int] = (nan, nan, 0)
    position = recording.channel(POSITION)
    if position is not None:
        integral = _integral(time, speed)
        use = ~np.isnan(position) & ~np.isnan(integral)
        if use.sum() >= 3:
            design = np.column_stack([np.ones(use.sum()), integral[use]])
            coefficients, *_ = np.linalg.lstsq(design, position[use], rcond=None)
            position_fit = (float(coefficients[1]), _rms(position[use] - design @ coefficients), int(use.sum()))
    return KinematicConsistency(*decel_fit, *position_fit)
