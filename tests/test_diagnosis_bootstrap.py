"""The parametric bootstrap of the selected model's parameters (:mod:`brakegym.diagnosis.bootstrap`):
the same data give the same intervals bit for bit, and on a small synthetic set with a known
gradient the bootstrap interval holds the truth and is narrower than the effect itself.

The thresholds were fixed before the test first ran: the interval must hold the drawn gradient,
exclude zero (the effect is there) and be narrower than the gradient's size.
"""

import numpy as np
import pytest
from scipy import stats

from brakegym.diagnosis.bootstrap import bootstrap, bootstrap_seed, merged_intervals
from brakegym.diagnosis.fitting import FitProblem
from brakegym.diagnosis.inputs import zero_corrected
from brakegym.diagnosis.locate import estimate_noise_models
from brakegym.diagnosis.rules import DiagnosisRules
from brakegym.physics.scatter import FrictionDraw
from brakegym.recordings.format import read_dataset
from brakegym.recordings.replay import replay_batch
from brakegym.recordings.synth import EffectRequest, synthesize

pytestmark = pytest.mark.filterwarnings("ignore")

GRADIENT_PERMIL = 6.0
REPLICATES = 8


def _gradient_fit(folder, seed):
    """A fitted gradient on 5 recordings with a 6 permil gradient, as the diagnosis fits it."""
    synthesize(folder, 5, seed=seed, effects=[EffectRequest("gradient", {"gradient_permil": GRADIENT_PERMIL})])
    recordings = read_dataset(folder).recordings
    rules = DiagnosisRules()
    noise_models = estimate_noise_models(recordings, rules.noise_window_s)
    noise = {c: m.sigma for c, m in noise_models.items() if np.isfinite(m.sigma) and m.sigma > 0}
    problem = FitProblem([zero_corrected(r) for r in recordings], noise)
    start = np.concatenate([[GRADIENT_PERMIL / 2.0], problem.gridded_start()])
    fit = problem.fit(["gradient"], start, max_iterations=rules.fit_iterations)
    return problem, fit, noise_models, rules


@pytest.fixture(scope="module")
def gradient_fit(tmp_path_factory):
    return _gradient_fit(tmp_path_factory.mktemp("bootstrap") / "set", seed=3)


@pytest.fixture(scope="module")
def accelerometer_gradient_fit(tmp_path_factory):
    """The same on a set whose deceleration channel is an accelerometer (seed 3's is the speed's
    derivative, which carries no bias)."""
    problem, fit, noise_models, rules = _gradient_fit(tmp_path_factory.mktemp("accelerometer") / "set", seed=4)
    assert all(r.metadata.decel_source == "accelerometer" for r in problem.recordings)
    return problem, fit, noise_models, rules


def test_the_same_data_give_the_same_bootstrap_bit_for_bit(gradient_fit):
    problem, fit, noise_models, rules = gradient_fit
    seed = bootstrap_seed(problem.recordings, fit.effect_ids)
    assert seed == bootstrap_seed(list(problem.recordings), ("gradient",))
    first = bootstrap(problem, fit, noise_models, 3, rules.fit_iterations, seed)
    second = bootstrap(problem, fit, noise_models, 3, rules.fit_iterations, seed)
    assert first.estimates.tobytes() == second.estimates.tobytes()
    assert first.ci95 == second.ci95


def test_the_seed_follows_the_bytes_of_the_data(gradient_fit):
    problem, fit, _, _ = gradient_fit
    recordings = list(problem.recordings)
    assert bootstrap_seed(recordings, ("gradient",)) != bootstrap_seed(recordings[1:], ("gradient",))
    assert bootstrap_seed(recordings, ("gradient",)) != bootstrap_seed(recordings, ("running_resistance",))


def test_the_bootstrap_interval_holds_a_known_gradient_and_is_narrower_than_it(gradient_fit):
    problem, fit, noise_models, rules = gradient_fit
    seed = bootstrap_seed(problem.recordings, fit.effect_ids)
    result = bootstrap(problem, fit, noise_models, REPLICATES, rules.fit_iterations, seed)
    low, high = result.ci95["gradient_permil"]
    assert low <= GRADIENT_PERMIL <= high, (low, high, fit.parameters)
    assert low > 0.0, (low, high)  # the effect is there
    assert high - low < GRADIENT_PERMIL, (low, high)
    # The replicates are real refits: they scatter, and around the fitted value.
    assert np.std(result.estimates[:, 0]) > 0.0
    assert abs(np.mean(result.estimates[:, 0]) - fit.x[0]) < GRADIENT_PERMIL / 2.0
    # The interval takes in both the bias-corrected one and the one on the estimate.
    theta, estimates = fit.x[0], result.estimates[:, 0]
    half = stats.t.ppf(0.975, REPLICATES - 1) * np.std(estimates, ddof=1)
    corrected = 2.0 * theta - np.mean(estimates)
    assert low == pytest.approx(min(corrected, theta) - half, abs=1e-5)
    assert high == pytest.approx(max(corrected, theta) + half, abs=1e-5)


