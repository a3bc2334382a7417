"""Recordings: the format's validation (file, line or column, value named), exact round trips,
and replay of recordings made by the simulator itself."""

import json
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import brakegym.recordings.replay as replay_module
from brakegym.effects import FrictionLevel, Gradient, make_effect
from brakegym.recordings import (
    Recording,
    RecordingError,
    RecordingMetadata,
    read_dataset,
    read_recording,
    write_recording,
)
from brakegym.recordings.measurement import first_order_lag
from brakegym.recordings.replay import compare, kinematic_consistency, replay, replay_batch, simulate_grid
from brakegym.recordings.synth import EffectRequest, synthesize

N_AXLES = 8


def _metadata(**changes):
    fields = dict(
        vehicle="emu_8axle",
        load="empty",
        brake_mode="emergency",
        actuation="EP",
        instrumented_disc=1,
        ambient_C=20.0,
        decel_source="accelerometer",
        pad_set="1",
    )
    fields.update(changes)
    return fields


def _frame(n=6):
    time = np.arange(n) * 0.1
    data = {"time_s": time, "speed_mps": 30.0 - time}
    for axle in range(1, N_AXLES + 1):
        data[f"p_c_bar_{axle}"] = np.full(n, 3.3)
    data["decel_mps2"] = np.full(n, 1.0)
    data["T_disc_C"] = 50.0 + time
    data["position_m"] = 30.0 * time
    return pd.DataFrame(data)


def _write_pair(folder: Path, stem="r", frame=None, metadata=None, csv_text=None):
    folder.mkdir(parents=True, exist_ok=True)
    if csv_text is None:
        (frame if frame is not None else _frame()).to_csv(folder / f"{stem}.csv", index=False)
    else:
        (folder / f"{stem}.csv").write_text(csv_text)
    if metadata is not False:
        (folder / f"{stem}.json").write_text(json.dumps(metadata or _metadata()))
    return folder / f"{stem}.csv"


def _csv_lines(frame=None):
    return (frame if frame is not None else _frame()).to_csv(index=False).splitlines()


# ------------------------------------------------------------------------------------------------
# Format


def test_round_trip_is_exact_with_blanks_and_extra_columns(tmp_path):
    frame = _frame(8)
    frame.loc[3, "T_disc_C"] = np.nan  # a missing sample
    frame.loc[5, "decel_mps2"] = np.nan
    frame["speed_mps"] = frame["speed_mps"] + 1e-13 * np.arange(8) + 0.1  # digits that must survive
    frame["axle_load_kN"] = np.linspace(70.1, 70.8, 8)  # extra numeric column
    frame["phase"] = ["coast"] * 3 + ["brake"] * 5  # extra text column
    recording = Recording("run_7", RecordingMetadata(**_metadata(notes="wet morning", initial_disc_C=48.5)), frame)
    csv_path, json_path = write_recording(recording, tmp_path)
    back = read_recording(csv_path)
    pd.testing.assert_frame_equal(back.data, recording.data, check_exact=True)
    assert back.metadata == recording.metadata
    assert list(back.data.columns) == list(frame.columns)
    assert np.isnan(back.data.loc[3, "T_disc_C"]) and len(back) == 8  # blank kept as NaN, row kept
    # Writing what was read gives the same bytes.
    write_recording(back, tmp_path / "again")
    assert (tmp_path / "again" / "run_7.csv").read_bytes() == csv_path.read_bytes()
    assert (tmp_path / "again" / "run_7.json").read_bytes() == json_path.read_bytes()


def test_inline_vehicle_object_is_validated(tmp_path):
    from brakegym import config as cfg

    vehicle = cfg.load("vehicles", "emu_8axle").model_dump()
    vehicle["name"] = "emu_custom"
    path = _write_pair(tmp_path, metadata=_metadata(vehicle=vehicle))
    assert read_recording(path).vehicle.name == "emu_custom"
    vehicle["bogies"] = 0
    _write_pair(tmp_path, metadata=_metadata(vehicle=vehicle))
    with pytest.raises(RecordingError, match=r"(?s)r\.json.*vehicle\.bogies' = 0"):
        read_recording(path)


