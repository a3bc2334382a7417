"""The warm start of a policy by behaviour cloning of a teacher (brakegym.agents.warm_start): the
returns it fits the value to, the teacher's episodes drawn the same for the same seed, and a
policy that agrees with the teacher after cloning far more than before."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import brakegym  # noqa: F401  (registers the environments)
from brakegym import config as cfg
from brakegym.agents.warm_start import (
    WarmStartConfig,
    collect_demonstrations,
    discounted_returns,
    running_returns,
    warm_start,
)

ENV_ID = "brakegym/WheelSlideProtection-v0"
REPO = Path(__file__).resolve().parent.parent
SLOW = {"initial_speed_kmh": {"low": 20.0, "high": 30.0}}


@pytest.fixture(autouse=True)
def checkout_configs(monkeypatch):
    monkeypatch.setenv(cfg.CONFIG_PATH_ENV, str(REPO / "configs"))


def test_returns_follow_each_episode_in_order_whatever_the_sample_order():
    # Episode 0: rewards 1, 1, 1; episode 1: 2, 2; the samples interleaved and shuffled.
    rewards = np.array([2.0, 1.0, 1.0, 2.0, 1.0])
    episode = np.array([1, 0, 0, 1, 0])
    step = np.array([1, 2, 0, 0, 1])
    gamma = 0.5
    np.testing.assert_allclose(discounted_returns(rewards, episode, step, gamma), [2.0, 1.0, 1.75, 3.0, 1.5])
    np.testing.assert_allclose(running_returns(rewards, episode, step, gamma), [3.0, 1.75, 1.0, 2.0, 1.5])


def test_the_teachers_episodes_are_the_same_for_the_same_seed_and_explored_as_configured():
    config = WarmStartConfig(teacher="wsp", rounds=1, exploration=0.0)
    first = collect_demonstrations(ENV_ID, 2, 7, "mcs-75-25", SLOW, config)
    again = collect_demonstrations(ENV_ID, 2, 7, "mcs-75-25", SLOW, config)
    for name in ("observations", "actions", "rewards", "episode", "step"):
        np.testing.assert_array_equal(getattr(first, name), getattr(again, name))
    assert set(np.unique(first.actions)) <= {0, 1, 2} and first.actions.shape[1] == 8
    # Each train's samples are its braking steps, numbered from 0 without a gap.
    for train in (0, 1):
        steps = first.step[first.episode == train]
        np.testing.assert_array_equal(steps, np.arange(len(steps)))
    explored = collect_demonstrations(ENV_ID, 2, 7, "mcs-75-25", SLOW, config.model_copy(update={"exploration": 0.3}))
    assert not np.array_equal(explored.rewards[: len(first.rewards)], first.rewards[: len(explored.rewards)])


def test_an_unknown_teacher_is_refused_by_name():
    with pytest.raises(ValueError, match="'pid'.*none, wsp, wsp-true-speed"):
        collect_demonstrations(ENV_ID, 2, 0, "mcs-75-25", SLOW, WarmStartConfig(teacher="pid"))


def test_cloning_sets_the_normaliser_and_makes_the_policy_agree_with_the_teacher():
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from brakegym.envs.sb3 import SB3VecEnv
    from brakegym.stress import make_vector_env

    config = WarmStartConfig(teacher="wsp", rounds=1, epochs=30, batch_size=256)
    demonstrations = collect_demonstrations(ENV_ID, 4, 3, "mcs-75-25", SLOW, config)
    venv = VecNormalize(SB3VecEnv(make_vector_env(ENV_ID, 4, "mcs-75-25", SLOW, autoreset=True)))
    model = PPO("MlpPolicy", venv, seed=0, device="cpu", policy_kwargs={"net_arch": [32, 32]})

    def agreement() -> float:
        observations = venv.normalize_obs(demonstrations.observations.astype(np.float32))
        actions, _ = model.predict(observations, deterministic=True)
        return float((actions == demonstrations.actions).mean())

    done = warm_start(model, venv, demonstrations, config, seed=0)
    np.testing.assert_allclose(venv.obs_rms.mean, demonstrations.observations.mean(axis=0), rtol=1e-6, atol=1e-9)
    assert done["samples"] == len(demonstrations.actions)
    # Cloning must beat always giving each valve its most frequent command.
    counts = np.stack([np.bincount(column, minlength=3) for column in demonstrations.actions.T])
    most_frequent_share = counts.max(axis=1).sum() / demonstrations.actions.size
    assert done["teacher_agreement"] == pytest.approx(agreement(), abs=1e-4)
    assert done["teacher_agreement"] > most_frequent_share + 0.05


def test_the_teachers_return_on_the_evaluation_trains_is_that_of_its_episodes():
    from brakegym.agents.rl import sb3_training_env
    from brakegym.agents.warm_start import teacher_return
    from brakegym.agents.wsp_policy import wsp_env_controller_factory
    from brakegym.envs import BrakeVectorEnv

    evaluation = sb3_training_env(ENV_ID, 2, 9, "mcs-75-25", SLOW, repeat_episodes=True)
    env = BrakeVectorEnv(ENV_ID, num_envs=2, config={**SLOW, "setup": "mcs-75-25"}, autoreset=False)
    teacher = wsp_env_controller_factory("wsp", ENV_ID)(env)
    observation, info = env.reset(seed=9)
    teacher.reset(info)
    returns = np.zeros(2)
    while not env.ended.all():
        braking = ~env.ended
        observation, reward, *_ = env.step(teacher.act(observation))
        returns += np.where(braking, reward, 0.0)
    assert teacher_return(evaluation, ENV_ID, "wsp") == pytest.approx(returns.mean(), rel=1e-6)
