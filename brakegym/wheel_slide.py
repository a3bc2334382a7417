"""Train stops with wheel-rail adhesion and wheel-slide protection (docs/adhesion.md):
the brake control's pressures through WSP valves per axle or bogie, the valves commanded each step
by a controller (:class:`brakegym.agents.wsp.WspController`), or left at rest (no WSP).

The simulator steps at the controller's step (``control_step_s``, 20 ms by default: WSP controllers
run at 50-100 Hz), so each step holds one valve command.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from . import config as cfg
from .applications import CommandSchedule, StepObserver, StopSummary, TrainApplication, run_stops, train_conditions
from .defaults import DEFAULT_WSP_CONTROL_STEP_S
from .physics import FrictionDraw
from .plants import brake_cylinder, nominal_draw, train_plant, valve_of_axle, wsp_valve
from .simulator import CommandedPressure
from .simulator.pressure import ValvedPressure
from .simulator.state import SPEED
from .simulator.wheelsets import AdhesionSimulator, WheelRailAdhesion
from .units import kmh_to_mps

#: WSP controllers run at 50-100 Hz (``brakegym.defaults.DEFAULT_WSP_CONTROL_STEP_S``).
DEFAULT_CONTROL_STEP_S = DEFAULT_WSP_CONTROL_STEP_S
#: A wheel turning slower than this share of the train speed counts as locked (sliding).
LOCKED_SPEED_RATIO = 0.05
#: Below this train speed no wheel counts as locked (the last metres of every stop).
LOCKED_MIN_TRAIN_SPEED_MPS = 1.0


class LockedTimeObserver:
    """After each step: each axle's time locked (wheel below ``LOCKED_SPEED_RATIO`` of the train
    speed while it runs faster than ``LOCKED_MIN_TRAIN_SPEED_MPS``), the longest unbroken stretch
    and the total, s (B, A); and whether it was locked when the train stopped."""

    def __init__(self, n_trains: int, n_axles: int) -> None:
        self.current_s = np.zeros((n_trains, n_axles))
        self.longest_s = np.zeros((n_trains, n_axles))
        self.total_s = np.zeros((n_trains, n_axles))

    def update(self, sim: AdhesionSimulator) -> None:
        speed = sim.train[SPEED]
        running = sim.moving & (speed > LOCKED_MIN_TRAIN_SPEED_MPS)
        locked = (sim.wheel_speed_mps.T < LOCKED_SPEED_RATIO * speed[:, None]) & running[:, None]
        self.current_s = np.where(locked, self.current_s + sim.step_s, 0.0)
        self.longest_s = np.maximum(self.longest_s, self.current_s)
        self.total_s += np.where(locked, sim.step_s, 0.0)


@dataclass
class BcuMeasurement:
    """What a brake control unit measures of a batch of trains at a control step, as its WSP
    controller reads it: each axle's wheel speed from its speed sensor (m/s at the tread, (B, A)),
    each axle's cylinder pressure (bar, (B, A)), the train's deceleration from its sensor
    (m/s^2, (B,), positive while slowing), the brake control's own pressure demand per axle for
    the coming step (bar, (B, A)), and the true train speed (m/s, (B,)) only for a controller that
    is given it for comparison (``uses_train_speed``); None otherwise, as on a train."""

    wheel_speed_mps: np.ndarray
    cylinder_pressure_bar: np.ndarray
    deceleration_mps2: np.ndarray
    demand_bar: np.ndarray
    train_speed_mps: np.ndarray | None = None


class WspControl(Protocol):
    """A WSP controller as the stops and the environment drive it: the reference
    (:class:`brakegym.agents.wsp.WspController`), a trained policy
    (:func:`brakegym.agents.wsp_policy.load_wsp_controller`) or none
    (:class:`brakegym.agents.wsp_policy.NoWsp`). ``reset`` at the first control step of a batch,
    then ``valves`` at every step: VALVE_DUMP, VALVE_HOLD or VALVE_APPLY per valve (B, valves)."""

    @property
    def uses_train_speed(self) -> bool: ...

    def reset(self, measurement: BcuMeasurement) -> None: ...

    def valves(self, measurement: BcuMeasurement) -> np.ndarray: ...


class _WspCommand:
    """The campaign's brake command, then the valve commands of the controller (none: at rest)."""

    def __init__(self, schedule: CommandSchedule, pressure: ValvedPressure, controller: WspControl | None):
        self.schedule, self.pressure, self.controller = schedule, pressure, controller
        self.command_time_s = schedule.command_time_s
        self.position_at_command_m = schedule.position_at_command_m
        self._started = False
        self._previous_speed_mps: np.ndarray | None = None

    def measurement(self, sim: AdhesionSimulator) -> BcuMeasurement:
        """What the controller reads now: the true wheel speeds, pressures and the mean
        deceleration of the last step (no sensor noise here: the reference's stops of the tests)."""
        speed = sim.train[SPEED]
        previous = speed if self._previous_speed_mps is None else self._previous_speed_mps
        self._previous_speed_mps = speed.copy()
        return BcuMeasurement(
            wheel_speed_mps=sim.wheel_speed_mps.T,
            cylinder_pressure_bar=self.pressure.pressure_bar.copy(),
            deceleration_mps2=(previous - speed) / sim.step_s,
            demand_bar=self.pressure.command_bar.copy(),
            train_speed_mps=speed.copy() if self.controller.uses_train_speed else None,
        )

    def __call__(self, sim: AdhesionSimulator) -> None:
        self.schedule(sim)
        if self.controller is None:
            return
        measurement = self.measurement(sim)
        if not self._started:
            self.controller.reset(measurement)
            self._started = True
        self.pressure.set_valves(self.controller.valves(measurement))


