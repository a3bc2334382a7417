"""A gradient on part of the line (issue 18, item 3 and the failure class "a gradient that begins
part-way along the line is not named"): the section's force, its place in the accelerometer and
the speed signal, the step of the residual along position that locates it, and the diagnosis that
names it from where the data put it."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from brakegym import config as cfg
from brakegym.diagnosis import diagnose
from brakegym.diagnosis.locate import residual_trace
from brakegym.diagnosis.markdown import found_lines, write_report
from brakegym.diagnosis.pipeline import Diagnoser
from brakegym.diagnosis.position_steps import find_position_step
from brakegym.diagnosis.rules import DiagnosisRules
from brakegym.effects import EFFECTS, Evidence, GradientSection, make_effect
from brakegym.effects.hooks import GradientSectionForce
from brakegym.recordings import read_dataset
from brakegym.recordings.measurement import MeasurementModel
from brakegym.recordings.synth import (
    ALONG_TRACK_EFFECT_IDS,
    RANDOM_EFFECT_IDS,
    EffectRequest,
    random_requests,
    synthesize,
)
from brakegym.units import STANDARD_GRAVITY_MPS2

REPO = Path(__file__).resolve().parent.parent
VEHICLE = cfg.load("vehicles", "emu_8axle")
TRAIN_LENGTH_M = GradientSection.TRAIN_LENGTH_M
# Level for 300 m, then 8 permil uphill for 400 m, then level again.
SECTION = {"section_start_m": 300.0, "section_length_m": 400.0, "section_gradient_permil": 8.0}

pytestmark = pytest.mark.filterwarnings("ignore")


@pytest.fixture(autouse=True)
def checkout_configs(monkeypatch):
    """This checkout's configs on the search path (an installed brakegym may ship others)."""
    monkeypatch.setenv(cfg.CONFIG_PATH_ENV, str(REPO / "configs"))


def test_the_grade_ramps_over_one_train_length_at_each_end_of_the_section():
    """The mean gradient under a train of length L whose front is at x: the share of [x - L, x]
    on the section times its gradient."""
    line = GradientSectionForce(
        np.array([1.0e6, 1.0e6]), np.array([100.0, 0.0]), np.array([300.0, 20.0]), np.array([10.0, -5.0]), 50.0
    )
    positions = np.array([0.0, 100.0, 125.0, 150.0, 300.0, 325.0, 350.0, 1e4])
    expected = [0.0, 0.0, 0.005, 0.010, 0.010, 0.005, 0.0, 0.0]
    np.testing.assert_allclose(line.grade_at(positions, 0), expected, atol=1e-15)
    # A section shorter than the train never carries all of it: at most 20 m of 50 m.
    assert line.grade_at(np.array([20.0, 45.0]), 1) == pytest.approx([-0.005 * 20 / 50, -0.005 * 20 / 50])
    # Per train at once, each at its own position.
    np.testing.assert_allclose(line.grade_at(np.array([150.0, 20.0])), [0.010, -0.002])


def test_a_section_over_the_whole_run_is_the_constant_gradient(simulate_one_stop):
    """Analytic limit: a section that the train is wholly on from start to stop leaves the same
    motion as the library's constant gradient."""
    weight = np.array([VEHICLE.mass_kg("empty") * STANDARD_GRAVITY_MPS2])
    section = GradientSectionForce(weight, np.array([-1e6]), np.array([1e6]), np.array([9.0]), TRAIN_LENGTH_M)
    _, on_section = simulate_one_stop(extra_forces=[section])
    _, graded = simulate_one_stop([make_effect("gradient", gradient_permil=9.0)])
    assert on_section.stop_time_s[0] == pytest.approx(graded.stop_time_s[0], rel=1e-9)
    np.testing.assert_allclose(on_section.position_m[-1], graded.position_m[-1], rtol=1e-9)


def test_the_section_acts_where_the_train_is_on_it_and_the_accelerometer_does_not_see_it(simulate_one_stop):
    effect = make_effect(
        "gradient_section", section_start_m=100.0, section_length_m=150.0, section_gradient_permil=12.0
    )
    model, graded = simulate_one_stop([effect])
    _, level = simulate_one_stop()
    # Before the train reaches the section the motion is the level track's (to rounding: with a
    # force that depends on the position the simulator integrates in another order).
    before = int(np.sum(graded.position_m[:, 0] < 100.0))
    assert before > 10
    np.testing.assert_allclose(graded.speed_mps[:before, 0], level.speed_mps[:before, 0], rtol=1e-12)
    assert abs(graded.speed_mps[before + 20, 0] - level.speed_mps[before + 20, 0]) > 0.01
    # Uphill on part of the way: it stops sooner, but later than on 12 permil all the way.
    _, uphill = simulate_one_stop([make_effect("gradient", gradient_permil=12.0)])
    assert uphill.stop_time_s[0] < graded.stop_time_s[0] < level.stop_time_s[0]
    # The accelerometer reads the motion minus g times the grade under the train.
    accelerometer = MeasurementModel(graded, 0, model, "accelerometer", 1)
    from_speed = MeasurementModel(graded, 0, model, "speed", 1)
    t = graded.time_s[graded.time_s < graded.stop_time_s[0] - 0.5]
    _, position, _ = from_speed.kinematics(t)
    grade = model.extra_forces[-1].grade_at(position, 0)
    assert np.max(grade) == pytest.approx(0.012)
    np.testing.assert_allclose(
        accelerometer.channels(t)["decel_mps2"],
        from_speed.channels(t)["decel_mps2"] - STANDARD_GRAVITY_MPS2 * grade,
        atol=1e-12,
    )


