"""What each environment asks of the train: its episode draws, extra observations, reward terms
and termination, vectorised over the fleet's N trains.

A task sees the :class:`~brakegym.envs.core.TrainFleet` after each control step and returns named
reward terms (summed into the reward and reported in ``info["reward_terms"]``), which trains
ended (``terminated``) and which of those succeeded.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Mapping

import numpy as np

from .config import BrakeEnvConfig, DecelTrackingConfig, EmergencyStopConfig, StationStopConfig
from .core import TrainFleet, _as_batch

# Above this the "deceleration still needed" of a station stop is out of reach of the brake
# anyway; capping it keeps the tracking term bounded when the train is at or past the mark.
MAX_REQUIRED_DECELERATION_MPS2 = 3.0


def _stopping_deceleration_mps2(speed_mps: np.ndarray, distance_m: np.ndarray, out: np.ndarray) -> None:
    """v^2 / (2 distance), the constant deceleration that stops within ``distance_m``, into
    ``out``: capped at MAX_REQUIRED_DECELERATION_MPS2, and that cap where the distance is not
    positive (at or past the mark)."""
    out.fill(MAX_REQUIRED_DECELERATION_MPS2)
    np.divide(speed_mps**2, 2.0 * distance_m, out=out, where=distance_m > 0)
    np.minimum(out, MAX_REQUIRED_DECELERATION_MPS2, out=out)


@dataclass
class Outcome:
    """The task's verdict after a control step, arrays of length N."""

    reward_terms: dict[str, np.ndarray]
    terminated: np.ndarray
    success: np.ndarray  # meaningful where terminated


