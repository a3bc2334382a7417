"""Load cases an identification fits to, and how the model predicts them for many parameter
vectors at once.

A case set holds observed series (one channel of one case at its own sample instants) and
predicts every series for a matrix of parameter vectors (rows). Rows that differ only in the
per-application parameters (mu_0, a) run in one simulator batch, one copy of the cases per row;
rows with other plant parameters (b, c, ..., thermal) need a batch of their own, because the
simulator holds those constants per batch (``brakegym.simulator.Plant``).

- :class:`DynoCurves`: mean curves mu(t) and T_fric(t) of dynamometer load cases (paper Table 1),
  as the dyno campaign's envelopes give them (:func:`dyno_curves_from_campaign`) or read from a
  CSV (:func:`read_dyno_curves`).
- :class:`RecordingCases`: train recordings (``brakegym.recordings.read_dataset``), replayed
  from their own measured inputs; channels speed, deceleration and disc temperature.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np
import pandas as pd

from .. import config as cfg
from ..applications import dyno_stops
from ..defaults import DEFAULT_STEP_S
from ..physics import DiscThermalModel, FrictionDraw, FrictionLaw
from ..plants import dynamometer_plant, friction_law, thermal_model
from .parameters import ParameterSpace

# Dyno curve CSV columns (long format: one row per load case and sample instant).
CURVE_COLUMNS = ("load_case", "t_s", "mu", "T_fric_C")
DYNO_CHANNELS = ("mu", "T_fric_C")


@dataclass(frozen=True)
class Series:
    """One observed channel of one case: values at ``time_s`` (s from the case's start)."""

    case: str
    channel: str
    time_s: np.ndarray
    values: np.ndarray

    def __post_init__(self) -> None:
        if self.time_s.shape != self.values.shape or self.time_s.ndim != 1:
            raise ValueError(f"{self.case}/{self.channel}: time and values must be 1-D of equal length")
        if len(self.time_s) < 2:
            raise ValueError(f"{self.case}/{self.channel}: needs at least 2 samples, has {len(self.time_s)}")
        if not np.all(np.isfinite(self.values)) or not np.all(np.isfinite(self.time_s)):
            raise ValueError(f"{self.case}/{self.channel}: non-finite samples (drop missing ones before)")
        if np.any(np.diff(self.time_s) <= 0):
            raise ValueError(f"{self.case}/{self.channel}: time must be strictly increasing")


class CaseSet(Protocol):
    series: tuple[Series, ...]

    def predict(self, space: ParameterSpace, rows: np.ndarray) -> list[list[np.ndarray]]:
        """Predicted values of every series (in ``series`` order) for each parameter row."""
        ...

    def describe(self) -> str: ...


def plant_groups(space: ParameterSpace, rows: np.ndarray) -> list[list[int]]:
    """Row indices grouped by plant parameters, in first-seen order (deterministic)."""
    groups: dict[tuple[float, ...], list[int]] = {}
    for index, row in enumerate(rows):
        groups.setdefault(space.plant_key(row), []).append(index)
    return list(groups.values())


def _laws(space: ParameterSpace, row: np.ndarray) -> tuple[cfg.FrictionMaterial, FrictionLaw, DiscThermalModel]:
    material, disc = space.configs(row)
    return material, friction_law(material), thermal_model(disc)


# ------------------------------------------------------------------------------------------------
# Dynamometer mean curves


@dataclass(frozen=True)
class DynoCurves:
    """Mean curves of dynamometer load cases: ``mu`` and ``T_fric_C`` series per case.

    The model of a mean curve is the deterministic stop at the (mean) parameters: the mean of
    scattered stops differs from it only to second order in the scatter (sigma of mu_0 is 3 % of
    it; see the benchmark for the bias this leaves)."""

    rig: cfg.Dynamometer
    series: tuple[Series, ...]
    step_s: float = DEFAULT_STEP_S

    def __post_init__(self) -> None:
        for item in self.series:
            self.rig.load_case(item.case)  # raises on an unknown load case
            if item.channel not in DYNO_CHANNELS:
                raise ValueError(f"{item.case}: unknown dyno channel {item.channel!r}; channels are {DYNO_CHANNELS}")

    @property
    def case_names(self) -> list[str]:
        return list(dict.fromkeys(item.case for item in self.series))

    def describe(self) -> str:
        n = sum(len(s.time_s) for s in self.series)
        cases = len(self.case_names)
        return f"{cases} dynamometer load case(s) of rig {self.rig.name!r}, {len(self.series)} series, {n} samples"

    def predict(self, space: ParameterSpace, rows: np.ndarray) -> list[list[np.ndarray]]:
        cases = [self.rig.load_case(name) for name in self.case_names]
        until = max(float(item.time_s[-1]) for item in self.series) + self.step_s
        out: list[list[np.ndarray]] = [[] for _ in rows]
        base_plant = dynamometer_plant(self.rig)
        for group in plant_groups(space, rows):
            _, friction, thermal = _laws(space, rows[group[0]])
            plant = dataclasses.replace(base_plant, friction=friction, thermal=thermal)
            materials = [space.configs(rows[i])[0] for i in group]
            per_row = np.array([[m.initial_mu, m.power_coefficient_per_s] for m in materials])
            draw = FrictionDraw(
                initial_mu=np.repeat(per_row[:, 0], len(cases)).reshape(-1, 1, 1),
                power_coefficient_per_s=np.repeat(per_row[:, 1], len(cases)).reshape(-1, 1, 1),
            )
            summary = dyno_stops(
                self.rig, cases * len(group), draw, self.step_s, record_every=1, until_time_s=until, plant=plant
            )
            trajectory = summary.trajectory
            assert trajectory is not None
            channels = {"mu": trajectory.mu[:, :, 0], "T_fric_C": trajectory.friction_temperature_C[:, :, 0]}
            for k, row_index in enumerate(group):
                column = {name: k * len(cases) + j for j, name in enumerate(self.case_names)}
                out[row_index] = [
                    np.interp(item.time_s, trajectory.time_s, channels[item.channel][:, column[item.case]])
                    for item in self.series
                ]
        return out


def dyno_curves_from_campaign(
    result, rig: cfg.Dynamometer, load_cases: Sequence[str] | None = None, step_s: float = DEFAULT_STEP_S
) -> DynoCurves:
    """Mean curves of a :class:`~brakegym.campaigns.DynoCampaignResult`: the instants at which
    every application of the case still brakes (later the mean runs over a shrinking subset of
    the stops and is no longer the mean stop), from the first instant after t = 0."""
    names = list(load_cases) if load_cases is not None else list(result.envelopes)
    series = []
    for name in names:
        if name not in result.envelopes:
            raise ValueError(f"load case {name!r} is not in the campaign; it has {sorted(result.envelopes)}")
        frame = result.envelopes[name]
        total = int(frame["n_braking"].iloc[0])
        keep = (frame["n_braking"] == total) & (frame["t_s"] > 0)
        for channel in DYNO_CHANNELS:
            series.append(
                Series(
                    name, channel, frame["t_s"][keep].to_numpy(float), frame[f"{channel}_mean"][keep].to_numpy(float)
                )
            )
    return DynoCurves(rig, tuple(series), step_s)


def write_dyno_curves(curves: DynoCurves, path: str | Path) -> Path:
    """The curves as a long CSV: ``load_case, t_s, mu, T_fric_C`` (blank where not observed)."""
    frames = []
    for name in curves.case_names:
        by_channel = {s.channel: s for s in curves.series if s.case == name}
        times = np.unique(np.concatenate([s.time_s for s in by_channel.values()]))
        frame = pd.DataFrame({"load_case": name, "t_s": times})
        for channel in DYNO_CHANNELS:
            values = np.full(len(times), np.nan)
            if channel in by_channel:
                s = by_channel[channel]
                values[np.searchsorted(times, s.time_s)] = s.values
            frame[channel] = values
        frames.append(frame)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    pd.concat(frames).to_csv(path, index=False, float_format="%.10g")
    return path


def read_dyno_curves(path: str | Path, rig: cfg.Dynamometer, step_s: float = DEFAULT_STEP_S) -> DynoCurves:
    """Mean curves from a CSV with columns ``load_case, t_s, mu, T_fric_C`` (a blank cell is a
    missing sample; either value column may be absent). Refuses bad files naming line and
    column."""
    path = Path(path)
    try:
        frame = pd.read_csv(path, dtype={"load_case": str})
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise ValueError(f"{path}: cannot read dyno curves ({exc})") from None
    missing = [c for c in ("load_case", "t_s") if c not in frame.columns]
    if missing or not any(c in frame.columns for c in DYNO_CHANNELS):
        raise ValueError(
            f"{path}: needs columns load_case, t_s and at least one of {DYNO_CHANNELS}; has {list(frame.columns)}"
        )
    unknown = [c for c in frame.columns if c not in CURVE_COLUMNS]
    if unknown:
        raise ValueError(f"{path}: unknown column(s) {unknown}; columns are {CURVE_COLUMNS}")
    for column in ("t_s", *[c for c in DYNO_CHANNELS if c in frame.columns]):
        values = pd.to_numeric(frame[column], errors="coerce")
        bad = values.isna() & frame[column].notna()
        if column == "t_s":
            bad |= frame[column].isna()
        bad |= ~np.isfinite(values.fillna(0.0))
        if bad.any():
            row = int(np.flatnonzero(bad.to_numpy())[0])
            raise ValueError(
                f"{path}: line {row + 2}, column {column}: {frame[column].iloc[row]!r} is not a finite number"
            )
        frame[column] = values
    series = []
    for name, group in frame.groupby("load_case", sort=False):
        try:
            rig.load_case(str(name))
        except cfg.ConfigError as exc:
            raise ValueError(f"{path}: line {int(group.index[0]) + 2}: {exc}") from None
        time = group["t_s"].to_numpy(float)
        if np.any(np.diff(time) <= 0):
            row = int(group.index[1 + int(np.flatnonzero(np.diff(time) <= 0)[0])])
            raise ValueError(f"{path}: line {row + 2}: t_s of load case {name} must increase strictly")
        for channel in DYNO_CHANNELS:
            if channel in group:
                present = group[channel].notna().to_numpy()
                if present.sum() >= 2:
                    series.append(Series(str(name), channel, time[present], group[channel].to_numpy(float)[present]))
    if not series:
        raise ValueError(f"{path}: no series with at least two samples")
    return DynoCurves(rig, tuple(series), step_s)


# ------------------------------------------------------------------------------------------------
# Train recordings

RECORDING_CHANNELS = {"speed_mps": "speed_mps", "decel_mps2": "decel_mps2", "T_disc_C": "T_disc_C"}


class _MaterialOverride:
    """Sets the friction and thermal laws and each application's mu_0 and a in a replay: used as
    an effect of :func:`brakegym.recordings.replay.replay_batch` (its extension point for model
    changes), not part of the effect library."""

    id = "identification_parameters"
    order = -1  # before every library effect
    sensor = False

    def __init__(
        self,
        friction: FrictionLaw,
        thermal: DiscThermalModel,
        initial_mu: np.ndarray,
        power_coefficient_per_s: np.ndarray,
    ) -> None:
        self.friction, self.thermal = friction, thermal
        self.initial_mu, self.power_coefficient_per_s = initial_mu, power_coefficient_per_s

    def apply(self, model) -> None:
        model.plant = dataclasses.replace(model.plant, friction=self.friction, thermal=self.thermal)
        shape = np.shape(model.conditions.initial_mu)
        model.conditions = dataclasses.replace(
            model.conditions,
            initial_mu=np.broadcast_to(self.initial_mu[:, None, None], shape).copy(),
            power_coefficient_per_s=np.broadcast_to(self.power_coefficient_per_s[:, None, None], shape).copy(),
        )


@dataclass(frozen=True)
class RecordingCases:
    """Train recordings of one vehicle, replayed from their measured inputs (pressures, initial
    speed and disc temperature, load); fitted channels speed, deceleration, disc temperature
    where recorded. Time from each recording's first sample."""

    recordings: tuple
    series: tuple[Series, ...]

    def describe(self) -> str:
        n = sum(len(s.time_s) for s in self.series)
        return f"{len(self.recordings)} train recording(s), {len(self.series)} series, {n} samples"

    def predict(self, space: ParameterSpace, rows: np.ndarray) -> list[list[np.ndarray]]:
        from ..recordings.replay import replay_batch

        n = len(self.recordings)
        index = {r.name: b for b, r in enumerate(self.recordings)}
        out: list[list[np.ndarray]] = [[] for _ in rows]
        for group in plant_groups(space, rows):
            _, friction, thermal = _laws(space, rows[group[0]])
            materials = [space.configs(rows[i])[0] for i in group]
            override = _MaterialOverride(
                friction,
                thermal,
                np.repeat([m.initial_mu for m in materials], n),
                np.repeat([m.power_coefficient_per_s for m in materials], n),
            )
            replays = replay_batch(list(self.recordings) * len(group), [override])  # type: ignore[list-item]
            for k, row_index in enumerate(group):
                predicted = []
                for item in self.series:
                    replayed = replays[k * n + index[item.case]]
                    time = replayed.recording.time_s
                    values = replayed.simulated[RECORDING_CHANNELS[item.channel]].to_numpy(float)
                    predicted.append(np.interp(item.time_s, time - time[0], values))
                out[row_index] = predicted
        return out


def recording_cases(dataset, channels: Sequence[str] = tuple(RECORDING_CHANNELS)) -> RecordingCases:
    """The fit's view of a :class:`~brakegym.recordings.Dataset` (or list of recordings): every
    recorded sample of ``channels``; blank cells are missing samples, not zeros."""
    recordings = tuple(dataset)
    if not recordings:
        raise ValueError("no recordings to identify from")
    unknown = [c for c in channels if c not in RECORDING_CHANNELS]
    if unknown:
        raise ValueError(f"unknown recording channel(s) {unknown}; channels are {list(RECORDING_CHANNELS)}")
    vehicle = recordings[0].vehicle
    series = []
    for recording in recordings:
        if recording.vehicle != vehicle:
            raise ValueError(
                f"{recording.name}: vehicle differs from {recordings[0].name}'s; identify one vehicle at a time"
            )
        time = recording.time_s - recording.time_s[0]
        for channel in channels:
            values = recording.channel(channel)
            if values is None:
                continue
            present = ~np.isnan(values)
            if present.sum() >= 2:
                series.append(Series(recording.name, channel, time[present], values[present]))
    if not series:
        raise ValueError(f"the recordings hold none of the channels {list(channels)}")
    return RecordingCases(recordings, tuple(series))
