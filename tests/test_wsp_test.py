"""The WSP test of UIC 541-05 / EN 15595 as a command (issue 16): ``brakegym.wsp_test`` and
``brakegym wsp-test``. Stops from 60 km/h to keep them cheap."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from brakegym import config as cfg
from brakegym.cli import main
from brakegym.plants import rail_friction_factor_for_samples
from brakegym.units import STANDARD_GRAVITY_MPS2, kmh_to_mps
from brakegym.wsp_test import ideal_distance_m, resolve_wsp, wsp_test

REPO = Path(__file__).resolve().parent.parent
V0_KMH = 60.0
STABLE_KEYS = (
    "stop_distance_m",
    "dry_stop_distance_m",
    "distance_extension_pct",
    "adhesion_utilisation",
    "max_locked_time_s",
    "slide_energy_MJ",
)


@pytest.fixture(autouse=True)
def checkout_configs(monkeypatch):
    """This checkout's configs on the search path (an installed brakegym may ship others)."""
    monkeypatch.setenv(cfg.CONFIG_PATH_ENV, str(REPO / "configs"))


@pytest.fixture(scope="module", autouse=True)
def checkout_agents():
    """brakegym.agents with this checkout's agents/ first (an editable install of another
    checkout maps the subpackage there)."""
    import brakegym.agents

    checkout = str(REPO / "agents")
    if checkout not in brakegym.agents.__path__:
        brakegym.agents.__path__.insert(0, checkout)


@pytest.fixture(scope="module")
def low_rail():
    with cfg.config_path(REPO / "configs"):
        return {
            wsp: wsp_test("emu_8axle", "empty", V0_KMH, wsp, condition="low").as_json() for wsp in ("reference", "none")
        }


def test_report_has_the_stable_keys_and_says_what_was_asked(low_rail):
    report = low_rail["reference"]
    for key in STABLE_KEYS:
        assert isinstance(report[key], float) and np.isfinite(report[key]), key
    assert (report["vehicle"], report["load"], report["condition"], report["wsp"]) == (
        "emu_8axle",
        "empty",
        "low",
        "reference",
    )
    assert report["v0_kmh"] == V0_KMH and report["seed"] is None
    assert "UIC 541-05" in report["adhesion_utilisation_source"]
    assert len(report["locked_time_longest_s"]) == len(report["slide_energy_per_axle_MJ"]) == 8
    json.dumps(report)  # plain JSON types throughout
    extension = 100.0 * (report["stop_distance_m"] / report["dry_stop_distance_m"] - 1.0)
    assert report["distance_extension_pct"] == pytest.approx(extension, rel=1e-12)


def test_without_wsp_the_axles_lock_and_the_stop_is_longer(low_rail):
    """No WSP on the low rail: every axle slides most of the stop (locked far longer than the
    0.5 s the reference allows), the stop is longer and the treads dissipate more."""
    none, reference = low_rail["none"], low_rail["reference"]
    assert none["max_locked_time_s"] > 10.0
    assert min(none["locked_time_longest_s"]) > 10.0
    assert reference["max_locked_time_s"] <= 0.5
    assert none["stop_distance_m"] > 1.2 * reference["stop_distance_m"]
    assert none["slide_energy_MJ"] > 5.0 * reference["slide_energy_MJ"]
    assert none["adhesion_utilisation"] < reference["adhesion_utilisation"]


@pytest.mark.parametrize("wsp", ["reference", "none"])
def test_utilisation_is_a_share_and_no_stop_beats_the_ideal(low_rail, wsp):
    """The adhesion used never exceeds the peak of the law: 0 < eta <= 1; no stop is shorter than
    the perfect WSP's, which takes the peak wherever the brake asks more."""
    report = low_rail[wsp]
    assert 0.0 < report["adhesion_utilisation"] <= 1.0
    assert report["stop_distance_m"] >= report["ideal_distance_m"]
    assert report["distance_over_ideal"] == pytest.approx(report["stop_distance_m"] / report["ideal_distance_m"])
    # The reference WSP (issue 16): within 20 % of the ideal, and using most of the adhesion.
    if wsp == "reference":
        assert report["stop_distance_m"] <= 1.2 * report["ideal_distance_m"]
        assert report["adhesion_utilisation"] > 0.75


