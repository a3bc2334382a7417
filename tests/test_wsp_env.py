"""brakegym/WheelSlideProtection-v0 (issue 16): spaces, checkers, determinism whatever the batch,
the reference and no WSP as controllers, reward terms, the adhesion bound, the stress harness and
the WSP controllers of one kind."""

from __future__ import annotations

import dataclasses
import functools
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import brakegym  # noqa: F401  (registers the environments)
from brakegym import config as cfg
from brakegym.agents.wsp import WspController, load_wsp_config
from brakegym.agents.wsp_policy import NoWsp, WspEnvController, load_wsp_controller
from brakegym.envs import BrakeEnv, BrakeVectorEnv
from brakegym.physics.pneumatics import VALVE_APPLY

ENV_ID = "brakegym/WheelSlideProtection-v0"
REPO = Path(__file__).resolve().parent.parent
# A short stop: 50 km/h, empty, the brake asked for at once (about 150 m, 15 s on the low rail).
SHORT = {"initial_speed_kmh": 50.0, "load": "empty", "coast_s": 0.0}


@pytest.fixture(autouse=True)
def checkout_configs(monkeypatch):
    """This checkout's configs on the search path (an installed brakegym may ship others)."""
    monkeypatch.setenv(cfg.CONFIG_PATH_ENV, str(REPO / "configs"))


def _make(name: str):
    return NoWsp if name == "none" else functools.partial(WspController, load_wsp_config(name))


def _run(env: BrakeVectorEnv, controller: str, seed: int = 0, options=SHORT, max_steps: int | None = None):
    """Episodes of every train of ``env`` (autoreset off) under ``controller``: the info at the
    end and the rows (observation, reward) of each step."""
    agent = WspEnvController(_make(controller), env)
    observation, info = env.reset(seed=seed, options=options)
    agent.reset(info)
    rows = [observation]
    steps = 0
    while not env.ended.all() and (max_steps is None or steps < max_steps):
        observation, reward, _, _, info = env.step(agent.act(observation))
        rows.append(np.concatenate([observation, reward[:, None]], axis=1))
        steps += 1
    return info, rows


@pytest.fixture(scope="module")
def short_stops():
    """No WSP and the reference WSP, 2 trains each, a short stop on the low rail."""
    with cfg.config_path(REPO / "configs"):
        return {name: _run(BrakeVectorEnv(ENV_ID, num_envs=2, autoreset=False), name)[0] for name in ("none", "wsp")}


def test_spaces_are_the_valves_and_the_brake_control_units_measurements():
    env = BrakeEnv("wheel_slide_protection")
    assert env.action_space == gym.spaces.MultiDiscrete([3] * 8)  # emu_8axle, a valve per axle
    assert env.observation_space.shape == (5 * 8 + 3,)
    names = env.observation_names
    assert names[0] == "wheel_speed_1" and names[-3:] == ("train_deceleration", "brake_demand", "reference_speed")
    assert not any("speed_mps" in name for name in names)  # the train speed is not observed
    observation, info = env.reset(seed=3)
    assert env.observation_space.contains(observation)
    # The wheel-speed columns read the wheels (rolling with the train at reset) to the sensor's
    # noise and resolution.
    np.testing.assert_allclose(observation[:8] * 50.0, info["speed_mps"], atol=0.05)


def test_bogie_valves_give_one_action_per_bogie():
    env = BrakeEnv("wheel_slide_protection", config={"wheel_rail": {"wsp_valves": "bogie"}})
    assert env.action_space == gym.spaces.MultiDiscrete([3] * 4)


def test_gymnasium_and_sb3_env_checkers_pass_without_warnings():
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(gym.make(ENV_ID).unwrapped, skip_render_check=True)
        sb3_check_env(gym.make(ENV_ID).unwrapped, warn=True)


