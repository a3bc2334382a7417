"""Throughput of brakegym/WheelSlideProtection-v0: train-steps per second with 256 trains.

    python benchmarks/bench_wsp_env.py [--trains 256] [--steps 300] [--repeats 3]

Target (issue 16): 20,000 train-steps per second with 256 trains, one train-step being one 20 ms
control step of one train (the adhesion simulator's step with its wheelset substeps, the WSP
valves, the brake control unit's observation with its noise, the reward terms). The baseline
timed in the same process is EmergencyStop-v0 with as many trains (a 0.1 s control step of two
RK4 steps of the paper's train in perfect rolling), so the ratio of the two rates is taken on the
same machine minutes apart. Every valve applies (no WSP: the wheels lock on the low rail, the
kernel's costliest branch); episodes restart when they end. Each env runs on one kernel thread and
on all of numba's threads; the best of ``--repeats`` runs is printed with the range, and the rate
per second of this process's CPU time, which waits less for the other processes of a shared
machine.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import brakegym  # noqa: F401
from brakegym.envs import BrakeVectorEnv
from brakegym.simulator import kernel_threads, set_kernel_threads


def train_steps_per_s(env: BrakeVectorEnv, action: np.ndarray, steps: int) -> tuple[float, float]:
    """Train-steps per second of wall-clock time and of process CPU time (after a warm-up)."""
    env.reset(seed=0)
    for _ in range(10):
        env.step(action)
    started, started_cpu = time.perf_counter(), time.process_time()
    for _ in range(steps):
        env.step(action)
    train_steps = steps * env.num_envs
    return train_steps / (time.perf_counter() - started), train_steps / (time.process_time() - started_cpu)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--trains", type=int, default=256, help="trains per batch (default 256)")
    parser.add_argument("--steps", type=int, default=300, help="control steps per timing (default 300)")
    parser.add_argument("--repeats", type=int, default=3, help="timings per env and thread count (default 3)")
    args = parser.parse_args()

    envs = {
        "WheelSlideProtection-v0": BrakeVectorEnv("wheel_slide_protection", num_envs=args.trains),
        "EmergencyStop-v0 (baseline)": BrakeVectorEnv("emergency_stop", num_envs=args.trains),
    }
    actions = {
        "WheelSlideProtection-v0": np.full((args.trains, envs["WheelSlideProtection-v0"].core.fleet.n_valves), 2),
        "EmergencyStop-v0 (baseline)": np.ones(envs["EmergencyStop-v0 (baseline)"].action_space.shape, np.float32),
    }
    all_threads = kernel_threads()
    best: dict[tuple[str, int], float] = {}
    print(f"{args.trains} trains, {args.steps} control steps per timing, best of {args.repeats}")
    print("| env | kernel threads | train-steps/s (range) | per CPU second |")
    print("|---|---|---|---|")
    for threads in sorted({1, all_threads}):
        set_kernel_threads(threads)
        for name, env in envs.items():
            rates = [train_steps_per_s(env, actions[name], args.steps) for _ in range(args.repeats)]
            wall = [rate for rate, _ in rates]
            best[name, threads] = max(wall)
            print(
                f"| {name} | {threads} | {max(wall):,.0f} ({min(wall):,.0f}-{max(wall):,.0f}) "
                f"| {max(cpu for _, cpu in rates):,.0f} |"
            )
    set_kernel_threads(all_threads)
    for threads in sorted({1, all_threads}):
        wsp, baseline = best["WheelSlideProtection-v0", threads], best["EmergencyStop-v0 (baseline)", threads]
        print(
            f"{threads} thread(s): WheelSlideProtection {wsp:,.0f} train-steps/s = {wsp / baseline:.2f} x "
            f"EmergencyStop's {baseline:,.0f} (target 20,000: {'met' if wsp >= 20_000 else 'NOT met'})"
        )


if __name__ == "__main__":
    main()
