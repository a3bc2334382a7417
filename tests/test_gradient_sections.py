"""A profile of two unknown sections of gradient (issue 18, item 3: "fitted as a profile where
the data support it"): the effect, the second step of the residual along position found in what
the first leaves, and the diagnosis that names the profile where one section would not do."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from brakegym import config as cfg
from brakegym.diagnosis import diagnose
from brakegym.diagnosis.locate import residual_trace
from brakegym.diagnosis.pipeline import Diagnoser
from brakegym.diagnosis.position_steps import find_position_step
from brakegym.diagnosis.rules import DiagnosisRules
from brakegym.effects import TRAIN_LENGTH_M, Evidence, GradientSections, LocatedStretch, make_effect
from brakegym.recordings import read_dataset
from brakegym.recordings.synth import EffectRequest, synthesize

REPO = Path(__file__).resolve().parent.parent
VEHICLE = cfg.load("vehicles", "emu_8axle")
# Up 8 permil from 200 to 500 m, level, then down 9 permil from 700 to 1000 m.
PROFILE = {
    "first_section_start_m": 200.0,
    "first_section_length_m": 300.0,
    "first_section_gradient_permil": 8.0,
    "second_section_start_m": 700.0,
    "second_section_length_m": 300.0,
    "second_section_gradient_permil": -9.0,
}

pytestmark = pytest.mark.filterwarnings("ignore")


@pytest.fixture(autouse=True)
def checkout_configs(monkeypatch):
    """This checkout's configs on the search path (an installed brakegym may ship others)."""
    monkeypatch.setenv(cfg.CONFIG_PATH_ENV, str(REPO / "configs"))


def test_a_profile_whose_second_section_is_level_is_the_single_section(simulate_one_stop):
    """Analytic limit: with the second gradient 0 the profile is the first section alone."""
    first = {name.removeprefix("first_"): value for name, value in PROFILE.items() if name.startswith("first_")}
    flat = {**PROFILE, "first_section_start_m": 100.0, "second_section_gradient_permil": 0.0}
    _, profile = simulate_one_stop([make_effect("gradient_sections", **flat)])
    _, single = simulate_one_stop([make_effect("gradient_section", **{**first, "section_start_m": 100.0})])
    _, free = simulate_one_stop()
    np.testing.assert_allclose(profile.speed_mps, single.speed_mps, rtol=0, atol=1e-12)
    assert profile.stop_time_s[0] != pytest.approx(free.stop_time_s[0], rel=1e-3)


def test_a_profile_is_screened_only_where_two_steps_are_located_the_nearer_first():
    near = LocatedStretch(230.0, 520.0, 0.05, 1.3)
    far = LocatedStretch(720.0, 1040.0, -0.09, 1.0)
    evidence = Evidence(1.0, 100.0, np.ones(4), VEHICLE.running_resistance, run_distance_m=1200.0)
    assert GradientSections.screening_points(evidence) == []
    located = Evidence(
        1.0, 100.0, np.ones(4), VEHICLE.running_resistance, run_distance_m=1200.0, profile_stretches=(far, near)
    )
    (point,) = GradientSections.screening_points(located)
    half = TRAIN_LENGTH_M / 2
    np.testing.assert_allclose(
        point, [230.0 - half, 290.0, near.gradient_permil, 720.0 - half, 320.0, far.gradient_permil]
    )
    assert GradientSections.is_relevant(PROFILE, located)
    assert not GradientSections.is_relevant({**PROFILE, "second_section_gradient_permil": 0.5}, located)


@pytest.fixture(scope="module")
def profile_set(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("profile") / "set"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        synthesize(folder, 8, seed=4, effects=[EffectRequest("gradient_sections", PROFILE)])
    return folder


def test_the_second_section_is_found_in_what_the_first_step_leaves(profile_set):
    """The first step is the steeper, farther section; in what it leaves, the second step is the
    nearer one. Each step's edges lie half a train length beyond its section's ends, to within two
    bins (thresholds fixed before the test)."""
    replays = Diagnoser(read_dataset(profile_set).recordings).unmodified_fit().replays
    traces = [residual_trace(replayed) for replayed in replays]
    rules = DiagnosisRules()
    first = find_position_step(traces, rules.position_step_bin_m, TRAIN_LENGTH_M)
    second = find_position_step(traces, rules.position_step_bin_m, TRAIN_LENGTH_M, earlier=(first,))
    steps = sorted([first, second], key=lambda step: step.start_m)
    for step, which in zip(steps, ("first", "second"), strict=True):
        start = PROFILE[f"{which}_section_start_m"]
        assert step.start_m == pytest.approx(start + TRAIN_LENGTH_M / 2, abs=2 * rules.position_step_bin_m)
        end = start + PROFILE[f"{which}_section_length_m"] + TRAIN_LENGTH_M / 2
        assert step.end_m == pytest.approx(end, abs=2 * rules.position_step_bin_m)
        assert np.sign(step.decel_step_mps2) == np.sign(PROFILE[f"{which}_section_gradient_permil"])
        assert step.explained_share >= rules.position_step_min_share


def test_the_diagnosis_names_a_profile_of_two_sections(profile_set, naming_rules):
    """Selected is the profile, each section where the truth is (thresholds fixed before the
    run: ends within 40 m, gradients within 20 %), and the report keeps both steps."""
    report = diagnose(profile_set, top_singles=2, pairs_from=0, rules=naming_rules).report
    assert report["selected"] == ["gradient_sections"], report["summary"]
    fitted = report["parameters"]
    for which in ("first", "second"):
        start = PROFILE[f"{which}_section_start_m"]
        assert fitted[f"{which}_section_start_m"] == pytest.approx(start, abs=40.0)
        end = fitted[f"{which}_section_start_m"] + fitted[f"{which}_section_length_m"]
        assert end == pytest.approx(start + PROFILE[f"{which}_section_length_m"], abs=40.0)
        gradient = PROFILE[f"{which}_section_gradient_permil"]
        assert fitted[f"{which}_section_gradient_permil"] == pytest.approx(gradient, rel=0.2)
    assert report["position_step"] is not None and report["second_position_step"] is not None
