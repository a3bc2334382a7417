"""The tutorial's figure script (examples/tutorial_figures.py) runs, writes its figures and shows
the physical facts docs/tutorial.md states. Figure 4 (the Gymnasium env with the PID) is the
slowest and is left to tests/test_envs.py and tests/test_agents.py."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def tutorial():
    spec = importlib.util.spec_from_file_location("tutorial_figures", REPO / "examples" / "tutorial_figures.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _is_png(path: str) -> bool:
    return Path(path).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_fig1_friction_falls_with_initial_speed_because_of_the_power_term(tutorial, tmp_path):
    numbers = tutorial.fig1_speed_dependence(tmp_path)
    assert _is_png(numbers["figure"])
    # Same pressure, higher initial speed: lower mean friction (paper Sec. 2, about 16 %).
    assert numbers["mu_s_160"] < numbers["mu_s_100"]
    assert 12.0 < numbers["mu_s_drop_percent"] < 20.0
    # ... and so lower deceleration at the same speed.
    assert numbers["deceleration_at_80_kmh_from_160_mps2"] < numbers["deceleration_at_80_kmh_from_100_mps2"]
    # At full clamp force the friction-power term pulls mu down from 160 km/h, not from 100 km/h.
    assert numbers["net_rate_at_full_clamp_160_per_s"] < 0 < numbers["net_rate_at_full_clamp_100_per_s"]
    # Switching that term off closes most of the gap.
    assert numbers["mu_s_gap_without_power_term"] < 0.5 * numbers["mu_s_gap"]


def test_fig2_disc_body_peaks_after_standstill_and_cools_with_the_predicted_time_constant(tutorial, tmp_path):
    numbers = tutorial.fig2_stop_and_cooling(tmp_path, simulated_time_s=400.0)
    assert _is_png(numbers["figure"])
    assert numbers["time_of_peak_friction_temperature_s"] < numbers["braking_time_s"]
    assert numbers["time_of_peak_disc_temperature_s"] > numbers["braking_time_s"]
    # The friction state is held at standstill (spec Section 1).
    assert numbers["mu_at_end"] == numbers["mu_at_standstill"]
    predicted_s = numbers["predicted_cooling_time_constant_s"]
    assert numbers["measured_cooling_time_constant_s"] == pytest.approx(predicted_s, rel=0.05)


def test_fig3_sixteen_discs_average_independent_scatter_only(tutorial, tmp_path):
    numbers = tutorial.fig3_sixteen_discs(tmp_path)
    assert _is_png(numbers["figure"])
    # sqrt(16) = 4 for independent draws; 300 stops per set-up leave about 6 % sampling error.
    assert 3.0 < numbers["ratio_shared_over_mcs100_friction_only"] < 5.0
    assert numbers["ratio_mcs7525_over_shared_friction_only"] == pytest.approx(0.75, abs=0.1)
    # The running resistance scatters once per train: it does not average out over the discs.
    assert (
        numbers["ratio_shared_over_mcs100_with_resistance_scatter"] < numbers["ratio_shared_over_mcs100_friction_only"]
    )
    assert numbers["ratio_shared_over_mcs100_with_resistance_scatter"] > 1.5
