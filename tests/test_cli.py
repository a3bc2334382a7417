"""The command line: public JSON keys, and clear errors with exit status 2 for bad input."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from brakegym.cli import main


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "brakegym", *args], capture_output=True, text=True, timeout=300)


def test_dyno_case_json(tmp_path):
    out = tmp_path / "out.json"
    assert main(["dyno", "--case", "V0100_Case1", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert set(data) == {"load_case", "s_m", "s2_m", "mu_s", "t_stop_s", "T_fric_max_C"}
    assert data["load_case"] == "V0100_Case1"
    assert data["s_m"] == pytest.approx(433.8256, rel=0.005)


def test_dyno_all_cases(tmp_path, capsys):
    out = tmp_path / "all.json"
    assert main(["dyno", "--json", str(out)]) == 0
    assert len(json.loads(out.read_text())) == 12
    assert "V0160_Case3" in capsys.readouterr().out


def test_simulate_json(tmp_path):
    out = tmp_path / "stop.json"
    args = [
        "simulate",
        "--vehicle",
        "emu_8axle",
        "--load",
        "empty",
        "--mode",
        "emergency",
        "--actuation",
        "EP",
        "--v0",
        "120",
        "--json",
        str(out),
    ]
    assert main(args) == 0
    data = json.loads(out.read_text())
    assert data["stop_distance_m"] == pytest.approx(589.3, rel=0.005)
    assert data["stop_time_s"] == pytest.approx(32.9, rel=0.005)


def test_simulate_with_scatter_is_seeded(tmp_path):
    results = []
    for seed in (4, 4, 5):
        out = tmp_path / f"s{seed}_{len(results)}.json"
        assert main(["simulate", "--v0", "100", "--setup", "mcs-100", "--seed", str(seed), "--json", str(out)]) == 0
        results.append(json.loads(out.read_text())["stop_distance_m"])
    assert results[0] == results[1] != results[2]


def test_mcs_field_json_and_figures(tmp_path):
    out = tmp_path / "field.json"
    figures = tmp_path / "fig"
    result = run_cli(
        "mcs", "--campaign", "field", "--setup", "ds", "--seed", "1", "--json", str(out), "--figures", str(figures)
    )
    assert result.returncode == 0, result.stderr
    data = json.loads(out.read_text())
    assert data["applications"] == 4400 and data["setup"] == "ds"
    assert len(data["field_applications"]) == 88
    assert sorted(p.name for p in figures.glob("*.png")) == ["fig15_mu_eff.png", "fig16_braking_distance.png"]


@pytest.mark.parametrize(
    "args,message",
    [
        (["simulate", "--v0", "-5"], "--v0 must be a positive finite number, got '-5'"),
        (["simulate", "--v0", "nan"], "--v0 must be a positive finite number"),
        (["simulate", "--v0", "120", "--vehicle", "tgv"], "unknown vehicle 'tgv'"),
        (["simulate", "--v0", "120", "--load", "crush"], "unknown load 'crush'"),
        (["simulate", "--v0", "120", "--mode", "parking"], "unknown brake mode 'parking'"),
        (["simulate", "--v0", "120", "--actuation", "XX"], "unknown pneumatic 'XX'"),
        (
            ["simulate", "--v0", "120", "--step", "0.15"],
            "dead time 0.2 s is not a whole number of time steps of 0.15 s",
        ),
        (["simulate", "--v0", "120", "--command-time", "-1"], "--command-time must be a non-negative"),
        (["mcs", "--campaign", "dyno", "--setup", "mcs-50"], "unknown setup 'mcs-50'"),
        (["mcs", "--campaign", "train"], "invalid choice: 'train'"),
        (["mcs", "--campaign", "dyno", "--seed", "-1"], "--seed must not be negative"),
        (["dyno", "--case", "V0999_Case9"], "unknown load case 'V0999_Case9'"),
        (["tail", "--load", "empty", "--v0", "160"], "one of the arguments --probability --distance is required"),
        (["tail", "--load", "empty", "--v0", "160", "--probability", "1"], "strictly between 0 and 1, got '1'"),
        (["tail", "--load", "empty", "--v0", "160", "--distance", "-3"], "--distance must be a positive"),
        (["tail", "--load", "full", "--v0", "160", "--probability", "1e-3"], "unknown load 'full'"),
        (["tail", "--load", "empty", "--v0", "160", "--probability", "1e-3", "--safety-case", "x"], "unknown safety"),
        (
            ["tail", "--load", "empty", "--v0", "160", "--probability", "1e-9", "--method", "brute"],
            "use --method subset or is",
        ),
        (
            ["tail", "--load", "empty", "--v0", "60", "--probability", "1e-3", "--samples", "100"],
            "--samples is brute force's sample size",
        ),
    ],
)
def test_bad_arguments_exit_2_with_message(args, message, capsys):
    try:
        status = main(args)
    except SystemExit as exit_:  # argparse's own errors
        status = exit_.code
    assert status == 2
    assert message in capsys.readouterr().err


def test_bad_config_file_exit_2(tmp_path, monkeypatch):
    import shutil
    from pathlib import Path

    configs = tmp_path / "configs"
    shutil.copytree(Path(__file__).resolve().parent.parent / "configs", configs)
    path = configs / "pneumatics" / "EP.yaml"
    path.write_text(path.read_text().replace("time_constant_s: 0.8", "time_constant_s: -0.8"))
    result = subprocess.run(
        [sys.executable, "-m", "brakegym", "simulate", "--v0", "100"],
        capture_output=True,
        text=True,
        env={**__import__("os").environ, "BRAKEGYM_CONFIG_PATH": str(configs)},
    )
    assert result.returncode == 2
    assert str(path) in result.stderr and "time_constant_s" in result.stderr and "-0.8" in result.stderr


def test_output_cut_short_by_its_reader_ends_quietly():
    """``brakegym dyno | head -1``: the reader closes the pipe; no traceback, status 0."""
    result = subprocess.run(
        f"{sys.executable} -m brakegym dyno | head -1", shell=True, capture_output=True, text=True, timeout=300
    )
    assert result.stdout.startswith("load case") and result.stderr == ""


def test_the_parser_loads_nothing_heavy():
    """Building the command line's parser (every command's options) imports neither the compiled
    simulator nor scipy.stats, pandas or matplotlib: the fixed cost of every command stays small.
    Each command imports what it runs."""
    heavy = ["numba", "scipy.stats", "pandas", "matplotlib", "torch", "stable_baselines3"]
    code = (
        "import sys; from brakegym.cli import build_parser; build_parser(); "
        f"print([name for name in {heavy!r} if name in sys.modules])"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


def test_tail_json(tmp_path, capsys):
    out = tmp_path / "tail.json"
    args = ["tail", "--load", "empty", "--v0", "60", "--probability", "1e-3", "--method", "is", "--json", str(out)]
    assert main(args) == 0
    data = json.loads(out.read_text())
    stable = {"probability", "braking_distance_m", "ci95_m", "model_evaluations", "method", "seconds"}
    assert stable <= set(data) and data["method"] == "is" and data["probability"] == 1e-3
    low, high = data["ci95_m"]
    assert low <= data["braking_distance_m"] <= high
    # The 1e-3 distance lies beyond the nominal stop; the table says both.
    assert data["braking_distance_m"] > data["nominal_braking_distance_m"]
    assert "exceeded with probability 0.001" in capsys.readouterr().out


def _kdry_values(path: Path) -> list:
    bands = json.loads(path.read_text())["bands"]
    return [[(level["value"], level["ci95"]) for level in band["kdry"].values()] for band in bands]


def test_kdry_json_figure_and_osrd_export(tmp_path, capsys):
    """``brakegym kdry`` on a user's safety case (a copy of the shipped one with a lower maximum
    speed, for a short test)."""
    import yaml

    from brakegym.safety.osrd import read_etcs_brake_params

    cases = tmp_path / "configs" / "safety_cases"
    cases.mkdir(parents=True)
    shipped = yaml.safe_load(open(Path(__file__).resolve().parent.parent / "configs/safety_cases/emu_8axle.yaml"))
    shipped.update(name="emu_slow")
    shipped["etcs"].update(maximum_speed_kmh=60.0, speed_band_edges_kmh=[30.0], export_confidence_level=1)
    (cases / "emu_slow.yaml").write_text(yaml.safe_dump(shipped))
    out = tmp_path / "out"
    args = ["--config-path", str(tmp_path / "configs"), "kdry", "--load", "empty", "--safety-case", "emu_slow"]
    args += ["--levels", "0,1", "--n-per-level", "500", "--json", str(out / "k.json"), "--osrd", str(out / "o.json")]
    assert main([*args, "--figure", str(out / "k.png")]) == 0
    data = json.loads((out / "k.json").read_text())
    assert [band["speed_high_kmh"] for band in data["bands"]] == [30.0, 60.0]
    assert set(data["bands"][0]["kdry"]) == {"0", "1"} and data["bands"][0]["kdry"]["1"]["ebcl"] == 0.9
    assert read_etcs_brake_params(out / "o.json")["k_dry"]["values"] == [b["kdry"]["1"]["value"] for b in data["bands"]]
    assert (out / "k.png").stat().st_size > 0
    assert "M_NVEBCL 1 (90 %)" in capsys.readouterr().out
    # Worker processes find the user's safety case too, and give the same table.
    local = ["--executor", "local", "--workers", "2", "--chunk-size", "100", "--json", str(out / "local.json")]
    assert main([*args[:-4], *local]) == 0
    assert _kdry_values(out / "local.json") == _kdry_values(out / "k.json")
    # An export at a level not computed is refused before any simulation.
    assert main([*args[:-4], "--levels", "0", "--osrd", str(out / "x.json")]) == 2
    assert "include it in --levels" in capsys.readouterr().err
