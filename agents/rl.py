"""stable-baselines3 agents (PPO, SAC) on the batched brakegym environments.

Hyperparameters live in ``configs/agents/<algo>.yaml`` in rl_zoo3's format: one entry per
environment id, which rl_zoo3 reads as it is
(``python -m rl_zoo3.train --algo ppo --env brakegym/StationStop-v0 --gym-packages brakegym
--conf-file ppo.yaml``). Training here runs N trains in one
:class:`~brakegym.envs.BrakeVectorEnv` handed to SB3 through
:class:`~brakegym.envs.sb3.SB3VecEnv`, with ``VecNormalize``, an evaluation callback on a separate
batch of trains, a progress bar and an optional wall-clock budget. A trained agent is a folder:
``model.zip``, ``vecnormalize.pkl`` (the observation statistics) and ``training.json`` (what
produced it), beside SB3's training log (``log/progress.csv``) and the evaluations (``eval/``).

brakegym's own settings of a run live under the file's top-level ``brakegym`` key, per
environment id, where rl_zoo3 does not read them (it would pass unknown keys of an entry to the
algorithm and fail):

``eval_freq_steps``, ``n_eval_episodes``
    how often and on how many trains the evaluation callback runs;

``env_config``
    overrides of the environment's config for training and evaluation during training (e.g.
    reward weights); the environment's defaults are not touched, and stress tests run on them.
``residual``
    ``{base: pid, scale: s}``: the policy is a *residual* on the PID baseline (agents/pid.py): the
    command sent is ``clip(pid + s * policy, -1, 1)``, and the policy observes the environment's
    observation plus the PID's command. The PID gains are stored with the agent.
``kernel_threads``
    the most threads the simulator's compiled kernels use during training
    (:func:`brakegym.simulator.kernel.set_kernel_threads`; results are the same whatever the
    count). 1 on a machine of few cores: the kernels' OpenMP threads keep spinning after each
    parallel step and starve torch, which is several times slower then.
``jerk_shaping``
    ``{above_mps3: j0, weight_per_mps3: w}``: a training-only reward term ``-w * max(0, jerk - j0)``
    per control step on the train's jerk, which penalises the *peak* jerk (the environment's own
    jerk term is linear in ``|jerk|`` and so only penalises the total variation of the deceleration).
    Applied to the evaluation trains of the training run too, so that the kept checkpoint is the
    best on the objective trained for.
``warm_start``
    ``{teacher: wsp, ...}``: before training, the policy is fitted to a teacher controller's
    commands and its value to the returns of the teacher's episodes, and the normaliser takes
    their statistics (behaviour cloning, :mod:`brakegym.agents.warm_start`).
"""

from __future__ import annotations

import json
import platform
import time
from importlib import resources
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import Any

import numpy as np

from .. import config as cfg
from ..envs.registry import full_env_id
from ..stress import make_vector_env

ALGORITHMS = ("ppo", "sac", "ppo-residual")
# Keys of an entry that configure the run rather than the algorithm (rl_zoo3 takes them too).
ZOO_SETUP_KEYS = ("n_envs", "n_timesteps", "policy", "normalize")
# brakegym's own keys, allowed only in the file's ``brakegym`` section.
BRAKEGYM_KEYS = (
    "eval_freq_steps",
    "n_eval_episodes",
    "env_config",
    "residual",
    "jerk_shaping",
    "kernel_threads",
    "warm_start",
)
OWN_SECTION = "brakegym"


def shipped_policies() -> Traversable:
    """The folder of the trained policies that ship with brakegym (one agent folder each)."""
    return resources.files(__package__).joinpath("policies")


def _torch_single_thread() -> None:
    # On 2 cores, torch's intra-op threads fight the environment for the CPU: PPO is ~20x faster
    # with one thread here.
    import torch

    torch.set_num_threads(1)


def short_env_id(env_id: str) -> str:
    return env_id.split("/", 1)[1] if env_id.startswith("brakegym/") else env_id


