"""Conformance: the simulator reproduces every number in tests/golden within the spec's
tolerances (0.5 % on distances, times and mu; 2 K on temperatures), at the default step."""

import numpy as np
import pandas as pd
import pytest

from brakegym import config as cfg
from brakegym.applications import TrainApplication, dyno_stops, train_stops
from brakegym.defaults import DEFAULT_STEP_S

REL = 0.005
KELVIN_TOL = 2.0


@pytest.fixture(scope="module")
def rig():
    return cfg.load("rigs", "dynamometer")


@pytest.mark.parametrize("step_s", [DEFAULT_STEP_S, 0.1])
def test_dyno_load_cases(golden_dir, rig, step_s):
    golden = pd.read_csv(golden_dir / "dyno_load_cases.csv")
    summary = dyno_stops(rig, [rig.load_case(name) for name in golden.load_case], step_s=step_s)
    np.testing.assert_allclose(summary.stop_distance_m, golden.s, rtol=REL)
    np.testing.assert_allclose(summary.onset_distance_m, golden.s2, rtol=REL)
    np.testing.assert_allclose(summary.mu_s[:, 0], golden.mu_s, rtol=REL)
    np.testing.assert_allclose(summary.stop_time_s, golden.t_stop, rtol=REL)
    np.testing.assert_allclose(summary.peak_friction_temperature_C[:, 0], golden.T_fric_max_C, atol=KELVIN_TOL)


def _check_series(golden: pd.DataFrame, traj, column_map: dict[str, np.ndarray], stop_time_s: float) -> None:
    times = np.round(traj.time_s, 9)
    for _, row in golden.iterrows():
        index = int(np.flatnonzero(np.isclose(times, row.t_s))[0])
        for column, values in column_map.items():
            expected = row[column]
            got = values[index]
            if column.endswith("_C"):
                assert abs(got - expected) <= KELVIN_TOL, (row.t_s, column, got, expected)
            elif abs(row.t_s - stop_time_s) < 1.0 and column in ("v_mps", "decel_mps2"):
                # Within a second of standstill speed and deceleration go to zero, so a
                # relative tolerance is meaningless: compare in absolute terms.
                assert abs(got - expected) <= 0.02, (row.t_s, column, got, expected)
            else:
                assert got == pytest.approx(expected, rel=REL, abs=1e-6), (row.t_s, column, got, expected)


@pytest.mark.parametrize("name", ["V0100_Case1", "V0160_Case3"])
def test_dyno_series(golden_dir, rig, name):
    golden = pd.read_csv(golden_dir / f"dyno_{name}_series.csv")
    record_every = int(round(1.0 / DEFAULT_STEP_S))
    summary = dyno_stops(rig, [rig.load_case(name)], record_every=record_every, until_time_s=golden.t_s.max() + 2.0)
    traj = summary.trajectory
    _check_series(
        golden,
        traj,
        {
            "v_mps": traj.speed_mps[:, 0],
            "s_m": traj.position_m[:, 0],
            "mu": traj.mu[:, 0, 0],
            "F_C_N": traj.clamp_force_N[:, 0, 0],
            "T_fric_C": traj.friction_temperature_C[:, 0, 0],
        },
        summary.stop_time_s[0],
    )


def test_train_series_and_stop(golden_dir):
    golden = pd.read_csv(golden_dir / "train_V0120_empty_emergency_EP_series.csv")
    vehicle = cfg.load("vehicles", "emu_8axle")
    app = TrainApplication(load="empty", brake_mode="emergency", actuation="EP", initial_speed_kmh=120.0)
    summary = train_stops(
        vehicle, [app], record_every=int(round(1.0 / DEFAULT_STEP_S)), until_time_s=golden.t_s.max() + 2.0
    )
    traj = summary.trajectory
    _check_series(
        golden,
        traj,
        {
            "v_mps": traj.speed_mps[:, 0],
            "s_m": traj.position_m[:, 0],
            "p_c_bar": traj.pressure_bar[:, 0, 0],
            "mu_disc1": traj.mu[:, 0, 0],
            "T_fric_disc1_C": traj.friction_temperature_C[:, 0, 0],
            "decel_mps2": traj.deceleration_mps2[:, 0],
        },
        summary.stop_time_s[0],
    )
    # Spec Section 8: 589.3 m and 32.9 s to standstill, counted from the start of the run.
    assert summary.stop_distance_m[0] == pytest.approx(589.3, rel=REL)
    assert summary.stop_time_s[0] == pytest.approx(32.9, rel=REL)
    assert summary.braking_distance_m[0] == pytest.approx(summary.stop_distance_m[0] - golden.s_m[1], rel=1e-3)


def test_step_convergence(rig):
    """RK4 is fourth order: halving the step cuts the distance error (against a fine reference)."""
    case = [rig.load_case("V0160_Case3")]
    reference = dyno_stops(rig, case, step_s=0.025).stop_distance_m[0]
    coarse = abs(dyno_stops(rig, case, step_s=0.2).stop_distance_m[0] - reference)
    fine = abs(dyno_stops(rig, case, step_s=0.1).stop_distance_m[0] - reference)
    assert fine < coarse
    assert coarse / reference < 1e-3


def test_golden_files_are_the_ones_their_provenance_names(golden_dir):
    """The reference values are data the project owns: a change to a file must come with a new
    provenance entry (tests/golden/PROVENANCE.md lists each file's SHA-256)."""
    import hashlib
    import re

    listed = dict(
        (name, digest)
        for digest, name in re.findall(r"^([0-9a-f]{64})  (\S+)$", (golden_dir / "PROVENANCE.md").read_text(), re.M)
    )
    files = {path.name: hashlib.sha256(path.read_bytes()).hexdigest() for path in golden_dir.glob("*.csv")}
    assert files == listed
