"""``brakegym synth --measurement-chain`` / ``--model-form``: each imperfection of the chain is in
the recordings with its configured statistics, the reader takes them as they are, the same seed
writes the same bytes, bad configs are refused naming file, field and value; and the channel noise
model recovers known AR(1) noise."""

import json
from pathlib import Path

import numpy as np
import pytest

from brakegym import config as cfg
from brakegym.cli import main
from brakegym.diagnosis import DiagnosisRules
from brakegym.diagnosis.inputs import accelerometer_bias_sigma, chain_report, initial_disc_temperature
from brakegym.diagnosis.locate import estimate_noise_models
from brakegym.diagnosis.noise import channel_runs, estimate_channel_noise, quantisation_step
from brakegym.recordings import read_dataset
from brakegym.recordings.chain import MeasurementChain, load_measurement_chain
from brakegym.recordings.columns import DECEL
from brakegym.recordings.logger import ar1_noise, dropout_mask, quantise
from brakegym.recordings.model_form import load_model_form
from brakegym.recordings.synth import synthesize
from brakegym.statistics import lag1_autocorrelation

pytestmark = pytest.mark.filterwarnings("ignore")

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
REAL_CHAIN = CONFIGS / "measurement_chains" / "real.yaml"
REAL_TRAIN = CONFIGS / "model_forms" / "real_train.yaml"
SEED = 2
N_RECORDINGS = 3


@pytest.fixture(scope="module")
def chain() -> MeasurementChain:
    return load_measurement_chain(REAL_CHAIN)


@pytest.fixture(scope="module")
def noisy(tmp_path_factory, chain):
    folder = tmp_path_factory.mktemp("noisy") / "set"
    return synthesize(folder, N_RECORDINGS, seed=SEED, measurement_chain=chain)


@pytest.fixture(scope="module")
def clean(tmp_path_factory, chain):
    """The same set with every noise level 0: the same instants, offsets and dropouts."""
    folder = tmp_path_factory.mktemp("clean") / "set"
    return synthesize(folder, N_RECORDINGS, seed=SEED, measurement_chain=chain, noise_scale=0.0)


def _own(recording, column):
    values = recording.channel(column)
    present = ~np.isnan(values)
    return recording.time_s[present], values[present]


def test_the_real_chain_is_found_by_name_on_the_config_path(chain):
    with cfg.config_path(CONFIGS):
        assert load_measurement_chain("real") == chain
        assert load_model_form("real_train") == load_model_form(REAL_TRAIN)


def test_each_channel_has_its_own_rate_jitter_and_start(noisy, chain):
    dataset = read_dataset(noisy.folder)
    assert len(dataset) == N_RECORDINGS and not dataset.errors
    clock = chain.clock_resolution_s
    for recording in dataset:
        for column, settings in chain.channels.by_column().items():
            column = recording.pressure_columns[0] if column == "p_c_bar" else column
            time, _ = _own(recording, column)
            assert time[0] == pytest.approx(settings.start_delay_s, abs=1e-9), column
            for run in channel_runs(recording.time_s, recording.channel(column), min_samples=2):
                intervals = np.diff(recording.time_s[run])
                # Jitter of both ends and the clock's rounding: within 2 jitter + 1 tick.
                assert np.max(np.abs(intervals - settings.interval_s)) <= 2 * settings.jitter_s + clock + 1e-9
                if settings.jitter_s > 2 * clock and len(intervals) > 50:
                    # Uniform jitter of both ends: the interval spread is jitter sqrt(2/3).
                    spread = np.std(intervals)
                    assert spread == pytest.approx(settings.jitter_s * np.sqrt(2 / 3), rel=0.25), column
        # A late thermometer: no initial disc temperature in the recording; the diagnosis starts
        # from its first sample, which comes before the brake onset.
        assert recording.initial_disc_C is None
        initial = initial_disc_temperature(recording)
        assert initial.source == "first_sample" and initial.sample_time_s == pytest.approx(3.0)


