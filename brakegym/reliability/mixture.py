"""Tails of mixtures: ``P(Y > d) = sum_k pi_k P(Y_k > d)`` from an estimate per component.

A response with a discrete input is a mixture over that input's values: the braking distance with
``k`` of the train's disc units failed is one continuous response ``Y_k`` of the standard normals,
and ``k`` has the probability ``pi_k`` (binomial for units failing independently). Conditioned on
``k``, each component is an ordinary single-region problem for the estimators, where the whole
response, a union of separate exceedance regions (which units failed), is not: importance sampling
with one Gaussian settles on one region. By the law of total probability the mixture's
exceedance probability is ``P(d) = sum_k pi_k P_k(d)``; the components are estimated by
independent runs, so the variance is ``sum_k pi_k**2 Var_k(d)`` (stratified sampling, e.g.
Cochran 1977, *Sampling Techniques*, 3rd ed., Wiley, ch. 5). Each run's estimate is a
:class:`~brakegym.reliability.results.WeightedTail`, a weighted sample that gives ``P_k`` and
``Var_k`` at any ``d``.

The components' tails differ by many orders of magnitude (with 16 units failing at ``q = 1e-3``
and each failed unit shifting the distance by two of its standard deviations, at ``p = 1e-9`` the
answer comes from three and four failed units, and the intact train contributes about ``1e-10`` of
it), so :func:`mixture_tail` does not estimate every ``P_k(d)``: a component whose
contribution is below ``negligible`` times the answer is only bounded, and the bound widens the
upper end of the intervals. How it finds which components matter:

1. *Pilot.* Each component gets a subset simulation (Au & Beck 2001) of ``pilot_per_level``
   samples per level (``p0 = 0.1``), deepened one level at a time, best first: always the
   component with the largest 95 % upper bound ``pi_k U_k`` on its contribution at the current
   estimate. With a threshold ``d`` given, the estimate is ``d``; with a probability ``p``, it is
   the quantile of the pilot's combined CCDF at ``p``, with an interval ``[d_lo, d_hi]`` from its
   variance. A component is *resolved* once the level holding ``d_hi`` has at least ``N p0``
   samples above it (subset simulation's own stopping rule), and *bounded* once
   ``pi_k U_k(d_lo) <= negligible * P`` (``P``: ``p``, or the resolved components' sum at
   ``d``). A component not yet sampled has ``U_k = 1``: one of weight at most ``negligible * P``
   is *skipped*, its weight the bound. One bounded for lack of levels (20) is *unreached*, its
   bound however large. ``U_k(d)`` at level ``j`` holding ``d`` is ``p0**j`` times the
   Clopper-Pearson upper end of the level's fraction above ``d``, times
   ``exp(1.96 s)`` for the uncertainty of ``p0**j`` (``s`` from the completed levels' terms).
2. *Final runs.* Resolved components are estimated again with the chosen method and settings,
   at the threshold ``d`` (at ``d_lo`` for brute force, whose sample resolves only upwards), with
   the seed ``derived_seed(seed, 5, k)``, as far as that pays. First the component with the
   largest Neyman index ``pi_k sigma_k / sqrt(c_k)`` (the optimal allocation of samples to
   strata goes as it: Neyman 1934, "On the two different aspects of the representative method",
   Journal of the Royal Statistical Society 97, 558-625; ``sigma_k**2`` the pilot's variance,
   ``c_k = 1 + (1 - p0) j_k`` the evaluations per sample of ``j_k`` levels). Its final run shows
   by how much the method reduces a pilot's variance ``V_k``, by the factor ``g``, for ``E``
   evaluations, that is ``V / E`` per evaluation (``V`` the final variance). Each further
   component, in the order of the index, is run when it removes at least as much variance per
   evaluation: ``V_k (1 - g) / (E c_k / c_top) >= V / E`` (for brute force,
   ``pi_k**2 P_k (1 - P_k) / n`` replaces ``g V_k`` and ``E`` is the cost); the others keep
   their pilot estimates. The rule adapts to the method: importance sampling, far more precise per
   evaluation than subset simulation on these responses, re-runs more components. Whatever the
   cost, the pilot estimates kept may carry at most a quarter of the combined variance (the one with
   the largest variance is run again until they do): the pilot's subset simulations of few samples
   per level are biased by ``O(1 / N)`` and their coefficients of variation leave out the levels'
   correlation, which must not show next to a precise final run. A final run that fails (a
   RuntimeError) leaves the pilot's estimate, with a note.
3. *Estimate.* The estimated components' tails combine into one weighted sample. With a
   threshold, ``P(d)`` and its variance are the sums above. With a probability, the quantile is
   read off the combined CCDF at ``p`` (mid-jump plotting positions, as in :mod:`.results`).
   A component whose sample has fewer than 10 samples above the answer (or, for brute force,
   does not reach down to it) does not resolve it: it is moved to the bounded ones (status
   ``"unresolved"``) and the answer recomputed without it.

Intervals as in :mod:`.results`, log-normal with ``s = sqrt(log(1 + delta**2))`` from the
combined coefficient of variation, with the bound ``B`` (the unmodelled weight ``1 - sum pi_k``,
plus the skipped components' weights, plus ``pi_k U_k`` of the bounded ones at the answer) added
to the upper end: probability ``(P exp(-1.96 s), P exp(1.96 s) + B)``, quantile from the
combined CCDF's crossings of ``p exp(1.96 s)`` and ``p exp(-1.96 s) - B`` (infinite when the
latter is not positive). The components' CCDFs are estimated independently, but the components
kept from the pilot and the answer itself are chosen from the pilot's samples, a selection that
the variance leaves out.
"""

