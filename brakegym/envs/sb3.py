"""Hand a natively batched brakegym environment to stable-baselines3 as its own ``VecEnv``.

SB3's own wrappers (``DummyVecEnv``) would step N single environments one after the other in
Python; this adapter keeps the N trains in one numpy call. Needs the ``rl`` extra.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvObs, VecEnvStepReturn

from .env import BrakeVectorEnv


class SB3VecEnv(VecEnv):
    """``BrakeVectorEnv`` (autoreset on) as an SB3 ``VecEnv``: ended trains restart in the same
    step, their last observation in ``infos[i]["terminal_observation"]``, ``is_success`` and
    ``TimeLimit.truncated`` in their info for SB3's callbacks."""

    def __init__(self, env: BrakeVectorEnv):
        if not env.autoreset:
            raise ValueError("SB3VecEnv needs a BrakeVectorEnv with autoreset=True")
        self.env = env  # before the base class asks for the render mode through get_attr
        super().__init__(env.num_envs, env.single_observation_space, env.single_action_space)
        self._actions: np.ndarray | None = None

    def reset(self) -> VecEnvObs:
        seed = self._seeds[0] if self._seeds else None
        options = self._options[0] if self._options and self._options[0] else None
        observation, _ = self.env.reset(seed=seed, options=options)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return observation

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        observation, reward, terminated, truncated, info = self.env.step(self._actions)
        dones = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for i in np.flatnonzero(dones):
            infos[i] = {
                "terminal_observation": info["final_obs"][i],
                "is_success": bool(info["is_success"][i]),
                "TimeLimit.truncated": bool(truncated[i] and not terminated[i]),
            }
        return observation, reward.astype(np.float32), dones, infos

    def close(self) -> None:
        self.env.close()

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        return [getattr(self.env, attr_name) for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        setattr(self.env, attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: Any = None, **method_kwargs: Any) -> list[Any]:
        method = getattr(self.env, method_name)
        return [method(*method_args, **method_kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None for _ in range(self.num_envs)]
