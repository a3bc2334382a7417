"""Wheel-slide protection controllers as one kind (:class:`brakegym.wheel_slide.WspControl`): the
reference (:class:`~brakegym.agents.wsp.WspController`), no WSP (:class:`NoWsp`) and a policy
trained on ``brakegym/WheelSlideProtection-v0`` (:class:`PolicyWsp`, built by
:func:`load_wsp_controller`); and :class:`WspEnvController`, which drives any of them as a batch
controller of that environment (``brakegym evaluate`` and ``brakegym stress``), reading what its
brake control units measure.

The same controller thus runs the environment's scattered episodes and the deterministic stops of
:func:`brakegym.wheel_slide.wsp_train_stops`.
"""

from __future__ import annotations

import dataclasses
import functools
import json
from collections.abc import Callable
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import Any

import numpy as np

from ..envs.tasks.wheel_slide_protection import BcuFeatures
from ..physics.pneumatics import VALVE_APPLY, VALVE_DUMP
from ..wheel_slide import BcuMeasurement, WspControl

#: The environment a WSP policy is trained on.
WSP_ENV = "WheelSlideProtection-v0"


class NoWsp:
    """No wheel-slide protection: every valve at rest (apply) at every step."""

    uses_train_speed = False

    def __init__(self, valve_of_axle: np.ndarray, control_step_s: float) -> None:
        self.n_valves = int(np.max(valve_of_axle)) + 1

    def reset(self, measurement: BcuMeasurement) -> None:
        """Nothing to remember."""

    def valves(self, measurement: BcuMeasurement) -> np.ndarray:
        return np.full((len(measurement.wheel_speed_mps), self.n_valves), VALVE_APPLY, dtype=np.int64)


class PolicyWsp:
    """A policy trained on ``WheelSlideProtection-v0`` (an agent folder of ``brakegym train``) as
    a :class:`~brakegym.wheel_slide.WspControl`: it observes what the environment's observation
    holds (:class:`~brakegym.envs.tasks.wheel_slide_protection.BcuFeatures`), normalised with
    the training's statistics, and acts deterministically."""

    uses_train_speed = False

    def __init__(self, agent_dir: str | Path | Traversable, valve_of_axle: np.ndarray, control_step_s: float) -> None:
        from .. import config as cfg
        from ..envs.registry import environment_config
        from .rl import PolicyController

        self.policy = PolicyController(agent_dir)
        meta = self.policy.meta
        if meta["env"] != WSP_ENV:
            raise ValueError(f"{agent_dir}: trained on {meta['env']}, not {WSP_ENV}: not a WSP policy")
        config = environment_config(WSP_ENV, meta.get("env_config") or None)
        if abs(config.control_step_s - control_step_s) > 1e-12:
            raise ValueError(
                f"{agent_dir}: trained at a control step of {config.control_step_s} s, "
                f"asked to run at {control_step_s} s"
            )
        self.control_step_s = float(control_step_s)
        self.max_pressure_bar = cfg.load("vehicles", config.vehicle).max_cylinder_pressure_bar
        self.n_valves = int(np.max(valve_of_axle)) + 1
        trained_valves = self.policy.model.action_space.shape[0]
        if trained_valves != self.n_valves:
            raise ValueError(f"{agent_dir}: the policy commands {trained_valves} valves, the train has {self.n_valves}")
        self.n_axles = len(valve_of_axle)
        self.features = BcuFeatures(0, self.n_axles, self.control_step_s, self.max_pressure_bar)
        self._step = np.zeros(0, dtype=np.int64)

    def reset(self, measurement: BcuMeasurement) -> None:
        """Start braking: the reset's reading is the first (as in the environment)."""
        n = len(measurement.wheel_speed_mps)
        self.features = BcuFeatures(n, self.n_axles, self.control_step_s, self.max_pressure_bar)
        self._step = np.zeros(n, dtype=np.int64)

    def valves(self, measurement: BcuMeasurement) -> np.ndarray:
        n = len(measurement.wheel_speed_mps)
        observation = np.empty((n, 5 * self.n_axles + 3))
        self.features.observe(measurement, self._step, observation)
        self._step = self._step + 1
        actions = self.policy.act(observation.astype(np.float32))
        return np.asarray(actions, dtype=np.int64) + VALVE_DUMP


