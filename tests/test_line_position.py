"""Recordings placed on the line (issue 18, item 3: effects that live along the track, on
recordings as they come off a train, each stop beginning at its own place): the metadata field
``line_position_m``, the effects on part of the line placed by it, ``brakegym synth
--line-spread-m``, and the step along position located in metres along the line."""

from __future__ import annotations

import dataclasses
import json
import math
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from brakegym import config as cfg
from brakegym.diagnosis.inputs import beyond_the_search_note, line_reach_m, on_set_line
from brakegym.diagnosis.locate import residual_trace
from brakegym.diagnosis.pipeline import Diagnoser, located_start_max_m
from brakegym.diagnosis.position_steps import find_position_step
from brakegym.diagnosis.rules import DiagnosisRules
from brakegym.effects import TRAIN_LENGTH_M, make_effect
from brakegym.recordings import RecordingError, read_dataset, read_recording
from brakegym.recordings.synth import EffectRequest, synthesize

REPO = Path(__file__).resolve().parent.parent
PATCH = {"patch_start_m": 500.0, "patch_length_m": 300.0, "patch_adhesion": 0.07}

pytestmark = pytest.mark.filterwarnings("ignore")


@pytest.fixture(autouse=True)
def checkout_configs(monkeypatch):
    """This checkout's configs on the search path (an installed brakegym may ship others)."""
    monkeypatch.setenv(cfg.CONFIG_PATH_ENV, str(REPO / "configs"))


def _write(folder: Path, stem: str, line_position) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    time = np.arange(6) * 0.1
    data = {"time_s": time, "speed_mps": 30.0 - time}
    for axle in range(1, 9):
        data[f"p_c_bar_{axle}"] = np.full(6, 3.3)
    pd.DataFrame(data).to_csv(folder / f"{stem}.csv", index=False)
    metadata = {
        "vehicle": "emu_8axle",
        "load": "empty",
        "brake_mode": "emergency",
        "actuation": "EP",
        "ambient_C": 20.0,
    }
    if line_position is not None:
        metadata["line_position_m"] = line_position
    (folder / f"{stem}.json").write_text(json.dumps(metadata))
    return folder / f"{stem}.csv"


@pytest.mark.parametrize("value", ["12 km", math.nan, math.inf])
def test_a_line_position_that_is_no_finite_number_is_refused_naming_the_field(tmp_path, value):
    path = _write(tmp_path, "r", value)
    with pytest.raises(RecordingError) as info:
        read_recording(path)
    (problem,) = info.value.problems
    assert problem.field == "line_position_m" and problem.file == str(path.with_suffix(".json"))
    assert "field 'line_position_m'" in str(info.value)


def test_a_set_is_placed_on_the_line_from_its_lowest_line_position(tmp_path):
    recordings = [read_recording(_write(tmp_path, f"r{i}", x)) for i, x in enumerate((12_250.0, 12_000.0, 12_900.5))]
    placed, origin = on_set_line(recordings)
    assert origin == 12_000.0
    assert [r.metadata.line_position_m for r in placed] == [250.0, 0.0, 900.5]
    assert [r.metadata.line_position_m for r in recordings] == [12_250.0, 12_000.0, 12_900.5]  # not changed
    unplaced = [read_recording(_write(tmp_path / "none", f"r{i}", None)) for i in range(2)]
    assert on_set_line(unplaced) == (unplaced, None)


def test_a_set_where_only_some_recordings_are_placed_on_the_line_is_refused_naming_the_others(tmp_path):
    recordings = [read_recording(_write(tmp_path, stem, x)) for stem, x in (("a", 100.0), ("b", None), ("c", None))]
    named = r"'line_position_m' is given for 1 of 3 recordings but not for \S*b\.csv, \S*c\.csv"
    with pytest.raises(ValueError, match=named):
        on_set_line(recordings)
    with pytest.raises(ValueError, match="line_position_m"):
        Diagnoser(recordings)


