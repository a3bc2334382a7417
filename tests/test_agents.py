"""Baseline controllers and the stress harness: what a user relies on when comparing controllers."""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np
import pytest

from brakegym.agents.pid import PIDController, load_pid_config
from brakegym.cli import main
from brakegym.config import ConfigError
from brakegym.stress import report, run_stress, table


def _pid(env):
    return PIDController(env.config, env.observation_names)


def test_pid_station_stop_meets_the_accuracy_target():
    """Issue target: 99 % of stops within 0.5 m of the mark under MCS-75/25."""
    result = run_stress("StationStop-v0", _pid, "pid", setup="mcs-75-25", episodes=200, seed=5, batch_size=200)
    assert result.success.mean() >= 0.99
    assert np.percentile(np.abs(result.metric), 99) < 0.5
    assert not result.ended_by_time_limit.any()


def test_pid_tracks_deceleration_demand():
    result = run_stress("DecelTracking-v0", _pid, "pid", episodes=50, seed=1, batch_size=50)
    # Mean |deceleration - demand| over each stop, including the brake's 1 s build-up per step.
    assert result.metric.mean() < 0.1


def test_pid_emergency_stop_respects_the_temperature_limit():
    result = run_stress("EmergencyStop-v0", _pid, "pid", episodes=50, seed=2, batch_size=50)
    assert result.success.all()
    assert result.peak_disc_temperature_C.max() < 600.0


def test_stress_is_deterministic_and_reports_bands():
    first = run_stress("StationStop-v0", _pid, "pid", episodes=40, seed=9, batch_size=20, keep_worst=2)
    second = run_stress("StationStop-v0", _pid, "pid", episodes=40, seed=9, batch_size=20, keep_worst=2)
    np.testing.assert_array_equal(first.metric, second.metric)
    np.testing.assert_array_equal(first.peak_jerk_mps3, second.peak_jerk_mps3)
    rep = report(first, [40, 60, 80, 100])
    assert sum(band["episodes"] for band in rep["bands"]) == 40
    assert len(first.worst) == 2 and first.worst[0]["trace"]["speed_mps"][0] > 0
    assert "| pid | all | 40 |" in table([rep])


def test_pid_gains_config_is_validated(tmp_path):
    bad = tmp_path / "pid.yaml"
    bad.write_text((load_pid_config().model_dump_json()).replace('"proportional_gain":0.6', '"proportional_gain":-1'))
    with pytest.raises(ConfigError, match="proportional_gain"):
        load_pid_config(bad)


def test_cli_stress_writes_table_figure_and_json(tmp_path, capsys):
    out = tmp_path / "stress"
    code = main(
        [
            "stress",
            "--agent",
            "pid",
            "--episodes",
            "30",
            "--batch",
            "30",
            "--out",
            str(out),
            "--json",
            str(tmp_path / "s.json"),
        ]
    )
    assert code == 0
    payload = json.loads((tmp_path / "s.json").read_text())
    overall = payload["agents"][0]["overall"]
    assert overall["episodes"] == 30 and 0.0 <= overall["success_rate"] <= 1.0
    assert {"stop_error_m_abs_p95", "stop_error_m_abs_p99", "stop_error_m_abs_worst", "peak_jerk_mps3_max"} <= set(
        overall
    )
    assert (out / "stress_comparison.png").stat().st_size > 10_000
    assert json.loads((out / "worst_pid.json").read_text())
    assert "| pid | all | 30 |" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, message",
    [
        (["stress", "--agent", "nonsense", "--episodes", "5"], "not pid, ppo, sac, ppo-residual or an agent folder"),
        (["stress", "--agent", "pid", "--env", "Nope-v0"], "unknown environment"),
        (["stress", "--agent", "pid", "--bands", "80,40"], "increasing"),
        (["evaluate", "--episodes", "0"], "at least 1"),
        (["evaluate", "--setup", "mcs-50"], "unknown setup"),
    ],
)
def test_cli_agent_commands_refuse_bad_arguments(argv, message, capsys):
    try:
        code = main(argv)
    except SystemExit as exit_:  # argparse rejects the argument itself
        code = exit_.code
    assert code == 2
    assert message in capsys.readouterr().err


def test_shipped_ppo_policy_stops_trains_on_the_mark():
    """The policy in agents/policies/ evaluates without training (README numbers come from
    `brakegym stress --agent pid --agent ppo --episodes 1000 --seed 100`)."""
    from brakegym.cli.controllers import controller_factory

    name, factory = controller_factory("ppo", "brakegym/StationStop-v0")
    result = run_stress("StationStop-v0", factory, name, episodes=100, seed=100, batch_size=100)
    assert result.success.mean() >= 0.95
    assert np.median(np.abs(result.metric)) < 0.1


