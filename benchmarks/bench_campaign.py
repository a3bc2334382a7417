"""Speed of the batched simulator against the solve_ivp baseline, measured in one run.

    python benchmarks/bench_campaign.py [--baseline-stops 40] [--step 0.2]

Runs the field campaign in MCS-75/25 (88 applications x 50 = 4400 train stops of 16 discs) in one
process on one kernel thread (the one-core reference), in one process on every kernel thread, and
in 2 worker processes of one thread each, then a sample of the same stops (same draws) one ``solve_ivp`` call
each, and prints wall times, disc-steps per second and the per-disc-stop speed ratio, with the
largest difference in stop distance between the two. Timings on a shared machine vary from run to
run; the ratio is measured within one run for that reason.

The compiled kernels are loaded before the timed runs (the line "kernels loaded" says how long
that took: numba's start-up and the disk cache, or the first compile on a new machine); a
campaign in a fresh process pays it once on top of the times shown.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from solve_ivp_baseline import solve_ivp_stop  # noqa: E402

from brakegym import config as cfg  # noqa: E402
from brakegym.applications import DEFAULT_STEP_S  # noqa: E402
from brakegym.campaigns import field_applications, train_monte_carlo  # noqa: E402
from brakegym.simulator import kernel  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline-stops", type=int, default=40)
    parser.add_argument("--step", type=float, default=DEFAULT_STEP_S)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()

    campaign = cfg.load("campaigns", "field2022")
    vehicle = cfg.load("vehicles", campaign.vehicle)
    setup = cfg.load("setups", "mcs-75-25")
    apps = [app for app in field_applications(campaign) for _ in range(campaign.repetitions)]
    n_discs = vehicle.n_discs

    start = time.perf_counter()
    kernel.warm_up()
    load_s = time.perf_counter() - start

    all_threads = kernel.kernel_threads()
    variants = {
        "1 process, 1 thread": (1, 1),
        f"1 process, {all_threads} threads": (1, all_threads),
        "2 processes": (2, 1),
    }
    timings = {}
    summaries = {}
    for label, (workers, threads) in variants.items():
        kernel.set_kernel_threads(threads)
        start = time.perf_counter()
        summary, draw, resistance = train_monte_carlo(vehicle, apps, setup, args.seed, args.step, workers=workers)
        timings[label] = time.perf_counter() - start
        summaries[label] = summary
    kernel.set_kernel_threads(all_threads)
    first = next(iter(summaries.values()))
    identical = all(
        np.array_equal(getattr(first, name), getattr(other, name), equal_nan=True)
        for other in summaries.values()
        for name in ("stop_distance_m", "stop_time_s", "mu_s", "mu_s_eff", "friction_heat_J")
    )
    # Disc-steps each stop needs (to its standstill), not the steps a chunk runs until its last
    # train stops.
    disc_steps = float(np.ceil(summary.stop_time_s / args.step).sum() * n_discs)

    rng = np.random.default_rng(0)
    sample = rng.choice(len(apps), size=args.baseline_stops, replace=False)
    start = time.perf_counter()
    baseline = [
        solve_ivp_stop(
            vehicle, apps[i], draw.initial_mu[i], draw.power_coefficient_per_s[i], float(resistance[i]), rtol=1e-6
        )
        for i in sample
    ]
    baseline_time = time.perf_counter() - start
    baseline_per_stop = baseline_time / len(sample)
    difference = max(abs(d - summary.stop_distance_m[i]) / d for (_, d), i in zip(baseline, sample))

    stops = len(apps)
    print(f"field campaign MCS-75/25: {stops} train stops x {n_discs} discs, step {args.step} s")
    print(f"  kernels loaded in {load_s:.2f} s before timing (numba start-up and disk cache)")
    one_core = timings["1 process, 1 thread"]
    for label, seconds in timings.items():
        per_disc_stop = seconds / (stops * n_discs)
        print(
            f"  batched, {label:<20}: {seconds:6.2f} s ({one_core / seconds:4.2f}x one core)   "
            f"{disc_steps / seconds:12,.0f} disc-steps/s   "
            f"{1e6 * per_disc_stop:7.2f} us per disc-stop   "
            f"ratio vs solve_ivp {baseline_per_stop / n_discs / per_disc_stop:6.1f}x"
        )
    print(
        f"  solve_ivp baseline (RK45, rtol 1e-6), {len(sample)} stops: {1e3 * baseline_per_stop:.1f} ms per stop, "
        f"{1e6 * baseline_per_stop / n_discs:.1f} us per disc-stop, "
        f"extrapolated {baseline_per_stop * stops:.0f} s for the campaign"
    )
    print(f"  largest stop-distance difference batched vs solve_ivp: {100 * difference:.3f} %")
    print(f"  every variant gives identical results: {identical}")


if __name__ == "__main__":
    main()
