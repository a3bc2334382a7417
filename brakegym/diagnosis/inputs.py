"""What the diagnosis takes from each recording where the recording does not state it, and what it
reports of each recording's measurement chain as the data show it.

- **Initial disc temperature.** ``initial_disc_C`` of the metadata, else the ``T_disc_C`` sample on
  the first line (the format's rule). A logger whose thermometer starts late has neither: then the
  first ``T_disc_C`` sample, when it comes before the brake onset (a disc cools by a fraction of a
  kelvin per second while coasting, well inside the fit's nuisance bounds), else the ambient
  temperature. Either way it is only the start of the fitted nuisance, and the report says which
  recordings had it estimated and from what.
- **Pressure-transducer zero offsets.** The replay takes a transducer's reading for cylinder
  pressure; a zero offset would be a clamp force of gain x offset through the whole stop (and heat
  into the instrumented disc's axle). Each transducer's reading before the brake onset (its median,
  :func:`.noise.zero_reading`) is its offset when few of those readings are saturated at 0
  (:class:`PressureZero`), and is subtracted from its samples before the replay
  (:func:`zero_corrected`). A transducer saturates at 0 bar, so a negative offset reads 0 before
  the brake like no offset at all: it cannot be identified from the data, nothing is subtracted,
  and the report lists the transducer.
- **The chain as seen.** Per channel: how many samples, the median interval and its spread (mixed
  and uneven rates), the blank cells inside the channel's own sampling (dropouts), the quantisation
  step the values lie on; per pressure transducer its zero reading and the offset removed, and for
  an accelerometer the reading at standstill (its bias less g x gradient; not corrected). Reported
  under ``measurement_chain`` in the diagnosis report.
- **Line position.** Effects on part of the line (a gradient section, a stretch of low adhesion)
  are located in metres along the line. Where every recording carries ``line_position_m`` (its
  first sample's place on the line), positions count from the set's line origin, the lowest
  line position they reach (:func:`on_set_line`), so that a stretch's bounds hold whatever the line's chainage; where
  none does, from each recording's own first sample (the recordings then start at one place). A
  set where some carry it and some do not is refused.
- **Accelerometer bias.** A bias is a constant on every sample of a recording, which no sample
  noise model holds. Its scatter between recordings, from the standstill readings
  (:func:`accelerometer_bias_sigma`), is drawn afresh for each recording in the parametric
  bootstrap (:mod:`.bootstrap`), so the intervals carry what a bias moves.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..recordings.columns import DECEL, DISC_TEMPERATURE, POSITION, SPEED
from ..recordings.format import Recording
from ..recordings.metadata import RecordingMetadata
from ..recordings.replay import measured_distance_m, standstill_index
from .locate import brake_onset_s
from .noise import ChannelNoise, channel_samples, quantisation_step, zero_reading

CHAIN_CHANNELS = (SPEED, DECEL, DISC_TEMPERATURE, POSITION)
# After the measured stop the deceleration steps to zero within a sample or two of the speed
# channel; readings from this long after it are standstill.
STANDSTILL_SETTLING_S = 0.5
# A zero offset is read from at least this many samples before the brake onset, fewer than this
# share of them saturated at 0 bar (see PressureZero).
MIN_ZERO_SAMPLES = 10
# Recordings with a standstill reading needed to estimate the accelerometer bias's scatter.
MIN_BIAS_READINGS = 3
MAX_SATURATED_SHARE = 0.25


@dataclass(frozen=True)
class InitialDiscTemperature:
    """A recording's initial disc temperature (degC) and where it comes from: ``given`` (metadata
    or the first line), ``first_sample`` (the first T_disc_C sample before brake onset, at
    ``sample_time_s``) or ``ambient``."""

    value_C: float
    source: str
    sample_time_s: float | None = None

    def describe(self) -> str:
        if self.source == "first_sample":
            return f"first T_disc_C sample, at t = {self.sample_time_s:g} s (before the brake onset)"
        if self.source == "ambient":
            return "ambient temperature (no T_disc_C sample before the brake onset)"
        return "given"


def initial_disc_temperature(recording: Recording) -> InitialDiscTemperature:
    """See the module documentation."""
    given = recording.initial_disc_C
    if given is not None:
        return InitialDiscTemperature(given, "given")
    temperature = recording.channel(DISC_TEMPERATURE)
    if temperature is not None:
        present = np.flatnonzero(~np.isnan(temperature))
        if present.size and recording.time_s[present[0]] < brake_onset_s(recording):
            first = int(present[0])
            return InitialDiscTemperature(float(temperature[first]), "first_sample", float(recording.time_s[first]))
    return InitialDiscTemperature(recording.metadata.ambient_C, "ambient")


@dataclass(frozen=True)
class PressureZero:
    """A pressure transducer's zero reading: the median of its samples before the brake onset
    (bar; None without any), how many, and the share of them that read 0 bar or below (saturated).

    A transducer's output saturates at 0 bar: with a negative zero offset it reads 0 before the
    brake, as it does with none, so a reading at 0 says only that the offset is at most 0. With
    fewer than ``MAX_SATURATED_SHARE`` of the samples saturated the median lies among the
    unsaturated readings and estimates the offset; that needs an offset above 0.67 noise sigma
    (smaller ones, under 0.015 bar for a 0.02 bar noise, are left in)."""

    reading_bar: float | None
    samples: int
    saturated_share: float

    @property
    def identifiable(self) -> bool:
        """Whether the reading estimates the zero offset (see the class documentation)."""
        return (
            self.reading_bar is not None
            and self.samples >= MIN_ZERO_SAMPLES
            and self.saturated_share < MAX_SATURATED_SHARE
            and self.reading_bar > 0.0
        )

    @property
    def offset_bar(self) -> float:
        """The offset (bar) removed from the replay's input, the reading where identifiable, else 0."""
        return float(self.reading_bar) if self.identifiable else 0.0


