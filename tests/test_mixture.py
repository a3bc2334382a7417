"""Weighted tails (brakegym.reliability.WeightedTail) and tails of mixtures (mixture_tail) on
responses whose tails are known exactly.

The mixture is the one of a train's 16 disc units failing independently with probability
``q = 1e-3``: component ``k`` (``k`` units failed) has the weight ``Binomial(k; 16, q)`` and the
response ``2 k + s_k . u`` (``|s_k| = 1``, a direction per component), a standard normal shifted by
two standard deviations per failed unit, so that ``P(D > d) = sum_k pi_k Phi(2 k - d)``. Only
``k = 0..4`` are modelled (``P(k >= 5) = 4.3e-12`` is not); the exact values are those of all 17
components, so the bound on the unmodelled mass is part of what the intervals must cover. The seed
(1, as in test_reliability.py) was fixed before the results were seen; the intervals are checked
as they come out, nothing widened.
"""

from __future__ import annotations

import math
import pickle
from collections.abc import Callable

import numpy as np
import pytest
from scipy import optimize, stats

from brakegym.reliability import (
    TailEstimate,
    WeightedTail,
    importance_sampling,
    mixture_tail,
    subset_simulation,
)

SEED = 1
DIMS = 30
UNITS, FAILURE = 16, 1e-3
SHIFT = 2.0


class Linear:
    """``shift + s . u`` with ``|s| = 1``, summed a column at a time (a matrix product may round a
    row differently in batches of other sizes); counts its rows and refuses batches larger than
    ``batch_size``."""

    def __init__(self, shift: float, direction: np.ndarray, batch_size: int = 4096) -> None:
        self.shift, self.direction, self.batch_size, self.rows = shift, direction, batch_size, 0

    def __call__(self, u: np.ndarray) -> np.ndarray:
        assert u.ndim == 2 and 1 <= len(u) <= self.batch_size, f"called with {u.shape}, batch {self.batch_size}"
        self.rows += len(u)
        total = np.full(len(u), self.shift)
        for column, component in zip(u.T, self.direction):
            total += column * component
        return total


def direction(dims: int, k: int) -> np.ndarray:
    values = np.cos(0.7 * (k + 1) * np.arange(dims) + k) + 1.5
    return values / np.linalg.norm(values)


def components(modelled: int = 5, batch_size: int = 4096, renormalise: bool = False) -> list[tuple[float, Linear]]:
    weights = stats.binom.pmf(np.arange(modelled), UNITS, FAILURE)
    if renormalise:
        weights = weights / weights.sum()
    return [(float(weights[k]), Linear(SHIFT * k, direction(DIMS, k), batch_size)) for k in range(modelled)]


def exact_exceedance(d: float, modelled: int = UNITS + 1, renormalise: bool = False) -> float:
    weights = stats.binom.pmf(np.arange(modelled), UNITS, FAILURE)
    if renormalise:
        weights = weights / weights.sum()
    return float(np.sum(weights * stats.norm.sf(d - SHIFT * np.arange(modelled))))


def exact_quantile(p: float, **options) -> float:
    return optimize.brentq(lambda d: exact_exceedance(d, **options) - p, -10.0, 60.0, xtol=1e-13)


def covers(interval: tuple[float, float], value: float) -> bool:
    return interval[0] <= value <= interval[1]


def linear(dims: int) -> Callable[[np.ndarray], np.ndarray]:
    return Linear(0.0, np.linspace(1.0, 2.0, dims) / np.linalg.norm(np.linspace(1.0, 2.0, dims)))


# --- weighted tails of mixtures -------------------------------------------------------------------------


def test_weighted_tails_pickle_and_stay_read_only():
    estimate = mixture_tail(components(), DIMS, SEED, "subset", probability=1e-5)
    copy = pickle.loads(pickle.dumps(estimate))
    points = np.linspace(4.0, 7.0, 7)
    assert np.array_equal(copy.tail.exceedance(points), estimate.tail.exceedance(points))
    assert np.array_equal(copy.tail.variance(points), estimate.tail.variance(points))
    assert copy.as_dict() == estimate.as_dict() and copy.diagnostics == estimate.diagnostics
    with pytest.raises(ValueError, match="read-only"):
        estimate.tail.weights[0] = 1.0
    assert "tail" not in estimate.as_dict()


# --- mixtures with exact tails --------------------------------------------------------------------------