def _tiny_hyperparameters(tmp_path, **extra):
    import yaml

    entry = {
        "n_envs": 4,
        "n_timesteps": 128,
        "policy": "MlpPolicy",
        "normalize": {"norm_obs": True, "norm_reward": True},
        "n_steps": 32,
        "batch_size": 64,
        "n_epochs": 1,
        "policy_kwargs": {"net_arch": [8, 8]},
    }
    own = {"eval_freq_steps": 64, "n_eval_episodes": 4, **extra}  # brakegym's keys, apart from rl_zoo3's
    path = tmp_path / "hyper.yaml"
    path.write_text(yaml.safe_dump({"brakegym/StationStop-v0": entry, "brakegym": {"brakegym/StationStop-v0": own}}))
    return path


def test_residual_agent_round_trip_and_zero_correction_is_the_pid(tmp_path):
    """A residual agent folder records its set-up (PID gains, env overrides) and, with the policy's
    correction forced to zero, commands exactly what the PID commands."""
    from brakegym.agents.rl import PolicyController, train

    hyper = _tiny_hyperparameters(
        tmp_path,
        residual={"base": "pid", "scale": 0.5},
        jerk_shaping={"above_mps3": 0.6, "weight_per_mps3": 1.0},
        env_config={"reward": {"jerk_per_mps3": 0.1}},
    )
    logs_elsewhere = set(Path(tempfile.gettempdir()).glob("SB3-*"))
    folder = train(
        "ppo-residual", "StationStop-v0", tmp_path / "agent", seed=3, hyperparameters=hyper, progress_bar=False
    )
    # The training log is kept with the run, not left in the system's temporary directory.
    assert (folder / "log" / "progress.csv").is_file()
    assert set(Path(tempfile.gettempdir()).glob("SB3-*")) == logs_elsewhere
    meta = json.loads((folder / "training.json").read_text())
    assert meta["env_config"] == {"reward": {"jerk_per_mps3": 0.1}}
    assert meta["residual"]["scale"] == 0.5 and meta["residual"]["pid_gains"]["proportional_gain"] == 0.6
    assert meta["command"].startswith("brakegym train --algo ppo-residual --env StationStop-v0 --seed 3")
    assert (folder / "best" / "model.zip").is_file() and json.loads((folder / "best" / "training.json").read_text())[
        "checkpoint_step"
    ] > 0

    controller = PolicyController(folder)
    groups = controller.model.action_space.shape[0]
    controller.model.predict = lambda observation, deterministic: (
        np.zeros((len(observation), groups), dtype=np.float32),
        None,
    )
    residual = run_stress("StationStop-v0", controller.for_env, "zero", episodes=8, seed=4, batch_size=8)
    pid = run_stress("StationStop-v0", _pid, "pid", episodes=8, seed=4, batch_size=8)
    np.testing.assert_array_equal(residual.metric, pid.metric)


def test_residual_needs_its_set_up(tmp_path):
    from brakegym.agents.rl import train

    with pytest.raises(ConfigError, match="residual"):
        train(
            "ppo-residual",
            "StationStop-v0",
            tmp_path / "agent",
            hyperparameters=_tiny_hyperparameters(tmp_path),
            progress_bar=False,
        )


def test_shipped_residual_policy_stops_on_the_mark_with_lower_jerk_than_the_pid():
    """The shipped PPO residual on the PID (README: 100 % at seeds 100 and 200, 1000 episodes each,
    peak jerk p95 0.9 m/s3 against the PID's 1.22)."""
    from brakegym.cli.controllers import controller_factory

    name, factory = controller_factory("ppo-residual", "brakegym/StationStop-v0")
    result = run_stress("StationStop-v0", factory, name, episodes=100, seed=100, batch_size=100)
    pid = run_stress("StationStop-v0", _pid, "pid", episodes=100, seed=100, batch_size=100)
    assert result.success.mean() >= 0.99
    assert np.median(np.abs(result.metric)) < 0.1
    assert np.percentile(result.peak_jerk_mps3, 95) < np.percentile(pid.peak_jerk_mps3, 95) - 0.15


def test_the_evaluation_trains_of_a_training_run_are_the_same_at_every_evaluation():
    """The evaluation callback resets its environment before each evaluation; its trains must be
    the same each time, so that checkpoints are compared on one set of trains."""
    from brakegym.agents.rl import sb3_training_env

    evaluation = sb3_training_env("brakegym/StationStop-v0", 4, 10_000, "mcs-75-25", None, repeat_episodes=True)
    first = evaluation.reset()
    evaluation.step(np.zeros((4, evaluation.action_space.shape[0]), dtype=np.float32))
    np.testing.assert_array_equal(evaluation.reset(), first)
    training = sb3_training_env("brakegym/StationStop-v0", 4, 10_000, "mcs-75-25", None)
    np.testing.assert_array_equal(training.reset(), first)
    assert not np.array_equal(training.reset(), first)  # training draws new trains at each reset
