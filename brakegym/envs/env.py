"""The Gymnasium environments: one train (:class:`BrakeEnv`) or N trains in one numpy call
(:class:`BrakeVectorEnv`), both around the same :class:`BrakeCore`, for any task of
:mod:`brakegym.envs.tasks` (each task module documents what it adds: observation columns, reward
terms, termination, reset options, info, and its version history).

Spaces
------
Action: ``Box(-1, 1, (groups,), float32)``, one brake-cylinder pressure command per control group
(``control_groups``: ``train`` 1, ``bogie`` 4, ``axle`` 8 for ``emu_8axle``), mapped linearly to
0..``max_cylinder_pressure_bar`` of the vehicle (4.5 bar). Values outside [-1, 1] are clipped to
it; a NaN, an infinite value or a wrong shape raises ``ValueError``. Commands reach the cylinders
through the pneumatic model (dead time, then first-order lag; ``actuation`` EP or PN).

Observation: ``Box(float32)`` of, in order, the measured speed (m/s), the deceleration (m/s^2, the
mean over the last control step from the speed sensor, positive while slowing), the cylinder
pressure of each axle (bar), the friction-surface temperature of every disc or of the
instrumented one only (``observed_temperatures``, deg C), then the task's columns. Each channel
carries Gaussian noise of the config's ``sensor_noise``. ``observation_names`` lists the columns.

Reward: the sum of the task's named terms, reported in ``info["reward_terms"]`` (weights in the
config's ``reward``).

Termination: ``terminated`` at standstill and on the task's failures; ``truncated`` when the
episode reaches ``max_episode_time_s``. ``info["is_success"]`` says whether an ended episode met
the task.

Info: ``reward_terms``, ``is_success``, the true physical state (``speed_mps``, ``position_m``,
``deceleration_mps2``, ``cylinder_pressure_bar``, ``command_bar``, per-disc ``mu``,
``friction_temperature_C``, ``disc_temperature_C``, ``mass_kg``, ``time_s``) and the task's
quantities, with ``peak_jerk_mps3`` and ``peak_friction_temperature_C`` of the episode so far.

Reset options (``reset(options={...})``) fix what is otherwise drawn: ``initial_speed_kmh``,
``load``, ``setup`` (friction scatter set-up), ``initial_disc_temperature_C``, and the task's own.

Physics: ``simulation_frequency_hz / policy_frequency_hz`` RK4 steps per control step (20 Hz and
10 Hz by default). With ``carry_over_thermal_state`` the discs start each episode as the last one
left them (consecutive stops heat them). ``effects`` names an effect set (``configs/effects/`` or a
YAML path, e.g. what ``brakegym diagnose --effects-out`` writes) that every train runs with: a
gradient, a friction level, wet pads, ... applied afresh to each episode's train, and the sensor
effects (speed-sensor scale, temperature-sensor lag) in the observation; see
:class:`brakegym.envs.fleet.TrainFleet`. State-dependent effects (wet pads, fade, adhesion) run
in Python at every RK4 stage, which slows a step several times.

Version history
---------------
- v0: initial release; the ``effects`` config field added later (default none: the same
  episodes as before).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .config import BrakeEnvConfig
from .fleet import TrainFleet
from .options import FLEET_OPTIONS
from .registry import environment_config, task_class
from .task import BrakeTask, Outcome

RENDER_MODES = ["human", "rgb_array", "ansi"]


class BrakeCore:
    """Fleet + task + spaces: one control step for N trains, no autoreset. ``task`` is an
    environment id or a task name (:func:`.registry.task_class`)."""

    def __init__(self, task: str, config: Mapping[str, Any] | str | Path | None, n_trains: int):
        task_type = task_class(task)
        self.config: BrakeEnvConfig = environment_config(task_type.name, config)
        self.fleet = TrainFleet(self.config, n_trains)
        self.task: BrakeTask = task_type(self.config, self.fleet)
        self.n = n_trains
        fleet = self.fleet
        axles = fleet.plant.n_axles
        if self.task.common_observations:
            columns: list[tuple[str, float, float]] = [("speed_mps", -1.0, 100.0), ("decel_mps2", -10.0, 10.0)]
            columns += [(f"pressure_bar_{axle + 1}", -1.0, 11.0) for axle in range(axles)]
            columns += [(f"temperature_C_{disc + 1}", -100.0, 2000.0) for disc in fleet.observed_discs]
            columns += list(self.task.extra_observations)
        else:
            columns = self.task.observation_columns()
        self.observation_names = tuple(name for name, _, _ in columns)
        self.single_observation_space = gym.spaces.Box(
            low=np.array([low for _, low, _ in columns], dtype=np.float32),
            high=np.array([high for _, _, high in columns], dtype=np.float32),
            dtype=np.float32,
        )
        if self.task.action_kind == "valves":
            self.single_action_space = gym.spaces.MultiDiscrete([3] * fleet.n_valves)
        else:
            self.single_action_space = gym.spaces.Box(-1.0, 1.0, (fleet.n_groups,), dtype=np.float32)
        self.ended = np.ones(n_trains, dtype=bool)  # no episode running until the first reset

    def reset(self, index: np.ndarray, rng: np.random.Generator, options: Mapping[str, Any] | None) -> None:
        options = dict(options or {})
        unknown = sorted(set(options) - set(FLEET_OPTIONS) - set(self.task.options))
        if unknown:
            raise ValueError(
                f"unknown reset option(s) {unknown}; "
                f"{self.config.name} accepts {sorted(FLEET_OPTIONS + self.task.options)}"
            )
        self.fleet.restart(index, rng, options)
        self.task.restart(index, rng, options)
        self.ended[index] = False

    def observe(self, rng: np.random.Generator) -> np.ndarray:
        fleet = self.fleet
        if not self.task.common_observations:
            observation = np.empty((self.n, len(self.observation_names)))
            self.task.measure(observation)
            return observation.astype(np.float32)
        # One draw per channel in a fixed order, always (zero noise included), so a seed's random
        # stream does not depend on the noise settings: the sensor channels, then the distance.
        draws = rng.standard_normal((self.n, fleet.n_measured_channels + 1))
        # Filled in float64, then rounded once to the float32 of the observation space.
        observation = np.empty((self.n, len(self.observation_names)))
        measured = fleet.measure(draws, observation[:, : fleet.n_measured_channels])
        self.task.observe(measured, observation[:, fleet.n_measured_channels :])
        return observation.astype(np.float32)

    def step(self, actions: np.ndarray, rng: np.random.Generator, allow_ended: bool = False):
        """Advance every train one control step. Returns observations, rewards, terminated,
        truncated and the task's :class:`Outcome` (for :meth:`info`). Trains whose episode ended
        are refused unless ``allow_ended`` (they are then simulated on, and their rewards mean
        nothing)."""
        if not allow_ended and self.ended.any():
            raise RuntimeError(
                f"train(s) {np.flatnonzero(self.ended).tolist()} have no running episode: call reset() first"
            )
        self.task.advance_fleet(actions)
        outcome = self.task.judge()
        truncated = ~outcome.terminated & (self.fleet.time_s >= self.config.max_episode_time_s - 1e-9)
        reward = sum(outcome.reward_terms.values())
        observation = self.observe(rng)
        self.ended |= outcome.terminated | truncated
        return observation, reward, outcome.terminated, truncated, outcome

    def info(self, outcome: Outcome | None = None, train: int | None = None) -> dict[str, Any]:
        """The info of the last step (with the ``outcome`` it returned) or of a reset: arrays over
        the trains, or with ``train`` that train's entries (numpy scalars and per-disc rows, the
        reward terms as floats)."""
        info: dict[str, Any] = self.fleet.physical_state(train)
        info.update(self.task.episode_info(train))
        episodes = self.fleet.episodes
        entries = (
            ("peak_jerk_mps3", episodes.peak_jerk_mps3),
            ("peak_friction_temperature_C", episodes.peak_friction_temperature_C),
            ("initial_speed_mps", episodes.initial_speed_mps),
        )
        if train is None:
            info.update((name, values.copy()) for name, values in entries)
        else:
            info.update((name, values[train]) for name, values in entries)
        if outcome is not None:
            if train is None:
                info["reward_terms"] = outcome.reward_terms
                info["is_success"] = outcome.success & outcome.terminated
            else:  # the reward terms last, as in every single-train info so far
                info["is_success"] = outcome.success[train] & outcome.terminated[train]
                info["reward_terms"] = {name: float(values[train]) for name, values in outcome.reward_terms.items()}
        return info


class BrakeEnv(gym.Env):
    """One train braking in ``task`` (an environment id or task name, e.g. ``"station_stop"``),
    what ``gymnasium.make`` builds. See the module documentation for spaces, reward, termination
    and options, and the task's module for what it adds."""

    metadata = {"render_modes": RENDER_MODES, "render_fps": 10}

    def __init__(self, task: str, config: Mapping[str, Any] | str | Path | None = None, render_mode: str | None = None):
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode {render_mode!r}: choose one of {RENDER_MODES}")
        self.core = BrakeCore(task, config, 1)
        self.config = self.core.config
        self.observation_space = self.core.single_observation_space
        self.action_space = self.core.single_action_space
        self.observation_names = self.core.observation_names
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": self.config.policy_frequency_hz}
        self._index = np.zeros(1, dtype=np.int64)
        self._dashboard = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode: draw the train (load, speed, friction scatter, ...) and the task's
        parameters, unless ``options`` fix them (see the module documentation). Returns the first
        observation and the info."""
        super().reset(seed=seed)
        self.core.reset(self._index, self.np_random, options)
        observation = self.core.observe(self.np_random)[0]
        info = self.core.info(train=0)
        if self._dashboard is not None:
            self._dashboard.clear()
        self._record(observation, info)
        if self.render_mode == "human":
            self.render()
        return observation, info

    def step(self, action):
        """One control step: ``action`` (the action space's shape) sets the cylinder-pressure
        commands. Returns observation, reward, terminated, truncated and info, as Gymnasium's
        ``Env.step``; a NaN or a wrong shape raises ``ValueError``."""
        action = np.asarray(action, dtype=np.float64)
        if action.shape != self.action_space.shape:
            raise ValueError(f"action shape {action.shape} does not match the action space {self.action_space.shape}")
        observation, reward, terminated, truncated, outcome = self.core.step(action[None, :], self.np_random)
        info = self.core.info(outcome, train=0)
        self._record(observation[0], info)
        if self.render_mode == "human":
            self.render()
        return observation[0], float(reward[0]), bool(terminated[0]), bool(truncated[0]), info

    def _record(self, observation: np.ndarray, info: dict[str, Any]) -> None:
        if self.render_mode is None:
            return
        from .render import Dashboard

        if self._dashboard is None:
            self._dashboard = Dashboard(self)
        self._dashboard.record(observation, info)

    def render(self):
        """The dashboard in the ``render_mode`` given at construction: a text for ``ansi``, an
        image array for ``rgb_array``, a window for ``human`` (then None)."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode= to gymnasium.make")
            return None
        if self._dashboard is None:
            raise RuntimeError("render() before reset()")
        if self.render_mode == "ansi":
            return self._dashboard.text()
        if self.render_mode == "rgb_array":
            return self._dashboard.rgb_array()
        self._dashboard.show()
        return None

    def close(self):
        """Close the dashboard, if one is open."""
        if self._dashboard is not None:
            self._dashboard.close()
            self._dashboard = None


