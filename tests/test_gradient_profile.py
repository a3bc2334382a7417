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

from brakegym import config as cfg
from brakegym.cli import main
from brakegym.diagnosis import diagnose
from brakegym.effects.hooks import GradientProfileForce
from brakegym.recordings import GradientProfile, RecordingError, read_dataset, read_metadata
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


def test_a_declared_profile_is_not_named_as_an_effect(tmp_path):
    """With scatter and noise, the line's known gradients are in the model: the diagnosis selects
    nothing on an effect-free set on the graded line."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        folder = synthesize(tmp_path / "set", 5, seed=61, gradient_profile=PROFILE).folder
    report = diagnose(folder, top_singles=2, pairs_from=0).report
    assert report["selected"] == [], report["summary"]
