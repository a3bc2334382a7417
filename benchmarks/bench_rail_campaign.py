"""Cost per stop of the field campaign on a rail (``brakegym mcs --condition``), low rail with the
reference WSP against the dry rail (no WSP, its default), and both against the field campaign
without a rail, in one process (issue 16: the low-adhesion campaign at most 10x the dry one per stop).

    python benchmarks/bench_rail_campaign.py [--stops 48] [--repeats 3]

Each run is one chunk of ``--stops`` stops of the paper's field campaign (the first field
applications, emergency and service, several repetitions), run as ``brakegym mcs`` runs a chunk:
:class:`brakegym.campaigns.rail.RailFieldChunkTask` at the WSP's 20 ms step (dry without WSP, low
with the reference controller on axle valves), :class:`brakegym.campaigns.field.FieldChunkTask`
at 0.2 s for the campaign without a rail. The runs alternate and the median over ``--repeats`` is
reported (the machine is shared). The kernels are compiled (or loaded from the cache) before
anything is timed.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

from brakegym import config as cfg
from brakegym.agents.wsp import load_wsp_config
from brakegym.campaigns import field_applications
from brakegym.campaigns.chunks import Chunk
from brakegym.campaigns.field import FieldChunkTask
from brakegym.campaigns.rail import RailFieldChunkTask
from brakegym.defaults import DEFAULT_STEP_S

REPO = Path(__file__).resolve().parent.parent
RUNS = ("no rail", "dry", "low + WSP")
#: Enough trains for the kernels' threaded variants.
WARM_UP_BATCH = 40


def tasks(repetitions: int) -> dict[str, object]:
    campaign = cfg.load("campaigns", "field2022").model_copy(update={"repetitions": repetitions})
    vehicle = cfg.load("vehicles", campaign.vehicle)
    applications = tuple(field_applications(campaign))
    setup = cfg.load("setups", "mcs-75-25")
    valves = cfg.load("wsp_valves", "axle")
    return {
        "no rail": FieldChunkTask(vehicle, applications, repetitions, setup, 0, DEFAULT_STEP_S),
        "dry": RailFieldChunkTask(
            vehicle, applications, repetitions, setup, 0, cfg.load("rail_conditions", "dry"), valves, None
        ),
        "low + WSP": RailFieldChunkTask(
            vehicle, applications, repetitions, setup, 0, cfg.load("rail_conditions", "low"), valves, load_wsp_config()
        ),
    }


def seconds_per_stop(task, n_stops: int) -> float:
    start = time.perf_counter()
    task(Chunk(0, 0, n_stops))
    return (time.perf_counter() - start) / n_stops


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--stops", type=int, default=48)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    with cfg.config_path(REPO / "configs"):
        # Stops spread over brake modes and speeds: a few repetitions of each field application.
        runs = tasks(repetitions=max(1, args.stops // 24))
        for task in runs.values():  # compile: the kernels' serial and threaded variants
            task(Chunk(0, 0, 2))
            task(Chunk(0, 0, WARM_UP_BATCH))
        times = {name: [] for name in RUNS}
        for _ in range(args.repeats):
            for name in RUNS:
                times[name].append(seconds_per_stop(runs[name], args.stops))
        median = {name: statistics.median(times[name]) for name in RUNS}
        print(f"{'campaign':>10} {'ms/stop':>9} {'x no rail':>10} {'x dry':>7}")
        for name in RUNS:
            print(
                f"{name:>10} {1e3 * median[name]:>9.1f} {median[name] / median['no rail']:>10.1f} "
                f"{median[name] / median['dry']:>7.2f}"
            )


if __name__ == "__main__":
    main()
