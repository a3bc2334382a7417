"""The noise model in the diagnosis' fit, on a set written through the real measurement chain:
each channel's noise window spans seconds of its own samples, the fit's residual weights follow
each channel's AR(1) level and its effective sample size its correlation, and the pressure
transducers' zero offsets are taken out of the replay's input. Every bound here was fixed before
the test first ran."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from brakegym.diagnosis import DiagnosisRules
from brakegym.diagnosis.locate import estimate_noise_models
from brakegym.diagnosis.noise import window_samples
from brakegym.recordings import read_dataset
from brakegym.recordings.chain import load_measurement_chain
from brakegym.recordings.columns import DECEL, DISC_TEMPERATURE, SPEED
from brakegym.recordings.synth import synthesize

pytestmark = pytest.mark.filterwarnings("ignore")

REAL_CHAIN = Path(__file__).resolve().parents[1] / "configs" / "measurement_chains" / "real.yaml"
SEED = 3
N_RECORDINGS = 4


@pytest.fixture(scope="module")
def chain():
    return load_measurement_chain(REAL_CHAIN)


@pytest.fixture(scope="module")
def real_set(tmp_path_factory, chain):
    folder = tmp_path_factory.mktemp("real") / "set"
    return synthesize(folder, N_RECORDINGS, seed=SEED, measurement_chain=chain)


@pytest.fixture(scope="module")
def recordings(real_set):
    return read_dataset(real_set.folder).recordings


def test_the_noise_window_spans_seconds_of_each_channels_own_samples():
    assert window_samples(1.0, 0.01) == 101  # a 100 Hz accelerometer over 1 s
    assert window_samples(2.0, 0.1) == 21  # a 10 Hz speed over 2 s
    assert window_samples(3.0, 0.1) == 31
    assert window_samples(3.0, 0.5) == 7  # a 2 Hz thermometer: 3 s is 6 samples, the least is 7


def test_a_slow_thermometer_reads_its_white_noise_with_a_window_in_seconds(recordings, chain):
    models = estimate_noise_models(recordings, DiagnosisRules().noise_window_s)
    thermometer = chain.channels.T_disc_C
    assert models[DISC_TEMPERATURE].window == 7
    assert models[DISC_TEMPERATURE].sigma == pytest.approx(thermometer.noise_sigma, rel=0.10)
    assert abs(models[DISC_TEMPERATURE].rho) <= 0.15
    accelerometer = chain.channels.decel_mps2
    assert models[DECEL].window == 101
    assert models[DECEL].sigma == pytest.approx(accelerometer.noise_sigma, rel=0.05)
    assert models[DECEL].rho == pytest.approx(accelerometer.ar1_rho, abs=0.05)


@pytest.fixture(scope="module")
def diagnoser(recordings):
    from brakegym.diagnosis import Diagnoser

    return Diagnoser(recordings)


def test_the_fit_divides_each_channel_by_its_ar1_level(diagnoser, chain):
    """The accelerometer's AR(1) noise (0.03 m/s^2, rho 0.8) is the fit's noise on it, where a
    white-noise estimate read half of it."""
    noise = diagnoser.problem.noise
    assert noise[DECEL] == pytest.approx(chain.channels.decel_mps2.noise_sigma, rel=0.05)
    assert noise[SPEED] == pytest.approx(chain.channels.speed_mps.noise_sigma, rel=0.05)
    assert noise[DISC_TEMPERATURE] == pytest.approx(chain.channels.T_disc_C.noise_sigma, rel=0.10)


@pytest.mark.parametrize("residual_rho", [0.0, 0.9])
def test_the_effective_sample_share_shrinks_as_the_noise_rho_grows(diagnoser, residual_rho):
    """With a white residual each channel's share is (1 - rho) / (1 + rho) of its noise's rho; a
    residual more correlated than its noise keeps its own share."""
    from brakegym.diagnosis.weighting import Weighting
    from brakegym.recordings.logger import ar1_noise

    problem = diagnoser.problem
    residual = ar1_noise(np.random.default_rng(5), (len(problem.recording_of),), 1.0, residual_rho)
    shares, totals = [], []
    for noise_rho in (0.0, 0.5, 0.8, 0.95):
        weighting = Weighting(problem, residual, {DECEL: noise_rho})
        expected = (1 - max(noise_rho, residual_rho)) / (1 + max(noise_rho, residual_rho))
        assert weighting.channel_shares[DECEL] == pytest.approx(expected, abs=0.02)
        shares.append(weighting.channel_shares[DECEL])
        totals.append(weighting.n_eff_total)
    if residual_rho == 0.0:
        assert np.all(np.diff(shares) < 0) and np.all(np.diff(totals) < 0)
    else:
        assert np.all(np.diff(shares[:3]) == 0) and shares[3] < shares[2]


def test_the_replay_takes_the_transducers_zero_offsets_out(diagnoser, recordings, real_set):
    """An offset of at least 0.02 bar (the transducer's noise sigma) is removed to within 0.01 bar
    (its resolution) from the pressures the fit replays; one of at most -0.02 bar reads 0 before the
    brake, is left in and reported as not identifiable."""
    from brakegym.diagnosis.inputs import chain_report
    from brakegym.recordings.replay import bridged_pressures_bar

    not_identifiable = chain_report(recordings)["pressure_zero_offset_not_identifiable"]
    positive = negative = 0
    for read, replayed, application in zip(recordings, diagnoser.problem.recordings, real_set.key["applications"]):
        true_offsets = np.array(application["measurement_chain"]["offsets"]["p_c_bar"])
        raw = bridged_pressures_bar(read)
        braking = raw.mean(axis=1) > 1.0  # well above every offset: no sample saturated
        left_in = np.mean(bridged_pressures_bar(replayed)[braking] - (raw[braking] - true_offsets), axis=0)
        for column, offset, error in zip(read.pressure_columns, true_offsets, left_in):
            if offset >= 0.02:
                positive += 1
                assert abs(error) <= 0.01, (read.stem, column, offset, error)
                assert column not in not_identifiable.get(read.stem, [])
            elif offset <= -0.02:
                negative += 1
                assert error == pytest.approx(offset, abs=1e-9)  # nothing removed
                assert column in not_identifiable[read.stem]
    assert positive >= 5 and negative >= 5  # the set holds both kinds (seed 3: 11 and 7)


def test_an_effect_free_real_chain_set_fits_within_its_noise(recordings, naming_rules):
    """With the accelerometer's AR(1) level in the fit, an effect-free set through the real chain
    is no mismatch (a white-noise level of half the true one read its noise as 2.4 sigma)."""
    from brakegym.diagnosis import Diagnoser

    report = Diagnoser(recordings, top_singles=2, pairs_from=0, rules=naming_rules).run().report
    assert report["selected"] == [], report["summary"]
    assert not report["mismatch"]["significant"], report["mismatch"]
    assert report["mismatch"]["rms_over_noise"]["decel"] < DiagnosisRules().mismatch_rms_over_noise
