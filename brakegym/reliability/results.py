"""The estimates: :class:`TailEstimate`, a quantile or an exceedance probability with its 95 %
intervals, and :class:`WeightedTail`, the estimate's CCDF as a weighted sample; with the interval
and CCDF arithmetic that the estimators share.

Every estimator takes either

- ``probability=p``: the quantile ``y_p`` with ``P(response > y_p) = p``, and its 95 % interval;
- ``threshold=b``: the exceedance probability ``P(response > b)``, and its 95 % interval;

and returns a :class:`TailEstimate`.

Intervals. Subset simulation and importance sampling give a coefficient of variation ``delta`` of
the probability estimate. Their 95 % probability interval is log-normal, ``P * exp(-+1.96 s)`` with
``s = sqrt(log(1 + delta**2))``: positive where ``P * (1 -+ 1.96 delta)`` can be negative,
right-skewed as products of level probabilities and sums of heavy-tailed weights are, and the same
to first order in ``delta``. A quantile's interval is where the estimated complementary
distribution function (CCDF) crosses the ends of the probability interval: the threshold whose
estimated exceedance probability is ``p * exp(+1.96 s)`` (lower end) and the one at
``p * exp(-1.96 s)`` (upper end); to first order these are the crossings at
``p / (1 -+ 1.96 delta)``. An end beyond what the samples resolve is infinite.

Empirical CCDF. Quantiles of a (weighted) sample are read off its CCDF with the samples at
mid-jump plotting positions: sorted from the largest, sample ``m`` sits at the probability
``S_m - w_m / 2`` (``S_m`` the sum of the ``m`` largest samples' weights over the sample size), and
the CCDF is linear between them. With equal weights and ``p * n`` a whole number ``m`` this is the
midpoint of the ``m``-th and ``m + 1``-th largest responses, Au & Beck's intermediate threshold.

Weighted samples. Every estimate carries its CCDF as a :class:`WeightedTail`
(:attr:`TailEstimate.tail`): responses with probability masses, whose sum over the responses above
``d`` is the estimate of ``P(response > d)`` at any ``d``, with the variance of that estimate. Tails
of independent runs combine by the law of total probability (:mod:`.mixture`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

Z95 = 1.959963984540054
"""The standard normal's 0.975 quantile, the factor of two-sided 95 % intervals."""


