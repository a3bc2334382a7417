"""Statistics shared by the campaigns, the identification and the diagnosis.

- :func:`sample_statistics`: mean and standard deviation with their 95 % intervals (spec
  Section 6: Student's t for means, chi-square for standard deviations).
- :func:`pooled_mean_std`: the mean and standard deviation of groups joined, from each group's.
- :func:`envelope`: the instantaneous mean and standard deviation over applications (paper Eq. 2).
- :func:`lag1_autocorrelation` and :func:`effective_sample_share`: how much independent
  information autocorrelated residuals hold (fits to time series count each sample as worth
  ``(1 - rho) / (1 + rho)`` of an independent one).
- :func:`gauss_newton_covariance`: the parameter covariance of a least-squares fit.
- :func:`paired_t`, :func:`paired_t_p_value` and :func:`paired_t_tail`: Student's t of paired
  differences, and the one-sided p-value it gives on their degrees of freedom.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import special


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
    # The quantile functions scipy.stats.t.ppf and chi2.ppf compute, called directly: importing
    # scipy.stats costs the command line about 0.3 s.
    half_width = special.stdtrit(n - 1, 1 - alpha / 2) * std / np.sqrt(n)
    chi_low, chi_high = (2 * special.gammaincinv((n - 1) / 2, q) for q in (1 - alpha / 2, alpha / 2))
    return SampleStatistics(
        n=n,
        mean=mean,
        std=std,
        mean_ci95=(mean - half_width, mean + half_width),
        std_ci95=(float(std * np.sqrt((n - 1) / chi_low)), float(std * np.sqrt((n - 1) / chi_high))),
    )


def pooled_mean_std(
    counts: Sequence[float] | np.ndarray, means: Sequence[float] | np.ndarray, stds: Sequence[float] | np.ndarray
) -> tuple[float, float]:
    """Mean and standard deviation (ddof 1) of several groups joined, from each group's count,
    mean and standard deviation (ddof 1; a group of one has std 0): the within-group squares plus
    the between-group squares. Lets a summary of many stops be built from summaries of parts
    without holding every stop."""
    n, mean_g, std_g = (np.asarray(values, dtype=float) for values in (counts, means, stds))
    total = float(n.sum())
    if total < 1:
        raise ValueError("pooled_mean_std: no values in the groups")
    mean = float(np.sum(n * mean_g) / total)
    if total < 2:
        return mean, math.nan
    squares = np.sum((n - 1) * std_g**2) + np.sum(n * (mean_g - mean) ** 2)
    return mean, float(np.sqrt(squares / (total - 1)))


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


def lag1_autocorrelation(series: Sequence[np.ndarray], centred: bool = False) -> float:
    """Pooled lag-1 autocorrelation of residual series: the sum over series of the products of
    neighbouring samples (pairs within a series only) over the sum of squares; about each series'
    mean when ``centred``, else about zero (a residual's offset then counts as correlated). Series
    of fewer than 3 samples are left out; 0 when nothing is left."""
    products, squares = [], []
    for values in series:
        if len(values) < 3:
            continue
        r = values - values.mean() if centred else values
        products.append(np.sum(r[1:] * r[:-1]))
        squares.append(np.sum(r**2))
    denominator = float(np.sum(squares))
    return float(np.sum(products)) / denominator if denominator > 0 else 0.0


def effective_sample_share(rho: float) -> float:
    """What one sample of a series with lag-1 autocorrelation ``rho`` is worth in independent
    samples, ``(1 - rho) / (1 + rho)`` (an AR(1) series' effective sample size over its length),
    with ``rho`` taken in [0, 0.999]: negative correlation is not counted as extra information."""
    rho = min(max(rho, 0.0), 0.999)
    return (1.0 - rho) / (1.0 + rho)


def gauss_newton_covariance(weighted_jacobian: np.ndarray, singular_cutoff: float = 1e-12) -> np.ndarray:
    """(J' J)^-1 of a Jacobian whose rows are already weighted by 1 / sigma, through its SVD, so
    that a singular problem gives infinite variances along its null directions (singular values
    below ``singular_cutoff`` times the largest) instead of a failed inversion."""
    _, singular, vt = np.linalg.svd(weighted_jacobian, full_matrices=False)
    tiny = singular <= singular[0] * singular_cutoff if singular[0] > 0 else np.ones_like(singular, bool)
    inverse = np.where(tiny, np.inf, 1.0 / np.where(tiny, 1.0, singular) ** 2)
    with np.errstate(invalid="ignore"):
        covariance = (vt.T * inverse) @ vt
    return np.where(np.isnan(covariance), np.inf, covariance)


def conditional_information(information: np.ndarray) -> np.ndarray:
    """Per parameter, what an information matrix (J' W J) holds of it with the other parameters
    free: the Schur complement ``I_jj - I_j,o I_oo^+ I_o,j`` (the reciprocal of the covariance's
    diagonal where the matrix is regular), 0 for a parameter the matrix says nothing of. Through
    the pseudo-inverse so that a matrix singular along other parameters still answers."""
    p = information.shape[0]
    out = np.zeros(p)
    for j in range(p):
        others = [k for k in range(p) if k != j]
        cross = information[j, others]
        out[j] = information[j, j] - cross @ np.linalg.pinv(information[np.ix_(others, others)]) @ cross
    return np.maximum(out, 0.0)


def paired_t(differences: np.ndarray) -> float:
    """Student's t of the mean of paired differences: inf when they agree exactly and are
    positive, nan with fewer than two."""
    if len(differences) < 2:
        return math.nan
    spread = float(np.std(differences, ddof=1))
    mean = float(np.mean(differences))
    if spread == 0:
        return math.copysign(math.inf, mean) if mean else math.nan
    return mean / (spread / math.sqrt(len(differences)))


def paired_t_p_value(differences: np.ndarray) -> float:
    """The one-sided p-value of :func:`paired_t` (that the differences' mean is not positive):
    :func:`paired_t_tail` of their t; nan with fewer than two."""
    return paired_t_tail(paired_t(differences), len(differences))


def paired_t_tail(t: float, n: int) -> float:
    """The one-sided p-value of a paired t over ``n`` differences, from Student's t on ``n - 1``
    degrees of freedom: 0 at t = inf, nan for a nan t or fewer than two. A t of 2 is p = 0.043
    over 8 differences and p = 0.15 over 2."""
    if math.isnan(t) or n < 2:
        return math.nan
    return float(special.stdtr(n - 1, -t))
