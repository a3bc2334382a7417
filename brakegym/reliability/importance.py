"""Importance sampling: :func:`importance_sampling`, the multilevel cross-entropy method (Rubinstein
& Kroese 2004, *The Cross-Entropy Method*, Springer) with a Gaussian importance density of unit
covariance whose mean is adapted, then a final importance-sampling run. Probability interval from
the standard error of the weighted sample.

The cross-entropy levels and the final run draw their samples from streams derived from the seed.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from .checks import check_integer, check_level_probability, check_target
from .response import CountedResponse, Response
from .results import TailEstimate, WeightedTail, ccdf_quantiles, lognormal_interval
from .streams import derived_seed, standard_normals

# Stream numbers under the user's seed: derived_seed(seed, _CROSS_ENTROPY_STREAM, level) for the
# cross-entropy levels, derived_seed(seed, _FINAL_STREAM) for the final run; subset simulation uses
# the stream 1, mixture_tail 4 and 5.
_CROSS_ENTROPY_STREAM = 2
_FINAL_STREAM = 3


def importance_sampling(
    response: Response,
    dims: int,
    seed: int,
    probability: float | None = None,
    threshold: float | None = None,
    n_per_level: int = 2000,
    n_final: int | None = None,
    level_probability: float = 0.1,
    max_levels: int = 30,
    batch_size: int = 4096,
) -> TailEstimate:
    """Cross-entropy importance sampling with a mean-shifted standard-normal density.

    The importance density is ``N(mu, I)``. Level ``t`` draws ``n_per_level`` samples from it
    (weights ``phi(u) / h(u) = exp(-mu.u + |mu|**2 / 2)``); its intermediate threshold ``g_t`` is
    the sample's ``1 - p0`` quantile (``p0 = level_probability``), or the target once at least
    ``N p0`` samples exceed it: the given threshold, or with ``probability=p`` the quantile read off
    the weighted CCDF at ``p``. The new mean is the weighted mean of the samples above ``g_t``, the
    cross-entropy optimum among unit-covariance Gaussians (Rubinstein & Kroese 2004). Once the
    target is reached, ``n_final`` fresh samples from the last density give the estimate:
    ``P = mean(w * 1[y > b])`` with coefficient of variation
    ``std(w * 1[y > b]) / (P sqrt(n_final))``; a quantile is read off the final sample's weighted
    CCDF, intervals as in :mod:`.results`.

    Only the mean is adapted: a covariance estimated from a few hundred elite samples in tens of
    dimensions is noisy, and the weights of such densities degenerate as the dimension grows
    (Au & Beck 2003, "Important sampling in high dimensions", Structural Safety 25, 139-163;
    Geyer, Papaioannou & Straub 2019, "Cross entropy-based importance sampling using Gaussian
    densities revisited", Structural Safety 76, 15-27), while the unit covariance keeps the
    weights' spread fixed by the shift alone. One Gaussian serves one failure region: a response
    that exceeds in several separate regions of comparable probability is not what this method
    is for: on the series system ``max(u1, u2)`` the density settles on one of the two equally
    probable regions, and the estimate is half the exact value with a narrow interval (or the
    levels stall). A cross-entropy level whose intermediate threshold does not rise above the
    previous one stops the estimate with a RuntimeError. Measured over 400 repetitions with the
    defaults, the 95 % intervals held the exact value in 94 to 97 % of the runs on a linear
    response in 50 dimensions and on a parallel system (``min(u1, u2)``), from 1e-3 to 1e-9; on
    the series system in almost none.

    Parameters
    ----------
    response, dims, seed, probability, threshold, batch_size
        As for :func:`~.montecarlo.brute_force`.
    n_per_level
        Samples per cross-entropy level; ``n_per_level * level_probability`` at least 1.
    n_final
        Samples of the final importance-sampling run (``n_per_level`` when None).
    level_probability
        ``p0``, the fraction of each level's samples above its intermediate threshold, in (0, 0.5].
    max_levels
        The most cross-entropy levels; not reaching the target in them is a RuntimeError.

    Raises
    ------
    RuntimeError
        When the cross-entropy levels stall or do not reach the target in ``max_levels``, or the
        final run has no exceedance.
    """
    start = time.perf_counter()
    check_target(probability, threshold)
    n_per_level, n_final, max_levels = importance_settings(n_per_level, n_final, level_probability, max_levels)
    evaluate = CountedResponse(response, dims, batch_size)
    mean, thresholds, mean_norms = _cross_entropy_levels(
        evaluate, seed, probability, threshold, n_per_level, level_probability, max_levels
    )
    responses, log_weights = _shifted_run(evaluate, mean, derived_seed(seed, _FINAL_STREAM), n_final)
    weights = np.exp(log_weights)
    estimate = _importance_estimate(responses, weights, probability, threshold)
    return TailEstimate(
        method="is",
        model_evaluations=evaluate.evaluations,
        seconds=time.perf_counter() - start,
        levels=tuple(thresholds),
        diagnostics={**estimate.pop("diagnostics"), "mean_norms": mean_norms, "importance_mean": mean.tolist()},
        tail=WeightedTail("is", responses, weights / n_final, n_final),
        **estimate,
    )


def importance_settings(
    n_per_level: int, n_final: int | None, level_probability: float, max_levels: int
) -> tuple[int, int, int]:
    """:func:`importance_sampling`'s settings, checked: ``n_per_level``, ``n_final``, ``max_levels``."""
    n_per_level = check_integer("n_per_level", n_per_level, 2)
    n_final = check_integer("n_final", n_per_level if n_final is None else n_final, 2)
    check_level_probability(level_probability)
    if n_per_level * level_probability < 1:
        raise ValueError(
            f"n_per_level = {n_per_level} with level_probability = {level_probability} leaves no sample above "
            f"the intermediate thresholds: need n_per_level * level_probability >= 1"
        )
    return n_per_level, n_final, check_integer("max_levels", max_levels, 1)


def _cross_entropy_levels(
    evaluate: CountedResponse,
    seed: int,
    probability: float | None,
    threshold: float | None,
    n_per_level: int,
    level_probability: float,
    max_levels: int,
) -> tuple[np.ndarray, list[float], list[float]]:
    """The cross-entropy levels, until one reaches the target: the importance density's mean, the
    intermediate thresholds below the target, and the mean's norm after each level (0 first)."""
    mean, thresholds, mean_norms = np.zeros(evaluate.dims), [], [0.0]
    for level in range(max_levels):
        stream = derived_seed(seed, _CROSS_ENTROPY_STREAM, level)
        responses, log_weights = _shifted_run(evaluate, mean, stream, n_per_level)
        intermediate, reached = _cross_entropy_threshold(
            responses, log_weights, probability, threshold, level_probability
        )
        if not reached and thresholds and intermediate <= thresholds[-1]:
            raise RuntimeError(
                f"cross entropy stalled at level {level}: intermediate threshold {intermediate:.6g} <= "
                f"{thresholds[-1]:.6g}; one Gaussian importance density cannot follow this response "
                f"(several failure regions?)"
            )
        mean = _cross_entropy_mean(mean, stream, responses, log_weights, intermediate)
        mean_norms.append(float(np.linalg.norm(mean)))
        if reached:
            return mean, thresholds, mean_norms
        thresholds.append(intermediate)
    raise RuntimeError(
        f"cross entropy did not reach the target in max_levels = {max_levels} levels "
        f"(last intermediate threshold {thresholds[-1]:.6g})"
    )


def _shifted_run(evaluate: CountedResponse, mean: np.ndarray, stream: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` samples ``mean + z`` (``z`` from ``stream``) evaluated batch by batch: their responses
    and log importance weights ``log phi(u) - log h(u) = -mean.z - |mean|**2 / 2``."""
    responses, log_weights = np.empty(n), np.empty(n)
    offset = 0.5 * float(mean @ mean)
    for begin in range(0, n, evaluate.batch_size):
        index = np.arange(begin, min(begin + evaluate.batch_size, n))
        noise = standard_normals(stream, index, evaluate.dims)
        responses[index] = evaluate(mean + noise)
        # A column at a time, not a matrix product: BLAS may sum a row in an order that depends on
        # the batch, and the weights must not.
        shift = np.zeros(len(index))
        for column, component in zip(noise.T, mean):
            shift += column * component
        log_weights[index] = -shift - offset
    return responses, log_weights


def _cross_entropy_threshold(
    responses: np.ndarray,
    log_weights: np.ndarray,
    probability: float | None,
    threshold: float | None,
    level_probability: float,
) -> tuple[float, bool]:
    """A level's intermediate threshold, and whether it is the target itself: the target once at
    least ``n p0`` samples exceed it, else the sample's ``1 - p0`` quantile."""
    if probability is not None:
        weights = np.exp(log_weights)
        threshold = float(ccdf_quantiles(responses, weights, np.array([probability]))[0])
    if math.isfinite(threshold) and np.count_nonzero(responses > threshold) >= level_probability * len(responses):
        return threshold, True
    return float(ccdf_quantiles(responses, None, np.array([level_probability]))[0]), False


def _cross_entropy_mean(
    mean: np.ndarray, stream: int, responses: np.ndarray, log_weights: np.ndarray, threshold: float
) -> np.ndarray:
    """The weighted mean of the samples above ``threshold``, their points drawn again from the
    counter-based ``stream`` (nothing but responses and weights is kept of a run)."""
    elite = np.flatnonzero(responses > threshold)
    if elite.size == 0:
        raise RuntimeError(f"no sample exceeds the intermediate threshold {threshold:.6g}: is the response constant?")
    weights = np.exp(log_weights[elite] - log_weights[elite].max())
    points = mean + standard_normals(stream, elite, len(mean))
    return (weights @ points) / weights.sum()


def _importance_estimate(
    responses: np.ndarray, weights: np.ndarray, probability: float | None, threshold: float | None
) -> dict[str, Any]:
    """The final run's estimate (fields of :class:`TailEstimate`) from its responses and weights."""
    n = len(responses)
    if probability is not None:
        threshold = float(ccdf_quantiles(responses, weights, np.array([probability]))[0])
    weighted = np.where(responses > threshold, weights, 0.0)
    estimate = float(weighted.mean())
    if not (estimate > 0.0 and math.isfinite(threshold)):
        raise RuntimeError(
            f"the final importance-sampling run of {n} samples has no exceedance of {threshold}: raise n_final"
        )
    cov = float(weighted.std(ddof=1)) / (estimate * math.sqrt(n))
    probability_ci95 = lognormal_interval(estimate if probability is None else probability, cov)
    if probability is None:
        threshold_ci95 = (threshold, threshold)
    else:
        ends = ccdf_quantiles(responses, weights, np.array(probability_ci95[::-1]))
        threshold_ci95 = (float(ends[0]), float(ends[1]))
    return {
        "target": "threshold" if probability is None else "probability",
        "probability": estimate if probability is None else float(probability),
        "probability_ci95": probability_ci95,
        "threshold": float(threshold),
        "threshold_ci95": threshold_ci95,
        "coefficient_of_variation": cov,
        "diagnostics": {
            "exceedances": int(np.count_nonzero(weighted)),
            "effective_sample_size": float(weights.sum() ** 2 / (weights**2).sum()),
        },
    }
