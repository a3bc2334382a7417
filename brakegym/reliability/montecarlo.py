"""Plain Monte Carlo: :func:`brute_force`, on
:func:`~brakegym.reliability.streams.standard_normals` of the seed's own stream.

Probability interval: Clopper & Pearson (1934, Biometrika 26, 404-413), exact binomial. Quantile
interval: distribution-free, between two order statistics whose ranks come from the binomial
distribution of the number of samples below the quantile (David & Nagaraja 2003, *Order
Statistics*, 3rd ed., Wiley, on distribution-free intervals for quantiles).
"""

from __future__ import annotations

import math
import time

import numpy as np
from scipy import stats

from .checks import check_integer, check_target
from .response import CountedResponse, Response
from .results import TailEstimate, WeightedTail
from .streams import standard_normals

# Brute force refuses a quantile with fewer expected exceedances than this.
_MIN_EXPECTED_EXCEEDANCES = 10
# Brute force with a threshold keeps the responses above it, at most this many (the largest).
_MAX_KEPT_RESPONSES = 1_000_000


def brute_force(
    response: Response,
    dims: int,
    seed: int,
    n_samples: int,
    probability: float | None = None,
    threshold: float | None = None,
    batch_size: int = 4096,
) -> TailEstimate:
    """Plain Monte Carlo on ``standard_normals(seed, arange(n_samples), dims)``.

    Samples are drawn and evaluated one batch at a time. With ``threshold``, only the responses
    above it are kept (at most the largest million), and the probability is the fraction of
    exceedances with a Clopper-Pearson interval. With ``probability``, the quantile is read off the empirical CCDF
    (see :mod:`.results`) and its interval lies between the order statistics of ranks ``l``
    and ``u``, the binomial ranks with ``P(l <= B < u) >= 0.95`` for ``B ~ Binomial(n, 1 - p)``,
    the number of samples below the true quantile; only the largest ``n - l + 2`` responses are
    kept (in a buffer of twice that plus a batch). The probability interval is Clopper-Pearson's
    at the estimated quantile. A probability with fewer than 10 expected exceedances (or
    non-exceedances) in ``n_samples`` is refused. The kept responses make the estimate's
    :class:`WeightedTail`, which therefore resolves the CCDF only above the threshold, or above
    the quantile interval's lower end.

    Parameters
    ----------
    response
        ``response(u) -> y`` on rows of standard normals (see :mod:`.response`).
    dims
        Number of standard-normal inputs.
    seed
        The stream of :func:`~brakegym.reliability.streams.standard_normals`.
    n_samples
        Monte Carlo sample size.
    probability, threshold
        Exactly one: the exceedance probability whose quantile to estimate, or the threshold
        whose exceedance probability to estimate.
    batch_size
        The most rows per call of ``response``.
    """
    start = time.perf_counter()
    check_target(probability, threshold)
    n_samples = check_integer("n_samples", n_samples, 1)
    if probability is not None:
        needed = math.ceil(_MIN_EXPECTED_EXCEEDANCES / min(probability, 1.0 - probability))
        if n_samples < needed:
            raise ValueError(
                f"n_samples = {n_samples} is too few for probability = {probability}: "
                f"{_MIN_EXPECTED_EXCEEDANCES} expected exceedances need n_samples >= {needed}"
            )
    evaluate = CountedResponse(response, dims, batch_size)
    if probability is None:
        exceedances, largest = _exceeding_responses(evaluate, seed, n_samples, threshold, _MAX_KEPT_RESPONSES)
        threshold_ci95 = (float(threshold), float(threshold))
        resolved_from = float(threshold) if exceedances == len(largest) else float(largest[-1])
    else:
        lower_rank, upper_rank = _binomial_ranks(n_samples, probability)
        # The interval's lower end is the (n - lower_rank + 1)-th largest response; the estimate lies above it.
        largest = _largest_responses(evaluate, seed, n_samples, min(n_samples, n_samples - lower_rank + 2))
        # The m-th largest of n sits at the CCDF position (m - 1/2) / n.
        threshold = float(np.interp(probability, (np.arange(len(largest)) + 0.5) / n_samples, largest))
        threshold_ci95 = (float(largest[n_samples - lower_rank]), float(largest[n_samples - upper_rank]))
        exceedances = int(np.count_nonzero(largest > threshold))
        resolved_from = -math.inf if len(largest) == n_samples else float(largest[-1])
    estimate = exceedances / n_samples
    probability_ci95 = _clopper_pearson(exceedances, n_samples)
    return TailEstimate(
        method="brute",
        target="threshold" if probability is None else "probability",
        probability=float(estimate if probability is None else probability),
        probability_ci95=probability_ci95,
        threshold=float(threshold),
        threshold_ci95=threshold_ci95,
        model_evaluations=evaluate.evaluations,
        seconds=time.perf_counter() - start,
        coefficient_of_variation=math.sqrt((1 - estimate) / exceedances) if exceedances else math.inf,
        diagnostics={"exceedances": exceedances},
        tail=WeightedTail(
            "brute", largest, np.full(len(largest), 1.0 / n_samples), n_samples, resolved_from=resolved_from
        ),
    )


