"""A stretch of low adhesion (issue 18, item 3: position-local effects located in position, from
where to where): the cap's reach along the train, its analytic limits, what the accelerometer sees,
where the diagnosis screens it, and the diagnosis that names it where it lies."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from brakegym import config as cfg
from brakegym.diagnosis import diagnose
from brakegym.effects import (
    TRAIN_LENGTH_M,
    AdhesionSection,
    Evidence,
    GradientSection,
    LocatedStretch,
    apply_effects,
    make_effect,
    separating_measurement,
)
from brakegym.effects.hooks import AdhesionCap, AdhesionSectionCap
from brakegym.plants import train_plant
from brakegym.recordings.measurement import MeasurementModel
from brakegym.recordings.synth import RANDOM_EFFECT_IDS, EffectRequest, synthesize
from brakegym.units import STANDARD_GRAVITY_MPS2

REPO = Path(__file__).resolve().parent.parent
VEHICLE = cfg.load("vehicles", "emu_8axle")
PLANT = train_plant(VEHICLE)
# Dry rail, then 400 m from 300 m on where the rail gives 0.07.
PATCH = {"patch_start_m": 300.0, "patch_length_m": 400.0, "patch_adhesion": 0.07}

pytestmark = pytest.mark.filterwarnings("ignore")


@pytest.fixture(autouse=True)
def checkout_configs(monkeypatch):
    """This checkout's configs on the search path (an installed brakegym may ship others)."""
    monkeypatch.setenv(cfg.CONFIG_PATH_ENV, str(REPO / "configs"))


def _patch_cap(start_m: float, end_m: float, adhesion: float) -> AdhesionSectionCap:
    axle_load_N = VEHICLE.mass_kg("empty") / PLANT.n_axles * STANDARD_GRAVITY_MPS2
    cap = AdhesionCap(np.array([adhesion * axle_load_N]), (), PLANT)
    return AdhesionSectionCap(cap, np.array([start_m]), np.array([end_m]), TRAIN_LENGTH_M)


def test_each_axle_comes_under_the_cap_over_its_share_of_the_train():
    """Eight axles over 50 m, each with 6.25 m of it: the leading axle is wholly on a stretch
    from 100 m once the front is 6.25 m onto it, the train wholly on it 50 m on, and the sum of
    the shares ramps linearly in between, as a section's gradient force does."""
    patch = _patch_cap(100.0, 300.0, 0.07)
    spacing = TRAIN_LENGTH_M / PLANT.n_axles
    share = patch.share_on_stretch(np.array([100.0]))[:, 0]
    np.testing.assert_allclose(share, 0.0)
    share = patch.share_on_stretch(np.array([100.0 + spacing / 2]))[:, 0]
    np.testing.assert_allclose(share, [0.5] + [0.0] * 7)
    share = patch.share_on_stretch(np.array([100.0 + spacing]))[:, 0]
    np.testing.assert_allclose(share, [1.0] + [0.0] * 7)
    for front_m in (110.0, 125.0, 137.3, 150.0):
        total = patch.share_on_stretch(np.array([front_m]))[:, 0].sum()
        assert total == pytest.approx((front_m - 100.0) / spacing, abs=1e-12)
    np.testing.assert_allclose(patch.share_on_stretch(np.array([200.0]))[:, 0], 1.0)
    # Leaving: the leading axle first; past 300 m + one train length nothing is on it.
    np.testing.assert_allclose(patch.share_on_stretch(np.array([300.0 + spacing]))[:, 0], [0.0] + [1.0] * 7)
    np.testing.assert_allclose(patch.share_on_stretch(np.array([350.0]))[:, 0], 0.0)


def test_a_stretch_over_the_whole_run_is_the_adhesion_limit(simulate_one_stop):
    """Analytic limit: a stretch that the train is wholly on from start to stop leaves the same
    motion as the library's adhesion limit."""
    _, on_stretch = simulate_one_stop(friction_modifiers=[_patch_cap(-1e6, 1e6, 0.07)])
    _, limited = simulate_one_stop([make_effect("adhesion_limit", adhesion=0.07)])
    assert on_stretch.stop_time_s[0] == pytest.approx(limited.stop_time_s[0], rel=1e-9)
    np.testing.assert_allclose(on_stretch.position_m[-1], limited.position_m[-1], rtol=1e-9)