def test_on_a_conditioned_rail_each_axle_counts_with_its_own_rail(low_rail):
    """On the rail the axles condition for each other the perfect WSP uses each axle's own peak
    (more behind the leader): its stop is shorter than on the low rail, no stop beats it, and no
    axle uses more than its own rail gives (0 < eta <= 1)."""
    with cfg.config_path(REPO / "configs"):
        report = wsp_test("emu_8axle", "empty", V0_KMH, "reference", condition="low_conditioned").as_json()
    assert report["ideal_distance_m"] < low_rail["reference"]["ideal_distance_m"]
    assert report["stop_distance_m"] >= report["ideal_distance_m"]
    assert report["stop_distance_m"] < low_rail["reference"]["stop_distance_m"]
    assert 0.0 < report["adhesion_utilisation"] <= 1.0


def test_on_the_dry_rail_nothing_slides_and_the_distance_is_the_dry_one():
    """The dry rail gives more adhesion than the emergency brake asks: no axle locks, the stop is
    the reference stop (no extension), the brake's whole demand reaches the rail (eta 1 to the
    creep's small losses) and the stop is the perfect WSP's (the ideal, integrated on its own,
    within 0.1 %)."""
    report = wsp_test("emu_8axle", "empty", V0_KMH, "reference", condition="dry").as_json()
    assert abs(report["distance_extension_pct"]) < 0.1
    assert report["max_locked_time_s"] == 0.0
    assert report["slide_energy_MJ"] < 0.05
    assert 0.99 < report["adhesion_utilisation"] <= 1.0
    assert report["ideal_distance_m"] == pytest.approx(report["stop_distance_m"], rel=1e-3)


class _ConstantPeak:
    """A rail whose peak adhesion is ``peak`` at every speed and place."""

    def __init__(self, peak: float) -> None:
        self.value = peak

    def section_of(self, position_m):
        return np.zeros((1, np.size(position_m)), dtype=np.int64)

    def peak(self, speed_mps, section):
        return np.full(section.shape, self.value)


@pytest.mark.parametrize("command_time_s", [0.0, 1.0])
@pytest.mark.parametrize("limit", ["rail", "brake"])
def test_ideal_distance_is_the_analytic_stop_at_constant_adhesion_or_brake_force(limit, command_time_s):
    """No running resistance, the demand a step D at the command plus a response time t_r: the
    rail's limit (peak mu) gives v0 t_r + v0^2 M / (2 mu m g), the brake's v0 t_r + v0^2 m / (2 D);
    the train coasting before the command does not count."""
    resistance = cfg.load("vehicles", "emu_8axle").running_resistance.model_copy(
        update={"B_N_per_mps": 0.0, "C_N_per_mps2": 0.0}
    )
    mass, body, v0, response = 200e3, 195e3, kmh_to_mps(120.0), 1.5
    mu, demand = (0.07, 1e9) if limit == "rail" else (10.0, 150e3)
    switch = command_time_s + response
    distance = ideal_distance_m(
        _ConstantPeak(mu), body, mass, resistance, 0.0, v0, np.array([switch, switch + 1e-9]),
        np.array([0.0, demand]), command_time_s,
    )  # fmt: skip
    braking = v0**2 * body / (2 * mu * mass * STANDARD_GRAVITY_MPS2) if limit == "rail" else v0**2 * mass / (2 * demand)
    # The midpoint rule is exact at constant deceleration; the step the demand switches in costs
    # at most half a step's a dt^2 / 2.
    assert distance == pytest.approx(v0 * response + braking, rel=1e-6)


def test_same_seed_same_json_bit_for_bit_and_the_seed_scatters(tmp_path):
    paths = [tmp_path / f"run{i}.json" for i in range(2)]
    for path in paths:
        assert main(["wsp-test", "--load", "empty", "--wsp", "reference", "--v0", "60", "--seed", "7",
                     "--json", str(path)]) == 0  # fmt: skip
    first, second = (path.read_text() for path in paths)
    assert first == second
    report = json.loads(first)
    assert report["seed"] == 7 and report["condition"] == "low" and report["scatter_setup"] == "mcs-100"
    # The rail of a seeded test is the rail a campaign seeded so draws for its stop 0.
    low = cfg.load("rail_conditions", "low")
    campaign_factor = rail_friction_factor_for_samples(low, 7, np.zeros(1, dtype=np.int64))
    assert report["rail_static_friction_factor"] == float(campaign_factor[0]) != 1.0
    nominal = wsp_test("emu_8axle", "empty", V0_KMH, "reference", condition="low").as_json()
    assert report["stop_distance_m"] != nominal["stop_distance_m"]


