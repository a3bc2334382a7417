"""The blind benchmark's bookkeeping (``benchmarks/bench_diagnosis.py``) on hand-built rows: pairs
counted both ways, the confusion matrix, the false-naming rate, interval coverage on the sets
where the model is right; and the SINDy baseline (:mod:`brakegym.diagnosis.baseline`) recovering
a known sparse answer from a synthetic residual. No diagnosis runs here."""

import itertools
import json

import numpy as np
import pytest

from brakegym.units import STANDARD_GRAVITY_MPS2


@pytest.fixture(scope="module")
def bench(load_benchmark):
    return load_benchmark("bench_diagnosis")


def row(truth, selected, *, out_of_library=(), unexplained=False, parameters=None, ci95=None, method="brakegym"):
    """A row as the benchmark writes it; ``truth`` maps effect ids to their parameters."""
    ids = list(truth)
    kind = ("unexplained" if out_of_library else "none") if not ids else ("single" if len(ids) == 1 else "pair")
    if kind in ("none", "unexplained"):
        hit = not selected
    elif kind == "single":
        hit = ids[0] in selected
    else:
        hit = bool(set(ids) & set(selected))
    return {
        "index": 0,
        "seed": 1,
        "recordings": 8,
        "method": method,
        "measurement_chain": "real",
        "model_form": "real_train" if out_of_library else None,
        "kind": kind,
        "truth": [{"id": e, "parameters": p, "drawn": list(p)} for e, p in truth.items()],
        "out_of_library": list(out_of_library),
        "base_offset": False,
        "selected": list(selected),
        "parameters": parameters or {},
        "ci95": ci95 or {},
        "indistinguishable": [],
        "unconfirmed": [],
        "unexplained": unexplained,
        "hit": hit,
        "expressed": ids,
        "seconds": 40.0,
    }


@pytest.fixture
def rows():
    return [
        # A pair with both named, and the model right: intervals judged.
        row(
            {"gradient": {"gradient_permil": -5.0}, "friction_level": {"mu_scale": 1.1}},
            ["gradient", "friction_level"],
            parameters={"gradient_permil": -5.2, "mu_scale": 1.12},
            ci95={"gradient_permil": [-5.5, -4.9], "mu_scale": [1.115, 1.125]},
        ),
        # A pair with one of two named, and a third effect named falsely.
        row(
            {"gradient": {"gradient_permil": 3.0}, "wet_pads": {"initial_loss": 0.3, "drying_energy_MJ": 1.0}},
            ["gradient", "rotating_mass"],
            parameters={"gradient_permil": 3.1, "mass_factor": 0.05},
            ci95={"gradient_permil": [2.9, 3.3], "mass_factor": [0.04, 0.06]},
        ),
        # A single effect named right: its interval covers.
        row(
            {"gradient": {"gradient_permil": 2.0}},
            ["gradient"],
            parameters={"gradient_permil": 2.1},
            ci95={"gradient_permil": [1.8, 2.4]},
        ),
        # Effect-free: a false name.
        row({}, ["friction_level"], parameters={"mu_scale": 1.05}, ci95={"mu_scale": [1.04, 1.06]}),
        # Effect-free and nothing selected.
        row({}, []),
        # Only effects outside the library: left unexplained (right), and named falsely (wrong).
        row({}, [], out_of_library=["contact_pressure_friction"], unexplained=True),
        row({}, ["friction_level"], out_of_library=["contact_pressure_friction"]),
    ]


def test_pairs_are_counted_both_ways(bench, rows):
    numbers = bench.metrics(rows)
    assert numbers["pairs"] == {"sets": 2, "both_named": 1, "at_least_one_named": 2, "both_named_or_alternative": 1}
    assert numbers["kinds"]["pair"] == {"sets": 2, "hits": 2}
    assert numbers["kinds"]["single"] == {"sets": 1, "hits": 1}
    assert numbers["kinds"]["none"] == {"sets": 2, "hits": 1}
    assert numbers["kinds"]["unexplained"] == {"sets": 2, "hits": 1}
    assert numbers["unexplained"] == {"sets": 2, "nothing_selected": 1, "said_unexplained": 1}