@pytest.mark.parametrize(
    "edit, message",
    [
        (
            lambda lines: [lines[0].replace("speed_mps", "v")] + lines[1:],
            r"missing required column\(s\) \['speed_mps'\]",
        ),
        (
            lambda lines: lines[:4] + [lines[4].replace("3.3", "abc", 1)] + lines[5:],
            r"line 5, column 'p_c_bar_1': 'abc' is not a finite number",
        ),
        (
            lambda lines: lines[:3] + [lines[3].replace("3.3", "nan", 1)] + lines[4:],
            r"line 4, column 'p_c_bar_1': 'nan'",
        ),
        (
            lambda lines: lines[:3] + ["0.1" + lines[3][lines[3].index(",") :]] + lines[4:],
            r"line 4, column 'time_s' = 0\.1: time must be strictly increasing \(line 3",
        ),
        (
            lambda lines: lines[:2] + ["0.1,-0.5" + lines[2][lines[2].index(",", 4) :]] + lines[3:],
            r"line 3, column 'speed_mps' = -0\.5: speed must not be negative",
        ),
        (
            lambda lines: lines[:6] + [lines[6].replace("3.3", "10.5", 1)] + lines[7:],
            r"line 7, column 'p_c_bar_1' = 10\.5: pressure outside 0\.\.10 bar",
        ),
        (lambda lines: lines[:2] + [lines[2] + ",1"] + lines[3:], r"line 3 has 14 fields, the header has 13"),
        (lambda lines: lines[:3] + [""] + lines[3:], r"line 4 is empty between samples"),
        (lambda lines: lines[:2] + ["," + lines[2].split(",", 1)[1]] + lines[3:], r"line 3, column 'time_s' is blank"),
    ],
)
def test_bad_csv_is_refused_naming_file_line_and_value(tmp_path, edit, message):
    lines = edit(_csv_lines())
    path = _write_pair(tmp_path, csv_text="\n".join(lines) + "\n")
    with pytest.raises(RecordingError) as info:
        read_recording(path)
    assert str(path) in str(info.value)
    assert info.match(message)


@pytest.mark.parametrize("drop, add, shown", [("p_c_bar_8", None, "p_c_bar_7'"), (None, "p_c_bar_9", "p_c_bar_9'")])
def test_pressure_columns_must_match_the_axles(tmp_path, drop, add, shown):
    frame = _frame()
    if drop:
        frame = frame.drop(columns=[drop])
    if add:
        frame[add] = 1.0
    path = _write_pair(tmp_path, frame=frame)
    with pytest.raises(
        RecordingError, match=rf"pressure columns \[.*{shown}\] do not match vehicle 'emu_8axle' with 8 axles"
    ):
        read_recording(path)


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"vehicle": "tgv"}, r"field 'vehicle' = 'tgv': unknown vehicle; known: .*emu_8axle"),
        ({"load": "heavy"}, r"field 'load' = 'heavy': unknown load"),
        ({"brake_mode": "parking"}, r"field 'brake_mode' = 'parking'"),
        ({"decel_source": "gps"}, r"field 'decel_source' = 'gps'"),
        ({"instrumented_disc": 17}, r"field 'instrumented_disc' = 17: must lie in 1\.\.16"),
        ({"instrumented_disc": 0}, r"field 'instrumented_disc' = 0"),
        ({"actuation": "XX"}, r"field 'actuation' = 'XX': unknown actuation"),
        ({"initial_disc_c": 40.0}, r"field 'initial_disc_c' = 40\.0: Extra inputs are not permitted"),
        ({"mass_kg": 120000.0}, r"exactly one of 'load' and 'mass_kg'"),
        ({"ambient_C": 293.0}, r"field 'ambient_C' = 293\.0"),
    ],
)
def test_bad_metadata_is_refused_naming_field_and_value(tmp_path, changes, message):
    path = _write_pair(tmp_path, metadata=_metadata(**changes))
    with pytest.raises(RecordingError, match=message) as info:
        read_recording(path)
    assert str(path.with_suffix(".json")) in str(info.value)


