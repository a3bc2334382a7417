"""Recovery numbers of brakegym.identification (README section): full parameter sets.

    python benchmarks/bench_identification.py [--seeds 1 2 3]

1. Deterministic: the 12 load cases' mean curves made (at 0.1 s) with known perturbed friction
   and thermal parameters plus white noise (mu 0.002, T 1 K); fit of the 'all' set (8 friction,
   4 thermal) at 0.2 s from the nominal material. Prints relative errors and coverage.
2. The bias of the mean-curve model: the 'friction' set fitted to the mean curves of an MCS-100
   dyno campaign with the nominal parameters (the model of a mean curve is the deterministic stop).
3. Stochastic: sigma of mu_0 and a from the 1950-stop dyno campaign (MCS-100), and the split from
   it plus 16-disc train stops (MCS-75/25, 2 conditions x 60).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd

from brakegym import campaigns
from brakegym import config as cfg
from brakegym.applications import TrainApplication, dyno_stops, train_stops
from brakegym.identification import DynoCurves, Series, dyno_curves_from_campaign, identify, load_identification_config
from brakegym.identification.parameters import ParameterSpace
from brakegym.identification.stochastic import dyno_spread_groups, field_spread_groups, identify_scatter
from brakegym.physics import draw_friction, draw_running_resistance
from brakegym.plants import scatter_partition, stochastic_friction

TRUTH = {
    "a": 0.0092,
    "b": 0.0115,
    "c": 0.038,
    "d": 0.040,
    "x": 0.95,
    "y": 0.56,
    "z": 1.65,
    "r": 0.34,
    "C_fric": 6500.0,
    "C_disc": 26000.0,
    "G_ref": 760.0,
    "h_surf": 33.0,
}
NOISE = {"mu": 0.002, "T_fric_C": 1.0}


def synthetic_curves(rig, material, disc, settings, seed: int) -> DynoCurves:
    space = ParameterSpace(tuple(settings.resolve(list(TRUTH))), material, disc)
    truth = np.array([TRUTH[s] for s in space.symbols])
    stops = dyno_stops(rig, rig.load_cases).stop_time_s
    grid = tuple(
        Series(case.name, channel, np.arange(1.0, np.floor(t)), np.zeros(int(np.floor(t)) - 1))
        for case, t in zip(rig.load_cases, stops)
        for channel in NOISE
    )
    clean = DynoCurves(rig, grid, step_s=0.1).predict(space, truth[None])[0]
    rng = np.random.default_rng(seed)
    return DynoCurves(
        rig,
        tuple(
            Series(s.case, s.channel, s.time_s, p + rng.normal(0, NOISE[s.channel], len(p)))
            for s, p in zip(grid, clean)
        ),
    )


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    rig, settings = cfg.load("rigs", "dynamometer"), load_identification_config()
    material, disc = cfg.load("materials", "ehret2022"), cfg.load("discs", "ehret2022_disc")

    for seed in args.seeds:
        start = time.perf_counter()
        result = identify(synthetic_curves(rig, material, disc, settings, seed), ["all"], material, disc, settings)
        print(f"\n[1] all 12 parameters, 12 load cases, noise seed {seed}: {time.perf_counter() - start:.0f} s")
        for p in result.parameters:
            truth = TRUTH[p.symbol]
            print(
                f"  {p.symbol:<7} truth {truth:<8g} est {p.estimate:<10.5g} "
                f"error {100 * (p.estimate / truth - 1):+6.1f} %  "
                f"+-{100 * p.relative_ci_half_width:5.1f} %  covered {p.ci95[0] <= truth <= p.ci95[1]!s:<5} "
                f"{'identifiable' if p.identifiable else 'NOT identifiable'}"
            )
        print("  weak directions:", result.weak_combinations or "none")

    start = time.perf_counter()
    campaign = campaigns.dyno_campaign(rig, cfg.load("setups", "mcs-100"), seed=7)
    result = identify(dyno_curves_from_campaign(campaign, rig), ["friction"], material, disc, settings)
    print(
        "\n[2] friction set from the mean curves of an MCS-100 campaign (nominal truth): "
        f"{time.perf_counter() - start:.0f} s"
    )
    for p in result.parameters:
        print(
            f"  {p.symbol}: {p.estimate:.5g} (nominal {p.start:.5g}, {100 * (p.estimate / p.start - 1):+.1f} %), "
            f"+-{100 * p.relative_ci_half_width:.1f} %, {'identifiable' if p.identifiable else 'NOT identifiable'}"
        )
    print("  channels:", [(c.channel, round(c.rms, 5), round(c.lag1_autocorrelation, 3)) for c in result.channels])

    true = material.model_copy(
        update={"scatter": cfg.FrictionScatter(initial_mu_sigma=0.013, power_coefficient_sigma_per_s=0.0007)}
    )
    cases = [case for case, _ in campaigns.dyno_applications(rig)]
    draw = draw_friction(
        np.random.default_rng(11),
        stochastic_friction(true),
        scatter_partition(cfg.load("setups", "mcs-100")),
        len(cases),
        (1, 1),
    )
    dyno = pd.DataFrame({"load_case": [c.name for c in cases], "mu_s": dyno_stops(rig, cases, draw).mu_s[:, 0]})
    vehicle, setup = cfg.load("vehicles", "emu_8axle"), cfg.load("setups", "mcs-75-25")
    apps = [TrainApplication("empty", "emergency", "EP", v0) for v0 in (100.0, 160.0) for _ in range(60)]
    rng = np.random.default_rng(12)
    partition = scatter_partition(setup)
    tdraw = draw_friction(
        rng, stochastic_friction(true), partition, len(apps), (vehicle.n_axles, vehicle.discs_per_axle)
    )
    resistance = draw_running_resistance(
        rng, vehicle.running_resistance.A_N, vehicle.running_resistance.A_sigma_N, partition, len(apps)
    )
    train = pd.DataFrame(
        {
            "brake_mode": "emergency",
            "load": "empty",
            "pad_set": "1",
            "actuation": "EP",
            "v0_kmh": [a.initial_speed_kmh for a in apps],
            "mu_s_eff": train_stops(vehicle, apps, tdraw, resistance).mu_s_eff,
        }
    )
    dyno_groups = dyno_spread_groups(dyno, rig)
    train_groups = field_spread_groups(train, vehicle)
    for label, groups in (
        ("dyno 1950 stops", dyno_groups),
        ("train 120 stops", train_groups),
        ("dyno + train", dyno_groups + train_groups),
    ):
        print(f"\n[3] scatter, {label} (truth sigma_mu0 0.013, sigma_a 0.0007, split 0.75 on the train)")
        print(identify_scatter(groups, settings).table())


if __name__ == "__main__":
    main()
