"""The Gymnasium environments: API conformance, determinism, input errors, batching, physics."""

from __future__ import annotations

import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest

import brakegym  # noqa: F401  (registers the environments)
from brakegym.config import ConfigError
from brakegym.envs import BrakeEnv, BrakeVectorEnv

ENV_IDS = ["brakegym/StationStop-v0", "brakegym/DecelTracking-v0", "brakegym/EmergencyStop-v0"]
QUIET = {
    "sensor_noise": {"speed_mps": 0.0, "decel_mps2": 0.0, "pressure_bar": 0.0, "temperature_C": 0.0, "distance_m": 0.0}
}


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_gymnasium_env_checker_passes_without_warnings(env_id):
    from gymnasium.utils.env_checker import check_env

    env = gym.make(env_id).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env, skip_render_check=True)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_sb3_env_checker_passes_without_warnings(env_id):
    from stable_baselines3.common.env_checker import check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(gym.make(env_id).unwrapped, warn=True)


def test_make_with_module_prefix_works_without_import():
    code = (
        "import gymnasium as gym, warnings; warnings.simplefilter('error');"
        "env = gym.make('brakegym:brakegym/StationStop-v0'); env.reset(seed=0); print('ok')"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_registration_is_idempotent():
    import importlib

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # gymnasium warns when an id is registered twice
        importlib.reload(brakegym)
    assert all(env_id in gym.registry for env_id in ENV_IDS)


def _episode(env, seed, steps=60, action=0.3):
    observation, _ = env.reset(seed=seed)
    rows = [observation]
    for _ in range(steps):
        observation, reward, terminated, truncated, info = env.step(np.full(env.action_space.shape, action, np.float32))
        rows.append(np.append(observation, reward))
        if terminated or truncated:
            break
    return rows


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_same_seed_same_episode_bit_for_bit(env_id):
    first = _episode(gym.make(env_id), seed=7)
    second = _episode(gym.make(env_id), seed=7)
    other = _episode(gym.make(env_id), seed=8)
    assert len(first) == len(second)
    assert all(np.array_equal(a, b) for a, b in zip(first, second))
    assert not np.array_equal(first[0], other[0])


def test_invalid_actions_raise_clear_errors():
    env = BrakeEnv("station_stop")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([0.1, np.nan, 0.1, 0.1], dtype=np.float32))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(3, dtype=np.float32))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros((1, 4), dtype=np.float32))


def test_out_of_range_actions_are_clipped_to_the_space():
    """Documented behaviour: values beyond [-1, 1] act like the nearest bound."""
    results = []
    for action in (1.0, 7.5):
        env = BrakeEnv("station_stop")
        env.reset(seed=3)
        for _ in range(20):
            observation, *_ = env.step(np.full(4, action, np.float32))
        results.append(observation)
    np.testing.assert_array_equal(results[0], results[1])
    env = BrakeEnv("station_stop")
    env.reset(seed=3)
    _, _, _, _, info = env.step(np.full(4, -3.0, np.float32))
    assert np.all(info["command_bar"] == 0.0)


def test_full_action_commands_the_vehicle_maximum_pressure():
    env = BrakeEnv("station_stop", config={"control_groups": "axle"})
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.ones(8, np.float32))
    np.testing.assert_allclose(info["command_bar"], 4.5)
    for _ in range(60):
        _, _, _, _, info = env.step(np.ones(8, np.float32))
    # EP: 0.2 s dead time, 0.8 s lag: after 6.1 s the cylinders are within 0.1 % of the command.
    np.testing.assert_allclose(info["cylinder_pressure_bar"], 4.5, rtol=2e-3)


@pytest.mark.parametrize("task", ["station_stop", "decel_tracking"])
def test_random_actions_never_produce_nan(task):
    """10^5 random-action train-steps, with autoresets, stay finite and inside the space."""
    env = BrakeVectorEnv(task, num_envs=250)
    observation, _ = env.reset(seed=11)
    rng = np.random.default_rng(0)
    for _ in range(400):
        action = rng.uniform(-1.2, 1.2, env.action_space.shape).astype(np.float32)
        observation, reward, terminated, truncated, info = env.step(action)
        assert np.isfinite(observation).all() and np.isfinite(reward).all()
        assert env.observation_space.contains(observation)
        assert np.isfinite(info["mu"]).all()


