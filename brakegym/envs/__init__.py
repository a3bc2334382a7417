"""Gymnasium environments of the braking train (see :mod:`brakegym.envs.env` for spaces, reward,
termination and version history)."""

from __future__ import annotations

from .config import environment_config
from .env import BrakeCore, BrakeEnv, BrakeVectorEnv


class StationStopEnv(BrakeEnv):
    """``brakegym/StationStop-v0``: stop with the train's reference point on the platform mark."""

    task_name = "station_stop"


class DecelTrackingEnv(BrakeEnv):
    """``brakegym/DecelTracking-v0``: follow service-brake deceleration steps."""

    task_name = "decel_tracking"


class EmergencyStopEnv(BrakeEnv):
    """``brakegym/EmergencyStop-v0``: shortest stop within the disc temperature limit."""

    task_name = "emergency_stop"


class StationStopVectorEnv(BrakeVectorEnv):
    task_name = "station_stop"


class DecelTrackingVectorEnv(BrakeVectorEnv):
    task_name = "decel_tracking"


class EmergencyStopVectorEnv(BrakeVectorEnv):
    task_name = "emergency_stop"


ENVIRONMENTS = {
    "brakegym/StationStop-v0": (StationStopEnv, StationStopVectorEnv),
    "brakegym/DecelTracking-v0": (DecelTrackingEnv, DecelTrackingVectorEnv),
    "brakegym/EmergencyStop-v0": (EmergencyStopEnv, EmergencyStopVectorEnv),
}


def full_env_id(env_id: str) -> str:
    """``StationStop-v0`` or ``brakegym/StationStop-v0`` as the registered id; unknown ids raise."""
    full = env_id if env_id.startswith("brakegym/") else f"brakegym/{env_id}"
    if full not in ENVIRONMENTS:
        raise ValueError(f"unknown environment {env_id!r}; known: {[e.split('/')[1] for e in ENVIRONMENTS]}")
    return full


__all__ = [
    "BrakeCore",
    "BrakeEnv",
    "BrakeVectorEnv",
    "ENVIRONMENTS",
    "environment_config",
    "full_env_id",
] + [cls.__name__ for pair in ENVIRONMENTS.values() for cls in pair]
