"""The field campaign of paper Table 4: train stops of a factorial of applications, each with the
set-up's friction and running-resistance scatter, summarised by mu_s,eff (Eq. 15) and braking
distance; and train stops of any list of applications with scatter (:func:`train_monte_carlo`).

Stop ``i`` of a campaign is repetition ``i % r`` of field application ``i // r`` (``r``
repetitions each, the applications in :func:`field_applications`' order), and its scatter comes
from the seed and ``i`` alone (:meth:`~brakegym.plants.TrainScatter.draw_for_samples`). The stops
run in chunks of consecutive stops (:mod:`.chunks`) on any executor; the per-stop rows stay in
memory, or go to Parquet files in a folder (:mod:`.store`), from which the summaries are computed
one field application at a time.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .. import config as cfg
from ..applications import StopSummary, TrainApplication, train_stops
from ..defaults import DEFAULT_CHUNK_STOPS, DEFAULT_STEP_S
from ..execution import Executor, InlineExecutor
from ..execution.base import Progress
from ..physics import FrictionDraw
from ..plants import train_scatter
from ..statistics import pooled_mean_std, sample_statistics
from .chunks import CampaignRows, Chunk, even_chunks, run_chunks
from .store import CampaignStore, versions

STOPS = "stops"
# The columns of a field campaign's stops table (one row per stop, in a folder's Parquet files).
STOP_COLUMNS = (
    "stop",  # the stop's number in the campaign, its random streams' sample index
    "field_application",  # its field application's number in field_applications()
    "repetition",
    "running_resistance_A_N",
    "stop_time_s",
    "stop_distance_m",
    "braking_distance_m",
    "mu_s_eff",
    "mu_s_mean",
    "T_fric_max_C",
)
# The summaries' quantities.
SUMMARY_COLUMNS = ("mu_s_eff", "braking_distance_m")
_DESCRIPTION = ("brake_mode", "load", "pad_set", "actuation", "v0_kmh")


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


def scattered_train_stops(
    vehicle: cfg.Vehicle,
    applications: Sequence[TrainApplication],
    setup: cfg.ScatterSetup,
    seed: int,
    sample_index: np.ndarray,
    step_s: float = DEFAULT_STEP_S,
) -> tuple[StopSummary, FrictionDraw, np.ndarray]:
    """Stops of ``vehicle``, application ``applications[k]`` with the scatter of sample
    ``sample_index[k]`` of the seed: the summary, the friction draw and the running resistance."""
    draw, resistance = train_scatter(vehicle, setup).draw_for_samples(seed, sample_index)
    return train_stops(vehicle, applications, draw, resistance, step_s), draw, resistance


def field_stop_columns(
    stop: np.ndarray, repetitions: int, running_resistance_A_N: np.ndarray, summary: StopSummary
) -> dict[str, np.ndarray]:
    """The ``STOP_COLUMNS`` of the field campaign's stops ``stop`` (their sample indices, of
    ``repetitions`` repetitions per field application), run with ``running_resistance_A_N``."""
    return {
        "stop": stop,
        "field_application": stop // repetitions,
        "repetition": stop % repetitions,
        "running_resistance_A_N": running_resistance_A_N,
        "stop_time_s": summary.stop_time_s,
        "stop_distance_m": summary.stop_distance_m,
        "braking_distance_m": summary.braking_distance_m,
        "mu_s_eff": summary.mu_s_eff,
        "mu_s_mean": summary.mean_mu_s,
        "T_fric_max_C": summary.peak_temperature_C,
    }


@dataclass(frozen=True)
class FieldChunkTask:
    """The stops of a chunk of a field campaign, from the seed and the stops' numbers alone."""

    vehicle: cfg.Vehicle
    applications: tuple[TrainApplication, ...]
    repetitions: int
    setup: cfg.ScatterSetup
    seed: int
    step_s: float

    def __call__(self, chunk: Chunk) -> dict[str, dict[str, np.ndarray]]:
        stop = chunk.sample_index()
        application = stop // self.repetitions
        summary, _, resistance = scattered_train_stops(
            self.vehicle, [self.applications[a] for a in application], self.setup, self.seed, stop, self.step_s
        )
        return {STOPS: field_stop_columns(stop, self.repetitions, resistance, summary)}


