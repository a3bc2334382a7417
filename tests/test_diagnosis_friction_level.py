"""``brakegym diagnose`` on a friction level of a few percent: a shift shared by every recording's
friction factor, judged against the scatter of the factors about it (:func:`brakegym.diagnosis.
judging.friction_level_shift`). A level of 5 % is named and its interval holds the truth; under a
speed-sensor scale it is named with the scale; a set whose base friction is moved within its
scatter selects nothing; the level screens no worse than the unmodified model on a train-like set.

The tolerances were fixed before the tests first ran: a fitted level within 0.02 of the truth
(the factors' mean is known to about 0.05 / sqrt(8) = 0.018), and the 95 % interval holding it.
"""

import numpy as np
import pytest

from brakegym.diagnosis import diagnose
from brakegym.diagnosis.fitting import FRICTION_FACTOR
from brakegym.diagnosis.judging import shared_friction_shift
from brakegym.diagnosis.pipeline import Diagnoser
from brakegym.diagnosis.screening import Screening
from brakegym.diagnosis.weighting import Weighting
from brakegym.effects import Evidence, FrictionLevel
from brakegym.recordings.format import read_dataset
from brakegym.recordings.synth import EffectRequest, synthesize

pytestmark = pytest.mark.filterwarnings("ignore")

FRICTION_LEVEL_TOLERANCE = 0.02


def _level_entry(report, effects):
    return next(c for c in report["candidates"] if c["effects"] == effects)


def test_names_a_friction_level_of_five_percent(tmp_path):
    # Before, the recordings' friction factors took the level (every factor 5 % low), and the BIC
    # could not credit a shift that only the factors' prior rows see.
    mu_scale = 0.95
    result = synthesize(tmp_path / "set", 8, seed=5, effects=[EffectRequest("friction_level", {"mu_scale": mu_scale})])
    report = diagnose(result.folder, top_singles=2, pairs_from=0).report
    assert report["selected"] == ["friction_level"], report["summary"]
    fitted = report["parameters"]["mu_scale"]
    assert abs(fitted - mu_scale) <= FRICTION_LEVEL_TOLERANCE, fitted
    chosen = _level_entry(report, ["friction_level"])
    low, high = chosen["ci95"]["mu_scale"]
    assert low <= mu_scale <= high, (low, high)
    shift = chosen["friction_level_shift"]
    assert abs(shift["z"]) >= 2.0 and shift["level"] == pytest.approx(fitted, abs=1e-4)
    assert len(chosen["heldout_acts_on"]) == 8


def test_names_a_friction_level_of_six_percent_with_a_speed_sensor_scale(tmp_path):
    # A scale of 0.98 takes the unmodified model's chi^2 far down; the level shows only screened
    # on top of it (the forward step), and was read as the scale alone.
    mu_scale = 1.06
    result = synthesize(
        tmp_path / "set",
        8,
        seed=11,
        effects=[
            EffectRequest("friction_level", {"mu_scale": mu_scale}),
            EffectRequest("speed_sensor_scale", {"scale": 0.98}),
        ],
    )
    report = diagnose(result.folder).report
    assert report["selected"] == ["friction_level", "speed_sensor_scale"], report["summary"]
    fitted = report["parameters"]["mu_scale"]
    assert abs(fitted - mu_scale) <= FRICTION_LEVEL_TOLERANCE, fitted
    low, high = _level_entry(report, report["selected"])["ci95"]["mu_scale"]
    assert low <= mu_scale <= high, (low, high)


def test_selects_nothing_when_the_base_friction_is_moved_within_its_scatter(tmp_path, naming_rules):
    # The set's nominal mu_0 and power coefficient are both moved by 0.6-0.8 of their scatter
    # sigma: the factors' mean sits about 3 % off 1, a shift of the base model, not an effect.
    result = synthesize(tmp_path / "set", 8, seed=8, base_offset=True)
    assert result.key["base_offset"]["kind"] == "friction"
    report = diagnose(result.folder, top_singles=2, pairs_from=0, rules=naming_rules).report
    assert report["selected"] == [], report["summary"]
    assert report["parameters"] == {}


def test_the_shared_shift_is_judged_against_the_larger_of_the_prior_and_the_factors_scatter():
    prior_sigma = 0.05
    # Factors that agree more tightly than the prior says: the prior's scatter sets the error.
    tight = 1.05 * np.array([0.99, 1.01, 1.0, 0.995, 1.005, 1.0, 0.99, 1.01])
    shift = shared_friction_shift(1.05, tight, prior_sigma)
    assert shift.scatter == prior_sigma
    assert shift.standard_error == pytest.approx(prior_sigma / np.sqrt(8))
    assert shift.z == pytest.approx(0.05 / (prior_sigma / np.sqrt(8)))
    # Factors that scatter more than the prior says leave the level less certain.
    wide = 1.05 * np.array([0.9, 1.1, 1.0, 0.92, 1.08, 1.0, 0.9, 1.1])
    shift = shared_friction_shift(1.05, wide, prior_sigma)
    assert shift.scatter == pytest.approx(np.std(wide / 1.05, ddof=1))
    assert abs(shift.z) < 2.0


def test_a_friction_level_screens_no_worse_than_the_unmodified_model(tmp_path, synth_train_like):
    # With a level, each recording's friction factor is the product the data see and the level
    # only centres the factors' prior: its data rows do not depend on the level, and at the level
    # the factors share the prior rows are no larger than at 1. The screening must see that.
    # Before, its starts divided the factors by the level, which moved every recording's
    # friction by it. On a train-like set of the blind benchmark (seed 26, set 10: a level of
    # 0.88 with a rotating mass, contact-pressure friction and an ED brake) the level screened
    # above the unmodified chi^2, and it was never fitted.
    result = synth_train_like(tmp_path / "set", 631983099)
    assert "friction_level" in {effect["id"] for effect in result.key["effects"]}
    diagnoser = Diagnoser(read_dataset(result.folder).recordings)
    problem, baseline = diagnoser.problem, diagnoser.unmodified_fit()
    noise_rho = {channel: model.rho for channel, model in diagnoser.noise_models.items() if np.isfinite(model.rho)}
    weighting = Weighting(problem, baseline.residual, noise_rho)
    # Only the friction factors matter to the friction level's screening point.
    evidence = Evidence(
        peak_decel_mps2=1.0,
        peak_disc_C=100.0,
        friction_factors=baseline.x[problem.nuisance_block(FRICTION_FACTOR, len(baseline.free))],
        nominal_resistance=problem.recordings[0].vehicle.running_resistance,
    )
    screening = Screening(problem, weighting, diagnoser.rules, evidence, diagnoser.n_discs, baseline)
    point = screening.run([FrictionLevel.id])[FrictionLevel.id]
    unmodified = weighting.chi2(baseline.residual)
    assert point.chi2 <= unmodified, (point.theta, point.chi2, unmodified)
