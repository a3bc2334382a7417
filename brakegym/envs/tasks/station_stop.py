"""``brakegym/StationStop-v0``: stop with the train's reference point on the platform mark.

The mark is placed where braking at a drawn constant deceleration (``required_deceleration_mps2``),
after the brake's response time, would stop the train.

Observation: the common columns (:mod:`brakegym.envs.env`), then ``distance_to_go_m`` (the mark's
distance at the start less the train's odometry, with ``sensor_noise.distance_m``) and
``required_deceleration_mps2`` (v^2 / (2 distance to go) from the measured values, capped at
3 m/s^2).

Reward terms: ``tracking`` (``-|deceleration - v^2/(2 distance to go)| dt``), ``jerk``
(``-|change of deceleration| per control step / dt``), ``stop_accuracy`` at the end (+bonus on success, -penalty
per metre of stop error).

Termination: standstill, or passing the mark by more than ``overrun_limit_m``. Success: standstill
within ``success_tolerance_m`` of the mark, never overrun. Reset option: ``distance_to_mark_m``.
Info: ``distance_to_go_m``, ``stop_error_m`` (position minus mark), ``mark_m``, ``overran``.

Version history: v0, initial release.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import Field

from ..config import BrakeEnvConfig, Range
from ..options import option_values
from ..task import BrakeTask, Outcome, copies, of_train

if TYPE_CHECKING:
    from ..fleet import TrainFleet

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


class StationStopConfig(BrakeEnvConfig):
    """The train approaches a platform and stops with its reference point on the mark."""

    # The mark is placed where braking at this constant deceleration, after the brake's
    # response time, stops the train: it sets how hard the task is.
    required_deceleration_mps2: Range
    response_allowance_s: float = Field(ge=0)
    success_tolerance_m: float = Field(gt=0)
    overrun_limit_m: float = Field(gt=0)


class StationStop(BrakeTask):
    """The station stop (see the module documentation)."""

    env_id = "brakegym/StationStop-v0"
    name = "station_stop"
    config_model = StationStopConfig
    metric = ("stop_error_m", "m")
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
        required = rng.uniform(
            config.required_deceleration_mps2.low, config.required_deceleration_mps2.high, len(index)
        )
        speed = self.fleet.episodes.initial_speed_mps[index]
        mark = speed**2 / (2.0 * required) + speed * config.response_allowance_s
        if "distance_to_mark_m" in options:
            mark = option_values(options["distance_to_mark_m"], len(index), "distance_to_mark_m")
            if np.any(~(mark > 0)):
                raise ValueError(
                    f"reset option 'distance_to_mark_m' = {options['distance_to_mark_m']}: must be positive"
                )
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
        return Outcome(
            {"tracking": tracking, "jerk": self._jerk_term(), "stop_accuracy": accuracy}, terminated, success
        )

    def episode_info(self, train: int | None = None) -> dict[str, Any]:
        info = {
            "distance_to_go_m": self.distance_to_go_m(),
            "stop_error_m": self.stop_error_m(),
            "mark_m": self.mark_m,
            "overran": self.overran,
        }
        return copies(info) if train is None else of_train(info, train)
