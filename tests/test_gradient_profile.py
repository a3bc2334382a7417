"""A line's gradient profile in the recording format (issue 18, item 3): validated on read, the
force of the section under the train in the replay and in ``brakegym synth``, invisible to the
accelerometer; a known profile is part of the model, not something for the diagnosis to name."""

from __future__ import annotations

import dataclasses
import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from brakegym import config as cfg
from brakegym.cli import main
from brakegym.diagnosis import diagnose
from brakegym.diagnosis.inputs import on_set_line
from brakegym.effects.hooks import GradientProfileForce
from brakegym.recordings import GradientProfile, LineGradientProfile, RecordingError, read_dataset, read_metadata
from brakegym.recordings.replay import compare, replay_batch
from brakegym.recordings.synth import synthesize
from brakegym.simulator import StageContext
from brakegym.units import STANDARD_GRAVITY_MPS2

REPO = Path(__file__).resolve().parent.parent
# Level for 150 m, then 10 permil downhill, then 5 permil uphill from 400 m.
PROFILE = GradientProfile(start_m=[0.0, 150.0, 400.0], gradient_permil=[0.0, -10.0, 5.0])


@pytest.fixture(autouse=True)
def checkout_configs(monkeypatch):
    """This checkout's configs on the search path (an installed brakegym may ship others)."""
    monkeypatch.setenv(cfg.CONFIG_PATH_ENV, str(REPO / "configs"))


def _metadata(**changes) -> dict:
    meta = {
        "vehicle": "emu_8axle",
        "load": "empty",
        "brake_mode": "service",
        "actuation": "EP",
        "ambient_C": 10.0,
    }
    meta.update(changes)
    return meta


START_NOT_ZERO = r"field 'gradient_profile\.start_m' = \[10\.0, 50\.0\]: the first section must start at 0 m"
STARTS_NOT_RISING = r"'gradient_profile\.start_m'.*must be finite and rise"
TOO_STEEP = r"'gradient_profile\.gradient_permil' = \[45\.0\]: gradients \[45\.0\] lie outside"


@pytest.mark.parametrize(
    "profile, message",
    [
        ({"start_m": [10.0, 50.0], "gradient_permil": [1.0, 2.0]}, START_NOT_ZERO),
        ({"start_m": [0.0, 50.0, 50.0], "gradient_permil": [1.0, 2.0, 3.0]}, STARTS_NOT_RISING),
        ({"start_m": [0.0], "gradient_permil": [45.0]}, TOO_STEEP),
        ({"start_m": [0.0, 50.0], "gradient_permil": [1.0]}, r"2 section starts for 1 gradients"),
        ({"start_m": [0.0], "gradient_permil": [1.0], "end_m": 9.0}, r"'gradient_profile\.end_m' = 9\.0: Extra inputs"),
    ],
)
def test_a_bad_profile_is_refused_naming_the_file_field_and_value(tmp_path, profile, message):
    path = tmp_path / "r.json"
    path.write_text(json.dumps(_metadata(gradient_profile=profile)))
    with pytest.raises(RecordingError, match=message) as info:
        read_metadata(path)
    assert str(path) in str(info.value)


def test_the_profile_force_is_the_weight_times_the_gradient_of_the_section_under_the_train():
    """m g p / 1000 of the section the train's position lies in, per train (each its own
    profile, padded with +inf starts)."""
    starts = np.array([[0.0, 150.0, 400.0], [0.0, 100.0, np.inf]])
    gradients = np.array([[0.0, -10.0, 5.0], [3.0, 0.0, 0.0]])
    weight = np.array([1.0e6, 2.0e6])
    line = GradientProfileForce(weight, starts, gradients)
    context = StageContext(0.0, np.ones(2), np.array([200.0, 50.0]), weight / STANDARD_GRAVITY_MPS2, *([None] * 4))
    np.testing.assert_allclose(line.force_N(context), [1.0e6 * -0.010, 2.0e6 * 0.003])
    np.testing.assert_allclose(line.grade_at(np.array([0.0, 149.9, 150.0, 1e4]), 0), [0.0, 0.0, -0.010, 0.005])


@pytest.fixture(scope="module")
def graded_set(tmp_path_factory):
    """Noise-free, scatter-free recordings on the graded line, the profile declared."""
    folder = tmp_path_factory.mktemp("graded") / "set"
    with warnings.catch_warnings(), cfg.config_path(REPO / "configs"):
        warnings.simplefilter("ignore")
        result = synthesize(folder, 4, seed=1, noise_scale=0.0, scatter_setup="ds", gradient_profile=PROFILE)
        return read_dataset(folder).recordings, result.key


