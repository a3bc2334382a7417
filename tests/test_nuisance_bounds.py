"""The chord iterations of the screening and the held-out prediction refit each recording's
nuisance (initial speed, initial disc temperature, friction factor) by a linear step within the
nuisance bounds (:class:`brakegym.diagnosis.fitting.NuisanceProfile`).

The set has a friction level of 0.5 that the unmodified model must explain with each
recording's friction factor, below the factors' lower bound of 0.6: every factor rests on its
bound. Solved without the bounds and clipped, the step let the initial speed and disc
temperature make up for the clipped factor, and a chord iteration from the fit predicted a
chi^2 40 % below the fit's where a simulation at the point it moved to stood 8 % above it.
"""

import numpy as np
import pytest

from brakegym.diagnosis.fitting import NUISANCE_BOUNDS, FitProblem
from brakegym.diagnosis.inputs import zero_corrected
from brakegym.diagnosis.locate import estimate_noise_models
from brakegym.diagnosis.rules import DiagnosisRules
from brakegym.recordings.format import read_dataset
from brakegym.recordings.synth import EffectRequest, synthesize

pytestmark = pytest.mark.filterwarnings("ignore")


@pytest.fixture(scope="module")
def unmodified_fit_on_bound(tmp_path_factory):
    folder = tmp_path_factory.mktemp("nuisance_bounds") / "set"
    synthesize(folder, 3, seed=4, effects=[EffectRequest("friction_level", {"mu_scale": 0.5})])
    recordings = read_dataset(folder).recordings
    rules = DiagnosisRules()
    noise_models = estimate_noise_models(recordings, rules.noise_window_s)
    noise = {c: m.sigma for c, m in noise_models.items() if np.isfinite(m.sigma) and m.sigma > 0}
    problem = FitProblem([zero_corrected(r) for r in recordings], noise)
    fit = problem.fit([], problem.gridded_start(), max_iterations=rules.fit_iterations)
    return problem, fit


def test_every_friction_factor_rests_on_its_lower_bound(unmodified_fit_on_bound):
    problem, fit = unmodified_fit_on_bound
    factors = fit.x[2 * problem.n :]
    np.testing.assert_allclose(factors, NUISANCE_BOUNDS["k"][0])


def test_the_bounded_nuisance_step_meets_the_optimality_conditions_on_the_box(unmodified_fit_on_bound):
    """The step minimises |r + J s| within the bounds (Karush-Kuhn-Tucker: no descent along a
    free coordinate, none into the box from a bound), its residual is the linear prediction of
    the moved point, and it lies between the unbounded optimum and the clipped unbounded step."""
    problem, fit = unmodified_fit_on_bound
    jac = fit.jacobian  # no effect parameters: every column is a nuisance one
    lower, upper = problem.nuisance_bounds()
    low, high = lower - fit.x, upper - fit.x
    # A residual whose unbounded step leaves the bounds: the fit's own, the factors pulled lower.
    residual = fit.residual + jac[:, 2 * problem.n :] @ np.full(problem.n, 0.05)
    profile = problem.profiler(jac)
    unbounded, unbounded_step = profile.project(residual)
    assert np.any(unbounded_step < low - 1e-9)

    projected, step = profile.project(residual, (low, high))
    assert np.all(step >= low - 1e-12) and np.all(step <= high + 1e-12)
    np.testing.assert_allclose(projected, residual + jac @ step, rtol=0, atol=1e-9 * np.abs(residual).max())
    gradient = jac.T @ projected
    scale = np.linalg.norm(jac, axis=0) * np.linalg.norm(projected)
    at_low, at_high = step <= low + 1e-9, step >= high - 1e-9
    free = ~(at_low | at_high)
    assert at_low.any()
    assert np.all(np.abs(gradient[free]) <= 1e-6 * scale[free])
    assert np.all(gradient[at_low] >= -1e-6 * scale[at_low])
    assert np.all(gradient[at_high] <= 1e-6 * scale[at_high])

    clipped = residual + jac @ np.clip(unbounded_step, low, high)
    assert unbounded @ unbounded <= projected @ projected <= clipped @ clipped


def test_a_chord_step_predicts_the_chi2_of_the_point_it_moves_to(unmodified_fit_on_bound):
    """One chord iteration from the fit (its own nuisance Jacobian) predicts the chi^2 of a point
    within the bounds, and a simulation there meets the prediction: the linear range of the
    samples holds for a step this small. Solved without the bounds and clipped, the predicted
    residual belonged to a point outside them, a third below what the clipped point reaches."""
    problem, fit = unmodified_fit_on_bound
    projected, points = problem.chord_refit([], {}, [], fit.x[None], problem.profiler(fit.jacobian), 1)
    lower, upper = problem.nuisance_bounds()
    assert np.all(points[0] >= lower) and np.all(points[0] <= upper)
    predicted = projected[0] @ projected[0]
    simulated, _ = problem.simulate([], {}, [], points)
    assert predicted <= fit.residual @ fit.residual
    assert predicted == pytest.approx(simulated[0] @ simulated[0], rel=0.02)