def test_every_channel_lies_on_its_resolution_and_the_step_is_recovered(noisy, chain):
    for recording in read_dataset(noisy.folder):
        for column, settings in chain.channels.by_column().items():
            columns = recording.pressure_columns if column == "p_c_bar" else [column]
            for name in columns:
                _, values = _own(recording, name)
                multiples = values / settings.resolution
                assert np.max(np.abs(multiples - np.round(multiples))) < 1e-6, name
            _, values = _own(recording, columns[0])
            assert quantisation_step(values) == pytest.approx(settings.resolution), column
    # Values that lie on no grid have no step.
    assert quantisation_step(np.random.default_rng(0).normal(size=500)) is None


def test_accelerometer_noise_is_ar1_with_the_configured_level_and_correlation(noisy, clean, chain):
    settings = chain.channels.decel_mps2
    differences = []
    for a, b in zip(read_dataset(noisy.folder), read_dataset(clean.folder)):
        np.testing.assert_array_equal(a.time_s, b.time_s)  # the same instants and dropouts
        difference = a.channel("decel_mps2") - b.channel("decel_mps2")
        differences += [difference[run] for run in channel_runs(a.time_s, difference, min_samples=50)]
    pooled = np.concatenate(differences)
    # Quantisation of both adds resolution^2 / 6 of white variance.
    white = settings.resolution**2 / 6
    expected_sigma = np.sqrt(settings.noise_sigma**2 + white)
    expected_rho = settings.ar1_rho * settings.noise_sigma**2 / expected_sigma**2
    assert np.std(pooled) == pytest.approx(expected_sigma, rel=0.08)
    assert lag1_autocorrelation(differences, centred=True) == pytest.approx(expected_rho, abs=0.03)


def test_offsets_are_the_keys_and_show_where_nothing_acts(clean, chain):
    key = clean.key
    for recording, truth in zip(read_dataset(clean.folder), key["applications"]):
        offsets = truth["measurement_chain"]["offsets"]
        # Before the brake command the cylinders are empty: a transducer reads its offset, and a
        # 0..10 bar transducer saturates at 0 below it.
        before = recording.time_s < truth["command_time_s"]
        for axle, column in enumerate(recording.pressure_columns):
            values = recording.channel(column)[before]
            expected = quantise(np.array([max(offsets["p_c_bar"][axle], 0.0)]), chain.channels.p_c_bar.resolution)
            np.testing.assert_array_equal(values[~np.isnan(values)], expected[0])
        # At standstill on level track an accelerometer reads its bias alone.
        standing = chain_report([recording])["recordings"][recording.stem]["accelerometer_at_standstill_mps2"]
        bias = quantise(np.array(offsets["decel_mps2"]), chain.channels.decel_mps2.resolution)[0]
        assert standing["median"] == pytest.approx(bias, abs=1e-9)
        assert standing["samples"] > 50


def test_dropouts_are_blank_runs_at_the_configured_rate(noisy, chain):
    # The generator: a dropout starts with probability p and lasts L samples on average, so a
    # sample is blank with probability 1 - exp(-p E[L]) (starts are rare and independent).
    blank = dropout_mask(np.random.default_rng(1), 400_000, 0.01, 5.0)
    assert blank.mean() == pytest.approx(1 - np.exp(-0.05), rel=0.05)
    starts = np.flatnonzero(np.diff(blank.astype(int)) == 1)
    assert blank.sum() / len(starts) == pytest.approx(5.0 * 1.05, rel=0.06)  # overlapping runs merge
    # In the recordings: blank cells inside the channels, never the first speed sample, and the
    # report counts the missing samples of each channel's own sampling.
    report = chain_report(read_dataset(noisy.folder).recordings)["recordings"]
    decel_missing = sum(entry["channels"]["decel_mps2"]["missing_samples"] for entry in report.values())
    decel_samples = sum(entry["channels"]["decel_mps2"]["samples"] for entry in report.values())
    settings = chain.channels.decel_mps2
    expected = 1 - np.exp(-settings.dropout_probability * settings.dropout_mean_samples)
    assert 0.3 * expected < decel_missing / (decel_samples + decel_missing) < 3 * expected
    for recording in read_dataset(noisy.folder):
        assert not np.isnan(recording.speed_mps[0])


