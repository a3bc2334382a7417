"""Noise models of the measured channels, and where the residuals of a replay exceed them.

Noise: each channel's AR(1) noise model (:mod:`.noise`), its level the noise sigma the fit's
residuals are divided by. Only the moving part of a recording is used for speed and deceleration
(the step at standstill is not noise).

Attribution: the residual deceleration (minus the time derivative of the speed residual, so that
an accelerometer blind to a slope cannot hide it) and the disc-temperature residual are binned
along each axis of the state (position, speed, time since brake onset, dissipated energy, disc
temperature, cylinder pressure); the share of their variance the bin means explain (the
correlation ratio eta^2) says along which axis a mismatch lives. On clean data it stays near
(bins - 1) / samples, below 0.01 for a set of a few thousand samples.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter

from ..recordings.columns import DECEL, DISC_TEMPERATURE, SPEED
from ..recordings.format import Recording
from ..recordings.replay import STANDSTILL_SPEED_MPS, Replay, bridged_pressures_bar, standstill_index
from .noise import ChannelNoise, channel_samples, pooled_channel_noise

NOISE_CHANNELS = (SPEED, DECEL, DISC_TEMPERATURE)
SMOOTH_WINDOW = 11  # samples of the smooth that differentiates the speed residual
ATTRIBUTION_BINS = 10
BRAKING_PRESSURE_BAR = 0.3  # mean cylinder pressure above which a sample counts as braking
SEGMENT_THRESHOLD = 3.0  # smoothed |residual| over noise that marks a segment
SEGMENT_SMOOTH_S = 1.0
SEGMENT_MIN_S = 1.0
AXES = (
    ("position_m", "position"),
    ("speed_mps", "speed"),
    ("time_since_brake_onset_s", "time since brake onset"),
    ("dissipated_energy_MJ", "dissipated energy per disc"),
    ("disc_temperature_C", "disc temperature"),
    ("pressure_bar", "cylinder pressure"),
)


def _moving(recording: Recording) -> np.ndarray:
    stop = standstill_index(recording.speed_mps, STANDSTILL_SPEED_MPS)
    mask = np.ones(len(recording), dtype=bool)
    if stop is not None:
        mask[max(stop - 5, 0) :] = False
    return mask


def estimate_noise_models(recordings: Sequence[Recording], window_s: Mapping[str, float]) -> dict[str, ChannelNoise]:
    """The AR(1) noise model of speed, deceleration and disc temperature
    (:func:`.noise.pooled_channel_noise`, one per channel over all recordings, its smooth spanning
    ``window_s[channel]`` seconds; speed and deceleration while moving); channels no recording has
    are left out."""
    out = {}
    for channel in NOISE_CHANNELS:
        series = []
        for recording in recordings:
            values = recording.channel(channel)
            if values is None:
                continue
            if channel in (SPEED, DECEL):
                values = np.where(_moving(recording), values, np.nan)
            series.append((recording.time_s, values))
        if series:
            out[channel] = pooled_channel_noise(series, window_s[channel])
    return out


def brake_onset_s(recording: Recording) -> float:
    """First instant the mean cylinder pressure (linear between its samples) exceeds
    ``BRAKING_PRESSURE_BAR`` (recording clock)."""
    pressure = np.mean(bridged_pressures_bar(recording), axis=1)
    above = np.flatnonzero(pressure > BRAKING_PRESSURE_BAR)
    return float(recording.time_s[above[0]]) if above.size else float(recording.time_s[0])


@dataclass
class ResidualTrace:
    """One recording's residuals against a replay, and the state axes at its samples."""

    recording: Recording
    time_s: np.ndarray
    speed: np.ndarray  # measured - simulated, nan where missing
    decel: np.ndarray | None  # of the decel channel
    kinematic_decel: np.ndarray  # -d/dt of the speed residual
    measured_decel: np.ndarray  # -d/dt of the measured speed: the deceleration the speed signal shows
    temperature: np.ndarray | None
    axes: dict[str, np.ndarray]
    moving: np.ndarray
    braking: np.ndarray


