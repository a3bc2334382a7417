"""The effect library against physics: each effect changes the forces, heat or sensor readings by
exactly what its law says, at a known state; bounds and configs are validated."""

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from brakegym import config as cfg
from brakegym.diagnosis.judging import not_bounded_by_data
from brakegym.effects import EFFECTS, apply_effects, load_effects, make_effect
from brakegym.plants import train_plant
from brakegym.recordings.measurement import MeasurementModel
from brakegym.recordings.replay import simulate_grid
from brakegym.simulator import BatchConditions, PrescribedPressure
from brakegym.units import STANDARD_GRAVITY_MPS2

REPO_CONFIGS = Path(__file__).resolve().parent.parent / "configs"
VEHICLE = cfg.load("vehicles", "emu_8axle")
MASS_KG = VEHICLE.mass_kg("empty")
SPEED_MPS = 30.0
STEP_S = 0.1

pytestmark = pytest.mark.filterwarnings("ignore")


def _conditions(n=1, speed_mps=SPEED_MPS, temperature_C=50.0):
    plant = train_plant(VEHICLE)
    material = cfg.load("materials", VEHICLE.material)
    shape = (n, *plant.disc_shape)
    return BatchConditions(
        mass_kg=np.full(n, MASS_KG),
        initial_speed_mps=np.full(n, speed_mps),
        initial_mu=np.full(shape, material.initial_mu),
        power_coefficient_per_s=np.full(shape, material.power_coefficient_per_s),
        running_resistance_A_N=np.full(n, VEHICLE.running_resistance.A_N),
        initial_friction_temperature_K=np.full(shape, temperature_C + 273.15),
        initial_disc_temperature_K=np.full(shape, temperature_C + 273.15),
        ambient_temperature_K=np.full(n, 293.15),
    )


def _simulator(effects, pressure_bar=3.3, n=1, **conditions):
    model = apply_effects(train_plant(VEHICLE), _conditions(n, **conditions), effects)
    trace = np.full((2, n, VEHICLE.n_axles), pressure_bar)
    return model, model.simulator(PrescribedPressure(np.array([0.0, 1.0]), trace, STEP_S), STEP_S)


def _nominal_resistance_N(speed_mps=SPEED_MPS):
    r = VEHICLE.running_resistance
    return r.A_N + r.B_N_per_mps * speed_mps + r.C_N_per_mps2 * speed_mps**2


def _initial_brake_force_N(effects, **kwargs):
    """The brake force at the initial state: what decelerates the train besides the resistance."""
    model, sim = _simulator(effects, **kwargs)
    return sim.deceleration_mps2()[0] * MASS_KG - _nominal_resistance_N()


def _run(effects, pressure_bar=3.3, speed_mps=20.0, n=1, decel_source="accelerometer"):
    model = apply_effects(train_plant(VEHICLE), _conditions(n, speed_mps=speed_mps), effects)
    trace = np.full((2, n, VEHICLE.n_axles), pressure_bar)
    grid = simulate_grid(
        model, PrescribedPressure(np.array([0.0, 1.0]), trace, STEP_S), STEP_S, lambda sim: not sim.moving.any()
    )
    return model, grid, [MeasurementModel(grid, b, model, decel_source, 1) for b in range(n)]


# ------------------------------------------------------------------------------------------------