def test_mass_instead_of_load_and_missing_metadata(tmp_path):
    meta = _metadata(mass_kg=130000.0)
    del meta["load"]
    path = _write_pair(tmp_path, metadata=meta)
    assert read_recording(path).mass_kg == 130000.0
    path = _write_pair(tmp_path / "b", metadata=False)
    with pytest.raises(RecordingError, match=r"r\.json: metadata file missing"):
        read_recording(path)


def test_channels_need_their_metadata(tmp_path):
    path = _write_pair(tmp_path, metadata=_metadata(decel_source=None))
    with pytest.raises(RecordingError, match=r"'decel_mps2' column but its metadata gives no 'decel_source'"):
        read_recording(path)


def test_dataset_reports_each_bad_recording_and_goes_on_when_asked(tmp_path):
    for stem in ("a", "c", "e"):
        _write_pair(tmp_path, stem=stem)
    lines = _csv_lines()
    _write_pair(tmp_path, stem="b", csv_text="\n".join(lines[:3] + [lines[3].replace("3.3", "x", 1)] + lines[4:]))
    _write_pair(tmp_path, stem="d", metadata=_metadata(load="heavy"))
    (tmp_path / "f.json").write_text(json.dumps(_metadata()))  # metadata without its time series
    (tmp_path / "README.txt").write_text("not a recording")
    with pytest.raises(RecordingError, match=r"b\.csv: line 4"):
        read_dataset(tmp_path)
    dataset = read_dataset(tmp_path, skip_bad=True)
    assert [r.stem for r in dataset] == ["a", "c", "e"]
    messages = [str(e) for e in dataset.errors]
    assert len(messages) == 3
    assert "b.csv: line 4, column 'p_c_bar_1': 'x'" in messages[0]
    assert "d.json" in messages[1] and "heavy" in messages[1]
    assert "f.json: metadata without its time series f.csv" in messages[2]


# ------------------------------------------------------------------------------------------------
# Replay on recordings made by the simulator itself


@pytest.fixture(scope="module")
def clean_set(tmp_path_factory):
    """Noise-free, scatter-free recordings with a gradient and a speed-sensor error concealed."""
    folder = tmp_path_factory.mktemp("clean") / "set"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = synthesize(
            folder,
            4,
            seed=3,
            noise_scale=0.0,
            scatter_setup="ds",
            effects=[
                EffectRequest("gradient", {"gradient_permil": 8.0}),
                EffectRequest("speed_sensor_scale", {"scale": 1.03}),
            ],
        )
    effects = [make_effect("gradient", gradient_permil=8.0), make_effect("speed_sensor_scale", scale=1.03)]
    return read_dataset(folder).recordings, effects, result.key


def test_replay_with_the_true_effects_leaves_no_residual(clean_set):
    recordings, effects, _ = clean_set
    comparisons = [compare(r) for r in replay_batch(recordings, effects)]
    for c in comparisons:
        # Residuals come only from the replay's 0.1 s step against the 0.05 s truth and from
        # the sensors' resolution: a tenth of the noise the synthetic sets carry.
        assert c.rms["speed_mps"] < 0.004
        assert c.rms["T_disc_C"] < 0.1
        assert c.rms["position_m"] < 0.1
        assert c.distance_rms["decel_mps2"] < 0.003
        assert abs(c.stop_distance_error_m) < 0.2
    nominal = [compare(r) for r in replay_batch(recordings)]
    assert min(c.rms["speed_mps"] for c in nominal) > 0.2  # the concealed effects are not small


def test_replay_one_by_one_equals_the_batch(clean_set):
    recordings, effects, _ = clean_set
    batch = replay_batch(recordings[:2], effects)
    single = replay(recordings[1], effects)
    pd.testing.assert_frame_equal(batch[1].simulated, single.simulated, check_exact=False, rtol=1e-12, atol=1e-12)


