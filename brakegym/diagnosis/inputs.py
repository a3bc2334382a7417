"""What the diagnosis takes from each recording where the recording does not state it, and what it
reports of each recording's measurement chain as the data show it.

- **Initial disc temperature.** ``initial_disc_C`` of the metadata, else the ``T_disc_C`` sample on
  the first line (the format's rule). A logger whose thermometer starts late has neither: then the
  first ``T_disc_C`` sample, when it comes before the brake onset (a disc cools by a fraction of a
  kelvin per second while coasting, well inside the fit's nuisance bounds), else the ambient
  temperature. Either way it is only the start of the fitted nuisance, and the report says which
  recordings had it estimated and from what.
- **The chain as seen.** Per channel: how many samples, the median interval and its spread (mixed
  and uneven rates), the blank cells inside the channel's own sampling (dropouts), the quantisation
  step the values lie on; per pressure transducer and for an accelerometer, the reading while
  nothing acts on it (a zero offset or bias, :func:`.noise.zero_reading`). Reported
  under ``measurement_chain`` in the diagnosis report; nothing is corrected from it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..recordings.columns import DECEL, DISC_TEMPERATURE, POSITION, SPEED
from ..recordings.format import Recording
from ..recordings.replay import standstill_index
from .locate import brake_onset_s
from .noise import channel_samples, quantisation_step, zero_reading

CHAIN_CHANNELS = (SPEED, DECEL, DISC_TEMPERATURE, POSITION)
# After the measured stop the deceleration steps to zero within a sample or two of the speed
# channel; readings from this long after it are standstill.
STANDSTILL_SETTLING_S = 0.5


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
    data show it, the pressure and accelerometer zero readings, and the initial disc temperature
    where it was not given."""
    out: dict[str, Any] = {"recordings": {}, "initial_disc_C_estimated": {}}
    for recording in recordings:
        channels = {c: d for c in CHAIN_CHANNELS if (d := _channel_description(recording, c)) is not None}
        onset = brake_onset_s(recording)
        before = recording.time_s < onset
        zeros = {column: zero_reading(recording.channel(column)[before]) for column in recording.pressure_columns}
        entry: dict[str, Any] = {"channels": channels, "pressure_before_brake_onset_bar": zeros}
        decel = recording.channel(DECEL)
        stop = standstill_index(recording.speed_mps)
        if decel is not None and recording.metadata.decel_source == "accelerometer" and stop is not None:
            # At standstill (after the stop's own transient) an accelerometer reads its bias less
            # g x gradient: the two are one number.
            standing = recording.time_s > recording.time_s[stop] + STANDSTILL_SETTLING_S
            entry["accelerometer_at_standstill_mps2"] = zero_reading(decel[standing])
        out["recordings"][recording.stem] = entry
        initial = initial_disc_temperature(recording)
        if initial.source != "given":
            out["initial_disc_C_estimated"][recording.stem] = {
                "start_C": initial.value_C,
                "from": initial.describe(),
            }
    return out
