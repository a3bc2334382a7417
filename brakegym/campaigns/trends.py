"""The paper's published trends, recomputed from the campaigns (spec Section 8).

``brakegym trends`` prints them; the README quotes its output.

1. mu_s falls by about 16 % of its maximum from 100 to 160 km/h (DS dynamometer stops).
2. The braking-distance scatter grows with speed (single-disc Monte Carlo, MCS-100 on the rig).
3. For 16 discs, independent scatter (MCS-100) shrinks the spread of mu_s,eff by about sqrt(16)
   against a single disc (all discs sharing one draw), while MCS-75/25 keeps about three quarters
   of it. The sqrt(n) law is compared with the running-resistance scatter switched off, because
   that scatter, not friction, dominates MCS-100's spread.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import config as cfg
from ..applications import TrainApplication
from ..defaults import DEFAULT_STEP_S
from ..execution import Executor
from ..statistics import sample_statistics
from .dyno import dyno_campaign
from .field import train_monte_carlo


@dataclass
class Trends:
    mu_s_by_speed: dict[float, float]  # DS, mean over the load cases of a speed group
    mu_s_drop_percent: float  # (max - mu_s at 160) / max, percent
    distance_rel_std_by_speed: dict[float, float]  # MCS-100 dynamometer, percent
    mu_eff_rel_std: dict[str, float]  # train set-ups, percent
    sqrt_n_ratio: float  # rel std shared / MCS-100, resistance scatter off
    partial_ratio: float  # rel std MCS-75/25 / shared, resistance scatter off
    n_discs: int
    train_applications: int

    def as_dict(self) -> dict[str, object]:
        return {
            "mu_s_by_speed": {str(k): v for k, v in self.mu_s_by_speed.items()},
            "mu_s_drop_percent": self.mu_s_drop_percent,
            "braking_distance_rel_std_percent_by_speed": {str(k): v for k, v in self.distance_rel_std_by_speed.items()},
            "mu_s_eff_rel_std_percent": self.mu_eff_rel_std,
            "sqrt_n_ratio": self.sqrt_n_ratio,
            "sqrt_n_expected": float(np.sqrt(self.n_discs)),
            "mcs_75_25_over_shared": self.partial_ratio,
            "train_applications_per_setup": self.train_applications,
        }

    def table(self) -> str:
        lines = ["Paper trends (spec Section 8)", ""]
        lines.append("1. DS dynamometer: mean mu_s per speed group")
        for v, mu in self.mu_s_by_speed.items():
            lines.append(f"   {v:5.0f} km/h  mu_s = {mu:.4f}")
        lines.append(f"   drop from 100 to 160 km/h: {self.mu_s_drop_percent:.1f} % of the maximum (paper: about 16 %)")
        lines.append("2. MCS-100 dynamometer: relative std of the braking distance")
        for v, rs in self.distance_rel_std_by_speed.items():
            lines.append(f"   {v:5.0f} km/h  {rs:.2f} %")
        lines.append("   (paper: about 2 % at 100 km/h and 5 % at 160 km/h; spec reference: 2 % and 3.5 %)")
        lines.append(
            f"3. Train, 120 km/h, empty, emergency, EP, {self.train_applications} applications per set-up: "
            "relative std of mu_s,eff"
        )
        for name, rs in self.mu_eff_rel_std.items():
            lines.append(f"   {name:<34s} {rs:.2f} %")
        lines.append(
            f"   shared / MCS-100 (no resistance scatter) = {self.sqrt_n_ratio:.2f}  "
            f"(sqrt({self.n_discs}) = {np.sqrt(self.n_discs):.0f})"
        )
        lines.append(
            f"   MCS-75/25 / shared (no resistance scatter) = {self.partial_ratio:.2f}  (about three quarters)"
        )
        return "\n".join(lines)


def compute_trends(
    seed: int = 2022,
    train_applications: int = 400,
    step_s: float = DEFAULT_STEP_S,
    executor: Executor | None = None,
) -> Trends:
    """The trends from campaigns of ``seed`` on ``executor`` (default: this process)."""
    rig = cfg.load("rigs", "dynamometer")
    ds = dyno_campaign(rig, cfg.load("setups", "ds"), seed, step_s=step_s, executor=executor).applications
    by_speed = ds.groupby("v0_kmh")["mu_s"].mean()
    mu_s_by_speed = {float(v): float(m) for v, m in by_speed.items()}
    drop = 100.0 * (by_speed.max() - by_speed.loc[160.0]) / by_speed.max()

    mcs = dyno_campaign(rig, cfg.load("setups", "mcs-100"), seed, step_s=step_s, executor=executor).applications
    rel_std = mcs.groupby(["v0_kmh", "load_case"])["s_m"].agg(lambda s: s.std(ddof=1) / s.mean())
    distance_rel_std = {float(v): 100.0 * float(rel_std.loc[v].mean()) for v in sorted(mcs.v0_kmh.unique())}

    vehicle = cfg.load("vehicles", "emu_8axle")
    app = TrainApplication(load="empty", brake_mode="emergency", actuation="EP", initial_speed_kmh=120.0)
    mu_eff: dict[str, float] = {}
    for setup_name in ("shared", "mcs-100", "mcs-75-25"):
        setup = cfg.load("setups", setup_name)
        for resistance in (True, False):
            variant = setup.model_copy(update={"resistance_scatter": resistance})
            summary, _, _ = train_monte_carlo(
                vehicle, [app] * train_applications, variant, seed, step_s, executor=executor
            )
            label = f"{setup_name}{'' if resistance else ' (no resistance scatter)'}"
            mu_eff[label] = 100.0 * sample_statistics(summary.mu_s_eff).relative_std
    return Trends(
        mu_s_by_speed=mu_s_by_speed,
        mu_s_drop_percent=float(drop),
        distance_rel_std_by_speed=distance_rel_std,
        mu_eff_rel_std=mu_eff,
        sqrt_n_ratio=mu_eff["shared (no resistance scatter)"] / mu_eff["mcs-100 (no resistance scatter)"],
        partial_ratio=mu_eff["mcs-75-25 (no resistance scatter)"] / mu_eff["shared (no resistance scatter)"],
        n_discs=vehicle.n_discs,
        train_applications=train_applications,
    )
