"""Field campaigns on a rail condition (docs/adhesion.md, "Campaigns on a rail"): each stop's rail
mu_0 drawn from the seed and the stop's number, stops with adhesion and WSP, the same rows bit for
bit whatever the chunks and the executor; the lognormal rail scatter; the inverse of the peak
adhesion."""

import dataclasses
import functools
import json

import numpy as np
import pandas as pd
import pytest

from brakegym import config as cfg
from brakegym.applications import TrainApplication, run_commanded_stops, train_conditions
from brakegym.campaigns import RAIL_STOP_COLUMNS, field_campaign, rail_field_campaign
from brakegym.cli import main
from brakegym.diagnosis.adhesion import read_adhesion
from brakegym.effects import apply_effects, make_effect
from brakegym.execution import InlineExecutor, LocalExecutor
from brakegym.physics import static_friction_factor
from brakegym.plants import (
    brake_cylinder,
    nominal_draw,
    polach_law,
    rail_friction_factor_for_samples,
    rail_static_friction_relative_sigma,
    train_plant,
    wheel_rail_adhesion,
    wheel_rail_contact,
)
from brakegym.units import STANDARD_GRAVITY_MPS2
from brakegym.wheel_slide import wsp_train_stops


@pytest.fixture(scope="module")
def small_campaign() -> cfg.FieldCampaign:
    """Emergency stops from 120 km/h, empty, both pad sets and actuations: 4 field applications,
    3 repetitions, 12 stops."""
    campaign = cfg.load("campaigns", "field2022")
    factors = {**campaign.factors, "brake_mode": ["emergency"], "load": ["empty"], "initial_speed_kmh": [120]}
    return campaign.model_copy(update={"factors": factors, "repetitions": 3})


@pytest.fixture(scope="module")
def wsp_config():
    from brakegym.agents.wsp import load_wsp_config

    return load_wsp_config("wsp")


def _low_campaign(small_campaign, wsp_config, **options) -> pd.DataFrame:
    return rail_field_campaign(
        small_campaign,
        cfg.load("setups", "mcs-75-25"),
        5,
        cfg.load("rail_conditions", "low"),
        cfg.load("wsp_valves", "axle"),
        wsp_config,
        **options,
    ).applications


@pytest.fixture(scope="module")
def low_reference(small_campaign, wsp_config) -> pd.DataFrame:
    """The low-rail campaign with the reference WSP in this process, one chunk."""
    return _low_campaign(small_campaign, wsp_config, chunk_size=1000)


@pytest.mark.parametrize(
    ("executor", "chunk_size"), [(InlineExecutor(kernel_threads=1), 5), (LocalExecutor(2), 4)], ids=["inline", "local"]
)
def test_rail_campaign_the_same_whatever_the_executor_and_chunk_size(
    small_campaign, wsp_config, low_reference, executor, chunk_size
):
    result = _low_campaign(small_campaign, wsp_config, chunk_size=chunk_size, executor=executor)
    pd.testing.assert_frame_equal(result, low_reference, check_exact=True)


def test_rail_campaign_with_load_transfer_is_its_own_and_the_same_whatever_the_chunks(
    small_campaign, wsp_config, low_reference
):
    """The option reaches every stop (the WSP's valves then act out of step, so the slide energy
    changes) and leaves the rail's draw alone; its rows too are the same in any chunks."""
    transferred = _low_campaign(small_campaign, wsp_config, chunk_size=1000, load_transfer=True)
    again = _low_campaign(small_campaign, wsp_config, chunk_size=5, load_transfer=True)
    pd.testing.assert_frame_equal(again, transferred, check_exact=True)
    np.testing.assert_array_equal(transferred.rail_friction_factor, low_reference.rail_friction_factor)
    assert not np.array_equal(transferred.slide_energy_MJ, low_reference.slide_energy_MJ)
    # The same rail and brake: the stops move by the WSP's response to unequal loads, not more.
    np.testing.assert_allclose(transferred.braking_distance_m, low_reference.braking_distance_m, rtol=0.05)