def load_hyperparameters(algo: str, env_id: str, path: str | Path | None = None) -> dict[str, Any]:
    """The entry for ``env_id`` in ``agents/<algo>.yaml`` on the config search path (or ``path``),
    with brakegym's own settings for it from the file's ``brakegym`` section."""
    if algo not in ALGORITHMS:
        raise ValueError(f"unknown algorithm {algo!r}; choose one of {ALGORITHMS}")
    source = Path(path) if path else cfg.find("agents", algo)
    entries = cfg.read_yaml(source)
    key = full_env_id(env_id)
    if key not in entries:
        known = sorted(k for k in entries if k != OWN_SECTION)
        raise cfg.ConfigError(f"{source}: no entry {key!r}; entries: {known}")
    hyper = dict(entries[key])
    misplaced = sorted(set(hyper) & set(BRAKEGYM_KEYS))
    if misplaced:
        raise cfg.ConfigError(
            f"{source}: entry {key!r} holds brakegym's own key(s) {misplaced}: they belong under "
            f"'{OWN_SECTION}: {key}:', where rl_zoo3 does not read them"
        )
    own = dict((entries.get(OWN_SECTION) or {}).get(key) or {})
    unknown = sorted(set(own) - set(BRAKEGYM_KEYS))
    if unknown:
        raise cfg.ConfigError(
            f"{source}: '{OWN_SECTION}: {key}:' has unknown key(s) {unknown}; allowed {list(BRAKEGYM_KEYS)}"
        )
    hyper.update(own)
    rate = hyper.get("learning_rate")
    if isinstance(rate, str):
        _learning_rate(rate, f"{source}: entry {key!r}")  # refuse a bad schedule now, not after setup
    missing = [k for k in ZOO_SETUP_KEYS[:3] if k not in hyper]
    if missing:
        raise cfg.ConfigError(f"{source}: entry {key!r} lacks field(s) {missing}")
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


def _model_class(algo: str):
    from stable_baselines3 import PPO, SAC

    return {"ppo": PPO, "sac": SAC, "ppo-residual": PPO}[algo]


def _residual_observation(observation: np.ndarray, base_action: np.ndarray) -> np.ndarray:
    """What a residual policy observes: the environment's observation and the base command (all
    control groups get the same PID command, so one column)."""
    return np.concatenate([np.asarray(observation, dtype=np.float32), base_action[:, :1]], axis=1)


def _residual_action(base_action: np.ndarray, policy_action: np.ndarray, scale: float) -> np.ndarray:
    return np.clip(base_action + scale * np.asarray(policy_action, dtype=np.float32), -1.0, 1.0).astype(np.float32)


def _wrappers():
    """The SB3 VecEnv wrappers (defined on first use: SB3 is an optional dependency)."""
    from gymnasium import spaces
    from stable_baselines3.common.vec_env import VecEnvWrapper

    class ResidualPID(VecEnvWrapper):
        """The policy's action is a correction to the PID's command, scaled by ``scale``."""

        def __init__(self, venv: Any, gains: Any, scale: float):
            from .pid import PIDController

            self.brake_env = venv.env  # the BrakeVectorEnv inside SB3VecEnv
            self.pid = PIDController(self.brake_env.config, self.brake_env.observation_names, gains)
            self.scale = scale
            low = np.append(venv.observation_space.low, -1.0).astype(np.float32)
            high = np.append(venv.observation_space.high, 1.0).astype(np.float32)
            super().__init__(venv, observation_space=spaces.Box(low, high, dtype=np.float32))
            self.base_action = np.zeros((venv.num_envs, venv.action_space.shape[0]), dtype=np.float32)

        def _mass(self) -> dict[str, np.ndarray]:
            return {"mass_kg": self.brake_env.core.fleet.episodes.mass_kg}

        def reset(self):
            observation = self.venv.reset()
            self.pid.reset(self._mass())
            self.base_action = self.pid.act(observation)
            return _residual_observation(observation, self.base_action)

        def step_async(self, actions: np.ndarray) -> None:
            self.venv.step_async(_residual_action(self.base_action, actions, self.scale))

        def step_wait(self):
            observation, reward, dones, infos = self.venv.step_wait()
            ended = np.flatnonzero(dones)
            previous = self.base_action
            if len(ended):
                self.pid.reset(self._mass(), ended)  # the restarted trains' new episodes
            self.base_action = self.pid.act(observation)
            for i in ended:
                # The ended episode's last observation, with the command the PID gave before.
                infos[i]["terminal_observation"] = _residual_observation(
                    infos[i]["terminal_observation"][None], previous[i : i + 1]
                )[0]
            return _residual_observation(observation, self.base_action), reward, dones, infos

    class JerkShaping(VecEnvWrapper):
        """Training-only reward term: -weight * max(0, jerk - above) per control step."""

        def __init__(self, venv: Any, above_mps3: float, weight_per_mps3: float):
            inner = venv
            while not hasattr(inner, "env"):
                inner = inner.venv
            self.fleet = inner.env.core.fleet
            self.above_mps3, self.weight = float(above_mps3), float(weight_per_mps3)
            super().__init__(venv)

        def reset(self):
            return self.venv.reset()

        def step_wait(self):
            observation, reward, dones, infos = self.venv.step_wait()
            # The fleet's jerk is that of the step just taken (before any restart zeroes it).
            excess = np.maximum(self.fleet.jerk_mps3 - self.above_mps3, 0.0)
            return observation, (reward - self.weight * excess).astype(np.float32), dones, infos

    class RepeatEpisodes(VecEnvWrapper):
        """Every reset starts the same episodes (those of ``seed``): the evaluation trains of a
        training run, so that its checkpoints are compared on one set of trains rather than on
        draws whose initial speeds alone move the return by more than training does."""

        def __init__(self, venv: Any, seed: int):
            self.episode_seed = int(seed)
            super().__init__(venv)

        def reset(self):
            self.venv.seed(self.episode_seed)
            return self.venv.reset()

        def step_wait(self):
            return self.venv.step_wait()

    return ResidualPID, JerkShaping, RepeatEpisodes