def test_the_cap_holds_the_train_on_the_stretch_only_and_the_accelerometer_sees_it(simulate_one_stop):
    model, capped = simulate_one_stop([make_effect("adhesion_section", **{**PATCH, "patch_start_m": 100.0})])
    _, free = simulate_one_stop()
    before = int(np.sum(capped.position_m[:, 0] < 100.0))
    assert before > 10
    np.testing.assert_allclose(capped.speed_mps[:before, 0], free.speed_mps[:before, 0], rtol=1e-12)
    # With the whole train on the stretch, the deceleration is at most the cap's brake force over
    # the mass plus the running resistance's (with rotating masses the train decelerates less).
    time, speed, position = capped.time_s, capped.speed_mps[:, 0], capped.position_m[:, 0]
    decel = -np.gradient(speed, time)
    on = (position > 100.0 + TRAIN_LENGTH_M + 5.0) & (speed > 2.0)
    assert on.sum() > 10
    mass = VEHICLE.mass_kg("empty")
    resistance = VEHICLE.running_resistance
    bound = (
        PATCH["patch_adhesion"] * STANDARD_GRAVITY_MPS2
        + (resistance.A_N + resistance.B_N_per_mps * speed[on] + resistance.C_N_per_mps2 * speed[on] ** 2) / mass
    )
    assert np.all(decel[on] <= bound + 1e-3)
    free_decel = -np.gradient(free.speed_mps[:, 0], free.time_s)
    assert np.max(decel[on]) < 0.75 * np.min(free_decel[free.speed_mps[:, 0] > 2.0])
    assert capped.stop_time_s[0] > free.stop_time_s[0]
    # The accelerometer reads the motion: no slope under the train.
    accelerometer = MeasurementModel(capped, 0, model, "accelerometer", 1)
    from_speed = MeasurementModel(capped, 0, model, "speed", 1)
    t = capped.time_s[capped.time_s < capped.stop_time_s[0] - 0.5]
    np.testing.assert_allclose(
        accelerometer.channels(t)["decel_mps2"], from_speed.channels(t)["decel_mps2"], atol=1e-12
    )


def test_an_application_braked_below_the_stretchs_adhesion_does_not_feel_it(simulate_one_stop):
    """Low adhesion acts only on a brake force above it: 0.2 g is twice this application's
    deceleration, so the motion is the free one to rounding."""
    _, capped = simulate_one_stop(
        [make_effect("adhesion_section", **{**PATCH, "patch_start_m": 50.0, "patch_adhesion": 0.2})]
    )
    _, free = simulate_one_stop()
    assert capped.stop_time_s[0] == pytest.approx(free.stop_time_s[0], rel=1e-12)
    np.testing.assert_allclose(capped.position_m[-1], free.position_m[-1], rtol=1e-12)


def _evidence(*stretches: LocatedStretch) -> Evidence:
    return Evidence(1.2, 100.0, np.ones(4), VEHICLE.running_resistance, run_distance_m=900.0, stretches=stretches)


def test_a_stretch_is_screened_where_the_train_slows_less_and_at_the_plateau_there():
    """The step's edges lie half a train length beyond the stretch's ends; the adhesion starts at
    shares of the hardest deceleration measured there over g. A step up (the train slows more)
    is a slope, not low adhesion."""
    down = LocatedStretch(325.0, 725.0, -0.19, 0.83)
    points = AdhesionSection.screening_points(_evidence(down))
    assert len(points) == len(AdhesionSection.PLATEAU_SHARES)
    for point, share in zip(points, AdhesionSection.PLATEAU_SHARES, strict=True):
        np.testing.assert_allclose(point, [300.0, 400.0, share * 0.83 / STANDARD_GRAVITY_MPS2])
    assert AdhesionSection.screening_points(_evidence(LocatedStretch(325.0, 725.0, 0.19, 0.83))) == []
    assert AdhesionSection.screening_points(_evidence(LocatedStretch(325.0, 725.0, -0.19, float("nan")))) == []
    # The gradient section reads the same step as a slope.
    (section,) = GradientSection.screening_points(_evidence(down))
    np.testing.assert_allclose(section, [300.0, 400.0, -1000.0 * 0.19 / STANDARD_GRAVITY_MPS2])