def test_gradient_is_in_the_speed_signal_and_not_in_the_accelerometer():
    permil = 12.0
    _, flat, (flat_accel,) = _run([])
    slope_model, slope, (slope_accel,) = _run([make_effect("gradient", gradient_permil=permil)])
    extra = STANDARD_GRAVITY_MPS2 * permil / 1000.0
    # At the common initial state the motion decelerates by exactly g x gradient more ...
    assert slope.decel_mps2[0, 0] - flat.decel_mps2[0, 0] == pytest.approx(extra, rel=1e-12)
    # ... which a speed-derived deceleration sees and the accelerometer does not.
    t0 = np.array([0.0])
    assert slope_accel.channels(t0)["decel_mps2"][0] == pytest.approx(
        flat_accel.channels(t0)["decel_mps2"][0], rel=1e-12
    )
    slope_speed = MeasurementModel(slope, 0, slope_model, "speed", 1)
    assert slope_speed.channels(t0)["decel_mps2"][0] - flat_accel.channels(t0)["decel_mps2"][0] == pytest.approx(
        extra, rel=1e-9
    )
    # Uphill the train stops sooner.
    assert slope.stop_time_s[0] < flat.stop_time_s[0]


def test_rotating_mass_scales_deceleration_by_one_over_one_plus_f():
    _, plain = _simulator([])
    _, heavy = _simulator([make_effect("rotating_mass", mass_factor=0.08)])
    assert heavy.deceleration_mps2()[0] == pytest.approx(plain.deceleration_mps2()[0] / 1.08, rel=1e-12)


def test_rotating_mass_keeps_gravity_on_the_true_mass():
    gradient = make_effect("gradient", gradient_permil=10.0)
    _, sim = _simulator([gradient, make_effect("rotating_mass", mass_factor=0.1)], pressure_bar=0.0)
    expected = (_nominal_resistance_N() + MASS_KG * STANDARD_GRAVITY_MPS2 * 0.01) / (1.1 * MASS_KG)
    assert sim.deceleration_mps2()[0] == pytest.approx(expected, rel=1e-12)


def test_friction_level_scales_the_brake_force():
    nominal = _initial_brake_force_N([])
    assert _initial_brake_force_N([make_effect("friction_level", mu_scale=0.85)]) == pytest.approx(
        0.85 * nominal, rel=1e-12
    )


def test_wet_pads_lose_friction_at_first_and_dry_with_heat():
    nominal = _initial_brake_force_N([])
    wet = make_effect("wet_pads", initial_loss=0.3, drying_energy_MJ=0.5)
    assert _initial_brake_force_N([wet]) == pytest.approx(0.7 * nominal, rel=1e-12)
    stop = {}
    for label, effects in (
        ("dry", []),
        ("dries fast", [make_effect("wet_pads", initial_loss=0.3, drying_energy_MJ=0.05)]),
        ("dries slowly", [make_effect("wet_pads", initial_loss=0.3, drying_energy_MJ=10.0)]),
    ):
        stop[label] = _run(effects)[1].stop_time_s[0]
    assert stop["dry"] < stop["dries fast"] < stop["dries slowly"]
    # Drying over 0.05 MJ, about a tenth of a 20 m/s stop's heat per disc: nearly dry.
    assert stop["dries fast"] - stop["dry"] < 0.1 * (stop["dries slowly"] - stop["dry"])


def test_adhesion_limits_each_axles_brake_force():
    limited = make_effect("adhesion_limit", adhesion=0.06)
    force = _initial_brake_force_N([limited])
    assert force == pytest.approx(0.06 * MASS_KG * STANDARD_GRAVITY_MPS2, rel=1e-12)
    nominal = _initial_brake_force_N([])
    assert force < nominal
    assert _initial_brake_force_N([make_effect("adhesion_limit", adhesion=0.5)]) == pytest.approx(nominal, rel=1e-12)
    # The limit caps the force the other effects leave, whatever order they are given in.
    # (the nominal force is 0.10 of the train's weight: 0.55 of it stays under the limit)
    low_friction = make_effect("friction_level", mu_scale=0.55)
    assert _initial_brake_force_N([limited, low_friction]) == pytest.approx(0.55 * nominal, rel=1e-12)


