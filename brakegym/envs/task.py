"""What each environment asks of the train: its episode draws, extra observations, reward terms
and termination, vectorised over the fleet's N trains.

A task sees the :class:`~brakegym.envs.fleet.TrainFleet` after each control step and returns named
reward terms (summed into the reward and reported in ``info["reward_terms"]``), which trains
ended (``terminated``) and which of those succeeded. The tasks themselves are the modules of
:mod:`brakegym.envs.tasks`, one per environment.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from .config import BrakeEnvConfig

if TYPE_CHECKING:
    from .fleet import TrainFleet


@dataclass
class Outcome:
    """The task's verdict after a control step, arrays of length N."""

    reward_terms: dict[str, np.ndarray]
    terminated: np.ndarray
    success: np.ndarray  # meaningful where terminated


def copies(arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The arrays copied (some are the task's state, which the next step changes)."""
    return {name: values.copy() for name, values in arrays.items()}


def of_train(arrays: dict[str, np.ndarray], train: int) -> dict[str, Any]:
    """Train ``train``'s entries: numpy scalars, which hold their value."""
    return {name: values[train] for name, values in arrays.items()}


class BrakeTask:
    """Base class: a task draws its episode parameters, adds observation columns and judges.

    A task is an environment: its module in :mod:`brakegym.envs.tasks` and its default config
    ``environments/<name>.yaml`` are all an environment needs (:mod:`brakegym.envs.registry`
    finds it). Its docstring documents what it adds to the common spaces, reward and termination
    of :mod:`brakegym.envs.env`, and its version history.
    """

    #: the Gymnasium id it is registered as
    env_id: ClassVar[str]
    #: the task's name, the stem of its default config ``environments/<name>.yaml``
    name: ClassVar[str]
    #: the model its config is validated as
    config_model: ClassVar[type[BrakeEnvConfig]]
    #: the per-episode quantity the stress harness judges (an ``info`` key) and its unit
    metric: ClassVar[tuple[str, str]]
    #: names and (low, high) bounds of the task's observation columns, after the common ones
    extra_observations: ClassVar[tuple[tuple[str, float, float], ...]] = ()
    #: further per-episode ``info`` keys the stress harness reports (mean, p95, largest)
    stress_quantities: ClassVar[tuple[str, ...]] = ()
    #: reset options the task accepts besides the fleet's
    options: ClassVar[tuple[str, ...]] = ()
    #: ``"pressure"`` when an action is a cylinder pressure per control group in [-1, 1]
    #: (``Box``), ``"valves"`` when it is a WSP valve command per valve, 0 dump, 1 hold, 2 apply
    #: (``MultiDiscrete``, for the fleets with ``wheel_rail``)
    action_kind: ClassVar[str] = "pressure"
    #: whether the observation starts with the fleet's common sensor columns; a task that
    #: observes otherwise (a brake control unit's wheel-speed sensors) gives all its columns in
    #: :meth:`observation_columns` and writes them in :meth:`measure`
    common_observations: ClassVar[bool] = True

    def __init__(self, config: BrakeEnvConfig, fleet: TrainFleet):
        self.config = config
        self.fleet = fleet
        self.n = fleet.n_trains

    def restart(self, index: np.ndarray, rng: np.random.Generator, options: Mapping[str, Any]) -> None:
        """Draw this task's episode parameters for trains ``index`` (after the fleet restarted)."""

    def observe(self, measured: Mapping[str, np.ndarray], out: np.ndarray) -> None:
        """Write the extra observation columns into ``out`` (N, len(extra_observations)), from
        the measured channels (:meth:`brakegym.envs.fleet.TrainFleet.measure`)."""

    def observation_columns(self) -> list[tuple[str, float, float]]:
        """Names and (low, high) bounds of the whole observation of a task without the common
        columns (``common_observations`` False)."""
        raise NotImplementedError(f"{type(self).__name__} observes the common columns")

    def measure(self, out: np.ndarray) -> None:
        """Write the whole observation (N, len(observation_columns())) of a task without the
        common columns; the noise its own (the episode keys' streams)."""
        raise NotImplementedError(f"{type(self).__name__} observes the common columns")

    def advance_fleet(self, actions: np.ndarray) -> None:
        """One control step of the fleet with the policy's ``actions`` (N, action dimensions)."""
        self.fleet.advance(actions)

    def judge(self) -> Outcome:
        raise NotImplementedError

    def episode_info(self, train: int | None = None) -> dict[str, Any]:
        """Task quantities for ``info``: arrays over the trains (copies), or with ``train`` that
        train's numbers (numpy scalars)."""
        return {}

    def _jerk_term(self) -> np.ndarray:
        return -self.config.reward.jerk_per_mps3 * self.fleet.jerk_mps3
