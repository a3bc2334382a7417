"""``brakegym diagnose`` on sets with two library effects: pairs before singles (the forward step of
:mod:`brakegym.diagnosis.pipeline`). A gradient and a running resistance on recordings of mixed
loads are both named (a gradient's force grows with the mass, a running resistance's constant term
does not), and a friction level under a speed-sensor scale is named with it.

The tolerances were fixed before the tests first ran: a gradient within 1 permil or 20 % (as in
``tests/test_diagnosis.py``), a friction level within 0.03 of its scale.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from brakegym.diagnosis import diagnose
from brakegym.diagnosis.judging import Candidate, Judge, nested_candidates
from brakegym.diagnosis.pipeline import look_alike_swaps
from brakegym.diagnosis.report import single_or_pair_sentence
from brakegym.diagnosis.rules import DiagnosisRules
from brakegym.effects import in_library_order, nested_effects, special_cases
from brakegym.recordings.synth import EffectRequest, synthesize

pytestmark = pytest.mark.filterwarnings("ignore")

GRADIENT_TOLERANCE_PERMIL = 1.0
GRADIENT_TOLERANCE_SHARE = 0.2
FRICTION_LEVEL_TOLERANCE = 0.03


def test_names_a_gradient_and_a_running_resistance_on_mixed_loads(tmp_path):
    gradient_permil = 6.0
    resistance = {"A_N": 9000.0, "B_N_per_mps": 100.0, "C_N_per_mps2": 10.0}
    result = synthesize(
        tmp_path / "set",
        8,
        seed=7,
        effects=[
            EffectRequest("gradient", {"gradient_permil": gradient_permil}),
            EffectRequest("running_resistance", resistance),
        ],
    )
    # The loads differ between recordings: what tells the two forces apart.
    assert len({application["load"] for application in result.key["applications"]}) >= 2
    # The bootstrap of a pair at its fit; its eight interval ends untested (96 more refits).
    report = diagnose(result.folder, rules=DiagnosisRules(bootstrap_end_replicates=0)).report
    assert sorted(report["selected"]) == ["gradient", "running_resistance"], report["summary"]
    fitted = report["parameters"]["gradient_permil"]
    assert abs(fitted - gradient_permil) <= max(
        GRADIENT_TOLERANCE_PERMIL, GRADIENT_TOLERANCE_SHARE * abs(gradient_permil)
    ), fitted
    # The forward step screened the other effects on top of the single it started from.
    forward = report["forward_screening"]
    assert len(forward["given"]) == 1 and forward["given"][0] in report["selected"]
    (second,) = [e for e in report["selected"] if e not in forward["given"]]
    assert forward["chi2_eff_profiled"][second] < forward["chi2_eff_given"]


def test_names_a_friction_level_under_a_speed_sensor_scale(tmp_path, naming_rules):
    # The recordings' friction factors absorb most of a friction level, and a speed-sensor scale
    # takes the unmodified model's chi^2 down so far that the level never screens among the best
    # singles: only screened on top of the scale does it show. The pair is selected, or named
    # indistinguishable from the scale alone with what would separate them.
    mu_scale = 1.10
    result = synthesize(
        tmp_path / "set",
        8,
        seed=11,
        effects=[
            EffectRequest("friction_level", {"mu_scale": mu_scale}),
            EffectRequest("speed_sensor_scale", {"scale": 0.97}),
        ],
    )
    report = diagnose(result.folder, rules=naming_rules).report
    pair = ["friction_level", "speed_sensor_scale"]
    if report["selected"] == pair:
        fitted = report["parameters"]["mu_scale"]
    else:
        assert report["selected"] == ["speed_sensor_scale"], report["summary"]
        entry = next(e for e in report["indistinguishable_single_or_pair"] if e["pair"] == pair)
        assert entry["separating_measurement"]
        assert "friction_level" in report["summary"]
        fitted = entry["pair_parameters"]["mu_scale"]
    assert abs(fitted - mu_scale) <= FRICTION_LEVEL_TOLERANCE, fitted


def test_a_pair_holds_the_pair_with_the_effect_its_member_extends():
    # A gradient section is a whole-line gradient that starts and ends somewhere, and a profile of
    # two sections holds one section: the pair with the section holds the pair with the gradient.
    def candidate(*ids):
        return SimpleNamespace(effect_ids=in_library_order(ids))

    with_gradient = candidate("running_resistance", "gradient")
    with_section = candidate("gradient_section", "running_resistance")
    with_level = candidate("friction_level", "gradient")
    others = [with_gradient, with_level, with_section]
    assert with_gradient.effect_ids == ("gradient", "running_resistance")
    assert nested_candidates(with_section, others) == [with_gradient]
    assert nested_candidates(with_gradient, others) == []
    assert nested_candidates(candidate("friction_level", "gradient_section"), others) == [with_level]
    # A member that extends the other member holds nothing: the pair would be one effect.
    assert nested_candidates(candidate("gradient", "gradient_section"), others) == []
    # A profile holds a section, and through it the whole-line gradient.
    assert special_cases("gradient_sections") == ("gradient_section", "gradient")
    profile = candidate("gradient_sections", "running_resistance")
    assert nested_candidates(profile, others) == [with_section, with_gradient]
    assert nested_candidates(candidate("gradient", "gradient_sections"), others) == []


def test_each_effect_of_a_selected_pair_meets_the_look_alikes_of_the_other():
    # An adhesion limit selected, a failed unit beside it: the next passing singles (a gradient
    # and a rotating mass, lowest held-out error first) are fitted in either effect's place.
    def candidate(*ids, heldout_sse=0.0, passes=True):
        return SimpleNamespace(
            effect_ids=in_library_order(ids), passes=passes, heldout=SimpleNamespace(sse=np.array([heldout_sse]))
        )

    single = candidate("adhesion_limit", heldout_sse=1.0)
    pair = candidate("adhesion_limit", "brake_unit_failure")
    gradient = candidate("gradient", heldout_sse=2.0)
    rotating = candidate("rotating_mass", heldout_sse=3.0)
    singles = [
        single,
        candidate("brake_unit_failure", heldout_sse=1.5),
        rotating,
        gradient,
        candidate("friction_level", heldout_sse=0.5, passes=False),
        candidate("wet_pads", heldout_sse=4.0),
    ]
    swaps = look_alike_swaps(single, pair, singles, [pair], count=2)
    assert [(kept, other.effect_ids[0]) for kept, other in swaps] == [
        ("brake_unit_failure", "gradient"),
        ("brake_unit_failure", "rotating_mass"),
        ("adhesion_limit", "gradient"),
        ("adhesion_limit", "rotating_mass"),
    ]
    # A pair already fitted is not fitted again.
    fitted = [pair, candidate("adhesion_limit", "gradient")]
    swaps = look_alike_swaps(single, pair, singles, fitted, count=2)
    assert ("adhesion_limit", gradient) not in swaps and ("adhesion_limit", rotating) in swaps
    # Nor is an effect beside one it holds as a special case, through the whole chain: a profile
    # of two sections holds the whole-line gradient through a section.
    assert nested_effects("gradient_sections", "gradient") and nested_effects("gradient", "gradient_section")
    assert not nested_effects("gradient", "adhesion_limit")
    profile_pair = candidate("brake_unit_failure", "gradient_sections")
    units = candidate("brake_unit_failure", heldout_sse=1.0)
    swaps = look_alike_swaps(units, profile_pair, [units, gradient, rotating], [profile_pair], count=2)
    assert [(kept, other.effect_ids[0]) for kept, other in swaps] == [
        ("gradient_sections", "rotating_mass"),
        ("brake_unit_failure", "gradient"),
        ("brake_unit_failure", "rotating_mass"),
    ]


def test_a_look_alike_of_the_single_is_fitted_beside_the_pairs_second_effect(tmp_path, naming_rules):
    # Three failed brake units of sixteen take 18.75 % of the brake force, a rotating mass of 0.23
    # as much of the deceleration. Alone, the rotating mass fits better (it also takes up some of
    # the unfitted profile) and the forward step pairs the profile with it; the failed units are
    # fitted in its place beside the profile. With each application's running resistance fitted,
    # the swapped pair starts both sections within 5 m of the truth and has the lower BIC. Its
    # held-out t against the rotating-mass pair was 1.9 (p 0.057) while the chord iterations
    # returned projected residuals, and the two were named indistinguishable (their corrections
    # correlate 0.99: the data hold no rear-disc temperature and no coasting that would tell them
    # apart); judged by simulation it is 2.69 and the swapped pair, the truth, is selected. Either
    # verdict is right on these data; the one that keeps the rotating mass must say why.
    result = synthesize(
        tmp_path / "set",
        8,
        seed=1016164991,
        effects=[
            EffectRequest(
                "gradient_sections",
                {
                    "first_section_start_m": 254.8,
                    "first_section_length_m": 337.5,
                    "first_section_gradient_permil": -5.154,
                    "second_section_start_m": 816.3,
                    "second_section_length_m": 315.0,
                    "second_section_gradient_permil": 4.686,
                },
            ),
            EffectRequest("brake_unit_failure", {"failed_units": 3}),
        ],
    )
    report = diagnose(result.folder, rules=naming_rules).report
    by_effects = {tuple(candidate["effects"]): candidate for candidate in report["candidates"]}
    swapped = by_effects[("brake_unit_failure", "gradient_sections")]
    assert ("rotating_mass", "gradient_sections") in by_effects
    assert swapped["parameters"]["failed_units"] == 3
    for name, truth in (("first_section_start_m", 254.8), ("second_section_start_m", 816.3)):
        assert abs(swapped["parameters"][name] - truth) < 20.0, (name, swapped["parameters"][name])
    assert swapped["delta_bic"] < by_effects[("rotating_mass", "gradient_sections")]["delta_bic"]
    if report["selected"] != ["brake_unit_failure", "gradient_sections"]:
        assert report["selected"] == ["rotating_mass", "gradient_sections"], report["summary"]
        assert ["rotating_mass", "brake_unit_failure"] in report["indistinguishable"], report["summary"]
        # The summary says so, with the measurement that would separate the two.
        separating = report["separating_measurements"]["rotating_mass / brake_unit_failure"]
        assert "rotating_mass and brake_unit_failure (their corrections to the model correlate" in report["summary"]
        assert separating in report["summary"]


def judged(ids, heldout_sse, delta_bic):
    """A candidate with held-out errors per recording (one residual row each) and a BIC."""
    sse = np.asarray(heldout_sse, dtype=float)
    fit = SimpleNamespace(residual=np.sqrt(sse))
    return Candidate(in_library_order(ids), fit, 0.0, delta_bic, SimpleNamespace(sse=sse, residual=np.sqrt(sse)))


def judge_of_four_recordings():
    """A judge of four recordings whose unmodified model leaves a held-out error of 10 on each."""
    judge = Judge.__new__(Judge)
    names = [SimpleNamespace(name=f"stop{i}") for i in range(4)]
    judge.problem = SimpleNamespace(n=4, recording_of=np.arange(4), recordings=names)
    judge.rules = DiagnosisRules()
    judge.weighting = SimpleNamespace(signature_correlation=lambda *residuals: 0.9)
    judge.baseline = SimpleNamespace(residual=np.sqrt(np.full(4, 10.0)))
    judge.base_sse = np.full(4, 10.0)
    return judge


def test_a_pair_with_a_look_alike_of_the_best_single_replaces_it():
    # A stretch of low adhesion over most of the line is selected alone, an adhesion limit passes
    # beside it with a held-out error a little higher; a running resistance lowers the error
    # beside the limit only. The pair of the limit and the resistance beats both singles by every
    # rule and replaces the stretch; its look-alikes are then swapped in beside the limit.
    section = judged(("adhesion_section",), [2.0, 2.1, 1.9, 2.0], -900.0)
    limit = judged(("adhesion_limit",), [2.1, 2.2, 2.0, 2.1], -880.0)
    section_and_resistance = judged(("adhesion_section", "running_resistance"), [2.0, 2.1, 1.8, 2.0], -905.0)
    limit_and_resistance = judged(("adhesion_limit", "running_resistance"), [1.0, 1.1, 0.9, 1.0], -1000.0)
    judge = judge_of_four_recordings()
    verdict = judge.verdict([section, limit], [section_and_resistance, limit_and_resistance])
    assert verdict.selected is limit_and_resistance
    assert judge.held_single(limit_and_resistance, [section, limit]) is limit
    # Its held-out figures are against the selected single.
    assert limit_and_resistance.report["heldout_gain"] == pytest.approx(1 - 4.0 / 8.0, abs=1e-4)

    # A pair that beats the look-alike it holds but not the selected single is not selected.
    judge = judge_of_four_recordings()
    weak = judged(("adhesion_limit", "running_resistance"), [1.95, 2.05, 1.85, 1.95], -910.0)
    verdict = judge.verdict([section, limit], [section_and_resistance, weak])
    assert verdict.selected is section
    # Nor is a pair that holds no passing single.
    judge = judge_of_four_recordings()
    failing_limit = judged(("adhesion_limit",), [9.9, 10.1, 9.8, 10.2], 50.0)
    verdict = judge.verdict([section, failing_limit], [section_and_resistance, limit_and_resistance])
    assert verdict.selected is section


def test_the_summary_says_why_a_pair_beside_the_single_has_no_held_out_t():
    # The second effect of the pair changes the held-out prediction of one recording, fewer than
    # the held-out rule counts: no t, and the summary says why instead of printing None.
    entry = {
        "single": ["gradient"],
        "pair": ["gradient", "adhesion_limit"],
        "delta_bic_over_single": -19.4,
        "heldout_t_over_single": None,
        "heldout_acts_on_over_single": ["stop_03.csv"],
        "separating_measurement": "coasting phases",
    }
    sentence = single_or_pair_sentence(entry)
    assert "None" not in sentence
    assert "no held-out t: it changes the held-out prediction of 1 recording(s) only" in sentence
    assert "BIC -19" in sentence and "gradient alone or with adhesion_limit" in sentence
    with_t = single_or_pair_sentence(dict(entry, heldout_t_over_single=2.7))
    assert "held-out t 2.7, against gradient alone" in with_t