def test_same_seed_same_episode_bit_for_bit_and_a_train_is_the_same_in_any_batch():
    """The episode's draws and its sensor noise come from its own key: train 0 of a batch of 8
    runs the episode of a batch of 1, bit for bit."""
    with cfg.config_path(REPO / "configs"):
        _, alone = _run(
            BrakeVectorEnv(ENV_ID, num_envs=1, autoreset=False), "wsp", seed=11, options=None, max_steps=150
        )
        _, again = _run(
            BrakeVectorEnv(ENV_ID, num_envs=1, autoreset=False), "wsp", seed=11, options=None, max_steps=150
        )
        _, batch = _run(
            BrakeVectorEnv(ENV_ID, num_envs=8, autoreset=False), "wsp", seed=11, options=None, max_steps=150
        )
        _, other = _run(
            BrakeVectorEnv(ENV_ID, num_envs=1, autoreset=False), "wsp", seed=12, options=None, max_steps=150
        )
    assert all(np.array_equal(a, b) for a, b in zip(alone, again))
    assert all(np.array_equal(a[0], b[0]) for a, b in zip(alone, batch))
    assert not np.array_equal(alone[0], batch[0][1:2])  # the other trains draw other episodes
    assert not np.array_equal(alone[0], other[0])


def test_without_wsp_the_axles_lock_and_the_reference_keeps_them_turning(short_stops):
    none, wsp = short_stops["none"], short_stops["wsp"]
    assert np.all(none["max_locked_time_s"] > 5.0)
    assert np.all(wsp["max_locked_time_s"] <= 0.5)
    assert np.all(wsp["slide_energy_MJ"] < 0.2 * none["slide_energy_MJ"])
    assert np.all(wsp["braking_distance_m"] < 0.9 * none["braking_distance_m"])  # 50 km/h: less slip speed to lose
    assert np.all(wsp["is_success"]) and not np.any(none["is_success"])


def test_no_stop_is_shorter_than_the_adhesion_limit(short_stops):
    """The peak adhesion of the rail at every speed bounds the deceleration: no controller stops
    shorter than ideal_braking_distance_m, itself at least v0^2 / (2 a) with a the largest
    adhesion Polach's law can give over the body mass: (2 mu / pi) (1/2 + pi/2) = mu_0 (1 + 1/pi),
    the largest values of its two terms (an analytic bound from the rail's config)."""
    vehicle = cfg.load("vehicles", "emu_8axle")
    rail = cfg.load("rail_conditions", "low")
    v0 = 50.0 / 3.6
    body_share = 1 - vehicle.n_axles * vehicle.wheelsets.inertia_kgm2 / vehicle.wheel_radius_m**2 / vehicle.mass_kg(
        "empty"
    )
    resistance_N = vehicle.running_resistance.A_N + vehicle.running_resistance.B_N_per_mps * v0
    resistance_N += vehicle.running_resistance.C_N_per_mps2 * v0**2
    for stops in short_stops.values():
        # Each episode's own rail: mu_0 times its factor (rail_scatter).
        mu_0 = rail.static_friction * stops["rail_friction_factor"]
        largest_mps2 = (mu_0 * (1 + 1 / np.pi) * 9.80665 + resistance_N / vehicle.mass_kg("empty")) / body_share
        assert np.all(stops["ideal_braking_distance_m"] >= v0**2 / (2 * largest_mps2))
        assert np.all(stops["braking_distance_m"] >= stops["ideal_braking_distance_m"])
    # The reference WSP comes within half of the limit (its valve cycles cost most at low speed;
    # about 20 % above it from 120 km/h, docs/adhesion.md).
    assert np.all(short_stops["wsp"]["braking_distance_m"] <= 1.5 * short_stops["wsp"]["ideal_braking_distance_m"])