def test_a_stretch_is_relevant_where_it_caps_and_lies_on_part_of_the_run():
    relevant = AdhesionSection.is_relevant
    evidence = _evidence()  # peak deceleration 1.2 m/s^2, recordings up to 900 m
    assert relevant(PATCH, evidence)
    assert not relevant({**PATCH, "patch_adhesion": 0.15}, evidence)  # above the peak: caps nothing
    assert not relevant({**PATCH, "patch_start_m": 0.0, "patch_length_m": 2000.0}, evidence)  # the whole run
    assert not relevant({**PATCH, "patch_start_m": 950.0}, evidence)  # beyond every recording


def test_a_stretch_is_drawn_on_request_only_and_says_what_separates_it_from_a_slope():
    assert "adhesion_section" not in RANDOM_EFFECT_IDS
    assert "accelerometer" in separating_measurement("adhesion_section", "gradient_section")
    assert "other parts of the line" in separating_measurement("adhesion_section", "adhesion_limit")


@pytest.fixture(scope="module")
def patch_set(tmp_path_factory):
    folder = tmp_path_factory.mktemp("patch") / "set"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        synthesize(folder, 8, seed=1, effects=[EffectRequest("adhesion_section", PATCH)])
    return folder


def test_the_diagnosis_names_a_stretch_of_low_adhesion_where_it_lies(patch_set, naming_rules):
    """Located along position and told from a downhill section by the accelerometer (thresholds
    fixed before the run, as for a gradient section: ends within 40 m; adhesion within 10 %)."""
    report = diagnose(patch_set, top_singles=3, pairs_from=0, rules=naming_rules).report
    assert report["selected"] == ["adhesion_section"], report["summary"]
    fitted = report["parameters"]
    assert fitted["patch_start_m"] == pytest.approx(PATCH["patch_start_m"], abs=40.0)
    end = PATCH["patch_start_m"] + PATCH["patch_length_m"]
    assert fitted["patch_start_m"] + fitted["patch_length_m"] == pytest.approx(end, abs=40.0)
    assert fitted["patch_adhesion"] == pytest.approx(PATCH["patch_adhesion"], rel=0.10)
    step = report["position_step"]
    assert step["decel_step_mps2"] < 0 and step["peak_decel_mps2"] > 0
    by_effects = {tuple(c["effects"]): c for c in report["candidates"]}
    section = by_effects.get(("gradient_section",))
    assert section is None or section["delta_bic"] > by_effects[("adhesion_section",)]["delta_bic"]


def test_a_located_effect_joins_the_pairs_without_pushing_a_whole_line_one_out():
    """The pairs are fitted among the best two grid-screened singles, and the best located one
    where it ranks among the best two of all."""
    from types import SimpleNamespace

    from brakegym.diagnosis.pipeline import pairing_pool

    def single(effect_id, delta_bic):
        return SimpleNamespace(effect_ids=(effect_id,), delta_bic=delta_bic)

    limit, stretch = single("adhesion_limit", -12480), single("adhesion_section", -12384)
    resistance = single("running_resistance", -10021)
    section, level = single("gradient_section", -12000), single("friction_level", -1780)
    pool = pairing_pool([limit, stretch, section, resistance, level], 2)
    assert [c.effect_ids[0] for c in pool] == ["adhesion_limit", "adhesion_section", "running_resistance"]
    # A located effect that ranks third is not paired; the grid's best two are.
    pool = pairing_pool([limit, resistance, stretch, level], 2)
    assert [c.effect_ids[0] for c in pool] == ["adhesion_limit", "running_resistance"]


@pytest.fixture(scope="module")
def limit_and_resistance_set(tmp_path_factory):
    """Set 1326102795 of the blind benchmark's seed 17: an adhesion limit of 0.0872 and a running
    resistance (A 7830 N, B 62 N s/m, C 8.9 N s^2/m^2), drawn by ``--random-effects``."""
    folder = tmp_path_factory.mktemp("limit") / "set"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = synthesize(folder, 8, seed=1326102795, random_effects=True)
    assert [e["id"] for e in result.key["effects"]] == ["adhesion_limit", "running_resistance"]
    return folder


