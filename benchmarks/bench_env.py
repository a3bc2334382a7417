"""Environment throughput: single-train steps per second and batched train-steps per second.

    python benchmarks/bench_env.py [--steps 20000] [--trains 256] [--repeats 3]

Issue targets: 5,000 single-env steps/s; 500,000 batched train-steps/s with 256 trains, and
250,000 on a 2-core machine against the same env on one kernel thread (the all-threads run uses
every thread numba has, NUMBA_NUM_THREADS, all cores by default). The
baseline measured in the same run is Gymnasium's SyncVectorEnv over 256 single environments (what
a user gets without the native vector env), so the batching speed-up is a ratio of two timings
taken minutes apart on the same machine. Control steps are 0.1 s with 2 RK4 substeps (default
config); actions are constant, episodes restart when they end. On a shared machine the rates
vary from run to run: ``--repeats`` times the native envs several times and prints the range,
and the rate per second of this process's CPU time, which waits for the other processes less.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import brakegym  # noqa: F401
from brakegym.envs import BrakeEnv, BrakeVectorEnv
from brakegym.simulator import kernel_threads, set_kernel_threads


def single_steps_per_s(steps: int, wrapped: bool) -> tuple[float, float]:
    """Steps per second of wall-clock time and of process CPU time."""
    env = gym.make("brakegym/StationStop-v0") if wrapped else BrakeEnv("station_stop")
    env.reset(seed=0)
    action = np.full(env.action_space.shape, 0.2, np.float32)
    started, started_cpu = time.perf_counter(), time.process_time()
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - started), steps / (time.process_time() - started_cpu)


def vector_train_steps_per_s(env: gym.vector.VectorEnv, steps: int) -> tuple[float, float]:
    """Train-steps per second of wall-clock time and of process CPU time."""
    env.reset(seed=0)
    action = np.full(env.action_space.shape, 0.2, np.float32)
    started, started_cpu = time.perf_counter(), time.process_time()
    for _ in range(steps):
        env.step(action)
    train_steps = steps * env.num_envs
    return train_steps / (time.perf_counter() - started), train_steps / (time.process_time() - started_cpu)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=20000, help="single-env steps (default 20000)")
    parser.add_argument("--trains", type=int, default=256, help="trains in the batched env (default 256)")
    parser.add_argument("--vector-steps", type=int, default=2000, help="batched steps (default 2000)")
    parser.add_argument(
        "--repeats", type=int, default=3, help="runs of each native env, best and range printed (default 3)"
    )
    args = parser.parse_args()

    single_steps_per_s(200, wrapped=False)  # warm-up: imports, compiled kernels
    raw = [single_steps_per_s(args.steps, wrapped=False) for _ in range(args.repeats)]
    wrapped = single_steps_per_s(args.steps // 4, wrapped=True)
    all_threads = kernel_threads()

    def batched(threads: int) -> list[tuple[float, float]]:
        set_kernel_threads(threads)
        return [
            vector_train_steps_per_s(BrakeVectorEnv("station_stop", num_envs=args.trains), args.vector_steps)
            for _ in range(args.repeats)
        ]

    one_core = batched(1)
    native = batched(all_threads)
    sync = gym.vector.SyncVectorEnv([lambda: BrakeEnv("station_stop") for _ in range(args.trains)])
    baseline, _ = vector_train_steps_per_s(sync, max(args.vector_steps // 20, 20))

    def spread(rates: list[tuple[float, float]]) -> str:
        wall, cpu = [rate for rate, _ in rates], [rate for _, rate in rates]
        runs = f", runs {min(wall):.0f}-{max(wall):.0f}" if len(rates) > 1 else ""
        return f"{max(wall):10.0f} (CPU time {max(cpu):.0f}{runs})"

    best_raw, best_native = max(rate for rate, _ in raw), max(rate for rate, _ in native)
    print(
        f"single env (BrakeEnv, unwrapped)    :        {spread(raw)} steps/s   (target 5,000: {best_raw / 5000:.2f}x)"
    )
    print(f"single env (gymnasium.make, checker wrappers): {wrapped[0]:10.0f} steps/s")
    print(
        f"batched, {args.trains} trains (BrakeVectorEnv):  {spread(native)} train-steps/s "
        f"(target 500,000: {best_native / 5e5:.2f}x)"
    )
    best_one_core = max(rate for rate, _ in one_core)
    print(
        f"batched on one kernel thread:                {spread(one_core)} train-steps/s; "
        f"{all_threads} threads {best_native / best_one_core:.2f}x (target 250,000 with 2: "
        f"{best_native / 2.5e5:.2f}x)"
    )
    print(f"baseline: SyncVectorEnv of {args.trains} single envs: {baseline:10.0f} train-steps/s")
    print(f"native batching speed-up over SyncVectorEnv: {best_native / baseline:.1f}x (best run)")


if __name__ == "__main__":
    main()