def test_vector_env_matches_single_env_physics():
    """Without noise or scatter, a batch of trains and one train see the same physics."""
    options = {
        "initial_speed_kmh": 80.0,
        "load": "normal",
        "setup": "ds",
        "initial_disc_temperature_C": 60.0,
        "distance_to_mark_m": 400.0,
    }
    single = BrakeEnv("station_stop", config=QUIET)
    single.reset(seed=0, options=options)
    vector = BrakeVectorEnv("station_stop", num_envs=5, config=QUIET)
    vector.reset(seed=1, options=options)
    for _ in range(100):
        single_observation, *_ = single.step(np.full(4, 0.1, np.float32))
        vector_observation, *_ = vector.step(np.full((5, 4), 0.1, np.float32))
    for row in vector_observation:
        np.testing.assert_allclose(row, single_observation, rtol=1e-6)


def test_make_vec_uses_the_native_vector_env():
    env = gym.make_vec("brakegym/StationStop-v0", num_envs=4)
    assert isinstance(env.unwrapped, BrakeVectorEnv) and env.unwrapped.config.name == "station_stop"
    observation, _ = env.reset(seed=0)
    assert observation.shape == (4, env.single_observation_space.shape[0])


def test_autoreset_same_step_reports_final_observation():
    env = BrakeVectorEnv("station_stop", num_envs=3, config=QUIET)
    env.reset(
        seed=0,
        options={
            "initial_speed_kmh": 20.0,
            "distance_to_mark_m": 50.0,
            "setup": "ds",
            "load": "max",
            "initial_disc_temperature_C": 50.0,
        },
    )
    for _ in range(1000):
        observation, _, terminated, truncated, info = env.step(np.ones((3, 4), np.float32))
        if (terminated | truncated).any():
            break
    ended = terminated | truncated
    assert ended.all()  # identical trains (no scatter) end together
    assert info["_final_obs"].all()
    assert np.all(info["final_obs"][:, 0] == 0.0)  # the ended episodes stand still
    np.testing.assert_allclose(observation[:, 0], 20.0 / 3.6)  # the new ones start at speed


def test_station_stop_success_and_reward_terms():
    env = BrakeEnv("station_stop", config=QUIET)
    env.reset(seed=0, options={"initial_speed_kmh": 30.0, "distance_to_mark_m": 60.0})
    total = 0.0
    for _ in range(600):
        observation, reward, terminated, truncated, info = env.step(np.full(4, 0.6, np.float32))
        total += reward
        assert reward == pytest.approx(sum(info["reward_terms"].values()))
        if terminated or truncated:
            break
    assert terminated
    # 3.6 bar from 30 km/h stops well short of 60 m: not a success.
    assert info["stop_error_m"] < -0.5 and not info["is_success"]
    assert info["reward_terms"]["stop_accuracy"] == pytest.approx(-abs(info["stop_error_m"]))


def test_station_stop_overrun_ends_the_episode():
    env = BrakeEnv("station_stop", config=QUIET)
    env.reset(seed=0, options={"initial_speed_kmh": 60.0, "distance_to_mark_m": 50.0})
    for _ in range(600):
        _, _, terminated, truncated, info = env.step(np.full(4, -1.0, np.float32))
        if terminated or truncated:
            break
    assert terminated and info["overran"] and not info["is_success"]
    assert 2.0 < info["stop_error_m"] < 2.0 + 60 / 3.6 * 0.1 + 1e-9
    assert info["speed_mps"] > 0


def test_decel_tracking_follows_given_demand():
    env = gym.make("brakegym/DecelTracking-v0", config=QUIET).unwrapped
    observation, _ = env.reset(seed=0, options={"demand_mps2": [0.5, 0.8], "demand_hold_s": [5.0, 100.0]})
    names = env.observation_names
    demand = [observation[names.index("demand_mps2")]]
    for _ in range(80):
        observation, *_ = env.step(np.zeros(4, np.float32))
        demand.append(observation[names.index("demand_mps2")])
    # 0 before 1 s, 0.5 from 1 s, 0.8 from 6 s (control steps of 0.1 s)
    assert demand[5] == 0.0 and demand[10] == pytest.approx(0.5) and demand[60] == pytest.approx(0.8)


def test_emergency_stop_overheat_terminates():
    env = gym.make("brakegym/EmergencyStop-v0", config={**QUIET, "disc_temperature_limit_C": 200.0}).unwrapped
    env.reset(seed=0, options={"initial_speed_kmh": 160.0, "initial_disc_temperature_C": 150.0})
    for _ in range(2000):
        _, reward, terminated, truncated, info = env.step(np.ones(4, np.float32))
        if terminated or truncated:
            break
    assert terminated and info["overheated"] and not info["is_success"]
    assert max(info["friction_temperature_C"]) > 200.0
    assert info["reward_terms"]["overheat"] == -10.0


