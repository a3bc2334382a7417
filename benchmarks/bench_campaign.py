"""Speed of the field campaign on each executor, and against the solve_ivp baseline, in one run.

    python benchmarks/bench_campaign.py [--rounds 3] [--baseline-stops 40] [--step 0.2] [--no-dask]

Runs the field campaign in MCS-75/25 (88 applications x 50 = 4400 train stops of 16 discs, chunks
of the default size) on: the inline executor with one kernel thread (the one-core reference), the
inline executor with every kernel thread, 2 local worker processes, and a local Dask cluster of 2
worker processes: one after the other, each started and warmed by an untimed campaign, then timed
``--rounds`` times and closed before the next starts (an idle Dask cluster alone slows the other
variants by a third on two cores). Each variant's best and median time are printed. Then a
sample of the same stops (same draws), one ``solve_ivp`` call each, for the per-disc-stop speed
ratio, with the largest difference in stop distance.
Timings on a shared machine vary from run to run; compare the variants within one run.

The compiled kernels are loaded before the timed runs (the line "kernels loaded" says how long
that took: numba's start-up and the disk cache, or the first compile on a new machine); a
campaign in a fresh process pays it once on top of the times shown, and so does each Dask worker
(not timed: each executor runs one untimed campaign first).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from solve_ivp_baseline import solve_ivp_stop  # noqa: E402

from brakegym import config as cfg  # noqa: E402
from brakegym.campaigns import field_applications, field_campaign  # noqa: E402
from brakegym.defaults import DEFAULT_STEP_S  # noqa: E402
from brakegym.execution import DaskExecutor, InlineExecutor, LocalExecutor  # noqa: E402
from brakegym.plants import train_scatter  # noqa: E402
from brakegym.simulator import kernel  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--baseline-stops", type=int, default=40)
    parser.add_argument("--step", type=float, default=DEFAULT_STEP_S)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--no-dask", action="store_true", help="leave the Dask cluster out")
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
    executors = {
        "inline, 1 kernel thread": lambda: InlineExecutor(kernel_threads=1),
        f"inline, {all_threads} kernel threads": lambda: InlineExecutor(kernel_threads=all_threads),
        "local, 2 processes": lambda: LocalExecutor(2),
    }
    if not args.no_dask:
        executors["dask, 2 local workers"] = lambda: DaskExecutor(workers=2)
    timings: dict[str, list[float]] = {}
    tables = {}
    # One executor alive at a time: an idle Dask cluster's scheduler and workers take enough of the
    # two cores to slow the other variants by a third.
    for label, make in executors.items():
        with make() as executor:
            start = time.perf_counter()
            field_campaign(campaign, setup, args.seed, args.step, executor=executor)  # workers load the kernels
            print(f"  {label}: started and warmed in {time.perf_counter() - start:.1f} s (untimed)")
            timings[label] = []
            for _ in range(args.rounds):
                start = time.perf_counter()
                result = field_campaign(campaign, setup, args.seed, args.step, executor=executor)
                timings[label].append(time.perf_counter() - start)
            tables[label] = result.applications
    first = next(iter(tables.values()))
    identical = all(other.equals(first) for other in tables.values())
    stop_time_s = first.stop_time_s.to_numpy()
    stop_distance_m = first.stop_distance_m.to_numpy()
    # Disc-steps each stop needs (to its standstill), not the steps a chunk runs until its last
    # train stops.
    disc_steps = float(np.ceil(stop_time_s / args.step).sum() * n_discs)

    rng = np.random.default_rng(0)
    sample = rng.choice(len(apps), size=args.baseline_stops, replace=False)
    draw, resistance = train_scatter(vehicle, setup).draw_for_samples(args.seed, sample)
    start = time.perf_counter()
    baseline = [
        solve_ivp_stop(
            vehicle, apps[i], draw.initial_mu[k], draw.power_coefficient_per_s[k], float(resistance[k]), rtol=1e-6
        )
        for k, i in enumerate(sample)
    ]
    baseline_time = time.perf_counter() - start
    baseline_per_stop = baseline_time / len(sample)
    difference = max(abs(d - stop_distance_m[i]) / d for (_, d), i in zip(baseline, sample))

    stops = len(apps)
    print(f"field campaign MCS-75/25: {stops} train stops x {n_discs} discs, step {args.step} s, {args.rounds} rounds")
    print(f"  kernels loaded in {load_s:.2f} s before timing (numba start-up and disk cache)")
    one_core = min(timings["inline, 1 kernel thread"])
    for label, seconds in timings.items():
        best = min(seconds)
        per_disc_stop = best / (stops * n_discs)
        ratio = baseline_per_stop / n_discs / per_disc_stop
        print(
            f"  {label:<26}: best {best:6.2f} s, median {statistics.median(seconds):6.2f} s "
            f"({one_core / best:4.2f}x one core)   {disc_steps / best:12,.0f} disc-steps/s   "
            f"{1e6 * per_disc_stop:6.2f} us per disc-stop   ratio vs solve_ivp {ratio:6.1f}x"
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
