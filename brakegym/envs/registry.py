"""The one registry of environments: every :class:`~brakegym.envs.task.BrakeTask` defined in the
modules of :mod:`brakegym.envs.tasks`, registered with Gymnasium under its ``env_id``.

The task modules are imported to find them; they are light (numpy and the config schemas), so that
``import brakegym`` can register every environment without loading the simulator.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Mapping
from functools import cache
from pathlib import Path
from typing import Any

from . import tasks as task_package
from .config import BrakeEnvConfig, load_environment_config
from .task import BrakeTask


@cache
def task_classes() -> dict[str, type[BrakeTask]]:
    """Every task, by its ``env_id``, in module order."""
    found: dict[str, type[BrakeTask]] = {}
    for module_info in sorted(pkgutil.iter_modules(task_package.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{task_package.__name__}.{module_info.name}")
        for value in vars(module).values():
            if isinstance(value, type) and issubclass(value, BrakeTask) and value.__module__ == module.__name__:
                if value.env_id in found:
                    raise ImportError(
                        f"{value.__qualname__} and {found[value.env_id].__qualname__} both claim {value.env_id}"
                    )
                found[value.env_id] = value
    return found


def task_class(task: str) -> type[BrakeTask]:
    """The task of an environment id (``brakegym/StationStop-v0`` or ``StationStop-v0``) or a
    task name (``station_stop``); unknown ones raise ``ValueError`` listing the known."""
    known = task_classes()
    for cls in known.values():
        if task in (cls.env_id, cls.env_id.split("/", 1)[1], cls.name):
            return cls
    raise ValueError(f"unknown environment {task!r}; known: {[env_id.split('/', 1)[1] for env_id in known]}")


def full_env_id(env_id: str) -> str:
    """``StationStop-v0`` or ``brakegym/StationStop-v0`` as the registered id; unknown ids raise."""
    return task_class(env_id).env_id


def environment_config(task: str, user: Mapping[str, Any] | str | Path | None = None) -> BrakeEnvConfig:
    """The config of an environment (id or task name): its defaults merged with ``user`` (a dict
    or a YAML file) and validated (:func:`.config.load_environment_config`)."""
    cls = task_class(task)
    return load_environment_config(cls.name, cls.config_model, user)


def register_environments() -> None:
    """Register every environment with Gymnasium, once: re-imports and reloads change nothing."""
    import gymnasium

    for env_id, cls in task_classes().items():
        if env_id not in gymnasium.registry:
            gymnasium.register(
                id=env_id,
                entry_point="brakegym.envs.env:BrakeEnv",
                vector_entry_point="brakegym.envs.env:BrakeVectorEnv",
                kwargs={"task": cls.name},
            )
