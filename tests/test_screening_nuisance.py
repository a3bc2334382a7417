"""The screening's best point of each effect with its nuisance refitted on fresh Jacobians
(``DiagnosisRules.screen_nuisance_iterations``), before its one-step refinement.

Under a steep gradient through the real measurement chain the unmodified model's nuisance has
taken much of the slope into every recording's running resistance (most at their bound) and
initial disc temperature. The chord iterations step with that fit's Jacobian and do not follow so
far: the gradient screens well above where it fits, at half its value.
"""

import numpy as np
import pytest

from brakegym.diagnosis.fitting import FRICTION_FACTOR
from brakegym.diagnosis.pipeline import Diagnoser
from brakegym.diagnosis.rules import DiagnosisRules
from brakegym.diagnosis.screening import Screening
from brakegym.effects import Evidence
from brakegym.recordings.chain import load_measurement_chain
from brakegym.recordings.format import read_dataset
from brakegym.recordings.model_form import load_model_form
from brakegym.recordings.synth import EffectRequest, synthesize

pytestmark = pytest.mark.filterwarnings("ignore")
GRADIENT_PERMIL = 14.0


def test_a_steep_gradient_screens_nearer_its_value_with_the_nuisance_refitted(tmp_path):
    synthesize(
        tmp_path / "set",
        4,
        seed=7,
        effects=[EffectRequest("gradient", {"gradient_permil": GRADIENT_PERMIL})],
        measurement_chain=load_measurement_chain("real"),
        model_form=load_model_form("real_train"),
    )
    diagnoser = Diagnoser(read_dataset(tmp_path / "set").recordings)
    problem = diagnoser.problem
    baseline = diagnoser.unmodified_fit()
    weighting = diagnoser.weighting(baseline)
    # Only the friction factors and the nominal resistance matter to a gradient's screening.
    evidence = Evidence(
        peak_decel_mps2=1.0,
        peak_disc_C=100.0,
        friction_factors=baseline.x[problem.nuisance_block(FRICTION_FACTOR)],
        nominal_resistance=problem.recordings[0].vehicle.running_resistance,
    )
    screened = {}
    for iterations in (0, DiagnosisRules().screen_nuisance_iterations):
        rules = DiagnosisRules(screen_nuisance_iterations=iterations)
        screening = Screening(problem, weighting, rules, evidence, diagnoser.n_discs, baseline)
        screened[iterations] = screening.run(["gradient"])["gradient"]
    chord_only, refitted = screened.values()
    assert refitted.chi2 < 0.5 * chord_only.chi2, (refitted.chi2, chord_only.chi2)
    assert abs(refitted.theta[0] - GRADIENT_PERMIL) < abs(chord_only.theta[0] - GRADIENT_PERMIL)
    # What the screening reports is simulated at the point it returns.
    free = problem.free_parameters(["gradient"], {})
    simulated, _ = problem.simulate(["gradient"], {}, free, np.concatenate([refitted.theta, refitted.nuisance])[None])
    assert weighting.chi2(simulated[0]) == pytest.approx(refitted.chi2, rel=1e-9)
    lower, upper = problem.nuisance_bounds()
    assert np.all((refitted.nuisance >= lower) & (refitted.nuisance <= upper))
