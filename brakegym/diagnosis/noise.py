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
samples (the odd number of the channel's samples that spans a window given in seconds,
:func:`window_samples`) is the stationary filter g = delta - h applied to the noise (interior
samples only, where the filter is exactly that). For AR(1) noise of level sigma and correlation rho its variance is
sigma^2 A(rho) and its lag-1 covariance sigma^2 B(rho), with A(rho) = sum_ij g_i g_j rho^|i-j| and
B(rho) = sum_ij g_i g_j rho^|i-j+1|. The measured ratio B/A gives rho (B/A increases with rho),
then sigma = sqrt(var / A(rho)). The signal must be a cubic on the window's span, which is a
property of the physics of a channel, not of its sample rate: the window is given in seconds and
each channel takes as many of its own samples as span it (a 2 Hz thermometer 7 samples over 3 s,
where a fixed 31 samples would span 15 s of a curving disc temperature and read its curvature as
correlated noise). Quantisation adds q^2/12 to the variance, white.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.signal import savgol_coeffs

GAP_OVER_INTERVAL = 1.5
NOISE_POLYNOMIAL_ORDER = 3
# A cubic's residual over fewer samples leaves too few degrees of freedom to tell rho apart.
MIN_WINDOW_SAMPLES = 7
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


def window_samples(window_s: float, interval_s: float) -> int:
    """The odd number of samples ``interval_s`` apart that spans ``window_s`` seconds, at least
    ``MIN_WINDOW_SAMPLES``."""
    return max(2 * int(round(window_s / interval_s / 2.0)) + 1, MIN_WINDOW_SAMPLES)


def median_interval_s(series: Sequence[tuple[np.ndarray, np.ndarray]]) -> float:
    """The median interval (s) between a channel's own samples (its non-blank cells) over several
    recordings' ``(time_s, values)``; NaN without two samples in any of them."""
    intervals = [np.diff(time_s[~np.isnan(values)]) for time_s, values in series]
    pooled = np.concatenate(intervals) if intervals else np.empty(0)
    return float(np.median(pooled)) if pooled.size else float("nan")


@lru_cache(maxsize=16)
def _residual_filter(window: int, order: int) -> np.ndarray:
    """g = delta - h: the residual about the smooth of the centre sample, as a filter."""
    g = -savgol_coeffs(window, order)
    g[window // 2] += 1.0
    return g


@lru_cache(maxsize=16)
def _ar1_moments(window: int, order: int) -> tuple[np.ndarray, np.ndarray]:
    """A(rho) and B(rho) of the module documentation on ``RHO_GRID``, through the filter's
    autocorrelation c_k = sum_{i - j = k} g_i g_j: A = sum_k c_k rho^|k|, B = sum_k c_k rho^|k+1|."""
    g = _residual_filter(window, order)
    lags = np.arange(-(window - 1), window)
    c = np.correlate(g, g, mode="full")
    a = np.power.outer(RHO_GRID, np.abs(lags)) @ c
    b = np.power.outer(RHO_GRID, np.abs(lags + 1)) @ c
    return a, b


@dataclass(frozen=True)
class ChannelNoise:
    """A channel's noise model. ``sigma``: marginal standard deviation (channel units);
    ``rho``: lag-1 autocorrelation per sample of the channel's own sampling; ``white_sigma``: what
    the same residual gives when the noise is taken as white (rho = 0); ``samples``: residual
    samples used; ``window``: samples of the smooth."""

    sigma: float
    rho: float
    white_sigma: float
    samples: int
    window: int


def estimate_channel_noise(
    time_s: np.ndarray, values: np.ndarray, window_s: float, order: int = NOISE_POLYNOMIAL_ORDER
) -> ChannelNoise:
    """The AR(1) noise model of one channel, its smooth spanning ``window_s`` seconds (see the
    module documentation); NaN where no run is long enough (the window's samples + 2)."""
    return pooled_channel_noise([(np.asarray(time_s, float), np.asarray(values, float))], window_s, order)


def pooled_channel_noise(
    series: Sequence[tuple[np.ndarray, np.ndarray]], window_s: float, order: int = NOISE_POLYNOMIAL_ORDER
) -> ChannelNoise:
    """:func:`estimate_channel_noise` over several recordings' ``(time_s, values)`` of one channel,
    with one noise model for all of them (one window: the channel's median interval over all)."""
    interval_s = median_interval_s(series)
    if not np.isfinite(interval_s) or interval_s <= 0:
        return ChannelNoise(float("nan"), float("nan"), float("nan"), 0, 0)
    window = window_samples(window_s, interval_s)
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
        return ChannelNoise(float("nan"), float("nan"), float("nan"), count, window)
    variance, covariance = squares / count, products / pairs
    a, b = _ar1_moments(window, order)
    ratio = b / a
    rho = float(np.interp(covariance / variance, ratio, RHO_GRID))
    sigma = float(np.sqrt(variance / np.interp(rho, RHO_GRID, a)))
    white_sigma = float(np.sqrt(variance / a[np.argmin(np.abs(RHO_GRID))]))
    return ChannelNoise(sigma, rho, white_sigma, count, window)


def noise_model_entry(model: ChannelNoise) -> dict[str, float | int | None]:
    """A noise model as the report gives it (rounded; None where it could not be estimated)."""

    def shown(value: float, digits: int) -> float | None:
        return round(value, digits) if np.isfinite(value) else None

    return {
        "sigma": shown(model.sigma, 5),
        "lag1_autocorrelation": shown(model.rho, 3),
        "white_noise_sigma": shown(model.white_sigma, 5),
        "samples": model.samples,
        "window_samples": model.window,
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
