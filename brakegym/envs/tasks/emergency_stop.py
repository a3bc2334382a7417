"""``brakegym/EmergencyStop-v0``: stop as short as possible without any disc exceeding its
temperature limit.

Observation: the common columns (:mod:`brakegym.envs.env`) only.

Reward terms: ``distance`` (-per km travelled), ``overheat`` (-penalty once a disc exceeds
``disc_temperature_limit_C``).

Termination: standstill, or a disc over its limit. Success: standstill with no disc over the
limit. Info: ``braking_distance_m``, ``overheated``.

Version history: v0, initial release.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from ..config import BrakeEnvConfig
from ..task import BrakeTask, Outcome, copies, of_train

if TYPE_CHECKING:
    from ..fleet import TrainFleet


class EmergencyStopConfig(BrakeEnvConfig):
    """Stop as short as possible without any disc exceeding its temperature limit."""

    disc_temperature_limit_C: float


class EmergencyStop(BrakeTask):
    """The emergency stop (see the module documentation)."""

    env_id = "brakegym/EmergencyStop-v0"
    name = "emergency_stop"
    config_model = EmergencyStopConfig
    metric = ("braking_distance_m", "m")
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
        return copies(info) if train is None else of_train(info, train)