def test_thermal_state_carries_over_between_episodes():
    env = BrakeEnv("station_stop", config={**QUIET, "carry_over_thermal_state": True})
    env.reset(seed=0, options={"initial_speed_kmh": 100.0, "distance_to_mark_m": 600.0})
    info = {}
    for _ in range(2000):
        _, _, terminated, truncated, info = env.step(np.ones(4, np.float32))
        if terminated or truncated:
            break
    _, new_info = env.reset()
    np.testing.assert_array_equal(new_info["friction_temperature_C"], info["friction_temperature_C"])
    np.testing.assert_array_equal(new_info["disc_temperature_C"], info["disc_temperature_C"])
    assert max(new_info["friction_temperature_C"]) > 100.0


def test_only_the_instrumented_disc_can_be_observed():
    env = BrakeEnv("station_stop", config={"observed_temperatures": "instrumented", "instrumented_disc": 5})
    assert [n for n in env.observation_names if n.startswith("temperature")] == ["temperature_C_5"]


def test_bad_config_and_options_are_refused_with_names():
    with pytest.raises(ConfigError, match="control_groups"):
        BrakeEnv("station_stop", config={"control_groups": "wagon"})
    with pytest.raises(ConfigError, match="simulation_frequency_hz"):
        BrakeEnv("station_stop", config={"simulation_frequency_hz": 15})
    with pytest.raises(ConfigError, match="no_such_field"):
        BrakeEnv("station_stop", config={"no_such_field": 1})
    with pytest.raises(ConfigError, match="loads"):
        BrakeEnv("station_stop", config={"loads": ["crush"]})
    env = BrakeEnv("station_stop")
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(seed=0, options={"initial_speed": 50})
    with pytest.raises(ValueError, match="load"):
        env.reset(seed=0, options={"load": "crush"})
    with pytest.raises(RuntimeError, match="reset"):
        BrakeEnv("station_stop").step(np.zeros(4, np.float32))


def test_render_modes():
    env = BrakeEnv("station_stop", render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.zeros(4, np.float32))
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    env = BrakeEnv("station_stop", render_mode="ansi")
    env.reset(seed=0)
    env.step(np.zeros(4, np.float32))
    assert "km/h" in env.render() and "to go" in env.render()


def test_sb3_adapter_trains_ppo_on_the_batched_env():
    import torch
    from stable_baselines3 import PPO

    from brakegym.envs.sb3 import SB3VecEnv

    torch.set_num_threads(1)
    venv = SB3VecEnv(BrakeVectorEnv("station_stop", num_envs=8, config={"max_episode_time_s": 3.0}))
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=128, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=1024)
    venv.reset()
    _, _, dones, infos = venv.step(np.zeros((8, 4), np.float32))
    for _ in range(40):
        _, _, dones, infos = venv.step(np.zeros((8, 4), np.float32))
        if dones.any():
            break
    ended = np.flatnonzero(dones)
    assert len(ended) == 8  # the 3 s time limit ends every train together
    assert infos[0]["TimeLimit.truncated"] and "terminal_observation" in infos[0]


def test_reset_trains_equals_a_fresh_simulator():
    """Restarting some trains of a running batch gives them exactly the run of a fresh batch."""
    from brakegym import config as cfg
    from brakegym.plants import brake_cylinder, train_plant
    from brakegym.simulator import BatchConditions, CommandedPressure, Simulator

    vehicle = cfg.load("vehicles", "emu_8axle")
    plant = train_plant(vehicle)
    rng = np.random.default_rng(4)

    def conditions(n):
        shape = (n, *plant.disc_shape)
        return BatchConditions(
            mass_kg=rng.uniform(1.2e5, 1.5e5, n),
            initial_speed_mps=rng.uniform(10, 40, n),
            initial_mu=rng.uniform(0.33, 0.37, shape),
            power_coefficient_per_s=rng.uniform(0.003, 0.005, shape),
            running_resistance_A_N=rng.uniform(1000, 4000, n),
            initial_friction_temperature_K=rng.uniform(300, 400, shape),
            initial_disc_temperature_K=rng.uniform(300, 400, shape),
            ambient_temperature_K=np.full(n, 293.15),
        )

    cylinder = brake_cylinder(cfg.load("pneumatics", "EP"))
    running = Simulator(plant, conditions(4), CommandedPressure([cylinder] * 4, 8, 0.05), step_s=0.05)
    running.pressure.set_command(np.full((4, 8), 3.0))
    for _ in range(30):
        running.step()
    restart = conditions(2)
    running.reset_trains(np.array([1, 3]), restart)
    running.pressure.reset_trains(np.array([1, 3]))
    fresh = Simulator(plant, restart, CommandedPressure([cylinder] * 2, 8, 0.05), step_s=0.05)
    for sim in (running, fresh):
        sim.pressure.set_command(np.full((sim.n_trains, 8), 2.5))
        for _ in range(40):
            sim.step()
    np.testing.assert_array_equal(running.disc[..., [1, 3]], fresh.disc)
    np.testing.assert_array_equal(running.train[:, [1, 3]], fresh.train)


