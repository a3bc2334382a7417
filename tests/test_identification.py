"""Identification (issue 4): recover known parameters from synthetic campaigns with measurement
noise, report what the data cannot determine, and refuse bad input.

Synthetic data come from the campaign code itself (``campaigns.dyno_campaign`` over a temporary
config folder holding the perturbed material), integrated at 0.1 s while the fits use 0.2 s, so
the fitted model is not the exact generator. Tolerances were fixed before the results were seen.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from threadpoolctl import threadpool_info, threadpool_limits

from brakegym import campaigns
from brakegym import config as cfg
from brakegym.applications import TrainApplication, dyno_stops, train_stops
from brakegym.cli import main
from brakegym.identification import (
    DynoCurves,
    Series,
    deterministic,
    dyno_curves_from_campaign,
    identify,
    load_identification_config,
    read_dyno_curves,
    write_dyno_curves,
)
from brakegym.identification.stochastic import dyno_spread_groups, field_spread_groups, identify_scatter
from brakegym.physics import draw_friction, draw_running_resistance
from brakegym.plants import scatter_partition, stochastic_friction

REPO_CONFIGS = Path(__file__).resolve().parent.parent / "configs"

# A campaign of one application per load case has no spread: its envelope's std warns.
pytestmark = pytest.mark.filterwarnings("ignore:Degrees of freedom <= 0:RuntimeWarning")

RIG = cfg.load("rigs", "dynamometer")
MATERIAL = cfg.load("materials", "ehret2022")
DISC = cfg.load("discs", "ehret2022_disc")
SETTINGS = load_identification_config()
NOISE = {"mu": 0.002, "T_fric_C": 1.0}  # the config's channel scales

# Known, perturbed parameters of the synthetic pads and disc (nominal: a 0.008, c 0.042,
# d 0.036, x 0.994, C_fric 7191, G_ref 691).
TRUTH = {"a": 0.0088, "c": 0.0386, "d": 0.0392, "x": 0.944, "C_fric": 6700.0, "G_ref": 745.0}
FIELDS = {p.symbol: p.field for p in SETTINGS.parameters}


def _perturbed_configs(truth: dict[str, float]) -> tuple[dict, dict]:
    material, disc = MATERIAL.model_dump(), DISC.model_dump()
    for symbol, value in truth.items():
        field = FIELDS[symbol]
        target = material if field in material else disc
        *head, last = field.split(".")
        for part in head:
            target = target[part]
        target[last] = value
    return material, disc


def synthetic_dyno_curves(tmp_path, monkeypatch, truth, cases, seed, until_s=None) -> DynoCurves:
    """Mean curves of a DS dyno campaign of ``cases`` (one application each) made with the
    ``truth`` parameters at 0.1 s, plus white measurement noise of the channel scales."""
    folder = tmp_path / "truth_configs"
    shutil.copytree(REPO_CONFIGS, folder)
    material, disc = _perturbed_configs(truth)
    (folder / "materials" / "ehret2022.yaml").write_text(yaml.safe_dump(material))
    (folder / "discs" / "ehret2022_disc.yaml").write_text(yaml.safe_dump(disc))
    rig = RIG.model_dump()
    rig["load_cases"] = [
        {**case, "applications_per_specimen": [1, 0, 0, 0, 0]} for case in rig["load_cases"] if case["name"] in cases
    ]
    (folder / "rigs" / "dynamometer.yaml").write_text(yaml.safe_dump(rig))
    with monkeypatch.context() as patch:
        patch.setenv(cfg.CONFIG_PATH_ENV, str(folder))
        truth_rig = cfg.load("rigs", "dynamometer")
        result = campaigns.dyno_campaign(truth_rig, cfg.load("setups", "ds"), seed=0, step_s=0.1)
    clean = dyno_curves_from_campaign(result, truth_rig)
    rng = np.random.default_rng(seed)
    series = []
    for item in clean.series:
        keep = item.time_s <= (until_s if until_s is not None else np.inf)
        noisy = item.values[keep] + rng.normal(0.0, NOISE[item.channel], keep.sum())
        series.append(Series(item.case, item.channel, item.time_s[keep], noisy))
    return DynoCurves(RIG, tuple(series))


# ------------------------------------------------------------------------------------------------
# Deterministic identification


def test_recovers_friction_and_thermal_parameters_from_four_load_cases(tmp_path, monkeypatch):
    cases = ["V0100_Case1", "V0120_Case2", "V0140_Case3", "V0160_Case1"]
    curves = synthetic_dyno_curves(tmp_path, monkeypatch, TRUTH, cases, seed=41)
    result = identify(curves, list(TRUTH), MATERIAL, DISC, SETTINGS)

    assert result.converged
    for estimate in result.parameters:
        truth = TRUTH[estimate.symbol]
        assert estimate.start != truth  # started from the nominal material, not the truth
        # Tolerances: within 5 % of the truth, and within 3 standard errors of it.
        assert abs(estimate.estimate - truth) <= 0.05 * truth, estimate
        assert abs(estimate.estimate - truth) <= 3 * estimate.standard_error, estimate
        assert estimate.identifiable, estimate
    # The residuals are the added white noise: rms near the noise, little autocorrelation.
    by_channel = {c.channel: c for c in result.channels}
    assert by_channel["mu"].rms == pytest.approx(NOISE["mu"], rel=0.2)
    assert by_channel["T_fric_C"].rms == pytest.approx(NOISE["T_fric_C"], rel=0.2)
    assert abs(by_channel["mu"].lag1_autocorrelation) < 0.2
    assert result.correlation.shape == (6, 6) and np.allclose(np.diag(result.correlation), 1.0)


def test_disc_ventilation_is_not_identifiable_from_one_short_low_energy_stop(tmp_path, monkeypatch):
    # 12 s of the mildest load case: the disc body hardly warms, so the ventilation of its
    # vents (h_vent) cannot show in the friction-surface temperature.
    curves = synthetic_dyno_curves(tmp_path, monkeypatch, {}, ["V0100_Case1"], seed=3, until_s=12.0)
    result = identify(curves, ["C_fric", "h_vent"], MATERIAL, DISC, SETTINGS)
    assert "h_vent" in result.not_identifiable
    h_vent = next(p for p in result.parameters if p.symbol == "h_vent")
    assert h_vent.reasons and h_vent.relative_ci_half_width > SETTINGS.identifiability.max_relative_ci_half_width
    assert "h_vent" in result.table() and "NO:" in result.table()


def test_fit_is_deterministic_and_flags_unfitted_thermal_error(tmp_path, monkeypatch):
    # Truth with another thermal model, fitted with a alone: the thermal error shows as
    # autocorrelated temperature residuals, which the intervals must account for.
    curves = synthetic_dyno_curves(tmp_path, monkeypatch, {"a": 0.0088, "G_ref": 850.0}, ["V0120_Case1"], seed=5)
    first = identify(curves, ["a"], MATERIAL, DISC, SETTINGS)
    second = identify(curves, ["a"], MATERIAL, DISC, SETTINGS)
    assert json.dumps(first.as_dict()) == json.dumps(second.as_dict())
    temperature = next(c for c in first.channels if c.channel == "T_fric_C")
    assert temperature.lag1_autocorrelation > 0.8 and temperature.effective_samples < 0.2 * temperature.samples


def test_the_fit_runs_on_one_blas_thread_whatever_the_callers_limit(tmp_path, monkeypatch):
    # A multithreaded BLAS sums in an order set by its thread count: a fit's last bits would
    # depend on the machine's cores.
    curves = synthetic_dyno_curves(tmp_path, monkeypatch, {"a": 0.0088}, ["V0120_Case1"], seed=5)
    seen = []
    least_squares = deterministic.optimize.least_squares

    def least_squares_recording_threads(*args, **kwargs):
        seen.extend(pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas")
        return least_squares(*args, **kwargs)

    monkeypatch.setattr(deterministic.optimize, "least_squares", least_squares_recording_threads)
    with threadpool_limits(limits=2, user_api="blas"):
        identify(curves, ["a"], MATERIAL, DISC, SETTINGS)
        outside = [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]
    assert seen and set(seen) == {1}, seen
    assert outside and set(outside) == {2}, outside  # the caller's limit is back after the fit


def test_curves_round_trip_through_csv(tmp_path, monkeypatch):
    curves = synthetic_dyno_curves(tmp_path, monkeypatch, {}, ["V0100_Case2"], seed=1)
    path = write_dyno_curves(curves, tmp_path / "curves.csv")
    again = read_dyno_curves(path, RIG)
    for a, b in zip(curves.series, again.series):
        assert (a.case, a.channel) == (b.case, b.channel)
        np.testing.assert_allclose(a.values, b.values, rtol=1e-9)


# ------------------------------------------------------------------------------------------------
# Stochastic identification

TRUE_SCATTER = cfg.FrictionScatter(initial_mu_sigma=0.013, power_coefficient_sigma_per_s=0.0007)
FAST = SETTINGS.model_copy(update={"stochastic": SETTINGS.stochastic.model_copy(update={"bootstrap_resamples": 100})})


@pytest.fixture(scope="module")
def dyno_applications_table() -> pd.DataFrame:
    """The full dyno campaign's 1950 single-disc stops (MCS-100) with the true scatter."""
    material = MATERIAL.model_copy(update={"scatter": TRUE_SCATTER})
    cases = [case for case, _ in campaigns.dyno_applications(RIG)]
    draw = draw_friction(
        np.random.default_rng(11),
        stochastic_friction(material),
        scatter_partition(cfg.load("setups", "mcs-100")),
        len(cases),
        (1, 1),
    )
    summary = dyno_stops(RIG, cases, draw)
    return pd.DataFrame({"load_case": [c.name for c in cases], "mu_s": summary.mu_s[:, 0]})