def test_a_pair_reported_as_the_alternative_to_one_of_its_effects_counts_apart(bench):
    """One effect of the pair selected with the pair of both reported as indistinguishable from it
    counts in the third way only; a different pair reported, or a false name beside the one
    selected, does not."""
    truth = {"thermal_fade": {"onset_C": 200.0, "loss_per_100K": 0.2}, "temperature_sensor_lag": {"tau_s": 3.0}}
    offered = row(truth, ["temperature_sensor_lag"])
    offered["single_or_pair"] = [["thermal_fade", "temperature_sensor_lag"], ["temperature_sensor_lag", "wet_pads"]]
    other = row(truth, ["temperature_sensor_lag"])
    other["single_or_pair"] = [["temperature_sensor_lag", "wet_pads"]]
    false_beside = row(truth, ["temperature_sensor_lag", "rotating_mass"])
    false_beside["single_or_pair"] = [["thermal_fade", "temperature_sensor_lag"]]
    numbers = bench.metrics([offered, other, false_beside])
    assert numbers["pairs"] == {"sets": 3, "both_named": 0, "at_least_one_named": 3, "both_named_or_alternative": 1}


def test_confusion_counts_every_drawn_effect_against_every_verdict(bench, rows):
    confusion = bench.metrics(rows)["confusion"]
    assert confusion["gradient"] == {"gradient": 3, "friction_level": 1, "rotating_mass": 1}
    assert confusion["friction_level"] == {"gradient": 1, "friction_level": 1}
    assert confusion["wet_pads"] == {"gradient": 1, "rotating_mass": 1}
    assert confusion["nothing"] == {"friction_level": 1, "nothing": 1}
    assert confusion["unexplained"] == {"unexplained": 1, "friction_level": 1}
    row_sets = bench.metrics(rows)["confusion_row_sets"]
    assert row_sets == {"gradient": 3, "friction_level": 1, "wet_pads": 1, "nothing": 2, "unexplained": 2}


def test_false_naming_over_all_sets_and_per_effect(bench, rows):
    false = bench.metrics(rows)["false_naming"]
    # The pair that named rotating_mass, the effect-free set and the out-of-library set that
    # named friction_level.
    assert (false["sets_with_a_false_name"], false["sets"]) == (3, 7)
    assert false["rate"] == pytest.approx(3 / 7)
    friction = false["per_effect"]["friction_level"]
    assert (friction["falsely_named"], friction["sets_without_it"], friction["times_selected"]) == (2, 6, 3)
    rotating = false["per_effect"]["rotating_mass"]
    assert (rotating["falsely_named"], rotating["sets_without_it"]) == (1, 7)
    assert false["per_effect"]["gradient"]["falsely_named"] == 0


def test_selected_models_with_a_parameter_the_data_do_not_bound_are_counted(bench, rows):
    # None of the fixture's intervals spans a search range.
    assert bench.metrics(rows)["not_bounded_by_data"] == {"sets": 0, "with_a_false_name": 0}
    # A friction level's mu_scale spans 0.5..1.5; a gradient's -40..40 permil.
    rows[3]["ci95"] = {"mu_scale": [0.5, 1.5]}  # the effect-free set's false name
    rows[2]["ci95"] = {"gradient_permil": [-40.0, 40.0]}  # a true name
    rows[0]["ci95"]["gradient_permil"] = [-40.0, 39.0]  # not to the upper end: bounded
    assert bench.metrics(rows)["not_bounded_by_data"] == {"sets": 2, "with_a_false_name": 1}


def test_coverage_only_where_the_model_is_right(bench, rows):
    coverage = bench.metrics(rows)["coverage"]
    # The right model: the pair named in full and the single gradient; not the pair with a
    # false name, nor the effect-free sets.
    assert coverage["right_model_sets"] == 2
    gradient = coverage["parameters"]["gradient.gradient_permil"]
    assert (gradient["sets"], gradient["covered"]) == (2, 2)
    assert gradient["median_relative_error"] == pytest.approx(np.median([0.2 / 5.0, 0.1 / 2.0]))
    mu = coverage["parameters"]["friction_level.mu_scale"]
    assert (mu["sets"], mu["covered"]) == (1, 0)  # 1.1 lies outside 1.115..1.125
    assert set(coverage["parameters"]) == {"gradient.gradient_permil", "friction_level.mu_scale"}


def test_summarize_prints_both_methods_and_writes_json(bench, rows, tmp_path, capsys):
    sindy_rows = [dict(r, method="sindy", ci95={}) for r in rows]
    out = tmp_path / "summary.json"
    numbers = bench.summarize(rows + sindy_rows, 0.0, str(out))
    text = capsys.readouterr().out
    assert "method: brakegym" in text and "method: sindy" in text
    assert "confusion matrices side by side" in text
    # The summary lines the README quotes keep their meaning.
    assert "single  sets: 1/1 hits" in text and "pair    sets: 2/2 hits" in text and "none    sets: 1/2 hits" in text
    assert "pairs: both named 1/2 (50 %), at least one named 2/2 (100 %)" in text
    written = json.loads(out.read_text())
    assert set(written) == {"brakegym", "sindy"}
    assert written["sindy"]["coverage"]["parameters"] == {}
    assert (
        written["brakegym"]["false_naming"]["sets_with_a_false_name"]
        == numbers["brakegym"]["false_naming"]["sets_with_a_false_name"]
    )