def test_coasting_before_the_command_follows_the_chain(tmp_path, chain):
    late = chain.model_copy(update={"coasting_range_s": (12.0, 15.0)})
    result = synthesize(tmp_path / "set", 2, seed=SEED, measurement_chain=late, noise_scale=0.0)
    for recording, truth in zip(read_dataset(result.folder), result.key["applications"]):
        assert 12.0 <= truth["command_time_s"] <= 15.0
        # Nothing in the cylinders before the command: pressures hold their zero reading.
        before = recording.time_s < truth["command_time_s"]
        assert recording.time_s[before][-1] > 11.9
        pressures = recording.pressures_bar[before]
        assert np.nanmax(pressures) <= max(max(truth["measurement_chain"]["offsets"]["p_c_bar"]), 0.0) + 0.01


def test_same_seed_same_bytes(tmp_path, noisy, chain):
    again = synthesize(tmp_path / "again" / "set", N_RECORDINGS, seed=SEED, measurement_chain=chain)
    for path in sorted(noisy.folder.iterdir()):
        assert (again.folder / path.name).read_bytes() == path.read_bytes(), path.name
    assert again.key_path.read_bytes() == noisy.key_path.read_bytes()


@pytest.mark.parametrize(
    ("field", "edit", "value"),
    [
        ("channels.decel_mps2.ar1_rho", lambda d: d["channels"]["decel_mps2"].update(ar1_rho=1.2), "1.2"),
        ("channels.speed_mps.jitter_s", lambda d: d["channels"]["speed_mps"].update(jitter_s=0.08), "0.08"),
        ("channels.T_disc_C.resolutoin", lambda d: d["channels"]["T_disc_C"].update(resolutoin=0.1), "0.1"),
        ("channels.p_c_bar.rate_Hz", lambda d: d["channels"]["p_c_bar"].update(rate_Hz=-5), "-5"),
    ],
)
def test_a_bad_chain_is_refused_naming_file_field_and_value(tmp_path, field, edit, value):
    data = cfg.read_yaml(REAL_CHAIN)
    edit(data)
    path = tmp_path / "real.yaml"
    path.write_text(json.dumps(data))  # JSON is YAML
    with pytest.raises(cfg.ConfigError) as error:
        load_measurement_chain(path)
    message = str(error.value)
    assert str(path) in message and field in message and value in message


def test_a_bad_model_form_is_refused_on_the_command_line(tmp_path, capsys):
    data = cfg.read_yaml(REAL_TRAIN)
    data["truth_step_s"] = 0.03  # does not divide the 0.1 s command grid
    path = tmp_path / "real_train.yaml"
    path.write_text(json.dumps(data))
    status = main(["synth", str(tmp_path / "set"), "--recordings", "1", "--seed", "1", "--model-form", str(path)])
    error = capsys.readouterr().err
    assert status == 2 and str(path) in error and "truth_step_s" in error and "0.03" in error


def test_the_model_form_is_in_the_key_with_its_out_of_library_effects(tmp_path):
    form = load_model_form(REAL_TRAIN)
    result = synthesize(tmp_path / "set", 4, seed=3, model_form=form)
    key = result.key
    assert key["truth_step_s"] == form.truth_step_s
    out = {entry["id"]: entry for entry in key["model_form"]["out_of_library"]}
    assert set(key["expected_unexplained"]) == set(out)
    assert out["contact_pressure_friction"]["recordings"] == [a["stem"] for a in key["applications"]]
    ed_stems = [a["stem"] for a in key["applications"] if a["model_form"]["electrodynamic_brake"]]
    assert all(a["brake_mode"] == "service" for a in key["applications"] if a["stem"] in ed_stems)
    assert out.get("electrodynamic_brake", {"recordings": []})["recordings"] == ed_stems
    low, high = form.slow_resistance.amplitude_range_N
    assert all(low <= a["model_form"]["slow_resistance"]["amplitude_N"] <= high for a in key["applications"])
    assert len(read_dataset(result.folder)) == 4


def test_ar1_generator_has_its_level_and_correlation():
    noise = ar1_noise(np.random.default_rng(3), (200_000,), 0.03, 0.8)
    assert np.std(noise) == pytest.approx(0.03, rel=0.02)
    assert lag1_autocorrelation([noise], centred=True) == pytest.approx(0.8, abs=0.01)