def test_per_train_resistance_B_and_C_equal_trains_simulated_alone():
    """B and C of the running resistance may differ per train (the kernels read them per train
    like A): a batch gives each train what it gets alone with its own plant, bit for bit, and
    the numpy reference agrees."""
    import dataclasses

    from brakegym import config as cfg
    from brakegym.physics import BrakeCylinder, RunningResistanceLaw
    from brakegym.plants import train_plant
    from brakegym.simulator import BatchConditions, CommandedPressure, NumpyReferenceSimulator, Simulator

    base = train_plant(cfg.load("vehicles", "emu_8axle"))
    B, C = np.array([30.0, 60.0, 10.0]), np.array([5.0, 2.0, 8.0])
    n = len(B)

    def run(plant, index, simulator=Simulator):
        shape = (len(index), *plant.disc_shape)
        conditions = BatchConditions(
            mass_kg=np.full(len(index), 1.2e5),
            initial_speed_mps=np.full(len(index), 30.0),
            initial_mu=np.full(shape, 0.35),
            power_coefficient_per_s=np.full(shape, 0.004),
            running_resistance_A_N=np.full(len(index), 2500.0),
            initial_friction_temperature_K=np.full(shape, 300.0),
            initial_disc_temperature_K=np.full(shape, 300.0),
            ambient_temperature_K=np.full(len(index), 293.15),
        )
        pressure = CommandedPressure([BrakeCylinder(0.2, 0.8)] * len(index), plant.n_axles, 0.1)
        pressure.set_command(np.full((len(index), plant.n_axles), 2.0))
        sim = simulator(plant, conditions, pressure, step_s=0.1)
        for _ in range(100):
            sim.step()
        return sim

    batch_plant = dataclasses.replace(
        base, running_resistance=RunningResistanceLaw(A_N=2500.0, B_N_per_mps=B, C_N_per_mps2=C)
    )
    batch = run(batch_plant, np.arange(n))
    for i in range(n):
        alone_plant = dataclasses.replace(
            base, running_resistance=RunningResistanceLaw(2500.0, float(B[i]), float(C[i]))
        )
        alone = run(alone_plant, [i])
        np.testing.assert_array_equal(batch.train[:, i], alone.train[:, 0])
        np.testing.assert_array_equal(batch.disc[..., i], alone.disc[..., 0])
    reference = run(batch_plant, np.arange(n), NumpyReferenceSimulator)
    np.testing.assert_allclose(batch.train, reference.train, rtol=1e-12)
    assert len(np.unique(batch.train[0])) == n, "different resistances give different speeds"

    wrong = dataclasses.replace(base, running_resistance=RunningResistanceLaw(2500.0, np.array([30.0, 60.0]), 5.0))
    with pytest.raises(ValueError, match="running resistance B_N_per_mps: one value or one per train"):
        run(wrong, np.arange(n))


# ------------------------------------------------------------------------------------------------
# Effect sets: the model a diagnosis found (or any effect set), in the environments

QUIET = {
    "sensor_noise": {"speed_mps": 0.0, "decel_mps2": 0.0, "pressure_bar": 0.0, "temperature_C": 0.0, "distance_m": 0.0}
}
G = 9.80665


