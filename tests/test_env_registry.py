"""The one registry of environments: an environment is a task module and its default config."""

import sys
import textwrap
from pathlib import Path

import gymnasium as gym
import numpy as np
import yaml

import brakegym.envs.tasks
from brakegym import config as cfg
from brakegym.envs import registry

REPO_CONFIGS = Path(__file__).resolve().parent.parent / "configs"

TASK_MODULE = '''
"""``brakegym/CoastDown-v0``: brake to standstill, nothing else asked (a task made by a test)."""

import numpy as np

from brakegym.envs.config import BrakeEnvConfig
from brakegym.envs.task import BrakeTask, Outcome


class CoastDownConfig(BrakeEnvConfig):
    """No fields of its own."""


class CoastDown(BrakeTask):
    """Every control step costs 1 until standstill."""

    env_id = "brakegym/CoastDown-v0"
    name = "coast_down"
    config_model = CoastDownConfig
    metric = ("time_s", "s")

    def judge(self):
        standstill = self.fleet.standstill
        return Outcome({"time": np.where(standstill, 0.0, -1.0)}, standstill, standstill.copy())
'''


def test_every_shipped_environment_is_registered_from_its_module():
    names = sorted(cls.name for cls in registry.task_classes().values())
    modules = sorted(
        path.stem for path in Path(brakegym.envs.tasks.__file__).parent.glob("*.py") if path.stem != "__init__"
    )
    assert names == modules
    assert all(env_id in gym.registry for env_id in registry.task_classes())


def test_a_new_environment_is_one_task_module_and_its_config(tmp_path, monkeypatch):
    """Nothing else to touch: the module (here in a folder added to the tasks package) and its
    default config (here on the config search path) are found, registered and made."""
    (tmp_path / "tasks").mkdir()
    (tmp_path / "tasks" / "coast_down.py").write_text(textwrap.dedent(TASK_MODULE))
    defaults = yaml.safe_load((REPO_CONFIGS / "environments" / "emergency_stop.yaml").read_text())
    defaults.pop("disc_temperature_limit_C")
    defaults.update(name="coast_down", description="brake to standstill")
    (tmp_path / "configs" / "environments").mkdir(parents=True)
    (tmp_path / "configs" / "environments" / "coast_down.yaml").write_text(yaml.safe_dump(defaults))
    monkeypatch.setattr(brakegym.envs.tasks, "__path__", [*brakegym.envs.tasks.__path__, str(tmp_path / "tasks")])
    registry.task_classes.cache_clear()
    try:
        with cfg.config_path(tmp_path / "configs"):
            registry.register_environments()
            env = gym.make("brakegym/CoastDown-v0")
            env.reset(seed=0)
            for _ in range(2000):
                _, reward, terminated, truncated, info = env.step(np.ones(env.action_space.shape, np.float32))
                if terminated or truncated:
                    break
            assert terminated and info["is_success"] and info["speed_mps"] == 0.0
            assert set(info["reward_terms"]) == {"time"}
    finally:
        gym.registry.pop("brakegym/CoastDown-v0", None)
        sys.modules.pop("brakegym.envs.tasks.coast_down", None)
        registry.task_classes.cache_clear()