@pytest.mark.parametrize("rho", [0.0, 0.5, 0.8])
def test_the_noise_model_recovers_ar1_level_and_correlation(rho):
    sigma, n = 0.03, 20_000
    time = np.arange(n) * 0.01
    signal = 2.0 * np.sin(time / 3.0) + 0.1 * time  # smooth on the estimator's window
    values = signal + ar1_noise(np.random.default_rng(7), (n,), sigma, rho)
    model = estimate_channel_noise(time, values, window_s=1.0)
    assert model.sigma == pytest.approx(sigma, rel=0.05)
    assert model.rho == pytest.approx(rho, abs=0.03)
    # What a white-noise estimate from neighbours' differences gives: sigma sqrt(1 - rho).
    from_differences = np.std(np.diff(values)) / np.sqrt(2)
    assert from_differences == pytest.approx(sigma * np.sqrt(1 - rho), rel=0.05)


def test_the_diagnosis_takes_each_channel_on_its_own_samples(noisy, chain):
    from brakegym.diagnosis.fitting import FitProblem
    from brakegym.diagnosis.locate import estimate_noise_models, residual_trace
    from brakegym.recordings.replay import replay

    recordings = read_dataset(noisy.folder).recordings
    models = estimate_noise_models(recordings, DiagnosisRules().noise_window_s)
    # Speed is blank on most lines of a merged table: its noise comes from its own runs of samples.
    assert models["speed_mps"].sigma == pytest.approx(chain.channels.speed_mps.noise_sigma, rel=0.15)
    # The accelerometer's AR(1) noise: the noise model recovers its level and correlation.
    decel = chain.channels.decel_mps2
    assert models["decel_mps2"].sigma == pytest.approx(decel.noise_sigma, rel=0.1)
    assert models["decel_mps2"].rho == pytest.approx(decel.ar1_rho, abs=0.05)
    # The fit starts each recording's initial disc temperature from its first sample.
    problem = FitProblem(recordings, {channel: model.sigma for channel, model in models.items()})
    first_samples = [initial_disc_temperature(r).value_C for r in recordings]
    np.testing.assert_array_equal(problem.initial_nuisance[len(recordings) : 2 * len(recordings)], first_samples)
    # A replay's residual trace has its speed derivative and pressure axis at every instant.
    trace = residual_trace(replay(recordings[0], initial_disc_C=first_samples[0]))
    assert np.isfinite(trace.kinematic_decel).all() and np.isfinite(trace.axes["pressure_bar"]).all()
    assert trace.braking.sum() > 0.5 * np.sum(trace.time_s > noisy.key["applications"][0]["command_time_s"] + 2)


def test_the_accelerometer_bias_scatter_is_read_from_the_standstill_readings(tmp_path, chain):
    # Each recording's accelerometer reads its bias at standstill on level track; the spread of
    # those readings across 8 recordings, less the readings' own noise (about 0.006 m/s^2 each for
    # a few hundred AR(1) samples), is the spread of the biases. The tolerance was fixed before the
    # test first ran: the readings' noise plus a quantisation step, 0.01 m/s^2.
    window = DiagnosisRules().noise_window_s
    result = synthesize(tmp_path / "real", 8, seed=3, measurement_chain=chain)
    recordings = read_dataset(result.folder).recordings
    biases = [a["measurement_chain"]["offsets"]["decel_mps2"] for a in result.key["applications"]]
    estimate = accelerometer_bias_sigma(recordings, estimate_noise_models(recordings, window)[DECEL])
    assert abs(estimate - np.std(biases, ddof=1)) <= 0.01, (estimate, np.std(biases, ddof=1))
    # A clean 10 Hz set has no bias: nothing is left once the readings' noise is taken out.
    clean_set = read_dataset(synthesize(tmp_path / "clean", 8, seed=3).folder).recordings
    assert accelerometer_bias_sigma(clean_set, estimate_noise_models(clean_set, window)[DECEL]) == 0.0
    # Fewer than three readings say nothing of a scatter.
    assert accelerometer_bias_sigma(recordings[:2], estimate_noise_models(recordings, window)[DECEL]) == 0.0