def test_an_accelerometer_bias_widens_what_the_replicates_spread(accelerometer_gradient_fit, gradient_fit):
    # A bias of 0.05 m/s^2 between recordings reads as 5 permil of gradient on each recording's
    # accelerometer. The fitted gradient rests mostly on the speed channel (the coasting, the
    # loads), so the bias moves it modestly; with the same noise and scatter draws (the bias has a
    # stream of its own) the replicates must differ and spread wider.
    problem, fit, noise_models, rules = accelerometer_gradient_fit
    seed = bootstrap_seed(problem.recordings, fit.effect_ids)
    plain = bootstrap(problem, fit, noise_models, 6, rules.fit_iterations, seed)
    biased = bootstrap(problem, fit, noise_models, 6, rules.fit_iterations, seed, decel_bias_sigma=0.05)
    assert not np.array_equal(biased.estimates, plain.estimates)
    assert np.std(biased.estimates[:, 0]) > np.std(plain.estimates[:, 0]), (biased.ci95, plain.ci95)
    # A deceleration taken from the speed has no bias to draw: the same replicates bit for bit.
    problem, fit, noise_models, rules = gradient_fit
    seed = bootstrap_seed(problem.recordings, fit.effect_ids)
    plain = bootstrap(problem, fit, noise_models, 3, rules.fit_iterations, seed)
    biased = bootstrap(problem, fit, noise_models, 3, rules.fit_iterations, seed, decel_bias_sigma=0.05)
    assert biased.estimates.tobytes() == plain.estimates.tobytes()


def test_the_ends_tested_by_their_own_replicates_widen_the_interval_by_the_inverted_test(gradient_fit):
    problem, fit, noise_models, rules = gradient_fit
    seed = bootstrap_seed(problem.recordings, fit.effect_ids)
    plain = bootstrap(problem, fit, noise_models, REPLICATES, rules.fit_iterations, seed)
    tested = bootstrap(problem, fit, noise_models, REPLICATES, rules.fit_iterations, seed, end_replicates=6)
    again = bootstrap(problem, fit, noise_models, REPLICATES, rules.fit_iterations, seed, end_replicates=6)
    # The replicates at the fit are the plain bootstrap's; the ends add to them, bit for bit.
    assert tested.estimates.tobytes() == plain.estimates.tobytes()
    assert [e.estimates.tobytes() for e in tested.ends] == [e.estimates.tobytes() for e in again.ends]
    assert tested.ci95 == again.ci95
    # One draw at each end of the plain interval, simulated with that end's gradient.
    assert [e.parameter for e in tested.ends] == ["gradient_permil"] * 2
    assert [e.point[0] for e in tested.ends] == pytest.approx(plain.ci95["gradient_permil"], abs=1e-5)
    low, high = tested.ci95["gradient_permil"]
    theta = fit.x[0]
    quantile = stats.t.ppf(0.975, 5)
    inverted = [
        theta - (e.estimates[:, 0].mean() - e.point[0]) + side * quantile * e.estimates[:, 0].std(ddof=1)
        for e, side in zip(tested.ends, (-1.0, 1.0))
    ]
    assert low == pytest.approx(min(plain.ci95["gradient_permil"][0], inverted[0]), abs=1e-5)
    assert high == pytest.approx(max(plain.ci95["gradient_permil"][1], inverted[1]), abs=1e-5)
    # The ends moved out here (the replicates at both ends of this set spread wider than those at
    # the fit: 1.1 and 1.2 permil against 0.75), and the interval still holds the truth and
    # excludes zero.
    assert low < plain.ci95["gradient_permil"][0] and high > plain.ci95["gradient_permil"][1]
    assert 0.0 < low <= GRADIENT_PERMIL <= high


def test_too_few_replicates_give_no_bootstrap(gradient_fit):
    problem, fit, noise_models, rules = gradient_fit
    assert bootstrap(problem, fit, noise_models, 2, rules.fit_iterations, 0) is None


def test_the_reported_interval_is_the_hull_of_both():
    merged = merged_intervals({"a": [1.0, 2.0], "b": [0.0, 1.0]}, {"a": [1.5, 2.5]})
    assert merged == {"a": [1.0, 2.5], "b": [0.0, 1.0]}


def test_a_parameter_resting_on_one_recording_takes_the_bootstraps_interval_alone():
    # Its jackknife stepped to a bound (80-510 degC) says where the bounds are, not how the
    # estimate scatters; without a bootstrap's interval it keeps the one it has.
    merged = merged_intervals(
        {"onset_C": [80.0, 510.0], "loss_per_100K": [0.2, 0.3], "gradient_permil": [1.0, 2.0]},
        {"onset_C": [190.0, 230.0], "loss_per_100K": [0.25, 0.35]},
        {"onset_C": "hot.csv", "gradient_permil": "hot.csv"},
    )
    assert merged == {"onset_C": [190.0, 230.0], "loss_per_100K": [0.2, 0.35], "gradient_permil": [1.0, 2.0]}


def test_replay_refuses_a_scatter_of_the_wrong_shape(gradient_fit):
    problem = gradient_fit[0]
    one = problem.recordings[:1]
    wrong = FrictionDraw(np.ones((2, 1, 1)), np.ones((2, 1, 1)))
    with pytest.raises(ValueError, match="friction_draw"):
        replay_batch(one, friction_draw=wrong)
    with pytest.raises(ValueError, match="running_resistance_deviation_N"):
        replay_batch(one, running_resistance_deviation_N=np.ones(3))


def test_a_vehicle_without_running_resistance_scatter_is_refused_by_name(gradient_fit, monkeypatch):
    # The fit holds each application's running resistance by a prior row of A_sigma_N: with none,
    # the row would divide by zero.
    problem = gradient_fit[0]
    vehicle = problem.recordings[0].vehicle
    resistance = vehicle.running_resistance.model_copy(update={"A_sigma_N": 0.0})
    without_scatter = vehicle.model_copy(update={"running_resistance": resistance})
    monkeypatch.setattr(type(problem.recordings[0].metadata), "vehicle_config", property(lambda self: without_scatter))
    with pytest.raises(ValueError, match="A_sigma_N 0.0 N"):
        FitProblem(problem.recordings, problem.noise)
