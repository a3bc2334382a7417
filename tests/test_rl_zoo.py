"""The hyperparameter files in configs/agents/ are readable by rl_zoo3 as they are: rl_zoo3 trains
from each (a short run), with brakegym's own keys kept where rl_zoo3 does not read them."""

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
import yaml

from brakegym.agents.rl import BRAKEGYM_KEYS, OWN_SECTION, load_hyperparameters
from brakegym.envs.registry import task_classes

CONFIGS = Path(__file__).resolve().parent.parent / "configs" / "agents"
ZOO_FILES = {"ppo": "ppo", "ppo-residual": "ppo", "sac": "sac"}  # file -> rl_zoo3 algorithm


@pytest.mark.parametrize("name", sorted(ZOO_FILES))
def test_entries_are_environment_ids_and_own_keys_stay_in_their_section(name):
    entries = yaml.safe_load((CONFIGS / f"{name}.yaml").read_text())
    ids = [key for key in entries if key != OWN_SECTION]
    assert ids and all(key in task_classes() for key in ids)
    for key in ids:
        assert not set(entries[key]) & set(BRAKEGYM_KEYS), key
        assert all(
            isinstance(value, (int, float))
            for field, value in entries[key].items()
            if field in ("n_timesteps", "gamma")
        )
        load_hyperparameters(name, key, CONFIGS / f"{name}.yaml")  # brakegym reads it too
    assert set(entries.get(OWN_SECTION, {})) <= set(ids)


@pytest.mark.parametrize("name", sorted(ZOO_FILES))
def test_rl_zoo3_trains_from_the_file(name, tmp_path):
    pytest.importorskip("rl_zoo3")
    env_id = next(key for key in yaml.safe_load((CONFIGS / f"{name}.yaml").read_text()) if key != OWN_SECTION)
    command = [
        sys.executable,
        "-m",
        "rl_zoo3.train",
        "--algo",
        ZOO_FILES[name],
        "--env",
        env_id,
        "--gym-packages",
        "brakegym",
        "--conf-file",
        str(CONFIGS / f"{name}.yaml"),
        "-n",
        "1000",
        "-f",
        str(tmp_path / "logs"),
        "--seed",
        "0",
    ]
    # Without a log folder of its own, SB3's logger makes a new SB3-* folder in the system temp
    # directory on every run; SB3_LOGDIR keeps it with the test's files.
    logs_elsewhere = set(Path(tempfile.gettempdir()).glob("SB3-*"))
    environment = {"OMP_NUM_THREADS": "1", **os.environ, "SB3_LOGDIR": str(tmp_path / "sb3")}
    result = subprocess.run(command, capture_output=True, text=True, timeout=600, env=environment)
    assert result.returncode == 0, result.stderr[-3000:]
    saved = list((tmp_path / "logs" / ZOO_FILES[name]).glob("brakegym-*_1/*.zip"))
    assert saved, result.stdout[-2000:]
    assert set(Path(tempfile.gettempdir()).glob("SB3-*")) == logs_elsewhere
