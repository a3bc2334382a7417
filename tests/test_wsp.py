"""Wheel-slide protection (issue 16): the WSP valves on top of the brake cylinders, their config,
and the reference WSP controller on the low-adhesion rail."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from brakegym import config as cfg
from brakegym.physics.pneumatics import VALVE_APPLY, VALVE_DUMP, VALVE_HOLD, valve_pressure_after
from brakegym.plants import brake_cylinder, train_plant, valve_of_axle, wsp_valve
from brakegym.simulator import CommandedPressure
from brakegym.simulator.pressure import ValvedPressure

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
