"""The chord iterations of the screening and the held-out prediction
(:meth:`brakegym.diagnosis.fitting.FitProblem.chord_refit`): what they return is a simulation at
the point they return, within the nuisance bounds, and no recording ends worse than it started.

Before, they returned the last linear step's projection, which no simulation at any point within
the bounds need give; the first assertion fails on that.
"""

import numpy as np
import pytest

from brakegym.diagnosis.fitting import FitProblem
from brakegym.diagnosis.inputs import zero_corrected
from brakegym.diagnosis.locate import estimate_noise_models
from brakegym.diagnosis.rules import DiagnosisRules
from brakegym.recordings.format import read_dataset
from brakegym.recordings.synth import EffectRequest, synthesize

pytestmark = pytest.mark.filterwarnings("ignore")


def test_chord_iterations_return_simulated_residuals_at_their_points(tmp_path):
    synthesize(tmp_path / "set", 3, seed=3, effects=[EffectRequest("gradient", {"gradient_permil": 6.0})])
    recordings = read_dataset(tmp_path / "set").recordings
    rules = DiagnosisRules()
    noise_models = estimate_noise_models(recordings, rules.noise_window_s)
    noise = {c: m.sigma for c, m in noise_models.items() if np.isfinite(m.sigma) and m.sigma > 0}
    problem = FitProblem([zero_corrected(r) for r in recordings], noise)
    nuisance = problem.gridded_start()
    _, jacobian = problem.jacobian([], {}, [], nuisance)
    profile = problem.profiler(jacobian)
    free = problem.free_parameters(["gradient"], {})
    # The truth, one far below it and none at all, each from the gridded start of the nuisance.
    points = np.column_stack([[6.0, 1.0, 0.0], np.tile(nuisance, (3, 1))])
    started, _ = problem.simulate(["gradient"], {}, free, points)
    residuals, moved = problem.chord_refit(["gradient"], {}, free, points, profile, rules.screen_chord_iterations)

    simulated, _ = problem.simulate(["gradient"], {}, free, moved)
    np.testing.assert_allclose(residuals, simulated, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(moved[:, :1], points[:, :1])  # the effect's parameters stay
    lower, upper = problem.nuisance_bounds()
    assert np.all((moved[:, 1:] >= lower) & (moved[:, 1:] <= upper))
    for i in range(problem.n):
        rows = problem.recording_of == i
        assert np.all(np.sum(residuals[:, rows] ** 2, axis=1) <= np.sum(started[:, rows] ** 2, axis=1))
