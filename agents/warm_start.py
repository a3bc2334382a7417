"""Warm start of an SB3 actor-critic policy by behaviour cloning of a teacher controller.

A policy trained from scratch on ``WheelSlideProtection-v0`` must first discover, by chance, that
dumping a sliding axle's cylinder pays; at 50 Hz over 8 valves it takes most of a 30-minute
budget to reach what the rule-based reference already does. Starting from the reference lets the
reinforcement learning spend its budget on doing better than the reference, which is what it is
for. The recipe is the usual one for fine-tuning from demonstrations:

1. the teacher (a batch controller of the environment, e.g. the reference WSP ``wsp``) drives
   ``rounds`` batches of trains, one episode each, on episode seeds of their own; on a share
   ``exploration`` of the steps each valve takes a random command instead, so that the states a
   learner reaches when it errs are in the data too; every step is labelled with the teacher's
   command (what it would have done there);
2. the observations set the normaliser's statistics (``VecNormalize``), and the episodes' rewards
   its return statistics, as the first rollouts of training would;
3. the policy is fitted to the labels (cross-entropy: minus the log-probability of the teacher's
   action) and its value function to the discounted returns of the normalised rewards, so that
   the first policy-gradient steps do not start from a random critic (which would undo the
   cloning before the critic has learnt anything).

The hyperparameter file sets it per environment under the ``brakegym`` section
(``warm_start: {teacher: wsp, rounds: 2, ...}``, :class:`WarmStartConfig`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import Field

from .. import config as cfg
from ..stress import make_vector_env
from .wsp_policy import wsp_env_controller_factory


class WarmStartConfig(cfg.StrictModel):
    """Behaviour cloning before training (module documentation)."""

    teacher: str = Field(min_length=1)
    rounds: int = Field(default=2, ge=1)
    exploration: float = Field(default=0.1, ge=0, lt=1)
    epochs: int = Field(default=8, ge=1)
    batch_size: int = Field(default=4096, ge=1)
    learning_rate: float = Field(default=1e-3, gt=0)
    value_coefficient: float = Field(default=0.5, ge=0)


@dataclass
class Demonstrations:
    """The teacher's episodes, stacked over the steps the trains were braking: raw observations
    (N, obs), the teacher's actions (N, valves), the rewards (N,), and each sample's episode
    (train and round, N,) and position in it (N,)."""

    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    episode: np.ndarray
    step: np.ndarray


def collect_demonstrations(
    env_id: str, n_trains: int, seed: int, setup: str, env_config: dict[str, Any] | None, config: WarmStartConfig
) -> Demonstrations:
    """Run the teacher (see the module documentation, step 1); round ``k`` resets its trains with
    ``seed + k`` and draws its exploration from ``seed + k`` too."""
    make_teacher = wsp_env_controller_factory(config.teacher, env_id)
    parts: dict[str, list[np.ndarray]] = {
        name: [] for name in ("observations", "actions", "rewards", "episode", "step")
    }
    for round_index in range(config.rounds):
        env = make_vector_env(env_id, n_trains, setup, env_config)
        teacher = make_teacher(env)
        rng = np.random.default_rng(seed + round_index)
        n_choices = env.single_action_space.nvec
        observation, info = env.reset(seed=seed + round_index)
        teacher.reset(info)
        ended = np.zeros(n_trains, dtype=bool)
        step = 0
        while not ended.all():
            label = np.asarray(teacher.act(observation), dtype=np.int64)
            explore = rng.random(label.shape) < config.exploration
            executed = np.where(explore, rng.integers(0, n_choices, size=label.shape), label)
            braking = ~ended
            next_observation, reward, terminated, truncated, _ = env.step(executed)
            parts["observations"].append(observation[braking])
            parts["actions"].append(label[braking])
            parts["rewards"].append(np.asarray(reward, dtype=float)[braking])
            parts["episode"].append(np.flatnonzero(braking) + round_index * n_trains)
            parts["step"].append(np.full(int(braking.sum()), step))
            ended |= terminated | truncated
            observation = next_observation
            step += 1
        env.close()
    return Demonstrations(**{name: np.concatenate(values) for name, values in parts.items()})


def teacher_return(eval_env: Any, env_id: str, teacher: str) -> float:
    """The teacher's mean return over one episode of each train of ``eval_env`` (an SB3 VecEnv
    over a brakegym environment whose rewards are not normalised): the evaluation trains of a
    training run, against which its checkpoints are judged."""
    inner = eval_env.unwrapped.env
    controller = wsp_env_controller_factory(teacher, env_id)(inner)
    observation = eval_env.reset()
    controller.reset({})
    finished = np.zeros(eval_env.num_envs, dtype=bool)
    returns = np.zeros(eval_env.num_envs)
    while not finished.all():
        observation, reward, dones, _ = eval_env.step(controller.act(observation))
        returns += np.where(finished, 0.0, reward)
        finished |= dones
    return float(returns.mean())


def discounted_returns(rewards: np.ndarray, episode: np.ndarray, step: np.ndarray, gamma: float) -> np.ndarray:
    """Each sample's discounted return to the end of its episode (the episode ends at its last
    sample: a standstill or the time limit, which the value then reads as an end)."""
    order = np.lexsort((step, episode))
    returns = np.empty_like(rewards, dtype=float)
    sorted_rewards = rewards[order]
    sorted_episode = episode[order]
    running = 0.0
    for k in range(len(order) - 1, -1, -1):
        if k == len(order) - 1 or sorted_episode[k + 1] != sorted_episode[k]:
            running = 0.0
        running = sorted_rewards[k] + gamma * running
        returns[order[k]] = running
    return returns


def running_returns(rewards: np.ndarray, episode: np.ndarray, step: np.ndarray, gamma: float) -> np.ndarray:
    """The discounted sum of each episode's rewards so far, as ``VecNormalize`` keeps it to
    scale the rewards."""
    order = np.lexsort((step, episode))
    sums = np.empty_like(rewards, dtype=float)
    running = 0.0
    for rank, k in enumerate(order):
        if rank == 0 or episode[k] != episode[order[rank - 1]]:
            running = 0.0
        running = running * gamma + rewards[k]
        sums[k] = running
    return sums


def warm_start(
    model: Any, venv: Any, demonstrations: Demonstrations, config: WarmStartConfig, seed: int
) -> dict[str, Any]:
    """Set ``venv``'s (a ``VecNormalize``) statistics from the demonstrations and fit ``model``'s
    policy and value to them (module documentation, steps 2 and 3). Returns what was done, for
    the agent's ``training.json``."""
    import torch

    gamma = float(model.gamma)
    if venv.norm_obs:
        venv.obs_rms.update(demonstrations.observations)
    if venv.norm_reward:
        venv.ret_rms.update(running_returns(demonstrations.rewards, demonstrations.episode, demonstrations.step, gamma))
    observations = venv.normalize_obs(demonstrations.observations.astype(np.float32))
    rewards = venv.normalize_reward(demonstrations.rewards)
    returns = discounted_returns(rewards, demonstrations.episode, demonstrations.step, gamma)

    policy = model.policy
    policy.set_training_mode(True)
    optimizer = torch.optim.Adam(policy.parameters(), lr=config.learning_rate)
    obs_t = torch.as_tensor(observations, dtype=torch.float32)
    act_t = torch.as_tensor(demonstrations.actions, dtype=torch.int64)
    ret_t = torch.as_tensor(returns, dtype=torch.float32)
    generator = torch.Generator().manual_seed(seed)
    n = len(obs_t)
    for _ in range(config.epochs):
        for batch in torch.randperm(n, generator=generator).split(config.batch_size):
            values, log_prob, _ = policy.evaluate_actions(obs_t[batch], act_t[batch])
            loss = -log_prob.mean() + config.value_coefficient * torch.nn.functional.mse_loss(
                values.flatten(), ret_t[batch]
            )
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
    policy.set_training_mode(False)
    with torch.no_grad():
        agreement = []
        for batch in torch.arange(n).split(65536):
            predicted = policy.get_distribution(obs_t[batch]).mode()
            agreement.append((predicted == act_t[batch]).float().mean(dim=1))
        teacher_agreement = float(torch.cat(agreement).mean())
    return {
        **config.model_dump(),
        "samples": int(n),
        "teacher_agreement": round(teacher_agreement, 4),
    }