def test_each_episode_draws_its_rail_from_its_key_with_the_conditions_scatter():
    """With rail_scatter each episode's factor on the rail's mu_0 is lognormal, mean 1, with the
    low rail's relative sigma (0.15), drawn from the episode's key (a train's is the same in any
    batch); the reset option fixes it; without rail_scatter every factor is 1 and another one is
    refused, as is a factor that is not positive."""
    sigma = cfg.load("rail_conditions", "low").static_friction_relative_sigma
    env = BrakeVectorEnv(ENV_ID, num_envs=400, autoreset=False)
    _, info = env.reset(seed=3)
    factor = info["rail_friction_factor"]
    assert np.all(factor > 0)
    assert abs(factor.mean() - 1.0) < 3 * sigma / np.sqrt(len(factor))
    assert abs(factor.std() / sigma - 1.0) < 0.15  # 4 standard errors of a standard deviation of 400
    _, alone = BrakeVectorEnv(ENV_ID, num_envs=1, autoreset=False).reset(seed=3)
    assert alone["rail_friction_factor"][0] == factor[0]
    _, fixed = env.reset(seed=3, options={"rail_friction_factor": 0.8})
    assert np.all(fixed["rail_friction_factor"] == 0.8)
    assert np.all(env.core.fleet.sim.static_friction_factor == 0.8)
    with pytest.raises(ValueError, match="must be positive"):
        env.reset(seed=3, options={"rail_friction_factor": -1.0})
    fixed_rail = BrakeVectorEnv(ENV_ID, num_envs=4, config={"wheel_rail": {"rail_scatter": False}}, autoreset=False)
    _, nominal = fixed_rail.reset(seed=3)
    assert np.all(nominal["rail_friction_factor"] == 1.0)
    with pytest.raises(ValueError, match="rail_scatter"):
        fixed_rail.reset(seed=3, options={"rail_friction_factor": 0.8})


@pytest.mark.parametrize("factor", [0.7, 1.3, 2.0])
def test_ideal_distance_on_a_scattered_rail_is_that_of_the_scaled_rails_own_peaks(factor):
    """The ideal distance of an episode on a rail with mu_0 times f, read from the nominal rail's
    peak table, is the distance computed from the scaled rail's own peaks, within 0.1 %."""
    from brakegym.envs.tasks.wheel_slide_protection import adhesion_limited_distance_m
    from brakegym.plants import polach_law, wheel_rail_contact

    vehicle = cfg.load("vehicles", "emu_8axle")
    law = polach_law(cfg.load("rail_conditions", "low"))
    scaled = dataclasses.replace(law, static_friction=factor * law.static_friction)
    mass_kg = vehicle.mass_kg("normal")
    wheel_load_N = mass_kg * 9.80665 / (2 * vehicle.n_axles)
    stiffness_N = wheel_rail_contact(vehicle).creep_stiffness_N(wheel_load_N)
    speeds = np.linspace(0.05, 150.0, 600)
    body_kg = mass_kg - vehicle.n_axles * vehicle.wheelsets.inertia_kgm2 / vehicle.wheel_radius_m**2
    args = (mass_kg, body_kg, vehicle.running_resistance)
    from_nominal = adhesion_limited_distance_m(
        120 / 3.6,
        np.array([factor]),
        speeds,
        law.peak_adhesion(speeds, wheel_load_N, stiffness_N, n_creeps=2001)[0],
        *args,
    )
    own = adhesion_limited_distance_m(
        120 / 3.6, np.ones(1), speeds, scaled.peak_adhesion(speeds, wheel_load_N, stiffness_N, n_creeps=2001)[0], *args
    )
    assert from_nominal == pytest.approx(own, rel=1e-3)
    # More adhesion, a shorter stop.
    nominal = adhesion_limited_distance_m(
        120 / 3.6, np.ones(1), speeds, law.peak_adhesion(speeds, wheel_load_N, stiffness_N, n_creeps=2001)[0], *args
    )
    assert (own < nominal) == (factor > 1)


