"""Wheel-slide protection (issue 16): the WSP valves on top of the brake cylinders, their config,
and the reference WSP controller on the low-adhesion rail."""

from __future__ import annotations

import functools
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from brakegym import config as cfg
from brakegym.applications import TrainApplication
from brakegym.physics.pneumatics import VALVE_APPLY, VALVE_DUMP, VALVE_HOLD, valve_pressure_after
from brakegym.plants import brake_cylinder, train_plant, valve_of_axle, wheel_rail_adhesion, wsp_valve
from brakegym.simulator import CommandedPressure
from brakegym.simulator.pressure import ValvedPressure
from brakegym.units import STANDARD_GRAVITY_MPS2
from brakegym.wheel_slide import wsp_train_stops

REPO_CONFIGS = Path(__file__).resolve().parent.parent / "configs"
STEP_S = 0.02


@pytest.fixture(autouse=True)
def checkout_configs(monkeypatch):
    """This checkout's configs on the search path (an installed brakegym may ship others)."""
    monkeypatch.setenv(cfg.CONFIG_PATH_ENV, str(REPO_CONFIGS))


def _supply(n_trains: int = 2, command_bar: float = 3.3) -> CommandedPressure:
    vehicle = cfg.load("vehicles", "emu_8axle")
    cylinder = brake_cylinder(cfg.load("pneumatics", "EP"))
    supply = CommandedPressure([cylinder] * n_trains, vehicle.n_axles, STEP_S)
    supply.set_command(np.full((n_trains, vehicle.n_axles), command_bar))
    return supply


def _valved(valve_set: str = "axle", n_trains: int = 2) -> ValvedPressure:
    vehicle = cfg.load("vehicles", "emu_8axle")
    valves = cfg.load("wsp_valves", valve_set)
    return ValvedPressure(_supply(n_trains), wsp_valve(valves), valve_of_axle(vehicle, valves))


def _advance(source, n_steps: int) -> list[np.ndarray]:
    pressures = []
    for _ in range(n_steps):
        pressures.append(np.stack(source.stage_pressures_bar()))
        source.advance()
    return pressures


def test_valves_at_rest_pass_the_supply_bit_for_bit():
    valved, plain = _valved(), _supply()
    for with_valves, without in zip(_advance(valved, 150), _advance(plain, 150)):
        np.testing.assert_array_equal(with_valves, without)


def test_dump_hold_and_refill_at_the_valve_rates():
    """From the supply's 3.3 bar (built up): dump falls at the dump rate to 0, hold keeps the
    pressure, apply refills at the refill rate (the supply standing) back up to the supply."""
    valves = cfg.load("wsp_valves", "axle")
    source = _valved()
    _advance(source, 400)  # 8 s: the supply has settled at the command
    supply = source.supply_bar.copy()
    np.testing.assert_allclose(source.pressure_bar, 3.3, atol=1e-3)
    source.set_valves(VALVE_DUMP)
    _advance(source, 5)
    np.testing.assert_allclose(supply - source.pressure_bar, 5 * STEP_S * valves.dump_rate_bar_per_s, rtol=1e-9)
    _advance(source, 50)
    assert np.all(source.pressure_bar == 0.0)
    source.set_valves(VALVE_APPLY)
    _advance(source, 10)
    np.testing.assert_allclose(source.pressure_bar, 10 * STEP_S * valves.refill_rate_bar_per_s, rtol=1e-6)
    source.set_valves(VALVE_HOLD)
    held = source.pressure_bar.copy()
    _advance(source, 10)
    np.testing.assert_array_equal(source.pressure_bar, held)
    source.set_valves(VALVE_APPLY)
    _advance(source, 100)
    np.testing.assert_allclose(source.pressure_bar, source.supply_bar, rtol=1e-12)


def test_a_cylinder_is_never_above_the_supply_whatever_the_valve():
    rng = np.random.default_rng(3)
    pressure, supply = rng.uniform(0, 4.5, 1000), rng.uniform(0, 4.5, 1000)
    next_supply = np.clip(supply + rng.uniform(-1, 1, 1000), 0.0, None)
    valve = rng.integers(-1, 2, 1000)
    after = valve_pressure_after(pressure, supply, next_supply, valve, 0.05, 10.0, 3.0)
    assert np.all(after <= next_supply)
    assert np.all(after >= 0.0)
    # Dumping never raises a pressure, holding never changes one below the supply.
    assert np.all(after[valve == VALVE_DUMP] <= pressure[valve == VALVE_DUMP])
    holding = (valve == VALVE_HOLD) & (pressure <= next_supply)
    np.testing.assert_array_equal(after[holding], pressure[holding])


def test_bogie_valves_move_both_axles_of_a_bogie_together():
    vehicle = cfg.load("vehicles", "emu_8axle")
    source = _valved("bogie")
    assert source.n_valves == vehicle.bogies
    _advance(source, 100)
    valves = np.full((2, vehicle.bogies), VALVE_APPLY)
    valves[0, 1] = VALVE_DUMP
    source.set_valves(valves)
    _advance(source, 5)
    pressure = source.pressure_bar
    assert pressure[0, 2] == pressure[0, 3] < pressure[0, 1] == pressure[0, 4]
    np.testing.assert_array_equal(pressure[1], source.supply_bar[1])
    assert train_plant(vehicle).n_axles == len(valve_of_axle(vehicle, cfg.load("wsp_valves", "bogie")))


