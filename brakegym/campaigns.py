"""Monte-Carlo campaigns of the paper: the dynamometer campaign (Table 1) and the field campaign
(Table 4), in the set-ups DS, MCS-100, MCS-75/25 (spec Section 5), with the statistics of
spec Section 6: instantaneous mean and standard deviation over applications (Eq. 2), mean COF over
distance (Eq. 3), effective COF of the train (Eq. 15), 95 % confidence intervals (Student's t for
means, chi-square for standard deviations).

All random numbers of a campaign come from one ``numpy.random.Generator`` seeded by the caller and
are drawn up front in a fixed order and the stops run in chunks of fixed composition, so the same
seed gives the same campaign bit for bit whatever the number of worker processes.
"""

from __future__ import annotations

import itertools
import multiprocessing
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
import pandas as pd
from scipy import stats

from . import config as cfg
from . import kernel
from .applications import DEFAULT_STEP_S, StopSummary, TrainApplication, Trajectory, dyno_stops, train_stops
from .physics import FrictionDraw, draw_friction, draw_running_resistance

# Stops run in chunks of this many trains: big enough that numpy's per-call overhead vanishes,
# small enough that the chunks spread over the worker processes.
CHUNK_TRAINS = 1100


# ------------------------------------------------------------------------------------------------
# Statistics


@dataclass(frozen=True)
class SampleStatistics:
    """Mean and empirical standard deviation of a sample with their 95 % confidence intervals."""

    n: int
    mean: float
    std: float
    mean_ci95: tuple[float, float]
    std_ci95: tuple[float, float]

    @property
    def relative_std(self) -> float:
        return self.std / self.mean

    def as_dict(self) -> dict[str, float | int | list[float]]:
        return {
            "n": self.n,
            "mean": self.mean,
            "std": self.std,
            "mean_ci95": list(self.mean_ci95),
            "std_ci95": list(self.std_ci95),
        }


