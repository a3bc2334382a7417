"""``brakegym synth``: seeded byte for byte, the key apart from the recordings, effects drawn within
bounds, documented noise levels, a base offset recorded as not an effect."""

import json
from pathlib import Path

import numpy as np
import pytest

from brakegym.cli import main
from brakegym.effects import EFFECTS
from brakegym.recordings import read_dataset
from brakegym.recordings.synth import SENSOR_NOISE, EffectRequest, synthesize

pytestmark = pytest.mark.filterwarnings("ignore")


def _files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_same_seed_gives_the_same_bytes_and_the_key_stays_apart(tmp_path):
    effects = [EffectRequest("gradient", {"gradient_permil": -5.8}), EffectRequest("wet_pads")]
    first = synthesize(tmp_path / "a" / "set", 3, seed=11, effects=effects)
    second = synthesize(tmp_path / "b" / "set", 3, seed=11, effects=effects)
    other = synthesize(tmp_path / "c" / "set", 3, seed=12, effects=effects)
    assert _files(first.folder) == _files(second.folder)
    assert first.key_path.read_bytes() == second.key_path.read_bytes()
    assert _files(first.folder) != _files(other.folder)
    # The key lies beside the recordings, not among them, and the folder reads as a data set.
    assert first.key_path == tmp_path / "a" / "set_key.json"
    assert sorted(_files(first.folder)) == sorted(f"rec_00{i}.{ext}" for i in (1, 2, 3) for ext in ("csv", "json"))
    assert len(read_dataset(first.folder)) == 3
    key = json.loads(first.key_path.read_text())
    assert key["expected_selected"] == ["gradient", "wet_pads"]
    assert {k: key["effects"][0][k] for k in ("id", "parameters", "drawn")} == {
        "id": "gradient",
        "parameters": {"gradient_permil": -5.8},
        "drawn": [],
    }
    assert key["effects"][1]["drawn"] == ["initial_loss", "drying_energy_MJ"]
    assert key["base_offset"] is None


def test_drawn_parameters_lie_in_their_ranges_and_do_not_shift_other_draws(tmp_path):
    seen = {}
    for seed in range(6):
        key = synthesize(tmp_path / f"s{seed}", 1, seed=seed, random_effects=True).key
        assert len(key["effects"]) <= 2
        for entry in key["effects"]:
            cls = EFFECTS[entry["id"]]
            for name, value in entry["parameters"].items():
                spec = cls.spec(name)
                assert any(low <= value <= high for low, high in spec.synth_ranges), (entry, name)
                assert spec.lower <= value <= spec.upper
            seen[entry["id"]] = True
    assert seen  # six seeds drew some effect
    # Giving one parameter leaves the draw of the other as it was.
    drawn = synthesize(tmp_path / "d1", 1, seed=4, effects=[EffectRequest("thermal_fade")]).key
    half = synthesize(tmp_path / "d2", 1, seed=4, effects=[EffectRequest("thermal_fade", {"onset_C": 150.0})]).key
    assert half["effects"][0]["parameters"]["loss_per_100K"] == drawn["effects"][0]["parameters"]["loss_per_100K"]
    assert half["effects"][0]["drawn"] == ["loss_per_100K"]


def test_noise_levels_are_the_documented_ones_and_an_effect_keeps_the_campaign(tmp_path):
    noisy = read_dataset(synthesize(tmp_path / "noisy", 3, seed=5).folder).recordings
    clean = read_dataset(synthesize(tmp_path / "clean", 3, seed=5, noise_scale=0.0).folder).recordings
    effect = read_dataset(synthesize(tmp_path / "fx", 3, seed=5, effects=[EffectRequest("friction_level")]).folder)
    differences = {channel: [] for channel in ("speed_mps", "decel_mps2", "T_disc_C", "position_m", "p_c_bar_3")}
    for a, b in zip(noisy, clean):
        moving = b.speed_mps > 1.0
        for channel in differences:
            d = a.channel(channel)[moving] - b.channel(channel)[moving]
            if channel == "p_c_bar_3":
                d = d[b.channel(channel)[moving] > 0.5]  # away from the transducer's zero
            differences[channel].extend(d[~np.isnan(d)])
    decel_noise = SENSOR_NOISE[f"decel_mps2_{noisy[0].metadata.decel_source}"]
    expected = {
        "speed_mps": SENSOR_NOISE["speed_mps"],
        "decel_mps2": decel_noise,
        "T_disc_C": SENSOR_NOISE["T_disc_C"],
        "position_m": SENSOR_NOISE["position_m"],
        "p_c_bar_3": SENSOR_NOISE["p_c_bar"],
    }
    for channel, values in differences.items():
        assert np.std(values) == pytest.approx(expected[channel], rel=0.1), channel
    # Speed is never negative and exactly zero once the train stands.
    for recording in noisy:
        speed = recording.speed_mps
        assert speed.min() >= 0 and speed[-5:].max() == 0.0
    # The same seed with an effect: the same applications, the same first samples.
    for a, b in zip(noisy, effect):
        assert a.metadata == b.metadata
        np.testing.assert_array_equal(a.time_s[:20], b.time_s[:20])
        np.testing.assert_array_equal(a.pressures_bar[:20], b.pressures_bar[:20])


