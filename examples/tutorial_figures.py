"""Figures of the brakegym teaching tutorial (docs/tutorial.md), one function per figure.

    python examples/tutorial_figures.py fig1          # one figure
    python examples/tutorial_figures.py all           # every figure
    python examples/tutorial_figures.py fig3 --out out/figs

Each function simulates what its figure shows, writes the PNG into the output folder (default
docs/tutorial/), prints the numbers the tutorial quotes and returns them as a dict, so the text
quotes measured values. Every run is seeded: the same command prints the same numbers.

All stops are the 16-disc ``emu_8axle`` train, empty, in emergency braking (3.3 bar on every
axle) with electro-pneumatic (EP) actuation unless a figure says otherwise.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from brakegym import config as cfg  # noqa: E402
from brakegym.applications import TrainApplication, train_stops  # noqa: E402
from brakegym.campaigns import train_monte_carlo  # noqa: E402
from brakegym.physics import FrictionDraw, FrictionLaw  # noqa: E402
from brakegym.plants import friction_law, nominal_draw, train_plant  # noqa: E402
from brakegym.statistics import sample_statistics  # noqa: E402
from brakegym.units import ZERO_CELSIUS_K  # noqa: E402

REPO_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_OUT_DIR = REPO_ROOT / "docs" / "tutorial"
VEHICLE = "emu_8axle"
FIGURE_DPI = 100  # the tutorial's figures must stay readable at this resolution
EMERGENCY_EMPTY_EP = dict(load="empty", brake_mode="emergency", actuation="EP")


def _emergency_stop(initial_speed_kmh: float) -> TrainApplication:
    return TrainApplication(initial_speed_kmh=initial_speed_kmh, **EMERGENCY_EMPTY_EP)


def _save(fig: plt.Figure, out_dir: Path, name: str) -> Path:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / name
    fig.savefig(path, dpi=FIGURE_DPI, bbox_inches="tight")
    plt.close(fig)
    return path


def _report(title: str, numbers: dict[str, object]) -> dict[str, object]:
    print(f"== {title}")
    for key, value in numbers.items():
        text = f"{value:.4g}" if isinstance(value, float) else str(value)
        print(f"  {key} = {text}")
    return numbers


def _speed_axis(ax: plt.Axes) -> None:
    # A stop runs from high to low speed: read the plot left to right as the stop goes on.
    ax.set_xlim(165, 0)
    ax.set_xlabel("speed v [km/h]")
    ax.grid(alpha=0.3)


def friction_law_terms_per_s(
    law: FrictionLaw,
    mu: np.ndarray,
    clamp_force_N: np.ndarray,
    sliding_speed_mps: np.ndarray,
    friction_temperature_K: np.ndarray,
) -> dict[str, np.ndarray]:
    """The four terms of Eq. 4, each as the magnitude of its contribution to dmu/dt (1/s):

        dmu/dt = - power - own_mu - temperature + clamp_force

    zero where the friction state is held (pads released or disc not sliding)."""
    evolves = (clamp_force_N > 0) & (sliding_speed_mps > law.min_sliding_speed_mps)
    friction_power_ratio = mu * clamp_force_N * sliding_speed_mps / law.reference_power_W
    terms = {
        "power": law.power_coefficient_per_s * friction_power_ratio**law.power_exponent,
        "own_mu": law.decay_coefficient_per_s * mu**law.decay_exponent,
        "temperature": law.temperature_coefficient_per_s
        * (mu * friction_temperature_K / law.reference_temperature_K) ** law.temperature_exponent,
        "clamp_force": law.clamp_force_coefficient_per_s
        * (clamp_force_N / law.reference_clamp_force_N) ** law.clamp_force_exponent,
    }
    return {name: np.where(evolves, value, 0.0) for name, value in terms.items()}


# ------------------------------------------------------------------------------------------------
# Figure 1


def fig1_speed_dependence(out_dir: Path = DEFAULT_OUT_DIR) -> dict[str, object]:
    """Same pressure, 100 and 160 km/h, nominal friction (DS): deceleration and mu over speed,
    the terms of Eq. 4 along both stops, and mu_s with the friction-power term switched off."""
    vehicle = cfg.load("vehicles", VEHICLE)
    material = cfg.load("materials", vehicle.material)
    law = friction_law(material)
    plant = train_plant(vehicle)
    initial_speeds_kmh = (100.0, 160.0)
    applications = [_emergency_stop(v0) for v0 in initial_speeds_kmh]
    stops = train_stops(vehicle, applications, record_every=1)
    trajectory = stops.trajectory
    assert trajectory is not None

    # The same stops with a = 0: what is left of the gap without the friction-power term.
    nominal = nominal_draw(material, len(applications), plant.disc_shape)
    without_power_term = FrictionDraw(nominal.initial_mu, np.zeros_like(nominal.power_coefficient_per_s))
    stops_without_power_term = train_stops(vehicle, applications, draw=without_power_term)

    # DS: all 16 discs are alike, disc 0 speaks for all.
    mu = trajectory.mu[:, :, 0]
    speed_kmh = trajectory.speed_mps * 3.6
    terms = friction_law_terms_per_s(
        law,
        mu,
        trajectory.clamp_force_N[:, :, 0],
        trajectory.speed_mps * plant.radius_ratio,
        trajectory.friction_temperature_C[:, :, 0] + ZERO_CELSIUS_K,
    )
    braking = (trajectory.clamp_force_N[:, :, 0] > 0) & (trajectory.speed_mps > 0)

    def at_speed(series: np.ndarray, stop: int, v_kmh: float) -> float:
        # Speed falls monotonically while braking: interpolate over the reversed braking part.
        part = braking[:, stop]
        return float(np.interp(v_kmh, speed_kmh[part, stop][::-1], series[part, stop][::-1]))

    compare_at_kmh = 80.0
    onset = {}
    for stop, v0 in enumerate(initial_speeds_kmh):
        # Full clamp force reached: the first sample at 95 % of the nominal clamp force.
        clamp = trajectory.clamp_force_N[:, stop, 0]
        onset[v0] = int(np.argmax(clamp >= 0.95 * clamp.max()))
    mu_s = stops.mu_s.mean(axis=1)
    mu_s_without = stops_without_power_term.mu_s.mean(axis=1)
    duration_s = stops.braking_time_s
    numbers: dict[str, object] = {
        "brake_pressure_bar": vehicle.brake_pressure_bar("emergency", "empty"),
        "mu_s_100": float(mu_s[0]),
        "mu_s_160": float(mu_s[1]),
        "mu_s_drop_percent": float(100 * (mu_s[0] - mu_s[1]) / mu_s[0]),
        "braking_distance_100_m": float(stops.braking_distance_m[0]),
        "braking_distance_160_m": float(stops.braking_distance_m[1]),
        "braking_time_100_s": float(duration_s[0]),
        "braking_time_160_s": float(duration_s[1]),
        "peak_friction_temperature_100_C": float(stops.peak_temperature_C[0]),
        "peak_friction_temperature_160_C": float(stops.peak_temperature_C[1]),
        f"deceleration_at_{compare_at_kmh:.0f}_kmh_from_100_mps2": at_speed(
            trajectory.deceleration_mps2, 0, compare_at_kmh
        ),
        f"deceleration_at_{compare_at_kmh:.0f}_kmh_from_160_mps2": at_speed(
            trajectory.deceleration_mps2, 1, compare_at_kmh
        ),
        f"mu_at_{compare_at_kmh:.0f}_kmh_from_100": at_speed(mu, 0, compare_at_kmh),
        f"mu_at_{compare_at_kmh:.0f}_kmh_from_160": at_speed(mu, 1, compare_at_kmh),
        "min_mu_160": float(mu[braking[:, 1], 1].min()),
        "speed_at_min_mu_160_kmh": float(speed_kmh[braking[:, 1], 1][np.argmin(mu[braking[:, 1], 1])]),
    }
    for stop, v0 in enumerate(initial_speeds_kmh):
        label = f"{v0:.0f}"
        i = onset[v0]
        for name, values in terms.items():
            numbers[f"{name}_term_at_full_clamp_{label}_per_s"] = float(values[i, stop])
        net = terms["clamp_force"] - terms["power"] - terms["own_mu"] - terms["temperature"]
        numbers[f"net_rate_at_full_clamp_{label}_per_s"] = float(net[i, stop])
        for name, values in terms.items():
            mean_rate = np.trapezoid(values[:, stop], trajectory.time_s) / duration_s[stop]
            numbers[f"{name}_term_mean_over_stop_{label}_per_s"] = float(mean_rate)
        numbers[f"friction_temperature_at_{compare_at_kmh:.0f}_kmh_from_{label}_C"] = at_speed(
            trajectory.friction_temperature_C[:, :, 0], stop, compare_at_kmh
        )
    numbers["mu_s_100_without_power_term"] = float(mu_s_without[0])
    numbers["mu_s_160_without_power_term"] = float(mu_s_without[1])
    numbers["mu_s_gap"] = float(mu_s[0] - mu_s[1])
    numbers["mu_s_gap_without_power_term"] = float(mu_s_without[0] - mu_s_without[1])

    styles = {100.0: dict(color="tab:blue", label="from 100 km/h"), 160.0: dict(color="tab:red", label="from 160 km/h")}
    fig, axes = plt.subplots(2, 2, figsize=(12, 8.5))
    ax_decel, ax_mu, ax_terms, ax_bars = axes.ravel()
    for stop, v0 in enumerate(initial_speeds_kmh):
        part = braking[:, stop]
        ax_decel.plot(speed_kmh[part, stop], trajectory.deceleration_mps2[part, stop], **styles[v0])
        ax_mu.plot(speed_kmh[part, stop], mu[part, stop], **styles[v0])
        ax_mu.axhline(mu_s[stop], color=styles[v0]["color"], ls=":", lw=1)
    ax_mu.text(160, mu_s[0] + 0.003, f"μ_s (Eq. 3) = {mu_s[0]:.3f}", color="tab:blue", fontsize=9)
    ax_mu.text(160, mu_s[1] - 0.008, f"μ_s (Eq. 3) = {mu_s[1]:.3f}", color="tab:red", fontsize=9)
    ax_decel.set_ylabel("deceleration [m/s²]")
    ax_decel.set_title("(a) same pressure, different deceleration")
    ax_decel.legend()
    ax_mu.set_ylabel("μ (every disc alike, DS)")
    ax_mu.set_title("(b) coefficient of friction along the stop")
    ax_mu.legend(loc="lower right")
    term_colors = {"power": "tab:orange", "own_mu": "tab:gray", "temperature": "tab:purple", "clamp_force": "tab:green"}
    term_labels = {
        "power": "−a (μ F_C v_fric / P_ref)^x",
        "own_mu": "−b μ^y",
        "temperature": "−c (μ T_fric / T_ref)^z",
        "clamp_force": "+d (F_C / F_ref)^r",
    }
    for name, values in terms.items():
        sign = 1.0 if name == "clamp_force" else -1.0
        for stop, v0 in enumerate(initial_speeds_kmh):
            part = braking[:, stop]
            ax_terms.plot(
                speed_kmh[part, stop],
                sign * values[part, stop],
                color=term_colors[name],
                ls="-" if v0 == 160.0 else "--",
                label=term_labels[name] if v0 == 160.0 else None,
            )
    net_rate = terms["clamp_force"] - terms["power"] - terms["own_mu"] - terms["temperature"]
    for stop, v0 in enumerate(initial_speeds_kmh):
        part = braking[:, stop]
        ax_terms.plot(
            speed_kmh[part, stop],
            net_rate[part, stop],
            color="k",
            lw=1.2,
            ls="-" if v0 == 160.0 else "--",
            label="dμ/dt, the sum" if v0 == 160.0 else None,
        )
    ax_terms.axhline(0, color="k", lw=0.5)
    ax_terms.set_ylabel("contribution to dμ/dt [1/s]")
    ax_terms.set_title("(c) terms of Eq. 4 (solid: from 160, dashed: from 100 km/h)")
    ax_terms.legend(fontsize=8, loc="center right")
    for ax in (ax_decel, ax_mu, ax_terms):
        _speed_axis(ax)
    x = np.arange(2)
    width = 0.35
    ax_bars.bar(x - width / 2, mu_s, width, label="model (a = 0.008 1/s)", color="tab:blue")
    ax_bars.bar(x + width / 2, mu_s_without, width, label="friction-power term off (a = 0)", color="tab:orange")
    for xi, value in zip(np.r_[x - width / 2, x + width / 2], np.r_[mu_s, mu_s_without]):
        ax_bars.text(xi, value + 0.004, f"{value:.3f}", ha="center", fontsize=9)
    ax_bars.set_xticks(x, [f"from {v0:.0f} km/h" for v0 in initial_speeds_kmh])
    ax_bars.set_ylim(0.25, 0.47)
    ax_bars.set_ylabel("μ_s, mean over distance (Eq. 3)")
    ax_bars.set_title("(d) which term makes the gap: switch the power term off")
    ax_bars.legend(fontsize=9, loc="upper right")
    ax_bars.grid(alpha=0.3, axis="y")
    fig.suptitle("Fig. 1: emu_8axle, empty, emergency 3.3 bar, EP, nominal friction (DS)")
    fig.tight_layout()
    numbers["figure"] = str(_save(fig, out_dir, "fig1_speed_dependence.png"))
    return _report("fig1: why 160 km/h brakes differently from 100 km/h", numbers)


# ------------------------------------------------------------------------------------------------
# Figure 2


def fig2_stop_and_cooling(out_dir: Path = DEFAULT_OUT_DIR, simulated_time_s: float = 900.0) -> dict[str, object]:
    """One DS stop from 160 km/h and the discs cooling at standstill: mu(t), the heat flows of the
    two-capacity model and T_fric, T_disc."""
    vehicle = cfg.load("vehicles", VEHICLE)
    plant = train_plant(vehicle)
    thermal = plant.thermal
    application = _emergency_stop(160.0)
    stop = train_stops(vehicle, [application], record_every=1, until_time_s=simulated_time_s)
    trajectory = stop.trajectory
    assert trajectory is not None
    time_s = trajectory.time_s - application.command_time_s  # since the brake command
    stop_s = float(stop.braking_time_s[0])
    speed_kmh = trajectory.speed_mps[:, 0] * 3.6
    mu = trajectory.mu[:, 0, 0]
    friction_C = trajectory.friction_temperature_C[:, 0, 0]
    disc_C = trajectory.disc_temperature_C[:, 0, 0]
    sliding_mps = trajectory.speed_mps[:, 0] * plant.radius_ratio
    flows = thermal.heat_flows(
        mu * trajectory.clamp_force_N[:, 0, 0] * sliding_mps,
        friction_C + ZERO_CELSIUS_K,
        disc_C + ZERO_CELSIUS_K,
        sliding_mps,
        vehicle.ambient_temperature_C + ZERO_CELSIUS_K,
    )

    ambient_C = vehicle.ambient_temperature_C
    peak_disc = int(np.argmax(disc_C))
    # Slow cooling at standstill: both capacities together lose heat through both surfaces.
    t1, t2 = time_s[peak_disc] + 60.0, time_s[-1]
    disc_at = lambda t: float(np.interp(t, time_s, disc_C))  # noqa: E731
    measured_cooling_time_constant_s = (t2 - t1) / np.log((disc_at(t1) - ambient_C) / (disc_at(t2) - ambient_C))
    standstill_conductance_W_per_K = (
        thermal.surface.h0_W_per_m2K * thermal.surface.area_m2
        + thermal.ventilation.h0_W_per_m2K * thermal.ventilation.area_m2
    )
    heat_capacity_J_per_K = thermal.friction_layer_heat_capacity_J_per_K + thermal.disc_body_heat_capacity_J_per_K
    # Fast equalisation: the friction layer empties into the body through G(T_m), Eq. 8.
    at_stop = int(np.searchsorted(time_s, stop_s))
    mean_at_stop_K = 0.5 * (friction_C[at_stop] + disc_C[at_stop]) + ZERO_CELSIUS_K
    equalisation_time_constant_s = thermal.friction_layer_heat_capacity_J_per_K / float(
        thermal.conductance_W_per_K_at(np.array(mean_at_stop_K))
    )
    gap = friction_C - disc_C
    after_stop = time_s >= stop_s
    within_5K = np.flatnonzero(after_stop & (np.abs(gap) < 5.0))
    braking = speed_kmh > 0
    numbers: dict[str, object] = {
        "braking_time_s": stop_s,
        "braking_distance_m": float(stop.braking_distance_m[0]),
        "mu_initial": float(mu[0]),
        "mu_min": float(mu[braking].min()),
        "time_of_mu_min_s": float(time_s[braking][np.argmin(mu[braking])]),
        "speed_at_mu_min_kmh": float(speed_kmh[braking][np.argmin(mu[braking])]),
        "mu_at_standstill": float(mu[at_stop]),
        "mu_at_end": float(mu[-1]),
        "peak_friction_temperature_C": float(friction_C.max()),
        "time_of_peak_friction_temperature_s": float(time_s[np.argmax(friction_C)]),
        "speed_at_peak_friction_temperature_kmh": float(speed_kmh[np.argmax(friction_C)]),
        "friction_temperature_at_standstill_C": float(friction_C[at_stop]),
        "disc_temperature_at_standstill_C": float(disc_C[at_stop]),
        "peak_disc_temperature_C": float(disc_C[peak_disc]),
        "time_of_peak_disc_temperature_s": float(time_s[peak_disc]),
        "time_layer_within_5K_of_body_s": float(time_s[within_5K[0]]) if len(within_5K) else float("nan"),
        "equalisation_time_constant_s": equalisation_time_constant_s,
        "friction_temperature_at_end_C": float(friction_C[-1]),
        "disc_temperature_at_end_C": float(disc_C[-1]),
        "end_time_s": float(time_s[-1]),
        "peak_friction_heat_flow_kW": float(flows.friction_W.max() / 1e3),
        "peak_conduction_heat_flow_kW": float(flows.conduction_W.max() / 1e3),
        "peak_heat_flow_to_air_kW": float((flows.surface_W + flows.ventilation_W).max() / 1e3),
        "friction_heat_per_disc_MJ": float(stop.friction_heat_J[0, 0] / 1e6),
        "heat_stored_at_end_per_disc_MJ": float(stop.stored_heat_J[0, 0] / 1e6),
        "heat_to_air_at_end_per_disc_MJ": float(stop.cooling_heat_J[0, 0] / 1e6),
        "measured_cooling_time_constant_s": float(measured_cooling_time_constant_s),
        "predicted_cooling_time_constant_s": heat_capacity_J_per_K / standstill_conductance_W_per_K,
    }

    fig, axes = plt.subplots(2, 2, figsize=(12, 8.5))
    ax_mu, ax_flows, ax_temps, ax_cooling = axes.ravel()
    zoom_s = 120.0
    ax_mu.plot(time_s, mu, color="tab:red", label="μ (every disc, DS)")
    ax_mu.set_ylabel("μ")
    ax_mu.set_title("(a) friction state: falls at high power, recovers, then held")
    ax_speed = ax_mu.twinx()
    ax_speed.plot(time_s, speed_kmh, color="k", lw=1, ls="--", label="speed")
    ax_speed.set_ylabel("speed [km/h]")
    lines = ax_mu.get_lines() + ax_speed.get_lines()
    ax_mu.legend(lines, [line.get_label() for line in lines], loc="center right")
    ax_flows.plot(time_s, flows.friction_W / 1e3, color="tab:red", label="Q_fric = ½ μ F_C v_fric (Eq. 6)")
    ax_flows.plot(time_s, flows.conduction_W / 1e3, color="tab:purple", label="Q_cond, layer → body (Eq. 7)")
    ax_flows.plot(time_s, flows.surface_W / 1e3, color="tab:cyan", label="Q_surf, layer → air (Eq. 9)")
    ax_flows.plot(time_s, flows.ventilation_W / 1e3, color="tab:blue", label="Q_vent, body → air")
    ax_flows.set_ylabel("heat flow per disc [kW]")
    ax_flows.set_title("(b) heat flows of the two-capacity model (Eq. 5)")
    ax_flows.legend(fontsize=8)
    for ax in (ax_temps, ax_cooling):
        ax.plot(time_s, friction_C, color="tab:red", label="T_fric, friction layer")
        ax.plot(time_s, disc_C, color="tab:blue", label="T_disc, disc body")
        ax.axhline(ambient_C, color="gray", lw=0.8, ls=":", label="ambient")
        ax.set_ylabel("temperature [°C]")
        ax.legend(fontsize=8, loc="upper right")
    ax_temps.set_title("(c) temperatures during the stop and the heat soak")
    ax_cooling.set_title(f"(d) cooling at standstill, {time_s[-1] / 60:.0f} min")
    for ax in (ax_mu, ax_flows, ax_temps):
        ax.set_xlim(0, zoom_s)
    for ax in axes.ravel():
        ax.axvline(stop_s, color="k", lw=0.8)
        ax.set_xlabel("time since brake command [s]")
        ax.grid(alpha=0.3)
    ax_temps.text(stop_s + 2, friction_C.max() * 0.95, "standstill", fontsize=9)
    fig.suptitle("Fig. 2: one stop from 160 km/h (emu_8axle, empty, emergency, EP, DS) and standstill")
    fig.tight_layout()
    numbers["figure"] = str(_save(fig, out_dir, "fig2_stop_and_cooling.png"))
    return _report("fig2: friction state and disc temperatures during and after a stop", numbers)


# ------------------------------------------------------------------------------------------------
# Figure 3


def fig3_sixteen_discs(
    out_dir: Path = DEFAULT_OUT_DIR, stops_per_setup: int = 300, seed: int = 2022, initial_speed_kmh: float = 120.0
) -> dict[str, object]:
    """Monte Carlo of the train in the set-ups shared, mcs-100 and mcs-75-25: spread of mu_s,eff
    and braking distance, with and without the running-resistance scatter."""
    vehicle = cfg.load("vehicles", VEHICLE)
    n_discs = vehicle.n_discs
    applications = [_emergency_stop(initial_speed_kmh)] * stops_per_setup
    setup_names = ("shared", "mcs-100", "mcs-75-25")
    # One seed for every set-up: the scatter module draws the same random numbers in each
    # (common random numbers), so the set-ups differ only in how the draw is shared by the discs.
    results: dict[tuple[str, bool], object] = {}
    for resistance_scatter in (False, True):
        for name in setup_names:
            setup = cfg.load("setups", name).model_copy(update={"resistance_scatter": resistance_scatter})
            summary, _, _ = train_monte_carlo(vehicle, applications, setup, seed=seed)
            results[(name, resistance_scatter)] = summary

    numbers: dict[str, object] = {
        "stops_per_setup": stops_per_setup,
        "seed": seed,
        "initial_speed_kmh": initial_speed_kmh,
    }
    std_mu = {}
    for (name, resistance_scatter), summary in results.items():
        suffix = "with_resistance_scatter" if resistance_scatter else "friction_only"
        mu_stats = sample_statistics(summary.mu_s_eff)
        distance_stats = sample_statistics(summary.braking_distance_m)
        std_mu[(name, resistance_scatter)] = mu_stats.std
        numbers[f"{name}_{suffix}_mu_s_eff_mean"] = mu_stats.mean
        numbers[f"{name}_{suffix}_mu_s_eff_std"] = mu_stats.std
        numbers[f"{name}_{suffix}_mu_s_eff_std_ci95"] = f"{mu_stats.std_ci95[0]:.5f}..{mu_stats.std_ci95[1]:.5f}"
        numbers[f"{name}_{suffix}_mu_s_eff_relative_std_percent"] = 100 * mu_stats.relative_std
        numbers[f"{name}_{suffix}_braking_distance_mean_m"] = distance_stats.mean
        numbers[f"{name}_{suffix}_braking_distance_std_m"] = distance_stats.std
    # Partition of sigma (spec Section 5): a global g sigma plus n individual i sigma average to
    # sqrt(g^2 + i^2 / n) sigma, if mu_s,eff responds linearly to the draws.
    mixed = cfg.load("setups", "mcs-75-25")
    mixed_prediction = np.sqrt(mixed.global_fraction**2 + mixed.individual_fraction**2 / n_discs)
    for resistance_scatter, suffix in ((False, "friction_only"), (True, "with_resistance_scatter")):
        shared = std_mu[("shared", resistance_scatter)]
        numbers[f"ratio_shared_over_mcs100_{suffix}"] = shared / std_mu[("mcs-100", resistance_scatter)]
        numbers[f"ratio_mcs7525_over_shared_{suffix}"] = std_mu[("mcs-75-25", resistance_scatter)] / shared
    # Eq. 15 subtracts the nominal running resistance, so a train's deviation of A shows up as
    # friction: sigma_A / sum_i (r_fric / r_wheel) F_C,i, once per train, whatever the discs do.
    plant = train_plant(vehicle)
    pressure_bar = vehicle.brake_pressure_bar("emergency", "empty")
    weighted_clamp_force_N = n_discs * plant.radius_ratio * float(plant.caliper.clamp_force_N(np.array(pressure_bar)))
    numbers["resistance_scatter_mu_s_eff_std_predicted"] = vehicle.running_resistance.A_sigma_N / weighted_clamp_force_N
    numbers["predicted_ratio_shared_over_mcs100"] = float(np.sqrt(n_discs))
    numbers["predicted_ratio_mcs7525_over_shared"] = float(mixed_prediction)

    colors = {"shared": "tab:red", "mcs-100": "tab:blue", "mcs-75-25": "tab:green"}
    labels = {
        "shared": f"shared: one draw for all {n_discs} discs",
        "mcs-100": "MCS-100: independent per disc",
        "mcs-75-25": "MCS-75/25",
    }
    fig, (ax_mu, ax_distance, ax_std) = plt.subplots(1, 3, figsize=(16, 5))
    mu_bins = np.linspace(0.318, 0.378, 41)
    distance_bins = np.linspace(515, 600, 41)
    for name in setup_names:
        summary = results[(name, False)]
        ax_mu.hist(
            summary.mu_s_eff,
            bins=mu_bins,
            histtype="step",
            lw=1.8,
            color=colors[name],
            label=f"{labels[name]}\nσ = {np.std(summary.mu_s_eff, ddof=1):.4f}",
        )
        ax_distance.hist(
            summary.braking_distance_m,
            bins=distance_bins,
            histtype="step",
            lw=1.8,
            color=colors[name],
            label=f"{name}: σ = {np.std(summary.braking_distance_m, ddof=1):.1f} m",
        )
    for ax in (ax_mu, ax_distance):
        ax.set_ylim(0, 1.35 * ax.get_ylim()[1])  # room for the legend above the peaks
    ax_mu.set_xlabel("μ_s,eff of the train (Eq. 15, mean over distance)")
    ax_mu.set_ylabel(f"stops (of {stops_per_setup})")
    ax_mu.set_title("(a) friction scatter only")
    ax_mu.legend(fontsize=8, loc="upper left")
    ax_distance.set_xlabel("braking distance [m]")
    ax_distance.set_title("(b) friction scatter only")
    ax_distance.legend(fontsize=8, loc="upper left")
    x = np.arange(len(setup_names))
    width = 0.38
    friction_only = [std_mu[(name, False)] for name in setup_names]
    with_resistance = [std_mu[(name, True)] for name in setup_names]
    ax_std.bar(
        x - width / 2, friction_only, width, color=[colors[n] for n in setup_names], label="friction scatter only"
    )
    ax_std.bar(
        x + width / 2,
        with_resistance,
        width,
        color=[colors[n] for n in setup_names],
        alpha=0.45,
        hatch="//",
        label="+ running-resistance scatter",
    )
    shared_std = std_mu[("shared", False)]
    predictions = [shared_std, shared_std / np.sqrt(n_discs), shared_std * mixed_prediction]
    ax_std.scatter(x - width / 2, predictions, marker="_", s=900, color="k", zorder=3, label="prediction from shared σ")
    for xi, value in zip(np.r_[x - width / 2, x + width / 2], friction_only + with_resistance):
        ax_std.text(xi, value + 0.0002, f"{value:.4f}", ha="center", fontsize=8)
    ax_std.set_xticks(x, setup_names)
    ax_std.set_ylabel("standard deviation of μ_s,eff")
    ratio = numbers["ratio_shared_over_mcs100_friction_only"]
    ax_std.set_title(f"(c) shared / MCS-100 = {ratio:.2f} (√16 = 4)")
    ax_std.legend(fontsize=8, loc="upper right")
    ax_std.grid(alpha=0.3, axis="y")
    fig.suptitle(
        f"Fig. 3: {stops_per_setup} stops per set-up from {initial_speed_kmh:.0f} km/h "
        "(emu_8axle, empty, emergency, EP), seed " + str(seed)
    )
    fig.tight_layout()
    numbers["figure"] = str(_save(fig, out_dir, "fig3_sixteen_discs.png"))
    return _report("fig3: sixteen discs average out independent scatter, not shared scatter", numbers)


# ------------------------------------------------------------------------------------------------
# Figure 4


def _import_pid_controller():
    # agents/ is a top-level folder of the checkout beside brakegym/, not part of the installed
    # package: make it importable however this script is started.
    if str(REPO_ROOT) not in sys.path:
        sys.path.insert(0, str(REPO_ROOT))
    from brakegym.agents.pid import PIDController

    return PIDController


def _run_station_stops(
    env, options: dict[str, object], seed: int, act: Callable, on_reset=None
) -> dict[str, np.ndarray]:
    """Run every train of a vector env (autoreset off) once until its episode ends. Returns per
    train the stop error where it ended and, per control step, the command of axle 1, the mean
    mu of its discs and whether it was still moving."""
    observation, info = env.reset(seed=seed, options=options)
    if on_reset is not None:
        on_reset(info)
    n = env.num_envs
    stop_error_m = np.full(n, np.nan)
    overran = np.zeros(n, dtype=bool)
    series: dict[str, list[np.ndarray]] = {"time_s": [], "command_bar": [], "mean_mu": [], "moving": []}
    while not env.ended.all():
        ended_before = env.ended
        observation, _, _, _, info = env.step(act(observation))
        ended_now = env.ended & ~ended_before
        stop_error_m[ended_now] = info["stop_error_m"][ended_now]
        overran[ended_now] = info["overran"][ended_now]
        series["time_s"].append(info["time_s"].copy())
        series["command_bar"].append(info["command_bar"][:, 0].copy())
        series["mean_mu"].append(info["mu"].reshape(n, -1).mean(axis=1))
        series["moving"].append(info["speed_mps"] > 0)
    result = {name: np.stack(values) for name, values in series.items()}
    result["stop_error_m"] = stop_error_m
    result["overran"] = overran
    return result


def _mean_while_moving(run: dict[str, np.ndarray], name: str) -> np.ndarray:
    """Per train, the mean of a recorded series over the control steps it was still moving."""
    moving = run["moving"]
    return (run[name] * moving).sum(axis=0) / moving.sum(axis=0)


def fig4_controller(
    out_dir: Path = DEFAULT_OUT_DIR,
    n_trains: int = 200,
    seed: int = 4,
    initial_speed_kmh: float = 80.0,
    distance_to_mark_m: float = 400.0,
) -> dict[str, object]:
    """StationStop under MCS-75/25: open-loop constant pressure against the PID baseline on the
    same trains, the same with friction scatter alone, and the PID's pressure command for a low-
    and a high-friction train."""
    from brakegym.envs import BrakeVectorEnv

    PIDController = _import_pid_controller()
    # Load and disc temperature fixed, so that the spread left is that of the MCS set-up's draws:
    # friction per disc and running resistance per train.
    scenario = {
        "initial_speed_kmh": initial_speed_kmh,
        "distance_to_mark_m": distance_to_mark_m,
        "load": "empty",
        "initial_disc_temperature_C": 50.0,
    }
    # The open-loop driver may run past the mark: lift the task's overrun limit so that every
    # train shows where it would have stood.
    no_overrun_limit = {"overrun_limit_m": 1e4}
    # The set-up goes into the env config, not the reset options: a reset option would replace
    # the friction-only variant that _without_resistance_scatter installs.
    scatter_setup = {"setup": "mcs-75-25"}
    vehicle = cfg.load("vehicles", VEHICLE)
    # Actions in [-1, 1] map linearly to 0..max cylinder pressure (brakegym/envs/env.py).
    max_pressure_bar = vehicle.max_cylinder_pressure_bar

    # The best constant pressure for the nominal train: a grid of pressures on DS trains, then
    # the pressure whose stop lands on the mark (the stop position falls as the pressure rises).
    probe_pressures_bar = np.linspace(1.0, 4.0, 31)
    probe_env = BrakeVectorEnv("station_stop", len(probe_pressures_bar), config=no_overrun_limit, autoreset=False)
    groups = probe_env.single_action_space.shape[0]
    probe_actions = np.repeat((2.0 * probe_pressures_bar / max_pressure_bar - 1.0)[:, None], groups, axis=1)
    probe = _run_station_stops(probe_env, {**scenario, "setup": "ds"}, seed, lambda _: probe_actions)
    open_loop_pressure_bar = float(np.interp(0.0, probe["stop_error_m"][::-1], probe_pressures_bar[::-1]))
    open_loop_actions = np.full((n_trains, groups), 2.0 * open_loop_pressure_bar / max_pressure_bar - 1.0)

    def open_loop_run(friction_only: bool) -> dict[str, np.ndarray]:
        env = BrakeVectorEnv("station_stop", n_trains, config={**no_overrun_limit, **scatter_setup}, autoreset=False)
        if friction_only:
            _without_resistance_scatter(env)
        return _run_station_stops(env, scenario, seed, lambda _: open_loop_actions)

    def pid_run(friction_only: bool) -> dict[str, np.ndarray]:
        env = BrakeVectorEnv("station_stop", n_trains, config=scatter_setup, autoreset=False)
        if friction_only:
            _without_resistance_scatter(env)
        controller = PIDController(env.config, env.observation_names)
        return _run_station_stops(env, scenario, seed, controller.act, on_reset=controller.reset)

    # Same seed, same options: every run brakes the very same trains (the same draws).
    open_loop, pid = open_loop_run(friction_only=False), pid_run(friction_only=False)
    open_loop_friction_only, pid_friction_only = open_loop_run(friction_only=True), pid_run(friction_only=True)
    nominal_env = BrakeVectorEnv("station_stop", 1, autoreset=False)
    nominal_controller = PIDController(nominal_env.config, nominal_env.observation_names)
    nominal = _run_station_stops(
        nominal_env, {**scenario, "setup": "ds"}, seed, nominal_controller.act, on_reset=nominal_controller.reset
    )

    # A train's friction level: its discs' mean mu over the braking part of the open-loop stop,
    # where every train had the same pressure, so that the level reflects the draws alone (under
    # the PID, mu also depends on the pressure the PID chose).
    friction_level = _mean_while_moving(open_loop_friction_only, "mean_mu")
    low, high = int(np.argmin(friction_level)), int(np.argmax(friction_level))
    pid_command_bar = _mean_while_moving(pid, "command_bar")
    pid_friction_only_command_bar = _mean_while_moving(pid_friction_only, "command_bar")

    plant = train_plant(vehicle)
    open_loop_clamp_force_N = float(plant.caliper.clamp_force_N(np.array(open_loop_pressure_bar)))
    open_loop_brake_force_N = friction_level.mean() * vehicle.n_discs * plant.radius_ratio * open_loop_clamp_force_N
    success_tolerance_m = nominal_env.config.success_tolerance_m
    numbers: dict[str, object] = {
        "n_trains": n_trains,
        "seed": seed,
        "initial_speed_kmh": initial_speed_kmh,
        "distance_to_mark_m": distance_to_mark_m,
        "required_deceleration_after_1p5s_mps2": (initial_speed_kmh / 3.6) ** 2
        / (2 * (distance_to_mark_m - 1.5 * initial_speed_kmh / 3.6)),
        "open_loop_pressure_bar": open_loop_pressure_bar,
        "success_tolerance_m": success_tolerance_m,
    }
    for label, run in (
        ("open_loop", open_loop),
        ("pid", pid),
        ("open_loop_friction_only", open_loop_friction_only),
        ("pid_friction_only", pid_friction_only),
    ):
        error = run["stop_error_m"]
        numbers[f"{label}_stop_error_mean_m"] = float(error.mean())
        numbers[f"{label}_stop_error_std_m"] = float(error.std(ddof=1))
        numbers[f"{label}_stop_error_max_abs_m"] = float(np.abs(error).max())
        numbers[f"{label}_within_tolerance_percent"] = float(100 * np.mean(np.abs(error) <= success_tolerance_m))
        numbers[f"{label}_overruns"] = int(run["overran"].sum())
    numbers.update(
        {
            "spread_reduction_factor": numbers["open_loop_stop_error_std_m"] / numbers["pid_stop_error_std_m"],
            "friction_level_min": float(friction_level.min()),
            "friction_level_max": float(friction_level.max()),
            "friction_level_relative_std_percent": float(100 * friction_level.std(ddof=1) / friction_level.mean()),
            # The running resistance scatters once per train (sigma_A); against the gentle brake
            # force of a station stop it weighs more than the friction scatter.
            "resistance_sigma_percent_of_brake_force": float(
                100 * vehicle.running_resistance.A_sigma_N / open_loop_brake_force_N
            ),
            "correlation_open_loop_error_vs_friction_level_friction_only": float(
                np.corrcoef(friction_level, open_loop_friction_only["stop_error_m"])[0, 1]
            ),
            "correlation_pid_command_vs_open_loop_error": float(
                np.corrcoef(open_loop["stop_error_m"], pid_command_bar)[0, 1]
            ),
            "low_friction_train_open_loop_stop_error_m": float(open_loop_friction_only["stop_error_m"][low]),
            "high_friction_train_open_loop_stop_error_m": float(open_loop_friction_only["stop_error_m"][high]),
            "low_friction_train_pid_mean_command_bar": float(pid_friction_only_command_bar[low]),
            "high_friction_train_pid_mean_command_bar": float(pid_friction_only_command_bar[high]),
            "nominal_train_pid_mean_command_bar": float(_mean_while_moving(nominal, "command_bar")[0]),
            "low_friction_train_pid_stop_error_m": float(pid_friction_only["stop_error_m"][low]),
            "high_friction_train_pid_stop_error_m": float(pid_friction_only["stop_error_m"][high]),
            # The brake needs about 1.5 s to build up; the PID pushes hard meanwhile.
            "pid_initial_peak_command_bar": float(
                np.where(pid["time_s"] <= 5.0, pid["command_bar"], 0.0).max(axis=0).mean()
            ),
            "pid_braking_time_mean_s": float(_braking_time_s(pid).mean()),
        }
    )

    fig, axes = plt.subplots(2, 2, figsize=(12, 8.5))
    ax_open, ax_pid, ax_command, ax_scatter = axes.ravel()
    open_bins = np.linspace(-25, 25, 41)
    ax_open.hist(
        open_loop["stop_error_m"],
        bins=open_bins,
        color="tab:gray",
        alpha=0.8,
        label=f"MCS-75/25: σ = {numbers['open_loop_stop_error_std_m']:.1f} m",
    )
    ax_open.hist(
        open_loop_friction_only["stop_error_m"],
        bins=open_bins,
        histtype="step",
        lw=2,
        color="tab:orange",
        label=f"friction scatter only: σ = {numbers['open_loop_friction_only_stop_error_std_m']:.1f} m",
    )
    ax_open.set_title(f"(a) open loop, constant {open_loop_pressure_bar:.2f} bar")
    pid_bins = np.linspace(-0.1, 0.1, 41)
    ax_pid.hist(
        pid["stop_error_m"],
        bins=pid_bins,
        color="tab:blue",
        alpha=0.8,
        label=f"MCS-75/25: σ = {100 * numbers['pid_stop_error_std_m']:.1f} cm",
    )
    ax_pid.hist(
        pid_friction_only["stop_error_m"],
        bins=pid_bins,
        histtype="step",
        lw=2,
        color="tab:orange",
        label=f"friction scatter only: σ = {100 * numbers['pid_friction_only_stop_error_std_m']:.1f} cm",
    )
    ax_pid.set_title("(b) PID (agents/pid.py); note the scale: centimetres")
    for ax in (ax_open, ax_pid):
        ax.axvspan(
            -success_tolerance_m,
            success_tolerance_m,
            color="tab:green",
            alpha=0.15,
            label=f"±{success_tolerance_m} m success band",
        )
        ax.set_xlabel("stop error: position − mark [m]")
        ax.set_ylabel(f"trains (of {n_trains})")
        ax.set_ylim(0, 1.3 * ax.get_ylim()[1])
        ax.legend(fontsize=8, loc="upper left")
        ax.grid(alpha=0.3)

    traces = (
        (pid_friction_only, low, "tab:red", f"low-friction train (μ level {friction_level[low]:.3f})"),
        (nominal, 0, "k", "nominal train (DS)"),
        (pid_friction_only, high, "tab:blue", f"high-friction train (μ level {friction_level[high]:.3f})"),
    )
    smoothing_steps = int(round(1.0 / nominal_env.config.control_step_s))
    for run, train, color, label in traces:
        moving_part = run["moving"][:, train]
        time_s = run["time_s"][moving_part, train]
        command = run["command_bar"][moving_part, train]
        # The measured deceleration is noisy and so is the command: a 1-s running mean shows its level.
        smoothed = np.convolve(command, np.ones(smoothing_steps) / smoothing_steps, mode="valid")
        ax_command.plot(time_s, command, color=color, lw=0.6, alpha=0.3)
        ax_command.plot(time_s[smoothing_steps - 1 :], smoothed, color=color, lw=1.8, label=label)
    ax_command.axhline(open_loop_pressure_bar, color="tab:gray", ls="--", label="open-loop constant pressure")
    ax_command.set_ylabel("PID pressure command [bar]")
    ax_command.set_xlabel("time since reset [s]")
    ax_command.set_title("(c) PID command, friction scatter only (faint: raw, bold: 1-s mean)", fontsize=11)
    ax_command.set_ylim(1.5, 2.6)
    ax_command.legend(fontsize=8, loc="upper right")
    ax_command.grid(alpha=0.3)
    ax_scatter.scatter(open_loop["stop_error_m"], pid_command_bar, s=12, color="tab:blue")
    ax_scatter.set_xlabel("where the train stops open loop: stop error [m]")
    ax_scatter.set_ylabel("PID command, mean while braking [bar]")
    ax_scatter.set_title(
        f"(d) MCS-75/25, each train twice: correlation {numbers['correlation_pid_command_vs_open_loop_error']:.2f}"
    )
    ax_scatter.grid(alpha=0.3)
    fig.suptitle(
        f"Fig. 4: StationStop, {n_trains} trains from {initial_speed_kmh:.0f} km/h, "
        f"mark at {distance_to_mark_m:.0f} m, empty, MCS-75/25 scatter"
    )
    fig.tight_layout()
    numbers["figure"] = str(_save(fig, out_dir, "fig4_controller.png"))
    return _report("fig4: a controller compensates friction scatter", numbers)


def _without_resistance_scatter(env) -> None:
    """Let ``env`` draw the friction scatter of its set-up but keep the running resistance at its
    nominal value. The env takes set-ups by name only, so its fleet's set-up is replaced."""
    fleet = env.core.fleet
    if not hasattr(fleet, "setup"):
        raise AttributeError("the env's fleet has no 'setup' any more: update _without_resistance_scatter")
    fleet.setup = fleet.setup.model_copy(update={"resistance_scatter": False})


def _braking_time_s(run: dict[str, np.ndarray]) -> np.ndarray:
    """Per train, the time of the last control step in which it was still moving."""
    return np.where(run["moving"], run["time_s"], 0.0).max(axis=0)


FIGURES: dict[str, Callable[..., dict[str, object]]] = {
    "fig1": fig1_speed_dependence,
    "fig2": fig2_stop_and_cooling,
    "fig3": fig3_sixteen_discs,
    "fig4": fig4_controller,
}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("figure", choices=[*FIGURES, "all"], help="which figure to make")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT_DIR, help=f"output folder (default {DEFAULT_OUT_DIR})")
    args = parser.parse_args(argv)
    names = list(FIGURES) if args.figure == "all" else [args.figure]
    for name in names:
        FIGURES[name](args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
