"""The field campaign of paper Table 4: train stops of a factorial of applications, each with the
set-up's friction and running-resistance scatter, summarised by mu_s,eff (Eq. 15) and braking
distance."""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .. import config as cfg
from ..applications import DEFAULT_STEP_S, StopSummary, TrainApplication, train_stops
from ..physics import FrictionDraw
from ..plants import train_scatter
from ..statistics import sample_statistics
from .runner import CHUNK_TRAINS, chunks, run_chunks, scatter_back


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
    n = len(applications)
    draw, resistance = train_scatter(vehicle, setup).draw(np.random.default_rng(seed), n)
    # Similar stops together, so a chunk finishes at about the same time for all its trains.
    order = np.array(
        sorted(range(n), key=lambda i: (applications[i].initial_speed_kmh, applications[i].brake_mode)), dtype=np.int64
    )
    indices = chunks(order, CHUNK_TRAINS)

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
    parts = run_chunks(jobs, workers, progress, [len(c) for c in indices])
    merged = {
        name: scatter_back(n, indices, [getattr(p, name) for p in parts])
        for name in StopSummary.__dataclass_fields__
        # Left at their defaults: no trajectories in a campaign, no slip work without adhesion.
        if name != "trajectory" and getattr(parts[0], name) is not None
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