@dataclass(frozen=True, eq=False)
class WeightedTail:
    """An estimate of the complementary distribution function (CCDF) of a response, as a weighted
    sample: ``P(response > d)`` is estimated by the sum of :attr:`weights` over the
    :attr:`responses` above ``d``, for any ``d``, with the variance of that estimate.

    Every estimator's result is such a sample, so that tails of independent runs (strata of a
    mixture, :mod:`.mixture`) combine by the law of total probability. The weights are probability
    masses (they sum to at most 1); a sample with zero weight stands for nothing (subset
    simulation's seeds, counted in the next level).

    - ``"brute"`` (Monte Carlo, ``n = sample_size``): weights ``1 / n``. Only the largest
      responses are kept (those above the threshold given, or those down to the lower end of the
      quantile's interval), so the sample resolves the CCDF only from :attr:`resolved_from` up;
      below it :meth:`exceedance` and :meth:`variance` are NaN. Variance ``P (1 - P) / n``.
    - ``"subset"`` (``N = sample_size`` per level, ``p0 = level_probability``, intermediate
      thresholds ``b_1 < ... < b_L`` = :attr:`levels`): level ``j``'s samples in
      ``(b_j, b_{j+1}]`` (``b_0 = -inf``; those not carried on as seeds) weigh ``p0**j / N``, the
      last level's samples ``p0**L / N``. The sum above ``d`` in ``[b_j, b_{j+1})`` is then
      ``p0**j`` times level ``j``'s fraction above ``d``: subset simulation's CCDF estimate
      itself. The variance is Au & Beck's (2001) at ``d``:
      ``P**2 (sum_{i<j} (1 - p0) / (N p0) (1 + gamma_i) + (1 - P_j) / (N P_j) (1 + gamma_j(d)))``,
      with ``P_j`` level ``j``'s fraction above ``d`` and ``gamma_j(d)`` the correlation factor of
      its chains' indicators ``1[y > d]``; the completed levels' terms are :attr:`level_terms`.
      :attr:`responses` holds level after level, ``N`` each: level 0 in sample order, each later
      level as its chains' states step after step (``N / chains`` steps of ``chains`` states).
    - ``"is"`` (importance sampling, ``n = sample_size`` final samples with importance weights
      ``w_i``): weights ``w_i / n``; variance ``s**2 / n`` with ``s`` the sample standard
      deviation of ``w_i 1[y_i > d]``.
    - ``"mixture"``: ``sum_k pi_k`` times the CCDFs of independent :attr:`parts` with weights
      ``pi_k`` = :attr:`part_weights`; variance ``sum_k pi_k**2`` times theirs. :attr:`responses`
      and :attr:`weights` are the parts' samples with their weights times ``pi_k``.

    A CCDF of zero (no sample above ``d``) has zero variance: whether a sample resolves ``d`` is
    for :meth:`exceedance_count` to say. Instances pickle (plain arrays and numbers).

    Attributes
    ----------
    method
        ``"brute"``, ``"subset"``, ``"is"`` or ``"mixture"``.
    responses
        The sample's responses (read-only).
    weights
        Their probability masses (read-only).
    sample_size
        ``n`` of Monte Carlo or of the final importance-sampling run, ``N`` per level of subset
        simulation; 0 for a mixture.
    resolved_from
        The smallest ``d`` whose CCDF the sample gives; ``-inf`` except for brute force's kept tail.
    level_probability
        Subset simulation: ``p0``.
    levels
        Subset simulation: the intermediate thresholds ``b_1, ..., b_L``.
    chains
        Subset simulation: the number of Markov chains per level.
    level_terms
        Subset simulation: ``(1 - p0) / (N p0) (1 + gamma_i)`` of each completed level ``i < L``.
    parts
        A mixture's tails.
    part_weights
        Their weights ``pi_k``.
    """

    method: str
    responses: np.ndarray
    weights: np.ndarray
    sample_size: int = 0
    resolved_from: float = -math.inf
    level_probability: float = 0.0
    levels: tuple[float, ...] = ()
    chains: int = 0
    level_terms: tuple[float, ...] = ()
    parts: tuple[WeightedTail, ...] = ()
    part_weights: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        for name in ("responses", "weights"):
            values = np.array(getattr(self, name), dtype=np.float64)
            values.flags.writeable = False
            object.__setattr__(self, name, values)
        if self.responses.shape != self.weights.shape or self.responses.ndim != 1:
            raise ValueError(
                f"responses {self.responses.shape} and weights {self.weights.shape}: need two 1-D arrays of one length"
            )

    @classmethod
    def mixture(cls, parts: tuple[WeightedTail, ...], part_weights: tuple[float, ...]) -> WeightedTail:
        """The tail of ``sum_k part_weights[k] * parts[k]``, the parts independent estimates."""
        parts, part_weights = tuple(parts), tuple(float(w) for w in part_weights)
        responses = np.concatenate([part.responses for part in parts]) if parts else np.empty(0)
        weights = np.concatenate([w * part.weights for part, w in zip(parts, part_weights)]) if parts else np.empty(0)
        resolved_from = max((part.resolved_from for part in parts), default=-math.inf)
        return cls("mixture", responses, weights, resolved_from=resolved_from, parts=parts, part_weights=part_weights)

    def exceedance(self, d: float | np.ndarray) -> float | np.ndarray:
        """The estimate of ``P(response > d)``, for each ``d`` (NaN below :attr:`resolved_from`)."""
        points = np.asarray(d, dtype=np.float64)
        if self.method == "mixture":
            terms = (w * part.exceedance(points) for part, w in zip(self.parts, self.part_weights))
            result = sum(terms, np.zeros(points.shape))
        else:
            order = np.argsort(self.responses, kind="stable")
            ascending = self.responses[order]
            # Masses summed from the largest response down: above[m] is the mass of ascending[m:].
            above = np.append(np.cumsum(self.weights[order][::-1])[::-1], 0.0)
            result = above[np.searchsorted(ascending, points, side="right")]
            result = np.where(points < self.resolved_from, np.nan, result)
        return _like(result, points)

    def exceedance_count(self, d: float | np.ndarray) -> int | np.ndarray:
        """How many samples above ``d`` the estimate at ``d`` rests on: of the whole sample for brute
        force and importance sampling, of the level that holds ``d`` for subset simulation, summed
        over the parts of a mixture. Few (under 10, say) means the sample does not resolve ``d``."""
        points = np.asarray(d, dtype=np.float64)
        if self.method == "mixture":
            counts = sum((part.exceedance_count(points) for part in self.parts), np.zeros(points.shape, dtype=np.int64))
        elif self.method == "subset":
            counts = [np.count_nonzero(self._level(value) > value) for value in points.ravel()]
            counts = np.array(counts, dtype=np.int64).reshape(points.shape)
        else:
            ascending = np.sort(self.responses)
            counts = len(ascending) - np.searchsorted(ascending, points, side="right")
        return counts if points.ndim else int(counts)

    def variance(self, d: float | np.ndarray) -> float | np.ndarray:
        """The estimated variance of :meth:`exceedance` at each ``d`` (see the class notes)."""
        points = np.asarray(d, dtype=np.float64)
        probabilities = np.asarray(self.exceedance(points), dtype=np.float64)
        if self.method == "mixture":
            terms = (w**2 * part.variance(points) for part, w in zip(self.parts, self.part_weights))
            result = sum(terms, np.zeros(points.shape))
        elif self.method == "brute":
            result = probabilities * (1.0 - probabilities) / self.sample_size
        elif self.method == "is":
            n = self.sample_size
            order = np.argsort(self.responses, kind="stable")
            ascending, importance = self.responses[order], self.weights[order] * n
            first = np.append(np.cumsum(importance[::-1])[::-1], 0.0)
            second = np.append(np.cumsum(importance[::-1] ** 2)[::-1], 0.0)
            above = np.searchsorted(ascending, points, side="right")
            mean = first[above] / n
            result = np.maximum(second[above] / n - mean**2, 0.0) * n / (n - 1) / n
        else:
            squared_cov = np.array([self._squared_cov(value) for value in points.ravel()]).reshape(points.shape)
            result = probabilities**2 * squared_cov
        return _like(result, points)

    def coefficient_of_variation(self, d: float | np.ndarray) -> float | np.ndarray:
        """``sqrt(variance(d)) / exceedance(d)``; infinite where the estimate is zero."""
        points = np.asarray(d, dtype=np.float64)
        probabilities = np.asarray(self.exceedance(points), dtype=np.float64)
        spread = np.sqrt(np.asarray(self.variance(points), dtype=np.float64))
        with np.errstate(divide="ignore", invalid="ignore"):
            result = np.where(probabilities > 0.0, spread / np.where(probabilities > 0.0, probabilities, 1.0), np.inf)
        result = np.where(np.isnan(probabilities), np.nan, result)
        return _like(result, points)

    def level_index(self, value: float) -> int:
        """Subset simulation: the level whose samples give the CCDF at ``value``, the number of
        intermediate thresholds at or below it. At a threshold ``b_{j+1}`` itself this is level
        ``j + 1``, all of whose samples exceed it, except where the chains' repeated states tie
        at ``b_{j+1}``: then fewer than ``N p0`` of level ``j`` exceed it, and the weighted sample,
        like subset simulation with that threshold, counts level ``j + 1``'s."""
        return int(np.searchsorted(np.asarray(self.levels), value, side="right"))

    def _level(self, value: float) -> np.ndarray:
        """Subset simulation: the responses of the level that holds ``value``, as (steps, chains)."""
        level, n = self.level_index(value), self.sample_size
        block = self.responses[level * n : (level + 1) * n]
        return block[None, :] if level == 0 else block.reshape(n // self.chains, self.chains)

    def _squared_cov(self, value: float) -> float:
        """Subset simulation: Au & Beck's squared coefficient of variation at ``value``."""
        level = self.level_index(value)
        exceeds = self._level(value) > value
        share = float(np.mean(exceeds))
        if share == 0.0:
            return 0.0
        own = (1.0 - share) / (self.sample_size * share) * (1.0 + chain_correlation_factor(exceeds))
        return float(sum(self.level_terms[:level])) + own


@dataclass(frozen=True)
class TailEstimate:
    """A tail estimate: a quantile or an exceedance probability, with 95 % intervals.

    Attributes
    ----------
    method
        ``"brute"``, ``"subset"`` or ``"is"``.
    target
        What was given: ``"probability"`` (the quantile was estimated) or ``"threshold"`` (the
        exceedance probability was estimated).
    probability
        The probability asked for, or the estimated exceedance probability of :attr:`threshold`.
    probability_ci95
        95 % interval of the exceedance probability of :attr:`threshold`.
    threshold
        The response value: the estimated quantile, or the threshold given.
    threshold_ci95
        95 % interval of the quantile; ``(threshold, threshold)`` for a given threshold.
    model_evaluations
        Response rows evaluated.
    seconds
        Wall time of the estimate.
    coefficient_of_variation
        Estimated coefficient of variation of the probability estimate at :attr:`threshold`.
    levels
        Intermediate thresholds of subset simulation or of the cross-entropy levels; empty for
        brute force.
    diagnostics
        Method-specific figures (JSON-ready): exceedance counts, acceptance rates and correlation
        factors per level, importance-density means, effective sample sizes.
    tail
        The estimate as a weighted sample (:class:`WeightedTail`): the CCDF and its variance at
        any threshold. Not part of :meth:`as_dict`, and not compared by ``==``.
    """

    method: str
    target: str
    probability: float
    probability_ci95: tuple[float, float]
    threshold: float
    threshold_ci95: tuple[float, float]
    model_evaluations: int
    seconds: float
    coefficient_of_variation: float
    levels: tuple[float, ...] = ()
    diagnostics: dict[str, Any] = field(default_factory=dict)
    tail: WeightedTail | None = field(default=None, compare=False, repr=False)

    def as_dict(self) -> dict[str, Any]:
        """The fields the command line writes, JSON-ready (non-finite numbers become None).

        ``braking_distance_m`` is :attr:`threshold` and ``ci95_m`` is :attr:`threshold_ci95`: the
        library is generic, but its one user's response is a braking distance in metres, and its
        output files keep these names. ``threshold`` is :attr:`threshold` too, under its generic
        name.
        """
        return {
            "probability": json_number(self.probability),
            "braking_distance_m": json_number(self.threshold),
            "ci95_m": [json_number(value) for value in self.threshold_ci95],
            "model_evaluations": self.model_evaluations,
            "method": self.method,
            "seconds": self.seconds,
            "probability_ci95": [json_number(value) for value in self.probability_ci95],
            "threshold": json_number(self.threshold),
        }


def lognormal_interval(probability: float, coefficient_of_variation: float) -> tuple[float, float]:
    """The log-normal 95 % interval ``P * exp(-+1.96 s)``, ``s = sqrt(log(1 + delta**2))`` (see the module's notes)."""
    spread = Z95 * math.sqrt(math.log1p(coefficient_of_variation**2))
    return probability * math.exp(-spread), probability * math.exp(spread)


def ccdf_quantiles(values: np.ndarray, weights: np.ndarray | None, probabilities: np.ndarray) -> np.ndarray:
    """The responses at which the sample's CCDF (mid-jump plotting positions, see the module's
    notes) takes the given probabilities; +inf above the largest sample's position, -inf below the
    smallest's. ``weights`` None: equal weights."""
    order = np.argsort(values, kind="stable")[::-1]
    descending = values[order]
    if weights is None:
        positions = (np.arange(len(values)) + 0.5) / len(values)
    else:
        shares = weights[order] / len(values)
        positions = np.cumsum(shares) - shares / 2
    probabilities = np.asarray(probabilities, dtype=np.float64)
    quantiles = np.interp(probabilities, positions, descending)
    quantiles[probabilities < positions[0]] = np.inf
    quantiles[probabilities > positions[-1]] = -np.inf
    return quantiles


def chain_correlation_factor(exceeds: np.ndarray) -> float:
    """Au & Beck's (2001) ``gamma`` of exceedance indicators of shape (chain_length, chains):
    ``2 sum_k (1 - k / N_s) R(k) / R(0)`` with ``R(k)`` the lag-``k`` covariance pooled over
    chains. 0 for independent samples (one state per chain) or constant indicators."""
    chain_length, chains = exceeds.shape
    share = float(np.mean(exceeds))
    variance = share * (1.0 - share)
    if chain_length == 1 or variance == 0.0:
        return 0.0
    indicators = exceeds.astype(np.float64)
    gamma = 0.0
    for lag in range(1, chain_length):
        products = float(np.sum(indicators[:-lag] * indicators[lag:])) / ((chain_length - lag) * chains)
        gamma += (1.0 - lag / chain_length) * (products - share**2) / variance
    return 2.0 * gamma


def json_number(value: float) -> float | None:
    """The number for a JSON file: ``value`` as a float, None where it is not finite."""
    return float(value) if math.isfinite(value) else None


def _like(result: np.ndarray, points: np.ndarray) -> float | np.ndarray:
    """A float for a scalar argument, else the array."""
    return result if points.ndim else float(result)