def test_a_section_is_relevant_only_where_it_begins_or_ends_inside_the_recordings():
    evidence = Evidence(1.0, 100.0, np.ones(4), VEHICLE.running_resistance, run_distance_m=900.0)
    relevant = GradientSection.is_relevant
    assert relevant(SECTION, evidence)
    assert relevant({**SECTION, "section_start_m": 0.0}, evidence)  # ends part-way
    assert not relevant({**SECTION, "section_start_m": 0.0, "section_length_m": 2000.0}, evidence)  # the whole run
    assert not relevant({**SECTION, "section_start_m": 950.0}, evidence)  # beyond every recording
    assert not relevant({**SECTION, "section_gradient_permil": 0.8}, evidence)  # below the gradient's relevance


def test_parameter_names_are_unique_across_the_library():
    """A fit holds and reports the parameters of several effects by name in one mapping."""
    names = [spec.name for cls in EFFECTS.values() for spec in cls.parameters]
    assert len(names) == len(set(names))


def test_random_effects_keep_their_library_so_that_a_seed_keeps_its_set():
    """``--random-effects`` draws from the effects of brakegym 0.2; a gradient section is drawn
    on request only."""
    assert set(RANDOM_EFFECT_IDS) <= set(EFFECTS)
    assert "gradient_section" not in RANDOM_EFFECT_IDS
    rng = np.random.default_rng(5)
    drawn = {request.id for _ in range(200) for request in random_requests(rng)}
    assert drawn == set(RANDOM_EFFECT_IDS)


def test_the_along_track_library_puts_one_located_effect_in_every_set():
    rng = np.random.default_rng(5)
    draws = [[request.id for request in random_requests(rng, "along_track")] for _ in range(200)]
    assert all(len(ids) in (1, 2) and ids[0] in ALONG_TRACK_EFFECT_IDS for ids in draws)
    assert all(ids[1] in RANDOM_EFFECT_IDS for ids in draws if len(ids) == 2)
    assert {ids[0] for ids in draws} == set(ALONG_TRACK_EFFECT_IDS)
    assert 70 <= sum(len(ids) == 2 for ids in draws) <= 130  # one beside it in half the sets
    # Naming the default library draws what no library drew before.
    plain, named = np.random.default_rng(9), np.random.default_rng(9)
    assert [random_requests(plain) for _ in range(50)] == [random_requests(named, "default") for _ in range(50)]
    with pytest.raises(ValueError, match="'on_the_line'.*default, along_track"):
        random_requests(rng, "on_the_line")