from __future__ import annotations

import inspect
import math
import numbers
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from scipy import stats

from .checks import check_integer, check_target
from .importance import importance_sampling, importance_settings
from .montecarlo import brute_force
from .response import CountedResponse, Response
from .results import Z95, TailEstimate, WeightedTail, json_number
from .streams import derived_seed
from .subset import SubsetRun, subset_layout, subset_simulation

_ESTIMATORS: dict[str, Callable[..., TailEstimate]] = {
    "brute": brute_force,
    "subset": subset_simulation,
    "is": importance_sampling,
}
# Arguments of the estimators that mixture_tail sets itself.
_FIXED_ARGUMENTS = {"response", "dims", "seed", "probability", "threshold"}
# Stream numbers under the user's seed (derived_seed(seed, stream, component)); the estimators use 1 to 3.
_PILOT_STREAM = 4
_FINAL_STREAM = 5
_PILOT_LEVEL_PROBABILITY = 0.1
_PILOT_MAX_LEVELS = 20
# The largest share of the combined variance that the pilot's estimates kept may carry.
_KEPT_VARIANCE_SHARE = 0.25
# Fewer samples than this above the answer do not resolve a component's CCDF there.
_MIN_EXCEEDANCES = 10
# Rounding allowance of "the weights sum to at most 1" (binomial probabilities sum to 1 +- 1e-16).
_WEIGHT_TOLERANCE = 1e-9