def test_rail_campaign_rows_are_the_field_campaigns_stops_on_a_scattered_rail(small_campaign, low_reference):
    """The same applications and running-resistance draws as the field campaign (the rail's draw
    has a stream of its own), the rail columns added; each stop's mu_0 is the condition's times its
    factor; the reference WSP keeps every axle from locking for long; the slipperier the drawn rail,
    the longer the stop (a rank correlation over the stops)."""
    field = field_campaign(small_campaign, cfg.load("setups", "mcs-75-25"), 5).applications
    assert list(low_reference.columns) == [*field.columns, *RAIL_STOP_COLUMNS]
    for column in ("brake_mode", "load", "pad_set", "actuation", "v0_kmh", "repetition", "running_resistance_A_N"):
        pd.testing.assert_series_equal(low_reference[column], field[column], check_exact=True)
    low = cfg.load("rail_conditions", "low")
    factor = rail_friction_factor_for_samples(low, 5, np.arange(len(low_reference)))
    np.testing.assert_array_equal(low_reference.rail_friction_factor, factor)
    np.testing.assert_allclose(low_reference.rail_static_friction, low.static_friction * factor, rtol=1e-15)
    assert low_reference.rail_friction_factor.std() > 0.05
    # The drawn peaks around the condition's 0.07 (its scatter 15 %).
    assert 0.04 < low_reference.rail_peak_adhesion.min() and low_reference.rail_peak_adhesion.max() < 0.11
    assert (low_reference.longest_locked_s < 0.5).all()
    assert (low_reference.slide_energy_MJ > 0).all()
    # The adhesion limits the stop: every stop longer than its stop without a rail, by far on average.
    assert (low_reference.braking_distance_m > field.braking_distance_m).all()
    assert low_reference.braking_distance_m.mean() > 1.3 * field.braking_distance_m.mean()
    same_actuation = low_reference[low_reference.actuation == "EP"]
    rank = same_actuation[["rail_peak_adhesion", "braking_distance_m"]].rank().corr().iloc[0, 1]
    assert rank < -0.5


def test_line_scatter_takes_its_widest_section_and_scales_every_section(small_campaign):
    line = cfg.load("lines", "low_patch")
    sigmas = [cfg.load("rail_conditions", s.rail_condition).static_friction_relative_sigma for s in line.sections]
    assert rail_static_friction_relative_sigma(line) == max(sigmas)


def test_rail_scatter_is_lognormal_with_mean_one_and_the_relative_sigma():
    """static_friction_factor: E[f] = 1 and std(f) = sigma exactly (Gauss-Hermite quadrature,
    exact for these integrands to round-off), positive for any normal, and per stop the same
    whatever the other stops drawn with it."""
    nodes, weights = np.polynomial.hermite_e.hermegauss(80)
    weights = weights / weights.sum()
    for sigma in (0.05, 0.15, 0.4):
        f = static_friction_factor(sigma, nodes)
        mean = float(weights @ f)
        assert mean == pytest.approx(1.0, abs=1e-12)
        assert np.sqrt(weights @ (f - mean) ** 2) == pytest.approx(sigma, rel=1e-10)
    assert static_friction_factor(0.15, np.array([-40.0, 40.0])).min() > 0
    assert static_friction_factor(0.0, np.array([-3.0, 3.0])).tolist() == [1.0, 1.0]
    low = cfg.load("rail_conditions", "low")
    np.testing.assert_array_equal(
        rail_friction_factor_for_samples(low, 9, np.arange(10, 20))[3:6],
        rail_friction_factor_for_samples(low, 9, np.arange(13, 16)),
    )


@pytest.mark.parametrize("name", ["dry", "wet", "low"])
@pytest.mark.parametrize("load", ["empty", "max"])
def test_static_friction_for_a_peak_adhesion_inverts_peak_adhesion(name, load):
    """PolachLaw.with_peak_adhesion: the mu_0 found gives the asked peak at that contact and speed
    (PolachLaw.peak_adhesion), and the condition's own peak gives back the condition's mu_0."""
    vehicle = cfg.load("vehicles", "emu_8axle")
    wheel_load = vehicle.mass_kg(load) * STANDARD_GRAVITY_MPS2 / (2 * vehicle.n_axles)
    stiffness = wheel_rail_contact(vehicle).creep_stiffness_N(wheel_load)
    law = polach_law(cfg.load("rail_conditions", name))
    for speed in (10.0, 30.0):
        own_peak = law.peak_adhesion(speed, wheel_load, stiffness)[0]
        assert law.with_peak_adhesion(own_peak, speed, wheel_load, stiffness).static_friction == pytest.approx(
            law.static_friction, rel=1e-4
        )
        for peak in (0.05, 0.12, 0.30):
            found = law.with_peak_adhesion(peak, speed, wheel_load, stiffness)
            assert found.peak_adhesion(speed, wheel_load, stiffness)[0] == pytest.approx(peak, abs=2e-6)
            assert dataclasses.replace(found, static_friction=law.static_friction) == law


