"""Bad recordings: every problem of a recording and every bad recording of a folder is reported
(file, line or column or field, value), and the commands that read a folder go on with the good
ones when asked (``--skip-bad-recordings``), saying which were left out."""

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from brakegym.cli import main
from brakegym.recordings import (
    DatasetError,
    Recording,
    RecordingError,
    RecordingMetadata,
    read_dataset,
    read_recording,
)

METADATA = dict(
    vehicle="emu_8axle",
    load="empty",
    brake_mode="emergency",
    actuation="EP",
    instrumented_disc=1,
    ambient_C=20.0,
    decel_source="accelerometer",
)


def samples(n=6):
    """A valid time series of emu_8axle (8 axles): sample k is on CSV line k + 2."""
    time = np.arange(n) * 0.1
    data = {"time_s": time, "speed_mps": 30.0 - time}
    for axle in range(1, 9):
        data[f"p_c_bar_{axle}"] = np.full(n, 3.3)
    data["decel_mps2"] = np.full(n, 1.0)
    data["T_disc_C"] = 50.0 + time
    return pd.DataFrame(data)


def write(folder: Path, stem: str, frame=None, metadata=None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (frame if frame is not None else samples()).to_csv(folder / f"{stem}.csv", index=False)
    (folder / f"{stem}.json").write_text(json.dumps(METADATA if metadata is None else metadata))
    return folder / f"{stem}.csv"


def where(problem):
    return problem.line, problem.column, problem.field, problem.value


# ------------------------------------------------------------------------------------------------
# One recording


def test_a_recording_with_three_faults_reports_all_three(tmp_path):
    frame = samples()
    frame.loc[2, "time_s"] = 0.1  # line 4: as early as line 3
    frame.loc[3, "speed_mps"] = -0.5  # line 5
    frame.loc[4, "p_c_bar_6"] = 10.5  # line 6
    path = write(tmp_path, "r", frame)
    with pytest.raises(RecordingError) as info:
        read_recording(path)
    message = str(info.value)
    assert message.startswith(f"{path}: 3 problems")
    assert "line 4, column 'time_s' = 0.1: time must be strictly increasing (line 3 has 0.1)" in message
    assert "line 5, column 'speed_mps' = -0.5: speed must not be negative" in message
    assert "line 6, column 'p_c_bar_6' = 10.5: pressure outside 0..10 bar" in message
    assert [where(p) for p in info.value.problems] == [
        (4, "time_s", None, 0.1),
        (5, "speed_mps", None, -0.5),
        (6, "p_c_bar_6", None, 10.5),
    ]
    assert {p.file for p in info.value.problems} == {str(path)} and info.value.file == str(path)


def test_faults_in_both_files_are_reported_together(tmp_path):
    frame = samples().drop(columns=["speed_mps"])
    frame["time_s"] = frame["time_s"].astype(object)
    frame.loc[1, "time_s"] = "0.1s"  # line 3: not a number, reported once (not also as blank)
    path = write(tmp_path, "r", frame, {**METADATA, "load": "heavy", "actuation": "XX", "brake_mode": "parking"})
    with pytest.raises(RecordingError) as info:
        read_recording(path)
    problems = info.value.problems
    assert [p.description.split(";")[0] for p in problems[:2]] == [
        f"missing required column(s) {['speed_mps']}",
        "line 3, column 'time_s': '0.1s' is not a finite number",
    ]
    json_path = str(path.with_suffix(".json"))
    assert [(p.file, p.field, p.value) for p in problems[2:]] == [
        (json_path, "load", "heavy"),
        (json_path, "brake_mode", "parking"),
        (json_path, "actuation", "XX"),
    ]
    assert f"{json_path}: field 'actuation' = 'XX': unknown actuation" in str(info.value)
    # A missing field is named as missing; the vehicle's own checks wait for a valid vehicle.
    without_ambient = {k: v for k, v in METADATA.items() if k != "ambient_C"}
    write(tmp_path, "r", samples(), {**without_ambient, "vehicle": "tgv", "load": "heavy"})
    with pytest.raises(RecordingError) as info:
        read_recording(path)
    assert [where(p) for p in info.value.problems] == [(None, None, "vehicle", "tgv"), (None, None, "ambient_C", None)]
    assert "field 'ambient_C' = (missing)" in str(info.value)


def test_a_rule_broken_on_a_thousand_lines_stays_short(tmp_path):
    frame = samples(1001)
    frame.loc[1:, "speed_mps"] = -1.0  # lines 3 .. 1002
    path = write(tmp_path, "r", frame)
    with pytest.raises(RecordingError) as info:
        read_recording(path)
    (problem,) = info.value.problems
    assert (problem.line, problem.also_lines, problem.more_lines, problem.line_count) == (3, (4, 5, 6), 996, 1000)
    assert str(info.value) == (
        f"{path}: line 3, column 'speed_mps' = -1.0: speed must not be negative; also on lines 4, 5, 6 and 996 more"
    )


def test_layout_faults_are_each_reported_and_the_other_lines_still_checked(tmp_path):
    lines = samples(8).to_csv(index=False).splitlines()
    lines[2] += ",1"  # line 3: a field too many
    lines[4] = lines[4].rsplit(",", 1)[0]  # line 5: a field too few
    lines.insert(6, "")  # line 7 empty between samples
    lines[7] = lines[7].replace("3.3", "11.0", 1)  # line 8: pressure of axle 1
    path = tmp_path / "r.csv"
    path.write_text("\n".join(lines) + "\n")
    (tmp_path / "r.json").write_text(json.dumps(METADATA))
    with pytest.raises(RecordingError) as info:
        read_recording(path)
    assert [where(p) for p in info.value.problems] == [
        (7, None, None, None),
        (3, None, None, 13),
        (8, "p_c_bar_1", None, 11.0),
    ]
    assert "line 3 has 13 fields, the header has 12; also on line 5" in str(info.value)


def test_a_recording_built_in_code_reports_every_problem():
    frame = samples()
    frame.loc[2, "decel_mps2"] = np.inf
    frame.loc[3, "T_disc_C"] = -300.0
    frame["p_c_bar_2"] = ["3.3"] * len(frame)  # text, not numbers
    metadata = RecordingMetadata(**{**METADATA, "decel_source": None})
    with pytest.raises(RecordingError) as info:
        Recording("run", metadata, frame)
    assert [where(p) for p in info.value.problems] == [
        (None, "p_c_bar_2", None, None),
        (4, "decel_mps2", None, np.inf),
        (5, "T_disc_C", None, -300.0),
        (None, "decel_mps2", "decel_source", None),
    ]
    assert str(info.value).startswith("recording 'run': 4 problems")


# ------------------------------------------------------------------------------------------------
# A folder


def mixed_folder(root: Path) -> Path:
    """Good recordings a, c, e; b with a cell that is not a number (line 4) and time going back
    (line 6); d naming an unknown load."""
    folder = root / "set"
    for stem in ("a", "c", "e"):
        write(folder, stem)
    frame = samples().astype({"p_c_bar_1": object})
    frame.loc[2, "p_c_bar_1"] = "x"
    frame.loc[4, "time_s"] = 0.05
    write(folder, "b", frame)
    write(folder, "d", metadata={**METADATA, "load": "heavy"})
    return folder


B_PROBLEMS = ("line 4, column 'p_c_bar_1': 'x' is not a finite number", "line 6, column 'time_s' = 0.05: time must be")
D_PROBLEM = "d.json: field 'load' = 'heavy': unknown load"


def test_a_folder_lists_every_bad_recording_and_goes_on_when_asked(tmp_path):
    folder = mixed_folder(tmp_path)
    (folder / "f.csv").write_text((folder / "a.csv").read_text())  # time series without its metadata
    with pytest.raises(DatasetError) as info:
        read_dataset(folder)
    error = info.value
    assert str(error).startswith(f"{folder}: 3 of the 6 recordings are bad:")
    assert all(text in str(error) for text in (*B_PROBLEMS, D_PROBLEM, "f.json: metadata file missing"))
    assert [Path(e.file).name for e in error.errors] == ["b.csv", "d.csv", "f.csv"] and error.n_good == 3
    assert len(error.problems) == 4
    dataset = read_dataset(folder, skip_bad=True)
    assert [r.stem for r in dataset] == ["a", "c", "e"]
    assert [e.as_dict()["file"] for e in dataset.errors] == [e.file for e in error.errors]
    b = json.loads(json.dumps(dataset.errors[0].as_dict()))
    assert [(p["line"], p["column"], p["value"]) for p in b["problems"]] == [(4, "p_c_bar_1", "x"), (6, "time_s", 0.05)]


def test_a_folder_without_a_good_recording_is_refused_in_both_modes(tmp_path):
    folder = mixed_folder(tmp_path)
    for stem in ("a", "c", "e"):
        (folder / f"{stem}.csv").unlink()
    for skip_bad in (False, True):
        with pytest.raises(DatasetError, match=r"none of the 5 recordings could be read") as info:
            read_dataset(folder, skip_bad=skip_bad)
        expected = (*B_PROBLEMS, D_PROBLEM, "e.json: metadata without its time series")
        assert all(text in str(info.value) for text in expected)


# ------------------------------------------------------------------------------------------------
# Command line


def test_diagnose_refuses_a_folder_with_bad_recordings_naming_each(tmp_path, capsys):
    folder = mixed_folder(tmp_path)
    assert main(["diagnose", str(folder), "--json", str(tmp_path / "out.json")]) == 2
    err = capsys.readouterr().err
    assert all(text in err for text in (f"{folder / 'b.csv'}: 2 problems", *B_PROBLEMS, D_PROBLEM))
    assert "--skip-bad-recordings goes on with the 3 good recording(s)" in err
    assert not (tmp_path / "out.json").exists()


def test_diagnose_goes_on_with_the_good_recordings_when_asked(tmp_path, capsys, monkeypatch):
    diagnosed = []

    class Diagnoser:  # the diagnosis itself is tested in test_diagnosis.py; here only what it is given
        def __init__(self, recordings, top_singles, pairs_from):
            diagnosed.extend(r.stem for r in recordings)

        def run(self):
            return SimpleNamespace(report={"recordings": len(diagnosed), "selected": [], "summary": "no mismatch"})

    monkeypatch.setattr("brakegym.diagnosis.pipeline.Diagnoser", Diagnoser)
    folder = mixed_folder(tmp_path)
    out = tmp_path / "out.json"
    assert main(["diagnose", str(folder), "--skip-bad-recordings", "--json", str(out)]) == 0
    assert diagnosed == ["a", "c", "e"]
    captured = capsys.readouterr()
    assert "brakegym diagnose: left out 2 of the 5 recordings:" in captured.err
    assert all(text in captured.err for text in (*B_PROBLEMS, D_PROBLEM))
    assert "left out 2 bad recording(s)" in captured.out
    report = json.loads(out.read_text())
    assert report["recordings"] == 3 and report["summary"] == "no mismatch"
    left_out = report["recordings_left_out"]
    assert [Path(r["file"]).name for r in left_out] == ["b.csv", "d.csv"]
    b_problems = [(p["line"], p["column"], p["value"]) for p in left_out[0]["problems"]]
    assert b_problems == [(4, "p_c_bar_1", "x"), (6, "time_s", 0.05)]
    assert (left_out[1]["problems"][0]["field"], left_out[1]["problems"][0]["value"]) == ("load", "heavy")


def test_identify_from_recordings_goes_on_with_the_good_ones_only_when_asked(tmp_path, capsys):
    folder = mixed_folder(tmp_path)
    out = tmp_path / "out.json"
    command = ["identify", "parameters", "--recordings", str(folder), "--parameters", "a", "--json", str(out)]
    assert main(command) == 2
    err = capsys.readouterr().err
    assert all(text in err for text in (*B_PROBLEMS, D_PROBLEM)) and not out.exists()
    assert main([*command, "--skip-bad-recordings"]) == 0
    err = capsys.readouterr().err
    assert all(text in err for text in ("left out 2 of the 5 recordings", *B_PROBLEMS, D_PROBLEM))
    result = json.loads(out.read_text())
    assert [Path(r["file"]).name for r in result["recordings_left_out"]] == ["b.csv", "d.csv"]
    assert result["data"].startswith("3 train recording(s)")
    assert [p["symbol"] for p in result["parameters"]] == ["a"]
    dyno = ["identify", "parameters", "--dyno-curves", str(tmp_path / "curves.csv"), "--skip-bad-recordings"]
    assert main(dyno) == 2
    assert "--skip-bad-recordings applies to --recordings" in capsys.readouterr().err
