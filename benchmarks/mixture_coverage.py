"""Coverage of brakegym.reliability.mixture_tail's 95 % intervals on mixtures with exact tails.

    python benchmarks/mixture_coverage.py [--repeats 200] [--dims 30] [--methods subset is]
        [--probabilities 1e-3 1e-5 1e-9] [--pilot-per-level 500] [--workers 2]

The mixture: ``k = 0..4`` failed units of 16, each failing with probability ``q = 1e-3``
(weights ``Binomial(k; 16, q)``, not renormalised: ``P(k >= 5) = 4.3e-12`` is unmodelled), and
given ``k`` the response ``2 k + s_k . u``, ``|s_k| = 1``, a standard normal shifted by two
standard deviations per failed unit. The exact tail is that of all 17 components,
``P(D > d) = sum_{k=0}^{16} pi_k Phi(2 k - d)``: the five modelled components and the bound on the
unmodelled mass must together cover it. Per method and probability ``p``, over seeds
``1000, 1001, ...``: how often the quantile's interval holds the exact quantile, and (threshold
mode at the exact quantile) how often the probability's interval holds ``p``; the mean of
``log(estimate / p)`` and its standard deviation, the mean reported coefficient of variation, the
mean evaluations (pilot's in brackets) and seconds.
"""

from __future__ import annotations

import argparse
import math
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from scipy import optimize, stats

from brakegym.reliability import mixture_tail

UNITS, FAILURE = 16, 1e-3
MODELLED = 5
SHIFT = 2.0


class Linear:
    """``shift + s . u``, summed a column at a time (the same numbers whatever the batch)."""

    def __init__(self, shift: float, direction: np.ndarray) -> None:
        self.shift, self.direction = shift, direction

    def __call__(self, u: np.ndarray) -> np.ndarray:
        total = np.full(len(u), self.shift)
        for column, component in zip(u.T, self.direction):
            total += column * component
        return total


def components(dims: int) -> list[tuple[float, Linear]]:
    weights = stats.binom.pmf(np.arange(MODELLED), UNITS, FAILURE)
    result = []
    for k in range(MODELLED):
        direction = np.cos(0.7 * (k + 1) * np.arange(dims) + k) + 1.5
        result.append((float(weights[k]), Linear(SHIFT * k, direction / np.linalg.norm(direction))))
    return result


def exact_exceedance(d: float) -> float:
    k = np.arange(UNITS + 1)
    return float(np.sum(stats.binom.pmf(k, UNITS, FAILURE) * stats.norm.sf(d - SHIFT * k)))


def exact_quantile(p: float) -> float:
    return optimize.brentq(lambda d: exact_exceedance(d) - p, -10.0, 60.0, xtol=1e-13)


def one(job: tuple[str, float, int, int, int]) -> dict[str, float]:
    method, p, seed, dims, pilot = job
    mixture, exact = components(dims), exact_quantile(p)
    quantile = mixture_tail(mixture, dims, seed, method, probability=p, pilot_per_level=pilot)
    exceedance = mixture_tail(mixture, dims, seed, method, threshold=exact, pilot_per_level=pilot)
    return {
        "quantile_covers": quantile.threshold_ci95[0] <= exact <= quantile.threshold_ci95[1],
        "probability_covers": exceedance.probability_ci95[0] <= p <= exceedance.probability_ci95[1],
        "log_ratio": math.log(exceedance.probability / p),
        "cov": exceedance.coefficient_of_variation,
        "evaluations": quantile.model_evaluations,
        "pilot_evaluations": quantile.diagnostics["pilot_evaluations"],
        "seconds": quantile.seconds,
        "threshold_evaluations": exceedance.model_evaluations,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=200)
    parser.add_argument("--dims", type=int, default=30)
    parser.add_argument("--methods", nargs="+", default=["subset", "is"])
    parser.add_argument("--probabilities", nargs="+", type=float, default=[1e-3, 1e-5, 1e-9])
    parser.add_argument("--pilot-per-level", type=int, default=500)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    print(
        f"{args.repeats} repeats, {args.dims} dimensions, pilot_per_level {args.pilot_per_level}; "
        f"coverage of the exact value by the 95 % intervals"
    )
    with ProcessPoolExecutor(args.workers) as pool:
        for method in args.methods:
            for p in args.probabilities:
                start = time.perf_counter()
                jobs = [(method, p, 1000 + r, args.dims, args.pilot_per_level) for r in range(args.repeats)]
                rows = list(pool.map(one, jobs, chunksize=4))
                column = {key: np.array([row[key] for row in rows], dtype=float) for key in rows[0]}
                print(
                    f"{method:6s} p={p:.0e}: quantile {column['quantile_covers'].mean():6.1%}  "
                    f"probability {column['probability_covers'].mean():6.1%}  "
                    f"log(P/p) {column['log_ratio'].mean():+.3f} sd {column['log_ratio'].std(ddof=1):.3f} "
                    f"(reported CoV {column['cov'].mean():.3f})  "
                    f"evaluations {column['evaluations'].mean():.0f} (pilot {column['pilot_evaluations'].mean():.0f}; "
                    f"threshold mode {column['threshold_evaluations'].mean():.0f})  "
                    f"{column['seconds'].mean():.2f} s  [{time.perf_counter() - start:.0f} s]",
                    flush=True,
                )


if __name__ == "__main__":
    main()