def test_reward_terms_sum_to_the_reward_and_penalise_sliding():
    env = BrakeVectorEnv(ENV_ID, num_envs=2, autoreset=False)
    env.reset(seed=1, options=SHORT)
    actions = np.stack([np.full(8, 2), np.full(8, 0)])  # train 0 applies, train 1 dumps
    slides = np.zeros(2)
    for _ in range(300):
        _, reward, _, _, info = env.step(actions)
        terms = info["reward_terms"]
        assert set(terms) == {"adhesion", "distance", "slide", "locked"}
        np.testing.assert_array_equal(reward, sum(terms.values()))
        slides += terms["slide"]
    np.testing.assert_allclose(-slides, env.config.reward.slide_per_MJ * info["slide_energy_MJ"], rtol=1e-9)
    # Dumping the cylinders leaves the wheels rolling, with no slide to speak of.
    assert info["slide_energy_MJ"][0] > 100 * info["slide_energy_MJ"][1]


def test_bad_actions_and_configs_are_refused_with_names():
    env = BrakeEnv("wheel_slide_protection")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="valve actions"):
        env.step(np.full(8, 3))
    with pytest.raises(ValueError, match="action shape"):
        env.step(np.full(4, 2))
    with pytest.raises(cfg.ConfigError, match="rail_condition"):
        BrakeEnv("wheel_slide_protection", config={"wheel_rail": {"line": "low_patch"}})
    with pytest.raises(cfg.ConfigError, match="effects"):
        BrakeEnv("wheel_slide_protection", config={"effects": "wet_pads"})
    with pytest.raises(cfg.ConfigError, match="wheel_rail"):
        BrakeEnv("wheel_slide_protection", config={"wheel_rail": None})


def test_a_line_with_a_patch_runs_without_an_ideal_distance():
    config = {"wheel_rail": {"rail_condition": None, "line": "low_patch"}}
    env = BrakeVectorEnv(ENV_ID, num_envs=1, config=config, autoreset=False)
    info, _ = _run(env, "wsp", options={**SHORT, "initial_speed_kmh": 30.0})
    assert np.isnan(info["ideal_braking_distance_m"][0])
    assert info["is_success"][0]


def test_stress_reports_slide_energy_and_locked_time():
    from brakegym.cli.controllers import controller_factory
    from brakegym.stress import report, run_stress, table

    name, factory = controller_factory("none", ENV_ID)
    result = run_stress(
        ENV_ID, factory, name, episodes=2, batch_size=2, config={"initial_speed_kmh": {"low": 30.0, "high": 40.0}}
    )
    assert set(result.quantities) == {"slide_energy_MJ", "max_locked_time_s"}
    row = report(result, [30.0, 40.0])["overall"]
    assert row["max_locked_time_s_max"] == result.quantities["max_locked_time_s"].max() > 0
    assert "slide_energy_MJ mean / p95 / max" in table([report(result, [30.0, 40.0])])


def test_no_wsp_in_the_stops_equals_the_valves_at_rest():
    from brakegym.applications import TrainApplication
    from brakegym.plants import wheel_rail_adhesion
    from brakegym.wheel_slide import wsp_train_stops

    vehicle = cfg.load("vehicles", "emu_8axle")
    adhesion = wheel_rail_adhesion(vehicle, cfg.load("rail_conditions", "low"))
    valves = cfg.load("wsp_valves", "axle")
    application = [TrainApplication("empty", "emergency", "EP", 40.0)]
    at_rest = wsp_train_stops(vehicle, application, adhesion, valves, None)
    none = wsp_train_stops(vehicle, application, adhesion, valves, NoWsp)
    assert none.summary.braking_distance_m[0] == at_rest.summary.braking_distance_m[0]
    assert NoWsp(np.arange(8), 0.02).valves(none_measurement(2)).tolist() == [[VALVE_APPLY] * 8] * 2


def none_measurement(n_trains: int):
    from brakegym.wheel_slide import BcuMeasurement

    zeros = np.zeros((n_trains, 8))
    return BcuMeasurement(zeros, zeros, np.zeros(n_trains), zeros)


def test_the_loader_refuses_what_is_not_a_wsp_policy(tmp_path):
    with pytest.raises(FileNotFoundError, match="training.json"):
        load_wsp_controller(tmp_path)
    (tmp_path / "training.json").write_text('{"env": "StationStop-v0"}')
    with pytest.raises(ValueError, match="not a WSP policy"):
        load_wsp_controller(tmp_path)