def test_a_stretch_that_looks_like_the_adhesion_limit_leaves_the_pair_of_the_truth_found(
    limit_and_resistance_set, naming_rules
):
    """The limit leaves a step along position and the stretch fits nearly as well as the limit;
    fitted in place of the running resistance it had the pair of the truth go unfitted."""
    report = diagnose(limit_and_resistance_set, rules=naming_rules).report
    assert report["selected"] == ["adhesion_limit", "running_resistance"], report["summary"]
    assert report["position_step"]["explained_share"] >= 0.05  # the stretch was screened


def test_an_adhesion_cap_holds_whatever_friction_law_a_synthetic_truth_adds():
    """Adhesion limits the force at the wheel, so a friction factor from outside the library (the
    ``real_train`` form's contact-pressure friction) must act before the cap, not on top of it:
    on a capped axle the force is the cap, with the law or without it."""
    from brakegym.recordings.model_form import ContactPressureFactor
    from brakegym.simulator.hooks import friction_scale

    n_axles, per_axle = PLANT.n_axles, PLANT.discs_per_axle
    conditions = _one_empty_train()
    law = ContactPressureFactor(0.1, 20e3, 2e3)
    adhesion = 0.05
    limit_N = adhesion * VEHICLE.mass_kg("empty") / n_axles * STANDARD_GRAVITY_MPS2
    # Clamp forces from well below to well above what the cap allows, one per axle.
    clamp = np.linspace(3e3, 45e3, n_axles)[:, None, None]
    context = _stage_context(n_axles, per_axle, clamp)
    # The train's front at 400 m: every axle on the stretch from 300 m.
    caps = [
        make_effect("adhesion_limit", adhesion=adhesion),
        make_effect("adhesion_section", **{**PATCH, "patch_adhesion": adhesion}),
    ]
    mu_free = PLANT.friction.bounded(context.mu) * law.scale(context)
    free_N = (mu_free * clamp).sum(axis=1)[:, 0] * PLANT.radius_ratio
    for effect in caps:
        effect_id = effect.id
        model = apply_effects(PLANT, conditions, [effect], friction_modifiers=[law])
        mu = PLANT.friction.bounded(context.mu) * friction_scale(model.friction_modifiers, context)
        axle_force_N = (mu * clamp).sum(axis=1)[:, 0] * PLANT.radius_ratio
        capped = free_N > limit_N
        assert capped.any() and (~capped).any(), effect_id
        np.testing.assert_allclose(axle_force_N[capped], limit_N, rtol=1e-12, err_msg=effect_id)
        np.testing.assert_allclose(axle_force_N[~capped], free_N[~capped], rtol=1e-12, err_msg=effect_id)


def _one_empty_train():
    """The conditions of one empty emu_8axle at 25 m/s with every disc at 50 degC."""
    from brakegym.simulator import BatchConditions

    disc_shape = (1, PLANT.n_axles, PLANT.discs_per_axle)
    return BatchConditions(
        mass_kg=np.full(1, VEHICLE.mass_kg("empty")),
        initial_speed_mps=np.full(1, 25.0),
        initial_mu=np.full(disc_shape, 0.35),
        power_coefficient_per_s=np.full(disc_shape, 0.008),
        running_resistance_A_N=np.full(1, VEHICLE.running_resistance.A_N),
        initial_friction_temperature_K=np.full(disc_shape, 323.15),
        initial_disc_temperature_K=np.full(disc_shape, 323.15),
        ambient_temperature_K=np.full(1, 293.15),
    )


def _stage_context(n_axles: int, per_axle: int, clamp_N: np.ndarray, front_m: float = 400.0):
    """A stage of one empty train whose front is at ``front_m``, each disc at mu 0.35 and 400 K."""
    from brakegym.simulator import StageContext

    return StageContext(
        0.0,
        np.array([20.0]),
        np.array([front_m]),
        np.full(1, VEHICLE.mass_kg("empty")),
        np.full((n_axles, per_axle, 1), 0.35),
        clamp_N,
        np.full((n_axles, per_axle, 1), 400.0),
        np.zeros((n_axles, per_axle, 1)),
    )