def test_rail_options_only_where_they_apply(capsys):
    for args, message in (
        (["mcs", "--campaign", "dyno", "--condition", "low"], "--condition and --line are for the field campaign"),
        (["mcs", "--campaign", "field", "--wsp", "none"], "--wsp, --wsp-valves and --load-transfer need a rail"),
        (["mcs", "--campaign", "field", "--load-transfer"], "--wsp, --wsp-valves and --load-transfer need a rail"),
        (["mcs", "--campaign", "field", "--condition", "icy"], "unknown rail condition 'icy'"),
    ):
        assert main(args) == 2
        assert message in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["mcs", "--campaign", "field", "--condition", "low", "--line", "low_patch"])
    assert "not allowed with argument" in capsys.readouterr().err


# ------------------------------------------------------------------------------------------------
# The diagnosis's adhesion_limit and the rail's creep curve


def _cap_braking_distances_m(vehicle, adhesions: np.ndarray) -> np.ndarray:
    """Braking distances of the nominal model (no adhesion option) with the diagnosis's
    adhesion_limit at each of ``adhesions``: emu_8axle empty, emergency, EP, 120 km/h."""
    plant = train_plant(vehicle)
    n = len(adhesions)
    conditions = train_conditions(
        vehicle,
        mass_kg=np.full(n, vehicle.mass_kg("empty")),
        initial_speed_mps=np.full(n, 120 / 3.6),
        draw=nominal_draw(cfg.load("materials", vehicle.material), n, plant.disc_shape),
        running_resistance_A_N=np.full(n, vehicle.running_resistance.A_N),
    )
    model = apply_effects(plant, conditions, [make_effect("adhesion_limit", adhesion=adhesions)])
    command = np.full((n, plant.n_axles), vehicle.brake_pressure_bar("emergency", "empty"))
    return run_commanded_stops(
        model.plant,
        model.conditions,
        [brake_cylinder(cfg.load("pneumatics", "EP"))] * n,
        command,
        np.ones(n),
        plant.caliper.clamp_force_N(command),
        friction_modifiers=model.friction_modifiers,
        extra_forces=model.extra_forces,
    ).braking_distance_m


def _fitted_cap(vehicle, braking_distance_m: float) -> float:
    """The adhesion_limit whose stop brakes over ``braking_distance_m`` (the fit on that one
    number: the distance falls monotonically with the cap)."""
    adhesions = np.linspace(0.04, 0.10, 61)
    distances = _cap_braking_distances_m(vehicle, adhesions)
    assert np.all(np.diff(distances) < 0)
    return float(np.interp(braking_distance_m, distances[::-1], adhesions[::-1]))


def _ideal_wsp_braking_distance_m(vehicle, adhesion) -> float:
    """Every axle at the peak of the rail's creep curve at each speed from 120 km/h (an ideal
    WSP): d = integral of v dv / a(v), a = (peak(v) m g + F_R(v)) / M, after the EP cylinders'
    response (v0 times dead time plus time constant)."""
    cylinder = cfg.load("pneumatics", "EP")
    mass_kg = vehicle.mass_kg("empty")
    wheel_load_N = mass_kg * STANDARD_GRAVITY_MPS2 / (2 * vehicle.n_axles)
    stiffness_N = adhesion.contact.creep_stiffness_N(wheel_load_N)
    body_mass_kg = mass_kg - vehicle.n_axles * adhesion.wheelset_inertia_kgm2 / vehicle.wheel_radius_m**2
    resistance = vehicle.running_resistance
    speeds = np.linspace(0.05, 120 / 3.6, 300)
    peaks = np.array([adhesion.law.peak_adhesion(v, wheel_load_N, stiffness_N, n_creeps=4001)[0] for v in speeds])
    force = peaks * mass_kg * STANDARD_GRAVITY_MPS2 + resistance.A_N + resistance.B_N_per_mps * speeds
    deceleration = (force + resistance.C_N_per_mps2 * speeds**2) / body_mass_kg
    response_m = 120 / 3.6 * (cylinder.dead_time_s + cylinder.time_constant_s)
    return response_m + float(np.trapezoid(speeds / deceleration, speeds))


