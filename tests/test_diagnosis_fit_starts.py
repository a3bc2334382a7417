"""A single's full fit starts from more than its best screened point: the nuisance gridded with
the effect acting, and the best point of another valley of the screening grid
(``Diagnoser._fit_screened``).

The sets are the coverage benchmark's three misses that these starts address, written by
``brakegym synth``; the thresholds were fixed before the test first ran: the fit lands within
0.05 of the true wet-pads loss and within a factor 1.5 of its drying energy (from the other
valley it ended at 0.37 and 5.1 MJ), within 1 permil of the true gradient through the real
measurement chain (from the unmodified model's nuisance it ended at 6.6), within 15 K of the true
fade onset and 0.05 of its loss where the grid's second minimum lies on the plateau of onsets the
discs never reach (from there it ended at the bounds, 225 degC and 0.6 for 142.4 degC and 0.284).
"""

import numpy as np
import pytest

from brakegym.diagnosis import Diagnoser, DiagnosisRules
from brakegym.diagnosis.screening import grid, grid_minima, grid_valley
from brakegym.effects import EFFECTS
from brakegym.recordings.chain import load_measurement_chain
from brakegym.recordings.synth import EffectRequest, synthesize

pytestmark = pytest.mark.filterwarnings("ignore")


def test_grid_minima_are_the_points_below_every_neighbour():
    rules = DiagnosisRules()
    assert len(grid("rotating_mass", rules)) == rules.grid_points_1d == 8
    one_axis = np.array([5.0, 3.0, 4.0, 6.0, 2.0, 2.5, 7.0, 1.0])
    assert grid_minima("rotating_mass", rules, one_axis) == [1, 4, 7]
    # Two parameters on a 3 x 3 grid, first parameter along the rows (itertools.product's order).
    two_axes = np.array([[4.0, 5.0, 1.0], [2.0, 6.0, 7.0], [3.0, 8.0, 9.0]])
    assert grid_minima("wet_pads", rules, two_axes.ravel()) == [2, 3]
    # A tie is no minimum: a flat floor has no point below every neighbour.
    assert grid_minima("rotating_mass", rules, np.ones(8)) == []


def test_the_valley_of_a_point_is_where_descent_from_its_nearest_grid_point_ends():
    rules = DiagnosisRules()
    one_axis = np.array([5.0, 3.0, 4.0, 6.0, 2.0, 2.5, 7.0, 1.0])
    (spec,) = EFFECTS["rotating_mass"].parameters
    points = spec.grid(8)
    # Between grid points 5 and 6, nearer 5: down to 4. At grid point 2: down to 1.
    assert grid_valley("rotating_mass", rules, one_axis, np.array([0.8 * points[5] + 0.2 * points[6]])) == 4
    assert grid_valley("rotating_mass", rules, one_axis, points[2:3]) == 1
    assert grid_valley("rotating_mass", rules, one_axis, points[7:8]) == 7


def _fitted(tmp_path, seed, effect_id, rules, chain=None):
    result = synthesize(
        tmp_path / "set",
        8,
        seed,
        effects=[EffectRequest(effect_id)],
        key_path=tmp_path / "key.json",
        measurement_chain=load_measurement_chain(chain) if chain else None,
    )
    (entry,) = result.key["effects"]
    candidate = Diagnoser(result.recordings, rules=rules).fit_effects([effect_id])
    return entry["parameters"], candidate.report["parameters"]


def test_wet_pads_are_fitted_in_the_valley_of_the_truth(tmp_path, naming_rules):
    truth, fitted = _fitted(tmp_path, 200202, "wet_pads", naming_rules)
    assert abs(fitted["initial_loss"] - truth["initial_loss"]) <= 0.05, (truth, fitted)
    ratio = fitted["drying_energy_MJ"] / truth["drying_energy_MJ"]
    assert 1 / 1.5 <= ratio <= 1.5, (truth, fitted)


def test_a_steep_gradient_through_a_real_chain_is_fitted_whole(tmp_path, naming_rules):
    truth, fitted = _fitted(tmp_path, 300100, "gradient", naming_rules, chain="real")
    assert abs(fitted["gradient_permil"] - truth["gradient_permil"]) <= 1.0, (truth, fitted)


def test_a_fade_is_not_started_where_it_acts_on_nothing(tmp_path, naming_rules):
    truth, fitted = _fitted(tmp_path, 400404, "thermal_fade", naming_rules)
    assert abs(fitted["onset_C"] - truth["onset_C"]) <= 15.0, (truth, fitted)
    assert abs(fitted["loss_per_100K"] - truth["loss_per_100K"]) <= 0.05, (truth, fitted)