def mixture_tail(
    components: Sequence[tuple[float, Response]],
    dims: int,
    seed: int,
    method: str,
    probability: float | None = None,
    threshold: float | None = None,
    negligible: float = 1e-3,
    pilot_per_level: int = 500,
    **settings: Any,
) -> TailEstimate:
    """The tail of the mixture ``sum_k pi_k Y_k``: a quantile or an exceedance probability with
    95 % intervals, from independent estimates per component (see the module's notes).

    Measured over 300 repetitions (``benchmarks/mixture_coverage.py``) on the mixture of ``k = 0..4``
    of 16 units failed at ``q = 1e-3`` with the linear responses ``2 k + s_k . u`` in 30
    dimensions, the exact values those of all 17 components: the 95 % intervals (of the quantile; of
    the probability at the exact quantile) held them in 92.7 % and 92.3 % of the runs with subset
    simulation at 1e-3, 94.3 % and 94.3 % at 1e-5, 94.0 % and 93.0 % at 1e-9, and with importance
    sampling in 95.3 % and 96.7 %, 94.3 % and 94.7 %, 94.3 % and 93.7 %. A quantile took on
    average 13,500, 18,700 and 22,000 evaluations with subset simulation (of which the pilot's
    3,600, 7,500 and 15,900), 17,600, 21,500 and 30,200 with importance sampling. With
    ``pilot_per_level = 200`` subset simulation took 11,600, 14,500 and 14,800 evaluations, and its
    intervals held the exact quantile in 91 %, 94 % and 92 % of the runs.

    Parameters
    ----------
    components
        Pairs ``(pi_k, response_k)``: the component's probability (non-negative, summing to at
        most 1; the rest is not modelled and only widens the intervals' upper ends) and its
        response on ``(n, dims)`` standard normals, as for the estimators.
    dims
        Number of standard-normal inputs of every component's response.
    seed
        The seed; component ``k``'s pilot runs on ``derived_seed(seed, 4, k)``, its final run on
        ``derived_seed(seed, 5, k)``.
    method
        The estimator of the final runs: ``"brute"`` (:func:`~.montecarlo.brute_force`, needs
        ``n_samples``), ``"subset"`` (:func:`~.subset.subset_simulation`) or ``"is"``
        (:func:`~.importance.importance_sampling`).
    probability, threshold
        Exactly one: the exceedance probability whose quantile to estimate, or the threshold whose
        exceedance probability to estimate.
    negligible
        The share of the answer below which a component's contribution is bounded instead of
        estimated, in (0, 1).
    pilot_per_level
        Samples per level of the pilot's subset simulations; a multiple of 10, at least 20.
    **settings
        Passed to the estimator of the final runs (``n_samples``, ``n_per_level``, ``n_final``,
        ``level_probability``, ``max_levels``, ``batch_size``); ``batch_size`` serves the pilot too.

    Returns
    -------
    TailEstimate
        :attr:`~.results.TailEstimate.method` is ``method``; ``model_evaluations`` counts the
        pilot's and the final runs' rows of all components; ``levels`` is empty;
        ``diagnostics`` has per component (``"components"``) its weight, status (``"estimated"``
        by a final run, ``"pilot"``: estimated by the pilot, ``"bounded"``, ``"unreached"``,
        ``"skipped"``, ``"unresolved"``), conditional probability, contribution, bound,
        coefficient of variation, samples above the answer and evaluations, and
        ``"unmodelled_weight"``, ``"bound"`` (the upper ends' addition) and the pilot's figures;
        ``tail`` is the estimated components' combined :class:`~.results.WeightedTail`.

    Raises
    ------
    RuntimeError
        When no component resolves the answer (every one bounded, unreached or unresolved).
    """
    start = time.perf_counter()
    check_target(probability, threshold)
    options = _check_settings(method, settings)
    if not (isinstance(negligible, numbers.Real) and 0.0 < negligible < 1.0):
        raise ValueError(f"negligible = {negligible!r}: need a number in the open interval (0, 1)")
    if not (isinstance(pilot_per_level, numbers.Integral) and pilot_per_level >= 20 and pilot_per_level % 10 == 0):
        raise ValueError(f"pilot_per_level = {pilot_per_level!r}: need a multiple of 10, at least 20")
    derived_seed(seed)  # checks the seed before any evaluation
    parts = _check_components(components, dims, options["batch_size"])
    total_weight = math.fsum(part.weight for part in parts)
    if probability is not None and probability >= total_weight:
        raise ValueError(
            f"probability = {probability} is not below the components' total weight {total_weight}: the quantile "
            f"would lie in the unmodelled mass"
        )
    pilot = _Pilot(parts, seed, probability, threshold, negligible, pilot_per_level)
    low, centre, _ = pilot.run()
    # Brute force's sample resolves the CCDF only above its threshold: run it from the interval's lower end.
    at = low if method == "brute" and math.isfinite(low) else centre
    _final_runs(parts, method, settings, dims, seed, at)
    return _estimate(parts, method, probability, threshold, negligible, max(0.0, 1.0 - total_weight), pilot, start)


class _Part:
    """A component's state: its pilot (a subset simulation run level by level), its final run, its
    status and its bound."""

    def __init__(self, index: int, weight: float, response: Response, dims: int, batch_size: int) -> None:
        self.index, self.weight, self.response = index, weight, response
        self.counted = CountedResponse(response, dims, batch_size)
        self.run: SubsetRun | None = None
        self.pilot: WeightedTail | None = None
        self.final: TailEstimate | None = None
        self.final_evaluations, self.attempted = 0, False
        self.pilot_variance = self.final_variance = self.cost = math.nan
        self.note = ""
        self.status = "pending"

    @property
    def tail(self) -> WeightedTail:
        """The estimate: the final run's, else the pilot's."""
        return self.final.tail if self.final is not None else self.pilot

    def bound(self, d: float) -> float:
        """``pi_k U_k(d)``: the 95 % upper bound on the contribution at ``d`` (the weight when
        never sampled)."""
        return self.weight if self.pilot is None else self.weight * _upper_bound(self.pilot, d)