def pressure_zeros(recording: Recording) -> dict[str, PressureZero]:
    """Each pressure transducer's :class:`PressureZero`, from its samples before the brake onset."""
    before = recording.time_s < brake_onset_s(recording)
    out = {}
    for column in recording.pressure_columns:
        values = recording.channel(column)[before]
        values = values[~np.isnan(values)]
        reading = zero_reading(values)
        if reading is None:
            out[column] = PressureZero(None, 0, float("nan"))
        else:
            out[column] = PressureZero(reading["median"], reading["samples"], float(np.mean(values <= 0.0)))
    return out


def zero_corrected(recording: Recording) -> Recording:
    """The recording with each transducer's identifiable zero offset subtracted from its pressures
    (held at 0 bar below it: a cylinder pressure is not negative, and below the clamp threshold
    a reading gives no force either way). The replay takes a transducer's zero offset for cylinder
    pressure, a clamp force of gain x offset on every sample of the stop."""
    zeros = pressure_zeros(recording)
    offsets = {column: zero.offset_bar for column, zero in zeros.items() if zero.offset_bar > 0}
    if not offsets:
        return recording
    data = recording.data.copy()
    for column, offset in offsets.items():
        data[column] = np.maximum(data[column].to_numpy(dtype=float) - offset, 0.0)
    return dataclasses.replace(recording, data=data)


def _accelerometer_standing(recording: Recording) -> np.ndarray | None:
    """An accelerometer's samples at standstill, after the stop's own transient; None without an
    accelerometer or a stop."""
    decel = recording.channel(DECEL)
    stop = standstill_index(recording.speed_mps)
    if decel is None or recording.metadata.decel_source != "accelerometer" or stop is None:
        return None
    return decel[recording.time_s > recording.time_s[stop] + STANDSTILL_SETTLING_S]