class BrakeVectorEnv(VectorEnv):
    """N trains braking in ``task``, what ``gymnasium.make_vec`` builds: stepped in one numpy call,
    autoreset in the same step (Gymnasium's SAME_STEP):
    an ended train's last observation and info are in ``info["final_obs"]`` /
    ``info["final_info"]`` (rows valid where ``info["_final_obs"]``), and its row of the returned
    observation already starts the next episode. Info entries are arrays over the trains; the
    rows of trains that were just restarted still describe the episode that ended.

    ``autoreset=False`` runs each train's episode once (for evaluation): ended trains stay
    ended, see :attr:`ended`."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}

    def __init__(
        self,
        task: str,
        num_envs: int = 1,
        config: Mapping[str, Any] | str | Path | None = None,
        autoreset: bool = True,
    ):
        self.core = BrakeCore(task, config, num_envs)
        self.config = self.core.config
        self.num_envs = num_envs
        self.autoreset = autoreset
        self.single_observation_space = self.core.single_observation_space
        self.single_action_space = self.core.single_action_space
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.observation_names = self.core.observation_names
        self.render_mode = None
        self.metadata = {**self.metadata}
        if not autoreset:
            self.metadata["autoreset_mode"] = AutoresetMode.DISABLED
        self._rng, _ = gym.utils.seeding.np_random(None)
        self._all = np.arange(num_envs)
        self._options: dict[str, Any] | None = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode in every train; ``options`` fix what is otherwise drawn, for this reset
        and for the autoresets that follow. Returns the observations (N rows) and the info."""
        if seed is not None:
            self._rng, _ = gym.utils.seeding.np_random(seed)
        self._options = options
        self.core.reset(self._all, self._rng, options)
        return self.core.observe(self._rng), self.core.info()

    def step(self, actions):
        """One control step of every train: ``actions`` of shape (N, groups). Returns observations,
        rewards, terminated, truncated (arrays over the trains) and the info; ended trains are
        restarted in the same step when ``autoreset`` (see the class documentation)."""
        actions = np.asarray(actions, dtype=np.float64)
        if actions.shape != self.action_space.shape:
            raise ValueError(f"actions shape {actions.shape} does not match the action space {self.action_space.shape}")
        observation, reward, terminated, truncated, outcome = self.core.step(
            actions, self._rng, allow_ended=not self.autoreset
        )
        info = self.core.info(outcome)
        ended = terminated | truncated
        if self.autoreset and ended.any():
            index = np.flatnonzero(ended)
            info["final_obs"] = observation.copy()
            info["_final_obs"] = ended
            info["final_info"] = {key: value for key, value in info.items() if key not in ("final_obs", "_final_obs")}
            info["_final_info"] = ended
            # Restarts use the options of the last reset(), so a fixed scenario stays fixed.
            self.core.reset(index, self._rng, self._options)
            observation[index] = self.core.observe(self._rng)[index]
        return observation, reward, terminated, truncated, info

    @property
    def ended(self) -> np.ndarray:
        """Trains whose episode has ended (with ``autoreset=False`` they stay ended until the next
        ``reset()``; stepping simulates them on, and their rewards mean nothing)."""
        return self.core.ended.copy()
