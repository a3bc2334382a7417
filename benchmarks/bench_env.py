"""Environment throughput: single-train steps per second and batched train-steps per second.

    python benchmarks/bench_env.py [--steps 20000] [--trains 256]

Issue targets: 5,000 single-env steps/s; 500,000 batched train-steps/s with 256 trains. The
baseline measured in the same run is Gymnasium's SyncVectorEnv over 256 single environments (what
a user gets without the native vector env), so the batching speed-up is a ratio of two timings
taken minutes apart on the same machine. Control steps are 0.1 s with 2 RK4 substeps (default
config); actions are constant, episodes restart when they end.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import brakegym  # noqa: F401
from brakegym.envs import StationStopEnv, StationStopVectorEnv


def single_steps_per_s(steps: int, wrapped: bool) -> float:
    env = gym.make("brakegym/StationStop-v0") if wrapped else StationStopEnv()
    env.reset(seed=0)
    action = np.full(env.action_space.shape, 0.2, np.float32)
    started = time.perf_counter()
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - started)


def vector_train_steps_per_s(env: gym.vector.VectorEnv, steps: int) -> float:
    env.reset(seed=0)
    action = np.full(env.action_space.shape, 0.2, np.float32)
    started = time.perf_counter()
    for _ in range(steps):
        env.step(action)
    return steps * env.num_envs / (time.perf_counter() - started)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=20000, help="single-env steps (default 20000)")
    parser.add_argument("--trains", type=int, default=256, help="trains in the batched env (default 256)")
    parser.add_argument("--vector-steps", type=int, default=2000, help="batched steps (default 2000)")
    args = parser.parse_args()

    single_steps_per_s(200, wrapped=False)  # warm-up: imports, compiled kernels
    raw = single_steps_per_s(args.steps, wrapped=False)
    wrapped = single_steps_per_s(args.steps // 4, wrapped=True)
    native = vector_train_steps_per_s(StationStopVectorEnv(num_envs=args.trains), args.vector_steps)
    sync = gym.vector.SyncVectorEnv([StationStopEnv for _ in range(args.trains)])
    baseline = vector_train_steps_per_s(sync, max(args.vector_steps // 20, 20))

    print(f"single env (StationStopEnv, unwrapped):        {raw:10.0f} steps/s   (target 5,000: {raw / 5000:.2f}x)")
    print(f"single env (gymnasium.make, checker wrappers): {wrapped:10.0f} steps/s")
    print(f"batched, {args.trains} trains (StationStopVectorEnv):  {native:10.0f} train-steps/s (target 500,000: {native / 5e5:.2f}x)")
    print(f"baseline: SyncVectorEnv of {args.trains} single envs: {baseline:10.0f} train-steps/s")
    print(f"native batching speed-up over SyncVectorEnv: {native / baseline:.1f}x")


if __name__ == "__main__":
    main()