class _Pilot:
    """The pilot pass: subset simulations of the components, deepened best first until each is
    resolved or bounded at the estimate (see the module's notes)."""

    def __init__(
        self,
        parts: list[_Part],
        seed: int,
        probability: float | None,
        threshold: float | None,
        negligible: float,
        n_per_level: int,
    ) -> None:
        self.parts, self.seed, self.probability, self.threshold = parts, seed, probability, threshold
        self.negligible, self.n_per_level = negligible, n_per_level
        self.located = (math.nan, math.nan, math.nan)

    def run(self) -> tuple[float, float, float]:
        """Deepens the components until none needs a level; returns the estimate's
        ``(d_lo, d, d_hi)``."""
        for part in self.parts:
            if part.weight == 0.0:
                part.status = "skipped"
        active = [part for part in self.parts if part.status != "skipped"]
        while True:
            low, centre, high = self.located = self._locate(active)
            scale = self.probability
            if scale is None:
                scale = sum(
                    part.weight * part.pilot.exceedance(centre)
                    for part in active
                    if part.pilot is not None and _resolves(part.pilot, centre)
                )
            needs = []
            for part in active:
                if part.pilot is not None and _resolves(part.pilot, high):
                    part.status = "resolved"
                    continue
                if part.bound(low) <= self.negligible * scale:
                    part.status = "skipped" if part.pilot is None else "bounded"
                elif part.run is not None and part.run.depth >= _PILOT_MAX_LEVELS:
                    part.status = "unreached"
                else:
                    part.status = "pending"
                    needs.append(part)
            if not needs:
                return self.located
            chosen = max(needs, key=lambda part: part.bound(centre))
            if chosen.run is None:
                stream = derived_seed(self.seed, _PILOT_STREAM, chosen.index)
                chosen.run = SubsetRun(chosen.counted, stream, self.n_per_level, _PILOT_LEVEL_PROBABILITY)
            else:
                chosen.run.advance()
            chosen.pilot = chosen.run.tail()

    def _locate(self, active: list[_Part]) -> tuple[float, float, float]:
        """The estimate and its interval from the pilot's samples so far: the threshold, or the
        combined CCDF's quantile at ``p`` with its crossings of ``p exp(-+1.96 s)`` (``+inf``
        while the samples do not reach ``p``)."""
        if self.threshold is not None:
            return (float(self.threshold),) * 3
        sampled = [part for part in active if part.pilot is not None]
        if not sampled:
            return (math.inf,) * 3
        tails, weights = [part.pilot for part in sampled], [part.weight for part in sampled]
        centre = float(_quantiles(tails, weights, [self.probability])[0])
        if not math.isfinite(centre):
            return (centre,) * 3
        spread = Z95 * _log_spread(tails, weights, centre)
        ends = [self.probability * math.exp(spread), self.probability * math.exp(-spread)]
        low, high = _quantiles(tails, weights, ends)
        return float(low), centre, float(high)


