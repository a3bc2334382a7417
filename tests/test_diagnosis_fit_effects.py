"""``Diagnoser.fit_effects``: a named model fitted without any selection, reported as a selected
model is (parameters, the Gauss-Newton/jackknife interval, the bootstrap's, their hull).

The thresholds were fixed before the test first ran: started from its screening or at half the
true gradient, the fit lands within 15 % of it, and the reported interval holds it and both intervals it is made of.
A thermal fade that one stop of eight reaches (coverage set 800104 of ``benchmarks/bench_coverage.py``)
is reported as resting on that stop, the hottest, and its interval holds it. On a concealed profile
of two sections, the one stop that brakes into the second is predicted better held out than by
the unmodified model.
"""

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from brakegym.diagnosis import Diagnoser, DiagnosisRules
from brakegym.diagnosis.fitting import FitProblem
from brakegym.effects import GradientSection
from brakegym.recordings.columns import DISC_TEMPERATURE
from brakegym.recordings.metadata import GradientProfile
from brakegym.recordings.synth import EffectRequest, synthesize

pytestmark = pytest.mark.filterwarnings("ignore")

GRADIENT_PERMIL = 6.0


@pytest.fixture(scope="module")
def diagnoser(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fit_effects") / "set"
    recordings = synthesize(
        folder, 5, seed=3, effects=[EffectRequest("gradient", {"gradient_permil": GRADIENT_PERMIL})]
    ).recordings
    return Diagnoser(recordings)


@pytest.mark.parametrize("start", [None, {"gradient_permil": GRADIENT_PERMIL / 2.0}], ids=["screened", "given"])
def test_a_named_gradient_is_fitted_with_the_intervals_of_a_selected_model(diagnoser, start):
    candidate = diagnoser.fit_effects(["gradient"], start)
    report = candidate.report
    assert candidate.effect_ids == ("gradient",)
    fitted = report["parameters"]["gradient_permil"]
    assert abs(fitted - GRADIENT_PERMIL) <= 0.15 * GRADIENT_PERMIL, fitted
    low, high = report["ci95"]["gradient_permil"]
    assert low <= GRADIENT_PERMIL <= high, (low, high)
    for part in ("ci95_gauss_newton_jackknife", "ci95_bootstrap"):
        part_low, part_high = report[part]["gradient_permil"]
        assert low <= part_low and part_high <= high, (part, report[part], report["ci95"])
    assert report["bootstrap_replicates"] == diagnoser.rules.bootstrap_replicates
    # The ends tested by replicates of their own only widen the interval drawn at the fit.
    assert report["bootstrap_end_replicates"] == diagnoser.rules.bootstrap_end_replicates
    at_fit_low, at_fit_high = report["ci95_bootstrap_at_fit"]["gradient_permil"]
    boot_low, boot_high = report["ci95_bootstrap"]["gradient_permil"]
    assert boot_low <= at_fit_low < at_fit_high <= boot_high
    assert report["rms_after"]["speed_mps"] < report["rms_before"]["speed_mps"]
    assert report["not_bounded_by_data"] == []  # the interval holds the gradient to a few permil


def test_an_unknown_effect_is_refused_by_name(diagnoser):
    with pytest.raises(ValueError, match="unknown effect.*'gradiant'"):
        diagnoser.fit_effects(["gradiant"], {})


def test_a_parameter_without_a_value_is_refused_by_name(diagnoser):
    with pytest.raises(ValueError, match="onset_C"):
        diagnoser.fit_effects(["thermal_fade"], {"loss_per_100K": 0.1})
    # An integer parameter is held, so its value goes in ``fixed``.
    with pytest.raises(ValueError, match="failed_units"):
        diagnoser.fit_effects(["brake_unit_failure"], {})


def test_an_integer_parameter_is_held_where_it_is_given(diagnoser):
    # Screened with the value held, the failed units stay at it: the model the user names, not the
    # one the screening would pick (on a gradient set, with no failed unit at all).
    candidate = diagnoser.fit_effects(["brake_unit_failure"], fixed={"failed_units": 3.0})
    assert candidate.report["parameters"] == {"failed_units": 3.0}
    assert candidate.report["ci95"] == {"failed_units": [3.0, 3.0]}


def test_a_screening_point_beyond_the_bounds_is_screened_at_the_bound(diagnoser, monkeypatch):
    """A step along position can read steeper than any section the library allows (a -45 permil
    step on a train-like set of the blind benchmark, seed 1055700636, stopped the diagnosis with
    an out-of-bounds error). The screening starts such a point at the bound instead, and the fit
    stays inside the bounds."""
    specs = GradientSection.parameters
    steep = np.array([100.0, 400.0, -60.0])
    np.testing.assert_array_equal(GradientSection.inside_bounds(steep), [100.0, 400.0, specs[2].lower])
    monkeypatch.setattr(GradientSection, "screening_points", classmethod(lambda cls, evidence: [steep]))
    quick = Diagnoser(diagnoser.recordings, rules=DiagnosisRules(bootstrap_replicates=2, fit_iterations=2))
    parameters = quick.fit_effects(["gradient_section"]).report["parameters"]
    for spec in specs:
        assert spec.lower <= parameters[spec.name] <= spec.upper, (spec.name, parameters)


def test_the_fits_run_on_one_blas_thread_whatever_the_callers_limit(diagnoser, monkeypatch):
    """A multithreaded BLAS sums in an order set by its thread count; a verdict that turns on the
    last bits then depends on the machine's cores (a train-like set of the blind benchmark, seed
    1055700636, selected a profile of two sections on two BLAS threads and nothing on one). The
    diagnosis limits BLAS to one thread whatever the caller set."""
    seen = []
    fit = FitProblem.fit

    def fit_and_record_threads(self, *args, **kwargs):
        seen.extend(pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas")
        return fit(self, *args, **kwargs)

    monkeypatch.setattr(FitProblem, "fit", fit_and_record_threads)
    quick = Diagnoser(diagnoser.recordings, rules=DiagnosisRules(bootstrap_replicates=2, fit_iterations=2))
    with threadpool_limits(limits=2, user_api="blas"):
        quick.fit_effects(["gradient"], {"gradient_permil": GRADIENT_PERMIL / 2.0})
        outside = [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]
    assert seen and set(seen) == {1}, seen
    assert outside and set(outside) == {2}, outside  # the caller's limit is back after the fit


def test_a_fade_that_one_stop_reaches_is_reported_as_resting_on_that_stop(tmp_path):
    # Left out, the one stop that reaches the fade's onset leaves the others nothing to rest it
    # on: the report says which stop it rests on, and its interval is the bootstrap's.
    result = synthesize(tmp_path / "set", 8, seed=800104, effects=[EffectRequest("thermal_fade")])
    truth = result.key["effects"][0]["parameters"]
    diagnoser = Diagnoser(result.recordings)
    candidate = diagnoser.fit_effects(["thermal_fade"])
    report = candidate.report
    hottest = max(result.recordings, key=lambda r: np.nanmax(r.channel(DISC_TEMPERATURE)))
    assert report["resting_on_one_recording"] == {name: hottest.name for name in truth}
    for name, value in truth.items():
        low, high = report["ci95"][name]
        assert low <= value <= high, (name, value, report["ci95"])
        assert report["ci95"][name] == report["ci95_bootstrap"][name]
    # Without that stop nothing says the fade is there: it is predicted with the fade absent,
    # which is the unmodified model's fit of it (the others' bounded refit stepped the onset to a
    # bound, a prediction a hundred times worse).
    i = result.recordings.index(hottest)
    held = candidate.heldout.held_at_no_effect
    loss = [parameter.name for parameter in candidate.fit.free].index("loss_per_100K")
    assert held[i, loss] and held.sum() == 1, held  # the loss; the onset only places the fade
    assert report["heldout_at_no_effect"] == {"loss_per_100K": [hottest.name]}
    rows = diagnoser.problem.recording_of == i
    predicted = float(np.sum(candidate.heldout.residual[rows] ** 2))
    unmodified = float(np.sum(diagnoser.unmodified_fit().residual[rows] ** 2))
    assert predicted == unmodified


def test_a_profiles_section_that_one_stop_brakes_into_is_predicted_better_than_without_it(tmp_path, naming_rules):
    # A concealed profile (level, 8 permil up over 200-500 m, level, 9 permil down from 700 m):
    # one stop of eight brakes into the second section. Left out, the others' step on their own
    # gradient predicts it better than the unmodified model does; a step on the stop's gradient
    # turned round (the set's gradient taken as zero, which it is not) ran the second section's
    # gradient towards its bound and predicted that stop 4.3 times worse than without the profile.
    profile = GradientProfile(start_m=[0.0, 200.0, 500.0, 700.0], gradient_permil=[0.0, 8.0, 0.0, -9.0])
    result = synthesize(tmp_path / "set", 8, seed=5, gradient_profile=profile, declare_gradient_profile=False)
    diagnoser = Diagnoser(result.recordings, rules=naming_rules)
    start = {
        "first_section_start_m": 200.0,
        "first_section_length_m": 300.0,
        "first_section_gradient_permil": 8.0,
        "second_section_start_m": 700.0,
        "second_section_length_m": 1000.0,
        "second_section_gradient_permil": -9.0,
    }
    candidate = diagnoser.fit_effects(["gradient_sections"], start=start)
    second = [parameter.name for parameter in candidate.fit.free].index("second_section_gradient_permil")
    stop = int(np.argmin(candidate.heldout.others_share[:, second]))
    assert candidate.heldout.others_share[stop, second] < 0.1  # the one stop that brakes into it
    problem = diagnoser.problem
    unmodified = diagnoser.unmodified_fit().residual
    rows = problem.recording_of == stop
    assert np.sum(candidate.heldout.residual[rows] ** 2) < np.sum(unmodified[rows] ** 2)
