"""Statistics shared by the campaigns, the identification and the diagnosis.

- :func:`sample_statistics`: mean and standard deviation with their 95 % intervals (spec
  Section 6: Student's t for means, chi-square for standard deviations).
- :func:`envelope`: the instantaneous mean and standard deviation over applications (paper Eq. 2).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats


@dataclass(frozen=True)
class SampleStatistics:
    """Mean and empirical standard deviation of a sample with their 95 % confidence intervals."""

    n: int
    mean: float
    std: float
    mean_ci95: tuple[float, float]
    std_ci95: tuple[float, float]

    @property
    def relative_std(self) -> float:
        return self.std / self.mean

    def as_dict(self) -> dict[str, float | int | list[float]]:
        return {
            "n": self.n,
            "mean": self.mean,
            "std": self.std,
            "mean_ci95": list(self.mean_ci95),
            "std_ci95": list(self.std_ci95),
        }


def sample_statistics(values: Sequence[float] | np.ndarray, confidence: float = 0.95) -> SampleStatistics:
    """Mean with a Student-t interval, standard deviation (ddof 1) with a chi-square interval."""
    x = np.asarray(values, dtype=float)
    if x.ndim != 1 or len(x) < 2:
        raise ValueError(f"need a 1-D sample of at least 2 values, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("sample contains non-finite values")
    n = len(x)
    mean = float(x.mean())
    std = float(x.std(ddof=1))
    alpha = 1.0 - confidence
    half_width = stats.t.ppf(1 - alpha / 2, n - 1) * std / np.sqrt(n)
    chi_low, chi_high = stats.chi2.ppf(1 - alpha / 2, n - 1), stats.chi2.ppf(alpha / 2, n - 1)
    return SampleStatistics(
        n=n,
        mean=mean,
        std=std,
        mean_ci95=(mean - half_width, mean + half_width),
        std_ci95=(float(std * np.sqrt((n - 1) / chi_low)), float(std * np.sqrt((n - 1) / chi_high))),
    )


def envelope(trajectory_values: np.ndarray, moving: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Instantaneous mean and standard deviation over applications (Eq. 2) of a (T, B) series,
    counting at each instant only the applications still braking. Returns (mean, std, count)."""
    values = np.where(moving, trajectory_values, np.nan)
    count = moving.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.nanmean(np.where(count[:, None] > 0, values, 0.0), axis=1)
        std = np.where(count > 1, np.nanstd(np.where(count[:, None] > 1, values, 0.0), axis=1, ddof=1), np.nan)
    mean = np.where(count > 0, mean, np.nan)
    return mean, std, count
