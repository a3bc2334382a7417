"""``brakegym diagnose`` run blind on synthetic sets: it names a concealed gradient and recovers
its size, names a friction level (or reports it indistinguishable from its confounders), and
names an adhesion limit and recovers it, selects nothing on effect-free sets, also when the base
model is moved within its scatter.

Sets are small (5-6 recordings) and only the best two screened effects are fitted in full, to
keep the run short; the benchmark (``benchmarks/bench_diagnosis.py``) uses the defaults.
Effect sizes are drawn from a seeded RNG inside clearly detectable ranges.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from brakegym.cli import main
from brakegym.diagnosis import diagnose, write_effect_set
from brakegym.effects import load_effects
from brakegym.envs import BrakeEnv
from brakegym.recordings.format import read_dataset
from brakegym.recordings.synth import EffectRequest, synthesize

pytestmark = pytest.mark.filterwarnings("ignore")

SIZES = np.random.default_rng(20260422)
# Tolerance on a recovered gradient: 1 permil or 20 %, whichever is larger (the fit leaves a
# bias of about 10 % from friction scatter shared with the per-recording friction factors).
GRADIENT_TOLERANCE_PERMIL = 1.0
GRADIENT_TOLERANCE_SHARE = 0.2


def test_names_a_gradient_and_recovers_its_size(tmp_path, naming_rules):
    gradient = float(SIZES.choice([-1, 1]) * SIZES.uniform(4.0, 10.0))
    # Seed 3 draws an accelerometer set: with deceleration differentiated from speed, a gradient
    # and a running-resistance offset act alike on every channel but through the train mass, and
    # six recordings do not always separate them (the report then names the other).
    result = synthesize(
        tmp_path / "set", 6, seed=3, effects=[EffectRequest("gradient", {"gradient_permil": round(gradient, 2)})]
    )
    assert result.key["decel_source"] == "accelerometer"
    report = diagnose(result.folder, top_singles=3, pairs_from=2, rules=naming_rules).report
    assert "gradient" in report["selected"], report["summary"]
    fitted = report["parameters"]["gradient_permil"]
    assert abs(fitted - gradient) <= max(GRADIENT_TOLERANCE_PERMIL, GRADIENT_TOLERANCE_SHARE * abs(gradient)), (
        fitted,
        gradient,
    )
    chosen = next(c for c in report["candidates"] if c["effects"] == report["selected"])
    # The held-out fit improves in speed, the channel a gradient acts on.
    assert chosen["heldout_rms_after"]["speed_mps"] < chosen["heldout_rms_before"]["speed_mps"]
    assert report["mismatch"]["significant"]
    # The modified model goes on as an effect set the simulator and environments load.
    effects = load_effects(write_effect_set(report, tmp_path / "diagnosed.yaml", "set"))
    assert [e.id for e in effects] == report["selected"]
    gradient_effect = next(e for e in effects if e.id == "gradient")
    assert gradient_effect["gradient_permil"] == pytest.approx(fitted)
    env = BrakeEnv("station_stop", config={"effects": str(tmp_path / "diagnosed.yaml")})
    env.reset(seed=0)
    env.step(np.zeros(env.action_space.shape, np.float32))
    assert [e.id for e in env.unwrapped.core.fleet.effects] == report["selected"]


def test_names_a_friction_level_or_its_confounders(tmp_path, naming_rules):
    mu_scale = float(SIZES.uniform(0.78, 0.86))
    folder = synthesize(
        tmp_path / "set", 6, seed=47, effects=[EffectRequest("friction_level", {"mu_scale": round(mu_scale, 3)})]
    ).folder
    report = diagnose(folder, top_singles=2, pairs_from=0, rules=naming_rules).report
    named = "friction_level" in report["selected"] or any(
        "friction_level" in pair for pair in report["indistinguishable"]
    )
    assert named, (report["selected"], report["indistinguishable"], report["summary"])
    if report["selected"] == ["friction_level"]:
        assert report["parameters"]["mu_scale"] == pytest.approx(mu_scale, abs=0.05)


def test_names_an_adhesion_limit_and_recovers_it(tmp_path):
    # The cap's chi^2 valley is about 0.005 wide in adhesion: the diagnosis must start from the
    # plateau of the measured deceleration, not only from its grid (which found 1 in 7 such sets).
    adhesion = round(float(SIZES.uniform(0.062, 0.078)), 4)
    result = synthesize(tmp_path / "set", 6, seed=61, effects=[EffectRequest("adhesion_limit", {"adhesion": adhesion})])
    assert result.key["expected_selected"] == ["adhesion_limit"]
    report = diagnose(result.folder, top_singles=2, pairs_from=0).report
    assert report["selected"] == ["adhesion_limit"], report["summary"]
    assert report["parameters"]["adhesion"] == pytest.approx(adhesion, abs=0.002)
    low, high = next(c for c in report["candidates"] if c["effects"] == ["adhesion_limit"])["ci95"]["adhesion"]
    assert low - 0.001 <= adhesion <= high + 0.001
    # Read as a rail (docs/adhesion.md): the WSP-test rail, with a mu_0 near its own.
    rail = report["adhesion_limit_rail"]
    assert rail["peak_adhesion"] == report["parameters"]["adhesion"]
    assert rail["nearest_rail_condition"] == "low"
    assert rail["polach_static_friction"] == pytest.approx(0.063 * adhesion / 0.07, rel=0.1)


def test_names_a_thermal_fade_that_only_the_hottest_stops_reach(tmp_path, naming_rules):
    # The fade of a blind benchmark set (8 recordings; four stops get hot enough to show it). Its
    # held-out gain is large on those and nil on the others: the selection must weigh the
    # recordings it acts on, not all eight alike (before, t 1.5 < 2 and nothing was selected).
    result = synthesize(
        tmp_path / "set",
        8,
        seed=409715195,
        effects=[EffectRequest("thermal_fade", {"onset_C": 207.1, "loss_per_100K": 0.3896})],
    )
    assert result.key["expected_selected"] == ["thermal_fade"]
    report = diagnose(result.folder, top_singles=1, pairs_from=0, rules=naming_rules).report
    assert report["selected"] == ["thermal_fade"], report["summary"]
    assert report["parameters"]["onset_C"] == pytest.approx(207.1, abs=10.0)
    assert report["parameters"]["loss_per_100K"] == pytest.approx(0.3896, abs=0.05)
    fade = report["candidates"][0]
    assert fade["delta_bic"] < -1000.0
    assert 2 <= len(fade["heldout_acts_on"]) < 8


def test_names_a_fade_whose_onset_lies_between_the_screening_grid_points(tmp_path, naming_rules):
    # Onset 224 degC in stops that peak near 250 degC (measured disc): the grid's onsets (167,
    # 340, 513 degC) either fade every stop or none, and screening never ranked the fade; it is
    # screened from onsets below the measured peak now, and judged relevant by the friction it
    # takes at the hottest friction surface (a rule on the measured peak rejected the fit).
    result = synthesize(
        tmp_path / "set",
        8,
        seed=1910104468,
        effects=[EffectRequest("thermal_fade", {"onset_C": 224.4, "loss_per_100K": 0.3439})],
    )
    report = diagnose(result.folder, top_singles=1, pairs_from=0, rules=naming_rules).report
    assert report["selected"] == ["thermal_fade"], report["summary"]
    assert report["parameters"]["onset_C"] == pytest.approx(224.4, abs=10.0)
    assert report["parameters"]["loss_per_100K"] == pytest.approx(0.3439, abs=0.05)


def test_held_out_predictions_of_a_fade_are_simulated_not_extrapolated(tmp_path, naming_rules):
    # Left out, each of the hot stops moves the fade's parameters far; the linear prediction of
    # one of them came out 17 % worse than no effect (paired t 1.97, nothing selected), its
    # simulation 9 % better.
    result = synthesize(
        tmp_path / "set",
        8,
        seed=724340878,
        effects=[EffectRequest("thermal_fade", {"onset_C": 194.0, "loss_per_100K": 0.2048})],
    )
    report = diagnose(result.folder, top_singles=1, pairs_from=0, rules=naming_rules).report
    assert report["selected"] == ["thermal_fade"], report["summary"]
    fade = report["candidates"][0]
    names = [recording.name for recording in read_dataset(result.folder).recordings]
    acting = [gain for gain, name in zip(fade["heldout_gain_per_recording"], names) if name in fade["heldout_acts_on"]]
    assert len(acting) >= 2 and min(acting) > 0.0
    assert report["parameters"]["onset_C"] == pytest.approx(194.0, abs=10.0)


def test_a_fade_that_only_one_or_two_stops_reach_is_reported_unconfirmed(tmp_path, naming_rules):
    # Only the hottest two of eight stops reach the onset: the fade fits them far better (BIC lower
    # by about 4,900), but a paired t over two recordings shows no consistency, and one of them
    # gains nothing held out. Not selected; named unconfirmed, with the stops that would confirm it.
    result = synthesize(
        tmp_path / "set",
        8,
        seed=799579680,
        effects=[EffectRequest("thermal_fade", {"onset_C": 214.9, "loss_per_100K": 0.3864})],
    )
    report = diagnose(result.folder, top_singles=1, pairs_from=0, rules=naming_rules).report
    assert report["selected"] == [], report["summary"]
    [entry] = report["unconfirmed"]
    assert entry["effects"] == ["thermal_fade"]
    assert 1 <= len(entry["acts_on"]) <= 2 and entry["heldout_gain_acting"] >= 0.1
    assert entry["parameters"]["onset_C"] == pytest.approx(214.9, abs=15.0)
    assert all(Path(name).name in entry["to_confirm"] for name in entry["acts_on"])
    assert report["mismatch"]["significant"] and "Unconfirmed: thermal_fade" in report["summary"]


def test_a_sensor_scale_that_helps_two_recordings_and_worsens_others_is_not_selected(tmp_path, naming_rules):
    # An effect-free set on which a speed-sensor scale of 1.009 lowers the BIC by about 500: it
    # moves rows of only two recordings by a noise sigma, and a paired t over those two was 25,
    # so it was selected, while it raised the held-out error of others by up to 24 %. A recording
    # whose held-out error it changes by 10 % counts too, and over those the gain is not consistent.
    # With each application's running resistance fitted, the scale no longer ranks among the three
    # best singles here: the resistances take up what it fitted. Where it is fitted, the rule holds.
    folder = synthesize(tmp_path / "set", 8, seed=1837742268).folder
    report = diagnose(folder, top_singles=3, pairs_from=0, rules=naming_rules).report
    assert report["selected"] == [], report["summary"]
    scale = next((c for c in report["candidates"] if c["effects"] == ["speed_sensor_scale"]), None)
    if scale is None or scale["delta_bic"] >= -100:
        return
    counted = {Path(name).name for name in scale["heldout_acts_on"]}
    names = sorted(path.name for path in folder.glob("*.csv"))  # the order of the per-recording gains
    worsened = {name for name, share in zip(names, scale["heldout_gain_per_recording"]) if share <= -0.1}
    assert worsened and worsened <= counted, (worsened, counted)


def test_recovers_a_speed_sensor_scale_on_fast_stops(tmp_path):
    # A wheel that reads 4.5 % slow: the true initial speed of a 150 km/h stop lies 2 m/s above
    # the measured one. With the initial speeds fitted in true units and bounded 1.5 m/s around
    # the measured ones, the scale was pulled to 0.965 and its interval missed the truth.
    result = synthesize(tmp_path / "set", 8, seed=11, effects=[EffectRequest("speed_sensor_scale", {"scale": 0.955})])
    report = diagnose(result.folder, top_singles=1, pairs_from=0).report
    assert report["selected"] == ["speed_sensor_scale"], report["summary"]
    assert report["parameters"]["scale"] == pytest.approx(0.955, abs=0.003)
    chosen = next(c for c in report["candidates"] if c["effects"] == report["selected"])
    low, high = chosen["ci95"]["scale"]
    assert low <= 0.955 <= high


def test_names_four_failed_brake_units(tmp_path, naming_rules):
    # Four of sixteen units fail: the unmodified fit's friction factors sink to about 0.75, and
    # screening must start the failure's nuisance from factors rescaled by the force it leaves
    # (from 0.75 it rated the true failure worse than no effect, in every such benchmark set).
    result = synthesize(
        tmp_path / "set", 6, seed=67, effects=[EffectRequest("brake_unit_failure", {"failed_units": 4.0})]
    )
    report = diagnose(result.folder, top_singles=2, pairs_from=0, rules=naming_rules).report
    assert report["selected"] == ["brake_unit_failure"], report["summary"]
    assert report["parameters"]["failed_units"] == 4.0


def test_a_confounder_that_fits_as_well_held_out_is_named_indistinguishable(tmp_path, naming_rules):
    # Two failed units of sixteen against a heavier rotating mass: both take the same share of
    # the deceleration in every stop, and the blind benchmark selected the rotating mass (BIC
    # lower by 367, held-out error 8 % lower, paired t over the recordings 0.4) without a word on
    # the failure. Equally good held out, the two must be named indistinguishable, with what
    # would separate them.
    result = synthesize(
        tmp_path / "set", 8, seed=272204246, effects=[EffectRequest("brake_unit_failure", {"failed_units": 2.0})]
    )
    report = diagnose(result.folder, top_singles=3, pairs_from=0, rules=naming_rules).report
    named = set(report["selected"]) | {effect for pair in report["indistinguishable"] for effect in pair}
    assert "brake_unit_failure" in named, report["summary"]
    if report["selected"] != ["brake_unit_failure"]:
        pair = [report["selected"][0], "brake_unit_failure"]
        assert pair in report["indistinguishable"], report["indistinguishable"]
        assert "rear disc" in report["separating_measurements"][" / ".join(pair)]
        # Confounders: their corrections to the unmodified model have nearly the same shape.
        assert report["signature_correlations"][" / ".join(pair)] > 0.8


def test_recovers_wet_pads_that_dry_within_a_megajoule(tmp_path, naming_rules):
    # Drying at 0.73 MJ: on a linear screening grid (1.7, 5.0, 8.3 MJ) the fit ended in a second
    # valley near 6.7 MJ with a loss of 0.38 (twice the truth's chi^2); the grid is geometric now.
    result = synthesize(
        tmp_path / "set",
        8,
        seed=562067968,
        effects=[EffectRequest("wet_pads", {"initial_loss": 0.2716, "drying_energy_MJ": 0.7277})],
    )
    report = diagnose(result.folder, top_singles=2, pairs_from=0, rules=naming_rules).report
    assert report["selected"] == ["wet_pads"], report["summary"]
    assert report["parameters"]["initial_loss"] == pytest.approx(0.2716, abs=0.02)
    assert report["parameters"]["drying_energy_MJ"] == pytest.approx(0.7277, rel=0.2)


def test_selects_nothing_when_the_base_model_is_only_moved_within_its_scatter(tmp_path, naming_rules):
    folder = synthesize(tmp_path / "set", 5, seed=53, base_offset=True).folder
    report = diagnose(folder, top_singles=2, pairs_from=0, rules=naming_rules).report
    assert report["selected"] == [], report["summary"]
    assert report["parameters"] == {}


def test_cli_on_an_effect_free_set_selects_nothing_and_writes_the_keys(tmp_path, capsys):
    folder = synthesize(tmp_path / "set", 5, seed=61).folder
    out = tmp_path / "report.json"
    effect_set = tmp_path / "diagnosed.yaml"
    assert (
        main(
            [
                "diagnose",
                str(folder),
                "--json",
                str(out),
                "--report",
                str(tmp_path / "report"),
                "--top-singles",
                "2",
                "--pairs-from",
                "0",
                "--effects-out",
                str(effect_set),
            ]
        )
        == 0
    )
    assert load_effects(effect_set) == []
    report = json.loads(out.read_text())
    for key in (
        "recordings",
        "noise",
        "mismatch",
        "candidates",
        "selected",
        "parameters",
        "indistinguishable",
        "indistinguishable_single_or_pair",
        "forward_screening",
        "unexplained",
        "summary",
    ):
        assert key in report
    assert set(report["noise"]) == {"speed_mps", "decel_mps2", "T_disc_C"}
    # The noise estimated from the recordings is the generator's (0.03 m/s, 1 K) within 15 %.
    assert report["noise"]["speed_mps"] == pytest.approx(0.03, rel=0.15)
    assert report["noise"]["T_disc_C"] == pytest.approx(1.0, rel=0.15)
    assert report["recordings"] == 5
    assert report["selected"] == [] and report["unexplained"] is None and report["unconfirmed"] == []
    # No single selected: no forward step, no pair named against one.
    assert report["forward_screening"] is None and report["indistinguishable_single_or_pair"] == []
    assert not report["mismatch"]["significant"]
    for candidate in report["candidates"]:
        assert {
            "effects",
            "parameters",
            "ci95",
            "rms_before",
            "rms_after",
            "heldout_rms_before",
            "heldout_rms_after",
            "delta_bic",
        } <= set(candidate)
    assert (tmp_path / "report" / "report.md").is_file() and (tmp_path / "report" / "residuals.png").is_file()
    assert "selected: nothing" in capsys.readouterr().out


def test_cli_refuses_a_bad_folder_with_exit_2(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert main(["diagnose", str(tmp_path / "empty")]) == 2
    assert "no recordings" in capsys.readouterr().err
    assert main(["diagnose", str(tmp_path / "missing")]) == 2
    assert "not a folder" in capsys.readouterr().err