@pytest.mark.parametrize(
    "effect_id, parameters",
    [
        ("adhesion_section", PATCH),
        ("gradient_section", {"section_start_m": 500.0, "section_length_m": 300.0, "section_gradient_permil": -9.0}),
    ],
)
def test_an_effect_on_part_of_the_line_acts_where_the_run_meets_it(simulate_one_stop, effect_id, parameters):
    """Invariant: a run that begins 350 m along the line meets a stretch at 500 m of line as a run
    that begins at 0 meets it at 150 m: the same motion, to rounding (the stop takes some 270 m)."""
    start_key = next(name for name in parameters if name.endswith("_start_m"))
    moved = {**parameters, start_key: parameters[start_key] - 350.0}
    model, on_line = simulate_one_stop([make_effect(effect_id, **parameters)], line_position_at_start_m=350.0)
    _, from_zero = simulate_one_stop([make_effect(effect_id, **moved)])
    _, free = simulate_one_stop()
    np.testing.assert_allclose(on_line.speed_mps, from_zero.speed_mps, rtol=0, atol=1e-9)
    assert on_line.stop_time_s[0] != pytest.approx(free.stop_time_s[0], rel=1e-3)  # the stretch acts
    np.testing.assert_allclose(model.line_position_at_start_m, [350.0])


@pytest.mark.parametrize(
    "effect_id, parameters, mirrored",
    [
        ("adhesion_section", PATCH, {}),
        (
            "gradient_section",
            {"section_start_m": 500.0, "section_length_m": 300.0, "section_gradient_permil": 9.0},
            {"section_gradient_permil": -9.0},  # run the other way, the rise is a fall
        ),
    ],
)
def test_a_run_towards_falling_line_positions_meets_a_stretch_from_its_far_end(
    simulate_one_stop, effect_id, parameters, mirrored
):
    """Invariant: a run that begins 1000 m along the line and runs back meets a stretch from 500
    to 800 m of line after 200 m, as a run from 0 meets one from 200 to 500 m (a section's
    gradient then with the other sign): the same motion, to rounding."""
    start_key = next(name for name in parameters if name.endswith("_start_m"))
    moved = {**parameters, **mirrored, start_key: 1000.0 - 800.0}
    _, back = simulate_one_stop(
        [make_effect(effect_id, **parameters)], line_position_at_start_m=1000.0, line_direction_sign=-1.0
    )
    _, from_zero = simulate_one_stop([make_effect(effect_id, **moved)])
    _, free = simulate_one_stop()
    np.testing.assert_allclose(back.speed_mps, from_zero.speed_mps, rtol=0, atol=1e-9)
    assert back.stop_time_s[0] != pytest.approx(free.stop_time_s[0], rel=1e-3)


def test_a_direction_without_a_line_position_is_refused(tmp_path):
    path = _write(tmp_path, "r", None)
    metadata = json.loads(path.with_suffix(".json").read_text())
    path.with_suffix(".json").write_text(json.dumps({**metadata, "line_direction": "decreasing"}))
    with pytest.raises(RecordingError, match="'line_direction' = 'decreasing' needs 'line_position_m'"):
        read_recording(path)
    path.with_suffix(".json").write_text(json.dumps({**metadata, "line_position_m": 5.0, "line_direction": "up"}))
    with pytest.raises(RecordingError) as info:
        read_recording(path)
    assert [p.field for p in info.value.problems] == ["line_direction"]


