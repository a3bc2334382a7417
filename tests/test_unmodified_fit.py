"""The unmodified model's fit from two starts (:meth:`brakegym.diagnosis.pipeline.Diagnoser.unmodified_fit`,
:meth:`brakegym.diagnosis.fitting.FitProblem.refit_nuisance_from_prior_centre`): each recording
keeps the better of a refit from its gridded start and one from the centre of its priors.

From the gridded start alone a recording could stop in a valley away from its priors' centre (a
friction factor at its start, a running resistance at its bound) and the unmodified model then
stood too high: every candidate gained what a refit of that recording's nuisance alone gains.
"""

import numpy as np
import pytest

from brakegym.diagnosis.fitting import FRICTION_FACTOR, NUISANCE_BOUNDS, RESISTANCE_DEVIATION
from brakegym.diagnosis.pipeline import Diagnoser
from brakegym.recordings.format import read_dataset
from brakegym.recordings.synth import EffectRequest, synthesize

pytestmark = pytest.mark.filterwarnings("ignore")


def recording_sse(problem, residual: np.ndarray) -> np.ndarray:
    return np.array(
        [residual[problem.recording_of == i] @ residual[problem.recording_of == i] for i in range(problem.n)]
    )


@pytest.fixture(scope="module")
def diagnoser(tmp_path_factory):
    folder = tmp_path_factory.mktemp("unmodified") / "set"
    synthesize(folder, 3, seed=11, effects=[EffectRequest("gradient", {"gradient_permil": 8.0})])
    return Diagnoser(read_dataset(folder).recordings)


def test_each_recording_keeps_the_better_of_its_two_starts(diagnoser):
    problem = diagnoser.problem
    # A poor start for the first recording: its friction factor and running resistance both at
    # their upper bounds; the others at the gridded start.
    start = problem.gridded_start()
    k_high = NUISANCE_BOUNDS["k"][1]
    dA_high = NUISANCE_BOUNDS["dA_sigmas"] * problem.resistance_sigma_N
    start[problem.nuisance_block(FRICTION_FACTOR).start] = k_high
    start[problem.nuisance_block(RESISTANCE_DEVIATION).start] = dA_high
    poor = problem.refit_nuisance([], {}, [], start, max_iterations=1)
    chosen = problem.refit_nuisance_from_prior_centre([], {}, [], poor)
    centre = problem.refit_nuisance([], {}, [], problem.initial_nuisance.copy())
    residuals, _ = problem.simulate([], {}, [], np.array([poor, centre, chosen]))
    poor_sse, centre_sse, chosen_sse = (recording_sse(problem, r) for r in residuals)
    np.testing.assert_array_equal(chosen_sse, np.minimum(poor_sse, centre_sse))
    assert chosen_sse[0] < poor_sse[0]  # the poor start is left
    lower, upper = problem.nuisance_bounds()
    assert np.all((chosen >= lower) & (chosen <= upper))


def test_the_unmodified_fit_is_no_worse_than_the_gridded_start_alone_for_any_recording(diagnoser):
    problem = diagnoser.problem
    gridded = problem.fit([], problem.gridded_start())
    both = diagnoser.unmodified_fit()
    assert np.all(recording_sse(problem, both.residual) <= recording_sse(problem, gridded.residual) + 1e-9)
    # The fit is a simulation at its point.
    simulated, _ = problem.simulate([], {}, [], both.x[None])
    np.testing.assert_allclose(both.residual, simulated[0], rtol=0, atol=1e-12)