def _final_runs(
    parts: list[_Part],
    method: str,
    settings: dict[str, Any],
    dims: int,
    seed: int,
    threshold: float,
) -> None:
    """Runs the chosen estimator at ``threshold`` for the resolved components worth it (see the
    module's notes); the others keep their pilot estimates."""
    resolved = [part for part in parts if part.status == "resolved"]
    for part in resolved:
        part.status = "pilot"
        part.pilot_variance = part.weight**2 * float(part.pilot.variance(threshold))
        part.cost = 1.0 + (1.0 - _PILOT_LEVEL_PROBABILITY) * part.pilot.level_index(threshold)
    # Neyman's allocation index: the evaluations a stratum deserves go as pi_k sigma_k / sqrt(cost per sample).
    resolved.sort(key=lambda part: -math.sqrt(part.pilot_variance / part.cost))
    reference = None
    for part in resolved:
        if reference is not None:
            top, gain = reference
            cost = top.final_evaluations * (1.0 if method == "brute" else part.cost / top.cost)
            if method == "brute":
                conditional = float(part.pilot.exceedance(threshold))
                predicted = part.weight**2 * conditional * (1.0 - conditional) / settings["n_samples"]
            else:
                predicted = part.pilot_variance * gain
            removed_per_evaluation = top.final_variance / top.final_evaluations
            if (part.pilot_variance - predicted) / cost < removed_per_evaluation:
                continue
        _final_run(part, method, settings, dims, seed, threshold)
        if part.final is not None and reference is None:
            gain = part.final_variance / part.pilot_variance if part.pilot_variance > 0.0 else 1.0
            reference = (part, gain)
    # The pilot estimates kept carry at most a quarter of the variance; the largest is run again until they do.
    while True:
        kept = [part for part in resolved if part.status == "pilot" and not part.attempted]
        kept_variance = math.fsum(part.pilot_variance for part in kept)
        final_variance = math.fsum(part.final_variance for part in resolved if part.final is not None)
        if not kept or kept_variance <= _KEPT_VARIANCE_SHARE * (kept_variance + final_variance):
            return
        _final_run(max(kept, key=lambda part: part.pilot_variance), method, settings, dims, seed, threshold)


def _final_run(part: _Part, method: str, settings: dict[str, Any], dims: int, seed: int, threshold: float) -> None:
    """The chosen estimator on a component at ``threshold``, its rows counted even if it fails."""
    counted, part.attempted = _RowCounter(part.response), True
    try:
        part.final = _ESTIMATORS[method](
            counted, dims, derived_seed(seed, _FINAL_STREAM, part.index), threshold=threshold, **settings
        )
        part.final_variance = part.weight**2 * float(part.final.tail.variance(threshold))
        part.status = "estimated"
    except RuntimeError as error:
        part.note = f"final run failed ({error}); the pilot's estimate stands"
    part.final_evaluations = counted.rows


def _estimate(
    parts: list[_Part],
    method: str,
    probability: float | None,
    threshold: float | None,
    negligible: float,
    unmodelled: float,
    pilot: _Pilot,
    start: float,
) -> TailEstimate:
    """The combined estimate at the answer, after dropping the components that do not resolve it."""
    estimated, answer = _resolved_answer(parts, probability, threshold)
    tails, weights = [part.tail for part in estimated], [part.weight for part in estimated]
    bounds = {part.index: part.bound(answer) for part in parts if part.status not in ("estimated", "pilot")}
    bound = unmodelled + math.fsum(bounds.values())
    exceedance = math.fsum(w * tail.exceedance(answer) for tail, w in zip(tails, weights))
    variance = math.fsum(w**2 * tail.variance(answer) for tail, w in zip(tails, weights))
    cov = math.sqrt(variance) / exceedance
    centre = exceedance if probability is None else probability
    probability_ci95, threshold_ci95 = _intervals(tails, weights, centre, probability, threshold, cov, bound)
    pilot_evaluations = sum(part.counted.evaluations for part in parts)
    final_evaluations = sum(part.final_evaluations for part in parts)
    low, centre_pilot, high = pilot.located
    return TailEstimate(
        method=method,
        target="threshold" if probability is None else "probability",
        probability=float(centre),
        probability_ci95=probability_ci95,
        threshold=float(answer),
        threshold_ci95=threshold_ci95,
        model_evaluations=pilot_evaluations + final_evaluations,
        seconds=time.perf_counter() - start,
        coefficient_of_variation=cov,
        diagnostics={
            "components": [_describe(part, answer, bounds.get(part.index)) for part in parts],
            "unmodelled_weight": unmodelled,
            "bound": bound,
            "negligible": negligible,
            "pilot_threshold": json_number(centre_pilot),
            "pilot_interval": [json_number(low), json_number(high)],
            "pilot_evaluations": pilot_evaluations,
        },
        tail=WeightedTail.mixture(tuple(tails), tuple(weights)),
    )