def test_adhesion_limit_is_the_rails_peak_times_the_wsps_utilisation(wsp_config):
    """docs/adhesion.md, "One adhesion": on a uniform low rail (emu_8axle empty, emergency EP,
    120 km/h) the diagnosis's cap fitted to an ideal WSP's stop (every axle at the creep curve's
    peak) is the rail's peak adhesion over the stop (the peak rises a few per cent as the train
    slows, the cap does not: the cap is its mean as the stop weighs it), up to the wheelsets'
    inertia (4 % here: the cap acts on the brake force, the peak on the rail's). Fitted to the
    reference WSP's stop it is lower, by the WSP's utilisation: the ratio of the two caps is the
    ratio of the ideal's and the WSP's braking distances past the cylinders' response, within 3 %.
    The reading of the cap names the low rail, with a mu_0 that gives the fitted peak."""
    from brakegym.agents.wsp import WspController

    vehicle = cfg.load("vehicles", "emu_8axle")
    low = cfg.load("rail_conditions", "low")
    adhesion = wheel_rail_adhesion(vehicle, low)
    ideal_m = _ideal_wsp_braking_distance_m(vehicle, adhesion)
    wsp_m = float(
        wsp_train_stops(
            vehicle,
            [TrainApplication("empty", "emergency", "EP", 120.0)],
            adhesion,
            cfg.load("wsp_valves", "axle"),
            functools.partial(WspController, wsp_config),
        ).summary.braking_distance_m[0]
    )
    ideal_cap, wsp_cap = _fitted_cap(vehicle, ideal_m), _fitted_cap(vehicle, wsp_m)
    # The peak over the stop as a constant cap acts: the mean of 1 / peak(v) weighted by v dv.
    wheel_load_N = vehicle.mass_kg("empty") * STANDARD_GRAVITY_MPS2 / (2 * vehicle.n_axles)
    stiffness_N = adhesion.contact.creep_stiffness_N(wheel_load_N)
    speeds = np.linspace(0.5, 120 / 3.6, 200)
    peaks = np.array([adhesion.law.peak_adhesion(v, wheel_load_N, stiffness_N, n_creeps=4001)[0] for v in speeds])
    stop_peak = float(np.trapezoid(speeds, speeds) / np.trapezoid(speeds / peaks, speeds))
    assert peaks.min() == pytest.approx(low.peak_adhesion, rel=0.02)  # the config's, rounded
    # The cap limits the brake force, which decelerates the wheelsets too; the rail's force only
    # the body: the cap lies between the peak and the peak times m / M (M = m - n J / r^2), where
    # the ideal's lag against the cylinders' response (taken whole) puts it.
    mass_kg = vehicle.mass_kg("empty")
    body_mass_kg = mass_kg - vehicle.n_axles * adhesion.wheelset_inertia_kgm2 / vehicle.wheel_radius_m**2
    assert stop_peak < ideal_cap < stop_peak * mass_kg / body_mass_kg
    cylinder = cfg.load("pneumatics", "EP")
    response_m = 120 / 3.6 * (cylinder.dead_time_s + cylinder.time_constant_s)
    utilisation = (ideal_m - response_m) / (wsp_m - response_m)
    assert 0.7 < utilisation < 0.97
    assert wsp_cap / ideal_cap == pytest.approx(utilisation, rel=0.03)
    reading = read_adhesion(ideal_cap, vehicle, vehicle.mass_kg("empty"))
    assert reading.nearest_condition == "low"
    assert reading.static_friction == pytest.approx(low.static_friction * ideal_cap / low.peak_adhesion, rel=0.05)
    print(
        f"stop peak {stop_peak:.4f} ({peaks.min():.4f}-{peaks.max():.4f}), ideal {ideal_m:.1f} m, cap {ideal_cap:.4f}"
    )
    print(f"WSP {wsp_m:.1f} m, cap {wsp_cap:.4f}, utilisation {utilisation:.3f}")


def test_cli_campaign_on_a_rail_writes_its_keys(tmp_path, capsys):
    """``brakegym mcs --condition low`` (the reference WSP by default): the field campaign's JSON
    keys and the rail's, the step the WSP's; the rows' columns in the CSV."""
    out, csv = tmp_path / "low.json", tmp_path / "low.csv"
    args = ["mcs", "--campaign", "field", "--condition", "low", "--repetitions", "1", "--json", str(out)]
    assert main([*args, "--csv", str(csv)]) == 0
    data = json.loads(out.read_text())
    assert {"campaign", "setup", "seed", "step_s", "applications", "field_applications"} <= set(data)
    assert data["rail"] == "low" and data["rail_kind"] == "condition"
    assert data["wsp"] == "reference" and data["wsp_valves"] == "axle" and data["step_s"] == 0.02
    assert data["applications"] == 88 and data["stops_with_locked_axle"] == 0
    assert 0.06 < data["rail_peak_adhesion_mean"] < 0.08
    rows = pd.read_csv(csv)
    assert set(RAIL_STOP_COLUMNS) <= set(rows.columns) and len(rows) == 88
    assert "on low, WSP reference" in capsys.readouterr().out
