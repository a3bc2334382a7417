"""Replay speed: a recording set replayed in one compiled call against the step-by-step loop.

    python benchmarks/bench_replay.py [--recordings 8] [--points 9] [--repeats 5]

A diagnosis replays its recordings thousands of times (every grid point, every finite
difference), each a batch of ``recordings x points`` trains. ``replay_batch`` runs a replay
without state-dependent hooks in one compiled call (``simulate_steps``); the baseline, measured in
the same run on the same batch, is ``simulate_grid``'s loop of one kernel call and one Python
round per 0.1 s step, which replays used before. Both give the same numbers (checked here, and
bit for bit in ``tests/test_recordings.py``). The set is ``brakegym synth`` seed 3 with a
-5.8 permil gradient (the README's worked example); a friction factor per train makes the batch
as a fit runs it.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import brakegym.recordings.replay as replay_module
from brakegym.effects import FrictionLevel, Gradient
from brakegym.recordings.format import read_dataset
from brakegym.recordings.synth import EffectRequest, synthesize


def step_loop(model, pressure, step_s, n_steps):
    return replay_module.simulate_grid(model, pressure, step_s, lambda sim: sim.step_index >= n_steps)


def best_seconds(batch, effects, repeats: int) -> tuple[float, list]:
    replays = replay_module.replay_batch(batch, effects)  # warm-up (compiled kernels, caches)
    best = float("inf")
    for _ in range(repeats):
        started = time.perf_counter()
        replays = replay_module.replay_batch(batch, effects)
        best = min(best, time.perf_counter() - started)
    return best, replays


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--recordings", type=int, default=8)
    parser.add_argument(
        "--points", type=int, default=9, help="parameter points per batch (default 9, a screening batch)"
    )
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        folder = synthesize(
            Path(tmp) / "set", args.recordings, 3, effects=[EffectRequest("gradient", {"gradient_permil": -5.8})]
        ).folder
        recordings = read_dataset(folder).recordings
    batch = recordings * args.points
    effects = [Gradient(gradient_permil=-5.0), FrictionLevel(mu_scale=np.linspace(0.9, 1.1, len(batch)))]

    compiled, fast = best_seconds(batch, effects, args.repeats)
    original = replay_module.simulate_steps
    replay_module.simulate_steps = step_loop
    try:
        looped, slow = best_seconds(batch, effects, args.repeats)
    finally:
        replay_module.simulate_steps = original
    same = all(
        np.array_equal(a.channels[k], b.channels[k], equal_nan=True) for a, b in zip(fast, slow) for k in a.channels
    )

    print(
        f"replay_batch of {len(batch)} trains ({args.recordings} recordings x {args.points} points), "
        f"best of {args.repeats}:"
    )
    print(f"  step-by-step loop (baseline): {looped * 1e3:8.1f} ms")
    print(f"  one compiled call:            {compiled * 1e3:8.1f} ms   ({looped / compiled:.1f}x)")
    print(f"  same channels, bit for bit:   {same}")


if __name__ == "__main__":
    main()