def test_replay_in_one_compiled_call_equals_the_step_loop(clean_set, monkeypatch):
    """A replay without state-dependent hooks runs its steps in one compiled call
    (``simulate_steps``); the step-by-step loop of ``simulate_grid`` gives the same numbers, bit
    for bit (a friction level per recording and a gradient are constant hooks)."""
    recordings, _, _ = clean_set
    effects = [Gradient(gradient_permil=-4.0), FrictionLevel(mu_scale=np.linspace(0.9, 1.1, len(recordings)))]
    fast = replay_batch(recordings, effects)
    loops = []

    def step_loop(model, pressure, step_s, n_steps):
        loops.append(n_steps)
        return simulate_grid(model, pressure, step_s, lambda sim: sim.step_index >= n_steps)

    monkeypatch.setattr(replay_module, "simulate_steps", step_loop)
    looped = replay_batch(recordings, effects)
    assert loops and loops[0] > 100
    for a, b in zip(fast, looped):
        assert a.channels.keys() == b.channels.keys()
        for name in a.channels:
            np.testing.assert_array_equal(a.channels[name], b.channels[name], err_msg=name)
        pd.testing.assert_frame_equal(a.states, b.states, check_exact=True)
        assert a.stop_time_s == b.stop_time_s or (np.isnan(a.stop_time_s) and np.isnan(b.stop_time_s))


def test_nuisance_initial_state_overrides(clean_set):
    recordings, effects, _ = clean_set
    recording = recordings[0]
    base = replay(recording, effects)
    faster = replay(
        recording, effects, initial_speed_mps=base.initial_speed_mps + 1.0, initial_disc_C=base.initial_disc_C + 30.0
    )
    assert faster.simulated["speed_mps"].iloc[0] == pytest.approx(1.03 * (base.initial_speed_mps + 1.0))
    assert faster.states["T_fric_C"].iloc[0] == pytest.approx(base.initial_disc_C + 30.0)
    # The default initial speed is the first speed sample seen through the scaled sensor.
    assert base.initial_speed_mps == pytest.approx(recording.speed_mps[0] / 1.03)


def test_kinematic_consistency_sees_the_gradient_and_not_the_wheel_error_in_odometry(clean_set):
    recordings, _, key = clean_set
    for recording in recordings:
        check = kinematic_consistency(recording)
        if key["decel_source"] == "accelerometer":
            # The speed sees g x gradient that the accelerometer does not; the speed is 3 % high.
            assert check.decel_offset_mps2 == pytest.approx(9.80665 * 8.0e-3 * 1.03, abs=2e-3)
            assert check.decel_gain == pytest.approx(1.03, abs=2e-3)
        else:
            assert check.decel_offset_mps2 == pytest.approx(0.0, abs=2e-3)
            assert check.decel_gain == pytest.approx(1.0, abs=2e-3)
        # Speed and odometry scale together: consistent with each other.
        assert check.position_gain == pytest.approx(1.0, abs=1e-3)
        assert check.speed_vs_decel_rms_mps < 0.01


def test_replay_needs_an_initial_disc_temperature(tmp_path):
    frame = _frame().drop(columns=["T_disc_C"])
    recording = Recording("r", RecordingMetadata(**_metadata()), frame)
    with pytest.raises(RecordingError, match="no initial disc temperature"):
        replay(recording)
    assert len(replay(recording, initial_disc_C=40.0).simulated) == len(frame)


def test_first_order_lag_is_exact_for_a_ramp():
    tau, slope = 4.0, 2.5
    coarse = np.linspace(0.0, 30.0, 7)
    fine = np.linspace(0.0, 30.0, 301)

    def exact(t):
        return slope * t - tau * slope * (1.0 - np.exp(-t / tau))

    np.testing.assert_allclose(first_order_lag(coarse, slope * coarse, tau), exact(coarse), rtol=0, atol=1e-12)
    np.testing.assert_allclose(first_order_lag(fine, slope * fine, tau), exact(fine), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(first_order_lag(coarse, slope * coarse, 0.0), slope * coarse)
