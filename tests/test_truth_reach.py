"""``benchmarks/truth_reach.py``: the diagnosis's model evaluated at a synthesized set's truth.

Without scatter the synthesizer and the diagnosis share one model, so at the true parameters each
recording's effective chi^2 is its noise, about its effective samples, and its refitted friction
factor about 1. The tolerances (0.5-1.5 times the effective samples, friction factors within 0.05
of 1) were fixed before the test first ran.
"""

import json

import pytest

from brakegym import config as cfg
from brakegym.recordings.synth import EffectRequest, synthesize

pytestmark = pytest.mark.filterwarnings("ignore")


@pytest.fixture(scope="module")
def reach(load_benchmark):
    return load_benchmark("truth_reach")


def test_the_one_scatter_setups_are_valid_configs(reach, tmp_path):
    reach.write_setups(tmp_path)
    with cfg.config_path(tmp_path):
        for name, (global_fraction, individual_fraction, resistance) in reach.ONE_SCATTER_SETUPS.items():
            setup = cfg.load("setups", name)
            assert (setup.global_fraction, setup.individual_fraction) == (global_fraction, individual_fraction)
            assert setup.resistance_scatter is resistance


def test_a_set_without_scatter_is_reached_at_its_truth(reach, tmp_path):
    key_path = tmp_path / "key.json"
    synthesize(
        tmp_path / "set",
        4,
        seed=7,
        effects=[EffectRequest("gradient", {"gradient_permil": -6.0})],
        key_path=key_path,
        scatter_setup="ds",
    )
    _, per_sample, factors = reach.truth_reach(tmp_path / "set", json.loads(key_path.read_text()))
    assert ((per_sample > 0.5) & (per_sample < 1.5)).all(), per_sample
    assert (abs(factors - 1.0) < 0.05).all(), factors


def test_an_adhesion_limited_set_with_the_running_resistances_scatter_is_reached_at_its_truth(reach, tmp_path):
    # Under an adhesion cap the friction factor no longer scales the deceleration: each
    # application's own running resistance A is what reaches the data (its per-recording nuisance,
    # held by the vehicle's A_sigma_N). The tolerance (0.5-1.6 times the effective samples) was
    # fixed before the test first ran; without that nuisance recordings sat at 10-18 times.
    reach.write_setups(tmp_path / "configs")
    key_path = tmp_path / "key.json"
    with cfg.config_path(tmp_path / "configs"):
        synthesize(
            tmp_path / "set",
            4,
            seed=7,
            effects=[EffectRequest("adhesion_limit", {"adhesion": 0.05})],
            key_path=key_path,
            scatter_setup="resistance-per-application",
        )
        _, per_sample, _ = reach.truth_reach(tmp_path / "set", json.loads(key_path.read_text()))
    assert ((per_sample > 0.5) & (per_sample < 1.6)).all(), per_sample
