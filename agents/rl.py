"""stable-baselines3 agents (PPO, SAC) on the batched brakegym environments.

Hyperparameters live in ``configs/agents/<algo>.yaml`` (RL Zoo style, one entry per environment).
Training runs N trains in one :class:`~brakegym.envs.BrakeVectorEnv` handed to SB3 through
:class:`~brakegym.envs.sb3.SB3VecEnv`, with ``VecNormalize``, an evaluation callback on a separate
batch of trains, a progress bar and an optional wall-clock budget. A trained agent is a folder:
``model.zip``, ``vecnormalize.pkl`` (the observation statistics) and ``training.json`` (what
produced it).
"""

from __future__ import annotations

import json
import platform
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from brakegym import config as cfg
from brakegym.stress import make_vector_env

ALGORITHMS = ("ppo", "sac")
# Keys of the hyperparameter files that configure the set-up rather than the algorithm.
SETUP_KEYS = ("n_envs", "n_timesteps", "policy", "normalize", "eval_freq_steps", "n_eval_episodes")
SHIPPED_POLICIES = Path(__file__).resolve().parent / "policies"


def _torch_single_thread() -> None:
    # On 2 cores, torch's intra-op threads fight the environment for the CPU: PPO is ~20x faster
    # with one thread here.
    import torch

    torch.set_num_threads(1)


def short_env_id(env_id: str) -> str:
    return env_id.split("/", 1)[1] if env_id.startswith("brakegym/") else env_id


def load_hyperparameters(algo: str, env_id: str, path: str | Path | None = None) -> dict[str, Any]:
    """The entry for ``env_id`` in ``configs/agents/<algo>.yaml`` (or ``path``)."""
    if algo not in ALGORITHMS:
        raise ValueError(f"unknown algorithm {algo!r}; choose one of {ALGORITHMS}")
    path = Path(path) if path else cfg.config_dir() / "agents" / f"{algo}.yaml"
    try:
        entries = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise cfg.ConfigError(f"{path}: cannot read hyperparameters: {exc}") from exc
    key = short_env_id(env_id)
    if not isinstance(entries, dict) or key not in entries:
        known = sorted(entries) if isinstance(entries, dict) else []
        raise cfg.ConfigError(f"{path}: no entry {key!r}; entries: {known}")
    hyper = dict(entries[key])
    rate = hyper.get("learning_rate")
    if isinstance(rate, str):
        _learning_rate(rate, f"{path}: entry {key!r}")  # refuse a bad schedule now, not after setup
    missing = [k for k in ("n_envs", "n_timesteps", "policy") if k not in hyper]
    if missing:
        raise cfg.ConfigError(f"{path}: entry {key!r} lacks field(s) {missing}")
    return hyper


def _learning_rate(value: Any, where: str = "learning_rate") -> Any:
    """A number, or RL Zoo's "lin_3e-4": decaying linearly from 3e-4 to 0 over training."""
    if not isinstance(value, str):
        return value
    if not value.startswith("lin_"):
        raise cfg.ConfigError(f"{where}: learning_rate {value!r} is neither a number nor lin_<value>")
    try:
        initial = float(value[4:])
    except ValueError:
        raise cfg.ConfigError(f"{where}: learning_rate {value!r}: bad number after lin_") from None
    return lambda progress_remaining: progress_remaining * initial


def _vec_env(env_id: str, n_envs: int, seed: int, setup: str, env_config: dict[str, Any] | None):
    from stable_baselines3.common.vec_env import VecMonitor

    from brakegym.envs.sb3 import SB3VecEnv

    venv = VecMonitor(SB3VecEnv(make_vector_env(env_id, n_envs, setup, env_config, autoreset=True)))
    venv.seed(seed)
    return venv


def _save_normalizer_on_best(venv: Any, path: Path):
    """Keeps the observation statistics that belong to the best model, beside it."""
    from stable_baselines3.common.callbacks import BaseCallback

    class SaveNormalizer(BaseCallback):
        def _on_step(self) -> bool:
            path.mkdir(parents=True, exist_ok=True)
            venv.save(str(path / "vecnormalize.pkl"))
            return True

    return SaveNormalizer()


def _time_budget(budget_s: float):
    """Stops training once ``budget_s`` of wall-clock time has passed."""
    from stable_baselines3.common.callbacks import BaseCallback

    class TimeBudget(BaseCallback):
        def _init_callback(self) -> None:
            self.deadline = time.monotonic() + budget_s

        def _on_step(self) -> bool:
            return time.monotonic() < self.deadline

    return TimeBudget()