@dataclass
class FieldCampaignResult:
    """A field campaign's stops (``rows``, in memory or in a folder) and their summaries."""

    setup: str
    seed: int
    step_s: float
    field_applications: list[TrainApplication]
    repetitions: int
    rows: CampaignRows

    @property
    def n_stops(self) -> int:
        return len(self.field_applications) * self.repetitions

    @functools.cached_property
    def applications(self) -> pd.DataFrame:
        """Every stop, one row each in campaign order, with the field application (brake_mode, load,
        pad_set, actuation, v0_kmh), repetition, running_resistance_A_N, stop_time_s,
        stop_distance_m, braking_distance_m, mu_s_eff, mu_s_mean, T_fric_max_C. Every stop in
        memory at once (about 200 bytes a stop); :meth:`application_summary` and
        :meth:`write_csv` need one field application's or one chunk's rows at a time."""
        return self._table(self.rows.concatenated(STOPS))

    def write_csv(self, path: str | Path) -> None:
        """:attr:`applications` as CSV, written one chunk at a time."""
        with open(path, "w", newline="") as stream:
            for position, columns in enumerate(self.rows.read(STOPS)):
                self._table(columns).to_csv(stream, index=False, header=position == 0)

    def application_summary(self) -> pd.DataFrame:
        """Per field application (over its repetitions): n, and mean and std of mu_s,eff and
        braking distance with their 95 % CIs (``mu_s_eff_mean``, ``mu_s_eff_std``,
        ``mu_s_eff_mean_ci95``, ``mu_s_eff_std_ci95``, ``braking_distance_m_...``).

        Computed one field application at a time from its stops in repetition order, the same
        numbers whether the stops are in memory or in a folder, whatever the chunks."""
        rows = []
        columns = ["field_application", *SUMMARY_COLUMNS]
        for application, values in _by_application(self.rows.read(STOPS, columns)):
            row: dict[str, object] = dict(zip(_DESCRIPTION, _describe(self.field_applications[application])))
            row["n"] = len(values["field_application"])
            for column in SUMMARY_COLUMNS:
                row.update(_column_summary(column, values[column]))
            rows.append(row)
        return pd.DataFrame(rows)

    def mode_speed_summary(self, summary: pd.DataFrame | None = None) -> pd.DataFrame:
        """Per brake mode and initial speed: stops, and mean and std of mu_s,eff and braking
        distance over all their stops, pooled from the field applications' (``summary``: an
        :meth:`application_summary` already computed)."""
        summary = self.application_summary() if summary is None else summary
        rows = []
        for (mode, speed), group in summary.groupby(["brake_mode", "v0_kmh"], sort=True):
            row: dict[str, object] = {"brake_mode": mode, "v0_kmh": speed, "n": int(group.n.sum())}
            for column in SUMMARY_COLUMNS:
                mean, std = pooled_mean_std(group.n, group[f"{column}_mean"], group[f"{column}_std"])
                row.update({f"{column}_mean": mean, f"{column}_std": std})
            rows.append(row)
        return pd.DataFrame(rows)

    def _table(self, columns: Mapping[str, np.ndarray]) -> pd.DataFrame:
        described = np.array([_describe(app) for app in self.field_applications], dtype=object)
        application = columns["field_application"]
        table = {name: described[application, k] for k, name in enumerate(_DESCRIPTION)}
        table["v0_kmh"] = table["v0_kmh"].astype(float)
        table.update({name: columns[name] for name in STOP_COLUMNS[2:]})
        # A campaign's own columns after the field campaign's (the rail campaign's, .rail).
        table.update({name: values for name, values in columns.items() if name not in STOP_COLUMNS})
        return pd.DataFrame(table)


def _describe(app: TrainApplication) -> tuple[str, str, str, str, float]:
    return app.brake_mode, app.load, app.pad_set, app.actuation, app.initial_speed_kmh


def _column_summary(column: str, values: np.ndarray) -> dict[str, object]:
    """Mean and std with their 95 % CIs of one quantity of one field application; a quantity that
    does not scatter (DS, or one repetition) has std 0 and its mean as interval."""
    if len(values) > 1 and np.std(values, ddof=1) > 0:
        st = sample_statistics(values)
        return {
            f"{column}_mean": st.mean,
            f"{column}_std": st.std,
            f"{column}_mean_ci95": st.mean_ci95,
            f"{column}_std_ci95": st.std_ci95,
        }
    mean = float(np.mean(values))
    return {
        f"{column}_mean": mean,
        f"{column}_std": 0.0,
        f"{column}_mean_ci95": (mean, mean),
        f"{column}_std_ci95": (0.0, 0.0),
    }


def _by_application(chunks: Iterator[dict[str, np.ndarray]]) -> Iterator[tuple[int, dict[str, np.ndarray]]]:
    """The rows of each field application, joined from the chunks that hold them (an
    application's stops are consecutive): one application's rows in memory at a time."""
    current, pieces = -1, []
    for columns in chunks:
        application = columns["field_application"]
        starts = np.flatnonzero(np.r_[True, application[1:] != application[:-1]])
        for start, end in zip(starts, [*starts[1:], len(application)]):
            if application[start] != current and pieces:
                yield current, {name: np.concatenate([p[name] for p in pieces]) for name in pieces[0]}
                pieces = []
            current = int(application[start])
            pieces.append({name: values[start:end] for name, values in columns.items()})
    if pieces:
        yield current, {name: np.concatenate([p[name] for p in pieces]) for name in pieces[0]}


