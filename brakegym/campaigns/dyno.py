"""The dynamometer campaign of paper Table 1: single-disc stops per load case and pad specimen,
with the instantaneous mean and standard deviation over applications (Eq. 2) and mu_s (Eq. 3)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .. import config as cfg
from ..applications import DEFAULT_STEP_S, Trajectory, dyno_stops
from ..physics import FrictionDraw, draw_friction
from ..plants import scatter_partition, stochastic_friction
from ..statistics import envelope, sample_statistics
from .runner import run_chunks, scatter_back


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
                    row.update(
                        {
                            f"{column}_mean": st.mean,
                            f"{column}_std": st.std,
                            f"{column}_mean_ci95": st.mean_ci95,
                            f"{column}_std_ci95": st.std_ci95,
                        }
                    )
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
    draw = draw_friction(rng, stochastic_friction(material), scatter_partition(setup), n, (1, 1))
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
    summaries = run_chunks(jobs, workers, progress, [len(c) for c in indices])
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
            "s_m": scatter_back(n, indices, [s.stop_distance_m for s in summaries]),
            "s2_m": scatter_back(n, indices, [s.onset_distance_m for s in summaries]),
            "mu_s": scatter_back(n, indices, [s.mu_s[:, 0] for s in summaries]),
            "t_stop_s": scatter_back(n, indices, [s.stop_time_s for s in summaries]),
            "T_fric_max_C": scatter_back(n, indices, [s.peak_friction_temperature_C[:, 0] for s in summaries]),
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