def test_stlsq_recovers_a_sparse_answer():
    pytest.importorskip("pysindy")
    from brakegym.diagnosis.baseline import stlsq

    rng = np.random.default_rng(7)
    features = rng.standard_normal((3000, 8))
    truth = np.array([0.0, 2.0, 0.0, 0.0, -1.5, 0.0, 0.0, 0.8])
    target = features @ truth + 0.05 * rng.standard_normal(3000)
    coefficients = stlsq(features, target, threshold=0.3)
    assert np.flatnonzero(coefficients).tolist() == [1, 4, 7]
    np.testing.assert_allclose(coefficients, truth, atol=0.01)
    with pytest.raises(ValueError, match="do not match"):
        stlsq(features, target[:-1], threshold=0.3)


def test_sindy_verdict_names_the_effects_of_its_terms():
    """A residual made of a gradient's constant deceleration and a common friction level over
    two recordings, in noise of one sigma: the verdict names both, each within three of its
    standard errors (the constant and the friction columns correlate, r^2 = 0.89: 0.15 permil for
    the gradient, 0.002 for the friction level), and leaves the fade's term out."""
    pytest.importorskip("pysindy")
    from brakegym.diagnosis import baseline

    rng = np.random.default_rng(11)
    terms = [*baseline.TERMS, "brake@r1", "brake@r2", "heat@r1", "heat@r2"]
    n = 4000
    features = np.zeros((n, len(terms)))
    half = n // 2
    gravity, brake_r1, brake_r2 = terms.index("gravity"), terms.index("brake@r1"), terms.index("brake@r2")
    # Rows in noise sigmas (kinematic noise 0.03 m/s^2): the gravity column is 1 / 0.03.
    features[:, gravity] = 1.0 / 0.03
    features[:half, brake_r1] = rng.uniform(0.3, 1.2, half) / 0.03
    features[half:, brake_r2] = rng.uniform(0.3, 1.2, n - half) / 0.03
    features[:, terms.index("brake_hot")] = rng.uniform(0.0, 1.0, n) / 0.03
    gradient_permil = -4.0
    truth = np.zeros(len(terms))
    truth[gravity] = gradient_permil * STANDARD_GRAVITY_MPS2 / 1000.0
    truth[brake_r1], truth[brake_r2] = 0.09, 0.11
    target = features @ truth + rng.standard_normal(n)
    regression = baseline.Regression(terms, features, target, np.zeros(n, dtype=int), {})
    verdict = baseline.sindy_verdict(regression, [])
    assert verdict["selected"] == ["gradient", "friction_level"]
    assert verdict["parameters"]["gradient_permil"] == pytest.approx(gradient_permil, abs=0.45)
    assert verdict["parameters"]["mu_scale"] == pytest.approx(1.10, abs=0.006)
    assert "brake_hot" not in verdict["kept_terms"]
    assert not verdict["unexplained"]
    assert verdict["residual_rms_over_noise_after"] == pytest.approx(1.0, abs=0.05)


def test_rows_written_before_the_new_keys_count_as_the_diagnosis(bench, rows):
    """Rows of earlier runs have no method, chain, model form, out-of-library list or unexplained
    flag: they are the diagnosis's, on clean sets, and summarize as before."""
    old = [
        {k: v for k, v in r.items() if k not in ("method", "measurement_chain", "model_form", "unexplained")}
        for r in rows[:5]
    ]
    for r in old:
        del r["out_of_library"]
    numbers = bench.metrics(old)
    assert bench.row_method(old[0]) == "brakegym"
    assert numbers["confusion"]["nothing"] == {"friction_level": 1, "nothing": 1}
    assert "unexplained" not in numbers["confusion"]
    assert numbers["pairs"] == {"sets": 2, "both_named": 1, "at_least_one_named": 2, "both_named_or_alternative": 1}


