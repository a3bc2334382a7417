"""``brakegym/DecelTracking-v0``: follow a demanded deceleration, service-brake steps as a brake
control unit receives them.

Observation: the common columns (:mod:`brakegym.envs.env`), then ``demand_mps2`` (the demanded
deceleration, zero before ``first_demand_time_s``).

Reward terms: ``tracking`` (``-|deceleration - demand| dt`` while moving), ``jerk``.

Termination: standstill (always a success). Reset options: ``demand_mps2`` and ``demand_hold_s``
(the levels and holds in order, the last holding to the end). Info: ``demand_mps2`` (the demand of
the step just taken), ``mean_abs_tracking_error_mps2``.

Version history: v0, initial release.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import Field, model_validator

from ..config import BrakeEnvConfig, Range
from ..task import BrakeTask, Outcome, copies, of_train

if TYPE_CHECKING:
    from ..fleet import TrainFleet


class DecelTrackingConfig(BrakeEnvConfig):
    """Follow a demanded deceleration: service-brake steps as a brake control unit receives them."""

    demand_levels_mps2: list[float] = Field(min_length=1)
    first_demand_time_s: float = Field(ge=0)
    demand_hold_s: Range  # how long each level is held

    @model_validator(mode="after")
    def _levels_positive(self) -> DecelTrackingConfig:
        bad = [level for level in self.demand_levels_mps2 if not level > 0]
        if bad:
            raise ValueError(f"demand_levels_mps2 must be positive, got {bad}")
        if self.demand_hold_s.low <= 0:
            raise ValueError(f"demand_hold_s.low = {self.demand_hold_s.low} must be positive")
        return self


class DecelTracking(BrakeTask):
    """The deceleration tracking task (see the module documentation)."""

    env_id = "brakegym/DecelTracking-v0"
    name = "decel_tracking"
    config_model = DecelTrackingConfig
    metric = ("mean_abs_tracking_error_mps2", "m/s2")
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
        levels = np.asarray(config.demand_levels_mps2)[
            rng.integers(0, len(config.demand_levels_mps2), (n, self.n_segments))
        ]
        holds = rng.uniform(config.demand_hold_s.low, config.demand_hold_s.high, (n, self.n_segments))
        for name, drawn in (("demand_mps2", levels), ("demand_hold_s", holds)):
            if name in options:
                given = np.atleast_1d(np.asarray(options[name], dtype=float))
                if given.ndim != 1 or len(given) > self.n_segments or np.any(~(given > 0)):
                    raise ValueError(
                        f"reset option {name!r} = {options[name]}: need 1..{self.n_segments} positive values"
                    )
                drawn[:, : len(given)] = given
                drawn[:, len(given) :] = given[-1]  # the last value holds to the end
        starts = config.first_demand_time_s + np.concatenate(
            [np.zeros((n, 1)), np.cumsum(holds, axis=1)[:, :-1]], axis=1
        )
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
        return copies(info) if train is None else of_train(info, train)