@pytest.mark.parametrize("method", ["subset", "is"])
@pytest.mark.parametrize("probability", [1e-3, 1e-5, 1e-9])
def test_mixture_quantile_and_exceedance_cover_the_exact_values(method, probability):
    exact = exact_quantile(probability)
    quantile = mixture_tail(components(), DIMS, SEED, method, probability=probability)
    assert quantile.method == method and quantile.target == "probability" and quantile.probability == probability
    assert covers(quantile.threshold_ci95, exact), quantile
    assert covers(quantile.threshold_ci95, quantile.threshold)
    # The combined weighted sample's CCDF at the quantile is the probability (interpolated, so nearly).
    assert quantile.tail.exceedance(quantile.threshold) == pytest.approx(probability, rel=0.05)
    exceedance = mixture_tail(components(), DIMS, SEED, method, threshold=exact)
    assert exceedance.target == "threshold" and exceedance.threshold_ci95 == (exact, exact)
    assert covers(exceedance.probability_ci95, probability), exceedance
    assert exceedance.probability == pytest.approx(exceedance.tail.exceedance(exact), rel=1e-12)


def test_brute_force_mixture_at_1e_3():
    exact = exact_quantile(1e-3)
    estimate = mixture_tail(components(), DIMS, SEED, "brute", probability=1e-3, n_samples=100_000)
    assert covers(estimate.threshold_ci95, exact), estimate
    statuses = {line["component"]: line["status"] for line in estimate.diagnostics["components"]}
    assert statuses[1] == "estimated"


def test_mixture_at_1e_9_estimates_the_components_that_matter_and_bounds_the_others():
    """At 1e-9 the answer comes from three and four failed units (shares 0.69, 0.28); the intact
    train contributes about 1e-10 of it and is only bounded, after the pilot."""
    mixture = components()
    estimate = mixture_tail(mixture, DIMS, SEED, "subset", threshold=exact_quantile(1e-9))
    lines = {line["component"]: line for line in estimate.diagnostics["components"]}
    assert lines[0]["status"] == "bounded" and lines[3]["status"] == "estimated"
    bounded = [line for line in lines.values() if line["status"] in ("bounded", "skipped")]
    assert all(line["bound"] <= 1e-3 * estimate.probability for line in bounded)
    # The intervals' upper end holds the bounds and the unmodelled mass.
    unmodelled = 1.0 - sum(weight for weight, _ in mixture)
    assert estimate.diagnostics["unmodelled_weight"] == pytest.approx(unmodelled, rel=1e-6)
    assert estimate.diagnostics["bound"] == pytest.approx(unmodelled + sum(line["bound"] for line in bounded))
    spread = estimate.probability_ci95[0] / estimate.probability
    assert estimate.probability_ci95[1] == pytest.approx(estimate.probability / spread + estimate.diagnostics["bound"])
    # Every row evaluated is counted, the pilot's and the final runs'.
    assert estimate.model_evaluations == sum(response.rows for _, response in mixture)
    assert estimate.model_evaluations == sum(line["evaluations"] for line in lines.values())
    assert sum(line.get("contribution", 0.0) for line in lines.values()) == pytest.approx(estimate.probability)


def test_renormalised_mixture_has_no_unmodelled_mass():
    exact = exact_quantile(1e-5, modelled=5, renormalise=True)
    estimate = mixture_tail(components(renormalise=True), DIMS, SEED, "subset", probability=1e-5)
    assert estimate.diagnostics["unmodelled_weight"] == 0.0
    assert covers(estimate.threshold_ci95, exact), estimate


def test_unmodelled_mass_above_the_probability_leaves_the_quantile_unbounded_above():
    """Modelling k = 0..3 only leaves P(k >= 4) = 1.8e-9 unmodelled, more than p = 1e-9: the
    quantile could lie anywhere above, and its interval says so."""
    exact = exact_quantile(1e-9)
    estimate = mixture_tail(components(modelled=4), DIMS, SEED, "subset", probability=1e-9)
    assert estimate.diagnostics["unmodelled_weight"] == pytest.approx(1.8e-9, rel=0.01)
    assert estimate.threshold_ci95[1] == math.inf and estimate.threshold_ci95[0] <= exact
    assert estimate.probability_ci95[1] > 1.8e-9
    assert estimate.as_dict()["ci95_m"][1] is None


def test_mixture_does_not_depend_on_the_batch_size():
    def run(batch_size: int, **options) -> TailEstimate:
        return mixture_tail(
            components(batch_size=batch_size), DIMS, SEED, "is", probability=1e-5, batch_size=batch_size, **options
        )

    first, second = run(4096), run(150)
    assert {**first.as_dict(), "seconds": 0} == {**second.as_dict(), "seconds": 0}
    assert first.diagnostics == second.diagnostics
    other = mixture_tail(components(), DIMS, SEED + 1, "is", probability=1e-5)
    assert other.threshold != first.threshold


def test_a_mixture_of_one_component_is_that_components_tail():
    estimate = mixture_tail([(1.0, linear(10))], 10, SEED, "subset", probability=1e-5)
    assert covers(estimate.threshold_ci95, stats.norm.isf(1e-5)), estimate
    assert estimate.diagnostics["bound"] == 0.0