def accelerometer_at_standstill(recording: Recording) -> dict[str, float | int] | None:
    """An accelerometer's reading at standstill, after the stop's own transient (median and
    samples, :func:`.noise.zero_reading`): its bias less g x the gradient where the train stands,
    the two being one number. None without an accelerometer, a stop, or a sample after it."""
    standing = _accelerometer_standing(recording)
    return None if standing is None else zero_reading(standing)


def accelerometer_bias_sigma(recordings: Sequence[Recording], noise: ChannelNoise | None) -> float:
    """The scatter of the accelerometer's bias between recordings (m/s^2) as the data show it: the
    spread (ddof 1) of the recordings' standstill readings, less what the channel's noise explains
    of it (each reading a median of AR(1) samples: variance sigma^2 (1 + rho) / (1 - rho) / samples
    x pi / 2), 0 where nothing is left or fewer than ``MIN_BIAS_READINGS`` recordings have a
    reading. On one line each reading is the bias less g x the gradient where the train stood:
    stops on different gradients make it an upper bound, so the intervals it widens err wide."""
    readings = [r for r in (accelerometer_at_standstill(recording) for recording in recordings) if r is not None]
    if len(readings) < MIN_BIAS_READINGS or noise is None or not np.isfinite(noise.sigma):
        return 0.0
    rho = float(np.clip(noise.rho, 0.0, 0.99)) if np.isfinite(noise.rho) else 0.0
    per_sample = noise.sigma**2 * (1.0 + rho) / (1.0 - rho) * math.pi / 2.0
    reading_variance = float(np.mean([per_sample / r["samples"] for r in readings]))
    spread = float(np.var([r["median"] for r in readings], ddof=1))
    return math.sqrt(max(spread - reading_variance, 0.0))


def _channel_description(recording: Recording, channel: str) -> dict[str, Any] | None:
    values = recording.channel(channel)
    if values is None:
        return None
    time, own = channel_samples(recording.time_s, values)
    present = ~np.isnan(own)
    intervals = np.diff(time[present])
    # Blank cells of the channel's own sampling: rows within its span whose interval to the next
    # present sample is more than 1.5 of its typical interval count the samples missing there.
    typical = float(np.median(intervals)) if intervals.size else float("nan")
    missing = int(np.sum(np.maximum(np.round(intervals / typical) - 1, 0))) if intervals.size else 0
    return {
        "samples": int(present.sum()),
        "median_interval_s": round(typical, 4),
        "interval_spread_s": round(float(np.std(intervals)), 4) if intervals.size else None,
        "first_sample_s": round(float(time[present][0] - recording.time_s[0]), 3) if present.any() else None,
        "missing_samples": missing,
        "quantisation_step": quantisation_step(own[present]),
    }


def chain_report(recordings: Sequence[Recording]) -> dict[str, Any]:
    """The ``measurement_chain`` entry of the report: per recording, each channel's sampling as the
    data show it, the pressure zero readings and the offsets removed, the accelerometer's reading
    at standstill, and the initial disc temperature where it was not given; the transducers whose
    zero offset cannot be identified."""
    out: dict[str, Any] = {
        "recordings": {},
        "initial_disc_C_estimated": {},
        "pressure_zero_offset_not_identifiable": {},
    }
    for recording in recordings:
        channels = {c: d for c in CHAIN_CHANNELS if (d := _channel_description(recording, c)) is not None}
        zeros = pressure_zeros(recording)
        entry: dict[str, Any] = {
            "channels": channels,
            "pressure_before_brake_onset_bar": {
                column: None if zero.reading_bar is None else {"median": zero.reading_bar, "samples": zero.samples}
                for column, zero in zeros.items()
            },
            "pressure_zero_offset_removed_bar": {column: zero.offset_bar for column, zero in zeros.items()},
        }
        unidentified = [column for column, zero in zeros.items() if not zero.identifiable]
        if unidentified:
            out["pressure_zero_offset_not_identifiable"][recording.stem] = unidentified
        standing = _accelerometer_standing(recording)
        if standing is not None:
            entry["accelerometer_at_standstill_mps2"] = zero_reading(standing)
        out["recordings"][recording.stem] = entry
        initial = initial_disc_temperature(recording)
        if initial.source != "given":
            out["initial_disc_C_estimated"][recording.stem] = {
                "start_C": initial.value_C,
                "from": initial.describe(),
            }
    if out["pressure_zero_offset_not_identifiable"]:
        out["pressure_zero_offset_note"] = (
            "these transducers read 0 bar on at least a quarter of their samples before the brake (or have "
            "fewer than 10 there): a negative zero offset saturates at 0 like no offset at all (or one below about "
            "0.7 noise sigma), so it cannot be identified and their readings are replayed as they are"
        )
    return out


