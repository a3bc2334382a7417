"""The noise model of a measured channel, estimated from the data: level, AR(1) autocorrelation,
quantisation step, and the reading while nothing acts on the sensor (its offset or bias).

A channel is taken on its own sampling: in a table that merges channels of different rates a
channel's blank cells are mostly instants at which it was not sampled, so its samples are its
non-blank cells, split into runs where the gap to the next sample exceeds ``GAP_OVER_INTERVAL``
times its median interval (a dropout).

**Level and autocorrelation.** A white-noise estimate (the residual about a smooth, or the
differences of neighbours) takes correlated noise for signal: for AR(1) noise with lag-1
correlation rho, half the variance of the first differences is sigma^2 (1 - rho), 0.45 sigma for
rho = 0.8. Here the residual of each run about a cubic Savitzky-Golay smooth of ``window``
samples is the stationary filter g = delta - h applied to the noise (interior samples only, where
the filter is exactly that). For AR(1) noise of level sigma and correlation rho its variance is
sigma^2 A(rho) and its lag-1 covariance sigma^2 B(rho), with A(rho) = sum_ij g_i g_j rho^|i-j| and
B(rho) = sum_ij g_i g_j rho^|i-j+1|. The measured ratio B/A gives rho (B/A increases with rho),
then sigma = sqrt(var / A(rho)). The signal must be smooth on the window's scale (a cubic over
``window`` samples); quantisation adds q^2/12 to the variance, white.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.signal import savgol_coeffs

GAP_OVER_INTERVAL = 1.5
NOISE_WINDOW_SAMPLES = 31
NOISE_POLYNOMIAL_ORDER = 3
RHO_GRID = np.linspace(-0.9, 0.99, 380)
MIN_QUANTISED_VALUES = 10  # distinct values needed before a grid of values counts as quantisation


def channel_samples(time_s: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A channel's own samples in a merged table: the instants and values of its non-blank cells."""
    present = ~np.isnan(values)
    return time_s[present], values[present]


def channel_runs(time_s: np.ndarray, values: np.ndarray, min_samples: int = 3) -> list[np.ndarray]:
    """Index arrays (into ``values``) of the runs of a channel's own samples without a dropout:
    consecutive non-blank cells whose intervals stay within ``GAP_OVER_INTERVAL`` times the
    channel's median interval; runs shorter than ``min_samples`` are left out."""
    present = np.flatnonzero(~np.isnan(values))
    if present.size < 2:
        return [present] if present.size >= min_samples else []
    intervals = np.diff(time_s[present])
    breaks = np.flatnonzero(intervals > GAP_OVER_INTERVAL * np.median(intervals)) + 1
    return [run for run in np.split(present, breaks) if run.size >= min_samples]


@lru_cache(maxsize=8)
def _residual_filter(window: int, order: int) -> np.ndarray:
    """g = delta - h: the residual about the smooth of the centre sample, as a filter."""
    g = -savgol_coeffs(window, order)
    g[window // 2] += 1.0
    return g


@lru_cache(maxsize=8)
def _ar1_moments(window: int, order: int) -> tuple[np.ndarray, np.ndarray]:
    """A(rho) and B(rho) of the module documentation on ``RHO_GRID``."""
    g = _residual_filter(window, order)
    lags = np.subtract.outer(np.arange(window), np.arange(window))
    outer = np.outer(g, g)
    distance, shifted = np.abs(lags), np.abs(lags + 1)
    a = np.array([np.sum(outer * rho**distance) for rho in RHO_GRID])
    b = np.array([np.sum(outer * rho**shifted) for rho in RHO_GRID])
    return a, b


@dataclass(frozen=True)
class ChannelNoise:
    """A channel's noise model. ``sigma``: marginal standard deviation (channel units);
    ``rho``: lag-1 autocorrelation per sample of the channel's own sampling; ``white_sigma``: what
    the same residual gives when the noise is taken as white (rho = 0); ``samples``: residual
    samples used."""

    sigma: float
    rho: float
    white_sigma: float
    samples: int


def estimate_channel_noise(
    time_s: np.ndarray,
    values: np.ndarray,
    window: int = NOISE_WINDOW_SAMPLES,
    order: int = NOISE_POLYNOMIAL_ORDER,
) -> ChannelNoise:
    """The AR(1) noise model of one channel (see the module documentation); NaN where no run is
    long enough (``window`` + 2 samples)."""
    return pooled_channel_noise([(np.asarray(time_s, float), np.asarray(values, float))], window, order)


def pooled_channel_noise(
    series: Sequence[tuple[np.ndarray, np.ndarray]],
    window: int = NOISE_WINDOW_SAMPLES,
    order: int = NOISE_POLYNOMIAL_ORDER,
) -> ChannelNoise:
    """:func:`estimate_channel_noise` over several recordings' ``(time_s, values)`` of one channel,
    with one noise model for all of them."""
    g = _residual_filter(window, order)
    squares, products, count, pairs = 0.0, 0.0, 0, 0
    for time_s, values in series:
        for run in channel_runs(time_s, values, min_samples=window + 2):
            residual = np.convolve(values[run], g[::-1], mode="valid")
            squares += float(residual @ residual)
            products += float(residual[1:] @ residual[:-1])
            count += residual.size
            pairs += residual.size - 1
    if count < 2:
        return ChannelNoise(float("nan"), float("nan"), float("nan"), count)
    variance, covariance = squares / count, products / pairs
    a, b = _ar1_moments(window, order)
    ratio = b / a
    rho = float(np.interp(covariance / variance, ratio, RHO_GRID))
    sigma = float(np.sqrt(variance / np.interp(rho, RHO_GRID, a)))
    white_sigma = float(np.sqrt(variance / a[np.argmin(np.abs(RHO_GRID))]))
    return ChannelNoise(sigma, rho, white_sigma, count)


def noise_model_entry(model: ChannelNoise) -> dict[str, float | int | None]:
    """A noise model as the report gives it (rounded; None where it could not be estimated)."""

    def shown(value: float, digits: int) -> float | None:
        return round(value, digits) if np.isfinite(value) else None

    return {
        "sigma": shown(model.sigma, 5),
        "lag1_autocorrelation": shown(model.rho, 3),
        "white_noise_sigma": shown(model.white_sigma, 5),
        "samples": model.samples,
    }


def quantisation_step(values: np.ndarray) -> float | None:
    """The step the values lie on, when they lie on one: the smallest gap between distinct values,
    if every value is a whole multiple of it (to 1e-6 of a step) and there are at least
    ``MIN_QUANTISED_VALUES`` distinct values; else None."""
    distinct = np.unique(values[~np.isnan(values)])
    if distinct.size < MIN_QUANTISED_VALUES:
        return None
    step = float(np.min(np.diff(distinct)))
    multiples = distinct / step
    if np.max(np.abs(multiples - np.round(multiples))) > 1e-6 * max(1.0, float(np.max(np.abs(multiples)))):
        return None
    return float(f"{step:.6g}")


def zero_reading(values: np.ndarray) -> dict[str, float | int] | None:
    """A sensor's reading while nothing acts on it (a cylinder before the brake command, an
    accelerometer at standstill): the median of ``values`` and how many samples; None without any."""
    present = values[~np.isnan(values)]
    if present.size == 0:
        return None
    return {"median": round(float(np.median(present)), 5), "samples": int(present.size)}
