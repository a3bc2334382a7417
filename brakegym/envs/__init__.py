"""Gymnasium environments of the braking train.

- :mod:`.env`: :class:`BrakeEnv` (one train) and :class:`BrakeVectorEnv` (N trains in one call):
  spaces, reward, termination, options and version history common to every task;
- :mod:`.tasks`: one module per environment (``brakegym/StationStop-v0``, ...), found by
  :mod:`.registry`;
- :mod:`.fleet`: the batch of trains behind them; :mod:`.config`: their validated configs;
- :mod:`.sb3`: the batched environment as a stable-baselines3 ``VecEnv``; :mod:`.render`: the
  dashboard.
"""

from __future__ import annotations

from typing import Any

from .registry import environment_config, full_env_id, register_environments, task_class, task_classes

_LAZY = ("BrakeCore", "BrakeEnv", "BrakeVectorEnv")


def __getattr__(name: str) -> Any:
    # The environments load the simulator; ``import brakegym`` registers them through the light
    # registry alone, and the classes are imported when first asked for.
    if name in _LAZY:
        from . import env

        return getattr(env, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "BrakeCore",
    "BrakeEnv",
    "BrakeVectorEnv",
    "environment_config",
    "full_env_id",
    "register_environments",
    "task_class",
    "task_classes",
]