@pytest.fixture(scope="module")
def train_applications_table() -> pd.DataFrame:
    """16-disc train stops in MCS-75/25 with resistance scatter: 2 conditions x 60."""
    vehicle = cfg.load("vehicles", "emu_8axle")
    material = MATERIAL.model_copy(update={"scatter": TRUE_SCATTER})
    setup = cfg.load("setups", "mcs-75-25")
    apps = [TrainApplication("empty", "emergency", "EP", v0) for v0 in (100.0, 160.0) for _ in range(60)]
    rng = np.random.default_rng(12)
    partition = scatter_partition(setup)
    draw = draw_friction(
        rng, stochastic_friction(material), partition, len(apps), (vehicle.n_axles, vehicle.discs_per_axle)
    )
    resistance = draw_running_resistance(
        rng, vehicle.running_resistance.A_N, vehicle.running_resistance.A_sigma_N, partition, len(apps)
    )
    summary = train_stops(vehicle, apps, draw, resistance)
    return pd.DataFrame(
        {
            "brake_mode": "emergency",
            "load": "empty",
            "pad_set": "1",
            "actuation": "EP",
            "v0_kmh": [a.initial_speed_kmh for a in apps],
            "mu_s_eff": summary.mu_s_eff,
        }
    )


def test_recovers_scatter_sigmas_from_the_dyno_campaign(dyno_applications_table):
    result = identify_scatter(dyno_spread_groups(dyno_applications_table, RIG, settings=FAST), FAST)
    estimates = {p.name: p for p in result.parameters}
    assert set(estimates) == {"sigma_mu0", "sigma_a"}  # split known (MCS-100), not fitted
    # Tolerances: sigma_mu0 within 15 %, sigma_a within 10 %, truth inside the 95 % intervals.
    for name, truth, tolerance in (("sigma_mu0", 0.013, 0.15), ("sigma_a", 0.0007, 0.10)):
        estimate = estimates[name]
        assert abs(estimate.estimate - truth) <= tolerance * truth, estimate
        assert estimate.ci95[0] <= truth <= estimate.ci95[1], estimate
        assert estimate.identifiable


