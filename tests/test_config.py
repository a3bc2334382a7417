"""Configs: every shipped file validates; a wrong one fails naming file, field and value."""

import shutil
from pathlib import Path

import pytest
import yaml

from brakegym import config as cfg

REPO_CONFIGS = Path(__file__).resolve().parent.parent / "configs"


@pytest.mark.parametrize("kind", sorted(cfg.KINDS))
def test_every_shipped_config_loads(kind):
    names = cfg.available(kind)
    assert names, f"no {kind} configs"
    for name in names:
        cfg.load(kind, name)


@pytest.fixture
def config_copy(tmp_path, monkeypatch):
    target = tmp_path / "configs"
    shutil.copytree(REPO_CONFIGS, target)
    monkeypatch.setenv(cfg.CONFIG_PATH_ENV, str(target))
    return target


def _edit(path: Path, change) -> None:
    data = yaml.safe_load(path.read_text())
    change(data)
    path.write_text(yaml.safe_dump(data))


def test_negative_mass_names_file_field_value(config_copy):
    path = config_copy / "vehicles" / "emu_8axle.yaml"
    _edit(path, lambda d: d["loads"]["empty"].update(mass_per_disc_kg=-7574.0))
    with pytest.raises(cfg.ConfigError) as info:
        cfg.load("vehicles", "emu_8axle")
    message = str(info.value)
    assert str(path) in message
    assert "loads.empty.mass_per_disc_kg" in message and "-7574.0" in message


def test_missing_field(config_copy):
    path = config_copy / "materials" / "ehret2022.yaml"
    _edit(path, lambda d: d.pop("temperature_exponent"))
    with pytest.raises(cfg.ConfigError, match=r"field 'temperature_exponent' = \(missing\)"):
        cfg.load("materials", "ehret2022")


def test_misspelt_field_is_refused_not_ignored(config_copy):
    path = config_copy / "discs" / "ehret2022_disc.yaml"
    _edit(path, lambda d: d.update(condutance_W_per_K=700.0))
    with pytest.raises(cfg.ConfigError, match="condutance_W_per_K"):
        cfg.load("discs", "ehret2022_disc")


def test_safety_case_probability_above_one(config_copy):
    path = config_copy / "safety_cases" / "emu_8axle.yaml"
    _edit(path, lambda d: d["brake_units"].update(failure_probability_per_demand=1.5))
    with pytest.raises(cfg.ConfigError) as info:
        cfg.load("safety_cases", "emu_8axle")
    message = str(info.value)
    assert str(path) in message and "brake_units.failure_probability_per_demand" in message and "1.5" in message


def test_safety_case_input_without_source(config_copy):
    _edit(config_copy / "safety_cases" / "emu_8axle.yaml", lambda d: d["mass"].pop("source"))
    with pytest.raises(cfg.ConfigError, match=r"mass.source"):
        cfg.load("safety_cases", "emu_8axle")


def test_unknown_name_lists_known(config_copy):
    with pytest.raises(cfg.ConfigError, match="unknown vehicle 'ice4'.*known: emu_8axle"):
        cfg.load("vehicles", "ice4")


def test_name_must_match_file(config_copy):
    path = config_copy / "pneumatics" / "EP.yaml"
    _edit(path, lambda d: d.update(name="XP"))
    with pytest.raises(cfg.ConfigError, match="'XP' must equal the file's stem 'EP'"):
        cfg.load("pneumatics", "EP")


def test_pressure_above_maximum(config_copy):
    path = config_copy / "vehicles" / "emu_8axle.yaml"
    _edit(path, lambda d: d["brake_pressures_bar"]["emergency"].update(max=6.0))
    with pytest.raises(cfg.ConfigError, match="brake_pressures_bar.emergency.max = 6.0"):
        cfg.load("vehicles", "emu_8axle")


def test_specimen_count_mismatch(config_copy):
    path = config_copy / "rigs" / "dynamometer.yaml"
    _edit(path, lambda d: d["load_cases"][2].update(applications_per_specimen=[1, 2]))
    with pytest.raises(cfg.ConfigError, match=r"load_cases\[2\] \(V0100_Case3\).*2 entries.*5 specimens"):
        cfg.load("rigs", "dynamometer")


def test_mu_bounds_order(config_copy):
    path = config_copy / "materials" / "ehret2022.yaml"
    _edit(path, lambda d: d.update(mu_min=0.9))
    with pytest.raises(cfg.ConfigError, match=r"mu_min \(0.9\) must be below mu_max"):
        cfg.load("materials", "ehret2022")


def test_not_yaml(config_copy):
    (config_copy / "setups" / "ds.yaml").write_text("name: [unclosed\n")
    with pytest.raises(cfg.ConfigError, match="ds.yaml: not valid YAML"):
        cfg.load("setups", "ds")


def test_user_adds_a_vehicle_by_adding_a_file(config_copy):
    data = yaml.safe_load((config_copy / "vehicles" / "emu_8axle.yaml").read_text())
    data.update(name="emu_4axle", bogies=2)
    (config_copy / "vehicles" / "emu_4axle.yaml").write_text(yaml.safe_dump(data))
    vehicle = cfg.load("vehicles", "emu_4axle")
    assert vehicle.n_discs == 8
    assert "emu_4axle" in cfg.available("vehicles")