def test_thermal_fade_above_onset_only():
    fade = make_effect("thermal_fade", onset_C=200.0, loss_per_100K=0.2)
    hot_nominal = _initial_brake_force_N([], temperature_C=300.0)
    assert _initial_brake_force_N([fade], temperature_C=300.0) == pytest.approx(0.8 * hot_nominal, rel=1e-12)
    assert _initial_brake_force_N([fade], temperature_C=400.0) == pytest.approx(
        0.64 * _initial_brake_force_N([], temperature_C=400.0), rel=1e-12
    )
    assert _initial_brake_force_N([fade], temperature_C=190.0) == pytest.approx(
        _initial_brake_force_N([], temperature_C=190.0), rel=1e-12
    )


def test_brake_unit_failure_silences_the_last_units():
    failure = make_effect("brake_unit_failure", failed_units=2)
    assert _initial_brake_force_N([failure]) == pytest.approx(14 / 16 * _initial_brake_force_N([]), rel=1e-12)
    _, grid, _ = _run([failure])
    heat = grid.friction_heat_J[-1, :, 0]
    assert np.all(heat[14:] == 0.0) and np.all(heat[:14] > 1e5)


def test_running_resistance_replaces_the_nominal_coefficients():
    effect = make_effect("running_resistance", A_N=6000.0, B_N_per_mps=80.0, C_N_per_mps2=9.0)
    _, sim = _simulator([effect], pressure_bar=0.0)
    expected = (6000.0 + 80.0 * SPEED_MPS + 9.0 * SPEED_MPS**2) / MASS_KG
    assert sim.deceleration_mps2()[0] == pytest.approx(expected, rel=1e-12)


def test_only_a_running_resistance_shifts_the_resistance_and_by_its_difference_at_20_mps():
    # The diagnosis's screening starts each recording's resistance deviation this much lower.
    nominal = VEHICLE.running_resistance
    resistance = EFFECTS["running_resistance"]
    as_nominal = {"A_N": nominal.A_N, "B_N_per_mps": nominal.B_N_per_mps, "C_N_per_mps2": nominal.C_N_per_mps2}
    assert resistance.resistance_shift_N(as_nominal, nominal) == 0.0
    heavier = {**as_nominal, "A_N": nominal.A_N + 1000.0, "C_N_per_mps2": nominal.C_N_per_mps2 + 2.0}
    assert resistance.resistance_shift_N(heavier, nominal) == pytest.approx(1000.0 + 2.0 * 20.0**2)
    assert EFFECTS["gradient"].resistance_shift_N({"gradient_permil": 5.0}, nominal) == 0.0