def test_command_writes_json_and_figure(tmp_path, capsys):
    json_path, figure = tmp_path / "out" / "wsp.json", tmp_path / "out" / "wsp.png"
    code = main(
        ["wsp-test", "--vehicle", "emu_8axle", "--load", "empty", "--condition", "low", "--wsp", "none",
         "--v0", "60", "--json", str(json_path), "--figure", str(figure)]
    )  # fmt: skip
    assert code == 0
    report = json.loads(json_path.read_text())
    assert set(STABLE_KEYS) <= set(report)
    assert figure.stat().st_size > 10_000
    printed = capsys.readouterr().out
    assert "adhesion utilisation" in printed and "distance extension" in printed


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["--vehicle", "tgv", "--load", "empty"], "known: emu_8axle"),
        (["--load", "half"], "known: ['empty', 'max', 'normal']"),
        (["--load", "empty", "--condition", "icy"], "known: dry, low, low_conditioned, wet"),
        (["--load", "empty", "--line", "nowhere"], "nowhere"),
        (["--load", "empty", "--valves", "wheel"], "wheel"),
        (["--load", "empty", "--setup", "mcs-50"], "known: ds, mcs-100"),
    ],
)
def test_bad_input_names_what_and_lists_the_known(arguments, message, capsys):
    assert main(["wsp-test", *arguments, "--wsp", "reference", "--v0", "60"]) == 2
    assert message in capsys.readouterr().err


def test_bad_wsp_is_refused_clearly(tmp_path, capsys):
    assert main(["wsp-test", "--load", "empty", "--wsp", "abs", "--v0", "60"]) == 2
    assert "none, reference, reference-true-speed" in capsys.readouterr().err
    assert main(["wsp-test", "--load", "empty", "--wsp", str(tmp_path / "missing.yaml"), "--v0", "60"]) == 2
    assert "no such file" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(
            ["wsp-test", "--load", "empty", "--condition", "low", "--line", "low_patch", "--wsp", "none", "--v0", "60"]
        )


def test_a_policy_folder_goes_to_the_policy_loader(tmp_path, monkeypatch):
    """A folder is a trained policy: loaded by brakegym.agents.wsp_policy, or a clear error
    where that module is missing."""
    import sys
    import types

    try:
        import brakegym.agents.wsp_policy  # noqa: F401
    except ModuleNotFoundError:
        with pytest.raises(cfg.ConfigError, match="policies need brakegym.agents.wsp_policy"):
            resolve_wsp(tmp_path)
    loaded = []
    module = types.ModuleType("brakegym.agents.wsp_policy")
    module.load_wsp_controller = lambda path: loaded.append(path) or "factory"
    monkeypatch.setitem(sys.modules, "brakegym.agents.wsp_policy", module)
    choice = resolve_wsp(tmp_path)
    assert loaded == [tmp_path] and choice.make_controller == "factory" and choice.label == str(tmp_path)


def test_controller_yaml_of_the_reference_kind(tmp_path):
    source = (REPO / "configs" / "agents" / "wsp.yaml").read_text()
    path = tmp_path / "wsp.yaml"  # a config is named like its file
    path.write_text(source)
    choice = resolve_wsp(path)
    assert choice.label == str(path) and choice.make_controller is not None


def test_the_shipped_ppo_policy_stops_shorter_than_the_reference_with_no_more_slide_energy():
    """Issue 16's bar for the shipped policy, on the WSP test's case: emu_8axle empty, emergency
    from 120 km/h on the low rail, nominal friction."""
    reports = {
        wsp: wsp_test("emu_8axle", "empty", 120.0, wsp, condition="low").as_json() for wsp in ("reference", "ppo")
    }
    assert reports["ppo"]["wsp"] == "ppo"
    assert reports["ppo"]["stop_distance_m"] < reports["reference"]["stop_distance_m"]
    assert reports["ppo"]["slide_energy_MJ"] <= reports["reference"]["slide_energy_MJ"]
    assert reports["ppo"]["max_locked_time_s"] <= 1.0  # the environment's success bound