def test_a_trained_policy_acts_alike_in_the_env_and_as_a_wsp_controller_of_the_stops(tmp_path):
    """A policy folder (a tiny PPO run) drives the environment (its observations) and, through
    load_wsp_controller, the stops of wsp_train_stops (BcuMeasurements): the same actions for the
    same measurements."""
    import yaml

    from brakegym.agents.rl import PolicyController, train
    from brakegym.applications import TrainApplication
    from brakegym.plants import wheel_rail_adhesion
    from brakegym.wheel_slide import wsp_train_stops

    slow = {"initial_speed_kmh": {"low": 20.0, "high": 30.0}}
    entry = {
        "n_envs": 2,
        "n_timesteps": 64,
        "policy": "MlpPolicy",
        "normalize": {"norm_obs": True, "norm_reward": True},
        "n_steps": 32,
        "batch_size": 64,
        "n_epochs": 1,
        "policy_kwargs": {"net_arch": [8, 8]},
    }
    own = {"eval_freq_steps": 10**9, "n_eval_episodes": 2, "env_config": slow, "kernel_threads": 1}
    hyper = tmp_path / "hyper.yaml"
    hyper.write_text(yaml.safe_dump({ENV_ID: entry, "brakegym": {ENV_ID: own}}))
    folder = train("ppo", ENV_ID, tmp_path / "agent", seed=1, hyperparameters=hyper, progress_bar=False)

    env = BrakeVectorEnv(ENV_ID, num_envs=2, config=slow, autoreset=False)
    on_observations = PolicyController(folder)
    on_measurements = WspEnvController(load_wsp_controller(folder), env)
    observation, info = env.reset(seed=5)
    on_measurements.reset(info)
    for _ in range(60):
        actions = on_observations.act(observation)
        np.testing.assert_array_equal(on_measurements.act(observation), actions)
        observation, *_ = env.step(actions)

    vehicle = cfg.load("vehicles", "emu_8axle")
    adhesion = wheel_rail_adhesion(vehicle, cfg.load("rail_conditions", "low"))
    stops = wsp_train_stops(
        vehicle,
        [TrainApplication("empty", "emergency", "EP", 20.0)],
        adhesion,
        cfg.load("wsp_valves", "axle"),
        load_wsp_controller(folder),
    )
    assert 0 < stops.summary.braking_distance_m[0] < np.inf
    with pytest.raises(ValueError, match="valves"):
        load_wsp_controller(folder)(np.arange(8) // 2, 0.02)  # trained on a valve per axle


def test_bcu_features_follow_the_fastest_wheel_falling_at_most_at_their_limit_and_repeat_a_step():
    from brakegym.envs.tasks.wheel_slide_protection import REFERENCE_DECELERATION_MPS2, BcuFeatures
    from brakegym.wheel_slide import BcuMeasurement

    def reading(speed_mps):
        wheels = np.array([[speed_mps, speed_mps - 1.0]])
        return BcuMeasurement(wheels, np.zeros((1, 2)), np.zeros(1), np.zeros((1, 2)))

    features = BcuFeatures(1, 2, 0.02, 4.5)
    out = np.empty((1, 5 * 2 + 3))
    features.observe(reading(30.0), np.array([0]), out)
    assert features.reference_speed_mps[0] == 30.0
    features.observe(reading(10.0), np.array([1]), out)  # every wheel slides: the reference may not follow
    assert features.reference_speed_mps[0] == pytest.approx(30.0 - 0.02 * REFERENCE_DECELERATION_MPS2)
    first = out.copy()
    features.observe(reading(10.0), np.array([1]), out)  # the same step observed again
    np.testing.assert_array_equal(out, first)
    assert features.reference_speed_mps[0] == pytest.approx(30.0 - 0.02 * REFERENCE_DECELERATION_MPS2)
    features.restart(np.array([0]))
    features.observe(reading(20.0), np.array([0]), out)
    assert features.reference_speed_mps[0] == 20.0 and out[0, 4] == 0.0  # no wheel deceleration at the first reading