def test_weighted_tail_mixture_sums_its_parts():
    first = subset_simulation(linear(10), 10, SEED, threshold=3.0).tail
    second = importance_sampling(linear(10), 10, SEED, threshold=3.0).tail
    mixture = WeightedTail.mixture((first, second), (0.3, 0.5))
    points = np.array([2.5, 3.0, 3.5])
    assert np.allclose(mixture.exceedance(points), 0.3 * first.exceedance(points) + 0.5 * second.exceedance(points))
    assert np.allclose(mixture.variance(points), 0.09 * first.variance(points) + 0.25 * second.variance(points))
    assert mixture.weights.sum() == pytest.approx(0.3 * first.weights.sum() + 0.5 * second.weights.sum())


# --- refusals ----------------------------------------------------------------------------------------------


def never(u: np.ndarray) -> np.ndarray:
    raise AssertionError("bad input must be refused before any evaluation")


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: mixture_tail([], 3, 0, "subset", probability=1e-3), "components is empty"),
        (lambda: mixture_tail(None, 3, 0, "subset", probability=1e-3), "need a sequence"),
        (lambda: mixture_tail([(-0.1, never)], 3, 0, "subset", probability=1e-3), r"weight -0.1"),
        (lambda: mixture_tail([(math.nan, never)], 3, 0, "subset", probability=1e-3), "weight nan"),
        (lambda: mixture_tail([(0.7, never), (0.4, never)], 3, 0, "subset", threshold=1.0), "sum to 1.1"),
        (lambda: mixture_tail([(0.0, never)], 3, 0, "subset", threshold=1.0), "all zero"),
        (lambda: mixture_tail([never], 3, 0, "subset", threshold=1.0), r"components\[0\]"),
        (lambda: mixture_tail([(1.0, "linear")], 3, 0, "subset", threshold=1.0), "need a callable"),
        (lambda: mixture_tail([(1.0, never)], 3, 0, "mcmc", threshold=1.0), "method = 'mcmc'"),
        (lambda: mixture_tail([(1.0, never)], 3, 0, "subset"), "give exactly one"),
        (lambda: mixture_tail([(1.0, never)], 3, 0, "subset", probability=0.1, threshold=1.0), "give exactly one"),
        (lambda: mixture_tail([(0.5, never)], 3, 0, "subset", probability=0.6), "not below the components' total"),
        (lambda: mixture_tail([(1.0, never)], 3, 0, "brute", threshold=1.0), "needs n_samples"),
        (lambda: mixture_tail([(1.0, never)], 3, 0, "is", threshold=1.0, n_samples=10), r"\['n_samples'\]"),
        (lambda: mixture_tail([(1.0, never)], 3, 0, "subset", threshold=1.0, n_per_level=2005), "n_per_level = 2005"),
        (lambda: mixture_tail([(1.0, never)], 3, 0, "is", threshold=1.0, n_final=1), "n_final = 1"),
        (lambda: mixture_tail([(1.0, never)], 3, 0, "is", threshold=1.0, batch_size=0), "batch_size = 0"),
        (lambda: mixture_tail([(1.0, never)], 3, 0, "subset", threshold=1.0, negligible=1.0), "negligible = 1.0"),
        (lambda: mixture_tail([(1.0, never)], 3, 0, "subset", threshold=1.0, pilot_per_level=105), "pilot_per_level"),
        (lambda: mixture_tail([(1.0, never)], 0, 0, "subset", threshold=1.0), "dims = 0"),
        (lambda: mixture_tail([(1.0, never)], 3, -1, "subset", threshold=1.0), "seed = -1"),
    ],
)
def test_bad_input_is_refused(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_a_threshold_no_component_reaches_is_a_runtime_error():
    def bounded(u: np.ndarray) -> np.ndarray:
        return np.tanh(u[:, 0])

    with pytest.raises(RuntimeError, match="no component resolves the threshold"):
        mixture_tail([(0.5, bounded), (0.5, bounded)], 2, SEED, "subset", threshold=1.5)


def test_a_failed_final_run_leaves_the_pilots_estimate():
    """Importance sampling cannot follow |u1| > b (two symmetric regions) and stops; the pilot's
    subset simulation can, and its estimate stands, with a note."""
    threshold = stats.norm.isf(5e-6)
    estimate = mixture_tail([(1.0, lambda u: np.abs(u[:, 0]))], 10, SEED, "is", threshold=threshold)
    (line,) = estimate.diagnostics["components"]
    assert line["status"] == "pilot" and "cross entropy stalled" in line["note"]
    assert covers(estimate.probability_ci95, 1e-5), estimate
    assert estimate.model_evaluations == line["evaluations"] > estimate.diagnostics["pilot_evaluations"]
