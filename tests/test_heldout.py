"""The held-out prediction (:mod:`brakegym.diagnosis.heldout`) of a parameter that only the
recording left out informs.

A gradient section begins where only the longest of five stops reaches. Left out, that stop's
section is known to no other recording: its prediction takes the section's size at its
no-effect value (no section) instead of a Gauss-Newton step of the others, which along a
direction they do not inform runs to a bound. The stop is then predicted as the unmodified
model predicts it. The other recordings' predictions, and the leave-one-out steps the jackknife
interval reads, do not change.

The thresholds were fixed before the test first ran: the section's gradient is named uninformed
for that stop alone, its held-out error is within 1 % of the unmodified model's, and every other
number is the same bit for bit.
"""

import numpy as np
import pytest

from brakegym.diagnosis.fitting import FitProblem
from brakegym.diagnosis.heldout import held_out
from brakegym.diagnosis.inputs import zero_corrected
from brakegym.diagnosis.locate import estimate_noise_models
from brakegym.diagnosis.rules import DiagnosisRules
from brakegym.diagnosis.weighting import Weighting
from brakegym.recordings.synth import EffectRequest, synthesize

pytestmark = pytest.mark.filterwarnings("ignore")

# Seed 3's five stops run 580-1222 m; only the first (1222 m) reaches a section from 1050 m.
SECTION = {"section_start_m": 1050.0, "section_length_m": 600.0, "section_gradient_permil": 10.0}
REACHES_IT = "rec_001"


@pytest.fixture(scope="module")
def section_fit(tmp_path_factory):
    folder = tmp_path_factory.mktemp("heldout") / "set"
    recordings = synthesize(folder, 5, seed=3, effects=[EffectRequest("gradient_section", SECTION)]).recordings
    rules = DiagnosisRules()
    noise_models = estimate_noise_models(recordings, rules.noise_window_s)
    noise = {c: m.sigma for c, m in noise_models.items() if np.isfinite(m.sigma) and m.sigma > 0}
    problem = FitProblem([zero_corrected(r) for r in recordings], noise)
    start = np.concatenate([list(SECTION.values()), problem.gridded_start()])
    fit = problem.fit(["gradient_section"], start, max_iterations=rules.fit_iterations)
    baseline = problem.fit([], problem.gridded_start())
    weighting = Weighting(problem, baseline.residual, {c: m.rho for c, m in noise_models.items() if np.isfinite(m.rho)})
    return problem, weighting, fit, baseline, rules


def test_a_section_only_the_left_out_stop_reaches_is_predicted_absent(section_fit):
    problem, weighting, fit, baseline, rules = section_fit
    names = [r.name for r in problem.recordings]
    assert REACHES_IT in names[0]
    refitted = held_out(problem, weighting, fit, rules.screen_chord_iterations, uninformed_share=0.0)
    guarded = held_out(problem, weighting, fit, rules.screen_chord_iterations, rules.heldout_uninformed_share)
    assert refitted.uninformed == [()] * 5
    assert "section_gradient_permil" in guarded.uninformed[0]
    assert guarded.uninformed[1:] == [()] * 4
    unmodified = held_out(problem, weighting, baseline, rules.screen_chord_iterations, rules.heldout_uninformed_share)
    assert abs(guarded.sse[0] - unmodified.sse[0]) <= 0.01 * unmodified.sse[0], (guarded.sse[0], unmodified.sse[0])
    np.testing.assert_array_equal(guarded.sse[1:], refitted.sse[1:])
    others = problem.recording_of != 0
    np.testing.assert_array_equal(guarded.residual[others], refitted.residual[others])
    np.testing.assert_array_equal(guarded.steps, refitted.steps)