def _kinematic_decel(time_s: np.ndarray, speed_residual: np.ndarray) -> np.ndarray:
    """Minus the time derivative of the speed residual, taken on the speed channel's own samples
    (a channel logged at its own rate is blank between them; a dropout of a few samples counts as
    one interval there) and interpolated to every instant of the recording."""
    sample_time, own = channel_samples(time_s, speed_residual)
    step = float(np.median(np.diff(sample_time)))
    derivative = -savgol_filter(own, SMOOTH_WINDOW, 2, deriv=1, delta=step)
    return np.interp(time_s, sample_time, derivative)


def residual_trace(replayed: Replay) -> ResidualTrace:
    recording = replayed.recording
    sim = replayed.simulated
    time = recording.time_s
    speed = recording.speed_mps - sim[SPEED].to_numpy()
    kinematic = _kinematic_decel(time, speed)
    decel = temperature = None
    if DECEL in sim.columns and recording.channel(DECEL) is not None:
        decel = recording.channel(DECEL) - sim[DECEL].to_numpy()
    if DISC_TEMPERATURE in sim.columns and recording.channel(DISC_TEMPERATURE) is not None:
        temperature = recording.channel(DISC_TEMPERATURE) - sim[DISC_TEMPERATURE].to_numpy()
    states = replayed.states
    # The cylinder pressure as the replay sees it: linear between its samples (it is the
    # replay's input), so instants without a pressure sample keep their axis value.
    pressure = np.mean(bridged_pressures_bar(recording), axis=1)
    axes = {
        # Along the line, where the recording is placed on it (an effect on part of the line is
        # located there, the same place for every recording).
        "position_m": recording.metadata.on_line_m(states["true_position_m"].to_numpy()),
        "speed_mps": states["true_speed_mps"].to_numpy(),
        "time_since_brake_onset_s": time - brake_onset_s(recording),
        "dissipated_energy_MJ": states["friction_heat_MJ_per_disc"].to_numpy(),
        "disc_temperature_C": states["T_fric_C"].to_numpy() if "T_fric_C" in states else np.full(len(time), np.nan),
        "pressure_bar": pressure,
    }
    moving = _moving(recording)
    return ResidualTrace(
        recording,
        time,
        speed,
        decel,
        kinematic,
        _kinematic_decel(time, recording.speed_mps),
        temperature,
        axes,
        moving,
        moving & (pressure > BRAKING_PRESSURE_BAR),
    )


def correlation_ratio(axis: np.ndarray, residual: np.ndarray, bins: int = ATTRIBUTION_BINS) -> float:
    """Share of the variance of ``residual`` explained by its means in quantile bins of ``axis``."""
    use = ~np.isnan(axis) & ~np.isnan(residual)
    x, y = axis[use], residual[use]
    if len(y) < 4 * bins or np.var(y) == 0 or np.ptp(x) == 0:
        return 0.0
    edges = np.unique(np.quantile(x, np.linspace(0, 1, bins + 1)))
    index = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
    means = np.bincount(index, weights=y) / np.maximum(np.bincount(index), 1)
    # Against zero, not the mean: an offset along every axis is a mismatch too.
    total = np.mean(y**2)
    explained = np.mean(means[index] ** 2)
    return float(min(explained / total, 1.0))


def attribution(traces: Sequence[ResidualTrace]) -> dict[str, dict[str, float]]:
    """eta^2 of the residual deceleration (while braking) and of the temperature residual (while
    moving), per axis, pooled over the recordings."""
    out: dict[str, dict[str, float]] = {}
    pooled = {
        "decel": [(t.axes, t.kinematic_decel, t.braking) for t in traces],
        "T_disc": [(t.axes, t.temperature, t.moving) for t in traces if t.temperature is not None],
    }
    for name, parts in pooled.items():
        if not parts:
            continue
        out[name] = {}
        for axis, _ in AXES:
            x = np.concatenate([axes[axis][mask] for axes, _, mask in parts])
            y = np.concatenate([values[mask] for _, values, mask in parts])
            out[name][axis] = round(correlation_ratio(x, y), 4)
    return out