@pytest.fixture(scope="module")
def spread_set(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("spread") / "set"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        synthesize(folder, 8, seed=3, effects=[EffectRequest("adhesion_section", PATCH)], line_spread_m=400.0)
    return folder


def test_synth_places_each_application_on_the_line_and_keeps_the_rest_of_the_set(spread_set, tmp_path):
    """Each application begins at its own place in 0..400 m, written into its metadata and the
    key; the set's other draws (campaign, scatter, noise) are those of the same seed without it."""
    key = json.loads((spread_set.parent / "set_key.json").read_text())
    positions = [a["line_position_m"] for a in key["applications"]]
    assert all(0.0 <= x <= 400.0 for x in positions) and len(set(positions)) == len(positions)
    recordings = read_dataset(spread_set).recordings
    assert [r.metadata.line_position_m for r in recordings] == positions
    # Without a located effect the recordings' samples do not depend on where the runs begin.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        synthesize(tmp_path / "a", 3, seed=5, line_spread_m=900.0)
        synthesize(tmp_path / "b", 3, seed=5)
    for stem in ("rec_001", "rec_002", "rec_003"):
        assert (tmp_path / "a" / f"{stem}.csv").read_bytes() == (tmp_path / "b" / f"{stem}.csv").read_bytes()
        placed = json.loads((tmp_path / "a" / f"{stem}.json").read_text())
        assert 0.0 <= placed.pop("line_position_m") <= 900.0
        assert placed == json.loads((tmp_path / "b" / f"{stem}.json").read_text())
    with pytest.raises(ValueError, match="line spread -1.0 m"):
        synthesize(tmp_path / "c", 2, seed=1, line_spread_m=-1.0)


def test_the_step_along_position_is_located_in_metres_along_the_line(spread_set):
    """The stops begin up to 400 m apart; the step of the residual lies where the stretch is on
    the line (its edges half a train length beyond the stretch's ends, counted from the set's
    origin), to within two bins: in each run's own odometry it would be smeared over 400 m."""
    diagnoser = Diagnoser(read_dataset(spread_set).recordings)
    origin = diagnoser.line_origin_m
    assert origin == min(r.metadata.line_position_m for r in read_dataset(spread_set).recordings)
    traces = [residual_trace(replayed) for replayed in diagnoser.unmodified_fit().replays]
    rules = DiagnosisRules()
    step = find_position_step(traces, rules.position_step_bin_m, TRAIN_LENGTH_M)
    start = PATCH["patch_start_m"] - origin
    assert step.start_m == pytest.approx(start + TRAIN_LENGTH_M / 2, abs=2 * rules.position_step_bin_m)
    end = start + PATCH["patch_length_m"] + TRAIN_LENGTH_M / 2
    assert step.end_m == pytest.approx(end, abs=2 * rules.position_step_bin_m)
    assert step.decel_step_mps2 < 0 and step.explained_share > rules.position_step_min_share


def test_stops_run_both_ways_locate_the_stretch_at_one_place_on_the_line(spread_set):
    """The spread set's stops 2, 4, 6 and 8 read on a line numbered the other way: each then
    begins at 1300 m less its place and runs towards falling positions, and the stretch, from 500
    to 800 m, lies at 1300 - 800 to 1300 - 500 m: the same place. Run back, a stop's step edges
    lie half a train length before the stretch's ends instead of beyond them, so the step lies
    within that half length and two bins of the stretch."""
    recordings = read_dataset(spread_set).recordings
    both_ways = [
        r
        if index % 2 == 0
        else dataclasses.replace(
            r,
            metadata=r.metadata.model_copy(
                update={"line_position_m": 1300.0 - r.metadata.line_position_m, "line_direction": "decreasing"}
            ),
        )
        for index, r in enumerate(recordings)
    ]
    reached = [r.metadata.on_line_m(np.array([0.0, 300.0])) for r in both_ways[1::2]]
    assert all(x[1] < x[0] for x in reached)
    _assert_step_at_the_stretch(both_ways)


def _assert_step_at_the_stretch(recordings) -> None:
    """The step of the unmodified model's residual along position lies at PATCH's stretch on the
    line (counted from the set's origin), to within half a train length and two bins: run back,
    a stop's step edges lie half a train length before the stretch's ends instead of beyond them."""
    diagnoser = Diagnoser(recordings)
    traces = [residual_trace(replayed) for replayed in diagnoser.unmodified_fit().replays]
    rules = DiagnosisRules()
    step = find_position_step(traces, rules.position_step_bin_m, TRAIN_LENGTH_M)
    origin = diagnoser.line_origin_m
    tolerance = TRAIN_LENGTH_M / 2 + 2 * rules.position_step_bin_m
    assert step.start_m + origin == pytest.approx(PATCH["patch_start_m"], abs=tolerance)
    assert step.end_m + origin == pytest.approx(PATCH["patch_start_m"] + PATCH["patch_length_m"], abs=tolerance)
    assert step.decel_step_mps2 < 0 and step.explained_share > rules.position_step_min_share


@pytest.fixture(scope="module")
def both_ways_sets(tmp_path_factory) -> tuple[Path, Path]:
    """The same seed run both ways along the line, with the stretch of PATCH and without it."""
    root = tmp_path_factory.mktemp("both_ways")
    for name, effects in (("patch", [EffectRequest("adhesion_section", PATCH)]), ("free", [])):
        synthesize(root / name, 8, seed=4, effects=effects, line_spread_m=400.0, both_directions=True)
    return root / "patch", root / "free"


def test_synth_runs_stops_both_ways_and_each_meets_the_stretch_where_it_passes_it(both_ways_sets):
    """Runs both ways, a run back beginning 1000 m further along. Each run's speeds are those of
    the same seed without the stretch until the train is on the stretch (500-800 m on the line,
    from either end; a train length and a sample's travel of margin): a run that never comes that
    near it is unchanged throughout, and runs both ways that brake on it are changed there."""
    with_patch, without = read_dataset(both_ways_sets[0]).recordings, read_dataset(both_ways_sets[1]).recordings
    directions = [r.metadata.line_direction for r in with_patch]
    assert set(directions) == {"increasing", "decreasing"}
    for recording in with_patch:
        start = recording.metadata.line_position_m
        assert (1000.0 <= start <= 1400.0) if recording.metadata.line_direction == "decreasing" else 0 <= start <= 400
    margin = TRAIN_LENGTH_M + 10.0  # a sample's travel at the top speed is under 5 m
    low, high = PATCH["patch_start_m"] - margin, PATCH["patch_start_m"] + PATCH["patch_length_m"] + margin
    changed = {"increasing": 0, "decreasing": 0}
    for patched, free in zip(with_patch, without, strict=True):
        on_line = patched.metadata.on_line_m(patched.data["position_m"].to_numpy())
        speeds = patched.data["speed_mps"].to_numpy(), free.data["speed_mps"].to_numpy()
        common = min(len(speeds[0]), len(speeds[1]))
        differs = np.flatnonzero(speeds[0][:common] != speeds[1][:common])
        if on_line.max() < low or on_line.min() > high:
            assert differs.size == 0 and len(speeds[0]) == len(speeds[1]), patched.stem
        elif differs.size:
            assert low <= on_line[differs[0]] <= high, (patched.stem, on_line[differs[0]])
            changed[patched.metadata.line_direction] += 1
    assert min(changed.values()) >= 1, changed


def test_the_stretch_is_located_at_its_place_from_runs_both_ways(both_ways_sets):
    """On the set run both ways the step of the residual lies at the stretch on the line (counted
    from the set's origin), to within half a train length and two bins, as on the relabelled set."""
    _assert_step_at_the_stretch(read_dataset(both_ways_sets[0]).recordings)


def test_runs_both_ways_need_a_line_spread(tmp_path):
    with pytest.raises(ValueError, match="runs both ways along the line need a line spread"):
        synthesize(tmp_path / "set", 2, seed=1, both_directions=True)


def test_the_reach_along_the_line_is_reported_and_a_reach_beyond_the_search_is_said(spread_set):
    """The recordings' reach along the line from the origin: the farthest point a run towards
    growing positions covers (its first sample's place plus its odometry's last reading, within
    the odometer's noise). Where it passes the furthest start the located effects can take, the
    report says that part of the line was not searched."""
    recordings = read_dataset(spread_set).recordings
    diagnoser = Diagnoser(recordings)
    farthest = max(r.metadata.line_position_m + np.nanmax(r.data["position_m"]) for r in recordings)
    assert diagnoser.line_reach_m == pytest.approx(farthest - diagnoser.line_origin_m, abs=1.0)
    assert (
        line_reach_m(
            [
                dataclasses.replace(r, metadata=r.metadata.model_copy(update={"line_position_m": None}))
                for r in recordings
            ]
        )
        is None
    )
    bound = located_start_max_m()
    assert bound == 2500.0  # the start bounds of gradient_section, gradient_sections and adhesion_section
    assert beyond_the_search_note(diagnoser.line_reach_m, bound) is None
    note = beyond_the_search_note(4012.4, bound)
    assert "reach 4012 m along the line from its origin" in note and "start in 0-2500 m" in note