def test_synth_records_the_library_its_effects_were_drawn_from(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        key = synthesize(tmp_path / "set", 2, seed=3, random_effects=True, random_library="along_track").key
    assert key["random_library"] == "along_track"
    assert key["effects"][0]["id"] in ALONG_TRACK_EFFECT_IDS
    with pytest.raises(ValueError, match="'along_track' given without random effects"):
        synthesize(tmp_path / "other", 2, seed=3, random_library="along_track")


def _synth(tmp_path_factory, name: str, effects, n: int, seed: int) -> Path:
    folder = tmp_path_factory.mktemp(name) / "set"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        synthesize(folder, n, seed=seed, effects=effects)
    return folder


@pytest.fixture(scope="module")
def section_set(tmp_path_factory):
    return _synth(tmp_path_factory, "section", [EffectRequest("gradient_section", SECTION)], 6, 1)


def _position_step(folder: Path):
    replays = Diagnoser(read_dataset(folder).recordings).unmodified_fit().replays
    traces = [residual_trace(replayed) for replayed in replays]
    return find_position_step(traces, DiagnosisRules().position_step_bin_m, TRAIN_LENGTH_M)


def test_the_residual_along_position_locates_the_section(section_set):
    """The step's edges lie half a train length beyond the section's ends (the ramp's middle), to
    within two bins; its size is most of the gradient (each recording's friction factor absorbs
    a share of it)."""
    step = _position_step(section_set)
    bin_m = DiagnosisRules().position_step_bin_m
    assert step.start_m == pytest.approx(SECTION["section_start_m"] + TRAIN_LENGTH_M / 2, abs=2 * bin_m)
    end = SECTION["section_start_m"] + SECTION["section_length_m"] + TRAIN_LENGTH_M / 2
    assert step.end_m == pytest.approx(end, abs=2 * bin_m)
    assert 0.5 * SECTION["section_gradient_permil"] < step.gradient_permil < 1.1 * SECTION["section_gradient_permil"]
    assert step.explained_share > DiagnosisRules().position_step_min_share
    start, length = step.stretch().section(TRAIN_LENGTH_M)
    assert start == pytest.approx(step.start_m - TRAIN_LENGTH_M / 2)
    assert length == pytest.approx(step.end_m - step.start_m)
    evidence = Evidence(1.0, 100.0, np.ones(4), VEHICLE.running_resistance, stretches=(step.stretch(),))
    (point,) = GradientSection.screening_points(evidence)
    np.testing.assert_allclose(point, [start, length, step.gradient_permil])


def test_an_effect_free_set_shows_no_step_along_position(tmp_path_factory):
    """Without a force on part of the line the best stretch explains noise only: below the share
    at which the diagnosis screens a section (fixed before this test: 0.05)."""
    step = _position_step(_synth(tmp_path_factory, "free", [], 6, 2))
    assert step is not None and step.explained_share < DiagnosisRules().position_step_min_share


def test_the_diagnosis_names_a_section_that_begins_part_way_along_the_line(section_set, tmp_path, naming_rules):
    """The failure class of issue 18: a gradient that begins part-way went unnamed. Now the step
    along position is screened as a section, fitted, and selected; the fitted section lies where
    the truth does (thresholds fixed before the run: ends within 40 m, gradient within 15 %)."""
    diagnosis = diagnose(section_set, top_singles=2, pairs_from=0, rules=naming_rules)
    report = diagnosis.report
    assert report["selected"] == ["gradient_section"], report["summary"]
    fitted = report["parameters"]
    assert fitted["section_start_m"] == pytest.approx(SECTION["section_start_m"], abs=40.0)
    end = SECTION["section_start_m"] + SECTION["section_length_m"]
    assert fitted["section_start_m"] + fitted["section_length_m"] == pytest.approx(end, abs=40.0)
    assert fitted["section_gradient_permil"] == pytest.approx(SECTION["section_gradient_permil"], rel=0.15)
    assert report["position_step"]["gradient_permil"] > 0
    # The Markdown report says where the step along position lies.
    markdown = write_report(diagnosis, tmp_path / "report", "section").read_text()
    start = report["position_step"]["start_m"]
    assert f"Step of the residual deceleration along position (while braking): {start:g} to" in markdown
    # ...and the selected section's residual RMS per channel, fitted and held out, against the unmodified model's.
    chosen = next(c for c in report["candidates"] if c["effects"] == report["selected"])
    speed_row = next(line for line in markdown.splitlines() if line.startswith("| speed_mps |"))
    assert f"| {chosen['rms_after']['speed_mps']:g} | {chosen['heldout_rms_after']['speed_mps']:g} |" in speed_row


def test_the_markdown_report_lists_what_pointed_the_search():
    """The step along position, each friction level's shared shift and the fallback's tries, from
    the report's keys as ``diagnose`` writes them."""
    report = {
        "position_step": {
            "start_m": 310.0,
            "end_m": 720.0,
            "decel_step_mps2": 0.061,
            "gradient_permil": 6.217,
            "explained_share": 0.4327,
            "recordings": 8,
        },
        "candidates": [
            {"effects": ["gradient"]},
            {
                "effects": ["friction_level"],
                "friction_level_shift": {"level": 1.05, "scatter": 0.03, "standard_error": 0.011, "z": 4.6},
            },
        ],
        "fallback_screening": {
            "description": {"axis": "speed", "form": "quadratic", "explained_share": 0.4},
            "signatures": [
                {"signature": "force_quadratic_in_speed", "effect": "running_resistance", "verdict": "selected"}
            ],
        },
    }
    lines = found_lines(report)
    assert lines[0].startswith("- Step of the residual deceleration along position (while braking): 310 to 720 m")
    assert "43.3% of the residual's variance, 8 recordings on it" in lines[0]
    assert lines[1] == (
        "- Friction level in friction_level: a shared shift of the recordings' friction factors to 1.05 "
        "(their scatter 0.03, standard error 0.011, z = 4.6)."
    )
    assert lines[3] == "  - force_quadratic_in_speed -> running_resistance: selected"
    assert found_lines({"candidates": [], "position_step": None, "fallback_screening": None}) == []
    # Recordings placed on the line: the positions count from its origin.
    placed = found_lines({**report, "line_origin_m": 12000.0})
    assert placed[0].startswith("- Positions along the line (the step below, the start of a section or stretch) count ")
    assert "from 12000 m, the lowest line position the recordings reach" in placed[0]
    assert placed[1].startswith("- Step of the residual deceleration along position (while braking): 310 to 720 m al")
    # A profile of two sections: the second step, found in what the first leaves, is shown too.
    second = {**report["position_step"], "start_m": 760.0, "end_m": 980.0}
    two = found_lines({**report, "second_position_step": second})
    assert two[1].startswith("- Second step of the residual deceleration along position (while braking): 760 to 980 m")