def field_campaign(
    campaign: cfg.FieldCampaign,
    setup: cfg.ScatterSetup,
    seed: int,
    step_s: float = DEFAULT_STEP_S,
    executor: Executor | None = None,
    progress: Progress | None = None,
    chunk_size: int = DEFAULT_CHUNK_STOPS,
    out: str | Path | None = None,
    resume: bool = False,
) -> FieldCampaignResult:
    """Every field application of the campaign, simulated ``repetitions`` times, in chunks of
    ``chunk_size`` stops on ``executor`` (default: this process). With ``out``, each chunk's
    stops go to a Parquet file in that folder as it finishes (:mod:`.store`), and ``resume``
    continues a campaign interrupted there; the result then reads its rows from the folder."""
    vehicle = cfg.load("vehicles", campaign.vehicle)
    applications = field_applications(campaign)
    task = FieldChunkTask(vehicle, tuple(applications), campaign.repetitions, setup, seed, step_s)
    chunks = even_chunks(len(applications) * campaign.repetitions, chunk_size)
    store = None
    if out is not None:
        manifest = field_manifest(campaign, vehicle, setup, seed, step_s, chunk_size, len(chunks))
        store = CampaignStore.open(out, manifest, resume)
    elif resume:
        raise ValueError("resume needs the folder of the campaign to resume (out)")
    rows = run_chunks(task, chunks, executor, store, progress)
    return FieldCampaignResult(setup.name, seed, step_s, applications, campaign.repetitions, rows)


def field_manifest(
    campaign: cfg.FieldCampaign,
    vehicle: cfg.Vehicle,
    setup: cfg.ScatterSetup,
    seed: int,
    step_s: float,
    chunk_size: int,
    n_chunks: int,
) -> dict[str, object]:
    """What decides a field campaign's rows (:mod:`.store`): every config it reads, the seed, the
    step, the chunks, the versions."""
    configs = {
        "campaign": campaign.model_dump(mode="json"),
        "setup": setup.model_dump(mode="json"),
        "vehicle": vehicle.model_dump(mode="json"),
        "material": cfg.load("materials", vehicle.material).model_dump(mode="json"),
        "disc": cfg.load("discs", vehicle.disc).model_dump(mode="json"),
        "pneumatics": {
            str(name): cfg.load("pneumatics", str(name)).model_dump(mode="json")
            for name in campaign.factors["actuation"]
        },
    }
    return {
        "campaign": "field",
        "configs": configs,
        "seed": seed,
        "step_s": step_s,
        "chunk_size": chunk_size,
        "chunks": n_chunks,
        "stops": len(field_applications(campaign)) * campaign.repetitions,
        "tables": {STOPS: list(STOP_COLUMNS)},
        "versions": versions(),
    }


@dataclass(frozen=True)
class _TrainChunk:
    """Stops ``sample_index`` of a list of applications, with their applications."""

    sample_index: np.ndarray
    applications: tuple[TrainApplication, ...]

    def __str__(self) -> str:
        return f"stops {self.sample_index[0]} to {self.sample_index[-1]}"


@dataclass(frozen=True)
class _TrainStopsTask:
    vehicle: cfg.Vehicle
    setup: cfg.ScatterSetup
    seed: int
    step_s: float

    def __call__(self, chunk: _TrainChunk) -> StopSummary:
        summary, _, _ = scattered_train_stops(
            self.vehicle, chunk.applications, self.setup, self.seed, chunk.sample_index, self.step_s
        )
        return summary


def train_monte_carlo(
    vehicle: cfg.Vehicle,
    applications: Sequence[TrainApplication],
    setup: cfg.ScatterSetup,
    seed: int,
    step_s: float = DEFAULT_STEP_S,
    executor: Executor | None = None,
    progress: Progress | None = None,
    chunk_size: int = DEFAULT_CHUNK_STOPS,
) -> tuple[StopSummary, FrictionDraw, np.ndarray]:
    """Stops of ``vehicle`` for a list of applications with the set-up's scatter, stop ``i`` with
    sample ``i``'s draws of the seed, in chunks of ``chunk_size`` on ``executor`` (default: this
    process). Returns the summary (in the order of ``applications``), the friction draw and the
    running resistance; the same bit for bit whatever the executor and the chunk size."""
    n = len(applications)
    if n == 0:
        raise ValueError("train_monte_carlo: no applications to simulate")
    task = _TrainStopsTask(vehicle, setup, seed, step_s)
    chunks = [
        _TrainChunk(chunk.sample_index(), tuple(applications[chunk.start : chunk.stop]))
        for chunk in even_chunks(n, chunk_size)
    ]
    parts = list((executor or InlineExecutor()).map(task, chunks, [len(c.applications) for c in chunks], progress))
    merged = {
        name: np.concatenate([getattr(part, name) for part in parts])
        for name in StopSummary.__dataclass_fields__
        # Left at their defaults: no trajectories in a campaign, no slip work without adhesion.
        if name != "trajectory" and getattr(parts[0], name) is not None
    }
    draw, resistance = train_scatter(vehicle, setup).draw_for_samples(seed, np.arange(n))
    return StopSummary(**merged), draw, resistance