def test_heldout_rule_study_judges_each_candidate_by_both_rules(load_benchmark):
    study = load_benchmark("heldout_rule")

    def candidate(effect, t, recordings, delta_bic=-50.0, relevant=True):
        return {
            "effects": [effect],
            "delta_bic": delta_bic,
            "relevant_size": relevant,
            "heldout_t": t,
            "heldout_acts_on": [f"rec_{i}" for i in range(recordings)],
        }

    rows = [
        {
            "index": 3,
            "truth": [{"id": "thermal_fade", "parameters": {}}],
            "candidates": [
                candidate("thermal_fade", 2.98, 4),  # p 0.029: passes both
                candidate("adhesion_limit", 2.14, 2),  # p 0.14: passed t >= 2 alone
                candidate("gradient", 1.5, 8),  # fails both
                candidate("rotating_mass", 5.0, 8, delta_bic=-5.0),  # fails the BIC rule: not judged
                candidate("wet_pads", 5.0, 1),  # one recording: not judged
            ],
        }
    ]
    judged = {c["effect"]: c for c in study.judged_singles(rows, study.DiagnosisRules())}
    assert set(judged) == {"thermal_fade", "adhesion_limit", "gradient"}
    assert judged["thermal_fade"]["drawn"] and not judged["adhesion_limit"]["drawn"]
    # Student's t on 3 and on 1 degrees of freedom, in closed form.
    u = 2.98 / np.sqrt(3.0)
    assert judged["thermal_fade"]["p"] == pytest.approx(0.5 - (u / (1 + u * u) + np.arctan(u)) / np.pi)
    assert judged["adhesion_limit"]["p"] == pytest.approx(0.5 - np.arctan(2.14) / np.pi)
    assert (judged["thermal_fade"]["former"], judged["thermal_fade"]["now"]) == (True, True)
    assert (judged["adhesion_limit"]["former"], judged["adhesion_limit"]["now"]) == (True, False)
    assert (judged["gradient"]["former"], judged["gradient"]["now"]) == (False, False)


def test_friction_factor_study_reads_each_recordings_factor_and_braking_pressure(load_benchmark, tmp_path):
    """On a clean set without effects each factor is 1 within a few friction scatters, and each
    recording's mean braking pressure lies between the brake's threshold and its highest command."""
    import warnings

    from brakegym.recordings.synth import synthesize

    study = load_benchmark("friction_factor_pressure")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        synthesize(tmp_path / "set", 4, seed=3)
        stems, factors, pressures = study.factors_and_pressures(str(tmp_path / "set"))
    assert stems == ["rec_001", "rec_002", "rec_003", "rec_004"]
    assert np.all(np.abs(factors - 1.0) < 0.15), factors
    assert np.all((pressures > 1.0) & (pressures < 5.0)), pressures


def test_a_random_library_keeps_the_runs_sets_and_rides_with_each(bench):
    # The n-th set of a run has the same seed whatever its effects are drawn from; each job
    # carries the library to the synthesis, and rows record it for a rerun.
    default = list(bench.drawn_jobs(4, 6, 0.3, 8))
    along = list(bench.drawn_jobs(4, 6, 0.3, 8, library="along_track"))
    assert [job[:-1] for job in along] == [job[:-1] for job in default]
    assert {job[-1] for job in default} == {"default"} and {job[-1] for job in along} == {"along_track"}


def test_heldout_rule_study_reads_a_friction_level_by_a_signed_rank_test_too(load_benchmark):
    study = load_benchmark("heldout_rule")
    # One recording's large gain keeps the paired t short; the others all gain a little.
    gains = [0.021, 0.05, 0.2, 0.032, 0.018, -0.012, 0.027, -0.008]
    row = {
        "index": 10,
        "truth": [{"id": "friction_level", "parameters": {}}],
        "candidates": [
            {
                "effects": ["friction_level"],
                "delta_bic": 5.0,
                "relevant_size": True,
                "heldout_t": 1.09,
                "heldout_acts_on": [f"rec_{i}" for i in range(8)],
                "heldout_gain_per_recording": gains,
                "friction_level_shift": {"z": -4.2},
            }
        ],
    }
    (judged,) = study.judged_singles([row], study.DiagnosisRules())
    assert judged["drawn"] and not judged["now"]
    # The exact one-sided p: the share of the 2^8 sign patterns of the ranks whose positive rank
    # sum reaches the observed one (ranks of |gain|: the two losses are ranks 1 and 2).
    ranks = np.argsort(np.argsort(np.abs(gains))) + 1
    observed = ranks[np.array(gains) > 0].sum()
    signs = np.array(list(itertools.product([0, 1], repeat=8)))
    assert judged["rank_p"] == pytest.approx(np.mean(signs @ ranks >= observed), rel=1e-9)
    assert judged["rank_p"] < 0.05
    assert study.signed_rank_p([0.0, 0.0, 0.0]) == 1.0