@pytest.mark.parametrize("electrodynamic_share_of_limit", [0.5, 1.6])
def test_a_brake_force_through_the_wheels_shares_the_adhesion_limit_with_the_pads(electrodynamic_share_of_limit):
    """Physical bound: an electrodynamic brake acts through the wheels as the pads do, so on a
    capped axle the pads' force and its share together are the cap. Below the cap both are kept;
    a share above the cap is held at it and leaves the pads nothing."""
    from brakegym.effects.hooks import ConstantForce
    from brakegym.simulator.hooks import friction_scale

    n_axles, per_axle = PLANT.n_axles, PLANT.discs_per_axle
    mass = VEHICLE.mass_kg("empty")
    conditions = _one_empty_train()
    adhesion = 0.05
    limit_N = adhesion * mass / n_axles * STANDARD_GRAVITY_MPS2
    electrodynamic_N = electrodynamic_share_of_limit * limit_N * n_axles
    clamp = np.linspace(0.0, 45e3, n_axles)[:, None, None]
    context = _stage_context(n_axles, per_axle, clamp)  # every axle on the stretch from 300 m
    free_pads_N = (PLANT.friction.bounded(context.mu) * clamp).sum(axis=1)[:, 0] * PLANT.radius_ratio
    share_N = electrodynamic_N / n_axles
    expected_pads_N = np.minimum(free_pads_N, max(limit_N - share_N, 0.0))
    expected_wheel_N = min(share_N, limit_N) * n_axles
    for effect in (
        make_effect("adhesion_limit", adhesion=adhesion),
        make_effect("adhesion_section", **{**PATCH, "patch_adhesion": adhesion}),
    ):
        model = apply_effects(
            PLANT, conditions, [effect], wheel_brake_forces=[ConstantForce(np.array([electrodynamic_N]))]
        )
        mu = PLANT.friction.bounded(context.mu) * friction_scale(model.friction_modifiers, context)
        pads_N = (mu * clamp).sum(axis=1)[:, 0] * PLANT.radius_ratio
        np.testing.assert_allclose(pads_N, expected_pads_N, rtol=1e-12, atol=1e-9, err_msg=effect.id)
        (wheel_force,) = model.forces_on_train()[-1:]
        assert wheel_force.force_N(context)[0] == pytest.approx(expected_wheel_N, rel=1e-12), effect.id
        assert np.all(pads_N + share_N <= np.maximum(limit_N, share_N) + 1e-9)
    # Off the stretch, the section leaves both untouched.
    off = _stage_context(n_axles, per_axle, clamp, front_m=100.0)
    model = apply_effects(
        PLANT,
        conditions,
        [make_effect("adhesion_section", **{**PATCH, "patch_adhesion": adhesion})],
        wheel_brake_forces=[ConstantForce(np.array([electrodynamic_N]))],
    )
    np.testing.assert_allclose(friction_scale(model.friction_modifiers, off), 1.0)
    assert model.forces_on_train()[-1].force_N(off)[0] == pytest.approx(electrodynamic_N, rel=1e-12)


def test_a_train_with_an_electrodynamic_brake_decelerates_no_harder_than_adhesion_allows(simulate_one_stop):
    """Physical bound in a simulated stop: with an electrodynamic brake of a quarter of the
    train's weight x 0.07 g beside the pads, the deceleration stays at the adhesion limit plus the
    running resistance's; without the limit it is harder than that."""
    from brakegym.effects.hooks import ConstantForce

    adhesion = 0.07
    mass = VEHICLE.mass_kg("empty")
    electrodynamic = [ConstantForce(np.array([0.25 * adhesion * mass * STANDARD_GRAVITY_MPS2]))]
    _, limited = simulate_one_stop(
        [make_effect("adhesion_limit", adhesion=adhesion)], wheel_brake_forces=electrodynamic
    )
    _, free = simulate_one_stop(wheel_brake_forces=electrodynamic)
    speed = limited.speed_mps[:, 0]
    decel = -np.gradient(speed, limited.time_s)
    moving = speed > 2.0
    resistance = VEHICLE.running_resistance
    bound = (
        adhesion * STANDARD_GRAVITY_MPS2
        + (resistance.A_N + resistance.B_N_per_mps * speed + resistance.C_N_per_mps2 * speed**2) / mass
    )
    assert np.all(decel[moving] <= bound[moving] + 1e-3)
    assert np.max(decel[moving]) > bound[moving].min() - 0.02  # the cap is reached
    free_decel = -np.gradient(free.speed_mps[:, 0], free.time_s)
    assert np.max(free_decel[free.speed_mps[:, 0] > 2.0]) > np.max(bound[moving]) + 0.05