def _resolved_answer(
    parts: list[_Part], probability: float | None, threshold: float | None
) -> tuple[list[_Part], float]:
    """The estimated components that resolve the answer, and the answer: the threshold, or the
    quantile of their combined CCDF at ``probability``. A component with fewer than 10 samples
    above the answer (or whose sample does not reach down to it) becomes ``"unresolved"``, and the
    answer is read again without it."""
    while True:
        estimated = [part for part in parts if part.status in ("estimated", "pilot")]
        if not estimated:
            raise RuntimeError(
                f"no component resolves the {'threshold' if probability is None else 'quantile'}: "
                + "; ".join(f"component {part.index} {part.status}" for part in parts)
            )
        tails, weights = [part.tail for part in estimated], [part.weight for part in estimated]
        answer = threshold if probability is None else float(_quantiles(tails, weights, [probability])[0])
        if not math.isfinite(answer):
            raise RuntimeError(f"the components' samples do not reach probability = {probability}")
        dropped = [
            part
            for part in estimated
            if answer < part.tail.resolved_from or part.tail.exceedance_count(answer) < _MIN_EXCEEDANCES
        ]
        if not dropped:
            return estimated, answer
        for part in dropped:
            reason = f"fewer than {_MIN_EXCEEDANCES} samples above {answer:.6g}"
            part.note = f"{part.note}; {reason}" if part.note else reason
            part.status = "unresolved"


def _intervals(
    tails: list[WeightedTail],
    weights: list[float],
    centre: float,
    probability: float | None,
    threshold: float | None,
    cov: float,
    bound: float,
) -> tuple[tuple[float, float], tuple[float, float]]:
    """The 95 % intervals of the probability and of the threshold: log-normal from the combined
    coefficient of variation ``cov``, the bound added to the upper ends (see the module's notes)."""
    spread = Z95 * math.sqrt(math.log1p(cov**2))
    probability_ci95 = (centre * math.exp(-spread), centre * math.exp(spread) + bound)
    if probability is None:
        return probability_ci95, (float(threshold), float(threshold))
    upper_target = probability * math.exp(-spread) - bound
    low = float(_quantiles(tails, weights, [probability * math.exp(spread)])[0])
    high = float(_quantiles(tails, weights, [upper_target])[0]) if upper_target > 0.0 else math.inf
    return probability_ci95, (low, high)


def _describe(part: _Part, answer: float, bound: float | None) -> dict[str, Any]:
    """A component's line of the diagnostics (JSON-ready)."""
    line: dict[str, Any] = {
        "component": part.index,
        "weight": part.weight,
        "status": part.status,
        "evaluations": part.counted.evaluations + part.final_evaluations,
        "pilot_levels": None if part.run is None else part.run.depth,
    }
    if bound is None:
        tail = part.tail
        conditional = float(tail.exceedance(answer))
        line.update(
            probability=conditional,
            contribution=part.weight * conditional,
            coefficient_of_variation=json_number(float(tail.coefficient_of_variation(answer))),
            exceedances=int(tail.exceedance_count(answer)),
            levels=[] if part.final is None else list(part.final.levels),
        )
    else:
        line["bound"] = bound
    if part.note:
        line["note"] = part.note
    return line


class _RowCounter:
    """A response that counts its rows, so that a final run that fails is counted too."""

    def __init__(self, response: Response) -> None:
        self.response, self.rows = response, 0

    def __call__(self, u: np.ndarray) -> np.ndarray:
        self.rows += len(u)
        return self.response(u)


def _resolves(tail: WeightedTail, d: float) -> bool:
    """Whether a pilot's subset-simulation sample resolves ``d``: at least ``N p0`` samples above
    it in the level that holds it."""
    return tail.exceedance_count(d) >= tail.chains


def _upper_bound(tail: WeightedTail, d: float) -> float:
    """A 95 % upper bound on ``P(Y > d)`` from a subset-simulation sample, also where it does not
    resolve ``d``: ``p0**j`` times the Clopper-Pearson upper end of level ``j``'s fraction above
    ``d``, times ``exp(1.96 s)`` for the completed levels' uncertainty."""
    level, n = tail.level_index(d), tail.sample_size
    above = int(tail.exceedance_count(d))
    fraction = 1.0 if above >= n else float(stats.beta.ppf(0.975, above + 1, n - above))
    spread = Z95 * math.sqrt(math.log1p(math.fsum(tail.level_terms[:level])))
    return min(1.0, tail.level_probability**level * fraction * math.exp(spread))