def _clopper_pearson(successes: int, trials: int) -> tuple[float, float]:
    low = 0.0 if successes == 0 else float(stats.beta.ppf(0.025, successes, trials - successes + 1))
    high = 1.0 if successes == trials else float(stats.beta.ppf(0.975, successes + 1, trials - successes))
    return low, high


def _binomial_ranks(n: int, probability: float) -> tuple[int, int]:
    """The ranks (from the smallest, 1-based) of the order statistics that bound the quantile of
    exceedance probability ``probability`` with probability at least 0.95, distribution-free
    (David & Nagaraja 2003).

    ``B``, the number of samples below the true quantile, is Binomial(n, 1 - p); with ``l - 1``
    the largest count of lower tail ``P(B <= l - 1) <= 0.025`` and ``u - 1`` the smallest with
    ``P(B <= u - 1) >= 0.975``, the ``l``-th and ``u``-th smallest responses bound the quantile with
    probability ``P(l <= B <= u - 1) >= 0.95``."""
    below = stats.binom(n, 1.0 - probability)
    lower_rank = int(below.ppf(0.025))
    if below.cdf(lower_rank) <= 0.025:
        lower_rank += 1
    return lower_rank, int(below.ppf(0.975)) + 1


def _exceeding_responses(
    evaluate: CountedResponse, seed: int, n_samples: int, threshold: float, keep: int
) -> tuple[int, np.ndarray]:
    """How many of the Monte Carlo sample's responses exceed ``threshold``, and the largest
    ``keep`` of those, in descending order; batch by batch, the kept ones cut back to the ``keep``
    largest whenever more than twice as many are held."""
    exceedances, held, pieces = 0, 0, []
    for begin in range(0, n_samples, evaluate.batch_size):
        index = np.arange(begin, min(begin + evaluate.batch_size, n_samples))
        values = evaluate(standard_normals(seed, index, evaluate.dims))
        above = values[values > threshold]
        exceedances += len(above)
        pieces.append(above)
        held += len(above)
        if held > 2 * keep:
            merged = np.concatenate(pieces)
            pieces, held = [np.partition(merged, len(merged) - keep)[len(merged) - keep :]], keep
    kept = np.concatenate(pieces) if pieces else np.empty(0)
    if len(kept) > keep:
        kept = np.partition(kept, len(kept) - keep)[len(kept) - keep :]
    return exceedances, np.sort(kept)[::-1]


def _largest_responses(evaluate: CountedResponse, seed: int, n_samples: int, keep: int) -> np.ndarray:
    """The ``keep`` largest responses of the Monte Carlo sample, in descending order, evaluated
    batch by batch into a buffer of ``2 keep + batch_size`` values that is cut back to its ``keep``
    largest whenever it is full (each cut frees room for at least ``keep`` values, so the cuts cost
    a constant per sample)."""
    buffer = np.empty(min(n_samples, 2 * keep + evaluate.batch_size))
    filled = 0
    for begin in range(0, n_samples, evaluate.batch_size):
        index = np.arange(begin, min(begin + evaluate.batch_size, n_samples))
        values = evaluate(standard_normals(seed, index, evaluate.dims))
        if filled + len(values) > len(buffer):
            buffer[:keep] = np.partition(buffer[:filled], filled - keep)[filled - keep :]
            filled = keep
        buffer[filled : filled + len(values)] = values
        filled += len(values)
    return np.sort(np.partition(buffer[:filled], filled - keep)[filled - keep :])[::-1]