def sb3_training_env(
    env_id: str,
    n_envs: int,
    seed: int,
    setup: str,
    env_config: dict[str, Any] | None,
    residual: dict[str, Any] | None = None,
    pid_gains: Any = None,
    jerk_shaping: dict[str, Any] | None = None,
    repeat_episodes: bool = False,
):
    """The batched environment as SB3 trains on it; with ``repeat_episodes`` every reset starts
    the episodes of ``seed`` again (the evaluation trains)."""
    from stable_baselines3.common.vec_env import VecMonitor

    from ..envs.sb3 import SB3VecEnv

    ResidualPID, JerkShaping, RepeatEpisodes = _wrappers()
    venv = SB3VecEnv(make_vector_env(env_id, n_envs, setup, env_config, autoreset=True))
    if residual:
        venv = ResidualPID(venv, pid_gains, float(residual["scale"]))
    if jerk_shaping:
        venv = JerkShaping(venv, **jerk_shaping)
    venv = VecMonitor(venv)
    if repeat_episodes:
        return RepeatEpisodes(venv, seed)
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
    """Train ``algo`` on ``env_id``; write the agent folder ``out_dir`` and return it.

    ``env_config`` is merged over the hyperparameter entry's ``env_config`` (both override the
    environment's defaults for training only)."""
    _torch_single_thread()
    from stable_baselines3.common.callbacks import CallbackList, EvalCallback
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.vec_env import VecNormalize

    hyper = load_hyperparameters(algo, env_id, hyperparameters)
    if "kernel_threads" in hyper:
        from ..simulator.kernel import set_kernel_threads

        set_kernel_threads(int(hyper["kernel_threads"]))
    algo_kwargs = {k: v for k, v in hyper.items() if k not in ZOO_SETUP_KEYS + BRAKEGYM_KEYS}
    if "learning_rate" in algo_kwargs:
        algo_kwargs["learning_rate"] = _learning_rate(algo_kwargs["learning_rate"])
    n_envs = int(hyper["n_envs"])
    steps = int(total_timesteps if total_timesteps is not None else float(hyper["n_timesteps"]))
    normalize = dict(hyper.get("normalize") or {})
    training_env_config = {**(hyper.get("env_config") or {}), **(env_config or {})}
    residual = hyper.get("residual")
    if algo == "ppo-residual" and not residual:
        raise cfg.ConfigError(
            f"{algo}: the hyperparameter entry for {short_env_id(env_id)} needs residual: {{base: pid, scale: ...}}"
        )
    pid_gains = None
    if residual:
        if residual.get("base") != "pid" or not float(residual.get("scale", 0)) > 0:
            raise cfg.ConfigError(f"residual = {residual}: need base: pid and a positive scale")
        from .pid import load_pid_config

        pid_gains = load_pid_config()
    wrapping = {"residual": residual, "pid_gains": pid_gains, "jerk_shaping": hyper.get("jerk_shaping")}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)

    venv = VecNormalize(sb3_training_env(env_id, n_envs, seed, setup, training_env_config, **wrapping), **normalize)
    eval_env = VecNormalize(
        sb3_training_env(
            env_id,
            min(int(hyper.get("n_eval_episodes", 64)), 128),
            seed + 10_000,
            setup,
            training_env_config,
            **wrapping,
            repeat_episodes=True,
        ),
        training=False,
        norm_reward=False,
        norm_obs=normalize.get("norm_obs", True),
    )
    model = _model_class(algo)(hyper["policy"], venv, seed=seed, verbose=0, device="cpu", **algo_kwargs)
    # The training log goes with the run: without a logger of its own, learn() opens a new folder
    # in the system's temporary directory on every call and leaves it there.
    model.set_logger(configure(str(out / "log"), ["csv"]))
    warm_start = None
    if hyper.get("warm_start"):
        if residual or hyper.get("jerk_shaping"):
            raise cfg.ConfigError(f"{short_env_id(env_id)}: warm_start does not combine with residual or jerk_shaping")
        from stable_baselines3.common.evaluation import evaluate_policy
        from stable_baselines3.common.vec_env import sync_envs_normalization

        from .warm_start import WarmStartConfig, collect_demonstrations, teacher_return
        from .warm_start import warm_start as fit_to_teacher

        warm_config = WarmStartConfig.model_validate(hyper["warm_start"])
        warm_started = time.monotonic()
        demonstrations = collect_demonstrations(env_id, n_envs, seed + 20_000, setup, training_env_config, warm_config)
        warm_start = fit_to_teacher(model, venv, demonstrations, warm_config, seed)
        warm_start["wall_time_s"] = round(time.monotonic() - warm_started, 1)
        # Where training starts from, on the evaluation trains its checkpoints are judged on.
        sync_envs_normalization(venv, eval_env)
        warm_start["eval_reward"] = round(
            float(evaluate_policy(model, eval_env, n_eval_episodes=eval_env.num_envs)[0]), 3
        )
        warm_start["teacher_eval_reward"] = round(teacher_return(eval_env, env_id, warm_config.teacher), 3)
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
    budget = f" --time-budget-min {time_budget_s / 60:g}" if time_budget_s is not None else ""
    explicit_steps = f" --timesteps {steps}" if total_timesteps is not None else ""
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
        "env_config": training_env_config,
        "machine": platform.platform(),
        "command": (
            f"brakegym train --algo {algo} --env {short_env_id(env_id)} --seed {seed}{explicit_steps}{budget} "
            f"--out {out}"
        ),
    }
    if residual:
        meta["residual"] = {**residual, "pid_gains": pid_gains.model_dump()}
    if warm_start:
        meta["warm_start"] = warm_start
    (out / "training.json").write_text(json.dumps(meta, indent=2))
    best = out / "best"
    if (best / "best_model.zip").is_file():
        # The evaluation callback's best checkpoint, made an agent folder of its own (the one to
        # ship: chosen on evaluation trains, not on the stress test's).
        (best / "best_model.zip").replace(best / "model.zip")
        evaluations = np.load(out / "eval" / "evaluations.npz")
        rewards = evaluations["results"].mean(axis=1)
        k = int(np.argmax(rewards))
        checkpoint = {
            "checkpoint": "best by evaluation reward",
            "checkpoint_step": int(evaluations["timesteps"][k]),
            "checkpoint_eval_reward": float(rewards[k]),
        }
        (best / "training.json").write_text(json.dumps({**meta, **checkpoint}, indent=2))
    return out


