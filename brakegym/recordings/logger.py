"""What a data logger writes of a run through a :class:`~.chain.MeasurementChain`: each channel
sampled at its own, jittered instants, with its offset, white or AR(1) noise, quantisation and
dropouts, merged into one table on a common clock with blank cells where a channel has no sample.

The true values come from a callable (the synthetic truth), so the logger knows nothing of the
simulator. Every random draw of a channel comes from that channel's own generator, in a fixed
order (instants, offset, noise, dropouts): the same seeds write the same table bit for bit, and a
change to one channel's settings leaves the others' draws as they were.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from .chain import ChannelChain, MeasurementChain
from .columns import TIME

# Decimals the CSV keeps after quantising (the shortest text that reads back as the same value).
PRINT_DECIMALS = 6


def quantise(values: np.ndarray, resolution: float) -> np.ndarray:
    """``values`` snapped to multiples of ``resolution`` (0: unchanged), then print-rounded so the
    CSV holds short decimals; NaN stays NaN."""
    if resolution == 0:
        return np.round(values, PRINT_DECIMALS)
    return np.round(np.round(values / resolution) * resolution, PRINT_DECIMALS)


def ar1_noise(rng: np.random.Generator, shape: tuple[int, ...], sigma: float, rho: float) -> np.ndarray:
    """Stationary AR(1) noise along the first axis: x_k = rho x_(k-1) + sqrt(1 - rho^2) sigma e_k,
    x_0 ~ N(0, sigma^2); marginal standard deviation ``sigma``, lag-1 correlation ``rho``."""
    innovations = rng.standard_normal(shape)
    noise = np.empty(shape)
    noise[0] = sigma * innovations[0]
    gain = sigma * np.sqrt(1.0 - rho * rho)
    for k in range(1, shape[0]):
        noise[k] = rho * noise[k - 1] + gain * innovations[k]
    return noise


def dropout_mask(rng: np.random.Generator, n: int, probability: float, mean_samples: float) -> np.ndarray:
    """Which of ``n`` samples are blank: a dropout starts at each sample with ``probability`` and
    lasts a geometric number of samples of mean ``mean_samples`` (at least 1)."""
    starts = rng.random(n) < probability
    lengths = rng.geometric(1.0 / mean_samples, size=n)
    blank = np.zeros(n, dtype=bool)
    for start in np.flatnonzero(starts):
        blank[start : start + lengths[start]] = True
    return blank


def sample_ticks(rng: np.random.Generator, chain: ChannelChain, end_s: float, clock_s: float) -> np.ndarray:
    """A channel's sample instants up to ``end_s``, in clock ticks: start delay plus k intervals,
    each moved uniformly within +-jitter (the first not: it marks the channel's start)."""
    n = int(np.floor((end_s - chain.start_delay_s) / chain.interval_s)) + 1
    if n < 1:
        return np.zeros(0, dtype=np.int64)
    jitter = rng.uniform(-chain.jitter_s, chain.jitter_s, size=n)
    jitter[0] = 0.0
    ticks = np.round((chain.start_delay_s + np.arange(n) * chain.interval_s + jitter) / clock_s).astype(np.int64)
    return ticks[ticks <= int(np.floor(end_s / clock_s + 1e-9))]


@dataclass
class ChannelSamples:
    """One channel as logged: its instants (clock ticks), values (samples, sensors) with NaN for a
    dropout, and each sensor's offset (in the channel's unit)."""

    ticks: np.ndarray
    values: np.ndarray
    offsets: np.ndarray


# The true values of a channel at instants (s): (samples,) or (samples, sensors).
TrueValues = Callable[[np.ndarray], np.ndarray]
# What the sensor does to a reading before it is quantised (a magnitude, a range it saturates at).
SensorOutput = Callable[[np.ndarray, np.ndarray], np.ndarray]


def log_channel(
    rng: np.random.Generator,
    chain: ChannelChain,
    true_values: TrueValues,
    end_s: float,
    clock_s: float,
    sensor_output: SensorOutput | None = None,
) -> ChannelSamples:
    """One channel through its chain; ``sensor_output(time_s, reading)`` shapes the noisy reading
    (e.g. a speed sensor's magnitude, a transducer's saturation) before quantisation."""
    ticks = sample_ticks(rng, chain, end_s, clock_s)
    time = ticks * clock_s
    true = np.asarray(true_values(time), dtype=float)
    shape = true.shape
    sensors = 1 if true.ndim == 1 else shape[1]
    offsets = chain.offset_sigma * rng.standard_normal(sensors)
    noise = ar1_noise(rng, shape, chain.noise_sigma, chain.ar1_rho) if len(time) else np.zeros(shape)
    reading = true + (offsets[0] if true.ndim == 1 else offsets) + noise
    if sensor_output is not None:
        reading = sensor_output(time, reading)
    values = quantise(reading, chain.resolution)
    blank = dropout_mask(rng, len(time), chain.dropout_probability, chain.dropout_mean_samples)
    blank[:1] = False  # a channel's first sample marks its start (and speed's is the initial speed)
    values[blank] = np.nan
    return ChannelSamples(ticks, values, offsets)


def merge_channels(logged: Mapping[str, ChannelSamples], columns: Mapping[str, list[str]], clock_s: float) -> dict:
    """One table of every channel on the union of their instants: ``{time_s: ..., column: ...}``
    with NaN (a blank cell) where a channel has no sample. ``columns`` names each channel's columns
    (one per sensor). Instants of different channels on the same tick share a row."""
    ticks = np.unique(np.concatenate([samples.ticks for samples in logged.values()]))
    table: dict[str, np.ndarray] = {TIME: np.round(ticks * clock_s, PRINT_DECIMALS)}
    for channel, samples in logged.items():
        rows = np.searchsorted(ticks, samples.ticks)
        values = samples.values.reshape(len(samples.ticks), -1)
        for sensor, column in enumerate(columns[channel]):
            cells = np.full(len(ticks), np.nan)
            cells[rows] = values[:, sensor]
            table[column] = cells
    return table


def log_run(
    chain: MeasurementChain,
    seed: np.random.SeedSequence,
    true_values: Mapping[str, TrueValues],
    columns: Mapping[str, list[str]],
    end_s: float,
    sensor_outputs: Mapping[str, SensorOutput] | None = None,
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """A run's table (:func:`merge_channels`) and each channel's sensor offsets. ``true_values``
    and ``columns`` are keyed like :meth:`~.chain.ChainChannels.by_column`; channels left out of
    ``true_values`` are not logged. One generator per chain channel, spawned from ``seed`` in the
    chain's channel order."""
    chains = chain.channels.by_column()
    generators = dict(zip(chains, (np.random.default_rng(s) for s in seed.spawn(len(chains)))))
    outputs = sensor_outputs or {}
    logged = {
        channel: log_channel(
            generators[channel], chains[channel], values, end_s, chain.clock_resolution_s, outputs.get(channel)
        )
        for channel, values in true_values.items()
    }
    offsets = {channel: samples.offsets for channel, samples in logged.items()}
    return merge_channels(logged, columns, chain.clock_resolution_s), offsets