def load_wsp_controller(agent_dir: str | Path | Traversable) -> Callable[[np.ndarray, float], WspControl]:
    """A trained WSP policy folder as what :func:`brakegym.wheel_slide.wsp_train_stops` takes as
    ``make_controller``: a function of (valve of each axle, control step in s) that builds the
    controller (:class:`PolicyWsp`). The folder is checked now (a policy of ``WheelSlideProtection-v0``
    with ``training.json``, ``model.zip`` and ``vecnormalize.pkl``)."""
    folder = agent_dir if isinstance(agent_dir, Traversable) else Path(agent_dir)
    meta_path = folder.joinpath("training.json")
    if not meta_path.is_file():
        raise FileNotFoundError(f"{folder}: not an agent folder (no training.json)")
    trained_on = json.loads(meta_path.read_text()).get("env")
    if trained_on != WSP_ENV:
        raise ValueError(f"{folder}: trained on {trained_on}, not {WSP_ENV}: not a WSP policy")

    def make_controller(valve_of_axle: np.ndarray, control_step_s: float) -> PolicyWsp:
        return PolicyWsp(folder, valve_of_axle, control_step_s)

    return make_controller


#: Names of the WSP controllers that an environment with WSP valves runs (no WSP, the reference
#: WSP on the wheel speeds of ``configs/agents/wsp.yaml``, the reference given the true speed).
WSP_AGENTS = ("none", "wsp", "wsp-true-speed")


def wsp_env_controller_factory(agent: str, env_id: str) -> Callable[[Any], WspEnvController]:
    """A factory (environment -> :class:`WspEnvController`) of the WSP controller named ``agent``
    (one of :data:`WSP_AGENTS`) for the environment ``env_id``, which must have WSP valves."""
    from ..envs.registry import task_class
    from .wsp import WspController, load_wsp_config

    if agent not in WSP_AGENTS:
        raise ValueError(f"{agent!r}: not a WSP controller ({', '.join(WSP_AGENTS)})")
    if task_class(env_id).action_kind != "valves":
        raise ValueError(f"{agent}: a WSP controller; {env_id} has no WSP valves")
    make = NoWsp if agent == "none" else functools.partial(WspController, load_wsp_config(agent))
    return lambda env: WspEnvController(make, env)


class WspEnvController:
    """A :class:`~brakegym.wheel_slide.WspControl` as a batch controller of a
    ``WheelSlideProtection`` environment (:class:`brakegym.envs.BrakeVectorEnv`): it reads the
    brake control units' measurement of the last observation (the true train speed only for a
    controller that ``uses_train_speed``) and returns the valve actions (0 dump, 1 hold,
    2 apply)."""

    def __init__(self, make_controller: Callable[[np.ndarray, float], WspControl], env: Any) -> None:
        task = env.core.task
        if getattr(task, "action_kind", None) != "valves":
            raise ValueError(f"{env.config.name}: a WSP controller needs an environment with WSP valves")
        self.task = task
        self.controller = make_controller(env.core.fleet.valve_of_axle, env.core.fleet.control_step_s)

    def _measurement(self) -> BcuMeasurement:
        measurement = self.task.measurement
        if measurement is None:
            raise RuntimeError("WspEnvController before the environment's reset()")
        if self.controller.uses_train_speed:
            return measurement
        return dataclasses.replace(measurement, train_speed_mps=None)

    def reset(self, info: dict[str, Any]) -> None:
        self.controller.reset(self._measurement())

    def act(self, observation: np.ndarray) -> np.ndarray:
        return np.asarray(self.controller.valves(self._measurement()), dtype=np.int64) - VALVE_DUMP