def _log_spread(tails: list[WeightedTail], weights: list[float], d: float) -> float:
    """``s = sqrt(log(1 + delta**2))`` of the combined estimate at ``d`` (infinite where it is zero)."""
    exceedance = math.fsum(w * tail.exceedance(d) for tail, w in zip(tails, weights))
    if not exceedance > 0.0:
        return math.inf
    variance = math.fsum(w**2 * tail.variance(d) for tail, w in zip(tails, weights))
    return math.sqrt(math.log1p(variance / exceedance**2))


def _quantiles(tails: list[WeightedTail], weights: list[float], probabilities: Sequence[float]) -> np.ndarray:
    """The responses at which the combined CCDF ``sum_k w_k CCDF_k`` takes the given
    probabilities, read off the combined weighted sample with mid-jump plotting positions;
    ``+inf`` above the largest sample's position, ``-inf`` below the smallest's or below where
    a part's sample resolves its CCDF."""
    responses = np.concatenate([tail.responses for tail in tails])
    masses = np.concatenate([w * tail.weights for tail, w in zip(tails, weights)])
    keep = masses > 0.0
    responses, masses = responses[keep], masses[keep]
    order = np.argsort(responses, kind="stable")[::-1]
    descending, masses = responses[order], masses[order]
    positions = np.cumsum(masses) - masses / 2
    probabilities = np.asarray(probabilities, dtype=np.float64)
    quantiles = np.interp(probabilities, positions, descending)
    quantiles[probabilities < positions[0]] = np.inf
    quantiles[probabilities > positions[-1]] = -np.inf
    quantiles[quantiles < max(tail.resolved_from for tail in tails)] = -np.inf
    return quantiles


def _check_settings(method: str, settings: dict[str, Any]) -> dict[str, Any]:
    """The chosen estimator's settings with its defaults, checked before any evaluation."""
    if method not in _ESTIMATORS:
        raise ValueError(f"method = {method!r}: need one of {', '.join(repr(name) for name in _ESTIMATORS)}")
    parameters = inspect.signature(_ESTIMATORS[method]).parameters
    known = [name for name in parameters if name not in _FIXED_ARGUMENTS]
    unknown = sorted(set(settings) - set(known))
    if unknown:
        raise ValueError(f"settings {unknown} are not settings of method {method!r}: it takes {known}")
    empty = inspect.Parameter.empty
    options = {name: parameters[name].default for name in known if parameters[name].default is not empty}
    options.update(settings)
    if method == "brute":
        if "n_samples" not in settings:
            raise ValueError("method 'brute' needs n_samples in the settings")
        check_integer("n_samples", options["n_samples"], 1)
    elif method == "subset":
        subset_layout(options["n_per_level"], options["level_probability"])
        check_integer("max_levels", options["max_levels"], 1)
    else:
        levels = options["level_probability"], options["max_levels"]
        importance_settings(options["n_per_level"], options["n_final"], *levels)
    check_integer("batch_size", options["batch_size"], 1)
    return options


def _check_components(components: Sequence[tuple[float, Response]], dims: int, batch_size: int) -> list[_Part]:
    """The components as parts, checked: pairs of a finite non-negative weight and a callable,
    weights summing to at most 1."""
    try:
        items = list(components)
    except TypeError:
        raise ValueError(f"components = {components!r}: need a sequence of (weight, response) pairs") from None
    if not items:
        raise ValueError("components is empty: need at least one (weight, response) pair")
    parts = []
    for index, item in enumerate(items):
        try:
            weight, response = item
        except (TypeError, ValueError):
            raise ValueError(f"components[{index}] = {item!r}: need a pair (weight, response)") from None
        if isinstance(weight, bool) or not isinstance(weight, numbers.Real) or not (0.0 <= weight < math.inf):
            raise ValueError(f"components[{index}] has weight {weight!r}: need a finite number >= 0")
        parts.append(_Part(index, float(weight), response, dims, batch_size))
    total = math.fsum(part.weight for part in parts)
    if total > 1.0 + _WEIGHT_TOLERANCE:
        raise ValueError(f"the components' weights sum to {total!r}: need at most 1 (they are probabilities)")
    if total == 0.0:
        raise ValueError("the components' weights are all zero: nothing to estimate")
    return parts