def test_split_needs_single_and_multi_disc_data(dyno_applications_table, train_applications_table):
    vehicle = cfg.load("vehicles", "emu_8axle")
    dyno_groups = dyno_spread_groups(dyno_applications_table, RIG, settings=FAST)
    train_groups = field_spread_groups(train_applications_table, vehicle, settings=FAST)

    both = identify_scatter(dyno_groups + train_groups, FAST)
    split = next(p for p in both.parameters if p.name == "global_fraction")
    # Tolerance: within 0.15 of MCS-75/25's 0.75, truth inside the interval.
    assert abs(split.estimate - 0.75) <= 0.15 and split.ci95[0] <= 0.75 <= split.ci95[1], split
    assert split.identifiable

    train_only = identify_scatter(train_groups, FAST)
    assert "global_fraction" in train_only.not_identifiable
    assert any(
        "single-disc" in r for r in next(p for p in train_only.parameters if p.name == "global_fraction").reasons
    )

    free_dyno = dyno_spread_groups(dyno_applications_table.iloc[::4], RIG, global_fraction=None, settings=FAST)
    dyno_only = identify_scatter(free_dyno, FAST)
    reasons = next(p for p in dyno_only.parameters if p.name == "global_fraction").reasons
    assert any("multi-disc" in r for r in reasons)