def _copies(arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The arrays copied (some are the task's state, which the next step changes)."""
    return {name: values.copy() for name, values in arrays.items()}


def _of_train(arrays: dict[str, np.ndarray], train: int) -> dict[str, Any]:
    """Train ``train``'s entries: numpy scalars, which hold their value."""
    return {name: values[train] for name, values in arrays.items()}


class BrakeTask:
    """Base class: a task draws its episode parameters, adds observation columns and judges."""

    config_name: ClassVar[str]
    #: names and (low, high) bounds of the task's observation columns, after the common ones
    extra_observations: ClassVar[tuple[tuple[str, float, float], ...]] = ()
    #: reset options the task accepts besides the fleet's
    options: ClassVar[tuple[str, ...]] = ()

    def __init__(self, config: BrakeEnvConfig, fleet: TrainFleet):
        self.config = config
        self.fleet = fleet
        self.n = fleet.n_trains

    def restart(self, index: np.ndarray, rng: np.random.Generator, options: Mapping[str, Any]) -> None:
        """Draw this task's episode parameters for trains ``index`` (after the fleet restarted)."""

    def observe(self, measured: Mapping[str, np.ndarray], out: np.ndarray) -> None:
        """Write the extra observation columns into ``out`` (N, len(extra_observations)), from
        the measured channels (:meth:`TrainFleet.measure`)."""

    def judge(self) -> Outcome:
        raise NotImplementedError

    def episode_info(self, train: int | None = None) -> dict[str, Any]:
        """Task quantities for ``info``: arrays over the trains (copies), or with ``train`` that
        train's numbers (numpy scalars)."""
        return {}

    def _jerk_term(self) -> np.ndarray:
        return -self.config.reward.jerk_per_mps3 * self.fleet.jerk_mps3


class StationStop(BrakeTask):
    config_name = "station_stop"
    # The required deceleration is a function of the two measured channels before it, given so
    # that a learning controller need not discover v^2 / 2s itself.
    extra_observations = (("distance_to_go_m", -1000.0, 5000.0), ("required_deceleration_mps2", 0.0, 3.0))
    options = ("distance_to_mark_m",)
    config: StationStopConfig

    def __init__(self, config: StationStopConfig, fleet: TrainFleet):
        super().__init__(config, fleet)
        self.mark_m = np.zeros(self.n)
        self.overran = np.zeros(self.n, dtype=bool)

    def restart(self, index: np.ndarray, rng: np.random.Generator, options: Mapping[str, Any]) -> None:
        config = self.config
        required = rng.uniform(config.required_deceleration_mps2.low, config.required_deceleration_mps2.high, len(index))
        speed = self.fleet.episodes.initial_speed_mps[index]
        mark = speed**2 / (2.0 * required) + speed * config.response_allowance_s
        if "distance_to_mark_m" in options:
            mark = _as_batch(options["distance_to_mark_m"], len(index), "distance_to_mark_m")
            if np.any(~(mark > 0)):
                raise ValueError(f"reset option 'distance_to_mark_m' = {options['distance_to_mark_m']}: must be positive")
        self.mark_m[index] = mark
        self.overran[index] = False

    def distance_to_go_m(self) -> np.ndarray:
        return self.mark_m - self.fleet.position_m

    def required_deceleration_mps2(self) -> np.ndarray:
        """v^2 / (2 distance to go): the constant deceleration that would stop on the mark."""
        needed = np.empty(self.n)
        _stopping_deceleration_mps2(self.fleet.speed_mps, self.distance_to_go_m(), out=needed)
        return needed

    def observe(self, measured: Mapping[str, np.ndarray], out: np.ndarray) -> None:
        # As the train measures it: the mark's distance at the start less its odometry.
        to_go = out[:, 0]
        np.add(self.mark_m - self.fleet.odometry_m(), measured["distance_noise_m"], out=to_go)
        speed = np.maximum(measured["speed_mps"], 0.0)
        _stopping_deceleration_mps2(speed, to_go, out=out[:, 1])

    def stop_error_m(self) -> np.ndarray:
        """Position minus mark: positive past the mark."""
        return self.fleet.position_m - self.mark_m

    def judge(self) -> Outcome:
        config, fleet = self.config, self.fleet
        weights = config.reward
        error = self.stop_error_m()
        abs_error = np.abs(error)
        moving = fleet.sim.moving
        standstill = ~moving
        self.overran |= moving & (error > config.overrun_limit_m)
        terminated = standstill | self.overran
        success = standstill & ~self.overran & (abs_error <= config.success_tolerance_m)
        # Tracking the deceleration still needed, rather than rewarding only the final error,
        # gives a learning signal on every step and favours a steady, comfortable braking curve.
        tracking_error = np.abs(fleet.deceleration_mps2 - self.required_deceleration_mps2())
        tracking = np.where(standstill, 0.0, -weights.tracking_per_mps2_s * tracking_error * fleet.control_step_s)
        if terminated.any():
            terminal_error = np.minimum(abs_error, 50.0)
            accuracy = np.where(
                terminated, weights.stop_success * success - weights.stop_error_per_m * terminal_error, 0.0
            )
        else:  # on most steps no episode ends: the same zeros without computing the terminal terms
            accuracy = np.zeros(self.n)
        return Outcome({"tracking": tracking, "jerk": self._jerk_term(), "stop_accuracy": accuracy}, terminated, success)

    def episode_info(self, train: int | None = None) -> dict[str, Any]:
        info = {
            "distance_to_go_m": self.distance_to_go_m(),
            "stop_error_m": self.stop_error_m(),
            "mark_m": self.mark_m,
            "overran": self.overran,
        }
        return _copies(info) if train is None else _of_train(info, train)


class DecelTracking(BrakeTask):
    config_name = "decel_tracking"
    extra_observations = (("demand_mps2", 0.0, 5.0),)
    options = ("demand_mps2", "demand_hold_s")
    config: DecelTrackingConfig

    def __init__(self, config: DecelTrackingConfig, fleet: TrainFleet):
        super().__init__(config, fleet)
        # Enough segments to cover the longest episode with the shortest holds.
        self.n_segments = int(np.ceil(config.max_episode_time_s / config.demand_hold_s.low)) + 1
        self.switch_time_s = np.zeros((self.n, self.n_segments))
        self.level_mps2 = np.zeros((self.n, self.n_segments))
        self.demand_in_last_step = np.zeros(self.n)
        self.absolute_error_integral = np.zeros(self.n)

    def restart(self, index: np.ndarray, rng: np.random.Generator, options: Mapping[str, Any]) -> None:
        config, n = self.config, len(index)
        levels = np.asarray(config.demand_levels_mps2)[rng.integers(0, len(config.demand_levels_mps2), (n, self.n_segments))]
        holds = rng.uniform(config.demand_hold_s.low, config.demand_hold_s.high, (n, self.n_segments))
        for name, drawn in (("demand_mps2", levels), ("demand_hold_s", holds)):
            if name in options:
                given = np.atleast_1d(np.asarray(options[name], dtype=float))
                if given.ndim != 1 or len(given) > self.n_segments or np.any(~(given > 0)):
                    raise ValueError(f"reset option {name!r} = {options[name]}: need 1..{self.n_segments} positive values")
                drawn[:, : len(given)] = given
                drawn[:, len(given) :] = given[-1]  # the last value holds to the end
        starts = config.first_demand_time_s + np.concatenate([np.zeros((n, 1)), np.cumsum(holds, axis=1)[:, :-1]], axis=1)
        self.switch_time_s[index] = starts
        self.level_mps2[index] = levels
        self.demand_in_last_step[index] = 0.0
        self.absolute_error_integral[index] = 0.0

    def demand_mps2(self, time_s: np.ndarray) -> np.ndarray:
        """The demanded deceleration at ``time_s`` (per train): zero before the first step."""
        segment = (self.switch_time_s <= time_s[:, None] + 1e-9).sum(axis=1) - 1
        level = self.level_mps2[np.arange(self.n), np.maximum(segment, 0)]
        return np.where(segment >= 0, level, 0.0)

    def observe(self, measured: Mapping[str, np.ndarray], out: np.ndarray) -> None:
        out[:, 0] = self.demand_mps2(self.fleet.time_s)

    def judge(self) -> Outcome:
        fleet = self.fleet
        # The demand that held during the step just taken (the one observed before it).
        demand = self.demand_mps2(fleet.time_s - fleet.control_step_s)
        error = np.abs(fleet.deceleration_mps2 - demand)
        moving_part = fleet.sim.moving
        self.absolute_error_integral += np.where(moving_part, error * fleet.control_step_s, 0.0)
        self.demand_in_last_step = demand
        tracking = np.where(moving_part, -self.config.reward.tracking_per_mps2_s * error * fleet.control_step_s, 0.0)
        terminated = fleet.standstill
        return Outcome({"tracking": tracking, "jerk": self._jerk_term()}, terminated, terminated.copy())

    def episode_info(self, train: int | None = None) -> dict[str, Any]:
        time_s = np.maximum(self.fleet.time_s, self.fleet.control_step_s)
        info = {
            "demand_mps2": self.demand_in_last_step,
            "mean_abs_tracking_error_mps2": self.absolute_error_integral / time_s,
        }
        return _copies(info) if train is None else _of_train(info, train)


class EmergencyStop(BrakeTask):
    config_name = "emergency_stop"
    config: EmergencyStopConfig

    def __init__(self, config: EmergencyStopConfig, fleet: TrainFleet):
        super().__init__(config, fleet)
        self.previous_position_m = np.zeros(self.n)
        self.overheated = np.zeros(self.n, dtype=bool)

    def restart(self, index: np.ndarray, rng: np.random.Generator, options: Mapping[str, Any]) -> None:
        self.previous_position_m[index] = 0.0
        self.overheated[index] = False

    def judge(self) -> Outcome:
        config, fleet = self.config, self.fleet
        self.overheated |= fleet.hottest_friction_temperature_C > config.disc_temperature_limit_C
        travelled = fleet.position_m - self.previous_position_m
        self.previous_position_m = fleet.position_m.copy()
        standstill = fleet.standstill
        terminated = standstill | self.overheated
        success = standstill & ~self.overheated
        terms = {
            "distance": -config.reward.distance_per_km * travelled / 1000.0,
            "overheat": np.where(self.overheated, -config.reward.overheat, 0.0),
        }
        return Outcome(terms, terminated, success)

    def episode_info(self, train: int | None = None) -> dict[str, Any]:
        info = {"braking_distance_m": self.fleet.position_m, "overheated": self.overheated}
        return _copies(info) if train is None else _of_train(info, train)


TASKS: dict[str, type[BrakeTask]] = {task.config_name: task for task in (StationStop, DecelTracking, EmergencyStop)}