def test_synth_declares_the_profile_and_the_replay_with_it_leaves_no_residual(graded_set):
    """The replay puts the declared profile into the model: the recordings are reproduced to the
    replay's step and the sensors' resolution, the accelerometer included (it does not see the
    slope); without the profile the speeds and the accelerometer are far off."""
    recordings, key = graded_set
    assert key["gradient_profile"] == {**PROFILE.model_dump(), "declared": True}
    assert all(r.metadata.gradient_profile == PROFILE for r in recordings)
    assert recordings[0].metadata.decel_source == "accelerometer"
    for c in (compare(r) for r in replay_batch(recordings)):
        # The force steps where a section begins, and the replay's 0.1 s step crosses it mid-step:
        # about half a step times the step in deceleration (0.05 s x 0.1 m/s^2) at each crossing,
        # a sixth of the 0.03 m/s speed noise the synthetic sets carry.
        assert c.rms["speed_mps"] < 0.01
        assert c.distance_rms["decel_mps2"] < 0.003
        assert abs(c.stop_distance_error_m) < 0.2
    level = [
        dataclasses.replace(r, metadata=r.metadata.model_copy(update={"gradient_profile": None})) for r in recordings
    ]
    without = [compare(r) for r in replay_batch(level)]
    assert min(c.rms["speed_mps"] for c in without) > 0.1
    # The accelerometer reads the slope's gravity component the replay no longer subtracts.
    assert max(c.distance_rms["decel_mps2"] for c in without) > 0.03


def test_a_concealed_profile_is_in_the_key_only(tmp_path):
    result = synthesize(tmp_path / "set", 2, seed=4, gradient_profile=PROFILE, declare_gradient_profile=False)
    assert result.key["gradient_profile"]["declared"] is False
    assert all(r.metadata.gradient_profile is None for r in read_dataset(result.folder).recordings)
    plain = synthesize(tmp_path / "plain", 2, seed=4)
    assert "gradient_profile" not in plain.key
    assert "gradient_profile" not in (tmp_path / "plain" / f"{plain.recordings[0].stem}.json").read_text()


def test_the_command_line_takes_a_profile_and_refuses_a_bad_one(tmp_path, capsys):
    assert (
        main(
            [
                "synth",
                str(tmp_path / "set"),
                "--recordings",
                "1",
                "--seed",
                "4",
                "--gradient-profile",
                "0:0,150:-10,400:5",
            ]
        )
        == 0
    )
    (recording,) = read_dataset(tmp_path / "set").recordings
    assert recording.metadata.gradient_profile == PROFILE
    with pytest.raises(SystemExit) as exit_info:
        main(["synth", str(tmp_path / "bad"), "--recordings", "1", "--seed", "4", "--gradient-profile", "0:0,150"])
    assert exit_info.value.code == 2
    assert "'150' is not START_M:PERMIL" in capsys.readouterr().err


