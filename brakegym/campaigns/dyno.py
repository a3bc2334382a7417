"""The dynamometer campaign of paper Table 1: single-disc stops per load case and pad specimen,
with the instantaneous mean and standard deviation over applications (Eq. 2) and mu_s (Eq. 3).

Application ``i`` (in :func:`dyno_applications`' order) takes the friction of sample ``i`` of the
seed (:func:`~brakegym.plants.friction_for_samples`). The campaign runs one chunk per load case
(:mod:`.chunks`): the envelope of Eq. 2 is a statistic over a load case's applications at each
instant, computed in the chunk from that load case's trajectories, so its composition is fixed
by the campaign (and small: the largest load case has a few hundred single-disc stops).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .. import config as cfg
from ..applications import Trajectory, dyno_stops
from ..defaults import DEFAULT_STEP_S
from ..execution import Executor
from ..execution.base import Progress
from ..plants import friction_for_samples, scatter_partition, stochastic_friction
from ..statistics import envelope, sample_statistics
from .chunks import Chunk, chunks_between, run_chunks
from .store import CampaignStore, versions

STOPS, ENVELOPES = "stops", "envelopes"
# The columns of the dynamometer campaign's tables (in a folder's Parquet files): one row per stop,
# and per load case the envelope of Eq. 2 at each recorded instant.
STOP_COLUMNS = (
    "stop",  # the application's number, its random stream's sample index
    "load_case",  # the load case's number in the rig's list
    "specimen",  # the specimen's number in the rig's list
    "initial_mu",
    "power_coefficient_per_s",
    "s_m",
    "s2_m",
    "mu_s",
    "t_stop_s",
    "T_fric_max_C",
)
ENVELOPE_COLUMNS = ("t_s", "mu_mean", "mu_std", "n_braking", "T_fric_C_mean", "T_fric_C_std")


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


@dataclass(frozen=True)
class DynoChunkTask:
    """The stops of one load case of the dynamometer campaign, from the seed and the stops'
    numbers alone, and the load case's envelope."""

    rig: cfg.Dynamometer
    setup: cfg.ScatterSetup
    seed: int
    step_s: float
    record_every: int

    def __call__(self, chunk: Chunk) -> dict[str, dict[str, np.ndarray]]:
        applications = dyno_applications(self.rig)[chunk.start : chunk.stop]
        stop = chunk.sample_index()
        material = cfg.load("materials", self.rig.material)
        draw = friction_for_samples(
            stochastic_friction(material), scatter_partition(self.setup), (1, 1), self.seed, stop
        )
        cases = [case for case, _ in applications]
        summary = dyno_stops(self.rig, cases, draw, self.step_s, self.record_every)
        case_numbers = {case.name: number for number, case in enumerate(self.rig.load_cases)}
        specimen_numbers = {name: number for number, name in enumerate(self.rig.specimens)}
        stops = {
            "stop": stop,
            "load_case": np.array([case_numbers[case.name] for case in cases]),
            "specimen": np.array([specimen_numbers[specimen] for _, specimen in applications]),
            "initial_mu": draw.initial_mu.reshape(len(stop)),
            "power_coefficient_per_s": draw.power_coefficient_per_s.reshape(len(stop)),
            "s_m": summary.stop_distance_m,
            "s2_m": summary.onset_distance_m,
            "mu_s": summary.mu_s[:, 0],
            "t_stop_s": summary.stop_time_s,
            "T_fric_max_C": summary.peak_friction_temperature_C[:, 0],
        }
        return {STOPS: stops, ENVELOPES: _dyno_envelope(summary.trajectory)}


def dyno_campaign(
    rig: cfg.Dynamometer,
    setup: cfg.ScatterSetup,
    seed: int,
    step_s: float = DEFAULT_STEP_S,
    sample_every_s: float = 1.0,
    executor: Executor | None = None,
    progress: Progress | None = None,
    out: str | Path | None = None,
    resume: bool = False,
) -> DynoCampaignResult:
    """The 1950 single-disc stops of paper Table 1, each with its own friction draw, one chunk
    per load case on ``executor`` (default: this process); the envelopes recorded every
    ``sample_every_s``. With ``out``, each load case's rows go to Parquet files in that folder
    (:mod:`.store`) and ``resume`` continues a campaign interrupted there."""
    applications = dyno_applications(rig)
    record_every = max(1, int(round(sample_every_s / step_s)))
    boundaries = [0, *itertools.accumulate(sum(case.applications_per_specimen) for case in rig.load_cases)]
    chunks = chunks_between(sorted(set(boundaries)))
    store = None
    if out is not None:
        manifest = dyno_manifest(rig, setup, seed, step_s, sample_every_s, len(chunks))
        store = CampaignStore.open(out, manifest, resume)
    elif resume:
        raise ValueError("resume needs the folder of the campaign to resume (out)")
    task = DynoChunkTask(rig, setup, seed, step_s, record_every)
    rows = run_chunks(task, chunks, executor, store, progress)
    stops = rows.concatenated(STOPS)
    case_names = np.array([case.name for case in rig.load_cases], dtype=object)
    table = pd.DataFrame(
        {
            "load_case": case_names[stops["load_case"]],
            "specimen": np.array(rig.specimens, dtype=object)[stops["specimen"]],
            "v0_kmh": [case.initial_speed_kmh for case, _ in applications],
            **{name: stops[name] for name in STOP_COLUMNS[3:]},
        }
    )
    envelopes = {
        applications[chunk.start][0].name: pd.DataFrame(columns)
        for chunk, columns in zip(rows.chunks, rows.read(ENVELOPES))
    }
    return DynoCampaignResult(setup=setup.name, seed=seed, applications=table, envelopes=envelopes, step_s=step_s)


def dyno_manifest(
    rig: cfg.Dynamometer, setup: cfg.ScatterSetup, seed: int, step_s: float, sample_every_s: float, n_chunks: int
) -> dict[str, object]:
    """What decides the dynamometer campaign's rows (:mod:`.store`)."""
    configs = {
        "rig": rig.model_dump(mode="json"),
        "setup": setup.model_dump(mode="json"),
        "material": cfg.load("materials", rig.material).model_dump(mode="json"),
        "disc": cfg.load("discs", rig.disc).model_dump(mode="json"),
    }
    return {
        "campaign": "dyno",
        "configs": configs,
        "seed": seed,
        "step_s": step_s,
        "sample_every_s": sample_every_s,
        "chunks": n_chunks,
        "stops": len(dyno_applications(rig)),
        "tables": {STOPS: list(STOP_COLUMNS), ENVELOPES: list(ENVELOPE_COLUMNS)},
        "versions": versions(),
    }


def _dyno_envelope(trajectory: Trajectory | None) -> dict[str, np.ndarray]:
    assert trajectory is not None
    moving = trajectory.speed_mps > 0
    columns: dict[str, np.ndarray] = {"t_s": trajectory.time_s}
    for name, series in (("mu", trajectory.mu[:, :, 0]), ("T_fric_C", trajectory.friction_temperature_C[:, :, 0])):
        mean, std, count = envelope(series, moving)
        columns[f"{name}_mean"] = mean
        columns[f"{name}_std"] = std
        columns["n_braking"] = count
    return {name: columns[name] for name in ENVELOPE_COLUMNS}
