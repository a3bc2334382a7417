"""PID baseline: deceleration control with feed-forward from the nominal friction, anti-windup and
a braking-curve planner for StationStop; a temperature-limiting rule for EmergencyStop.

Vectorised over a batch of trains: ``act(observations)`` takes (N, observation columns) and
returns (N, control groups) actions. All groups receive the same command (the planner has one
deceleration target per train).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field

from .. import config as cfg
from ..envs.config import BrakeEnvConfig
from ..plants import train_plant


class StationStopPlanner(cfg.StrictModel):
    stop_offset_m: float
    min_distance_m: float = Field(gt=0)


class EmergencyLimiter(cfg.StrictModel):
    temperature_margin_C: float = Field(ge=0)
    temperature_band_C: float = Field(gt=0)


class PIDConfig(cfg.StrictModel):
    name: str
    nominal_mu: float = Field(gt=0)
    proportional_gain: float = Field(ge=0)
    integral_gain_per_s: float = Field(ge=0)
    derivative_gain_s: float = Field(ge=0)
    integral_limit_mps2: float = Field(ge=0)
    station_stop: StationStopPlanner
    emergency_stop: EmergencyLimiter


def load_pid_config(path: str | Path | None = None) -> PIDConfig:
    """``agents/pid.yaml`` on the config search path, or the file given, validated."""
    return cfg.load_file(path or cfg.find("agents", "pid"), PIDConfig)


class PIDController:
    """One PID brake controller per train of a batch.

    Parameters
    ----------
    env_config:
        The environment's config (which vehicle, which task, timing).
    observation_names:
        The environment's observation columns, to find speed, deceleration and the task's column.
    gains:
        PID config; ``configs/agents/pid.yaml`` if not given.
    """

    def __init__(self, env_config: BrakeEnvConfig, observation_names: tuple[str, ...], gains: PIDConfig | None = None):
        self.gains = gains or load_pid_config()
        self.env_config = env_config
        self.task = env_config.name
        vehicle = cfg.load("vehicles", env_config.vehicle)
        self.vehicle = vehicle
        plant = train_plant(vehicle)
        self.n_discs = plant.n_discs
        self.radius_ratio = plant.radius_ratio
        self.caliper = plant.caliper
        self.resistance = plant.running_resistance
        self.max_pressure_bar = vehicle.max_cylinder_pressure_bar
        self.dt_s = env_config.control_step_s
        self.n_groups = {"train": 1, "bogie": vehicle.bogies, "axle": vehicle.n_axles}[env_config.control_groups]
        self.column = {name: i for i, name in enumerate(observation_names)}
        self.temperature_columns = [i for name, i in self.column.items() if name.startswith("temperature_C_")]
        self.mass_kg = np.zeros(0)
        self.integral_mps2 = np.zeros(0)
        self.previous_error_mps2 = np.zeros(0)
        self.last_target_mps2 = np.zeros(0)

    def reset(self, info: Mapping[str, Any], index: np.ndarray | None = None) -> None:
        """Start new episodes: ``info["mass_kg"]`` is the load-weighing signal a brake control
        unit has (per train); ``index`` selects the restarted trains of a batch (all if None)."""
        mass = np.atleast_1d(np.asarray(info["mass_kg"], dtype=float))
        if index is None or len(self.mass_kg) != len(mass):
            self.mass_kg = mass.copy()
            n = len(mass)
            self.integral_mps2 = np.zeros(n)
            self.previous_error_mps2 = np.zeros(n)
            self.last_target_mps2 = np.zeros(n)
            return
        self.mass_kg[index] = mass[index]
        self.integral_mps2[index] = 0.0
        self.previous_error_mps2[index] = 0.0
        self.last_target_mps2[index] = 0.0

    def plant_gain_bar_per_mps2(self) -> np.ndarray:
        """Cylinder pressure per m/s^2 of deceleration at the nominal friction (per train)."""
        force_per_bar = self.n_discs * self.gains.nominal_mu * self.caliper.gain_N_per_bar * self.radius_ratio
        return self.mass_kg / force_per_bar

    def feed_forward_bar(self, target_mps2: np.ndarray, speed_mps: np.ndarray) -> np.ndarray:
        """The pressure that gives ``target_mps2`` with nominal friction and running resistance."""
        brake_force = self.mass_kg * target_mps2 - self.resistance.force_N(np.maximum(speed_mps, 0.0))
        pressure = brake_force * (self.plant_gain_bar_per_mps2() / self.mass_kg) + self.caliper.threshold_bar
        return np.where(brake_force > 0, pressure, 0.0)

    def target_deceleration_mps2(self, observation: np.ndarray) -> np.ndarray:
        speed = observation[:, self.column["speed_mps"]]
        if self.task == "station_stop":
            planner = self.gains.station_stop
            to_go = observation[:, self.column["distance_to_go_m"]] + planner.stop_offset_m
            # The constant deceleration that stops on the mark from here: the braking curve.
            target = np.where(
                to_go > planner.min_distance_m,
                np.maximum(speed, 0.0) ** 2 / (2.0 * np.maximum(to_go, planner.min_distance_m)),
                self.last_target_mps2,
            )
            self.last_target_mps2 = target
            return target
        if self.task == "decel_tracking":
            return observation[:, self.column["demand_mps2"]]
        raise ValueError(f"no deceleration target for task {self.task!r}")

    def act(self, observation: np.ndarray) -> np.ndarray:
        observation = np.asarray(observation, dtype=float)
        if self.task == "emergency_stop":
            pressure = self._temperature_limited_bar(observation)
        else:
            pressure = self._decelerate_bar(observation)
        action = 2.0 * pressure / self.max_pressure_bar - 1.0
        return np.repeat(np.clip(action, -1.0, 1.0)[:, None], self.n_groups, axis=1).astype(np.float32)

    def _decelerate_bar(self, observation: np.ndarray) -> np.ndarray:
        gains = self.gains
        speed = observation[:, self.column["speed_mps"]]
        measured = observation[:, self.column["decel_mps2"]]
        target = self.target_deceleration_mps2(observation)
        error = target - measured
        plant_gain = self.plant_gain_bar_per_mps2()
        derivative = (error - self.previous_error_mps2) / self.dt_s
        self.previous_error_mps2 = error
        unsaturated = self.feed_forward_bar(target, speed) + plant_gain * (
            gains.proportional_gain * error
            + gains.integral_gain_per_s * self.integral_mps2
            + gains.derivative_gain_s * derivative
        )
        # Anti-windup: integrate only while the command is not saturated in the error's direction.
        saturated_high = (unsaturated >= self.max_pressure_bar) & (error > 0)
        saturated_low = (unsaturated <= 0.0) & (error < 0)
        integrate = ~(saturated_high | saturated_low)
        self.integral_mps2 = np.where(
            integrate,
            np.clip(self.integral_mps2 + error * self.dt_s, -gains.integral_limit_mps2, gains.integral_limit_mps2),
            self.integral_mps2,
        )
        return np.clip(unsaturated, 0.0, self.max_pressure_bar)

    def _temperature_limited_bar(self, observation: np.ndarray) -> np.ndarray:
        limiter = self.gains.emergency_stop
        limit = self.env_config.disc_temperature_limit_C
        hottest = observation[:, self.temperature_columns].max(axis=1)
        headroom = (limit - limiter.temperature_margin_C - hottest) / limiter.temperature_band_C
        return self.max_pressure_bar * np.clip(headroom, 0.0, 1.0)