def test_bad_valve_command_is_refused():
    with pytest.raises(ValueError, match="dump"):
        _valved().set_valves(2)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [("valve_per", "wheel", "valve_per"), ("dump_rate_bar_per_s", -10.0, "dump_rate_bar_per_s")],
)
def test_bad_wsp_valves_name_file_field_value(tmp_path, monkeypatch, field, value, message):
    target = tmp_path / "configs"
    shutil.copytree(REPO_CONFIGS, target)
    monkeypatch.setenv(cfg.CONFIG_PATH_ENV, str(target))
    path = target / "wsp_valves" / "axle.yaml"
    data = yaml.safe_load(path.read_text())
    data[field] = value
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(cfg.ConfigError) as info:
        cfg.load("wsp_valves", "axle")
    assert str(path) in str(info.value) and message in str(info.value) and str(value) in str(info.value)


# ------------------------------------------------------------------------------------------------
# The reference WSP controller on the low rail


@pytest.fixture(scope="module")
def wsp_agents():
    """brakegym.agents with this checkout's agents/ first (an editable install of another
    checkout maps the subpackage there)."""
    import brakegym.agents

    checkout = str(Path(__file__).resolve().parent.parent / "agents")
    if checkout not in brakegym.agents.__path__:
        brakegym.agents.__path__.insert(0, checkout)
    from brakegym.agents import wsp

    return wsp


def _ideal_braking_distance_m(vehicle, adhesion) -> float:
    """The adhesion-limited ideal from 120 km/h: every axle at the peak adhesion of the rail at
    each speed, d = integral of v dv / a(v), a = (peak(v) m g + F_R(v)) / M, after the EP
    cylinders' response (v0 times dead time plus time constant, the distance a first-order lag
    behind a dead time loses against a step)."""
    cylinder = cfg.load("pneumatics", "EP")
    response_m = 120 / 3.6 * (cylinder.dead_time_s + cylinder.time_constant_s)
    mass_kg = vehicle.mass_kg("empty")
    wheel_load_N = mass_kg * STANDARD_GRAVITY_MPS2 / (2 * vehicle.n_axles)
    stiffness_N = adhesion.contact.creep_stiffness_N(wheel_load_N)
    body_mass_kg = mass_kg - vehicle.n_axles * adhesion.wheelset_inertia_kgm2 / vehicle.wheel_radius_m**2
    speeds = np.linspace(0.05, 120 / 3.6, 400)
    resistance = vehicle.running_resistance
    deceleration = (
        np.array(
            [
                adhesion.law.peak_adhesion(v, wheel_load_N, stiffness_N, n_creeps=4001)[0]
                * mass_kg
                * STANDARD_GRAVITY_MPS2
                + resistance.A_N
                + resistance.B_N_per_mps * v
                + resistance.C_N_per_mps2 * v**2
                for v in speeds
            ]
        )
        / body_mass_kg
    )
    return response_m + float(np.trapezoid(speeds / deceleration, speeds))


@pytest.fixture(scope="module")
def low_rail_stops(wsp_agents):
    with cfg.config_path(REPO_CONFIGS):
        vehicle = cfg.load("vehicles", "emu_8axle")
        adhesion = wheel_rail_adhesion(vehicle, cfg.load("rail_conditions", "low"))
        valves = cfg.load("wsp_valves", "axle")
        application = [TrainApplication("empty", "emergency", "EP", 120.0)]
        stops = {
            name: wsp_train_stops(
                vehicle,
                application,
                adhesion,
                valves,
                None
                if name == "none"
                else functools.partial(wsp_agents.WspController, wsp_agents.load_wsp_config(name)),
            )
            for name in ("none", "wsp", "wsp-true-speed")
        }
        return stops, _ideal_braking_distance_m(vehicle, adhesion)


def test_without_wsp_the_wheels_lock_on_the_low_rail(low_rail_stops):
    stops, _ = low_rail_stops
    locked = stops["none"].locked
    assert np.all(locked.longest_s > 30.0)  # every axle slides most of the stop


@pytest.mark.parametrize("controller", ["wsp", "wsp-true-speed"])
def test_reference_wsp_keeps_every_axle_turning_near_the_ideal_stop(low_rail_stops, controller):
    """Issue 16: with the reference WSP no axle stays locked (no stretch longer than 0.5 s), the
    slide energy falls far below that of locked wheels, and the stop lies within 20 % of the
    adhesion-limited ideal (never below it)."""
    stops, ideal_m = low_rail_stops
    result, without = stops[controller], stops["none"]
    distance = result.summary.braking_distance_m[0]
    assert result.locked.longest_s.max() <= 0.5
    assert result.summary.slip_work_J.sum() < 0.2 * without.summary.slip_work_J.sum()
    assert ideal_m <= distance <= 1.2 * ideal_m
    assert distance < 0.7 * without.summary.braking_distance_m[0]


def test_controller_rules_reference_and_bogie_valves(wsp_agents):
    """The reference follows the fastest wheel and falls at most at its deceleration limit; a
    bogie valve takes its axles' strictest command; the true-speed variant needs the speed."""
    config = wsp_agents.load_wsp_config("wsp")
    controller = wsp_agents.WspController(config, np.array([0, 0, 1, 1]), 0.02)
    # Axle 0 slides deep (dump), axle 2 a little (hold), the others roll; no wheel decelerates.
    wheels = np.array([[30.0 * (1 - 2 * config.dump_slip), 30.0, 30.0 * (1 - 1.5 * config.hold_slip), 30.0]])
    controller.reset(wheels)
    assert controller.valves(wheels).tolist() == [[VALVE_DUMP, VALVE_HOLD]]
    controller.valves(np.full((1, 4), 10.0))  # every wheel slides: the reference may not follow
    assert controller.reference_speed_mps[0] == pytest.approx(30.0 - 0.02 * config.reference_deceleration_mps2)
    with pytest.raises(ValueError, match="train_speed_mps"):
        wsp_agents.WspController(wsp_agents.load_wsp_config("wsp-true-speed"), np.arange(4), 0.02).valves(wheels)