def test_the_key_says_whether_an_effect_is_in_the_data(tmp_path):
    # A fade whose onset lies above every temperature the discs reach changes nothing: the key
    # records it as drawn but not expressed, and does not expect a diagnosis to select it.
    cold = synthesize(tmp_path / "cold", 2, seed=5, effects=[EffectRequest("thermal_fade", {"onset_C": 590.0})]).key
    imprint = cold["effects"][0]["imprint"]
    assert not imprint["expressed"] and cold["expected_selected"] == []
    assert max(imprint["max_change_over_noise"].values()) == 0.0
    # A 6 permil gradient moves the odometry by metres: expressed, by far.
    slope = synthesize(tmp_path / "slope", 2, seed=5, effects=[EffectRequest("gradient", {"gradient_permil": 6.0})]).key
    assert slope["effects"][0]["imprint"]["expressed"] and slope["expected_selected"] == ["gradient"]
    assert slope["effects"][0]["imprint"]["max_change_over_noise"]["position_m"] > 20.0
    # In a pair, each effect's imprint is measured against the truth with the other one kept.
    pair = synthesize(
        tmp_path / "pair",
        2,
        seed=5,
        effects=[
            EffectRequest("gradient", {"gradient_permil": 6.0}),
            EffectRequest("thermal_fade", {"onset_C": 590.0}),
        ],
    ).key
    assert pair["expected_selected"] == ["gradient"]


def test_base_offset_is_recorded_as_not_an_effect(tmp_path):
    kinds = set()
    for seed in range(4):
        key = synthesize(tmp_path / f"b{seed}", 1, seed=seed, base_offset=True).key
        offset = key["base_offset"]
        kinds.add(offset["kind"])
        assert key["expected_selected"] == [] and "not an effect" in key["base_offset_note"]
        if offset["kind"] == "running_resistance":
            assert 800.0 <= abs(offset["A_shift_N"]) <= 1600.0  # 0.5..1 sigma_A
            assert 0.8 <= offset["B_factor"] <= 1.2 and 0.8 <= offset["C_factor"] <= 1.2
        else:
            assert 0.005 <= abs(offset["initial_mu_shift"]) <= 0.01  # 0.5..1 sigma of mu_0
    assert kinds == {"running_resistance", "friction"}
    # With a running-resistance effect on, the offset moves the friction instead.
    key = synthesize(tmp_path / "rr", 1, seed=0, base_offset=True, effects=[EffectRequest("running_resistance")]).key
    assert key["base_offset"]["kind"] == "friction"


def test_command_line(tmp_path, capsys):
    out = tmp_path / "set"
    assert (
        main(["synth", str(out), "--recordings", "2", "--seed", "5", "--effect", "gradient:gradient_permil=-5.8"]) == 0
    )
    assert (tmp_path / "set_key.json").is_file() and len(read_dataset(out)) == 2
    assert main(["synth", str(out), "--recordings", "2", "--seed", "5"]) == 2  # folder holds a set
    assert "already holds recordings" in capsys.readouterr().err
    bad = [
        (["--effect", "gradient:gradient_permil=99"], "lies outside its bounds"),
        (["--effect", "gradient:slope=1"], "unknown parameter(s) ['slope']"),
        (["--effect", "sanding"], "unknown effect 'sanding'"),
        (["--effect", "gradient", "--effect", "wet_pads", "--effect", "rotating_mass"], "at most 2"),
        (["--random-effects", "--effect", "gradient"], "not both"),
        (["--key", str(tmp_path / "new" / "k.json")], "must not lie inside the recordings folder"),
    ]
    for extra, message in bad:
        assert main(["synth", str(tmp_path / "new"), "--recordings", "1", "--seed", "1", *extra]) == 2
        assert message in capsys.readouterr().err