def on_set_line(recordings: Sequence[Recording]) -> tuple[list[Recording], float | None]:
    """The recordings with each ``line_position_m`` counted from the set's line origin, and that
    origin, m: the lowest line position any of them reaches (a recording run towards falling
    positions reaches below its first sample's by the distance it covers). Unchanged with None
    where no recording carries one. ValueError naming the recordings where only some carry it:
    the others could not be placed on the line."""
    placed = [r.metadata.line_position_m is not None for r in recordings]
    if not any(placed):
        return list(recordings), None
    if not all(placed):
        missing = [r.name for r, p in zip(recordings, placed, strict=True) if not p]
        raise ValueError(
            f"metadata field 'line_position_m' is given for {sum(placed)} of {len(placed)} recordings but not for "
            f"{', '.join(missing)}: give it for all of a set's recordings (they are placed on one line) or for none"
        )
    origin = min(_line_span_m(r)[0] for r in recordings)
    rebased = [
        dataclasses.replace(r, metadata=r.metadata.model_copy(update=_counted_from(r.metadata, origin)))
        for r in recordings
    ]
    return rebased, origin


def _counted_from(metadata: RecordingMetadata, origin_m: float) -> dict[str, Any]:
    """The metadata fields in line positions, counted from ``origin_m``: the first sample's place
    and the known line profile's section starts (each run then meets the same sections)."""
    fields: dict[str, Any] = {"line_position_m": metadata.line_position_m - origin_m}
    profile = metadata.line_gradient_profile
    if profile is not None:
        fields["line_gradient_profile"] = profile.model_copy(
            update={"start_m": [start - origin_m for start in profile.start_m]}
        )
    return fields


def line_reach_m(recordings: Sequence[Recording]) -> float | None:
    """How far along the line the recordings reach: the highest line position any of them
    reaches (its first sample's, or that plus the distance it covers where it runs towards growing
    positions), in the recordings' own line positions (from the origin after
    :func:`on_set_line`). None where they are not placed on the line."""
    if not recordings or any(r.metadata.line_position_m is None for r in recordings):
        return None
    return max(_line_span_m(r)[1] for r in recordings)


def beyond_the_search_note(reach_m: float | None, search_start_max_m: float) -> str | None:
    """A sentence for the report where the recordings reach further along the line than the
    located effects' starts are searched (None where they do not): an effect that begins beyond
    ``search_start_max_m`` is not found, and the report must not read as if the whole line had
    been searched."""
    if reach_m is None or reach_m <= search_start_max_m:
        return None
    return (
        f"The recordings reach {reach_m:.0f} m along the line from its origin, but a section of gradient or a "
        f"stretch of low adhesion is searched with its start in 0-{search_start_max_m:g} m from the origin: one "
        "that begins further along is not found (diagnose the recordings of that part of the line on their own)."
    )


def _line_span_m(recording: Recording) -> tuple[float, float]:
    """The lowest and highest line positions a placed recording reaches: its first sample's, and
    that plus or minus the distance it covers, as it runs towards growing or falling positions."""
    start = float(recording.metadata.line_position_m)  # type: ignore[arg-type]
    end = start + recording.metadata.line_direction_sign * float(np.nanmax(measured_distance_m(recording)))
    return min(start, end), max(start, end)
