"""Cost of one ``Simulator.step()``: the numpy reference against the compiled kernels.

    python benchmarks/bench_step.py [--batches 1 16 256 4400] [--step 0.1] [--no-compile-timing]

For each batch size B, trains of the 16-disc vehicle brake from 100 to 160 km/h with friction
scatter (MCS-75/25) while every step is timed as a Gymnasium environment would drive it: a new
command through ``CommandedPressure.set_command``, then ``step()`` (which runs the cylinder
pressures). Both simulators are measured in the same run, alternately, and the median over
repeated runs is reported, since the machine is shared. Then, in fresh processes: the first
compile of the kernels into an empty cache, and the start-up of a process that finds them cached.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from brakegym import config as cfg
from brakegym.physics import draw_friction
from brakegym.plants import brake_cylinder, scatter_partition, stochastic_friction, train_plant
from brakegym.simulator import BatchConditions, CommandedPressure, NumpyReferenceSimulator, Simulator
from brakegym.units import ZERO_CELSIUS_K

REPO = Path(__file__).resolve().parent.parent


def braking_batch(n_trains: int, step_s: float, simulator_class: type[Simulator], seed: int = 0):
    """``n_trains`` trains braking at 3.3 bar on every axle, the pressure already built up."""
    vehicle = cfg.load("vehicles", "emu_8axle")
    plant = train_plant(vehicle)
    rng = np.random.default_rng(seed)
    draw = draw_friction(
        rng,
        stochastic_friction(cfg.load("materials", vehicle.material)),
        scatter_partition(cfg.load("setups", "mcs-75-25")),
        n_trains,
        plant.disc_shape,
    )
    shape = (n_trains, *plant.disc_shape)
    conditions = BatchConditions(
        mass_kg=np.full(n_trains, vehicle.mass_kg("empty")),
        initial_speed_mps=rng.uniform(100.0, 160.0, n_trains) / 3.6,
        initial_mu=draw.initial_mu,
        power_coefficient_per_s=draw.power_coefficient_per_s,
        running_resistance_A_N=np.full(n_trains, vehicle.running_resistance.A_N),
        initial_friction_temperature_K=np.full(shape, vehicle.initial_disc_temperature_C + ZERO_CELSIUS_K),
        initial_disc_temperature_K=np.full(shape, vehicle.initial_disc_temperature_C + ZERO_CELSIUS_K),
        ambient_temperature_K=np.full(n_trains, vehicle.ambient_temperature_C + ZERO_CELSIUS_K),
    )
    cylinder = brake_cylinder(cfg.load("pneumatics", "EP"))
    pressure = CommandedPressure([cylinder] * n_trains, plant.n_axles, step_s, initial_pressure_bar=3.3)
    command = np.full((n_trains, plant.n_axles), 3.3)
    return simulator_class(plant, conditions, pressure, step_s), pressure, command


def seconds_per_step(n_trains: int, step_s: float, simulator_class: type[Simulator], steps: int) -> float:
    sim, pressure, command = braking_batch(n_trains, step_s, simulator_class)
    pressure.set_command(command)
    sim.step()
    start = time.perf_counter()
    for _ in range(steps):
        pressure.set_command(command)
        sim.step()
    elapsed = (time.perf_counter() - start) / steps
    assert sim.moving.all(), "a train stopped while being timed: the benchmark would time a different load"
    return elapsed


def median_seconds_per_step(n_trains: int, step_s: float, simulator_class: type[Simulator], budget_s: float) -> float:
    """Median over runs of at least 3 runs; a run is at most 15 s of braking (trains from
    100 km/h need about 25 s to stop) and about a fifth of ``budget_s``."""
    probe = seconds_per_step(n_trains, step_s, simulator_class, 5)
    steps = int(min(15.0 / step_s, max(10, budget_s / 5 / probe)))
    runs = max(3, min(30, int(budget_s / (probe * steps))))
    return statistics.median(seconds_per_step(n_trains, step_s, simulator_class, steps) for _ in range(runs))


def startup_seconds(cache_dir: str) -> tuple[float, float]:
    """(import of the kernels, warm_up) in a fresh Python process using ``cache_dir``."""
    code = (
        "import time; t0 = time.perf_counter(); from brakegym import kernel; t1 = time.perf_counter(); "
        "kernel.warm_up(); t2 = time.perf_counter(); print(t1 - t0, t2 - t1)"
    )
    environment = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    output = subprocess.run(
        [sys.executable, "-c", code], env=environment, cwd=REPO, check=True, capture_output=True, text=True
    ).stdout.split()
    return float(output[-2]), float(output[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--batches", type=int, nargs="+", default=[1, 16, 256, 4400])
    parser.add_argument("--step", type=float, default=0.1, help="integration step, s (the environments use 0.1)")
    parser.add_argument("--budget", type=float, default=3.0, help="seconds of timing per batch and simulator")
    parser.add_argument("--no-compile-timing", action="store_true")
    args = parser.parse_args()

    braking_batch(1, args.step, Simulator)[0].step()  # load the kernels before timing
    print(f"Simulator.step() with set_command, 16-disc trains braking, step {args.step} s (median of runs)")
    print(
        f"{'B':>6} {'numpy us/step':>14} {'compiled us/step':>17} {'numpy train-steps/s':>20} "
        f"{'compiled train-steps/s':>23} {'ratio':>7}"
    )
    for n in args.batches:
        reference = median_seconds_per_step(n, args.step, NumpyReferenceSimulator, args.budget)
        compiled = median_seconds_per_step(n, args.step, Simulator, args.budget)
        print(
            f"{n:>6} {1e6 * reference:>14.1f} {1e6 * compiled:>17.1f} {n / reference:>20,.0f} "
            f"{n / compiled:>23,.0f} {reference / compiled:>6.1f}x"
        )

    if not args.no_compile_timing:
        with tempfile.TemporaryDirectory() as cache_dir:
            import_s, compile_s = startup_seconds(cache_dir)
            cached_import_s, load_s = startup_seconds(cache_dir)
        print(
            f"first compile of all kernels (empty cache): {compile_s:.1f} s, once per machine (import {import_s:.1f} s)"
        )
        print(f"a later process: import {cached_import_s:.1f} s, kernels loaded from the cache in {load_s:.1f} s")


if __name__ == "__main__":
    main()