def sample_statistics(values: Sequence[float] | np.ndarray, confidence: float = 0.95) -> SampleStatistics:
    """Mean with a Student-t interval, standard deviation (ddof 1) with a chi-square interval."""
    x = np.asarray(values, dtype=float)
    if x.ndim != 1 or len(x) < 2:
        raise ValueError(f"need a 1-D sample of at least 2 values, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("sample contains non-finite values")
    n = len(x)
    mean = float(x.mean())
    std = float(x.std(ddof=1))
    alpha = 1.0 - confidence
    half_width = stats.t.ppf(1 - alpha / 2, n - 1) * std / np.sqrt(n)
    chi_low, chi_high = stats.chi2.ppf(1 - alpha / 2, n - 1), stats.chi2.ppf(alpha / 2, n - 1)
    return SampleStatistics(
        n=n,
        mean=mean,
        std=std,
        mean_ci95=(mean - half_width, mean + half_width),
        std_ci95=(float(std * np.sqrt((n - 1) / chi_low)), float(std * np.sqrt((n - 1) / chi_high))),
    )


def envelope(trajectory_values: np.ndarray, moving: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Instantaneous mean and standard deviation over applications (Eq. 2) of a (T, B) series,
    counting at each instant only the applications still braking. Returns (mean, std, count)."""
    values = np.where(moving, trajectory_values, np.nan)
    count = moving.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.nanmean(np.where(count[:, None] > 0, values, 0.0), axis=1)
        std = np.where(count > 1, np.nanstd(np.where(count[:, None] > 1, values, 0.0), axis=1, ddof=1), np.nan)
    mean = np.where(count > 0, mean, np.nan)
    return mean, std, count


# ------------------------------------------------------------------------------------------------
# Running chunks


def _chunks(order: np.ndarray, size: int) -> list[np.ndarray]:
    return [order[i : i + size] for i in range(0, len(order), size)]


def _call(job: tuple[Callable[..., StopSummary], tuple]) -> StopSummary:
    function, arguments = job
    return function(*arguments)


def _run_chunks(
    jobs: list[tuple[Callable[..., StopSummary], tuple]],
    workers: int,
    progress: Callable[[int], None] | None = None,
    sizes: Sequence[int] | None = None,
) -> list[StopSummary]:
    """Run ``function(*arguments)`` for every job, in ``workers`` forked processes when more than
    one (the stop bookkeeping between the compiled steps holds the GIL, so threads gain little).
    Chunk composition is fixed by the caller, so the results do not depend on ``workers``."""
    results: list[StopSummary] = []
    if workers <= 1 or len(jobs) == 1 or "fork" not in multiprocessing.get_all_start_methods():
        iterator = map(_call, jobs)
        pool = None
    else:
        # Loaded once here, the compiled kernels are inherited by every forked worker.
        kernel.warm_up()
        pool = multiprocessing.get_context("fork").Pool(min(workers, len(jobs)))
        iterator = pool.imap(_call, jobs)
    try:
        for index, result in enumerate(iterator):
            results.append(result)
            if progress is not None:
                progress(sizes[index] if sizes is not None else 1)
    finally:
        if pool is not None:
            pool.close()
            pool.join()
    return results


def _scatter_back(n: int, indices: list[np.ndarray], parts: list[np.ndarray]) -> np.ndarray:
    first = parts[0]
    out = np.empty((n, *first.shape[1:]), dtype=first.dtype)
    for chunk, part in zip(indices, parts):
        out[chunk] = part
    return out


# ------------------------------------------------------------------------------------------------
# Dynamometer campaign (paper Table 1)


@dataclass
class DynoCampaignResult:
    setup: str
    seed: int
    applications: pd.DataFrame  # one row per application
    envelopes: dict[str, pd.DataFrame]  # per load case: t_s, mu/T mean and std, count
    step_s: float

    def load_case_summary(self) -> pd.DataFrame:
        """Per load case: mean and standard deviation of mu_s and braking distance, with CIs."""
        rows = []
        for name, group in self.applications.groupby("load_case", sort=False):
            row: dict[str, object] = {"load_case": name, "v0_kmh": group.v0_kmh.iloc[0], "n": len(group)}
            for column in ("mu_s", "s_m", "t_stop_s", "T_fric_max_C"):
                if len(group) > 1 and group[column].std() > 0:
                    st = sample_statistics(group[column].to_numpy())
                    row.update({f"{column}_mean": st.mean, f"{column}_std": st.std,
                                f"{column}_mean_ci95": st.mean_ci95, f"{column}_std_ci95": st.std_ci95})
                else:
                    row.update({f"{column}_mean": group[column].mean(), f"{column}_std": 0.0})
            rows.append(row)
        return pd.DataFrame(rows)

    def specimen_summary(self) -> pd.DataFrame:
        """Mean mu_s per pad specimen and load case (paper Fig. 12 style)."""
        return (
            self.applications.groupby(["load_case", "specimen"], sort=False)["mu_s"]
            .agg(["count", "mean", "std"])
            .reset_index()
        )


def dyno_applications(rig: cfg.Dynamometer) -> list[tuple[cfg.LoadCase, str]]:
    """Every application of the campaign: (load case, specimen), in the rig's order."""
    out = []
    for case in rig.load_cases:
        for specimen, count in zip(rig.specimens, case.applications_per_specimen):
            out.extend([(case, specimen)] * count)
    return out


def dyno_campaign(
    rig: cfg.Dynamometer,
    setup: cfg.ScatterSetup,
    seed: int,
    step_s: float = DEFAULT_STEP_S,
    sample_every_s: float = 1.0,
    workers: int = 2,
    progress: Callable[[int], None] | None = None,
) -> DynoCampaignResult:
    """The 1950 single-disc stops of paper Table 1, each with its own friction draw."""
    material = cfg.load("materials", rig.material)
    applications = dyno_applications(rig)
    n = len(applications)
    rng = np.random.default_rng(seed)
    draw = draw_friction(rng, material, setup, n, (1, 1))
    record_every = max(1, int(round(sample_every_s / step_s)))
    case_names = [case.name for case, _ in applications]
    indices = [np.flatnonzero(np.array(case_names) == case.name) for case in rig.load_cases]
    indices = [chunk for chunk in indices if len(chunk)]

    jobs = [
        (
            dyno_stops,
            (
                rig,
                [applications[i][0] for i in chunk],
                FrictionDraw(draw.initial_mu[chunk], draw.power_coefficient_per_s[chunk]),
                step_s,
                record_every,
            ),
        )
        for chunk in indices
    ]
    summaries = _run_chunks(jobs, workers, progress, [len(c) for c in indices])
    envelopes = {}
    for chunk, summary in zip(indices, summaries):
        envelopes[applications[chunk[0]][0].name] = _dyno_envelope(summary.trajectory)
    table = pd.DataFrame(
        {
            "load_case": case_names,
            "specimen": [specimen for _, specimen in applications],
            "v0_kmh": [case.initial_speed_kmh for case, _ in applications],
            "initial_mu": draw.initial_mu.reshape(n),
            "power_coefficient_per_s": draw.power_coefficient_per_s.reshape(n),
            "s_m": _scatter_back(n, indices, [s.stop_distance_m for s in summaries]),
            "s2_m": _scatter_back(n, indices, [s.onset_distance_m for s in summaries]),
            "mu_s": _scatter_back(n, indices, [s.mu_s[:, 0] for s in summaries]),
            "t_stop_s": _scatter_back(n, indices, [s.stop_time_s for s in summaries]),
            "T_fric_max_C": _scatter_back(n, indices, [s.peak_friction_temperature_C[:, 0] for s in summaries]),
        }
    )
    return DynoCampaignResult(setup=setup.name, seed=seed, applications=table, envelopes=envelopes, step_s=step_s)


def _dyno_envelope(trajectory: Trajectory | None) -> pd.DataFrame:
    assert trajectory is not None
    moving = trajectory.speed_mps > 0
    columns: dict[str, np.ndarray] = {"t_s": trajectory.time_s}
    for name, series in (("mu", trajectory.mu[:, :, 0]), ("T_fric_C", trajectory.friction_temperature_C[:, :, 0])):
        mean, std, count = envelope(series, moving)
        columns[f"{name}_mean"] = mean
        columns[f"{name}_std"] = std
        columns["n_braking"] = count
    return pd.DataFrame(columns)


# ------------------------------------------------------------------------------------------------
# Field campaign (paper Table 4)


def field_applications(campaign: cfg.FieldCampaign) -> list[TrainApplication]:
    """The field applications of the campaign: the factorial of its factors minus exclusions."""
    names = ["brake_mode", "load", "pad_set", "actuation", "initial_speed_kmh"]
    out = []
    for values in itertools.product(*(campaign.factors[name] for name in names)):
        combo = dict(zip(names, values))
        if any(all(combo[key] == value for key, value in rule.items()) for rule in campaign.exclude):
            continue
        out.append(
            TrainApplication(
                load=str(combo["load"]),
                brake_mode=str(combo["brake_mode"]),
                actuation=str(combo["actuation"]),
                initial_speed_kmh=float(combo["initial_speed_kmh"]),
                command_time_s=campaign.command_time_s,
                pad_set=str(combo["pad_set"]),
            )
        )
    return out


@dataclass
class FieldCampaignResult:
    setup: str
    seed: int
    applications: pd.DataFrame  # one row per simulated stop
    step_s: float

    def application_summary(self) -> pd.DataFrame:
        """Per field application (over its repetitions): mean and std of mu_s,eff and braking
        distance with 95 % CIs."""
        keys = ["brake_mode", "load", "pad_set", "actuation", "v0_kmh"]
        rows = []
        for key, group in self.applications.groupby(keys, sort=False):
            row: dict[str, object] = dict(zip(keys, key))
            row["n"] = len(group)
            for column in ("mu_s_eff", "braking_distance_m"):
                st = sample_statistics(group[column].to_numpy()) if group[column].std() > 0 else None
                row[f"{column}_mean"] = group[column].mean()
                row[f"{column}_std"] = st.std if st else 0.0
                row[f"{column}_mean_ci95"] = st.mean_ci95 if st else (row[f"{column}_mean"],) * 2
                row[f"{column}_std_ci95"] = st.std_ci95 if st else (0.0, 0.0)
            rows.append(row)
        return pd.DataFrame(rows)


def train_monte_carlo(
    vehicle: cfg.Vehicle,
    applications: Sequence[TrainApplication],
    setup: cfg.ScatterSetup,
    seed: int,
    step_s: float = DEFAULT_STEP_S,
    workers: int = 2,
    progress: Callable[[int], None] | None = None,
) -> tuple[StopSummary, FrictionDraw, np.ndarray]:
    """Stops of ``vehicle`` for a list of applications with the set-up's scatter. Returns the
    summary (in the order of ``applications``), the friction draw and the resistance draw."""
    material = cfg.load("materials", vehicle.material)
    n = len(applications)
    rng = np.random.default_rng(seed)
    draw = draw_friction(rng, material, setup, n, (vehicle.n_axles, vehicle.discs_per_axle))
    resistance = draw_running_resistance(rng, vehicle.running_resistance, setup, n)
    # Similar stops together, so a chunk finishes at about the same time for all its trains.
    order = np.array(
        sorted(range(n), key=lambda i: (applications[i].initial_speed_kmh, applications[i].brake_mode)), dtype=np.int64
    )
    indices = _chunks(order, CHUNK_TRAINS)

    jobs = [
        (
            train_stops,
            (
                vehicle,
                [applications[i] for i in chunk],
                FrictionDraw(draw.initial_mu[chunk], draw.power_coefficient_per_s[chunk]),
                resistance[chunk],
                step_s,
            ),
        )
        for chunk in indices
    ]
    parts = _run_chunks(jobs, workers, progress, [len(c) for c in indices])
    merged = {
        name: _scatter_back(n, indices, [getattr(p, name) for p in parts])
        for name in StopSummary.__dataclass_fields__
        if name != "trajectory"
    }
    return StopSummary(**merged), draw, resistance


def field_campaign(
    campaign: cfg.FieldCampaign,
    setup: cfg.ScatterSetup,
    seed: int,
    step_s: float = DEFAULT_STEP_S,
    workers: int = 2,
    progress: Callable[[int], None] | None = None,
) -> FieldCampaignResult:
    """Every field application of the campaign, simulated ``repetitions`` times."""
    vehicle = cfg.load("vehicles", campaign.vehicle)
    field_apps = field_applications(campaign)
    applications = [app for app in field_apps for _ in range(campaign.repetitions)]
    summary, _, resistance = train_monte_carlo(vehicle, applications, setup, seed, step_s, workers, progress)
    table = pd.DataFrame(
        {
            "brake_mode": [a.brake_mode for a in applications],
            "load": [a.load for a in applications],
            "pad_set": [a.pad_set for a in applications],
            "actuation": [a.actuation for a in applications],
            "v0_kmh": [a.initial_speed_kmh for a in applications],
            "repetition": np.tile(np.arange(campaign.repetitions), len(field_apps)),
            "running_resistance_A_N": resistance,
            "stop_time_s": summary.stop_time_s,
            "stop_distance_m": summary.stop_distance_m,
            "braking_distance_m": summary.braking_distance_m,
            "mu_s_eff": summary.mu_s_eff,
            "mu_s_mean": summary.mean_mu_s,
            "T_fric_max_C": summary.peak_temperature_C,
        }
    )
    return FieldCampaignResult(setup=setup.name, seed=seed, applications=table, step_s=step_s)
