"""Rare-event estimators (brakegym.reliability) on responses whose tails are known exactly.

Linear responses ``y = a.u / |a|`` are standard normal: ``P(y > b) = Phi(-b)``. The series system
``max(u1, u2)`` exceeds in two separate regions, ``P = 1 - (1 - Phi(-b))**2``; the parallel system
``min(u1, u2)`` in one corner, ``P = Phi(-b)**2``. Seeds were fixed before the results were seen
(1 for the estimates, 0 for the streams); the 95 % intervals are checked as they come out of the
estimators, nothing widened. Every response is wrapped so that a call with more rows than the
estimator's ``batch_size`` fails the test, and its rows are counted.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable

import numpy as np
import pytest
from scipy import stats

from brakegym.reliability import (
    TailEstimate,
    brute_force,
    derived_seed,
    importance_sampling,
    standard_normals,
    subset_simulation,
    uniforms,
)

SEED = 1
METHODS = {
    "brute": (brute_force, {"n_samples": 100_000}),
    "subset": (subset_simulation, {}),
    "is": (importance_sampling, {}),
}


class Guarded:
    """A response that fails when called with more rows than ``batch_size``, counting rows."""

    def __init__(self, response: Callable[[np.ndarray], np.ndarray], batch_size: int = 4096) -> None:
        self.response, self.batch_size, self.rows, self.calls = response, batch_size, 0, 0

    def __call__(self, u: np.ndarray) -> np.ndarray:
        assert u.ndim == 2 and 1 <= len(u) <= self.batch_size, f"called with {u.shape} rows, batch {self.batch_size}"
        self.rows += len(u)
        self.calls += 1
        return self.response(u)


def linear(dims: int) -> Callable[[np.ndarray], np.ndarray]:
    direction = np.linspace(1.0, 2.0, dims)
    direction /= np.linalg.norm(direction)

    def response(u: np.ndarray) -> np.ndarray:
        # A column at a time: a matrix product may round a row differently in batches of other sizes.
        total = np.zeros(len(u))
        for column, component in zip(u.T, direction):
            total += column * component
        return total

    return response


def series(u: np.ndarray) -> np.ndarray:
    return np.maximum(u[:, 0], u[:, 1])


def parallel(u: np.ndarray) -> np.ndarray:
    return np.minimum(u[:, 0], u[:, 1])


def covers(interval: tuple[float, float], value: float) -> bool:
    return interval[0] <= value <= interval[1]


# --- streams ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("draw", [uniforms, standard_normals])
def test_streams_do_not_depend_on_the_chunking(draw):
    whole = draw(0, np.arange(1000), 5)
    pieces = np.concatenate([draw(0, np.arange(start, min(start + 7, 1000)), 5) for start in range(0, 1000, 7)])
    assert np.array_equal(whole, pieces)
    shuffled = np.random.default_rng(0).permutation(1000)
    assert np.array_equal(draw(0, shuffled, 5), whole[shuffled])
    # A sample's first dimensions are the same whatever the number of dimensions.
    assert np.array_equal(draw(0, np.arange(1000), 12)[:, :5], whole)


def test_streams_of_different_seeds_are_independent():
    n = 20_000
    first, second = standard_normals(0, np.arange(n), 3), standard_normals(1, np.arange(n), 3)
    assert not np.any(first == second)
    correlations = [np.corrcoef(first[:, j], second[:, j])[0, 1] for j in range(3)]
    assert max(abs(r) for r in correlations) < 4 / math.sqrt(n)
    # Neighbouring samples and dimensions of one seed are uncorrelated too.
    assert abs(np.corrcoef(first[:-1, 0], first[1:, 0])[0, 1]) < 4 / math.sqrt(n)
    assert abs(np.corrcoef(first[:, 0], first[:, 1])[0, 1]) < 4 / math.sqrt(n)


def test_standard_normals_moments_and_kolmogorov_smirnov():
    values = standard_normals(0, np.arange(10_000), 10).ravel()
    n = values.size
    assert n == 100_000
    assert abs(values.mean()) < 4 / math.sqrt(n)
    assert abs(values.var() - 1) < 4 * math.sqrt(2 / n)
    assert abs(stats.skew(values)) < 4 * math.sqrt(6 / n)
    assert abs(stats.kurtosis(values)) < 4 * math.sqrt(24 / n)
    assert stats.kstest(values, "norm").pvalue > 1e-3
    assert stats.kstest(uniforms(0, np.arange(10_000), 10).ravel(), "uniform").pvalue > 1e-3


def test_uniforms_are_on_a_symmetric_lattice_inside_the_open_interval():
    values = uniforms(3, np.arange(100_000), 10)
    assert values.min() > 0 and values.max() < 1
    steps = values * 2.0**52 - 0.5
    assert np.array_equal(steps, np.round(steps))
    mirrored = (1 - values) * 2.0**52 - 0.5  # 1 - u is on the lattice too: the normals are symmetric
    assert np.array_equal(mirrored, np.round(mirrored))
    assert np.isfinite(standard_normals(3, np.arange(100_000), 10)).all()


def test_derived_seeds_make_other_streams():
    assert derived_seed(7, 1, 3) == derived_seed(7, 1, 3)
    seeds = {derived_seed(7), derived_seed(7, 1), derived_seed(7, 1, 3), derived_seed(7, 3, 1), derived_seed(8, 1, 3)}
    assert len(seeds) == 5 and all(0 <= s < 2**64 for s in seeds)
    assert not np.any(standard_normals(7, np.arange(100), 2) == standard_normals(derived_seed(7, 1), np.arange(100), 2))


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: uniforms(-1, np.arange(3), 2), "seed = -1"),
        (lambda: uniforms(2**64, np.arange(3), 2), "seed = 18446744073709551616"),
        (lambda: uniforms(1.5, np.arange(3), 2), "seed = 1.5"),
        (lambda: uniforms(True, np.arange(3), 2), "seed = True"),
        (lambda: uniforms(0, np.arange(3), 0), "dims = 0"),
        (lambda: uniforms(0, np.zeros((2, 2), int), 2), "shape"),
        (lambda: uniforms(0, np.array([-1, 2]), 2), "holds -1"),
        (lambda: uniforms(0, np.array([0.5]), 2), "dtype float64"),
        (lambda: derived_seed(0, -2), r"path\[0\] = -2"),
    ],
)
def test_streams_refuse_bad_input(call, message):
    with pytest.raises(ValueError, match=message):
        call()


# --- exact tails -------------------------------------------------------------------------------------


@pytest.mark.parametrize("method", METHODS)
def test_linear_response_at_1e_3(method):
    estimator, options = METHODS[method]
    probability, exact_quantile = 1e-3, stats.norm.isf(1e-3)
    quantile = estimator(Guarded(linear(10)), 10, SEED, probability=probability, **options)
    assert quantile.method == method and quantile.target == "probability"
    assert quantile.probability == probability
    assert covers(quantile.threshold_ci95, exact_quantile), quantile
    assert covers(quantile.threshold_ci95, quantile.threshold)
    assert covers(quantile.probability_ci95, probability)
    exceedance = estimator(Guarded(linear(10)), 10, SEED, threshold=exact_quantile, **options)
    assert exceedance.target == "threshold" and exceedance.threshold == exact_quantile
    assert exceedance.threshold_ci95 == (exact_quantile, exact_quantile)
    assert covers(exceedance.probability_ci95, probability), exceedance


def test_subset_simulation_and_importance_sampling_at_1e_9_in_50_dimensions():
    probability, exact_quantile = 1e-9, stats.norm.isf(1e-9)
    subset = subset_simulation(Guarded(linear(50)), 50, SEED, probability=probability)
    importance = importance_sampling(Guarded(linear(50)), 50, SEED, probability=probability)
    for estimate in (subset, importance):
        assert covers(estimate.threshold_ci95, exact_quantile), estimate
    # Each method's interval meets the other's.
    assert max(subset.threshold_ci95[0], importance.threshold_ci95[0]) <= min(
        subset.threshold_ci95[1], importance.threshold_ci95[1]
    )
    assert len(subset.levels) == 8  # p / p0**8 = p0: the quantile is read off the ninth level
    for estimator in (subset_simulation, importance_sampling):
        exceedance = estimator(Guarded(linear(50)), 50, SEED, threshold=exact_quantile)
        assert covers(exceedance.probability_ci95, probability), exceedance


def test_series_system_brute_force_and_subset_simulation():
    exact = 1 - (1 - stats.norm.sf(3.0)) ** 2
    brute = brute_force(Guarded(series), 10, SEED, n_samples=100_000, threshold=3.0)
    assert covers(brute.probability_ci95, exact)
    probability = 1e-5
    exact_quantile = stats.norm.isf(1 - math.sqrt(1 - probability))
    subset = subset_simulation(Guarded(series), 10, SEED, probability=probability)
    assert covers(subset.threshold_ci95, exact_quantile), subset
    exceedance = subset_simulation(Guarded(series), 10, SEED, threshold=exact_quantile)
    assert covers(exceedance.probability_ci95, probability), exceedance


def test_parallel_system_importance_sampling():
    probability = 1e-5
    exact_quantile = stats.norm.isf(math.sqrt(probability))
    importance = importance_sampling(Guarded(parallel), 10, SEED, probability=probability)
    assert covers(importance.threshold_ci95, exact_quantile), importance
    exceedance = importance_sampling(Guarded(parallel), 10, SEED, threshold=exact_quantile)
    assert covers(exceedance.probability_ci95, probability), exceedance
    # The importance density sits near the design point (b, b) of the failure corner.
    mean = np.array(exceedance.diagnostics["importance_mean"])
    assert np.all(mean[:2] > exact_quantile) and np.all(np.abs(mean[2:]) < 0.5)


def test_importance_sampling_stops_on_two_symmetric_failure_regions():
    with pytest.raises(RuntimeError, match="cross entropy stalled"):
        importance_sampling(lambda u: np.abs(u[:, 0]), 10, SEED, threshold=stats.norm.isf(5e-6))


# --- weighted tails ----------------------------------------------------------------------------------


def test_subset_simulations_weighted_sample_is_its_level_wise_ccdf():
    """Level j's samples in (b_j, b_{j+1}] weigh p0**j / N: the weighted sample's CCDF is p0**j
    times level j's fraction above d, which is what subset simulation with that threshold estimates
    (the same seed runs the same levels until it stops), at the level boundaries (at b_4 the chains'
    repeated states tie: 49 of level 3's samples exceed it, not N p0 = 50) and within levels; the
    variance is Au & Beck's at d."""
    options = {"n_per_level": 500}
    estimate = subset_simulation(linear(10), 10, SEED, probability=1e-6, **options)
    tail = estimate.tail
    assert tail.method == "subset" and tail.levels == estimate.levels and len(tail.levels) == 5
    assert math.isclose(tail.weights.sum(), 1.0, rel_tol=1e-12)
    bounds = (-3.0, *estimate.levels, estimate.threshold)
    points = sorted({*estimate.levels, *((a + b) / 2 for a, b in zip(bounds[:-1], bounds[1:]))})
    for d in points:
        exceedance = subset_simulation(linear(10), 10, SEED, threshold=d, **options)
        assert tail.exceedance(d) == pytest.approx(exceedance.probability, rel=1e-12), d
        assert tail.coefficient_of_variation(d) == pytest.approx(exceedance.coefficient_of_variation, rel=1e-9), d
    # Vectorised over d, and the same as one d at a time.
    assert np.array_equal(tail.exceedance(np.array(points)), [tail.exceedance(d) for d in points])
    assert np.array_equal(tail.variance(np.array(points)), [tail.variance(d) for d in points])
    # Above every sample the estimate is zero, and says so by its count.
    top = tail.responses.max()
    assert tail.exceedance(top) == 0.0 and tail.exceedance_count(top) == 0


def test_importance_samplings_weighted_sample():
    threshold = stats.norm.isf(1e-6)
    estimate = importance_sampling(linear(10), 10, SEED, threshold=threshold)
    tail = estimate.tail
    assert tail.method == "is" and tail.sample_size == 2000 and len(tail.responses) == 2000
    assert tail.exceedance(threshold) == pytest.approx(estimate.probability, rel=1e-12)
    assert tail.coefficient_of_variation(threshold) == pytest.approx(estimate.coefficient_of_variation, rel=1e-9)
    assert tail.exceedance_count(threshold) == estimate.diagnostics["exceedances"]
    # The final sample resolves the CCDF a factor 10 either side of the threshold: its intervals hold the exact values.
    for p in (1e-5, 1e-7):
        d = stats.norm.isf(p)
        spread = 1.96 * tail.coefficient_of_variation(d)
        assert tail.exceedance(d) * (1 - spread) <= p <= tail.exceedance(d) * (1 + spread)


def test_brute_forces_weighted_sample_resolves_only_its_tail():
    n = 100_000
    threshold = stats.norm.isf(1e-2)
    estimate = brute_force(linear(10), 10, SEED, n_samples=n, threshold=threshold)
    tail = estimate.tail
    assert tail.resolved_from == threshold and len(tail.responses) == estimate.diagnostics["exceedances"]
    assert tail.exceedance(threshold) == pytest.approx(estimate.probability, rel=1e-12)
    assert tail.coefficient_of_variation(threshold) == pytest.approx(estimate.coefficient_of_variation, rel=1e-9)
    assert math.isnan(tail.exceedance(threshold - 0.1)) and math.isnan(tail.variance(threshold - 0.1))
    # With a probability, the largest responses down to the interval's lower end are kept.
    quantile = brute_force(linear(10), 10, SEED, n_samples=n, probability=1e-2)
    assert quantile.tail.resolved_from <= quantile.threshold_ci95[0]
    assert quantile.tail.exceedance(quantile.threshold) == pytest.approx(1e-2, rel=1e-12)
    assert math.isnan(quantile.tail.exceedance(quantile.threshold_ci95[0] - 0.01))


# --- brute force ---------------------------------------------------------------------------------------


def test_brute_force_at_1e_2_and_its_conventions():
    exact_quantile = stats.norm.isf(1e-2)
    estimate = brute_force(Guarded(linear(10)), 10, SEED, n_samples=100_000, probability=1e-2)
    assert covers(estimate.threshold_ci95, exact_quantile)
    assert estimate.diagnostics["exceedances"] == 1000  # 1000 of 100,000 exceed the midpoint quantile
    # The quantile at p n = 1000 is the midpoint of the 1000-th and 1001-th largest responses, and
    # the interval's ends are order statistics.
    responses = np.sort(linear(10)(standard_normals(SEED, np.arange(100_000), 10)))[::-1]
    assert estimate.threshold == pytest.approx((responses[999] + responses[1000]) / 2, rel=1e-14)
    assert set(estimate.threshold_ci95) <= set(responses)
    exceedance = brute_force(Guarded(linear(10)), 10, SEED, n_samples=100_000, threshold=exact_quantile)
    assert covers(exceedance.probability_ci95, 1e-2)
    assert exceedance.probability == exceedance.diagnostics["exceedances"] / 100_000
    lower, upper = stats.binomtest(exceedance.diagnostics["exceedances"], 100_000).proportion_ci(method="exact")
    assert exceedance.probability_ci95 == pytest.approx((lower, upper), rel=1e-9)


def test_brute_force_refuses_a_probability_too_small_for_the_sample():
    with pytest.raises(ValueError, match=r"n_samples = 1000 is too few for probability = 0.001.*n_samples >= 10000"):
        brute_force(linear(3), 3, SEED, n_samples=1000, probability=1e-3)
    brute_force(linear(3), 3, SEED, n_samples=10_000, probability=1e-3)  # 10 expected: accepted


# --- determinism, batching, counting --------------------------------------------------------------------


def same_estimate(first: TailEstimate, second: TailEstimate) -> bool:
    return {**first.as_dict(), "seconds": 0} == {**second.as_dict(), "seconds": 0} and (
        first.diagnostics == second.diagnostics and first.levels == second.levels
    )


@pytest.mark.parametrize("method", METHODS)
def test_the_batch_size_changes_nothing(method):
    estimator, options = METHODS[method]
    large, small = (1000, 4096) if method == "brute" else (150, 4096)
    first = estimator(Guarded(linear(10), large), 10, SEED, probability=1e-3, batch_size=large, **options)
    second = estimator(Guarded(linear(10), small), 10, SEED, probability=1e-3, batch_size=small, **options)
    assert same_estimate(first, second)
    assert np.array_equal(first.tail.responses, second.tail.responses)
    assert np.array_equal(first.tail.weights, second.tail.weights)
    assert not same_estimate(first, estimator(linear(10), 10, SEED + 1, probability=1e-3, **options))


def test_subset_simulation_starts_from_the_brute_force_sample():
    # p > p0: the quantile is read off level 0, which is the brute-force sample of the same seed.
    subset = subset_simulation(linear(10), 10, SEED, probability=0.2, n_per_level=2000)
    brute = brute_force(linear(10), 10, SEED, n_samples=2000, probability=0.2)
    assert subset.threshold == brute.threshold and subset.model_evaluations == 2000


@pytest.mark.parametrize("method", METHODS)
def test_model_evaluations_count_every_row(method):
    estimator, options = METHODS[method]
    response = Guarded(linear(10), 150)
    options = {"n_samples": 200_000} if method == "brute" else options
    estimate = estimator(response, 10, SEED, probability=1e-4, batch_size=150, **options)
    assert estimate.model_evaluations == response.rows
    if method == "brute":
        assert response.rows == 200_000
    elif method == "subset":
        assert response.rows == 2000 + len(estimate.levels) * 1800  # seeds are not evaluated again
    else:
        assert response.rows == 2000 * (len(estimate.levels) + 1) + 2000  # the levels and the final run


def test_the_response_cannot_write_into_its_input():
    def overwriting(u: np.ndarray) -> np.ndarray:
        u[:, 0] = 0.0
        return u[:, 1]

    with pytest.raises(ValueError, match="read-only"):
        subset_simulation(overwriting, 3, SEED, probability=1e-2)


def test_as_dict_is_what_the_command_line_writes():
    estimate = importance_sampling(linear(10), 10, SEED, probability=1e-5)
    fields = estimate.as_dict()
    assert set(fields) == {
        "probability",
        "braking_distance_m",
        "ci95_m",
        "model_evaluations",
        "method",
        "seconds",
        "probability_ci95",
        "threshold",
    }
    assert fields["braking_distance_m"] == fields["threshold"] == estimate.threshold
    assert fields["ci95_m"] == list(estimate.threshold_ci95)
    assert fields["method"] == "is" and fields["probability"] == 1e-5
    json.dumps(fields, allow_nan=False)
    unbounded = TailEstimate("subset", "probability", 0.5, (0.1, 0.9), 1.0, (-math.inf, math.inf), 10, 0.0, 1.0)
    assert unbounded.as_dict()["ci95_m"] == [None, None]


# --- refusals --------------------------------------------------------------------------------------------


def bounded(u: np.ndarray) -> np.ndarray:
    return np.tanh(u[:, 0])


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: brute_force(linear(2), 2, 0, 100), "give exactly one"),
        (lambda: subset_simulation(linear(2), 2, 0, probability=0.1, threshold=1.0), "give exactly one"),
        (lambda: importance_sampling(linear(2), 2, 0, probability=0.0), "probability = 0.0"),
        (lambda: brute_force(linear(2), 2, 0, 100, probability=1.0), "probability = 1.0"),
        (lambda: brute_force(linear(2), 2, 0, 100, probability=math.nan), "probability = nan"),
        (lambda: subset_simulation(linear(2), 2, 0, threshold=math.inf), "threshold = inf"),
        (lambda: brute_force(linear(2), 0, 0, 100, threshold=1.0), "dims = 0"),
        (lambda: brute_force(linear(2), 2, -3, 100, threshold=1.0), "seed = -3"),
        (lambda: brute_force(linear(2), 2, 0, 0, threshold=1.0), "n_samples = 0"),
        (lambda: brute_force(linear(2), 2, 0, 100, threshold=1.0, batch_size=0), "batch_size = 0"),
        (lambda: brute_force("linear", 2, 0, 100, threshold=1.0), "need a callable"),
        (lambda: subset_simulation(linear(2), 2, 0, threshold=1.0, level_probability=0.3), "whole number"),
        (lambda: subset_simulation(linear(2), 2, 0, threshold=1.0, level_probability=0.6), "level_probability = 0.6"),
        (lambda: subset_simulation(linear(2), 2, 0, threshold=1.0, n_per_level=2005), "n_per_level = 2005"),
        (lambda: subset_simulation(linear(2), 2, 0, probability=1e-9, max_levels=5), "needs 8 levels"),
        (lambda: subset_simulation(linear(2), 2, 0, probability=0.9999, n_per_level=1000), "too close to 1"),
        (lambda: importance_sampling(linear(2), 2, 0, threshold=1.0, n_per_level=5), "n_per_level = 5"),
        (lambda: importance_sampling(linear(2), 2, 0, threshold=1.0, n_final=1), "n_final = 1"),
        (lambda: importance_sampling(linear(2), 2, 0, threshold=1.0, max_levels=0), "max_levels = 0"),
        (lambda: brute_force(lambda u: u, 2, 0, 100, threshold=1.0), r"shape \(100, 2\) for 100 rows"),
        (lambda: brute_force(lambda u: u[:, 0] * np.nan, 2, 0, 100, threshold=1.0), "NaN"),
    ],
)
def test_bad_input_is_refused(call, message):
    with pytest.raises(ValueError, match=message):
        call()


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: subset_simulation(bounded, 2, 0, threshold=1.5, max_levels=3), "not reached in max_levels = 3"),
        (lambda: importance_sampling(bounded, 2, 0, threshold=1.5, max_levels=3), "did not reach the target"),
        (lambda: importance_sampling(lambda u: 0 * u[:, 0], 2, 0, threshold=1.0), "is the response constant"),
    ],
)
def test_unreachable_targets_stop_with_a_runtime_error(call, message):
    with pytest.raises(RuntimeError, match=message):
        call()
