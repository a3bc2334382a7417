"""Cost per stop of a Monte-Carlo campaign with the wheel-rail adhesion option, against the same
campaign without it, in one process (issue 16: low adhesion at most 10x the dry campaign).

    python benchmarks/bench_adhesion.py [--batches 1 256] [--repeats 3] [--steps-batch 256]

For each batch size B: B emergency stops of the emu_8axle (empty, EP) from 100 to 160 km/h with
friction scatter (MCS-75/25), run to standstill by ``train_stops`` as a campaign runs them, three
ways: adhesion off (the compiled simulator), adhesion on a dry rail, adhesion on the low rail (the
wheels lock). The three are run alternately and the median over ``--repeats`` is reported (the
machine is shared), as seconds per stop and as ratios against the off run. Then the adhesion
step alone: train-steps per second of ``AdhesionSimulator.step()`` on ``--steps-batch`` trains
braking on the low rail (the environment's budget: 20,000 train-steps/s with 256 trains).
The kernels are compiled (or loaded from the cache) before anything is timed.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from brakegym import config as cfg
from brakegym.applications import TrainApplication, train_conditions, train_stops
from brakegym.physics import draw_friction
from brakegym.plants import brake_cylinder, scatter_partition, stochastic_friction, train_plant, wheel_rail_adhesion
from brakegym.simulator import CommandedPressure
from brakegym.simulator.wheelsets import AdhesionSimulator

REPO = Path(__file__).resolve().parent.parent
RAILS = (None, "dry", "low")
#: Enough trains for the kernels' threaded variants.
WARM_UP_BATCH = 40


def campaign(n_stops: int, seed: int = 0):
    """The applications and the friction draw of ``n_stops`` scattered emergency stops."""
    vehicle = cfg.load("vehicles", "emu_8axle")
    rng = np.random.default_rng(seed)
    draw = draw_friction(
        rng,
        stochastic_friction(cfg.load("materials", vehicle.material)),
        scatter_partition(cfg.load("setups", "mcs-75-25")),
        n_stops,
        train_plant(vehicle).disc_shape,
    )
    speeds_kmh = rng.uniform(100.0, 160.0, n_stops)
    applications = [TrainApplication("empty", "emergency", "EP", float(v)) for v in speeds_kmh]
    return vehicle, applications, draw


def seconds_per_stop(n_stops: int, rail: str | None) -> float:
    vehicle, applications, draw = campaign(n_stops)
    adhesion = None if rail is None else wheel_rail_adhesion(vehicle, cfg.load("rail_conditions", rail))
    start = time.perf_counter()
    train_stops(vehicle, applications, draw=draw, adhesion=adhesion)
    return (time.perf_counter() - start) / n_stops


def adhesion_steps_per_second(n_trains: int, n_steps: int = 50) -> float:
    """Train-steps per second of the adhesion step alone, trains braking on the low rail."""
    vehicle, applications, draw = campaign(n_trains)
    plant = train_plant(vehicle)
    conditions = train_conditions(
        vehicle,
        mass_kg=np.full(n_trains, vehicle.mass_kg("empty")),
        initial_speed_mps=np.array([a.initial_speed_kmh for a in applications]) / 3.6,
        draw=draw,
        running_resistance_A_N=np.full(n_trains, vehicle.running_resistance.A_N),
    )
    cylinder = brake_cylinder(cfg.load("pneumatics", "EP"))
    pressure = CommandedPressure([cylinder] * n_trains, plant.n_axles, 0.2, initial_pressure_bar=3.3)
    adhesion = wheel_rail_adhesion(vehicle, cfg.load("rail_conditions", "low"))
    sim = AdhesionSimulator(plant, conditions, pressure, adhesion, step_s=0.2)
    command = np.full((n_trains, plant.n_axles), 3.3)
    start = time.perf_counter()
    for _ in range(n_steps):
        pressure.set_command(command)
        sim.step()
    return n_trains * n_steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--batches", type=int, nargs="+", default=[1, 256])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--steps-batch", type=int, default=256)
    args = parser.parse_args()
    with cfg.config_path(REPO / "configs"):
        for rail in RAILS:  # compile, or load the kernels from the cache (one thread and several)
            seconds_per_stop(1, rail)
            seconds_per_stop(WARM_UP_BATCH, rail)
        print(f"{'B':>5} {'rail':>5} {'ms/stop':>9} {'x off':>7}")
        for n_stops in args.batches:
            times = {rail: [] for rail in RAILS}
            for _ in range(args.repeats):
                for rail in RAILS:
                    times[rail].append(seconds_per_stop(n_stops, rail))
            off = statistics.median(times[None])
            for rail in RAILS:
                median = statistics.median(times[rail])
                print(f"{n_stops:>5} {rail or 'off':>5} {1e3 * median:>9.3f} {median / off:>7.2f}")
        rate = adhesion_steps_per_second(args.steps_batch)
        print(f"adhesion step, low rail, {args.steps_batch} trains: {rate:,.0f} train-steps/s")


if __name__ == "__main__":
    main()
