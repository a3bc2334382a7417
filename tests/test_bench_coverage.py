"""The coverage benchmark's bookkeeping (``benchmarks/bench_coverage.py``) on hand-built rows:
each interval kind counted per parameter, an effect not expressed in the data counted apart, the
per-effect count of sets where every interval holds the truth, and the exact binomial interval of
a coverage. No fit runs here."""

import argparse

import pytest


@pytest.fixture(scope="module")
def bench(load_benchmark):
    return load_benchmark("bench_coverage")


def row(effect, truth, fitted, ci95, gauss_newton_jackknife=None, bootstrap=None, expressed=True, resting=()):
    out = {"effect": effect, "seed": 0, "truth": truth, "expressed": expressed}
    if expressed:
        out.update(
            fitted=fitted,
            ci95=ci95,
            ci95_gauss_newton_jackknife=gauss_newton_jackknife or ci95,
            ci95_bootstrap=bootstrap or {},
            resting_on_one_recording=list(resting),
        )
    return out


def effect_counts(
    sets, all_covered, spanning_range=0, resting=0, covered_resting=0, not_recorded=0, not_expressed=0, hull=None
):
    return {
        "sets": sets,
        "all_covered": all_covered,
        "all_covered_hull_of_both": all_covered if hull is None else hull,
        "spanning_range": spanning_range,
        "resting_on_one_recording": resting,
        "covered_resting_on_one_recording": covered_resting,
        "resting_not_recorded": not_recorded,
        "not_expressed": not_expressed,
    }


def test_coverage_is_counted_per_parameter_and_interval_kind(bench):
    rows = [
        row(
            "thermal_fade",
            {"onset_C": 200.0, "loss_per_100K": 0.1},
            {"onset_C": 210.0, "loss_per_100K": 0.12},
            {"onset_C": [190.0, 230.0], "loss_per_100K": [0.11, 0.2]},
            bootstrap={"onset_C": [205.0, 215.0], "loss_per_100K": [0.05, 0.15]},
        ),
        row(
            "thermal_fade",
            {"onset_C": 200.0, "loss_per_100K": 0.1},
            {"onset_C": 200.0, "loss_per_100K": 0.1},
            {"onset_C": [190.0, 210.0], "loss_per_100K": [0.05, 0.15]},
        ),
        row("thermal_fade", {"onset_C": 400.0, "loss_per_100K": 0.1}, None, None, expressed=False),
        # An integer parameter is held at the truth and has no interval of its own.
        row("brake_unit_failure", {"failed_units": 2.0}, {"failed_units": 2.0}, {}),
    ]
    summary = bench.summarize(rows)
    onset, loss = summary["parameters"]["thermal_fade.onset_C"], summary["parameters"]["thermal_fade.loss_per_100K"]
    assert onset["sets"] == 2 and onset["covered_ci95"] == 2 and onset["covered_ci95_bootstrap"] == 0
    assert loss["covered_ci95"] == 1 and loss["covered_ci95_bootstrap"] == 1
    assert loss["median_relative_error"] == pytest.approx(0.1)
    assert onset["spans_search_range"] == 0 and loss["spans_search_range"] == 0
    # The first row's loss is missed by its ci95 and held by the hull of both parts.
    assert summary["effects"]["thermal_fade"] == effect_counts(2, 1, not_expressed=1, hull=2)
    assert "brake_unit_failure.failed_units" not in summary["parameters"]
    assert summary["effects"]["brake_unit_failure"] == effect_counts(1, 1)


def test_an_interval_over_the_whole_search_range_is_counted_apart_and_not_as_covered(bench):
    """Such an interval holds any truth: it is counted per parameter, and its set is not one where
    every interval holds the truth (a fade's onset bounds are 80-600 degC, its loss 0-0.6)."""
    rows = [
        row(
            "thermal_fade",
            {"onset_C": 246.5, "loss_per_100K": 0.3},
            {"onset_C": 252.3, "loss_per_100K": 0.28},
            {"onset_C": [80.0, 600.0], "loss_per_100K": [0.0, 0.6]},
        ),
        row(
            "thermal_fade",
            {"onset_C": 200.0, "loss_per_100K": 0.1},
            {"onset_C": 200.0, "loss_per_100K": 0.1},
            {"onset_C": [190.0, 210.0], "loss_per_100K": [0.05, 0.15]},
        ),
    ]
    summary = bench.summarize(rows)
    onset = summary["parameters"]["thermal_fade.onset_C"]
    assert onset["covered_ci95"] == 2 and onset["spans_search_range"] == 1
    assert summary["effects"]["thermal_fade"] == effect_counts(2, 1, spanning_range=1)


def test_parameters_resting_on_one_recording_are_counted_apart(bench):
    """A fade only one stop reaches has a jackknife interval stepped to one bound (80-510 degC):
    it holds the truth without spanning the range, and is counted as resting on one recording;
    rows written before the report had the key are counted as not recorded, not as resting."""
    onset_wide = {"onset_C": [80.0, 510.0], "loss_per_100K": [0.1, 0.5]}
    rows = [
        row(
            "thermal_fade",
            {"onset_C": 199.1, "loss_per_100K": 0.3},
            {"onset_C": 220.0, "loss_per_100K": 0.28},
            onset_wide,
            resting=("loss_per_100K", "onset_C"),
        ),
        row(
            "thermal_fade",
            {"onset_C": 199.1, "loss_per_100K": 0.05},
            {"onset_C": 220.0, "loss_per_100K": 0.28},
            onset_wide,
            resting=("onset_C",),
        ),
        row(
            "thermal_fade",
            {"onset_C": 200.0, "loss_per_100K": 0.1},
            {"onset_C": 200.0, "loss_per_100K": 0.1},
            {"onset_C": [190.0, 210.0], "loss_per_100K": [0.05, 0.15]},
        ),
    ]
    del rows[2]["resting_on_one_recording"]
    summary = bench.summarize(rows)
    onset, loss = summary["parameters"]["thermal_fade.onset_C"], summary["parameters"]["thermal_fade.loss_per_100K"]
    assert onset["rests_on_one_recording"] == 2 and loss["rests_on_one_recording"] == 1
    assert onset["covered_ci95"] == 3 and onset["spans_search_range"] == 0
    assert summary["effects"]["thermal_fade"] == effect_counts(3, 2, resting=2, covered_resting=1, not_recorded=1)


def test_the_exact_binomial_interval_of_a_coverage(bench):
    # Clopper-Pearson, 95 %: 9 of 10 gives 0.555-0.997; none or all reach the bound.
    low, high = bench.clopper_pearson(9, 10)
    assert low == pytest.approx(0.5550, abs=1e-4) and high == pytest.approx(0.9975, abs=1e-4)
    assert bench.clopper_pearson(0, 5)[0] == 0.0 and bench.clopper_pearson(5, 5)[1] == 1.0


def test_the_seeds_of_a_run_are_distinct(bench):
    seeds = {bench.set_seed(seed, index, effect) for seed in (1, 2) for index in range(20) for effect in range(12)}
    assert len(seeds) == 2 * 20 * 12


def test_a_single_set_is_named_by_its_effect_and_seed(bench):
    parser = argparse.ArgumentParser()
    assert bench.parse_set(parser, "wet_pads:200202") == ("wet_pads", 200202)
    with pytest.raises(SystemExit):
        bench.parse_set(parser, "wet_pads:20x")
    with pytest.raises(SystemExit):
        bench.parse_set(parser, "wet_pads")