def test_speed_sensor_scale_scales_speed_odometry_and_derived_deceleration_only():
    scale = make_effect("speed_sensor_scale", scale=1.04)
    model, grid, (accelerometer,) = _run([scale])
    _, _, (plain,) = _run([])
    derived = MeasurementModel(grid, 0, model, "speed", 1)
    t = np.linspace(0.0, grid.time_s[-1], 37)
    measured, true = accelerometer.channels(t), plain.channels(t)
    np.testing.assert_allclose(measured["speed_mps"], 1.04 * true["speed_mps"], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(measured["position_m"], 1.04 * true["position_m"], rtol=1e-12)
    np.testing.assert_allclose(measured["decel_mps2"], true["decel_mps2"], rtol=1e-12)
    np.testing.assert_allclose(derived.channels(t)["decel_mps2"], 1.04 * true["decel_mps2"], rtol=1e-12)
    np.testing.assert_allclose(measured["T_disc_C"], true["T_disc_C"], rtol=1e-12)


def test_temperature_sensor_lag_delays_the_reading():
    _, grid, (lagged,) = _run([make_effect("temperature_sensor_lag", tau_s=8.0)])
    _, _, (plain,) = _run([])
    t = grid.time_s
    reading, surface = lagged.channels(t)["T_disc_C"], plain.channels(t)["T_disc_C"]
    assert reading[0] == surface[0]
    heating = np.flatnonzero(np.diff(surface) > 0)[5:20]
    assert np.all(reading[heating] < surface[heating] - 0.5)


def test_parameters_may_differ_per_application():
    both = _run([make_effect("gradient", gradient_permil=np.array([-5.0, 10.0]))], n=2)[1]
    down = _run([make_effect("gradient", gradient_permil=-5.0)])[1]
    up = _run([make_effect("gradient", gradient_permil=10.0)])[1]
    assert both.stop_time_s[0] == pytest.approx(down.stop_time_s[0], rel=1e-12)
    assert both.stop_time_s[1] == pytest.approx(up.stop_time_s[0], rel=1e-12)


@pytest.mark.parametrize(
    "effect_id, parameters, message",
    [
        ("gradient", {"gradient_permil": 45.0}, r"'gradient_permil' = 45 permil lies outside its bounds -40\.\.40"),
        ("gradient", {"gradient": 5.0}, r"unknown parameter\(s\) \['gradient'\]"),
        ("thermal_fade", {"onset_C": 200.0}, r"parameter\(s\) \['loss_per_100K'\] not given"),
        ("brake_unit_failure", {"failed_units": 1.5}, r"must be a whole number"),
        ("sanding", {}, r"unknown effect 'sanding'"),
    ],
)
def test_bad_parameters_are_refused(effect_id, parameters, message):
    with pytest.raises(ValueError, match=message):
        make_effect(effect_id, **parameters)


def test_every_effect_has_its_public_parameters_and_a_no_effect_value():
    expected = {
        "gradient": ["gradient_permil"],
        "friction_level": ["mu_scale"],
        "wet_pads": ["initial_loss", "drying_energy_MJ"],
        "adhesion_limit": ["adhesion"],
        "thermal_fade": ["onset_C", "loss_per_100K"],
        "rotating_mass": ["mass_factor"],
        "brake_unit_failure": ["failed_units"],
        "running_resistance": ["A_N", "B_N_per_mps", "C_N_per_mps2"],
        "speed_sensor_scale": ["scale"],
        "temperature_sensor_lag": ["tau_s"],
        "gradient_section": ["section_start_m", "section_length_m", "section_gradient_permil"],
        "adhesion_section": ["patch_start_m", "patch_length_m", "patch_adhesion"],
        "gradient_sections": [
            f"{which}_section_{name}"
            for which in ("first", "second")
            for name in ("start_m", "length_m", "gradient_permil")
        ],
    }
    assert {k: [p.name for p in cls.parameters] for k, cls in EFFECTS.items()} == expected
    nominal = _initial_brake_force_N([])
    for cls in EFFECTS.values():
        absent = cls(**cls.no_effect_values(VEHICLE))  # constructible: valid values
        if not cls.sensor:
            assert _initial_brake_force_N([absent]) == pytest.approx(nominal, rel=1e-12), cls.id
        for spec in cls.parameters:
            for low, high in spec.synth_ranges:
                assert spec.lower <= low < high <= spec.upper, (cls.id, spec.name)


def test_effect_set_from_yaml_runs_in_the_simulator():
    (gradient,) = load_effects("example_gradient")
    assert gradient["gradient_permil"] == -5.8
    downhill = _run([gradient])[1].stop_time_s[0]
    assert downhill > _run([])[1].stop_time_s[0]
    assert [e.id for e in load_effects(REPO_CONFIGS / "effects" / "example_wet_pads_heavy_train.yaml")] == [
        "wet_pads",
        "rotating_mass",
    ]


@pytest.mark.parametrize(
    "effects, message",
    [
        (
            [{"id": "gradient", "parameters": {"gradient_permil": 99}}],
            r"field 'effects\.0' .*'gradient_permil' = 99 permil lies outside",
        ),
        (
            [{"id": "gradient", "paramters": {"gradient_permil": 1}}],
            r"field 'effects\.0\.paramters' = .*Extra inputs are not permitted",
        ),
        ([{"id": "gradient", "parameters": {"gradient_permil": 1}}] * 2, r"\['gradient'\] appear more than once"),
    ],
)
def test_bad_effect_config_names_file_field_and_value(tmp_path, monkeypatch, effects, message):
    target = tmp_path / "configs"
    shutil.copytree(REPO_CONFIGS, target)
    monkeypatch.setenv(cfg.CONFIG_PATH_ENV, str(target))
    path = target / "effects" / "bad.yaml"
    path.write_text(yaml.safe_dump({"name": "bad", "effects": effects}))
    with pytest.raises(cfg.ConfigError, match=message) as info:
        load_effects("bad")
    assert str(path) in str(info.value)


def test_a_fit_at_a_search_bound_is_told_from_one_at_a_physical_bound():
    """A thermal fade's onset at the lowest the library allows ends its search range; a running
    resistance's B = 0 is a physical bound that the truth can sit on (no linear term)."""
    share = 0.005
    onset = make_effect("thermal_fade", onset_C=100.0, loss_per_100K=0.2).spec("onset_C")
    assert onset.at_range_end(80.01, share) and onset.at_range_end(599.0, share)
    assert not onset.at_range_end(100.0, share)
    resistance = EFFECTS["running_resistance"]
    assert not resistance.spec("B_N_per_mps").at_range_end(0.0, share)
    assert resistance.spec("B_N_per_mps").at_range_end(299.9, share)
    # A parameter on a log grid: the share of its range in logarithm (10 MJ is the top).
    drying = EFFECTS["wet_pads"].spec("drying_energy_MJ")
    assert drying.at_range_end(9.9, share) and not drying.at_range_end(9.0, share)
    assert drying.at_range_end(0.0502, share) and not drying.at_range_end(0.06, share)
    # Every bound of the library is one or the other on purpose: the physical ones by name.
    physical = {
        (cls.id, spec.name, side)
        for cls in EFFECTS.values()
        for spec in cls.parameters
        for side, is_physical in (("lower", spec.lower_is_physical), ("upper", spec.upper_is_physical))
        if is_physical
    }
    assert physical == {
        ("wet_pads", "initial_loss", "lower"),
        ("thermal_fade", "loss_per_100K", "lower"),
        ("running_resistance", "A_N", "lower"),
        ("running_resistance", "B_N_per_mps", "lower"),
        ("running_resistance", "C_N_per_mps2", "lower"),
        ("temperature_sensor_lag", "tau_s", "lower"),
        ("gradient_section", "section_start_m", "lower"),
        ("adhesion_section", "patch_start_m", "lower"),
        ("gradient_sections", "first_section_start_m", "lower"),
        ("gradient_sections", "second_section_start_m", "lower"),
    }


def test_an_interval_over_the_whole_search_range_is_not_bounded_by_the_data():
    """An interval that reaches both ends of a parameter's range, physical or not, holds any truth:
    the report names such parameters (``not_bounded_by_data``). A log-grid parameter is judged
    along its logarithm, as at its range's end."""
    share = 0.005
    section = EFFECTS["gradient_section"]
    assert section.spec("section_start_m").spans_range(0.0, 2499.0, share)  # from a physical bound
    assert not section.spec("section_start_m").spans_range(0.0, 2400.0, share)
    assert not section.spec("section_gradient_permil").spans_range(-39.0, 40.0, share)
    drying = EFFECTS["wet_pads"].spec("drying_energy_MJ")
    assert drying.spans_range(0.0502, 9.9, share) and not drying.spans_range(0.06, 10.0, share)
    ci95 = {
        "section_start_m": [0.0, 2500.0],
        "section_length_m": [100.0, 300.0],
        "section_gradient_permil": [-40.0, 40.0],
    }
    assert not_bounded_by_data(["gradient_section"], ci95, share) == ["section_start_m", "section_gradient_permil"]
    # An integer parameter held at its value is bounded by being held.
    assert not_bounded_by_data(["brake_unit_failure"], {"failed_units": [0.0, 8.0]}, share) == []
