"""``benchmarks/bootstrap_at_truth.py``: the diagnosis's bootstrap drawn at a coverage set's truth
and at its fit. On a small rotating-mass set (4 recordings, 3 replicates): the data prefer the
truth to a mass factor 0.15 off it, the replicates drawn at each point scatter around that point,
and the same row gives the same numbers twice."""

import pytest

pytestmark = pytest.mark.filterwarnings("ignore")


@pytest.fixture(scope="module")
def probe(load_benchmark):
    load_benchmark("bench_coverage")  # imported by name by the script
    return load_benchmark("bootstrap_at_truth")


def test_the_truth_fits_better_than_a_point_off_it_and_the_replicates_scatter_around_each(probe, tmp_path):
    row = {"effect": "rotating_mass", "seed": 700105, "recordings": 4, "measurement_chain": None}
    key = probe.synthesized_set("rotating_mass", 700105, 4, None, tmp_path).key
    truth = key["effects"][0]["parameters"]["mass_factor"]
    off = truth + 0.15 if truth < 0.1 else truth - 0.15
    result = probe.probe_row({**row, "fitted": {"mass_factor": off}}, replicates=3)
    assert result["truth"]["chi2_eff"] < result["fitted"]["chi2_eff"], result
    for point in ("truth", "fitted"):
        entry = result[point]
        centre, spread = entry["values"]["mass_factor"], entry["bootstrap_std"]["mass_factor"]
        assert abs(entry["bootstrap_mean"]["mass_factor"] - centre) < 0.05, entry
        assert 0 < spread < 0.05, entry
        low, high = entry["ci95_bootstrap"]["mass_factor"]
        assert low <= centre <= high, entry
    assert probe.probe_row({**row, "fitted": {"mass_factor": off}}, replicates=3) == result