class PolicyController:
    """A trained SB3 agent as a batch controller (deterministic actions on normalised
    observations), for evaluation and the stress harness."""

    def __init__(self, agent_dir: str | Path | Traversable):
        _torch_single_thread()
        import pickle

        folder = agent_dir if isinstance(agent_dir, Traversable) else Path(agent_dir)
        meta_path = folder.joinpath("training.json")
        if not meta_path.is_file():
            raise FileNotFoundError(f"{folder}: not an agent folder (no training.json)")
        self.meta = json.loads(meta_path.read_text())
        with resources.as_file(folder.joinpath("model.zip")) as model_path:
            self.model = _model_class(self.meta["algo"]).load(model_path, device="cpu")
        with folder.joinpath("vecnormalize.pkl").open("rb") as handle:
            self.normalizer = pickle.load(handle)  # VecNormalize without its env: the statistics
        self.name = f"{self.meta['algo']}:{folder.name}"
        self.residual = self.meta.get("residual")
        self.base = None

    def for_env(self, env: Any) -> PolicyController:
        """Bind to a batched environment (a residual policy builds its PID base for it, with the
        gains it was trained with)."""
        if self.residual:
            from .pid import PIDConfig, PIDController

            gains = PIDConfig.model_validate(self.residual["pid_gains"])
            self.base = PIDController(env.config, env.observation_names, gains)
        return self

    def reset(self, info: dict[str, Any]) -> None:
        """The policy keeps no state between steps; a residual policy's PID base does."""
        if self.residual:
            if self.base is None:
                raise RuntimeError("a residual policy needs for_env(env) before reset()")
            self.base.reset(info)

    def act(self, observation: np.ndarray) -> np.ndarray:
        observation = np.asarray(observation, dtype=np.float32)
        if self.residual:
            base_action = self.base.act(observation)
            observation = _residual_observation(observation, base_action)
        actions, _ = self.model.predict(self.normalizer.normalize_obs(observation), deterministic=True)
        if self.residual:
            return _residual_action(base_action, actions, float(self.residual["scale"]))
        return actions