def train(
    algo: str,
    env_id: str,
    out_dir: str | Path,
    seed: int = 0,
    total_timesteps: int | None = None,
    time_budget_s: float | None = None,
    setup: str = "mcs-75-25",
    env_config: dict[str, Any] | None = None,
    hyperparameters: str | Path | None = None,
    progress_bar: bool = True,
) -> Path:
    """Train ``algo`` on ``env_id``; write the agent folder ``out_dir`` and return it."""
    _torch_single_thread()
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.callbacks import CallbackList, EvalCallback
    from stable_baselines3.common.vec_env import VecNormalize

    hyper = load_hyperparameters(algo, env_id, hyperparameters)
    algo_kwargs = {k: v for k, v in hyper.items() if k not in SETUP_KEYS}
    if "learning_rate" in algo_kwargs:
        algo_kwargs["learning_rate"] = _learning_rate(algo_kwargs["learning_rate"])
    n_envs = int(hyper["n_envs"])
    steps = int(total_timesteps if total_timesteps is not None else float(hyper["n_timesteps"]))
    normalize = dict(hyper.get("normalize") or {})
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)

    venv = VecNormalize(_vec_env(env_id, n_envs, seed, setup, env_config), **normalize)
    eval_env = VecNormalize(
        _vec_env(env_id, min(int(hyper.get("n_eval_episodes", 64)), 128), seed + 10_000, setup, env_config),
        training=False,
        norm_reward=False,
        norm_obs=normalize.get("norm_obs", True),
    )
    model_class = {"ppo": PPO, "sac": SAC}[algo]
    model = model_class(hyper["policy"], venv, seed=seed, verbose=0, device="cpu", **algo_kwargs)
    callbacks = [
        EvalCallback(
            eval_env,
            n_eval_episodes=int(hyper.get("n_eval_episodes", 64)),
            eval_freq=max(int(hyper.get("eval_freq_steps", 100_000)) // n_envs, 1),
            best_model_save_path=str(out / "best"),
            callback_on_new_best=_save_normalizer_on_best(venv, out / "best"),
            log_path=str(out / "eval"),
            deterministic=True,
            verbose=0,
        )
    ]
    if time_budget_s is not None:
        callbacks.append(_time_budget(time_budget_s))
    started = time.monotonic()
    model.learn(total_timesteps=steps, callback=CallbackList(callbacks), progress_bar=progress_bar)
    wall_s = time.monotonic() - started
    model.save(out / "model.zip")
    venv.save(str(out / "vecnormalize.pkl"))
    meta = {
        "algo": algo,
        "env": short_env_id(env_id),
        "setup": setup,
        "seed": seed,
        "timesteps": int(model.num_timesteps),
        "requested_timesteps": steps,
        "time_budget_s": time_budget_s,
        "wall_time_s": round(wall_s, 1),
        "hyperparameters": hyper,
        "env_config": env_config or {},
        "machine": platform.platform(),
        "command": f"brakegym train --algo {algo} --env {short_env_id(env_id)} --seed {seed} --timesteps {steps} --out {out}",
    }
    (out / "training.json").write_text(json.dumps(meta, indent=2))
    best = out / "best"
    if (best / "best_model.zip").is_file():
        # The evaluation callback's best checkpoint, made an agent folder of its own (the one to
        # ship: chosen on evaluation trains, not on the stress test's).
        (best / "best_model.zip").replace(best / "model.zip")
        (best / "training.json").write_text(json.dumps({**meta, "checkpoint": "best by evaluation reward"}, indent=2))
    return out


class PolicyController:
    """A trained SB3 agent as a batch controller (deterministic actions on normalised
    observations), for evaluation and the stress harness."""

    def __init__(self, agent_dir: str | Path):
        _torch_single_thread()
        from stable_baselines3 import PPO, SAC

        folder = Path(agent_dir)
        meta_path = folder / "training.json"
        if not meta_path.is_file():
            raise FileNotFoundError(f"{folder}: not an agent folder (no training.json)")
        self.meta = json.loads(meta_path.read_text())
        model_class = {"ppo": PPO, "sac": SAC}[self.meta["algo"]]
        self.model = model_class.load(folder / "model.zip", device="cpu")
        import pickle

        with open(folder / "vecnormalize.pkl", "rb") as handle:
            self.normalizer = pickle.load(handle)  # VecNormalize without its env: the statistics
        self.name = f"{self.meta['algo']}:{folder.name}"

    def reset(self, info: dict[str, Any]) -> None:
        """The policy keeps no state between steps."""

    def act(self, observation: np.ndarray) -> np.ndarray:
        observation = self.normalizer.normalize_obs(np.asarray(observation, dtype=np.float32))
        actions, _ = self.model.predict(observation, deterministic=True)
        return actions