@dataclass
class WspStops:
    """Stops with WSP: the summary, each axle's locked times (:class:`LockedTimeObserver`)."""

    summary: StopSummary
    locked: LockedTimeObserver


def wsp_train_stops(
    vehicle: cfg.Vehicle,
    applications: Sequence[TrainApplication],
    adhesion: WheelRailAdhesion,
    valves: cfg.WspValves,
    make_controller=None,
    control_step_s: float = DEFAULT_CONTROL_STEP_S,
    draw: FrictionDraw | None = None,
    running_resistance_A_N: np.ndarray | None = None,
    observers: Sequence[StepObserver] = (),
) -> WspStops:
    """Stops of ``vehicle`` as :func:`~brakegym.applications.train_stops` runs them, on the rail
    of ``adhesion``, through the WSP ``valves``, commanded by the controller
    ``make_controller(valve_of_axle, control_step_s)`` builds (e.g.
    ``functools.partial(brakegym.agents.wsp.WspController, config)``, or
    :func:`brakegym.agents.wsp_policy.load_wsp_controller` of a trained policy; None: no WSP, the
    valves at rest).

    ``draw`` and ``running_resistance_A_N`` (B,): each stop's disc friction and running resistance
    A (e.g. from :meth:`brakegym.plants.TrainScatter.draw_for_samples`); None: nominal.
    ``observers``: more :class:`~brakegym.applications.StepObserver` s, updated after each step
    after the locked-time observer (e.g. one that records traces). Each stop's own rail:
    ``adhesion``'s ``static_friction_factor``."""
    plant = train_plant(vehicle)
    n = len(applications)
    cylinders = [brake_cylinder(cfg.load("pneumatics", app.actuation)) for app in applications]
    pressures = np.array([vehicle.brake_pressure_bar(app.brake_mode, app.load) for app in applications])
    command = np.repeat(pressures[:, None], plant.n_axles, axis=1)
    conditions = train_conditions(
        vehicle,
        mass_kg=np.array([vehicle.mass_kg(app.load) for app in applications]),
        initial_speed_mps=np.array([kmh_to_mps(app.initial_speed_kmh) for app in applications]),
        draw=nominal_draw(cfg.load("materials", vehicle.material), n, plant.disc_shape) if draw is None else draw,
        running_resistance_A_N=np.full(n, vehicle.running_resistance.A_N)
        if running_resistance_A_N is None
        else np.asarray(running_resistance_A_N, dtype=float),
    )
    axles = valve_of_axle(vehicle, valves)
    pressure = ValvedPressure(CommandedPressure(cylinders, plant.n_axles, control_step_s), wsp_valve(valves), axles)
    sim = AdhesionSimulator(plant, conditions, pressure, adhesion, step_s=control_step_s)
    schedule = CommandSchedule(
        pressure, command, np.array([app.command_time_s for app in applications]), control_step_s
    )
    controller = None if make_controller is None else make_controller(axles, control_step_s)
    locked = LockedTimeObserver(n, plant.n_axles)
    summary = run_stops(
        sim,
        plant.caliper.clamp_force_N(command),
        _WspCommand(schedule, pressure, controller),
        observers=[locked, *observers],
    )
    return WspStops(summary, locked)