# ------------------------------------------------------------------------------------------------
# Command line and bad input


def test_cli_parameters_and_scatter(tmp_path, monkeypatch, capsys, dyno_applications_table):
    curves = synthetic_dyno_curves(tmp_path, monkeypatch, {"a": 0.0088}, ["V0100_Case1"], seed=2)
    path = write_dyno_curves(curves, tmp_path / "curves.csv")
    out = tmp_path / "fit.json"
    assert main(["identify", "parameters", "--dyno-curves", str(path), "--parameters", "a", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["parameters"][0]["symbol"] == "a"
    assert data["parameters"][0]["estimate"] == pytest.approx(0.0088, rel=0.05)
    assert {"correlation", "channels", "not_identifiable", "weak_combinations", "normalised_singular_values"} <= set(
        data
    )
    assert "95 % interval" in capsys.readouterr().out

    table = tmp_path / "dyno.csv"
    dyno_applications_table.iloc[::6].to_csv(table, index=False)
    out = tmp_path / "scatter.json"
    assert main(["identify", "scatter", "--dyno-csv", str(table), "--json", str(out)]) == 0
    names = [p["name"] for p in json.loads(out.read_text())["parameters"]]
    assert names == ["sigma_mu0", "sigma_a"]


@pytest.mark.parametrize(
    "args, message",
    [
        (["identify", "parameters", "--dyno-curves", "{curves}", "--parameters", "a,q"], "unknown parameter 'q'"),
        (["identify", "parameters", "--dyno-curves", "{missing}"], "cannot read dyno curves"),
        (["identify", "parameters", "--dyno-curves", "{bad}"], "line 3, column mu"),
        (
            ["identify", "parameters", "--dyno-curves", "{curves}", "--config", "nope"],
            "unknown identification config 'nope'",
        ),
        (["identify", "scatter"], "give --dyno-csv and/or --field-csv"),
        (["identify", "scatter", "--dyno-csv", "{curves}"], "missing column(s) ['mu_s']"),
    ],
)
def test_cli_bad_input_exits_2_with_a_message(tmp_path, capsys, args, message):
    curves = tmp_path / "curves.csv"
    curves.write_text("load_case,t_s,mu,T_fric_C\nV0100_Case1,1,0.35,60\nV0100_Case1,2,0.35,70\n")
    bad = tmp_path / "bad.csv"
    bad.write_text("load_case,t_s,mu,T_fric_C\nV0100_Case1,1,0.35,60\nV0100_Case1,2,abc,70\n")
    paths = {"curves": curves, "missing": tmp_path / "none.csv", "bad": bad}
    assert main([a.format(**paths) for a in args]) == 2
    assert message in capsys.readouterr().err


def test_cli_rejects_a_split_outside_0_1(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["identify", "scatter", "--dyno-csv", "x.csv", "--dyno-split", "1.5"])
    assert exit_info.value.code == 2
    assert "--dyno-split" in capsys.readouterr().err


def test_bad_identification_config_names_file_and_field(tmp_path):
    data = yaml.safe_load((REPO_CONFIGS / "identification" / "default.yaml").read_text())
    data["name"] = "broken"
    data["parameters"][0]["lower"] = 1.0  # above its upper bound
    path = tmp_path / "broken.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(cfg.ConfigError, match=r"(?s)broken.yaml.*parameters.0.*lower < upper"):
        load_identification_config(path)
    data["parameters"][0] = {"symbol": "a", "field": "no_such_field", "lower": 0.0, "upper": 1.0}
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(cfg.ConfigError, match="no_such_field"):
        load_identification_config(path)


def test_start_outside_bounds_and_too_few_samples_are_refused():
    curves = DynoCurves(RIG, (Series("V0100_Case1", "mu", np.array([1.0, 2.0]), np.array([0.35, 0.36])),))
    with pytest.raises(ValueError, match=r"start: a .* not strictly inside"):
        identify(curves, ["a"], MATERIAL, DISC, SETTINGS, start={"a": 0.5})
    with pytest.raises(ValueError, match="2 samples cannot determine 2 parameters"):
        identify(curves, ["a", "x"], MATERIAL, DISC, SETTINGS)
    with pytest.raises(ValueError, match="unknown load case"):
        DynoCurves(RIG, (Series("V0999", "mu", np.array([1.0, 2.0]), np.array([0.35, 0.36])),))
