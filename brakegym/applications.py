"""Brake applications: run stops of configured rigs and trains, and summarise them.

A *brake application* is one stop: the dynamometer braking a load case from its initial speed, or
the train braking from v_0 with a brake mode, load and actuation. Functions here run a whole batch
of applications through one :class:`~brakegym.simulator.Simulator` and return per-application
summaries (and time series on request).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from . import config as cfg
from .defaults import DEFAULT_STEP_S
from .physics import BrakeCylinder, FrictionDraw
from .plants import brake_cylinder, dynamometer_plant, nominal_draw, train_plant
from .simulator import (
    BatchConditions,
    CommandedPressure,
    ExtraForce,
    FrictionModifier,
    Plant,
    Simulator,
    StopMetrics,
)
from .simulator.state import (
    BRAKE_WORK,
    COOLING_HEAT,
    EXTRA_WORK,
    FRICTION_HEAT,
    MU,
    POSITION,
    RESISTANCE_WORK,
    SPEED,
    T_DISC,
    T_FRIC,
)
from .simulator.wheelsets import SLIP_WORK, AdhesionSimulator, WheelRailAdhesion
from .units import ZERO_CELSIUS_K, kmh_to_mps

MAX_STOP_TIME_S = 900.0


@dataclass
class Trajectory:
    """Time series of a batch, sampled every ``record_every`` steps. Arrays are (samples, B, ...)."""

    time_s: np.ndarray
    speed_mps: np.ndarray
    position_m: np.ndarray
    deceleration_mps2: np.ndarray
    pressure_bar: np.ndarray  # (T, B, axles); clamp force in N on the dynamometer
    clamp_force_N: np.ndarray  # (T, B, discs)
    mu: np.ndarray  # (T, B, discs)
    friction_temperature_C: np.ndarray  # (T, B, discs)
    disc_temperature_C: np.ndarray  # (T, B, discs)


class _TrajectoryRecorder:
    def __init__(self, sim: Simulator, every: int):
        self.every = every
        self.rows: dict[str, list[np.ndarray]] = {name: [] for name in Trajectory.__dataclass_fields__}
        self.sample(sim)

    def sample(self, sim: Simulator) -> None:
        pressure = np.array(sim.pressure.pressure_bar, copy=True)
        clamp = np.broadcast_to(sim.clamp_force_N(pressure), sim.disc[MU].shape)
        self.rows["time_s"].append(np.array(sim.time_s))
        self.rows["speed_mps"].append(sim.train[SPEED].copy())
        self.rows["position_m"].append(sim.train[POSITION].copy())
        self.rows["deceleration_mps2"].append(sim.deceleration_mps2())
        self.rows["pressure_bar"].append(pressure)
        self.rows["clamp_force_N"].append(sim.to_external(clamp))
        self.rows["mu"].append(sim.to_external(sim.disc[MU]))
        self.rows["friction_temperature_C"].append(sim.to_external(sim.disc[T_FRIC]) - ZERO_CELSIUS_K)
        self.rows["disc_temperature_C"].append(sim.to_external(sim.disc[T_DISC]) - ZERO_CELSIUS_K)

    def after_step(self, sim: Simulator) -> None:
        if sim.step_index % self.every == 0:
            self.sample(sim)

    def result(self) -> Trajectory:
        return Trajectory(**{name: np.stack(values) for name, values in self.rows.items()})


class StepObserver(Protocol):
    """Something that follows a run step by step: ``update(sim)`` after each step."""

    def update(self, sim: Simulator) -> None: ...


@dataclass
class StopSummary:
    """Per-application results of a batch of stops. Arrays have the batch as first axis.

    Distances and times count from the start of the simulation; ``braking_distance_m`` and
    ``braking_time_s`` from the brake command (spec Section 6).
    """

    stop_time_s: np.ndarray
    stop_distance_m: np.ndarray
    braking_time_s: np.ndarray
    braking_distance_m: np.ndarray
    onset_distance_m: np.ndarray  # s_2 of Eq. 3: 95 % clamp-force point to standstill
    mu_s: np.ndarray  # (B, discs), Eq. 3 per disc
    mu_s_eff: np.ndarray  # (B,), Eq. 15 averaged over distance
    # Peaks and end values up to the end of the run: each train's standstill, or until_time_s.
    peak_friction_temperature_C: np.ndarray  # (B, discs)
    peak_disc_temperature_C: np.ndarray  # (B, discs)
    initial_kinetic_energy_J: np.ndarray
    brake_work_J: np.ndarray
    resistance_work_J: np.ndarray
    extra_work_J: np.ndarray
    friction_heat_J: np.ndarray  # (B, discs), heat that entered each disc
    stored_heat_J: np.ndarray  # (B, discs), C dT of both capacities at the end
    cooling_heat_J: np.ndarray  # (B, discs), heat given to the air
    trajectory: Trajectory | None = None
    # With wheel-rail adhesion (docs/adhesion.md) only: the treads' slip work on the rail, per axle.
    slip_work_J: np.ndarray | None = None  # (B, axles)

    @property
    def mean_mu_s(self) -> np.ndarray:
        """mu_s averaged over the discs of each application."""
        return self.mu_s.mean(axis=1)

    @property
    def peak_temperature_C(self) -> np.ndarray:
        """Hottest friction surface of each application."""
        return self.peak_friction_temperature_C.max(axis=1)


def run_stops(
    sim: Simulator,
    nominal_clamp_force_N: np.ndarray,
    command: CommandSchedule,
    record_every: int | None = None,
    until_time_s: float | None = None,
    max_time_s: float = MAX_STOP_TIME_S,
    progress: Callable[[int], None] | None = None,
    observers: Sequence[StepObserver] = (),
) -> StopSummary:
    """Step ``sim`` until every train stands still (or until ``until_time_s``), calling
    ``command(sim)`` before each step to set the brake commands and ``observer.update(sim)``
    after it for each of ``observers`` (e.g. :class:`~brakegym.simulator.metrics.SpeedCrossings`).

    Run to standstill, each train is held from its own standstill on (``sim.hold_standing_trains``
    for the run): its summary (peak temperatures, heat stored and given to the air) ends at its
    stop, whatever the other trains of the batch do. Run to ``until_time_s``, standing trains go on
    cooling until then."""
    metrics = StopMetrics(sim, nominal_clamp_force_N)
    recorder = _TrajectoryRecorder(sim, record_every) if record_every else None
    initial_energy = 0.5 * sim.mass_kg * sim.train[SPEED] ** 2
    initial_heat = _stored_heat_J(sim)
    stopped_before = int((~sim.moving).sum())
    held_before = sim.hold_standing_trains
    sim.hold_standing_trains = until_time_s is None
    try:
        while True:
            if until_time_s is None:
                if not sim.moving.any():
                    break
            elif sim.time_s >= until_time_s - 1e-9 * sim.step_s:
                break
            if sim.time_s > max_time_s and sim.moving.any():  # standing trains may cool for longer
                unfinished = np.flatnonzero(sim.moving)
                raise RuntimeError(
                    f"{len(unfinished)} application(s) (first: index {unfinished[0]}) still moving after "
                    f"{max_time_s} s: the brake command never stops them"
                )
            command(sim)
            sim.step()
            metrics.update(sim)
            for observer in observers:
                observer.update(sim)
            if recorder:
                recorder.after_step(sim)
            if progress is not None:
                stopped = int((~sim.moving).sum())
                if stopped > stopped_before:
                    progress(stopped - stopped_before)
                    stopped_before = stopped
    finally:
        sim.hold_standing_trains = held_before

    stop_distance = sim.train[POSITION].copy()
    return StopSummary(
        stop_time_s=sim.stop_time_s.copy(),
        stop_distance_m=stop_distance,
        braking_time_s=sim.stop_time_s - command.command_time_s,
        braking_distance_m=stop_distance - command.position_at_command_m,
        onset_distance_m=metrics.distance_after_onset_m(sim),
        mu_s=metrics.mean_mu_over_distance(sim),
        mu_s_eff=metrics.effective_mu_over_distance(sim),
        peak_friction_temperature_C=sim.to_external(metrics.peak_friction_temperature_K) - ZERO_CELSIUS_K,
        peak_disc_temperature_C=sim.to_external(metrics.peak_disc_temperature_K) - ZERO_CELSIUS_K,
        initial_kinetic_energy_J=initial_energy,
        brake_work_J=sim.train[BRAKE_WORK].copy(),
        resistance_work_J=sim.train[RESISTANCE_WORK].copy(),
        extra_work_J=sim.train[EXTRA_WORK].copy(),
        friction_heat_J=sim.to_external(sim.disc[FRICTION_HEAT]),
        stored_heat_J=sim.to_external(_stored_heat_J(sim) - initial_heat),
        cooling_heat_J=sim.to_external(sim.disc[COOLING_HEAT]),
        trajectory=recorder.result() if recorder else None,
        slip_work_J=sim.wheelset[SLIP_WORK].T.copy() if isinstance(sim, AdhesionSimulator) else None,
    )


def _stored_heat_J(sim: Simulator) -> np.ndarray:
    thermal = sim.plant.thermal
    return (
        thermal.friction_layer_heat_capacity_J_per_K * sim.disc[T_FRIC]
        + thermal.disc_body_heat_capacity_J_per_K * sim.disc[T_DISC]
    )


class CommandSchedule:
    """A constant command per axle switched on at a time per application (the campaigns' case).

    Also remembers each train's position at its command instant, for braking distances.
    """

    def __init__(self, pressure: CommandedPressure, command: np.ndarray, command_time_s: np.ndarray, step_s: float):
        self.pressure = pressure
        self.command = command
        self.command_time_s = np.asarray(command_time_s, dtype=float)
        self.command_step = np.round(self.command_time_s / step_s).astype(np.int64)
        if np.any(np.abs(self.command_step * step_s - self.command_time_s) > 1e-9):
            raise ValueError(f"command times {self.command_time_s} must be whole numbers of steps of {step_s} s")
        self.position_at_command_m = np.zeros(len(command))
        self._released = np.zeros_like(command)

    def __call__(self, sim: Simulator) -> None:
        just_now = sim.step_index == self.command_step
        if just_now.any():
            self.position_at_command_m[just_now] = sim.train[POSITION, just_now]
        active = (sim.step_index >= self.command_step)[:, None]
        self.pressure.set_command(np.where(active, self.command, self._released))


def run_commanded_stops(
    plant: Plant,
    conditions: BatchConditions,
    cylinders: Sequence[BrakeCylinder],
    command: np.ndarray,
    command_time_s: np.ndarray,
    nominal_clamp_force_N: np.ndarray,
    step_s: float = DEFAULT_STEP_S,
    record_every: int | None = None,
    until_time_s: float | None = None,
    extra_forces: Sequence[ExtraForce] = (),
    friction_modifiers: Sequence[FrictionModifier] = (),
    progress: Callable[[int], None] | None = None,
    max_time_s: float = MAX_STOP_TIME_S,
    observers: Sequence[StepObserver] = (),
    adhesion: WheelRailAdhesion | None = None,
) -> StopSummary:
    """Run a batch of stops, each with a constant command (B, A) switched on at its own time;
    with ``adhesion``, on wheelsets that creep on the rail (docs/adhesion.md; no hooks then)."""
    pressure = CommandedPressure(cylinders, plant.n_axles, step_s)
    if adhesion is None:
        sim = Simulator(
            plant, conditions, pressure, step_s=step_s, extra_forces=extra_forces, friction_modifiers=friction_modifiers
        )
    elif extra_forces or friction_modifiers:
        raise ValueError("the adhesion option runs without extra forces and friction modifiers (docs/adhesion.md)")
    else:
        sim = AdhesionSimulator(plant, conditions, pressure, adhesion, step_s=step_s)
    schedule = CommandSchedule(pressure, command, np.asarray(command_time_s, dtype=float), step_s)
    return run_stops(
        sim,
        nominal_clamp_force_N,
        schedule,
        record_every=record_every,
        until_time_s=until_time_s,
        max_time_s=max_time_s,
        progress=progress,
        observers=observers,
    )


# ------------------------------------------------------------------------------------------------
# Dynamometer


def dyno_stops(
    rig: cfg.Dynamometer,
    load_cases: Sequence[cfg.LoadCase],
    draw: FrictionDraw | None = None,
    step_s: float = DEFAULT_STEP_S,
    record_every: int | None = None,
    until_time_s: float | None = None,
    plant: Plant | None = None,
) -> StopSummary:
    """One dynamometer stop per entry of ``load_cases`` (a case may repeat), braking from t = 0
    with the clamp force rising as F_C,nom (1 - exp(-t / tau)).

    ``plant`` replaces the rig's own (:func:`dynamometer_plant`), e.g. with other friction or
    thermal parameters during an identification; ``draw`` then sets mu_0 and a."""
    plant = plant or dynamometer_plant(rig)
    material = cfg.load("materials", rig.material)
    n = len(load_cases)
    draw = draw or nominal_draw(material, n, plant.disc_shape)
    initial_K = rig.initial_disc_temperature_C + ZERO_CELSIUS_K
    conditions = BatchConditions(
        mass_kg=np.array([case.mass_kg for case in load_cases], dtype=float),
        initial_speed_mps=np.array([kmh_to_mps(case.initial_speed_kmh) for case in load_cases]),
        initial_mu=draw.initial_mu,
        power_coefficient_per_s=draw.power_coefficient_per_s,
        running_resistance_A_N=np.zeros(n),
        initial_friction_temperature_K=np.full((n, 1, 1), initial_K),
        initial_disc_temperature_K=np.full((n, 1, 1), initial_K),
        ambient_temperature_K=np.full(n, rig.ambient_temperature_C + ZERO_CELSIUS_K),
    )
    clamp_force = np.array([[case.clamp_force_kN * 1e3] for case in load_cases])
    ramp = BrakeCylinder(dead_time_s=0.0, time_constant_s=rig.clamp_force_time_constant_s)
    return run_commanded_stops(
        plant,
        conditions,
        [ramp] * n,
        command=clamp_force,
        command_time_s=np.zeros(n),
        nominal_clamp_force_N=clamp_force,
        step_s=step_s,
        record_every=record_every,
        until_time_s=until_time_s,
    )


# ------------------------------------------------------------------------------------------------
# Train


@dataclass(frozen=True)
class TrainApplication:
    """One train stop: a constant brake mode held from ``command_time_s`` to standstill."""

    load: str
    brake_mode: str
    actuation: str
    initial_speed_kmh: float
    command_time_s: float = 1.0
    pad_set: str = "1"


def train_conditions(
    vehicle: cfg.Vehicle,
    mass_kg: np.ndarray,
    initial_speed_mps: np.ndarray,
    draw: FrictionDraw,
    running_resistance_A_N: np.ndarray,
) -> BatchConditions:
    """The conditions of a batch of ``vehicle``'s stops, one per entry of ``mass_kg``: the discs
    start at the vehicle's initial disc temperature, the air at its ambient temperature."""
    n = len(mass_kg)
    initial_K = np.full((n, *train_plant(vehicle).disc_shape), vehicle.initial_disc_temperature_C + ZERO_CELSIUS_K)
    return BatchConditions(
        mass_kg=mass_kg,
        initial_speed_mps=initial_speed_mps,
        initial_mu=draw.initial_mu,
        power_coefficient_per_s=draw.power_coefficient_per_s,
        running_resistance_A_N=running_resistance_A_N,
        initial_friction_temperature_K=initial_K,
        initial_disc_temperature_K=initial_K.copy(),
        ambient_temperature_K=np.full(n, vehicle.ambient_temperature_C + ZERO_CELSIUS_K),
    )


def train_stops(
    vehicle: cfg.Vehicle,
    applications: Sequence[TrainApplication],
    draw: FrictionDraw | None = None,
    running_resistance_A_N: np.ndarray | None = None,
    step_s: float = DEFAULT_STEP_S,
    record_every: int | None = None,
    until_time_s: float | None = None,
    extra_forces: Sequence[ExtraForce] = (),
    friction_modifiers: Sequence[FrictionModifier] = (),
    progress: Callable[[int], None] | None = None,
    adhesion: WheelRailAdhesion | None = None,
    observers: Sequence[StepObserver] = (),
) -> StopSummary:
    """Stops of ``vehicle``, one per application: the brake mode's cylinder pressure for the
    load on every axle, through the application's actuation (EP or PN). ``adhesion``
    (:func:`brakegym.plants.wheel_rail_adhesion`) switches on the wheel-rail adhesion option."""
    plant = train_plant(vehicle)
    material = cfg.load("materials", vehicle.material)
    n = len(applications)
    draw = draw or nominal_draw(material, n, plant.disc_shape)
    if running_resistance_A_N is None:
        running_resistance_A_N = np.full(n, vehicle.running_resistance.A_N)
    cylinders_by_name = {}
    for app in applications:
        if app.actuation not in cylinders_by_name:
            cylinders_by_name[app.actuation] = brake_cylinder(cfg.load("pneumatics", app.actuation))
    pressures = np.array([vehicle.brake_pressure_bar(app.brake_mode, app.load) for app in applications])
    command = np.repeat(pressures[:, None], plant.n_axles, axis=1)
    conditions = train_conditions(
        vehicle,
        mass_kg=np.array([vehicle.mass_kg(app.load) for app in applications]),
        initial_speed_mps=np.array([kmh_to_mps(app.initial_speed_kmh) for app in applications]),
        draw=draw,
        running_resistance_A_N=np.asarray(running_resistance_A_N, dtype=float),
    )
    return run_commanded_stops(
        plant,
        conditions,
        [cylinders_by_name[app.actuation] for app in applications],
        command=command,
        command_time_s=np.array([app.command_time_s for app in applications]),
        nominal_clamp_force_N=plant.caliper.clamp_force_N(command),
        step_s=step_s,
        record_every=record_every,
        until_time_s=until_time_s,
        extra_forces=extra_forces,
        friction_modifiers=friction_modifiers,
        progress=progress,
        adhesion=adhesion,
        observers=observers,
    )