def _channel_segments(
    trace: ResidualTrace, channel: str, values: np.ndarray, mask: np.ndarray, sigma: float
) -> list[dict]:
    """The segments of one channel of one recording, on the channel's own samples (a channel
    logged at its own rate is blank between them; smoothing over blanks would dilute it)."""
    rows = np.flatnonzero(~np.isnan(values))
    if rows.size < 2:
        return []
    time, own = trace.time_s[rows], values[rows]
    width = max(int(round(SEGMENT_SMOOTH_S / float(np.median(np.diff(time))))), 1)
    smooth = np.convolve(own, np.ones(width) / width, mode="same")
    over = (np.abs(smooth) > SEGMENT_THRESHOLD * sigma) & mask[rows]
    edges = np.flatnonzero(np.diff(np.concatenate([[0], over.astype(int), [0]])))
    found = []
    for start, end in zip(edges[::2], edges[1::2]):
        if time[end - 1] - time[start] < SEGMENT_MIN_S:
            continue
        part = own[start:end]
        first, last = rows[start], rows[end - 1] + 1
        speed = trace.axes["speed_mps"][first:last]
        position = trace.axes["position_m"][first:last]
        found.append(
            {
                "recording": trace.recording.stem,
                "channel": channel,
                "t_s": [round(float(time[start]), 2), round(float(time[end - 1]), 2)],
                "speed_mps": [round(float(np.nanmin(speed)), 2), round(float(np.nanmax(speed)), 2)],
                "position_m": [round(float(np.nanmin(position)), 1), round(float(np.nanmax(position)), 1)],
                "rms": round(float(np.sqrt(np.mean(part**2))), 4),
                "_weight": float(np.sum(part**2)) / sigma**2,
            }
        )
    return found


def segments(traces: Sequence[ResidualTrace], noise: dict[str, float], limit: int = 20) -> list[dict]:
    """Stretches of at least ``SEGMENT_MIN_S`` where a channel's residual, smoothed over
    ``SEGMENT_SMOOTH_S``, exceeds ``SEGMENT_THRESHOLD`` times its noise."""
    found = []
    for trace in traces:
        for channel, values, mask in (
            (SPEED, trace.speed, trace.moving),
            (DECEL, trace.decel, trace.moving),
            (DISC_TEMPERATURE, trace.temperature, np.ones_like(trace.moving)),
        ):
            if values is not None and np.isfinite(noise.get(channel, np.nan)):
                found += _channel_segments(trace, channel, values, mask, noise[channel])
    found.sort(key=lambda s: -s["_weight"])
    for segment in found:
        del segment["_weight"]
    return found[:limit]


def describe_unexplained(traces: Sequence[ResidualTrace], shares: dict[str, dict[str, float]]) -> dict | None:
    """The residual deceleration as a simple function of its best axis: constant, linear and
    quadratic least squares; the share of its mean square each one removes."""
    if "decel" not in shares:
        return None
    axis = max(shares["decel"], key=lambda a: shares["decel"][a])
    x = np.concatenate([t.axes[axis][t.braking] for t in traces])
    y = np.concatenate([t.kinematic_decel[t.braking] for t in traces])
    use = ~np.isnan(x) & ~np.isnan(y)
    x, y = x[use], y[use]
    if len(y) < 10:
        return None
    total = float(np.mean(y**2))
    fits = {}
    centred = (x - x.mean()) / (x.std() or 1.0)
    for name, degree in (("constant", 0), ("linear", 1), ("quadratic", 2)):
        design = np.vander(centred, degree + 1)
        coefficients, *_ = np.linalg.lstsq(design, y, rcond=None)
        fits[name] = (1.0 - float(np.mean((y - design @ coefficients) ** 2)) / total, coefficients)
    # The simplest form within 0.02 of the best share.
    best_share = max(share for share, _ in fits.values())
    form = next(name for name in ("constant", "linear", "quadratic") if fits[name][0] >= best_share - 0.02)
    raw = np.polyfit(x, y, {"constant": 0, "linear": 1, "quadratic": 2}[form])
    label = dict(AXES)[axis]
    terms = (
        " + ".join(f"{c:.3g} x^{len(raw) - 1 - k}" for k, c in enumerate(raw)).replace(" x^0", "").replace("x^1", "x")
    )
    return {
        "axis": axis,
        "eta2": shares["decel"][axis],
        "form": form,
        "coefficients": [float(c) for c in raw],
        "explained_share": round(fits[form][0], 3),
        "text": (
            f"The residual deceleration (measured minus simulated, from the speed signal) lives along {label} "
            f"(eta^2 = {shares['decel'][axis]:.2f}) and follows a {form} function of it, "
            f"residual decel [m/s^2] = {terms} with x the {label} [{axis.rsplit('_', 1)[-1]}]; "
            f"that description removes {100 * fits[form][0]:.0f} % of its mean square."
        ),
    }