# An adhesion limit held at no effect sits at infinite adhesion: no arithmetic may meet it.
@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_a_declared_profile_is_not_named_as_an_effect(tmp_path, naming_rules):
    """With scatter and noise, the line's known gradients are in the model: the diagnosis selects
    nothing on an effect-free set on the graded line."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        folder = synthesize(tmp_path / "set", 5, seed=61, gradient_profile=PROFILE).folder
    report = diagnose(folder, top_singles=2, pairs_from=0, rules=naming_rules).report
    assert report["selected"] == [], report["summary"]


# --- a known profile in positions along the line ------------------------------------------------

LINE = LineGradientProfile(start_m=[0.0, 200.0, 500.0, 700.0], gradient_permil=[0.0, 8.0, 0.0, -9.0])


def test_a_run_over_a_line_profile_meets_its_sections_from_where_it_begins():
    """A run from 100 m towards growing positions meets the sections 100 m early; a run back from
    900 m meets them in reverse, each gradient with the other sign (a rise is a fall run back)."""
    ahead = LINE.along_run(100.0, +1.0)
    assert ahead.start_m == [0.0, 100.0, 400.0, 600.0] and ahead.gradient_permil == [0.0, 8.0, 0.0, -9.0]
    back = LINE.along_run(900.0, -1.0)
    assert back.start_m == [0.0, 200.0, 400.0, 700.0] and back.gradient_permil == [9.0, 0.0, -8.0, 0.0]
    # Beginning on a section's start: run ahead it is on that section, run back on the one before.
    assert LINE.along_run(500.0, +1.0).gradient_permil[0] == 0.0
    assert LINE.along_run(500.0, -1.0).gradient_permil[0] == -8.0


def _line_grade(profile: LineGradientProfile, x: float) -> float:
    section = max(int(np.searchsorted(profile.start_m, x, side="right")) - 1, 0)
    return profile.gradient_permil[section]


@settings(max_examples=200, deadline=None)
@given(
    starts=st.lists(st.integers(-2000, 3000), min_size=1, max_size=6, unique=True),
    gradients=st.lists(st.integers(-40, 40), min_size=6, max_size=6),
    begin=st.floats(-2500.0, 3500.0),
    back=st.booleans(),
    travelled=st.floats(0.0, 3000.0),
)
def test_the_run_profile_is_the_line_profile_where_the_run_is(starts, gradients, begin, back, travelled):
    """Invariant: the gradient under the run after ``travelled`` metres is the line's gradient where
    the run then is, times the direction (the first section also holds before its start)."""
    line = LineGradientProfile(start_m=[float(x) for x in sorted(starts)], gradient_permil=gradients[: len(starts)])
    sign = -1.0 if back else 1.0
    x = begin + sign * travelled
    assume(min(abs(x - a) for a in line.start_m) > 1e-6 and min(abs(begin - a) for a in line.start_m) > 1e-6)
    run = line.along_run(begin, sign)
    assert run.start_m[0] == 0.0
    section = int(np.searchsorted(run.start_m, travelled, side="right")) - 1
    assert run.gradient_permil[section] == sign * _line_grade(line, x)


def test_a_line_profile_needs_a_line_position_and_stands_alone(tmp_path):
    needs_position = _metadata(line_gradient_profile=LINE.model_dump())
    path = tmp_path / "rec.json"
    path.write_text(json.dumps(needs_position))
    with pytest.raises(RecordingError, match="'line_gradient_profile' needs 'line_position_m'"):
        read_metadata(path)
    path.write_text(json.dumps({**needs_position, "line_position_m": 50.0, "gradient_profile": PROFILE.model_dump()}))
    with pytest.raises(RecordingError, match="give the line's known gradient once"):
        read_metadata(path)
    path.write_text(json.dumps({**needs_position, "line_position_m": 150.0, "line_direction": "decreasing"}))
    assert read_metadata(path).run_gradient_profile == LINE.along_run(150.0, -1.0)


def test_synth_runs_a_spread_set_over_the_line_profile_and_the_replay_reproduces_it(tmp_path):
    """With a line spread the profile lies along the line: each recording carries it as
    ``line_gradient_profile`` and runs over its own part of it, both ways; the replay reproduces
    the noise-free recordings as well as with a profile from the first sample (and as exactly as
    the equivalent ``gradient_profile`` written into each recording)."""
    folder = tmp_path / "set"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        synthesize(
            folder,
            6,
            seed=2,
            noise_scale=0.0,
            scatter_setup="ds",
            gradient_profile=GradientProfile(**LINE.model_dump()),
            line_spread_m=600.0,
            both_directions=True,
        )
    recordings = read_dataset(folder).recordings
    key = json.loads((tmp_path / "set_key.json").read_text())
    assert key["gradient_profile"] == {**LINE.model_dump(), "declared": True, "in_line_positions": True}
    assert {r.metadata.line_direction for r in recordings} == {"increasing", "decreasing"}
    assert all(r.metadata.line_gradient_profile == LINE and r.metadata.gradient_profile is None for r in recordings)
    for c in (compare(r) for r in replay_batch(recordings)):
        assert c.rms["speed_mps"] < 0.01
        assert c.distance_rms["decel_mps2"] < 0.003
    own = [
        dataclasses.replace(
            r,
            metadata=r.metadata.model_copy(
                update={"line_gradient_profile": None, "gradient_profile": r.metadata.run_gradient_profile}
            ),
        )
        for r in recordings
    ]
    for placed, first_sample in zip(replay_batch(recordings), replay_batch(own), strict=True):
        assert np.array_equal(placed.channels["speed_mps"], first_sample.channels["speed_mps"])
    level = [
        dataclasses.replace(r, metadata=r.metadata.model_copy(update={"line_gradient_profile": None}))
        for r in recordings
    ]
    assert min(compare(r).rms["speed_mps"] for r in replay_batch(level)) > 0.1
    # The diagnosis counts line positions from the set's origin: the profile's starts move with
    # them, so each run still meets the same sections.
    placed, origin = on_set_line(recordings)
    assert origin != 0.0  # the positions move
    for rebased, original in zip(placed, recordings, strict=True):
        on_run, expected = rebased.metadata.run_gradient_profile, original.metadata.run_gradient_profile
        assert on_run.start_m == pytest.approx(expected.start_m, abs=1e-9)
        assert on_run.gradient_permil == expected.gradient_permil
    assert placed[0].metadata.line_gradient_profile.start_m[0] == -origin