def _effect_set(tmp_path, name, effects):
    lines = [f"name: {name}", "effects:"]
    for effect_id, parameters in effects.items():
        shown = ", ".join(f"{key}: {value}" for key, value in parameters.items())
        lines.append(f"  - id: {effect_id}\n    parameters: {{{shown}}}")
    path = tmp_path / f"{name}.yaml"
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def _coasting_deceleration(effects, steps=5, seed=3):
    """Deceleration of 4 trains (loads drawn) after ``steps`` control steps with the brakes released."""
    env = BrakeVectorEnv("station_stop", num_envs=4, config={**QUIET, "effects": effects}, autoreset=False)
    env.reset(seed=seed)
    for _ in range(steps):
        env.step(-np.ones(env.action_space.shape, np.float32))
    fleet = env.core.fleet
    return fleet.deceleration_mps2.copy(), fleet.episodes.mass_kg.copy()


def test_a_gradient_effect_set_adds_g_times_the_gradient_to_every_train_whatever_its_mass():
    nominal, mass = _coasting_deceleration(None)
    downhill, _ = _coasting_deceleration("example_gradient")  # configs/effects/: -5.8 permil
    assert len(set(mass)) > 1  # the loads drawn differ, so the gradient's force does too
    # Coasting: only the gradient (and running resistance at a speed a few mm/s apart) differs.
    np.testing.assert_allclose(downhill - nominal, G * -5.8 / 1000, rtol=0.01)


def test_a_rotating_mass_effect_scales_the_coasting_deceleration(tmp_path):
    nominal, _ = _coasting_deceleration(None)
    heavier, _ = _coasting_deceleration(_effect_set(tmp_path, "inertia", {"rotating_mass": {"mass_factor": 0.1}}))
    np.testing.assert_allclose(heavier / nominal, 1.0 / 1.1, rtol=1e-3)


def test_sensor_effects_act_on_the_observation_only(tmp_path):
    effects = _effect_set(
        tmp_path, "sensors", {"speed_sensor_scale": {"scale": 1.03}, "temperature_sensor_lag": {"tau_s": 10.0}}
    )
    config = {**QUIET, "effects": effects, "observed_temperatures": "instrumented"}
    env, nominal = BrakeEnv("station_stop", config=config), BrakeEnv("station_stop", config=QUIET)
    names = env.unwrapped.observation_names
    speed, decel, to_go, temperature = (
        names.index(n) for n in ("speed_mps", "decel_mps2", "distance_to_go_m", "temperature_C_1")
    )
    for e in (env, nominal):
        e.reset(seed=5, options={"initial_speed_kmh": 80.0})
    brake = np.full(env.action_space.shape, 0.5, np.float32)
    for _ in range(60):
        observation, _, _, _, info = env.step(brake)
        _, _, _, _, nominal_info = nominal.step(brake)
    # The train itself is the nominal one: sensor effects change no physics.
    assert info["position_m"] == nominal_info["position_m"]
    assert observation[speed] == np.float32(1.03 * info["speed_mps"])
    assert observation[decel] == np.float32(1.03 * info["deceleration_mps2"])
    # Odometry runs 3 % long, so the measured distance to go is short by 3 % of the distance run.
    assert observation[to_go] == pytest.approx(-info["stop_error_m"] - 0.03 * info["position_m"], abs=1e-3)
    # A braking disc heats: the lagging sensor reads below the surface, by about tau x its rise rate.
    true_C = info["friction_temperature_C"][0]
    assert 0.0 < true_C - observation[temperature] < 10.0 * 20.0


def test_effect_sets_needing_the_staged_path_pass_the_env_checker():
    from gymnasium.utils.env_checker import check_env

    env = gym.make("brakegym/StationStop-v0", config={"effects": "example_wet_pads_heavy_train"})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, skip_render_check=True)


def test_an_unknown_effect_set_is_refused_naming_the_field():
    with pytest.raises(ConfigError, match="field 'effects' = 'no_such_set'"):
        BrakeEnv("station_stop", config={"effects": "no_such_set"})


def test_restarting_trains_reads_no_config_file(monkeypatch):
    """Everything an episode draws comes from objects built with the environment: a restart (every
    few steps for some train of a batch) must not read and validate YAML again."""
    from brakegym.config import library

    env = BrakeVectorEnv("station_stop", num_envs=8, config={"max_episode_time_s": 2.0})
    env.reset(seed=0)
    reads = []
    read_yaml = library.read_yaml
    monkeypatch.setattr(library, "read_yaml", lambda path: reads.append(path) or read_yaml(path))
    env.reset(seed=1)
    restarted = 0
    for _ in range(40):
        _, _, terminated, truncated, _ = env.step(np.zeros((8, env.single_action_space.shape[0]), np.float32))
        restarted += int((terminated | truncated).sum())
    assert restarted >= 8 and reads == []
