"""Figures in the spirit of the paper's Figs. 3, 4, 9, 12, 13, 15 and 16, written as PNG files."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .. import config as cfg  # noqa: E402
from ..applications import StopSummary, dyno_stops  # noqa: E402
from .dyno import DynoCampaignResult  # noqa: E402
from .field import FieldCampaignResult  # noqa: E402


def _save(fig: plt.Figure, out_dir: Path, name: str) -> Path:
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / name
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def _envelope_grid(result: DynoCampaignResult, quantity: str, ylabel: str, title: str) -> plt.Figure:
    names = list(result.envelopes)
    speeds = sorted({name.split("_")[0] for name in names})
    cases = sorted({name.split("_")[1] for name in names})
    fig, axes = plt.subplots(
        len(speeds), len(cases), figsize=(3.6 * len(cases), 2.4 * len(speeds)), sharey=True, squeeze=False
    )
    for name, frame in result.envelopes.items():
        speed, case = name.split("_")
        ax = axes[speeds.index(speed)][cases.index(case)]
        mean, std = frame[f"{quantity}_mean"], frame[f"{quantity}_std"].fillna(0.0)
        ax.fill_between(frame.t_s, mean - 3 * std, mean + 3 * std, color="tab:blue", alpha=0.25, label="mean ± 3σ")
        ax.plot(frame.t_s, mean, color="tab:blue", label="mean")
        ax.set_title(name, fontsize=9)
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time since brake onset [s]")
    for row in axes:
        row[0].set_ylabel(ylabel)
    axes[0][0].legend(fontsize=8)
    fig.suptitle(f"{title} ({result.setup}, {len(result.applications)} applications, Eq. 2)")
    return fig


def dyno_campaign_figures(result: DynoCampaignResult, out_dir: Path) -> list[Path]:
    out_dir = Path(out_dir)
    paths = [
        _save(
            _envelope_grid(result, "mu", "μ [-]", "Dynamometer: coefficient of friction"),
            out_dir,
            "fig03_mu_envelopes.png",
        ),
        _save(
            _envelope_grid(result, "T_fric_C", "T_fric [°C]", "Dynamometer: friction-surface temperature"),
            out_dir,
            "fig04_temperature_envelopes.png",
        ),
    ]
    table = result.applications
    fig, ax = plt.subplots(figsize=(10, 4))
    specimens = sorted(table.specimen.unique())
    cases = list(dict.fromkeys(table.load_case))
    width = 0.8 / len(specimens)
    for k, specimen in enumerate(specimens):
        sub = table[table.specimen == specimen].groupby("load_case", sort=False)["mu_s"]
        means, stds = sub.mean().reindex(cases), sub.std().reindex(cases).fillna(0.0)
        ax.errorbar(
            np.arange(len(cases)) + (k - len(specimens) / 2 + 0.5) * width,
            means,
            yerr=stds,
            fmt="o",
            ms=3,
            label=specimen,
        )
    ax.set_xticks(np.arange(len(cases)), cases, rotation=45, ha="right", fontsize=8)
    ax.set_ylabel("μ_s (Eq. 3) [-]")
    ax.set_title(f"Mean COF over distance per specimen and load case ({result.setup}), mean ± 1σ")
    ax.legend(fontsize=8, ncol=len(specimens))
    ax.grid(alpha=0.3)
    paths.append(_save(fig, out_dir, "fig12_mu_s_per_specimen.png"))

    fig, ax = plt.subplots(figsize=(6, 4))
    for case in sorted({name.split("_")[1] for name in cases}):
        sub = table[table.load_case.str.endswith(case)].groupby("v0_kmh")["s_m"]
        rel = 100 * sub.std() / sub.mean()
        ax.plot(rel.index, rel.to_numpy(), "o-", label=case)
    ax.set_xlabel("initial speed [km/h]")
    ax.set_ylabel("relative std of braking distance [%]")
    ax.set_title(f"Braking-distance scatter grows with speed ({result.setup})")
    ax.legend()
    ax.grid(alpha=0.3)
    paths.append(_save(fig, out_dir, "fig13_distance_scatter.png"))
    return paths


def mu_trend_figure(out_dir: Path, step_s: float = 0.1) -> Path:
    """Deterministic mu(t) at 100 and 160 km/h (paper Fig. 9): rising through the slow stop,
    falling first and recovering at low speed in the fast one."""
    rig = cfg.load("rigs", "dynamometer")
    names = ["V0100_Case1", "V0100_Case3", "V0160_Case1", "V0160_Case3"]
    summary = dyno_stops(rig, [rig.load_case(n) for n in names], step_s=step_s, record_every=1)
    traj = summary.trajectory
    assert traj is not None
    fig, (ax_t, ax_v) = plt.subplots(1, 2, figsize=(11, 4))
    for i, name in enumerate(names):
        braking = traj.speed_mps[:, i] > 0
        ax_t.plot(traj.time_s[braking], traj.mu[braking, i, 0], label=f"{name}: μ_s = {summary.mu_s[i, 0]:.3f}")
        ax_v.plot(3.6 * traj.speed_mps[braking, i], traj.mu[braking, i, 0], label=name)
    ax_t.set_xlabel("time [s]")
    ax_v.set_xlabel("speed [km/h]")
    ax_v.invert_xaxis()
    for ax in (ax_t, ax_v):
        ax.set_ylabel("μ [-]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Dynamic COF of deterministic dynamometer stops (paper Fig. 9)")
    return _save(fig, Path(out_dir), "fig09_mu_trend.png")


def field_campaign_figures(result: FieldCampaignResult, out_dir: Path) -> list[Path]:
    out_dir = Path(out_dir)
    table = result.applications
    summary = result.application_summary()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    for ax, mode in zip(axes, ("emergency", "service")):
        sub = table[table.brake_mode == mode]
        speeds = sorted(sub.v0_kmh.unique())
        ax.boxplot([sub[sub.v0_kmh == v].mu_s_eff for v in speeds], tick_labels=[f"{v:.0f}" for v in speeds])
        ax.set_title(f"{mode} brake")
        ax.set_xlabel("initial speed [km/h]")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("μ_s,eff (Eq. 15) [-]")
    fig.suptitle(f"Field campaign: effective COF of the train ({result.setup}, {len(table)} stops)")
    paths = [_save(fig, out_dir, "fig15_mu_eff.png")]

    fig, ax = plt.subplots(figsize=(11, 4.5))
    order = summary.sort_values(["brake_mode", "v0_kmh", "load", "actuation", "pad_set"]).reset_index(drop=True)
    colors = {"emergency": "tab:red", "service": "tab:blue"}
    low = np.array([ci[0] for ci in order.braking_distance_m_mean_ci95])
    high = np.array([ci[1] for ci in order.braking_distance_m_mean_ci95])
    mean = order.braking_distance_m_mean.to_numpy()
    std = order.braking_distance_m_std.to_numpy()
    for mode, color in colors.items():
        idx = np.flatnonzero(order.brake_mode == mode)
        ax.errorbar(idx, mean[idx], yerr=3 * std[idx], fmt="none", ecolor=color, alpha=0.35, label=f"{mode}: ± 3σ")
        ax.errorbar(
            idx,
            mean[idx],
            yerr=[mean[idx] - low[idx], high[idx] - mean[idx]],
            fmt="o",
            ms=3,
            color=color,
            label=f"{mode}: mean, 95 % CI",
        )
    ax.set_xlabel("field application (sorted by mode, speed, load, actuation, pad set)")
    ax.set_ylabel("braking distance from command [m]")
    ax.set_title(f"Field campaign: braking distance per application ({result.setup})")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    paths.append(_save(fig, out_dir, "fig16_braking_distance.png"))
    return paths


def demo_figure(summaries: dict[str, StopSummary], out_path: Path) -> Path:
    """The demo: emergency stops of the 16-disc train from several speeds with friction scatter."""
    fig, axes = plt.subplots(2, 2, figsize=(12, 8), constrained_layout=True)
    colors = ["tab:blue", "tab:red", "tab:green", "tab:purple"]
    for color, (label, summary) in zip(colors, summaries.items()):
        traj = summary.trajectory
        assert traj is not None
        n = traj.speed_mps.shape[1]
        for i in range(n):
            braking = np.r_[True, traj.speed_mps[:-1, i] > 0]
            kw = {"color": color, "alpha": 0.25, "lw": 0.8}
            axes[0][0].plot(traj.position_m[braking, i], 3.6 * traj.speed_mps[braking, i], **kw)
            axes[0][1].plot(traj.time_s[braking], traj.deceleration_mps2[braking, i], **kw)
            axes[1][0].plot(traj.time_s[braking], traj.mu[braking, i].mean(axis=1), **kw)
            axes[1][1].plot(traj.time_s[braking], traj.friction_temperature_C[braking, i].max(axis=1), **kw)
        axes[0][0].plot(
            [],
            [],
            color=color,
            label=(
                f"{label}: braking distance {summary.braking_distance_m.mean():.0f} "
                f"± {summary.braking_distance_m.std(ddof=1):.1f} m"
            ),
        )
        axes[1][0].plot(
            [],
            [],
            color=color,
            label=f"{label}: μ_s,eff {summary.mu_s_eff.mean():.3f} ± {summary.mu_s_eff.std(ddof=1):.3f}",
        )
    axes[0][0].set(xlabel="distance [m]", ylabel="speed [km/h]", title="Speed over distance")
    axes[0][1].set(xlabel="time [s]", ylabel="deceleration [m/s²]", title="Deceleration")
    axes[1][0].set(xlabel="time [s]", ylabel="μ, mean of 16 discs [-]", title="Dynamic coefficient of friction")
    axes[1][1].set(xlabel="time [s]", ylabel="T_fric, hottest disc [°C]", title="Friction-surface temperature")
    for row in axes:
        for ax in row:
            ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=8)
    axes[1][0].legend(fontsize=8)
    fig.suptitle("emu_8axle emergency stops, empty, EP, MCS-75/25 friction scatter")
    out_path = Path(out_path)
    return _save(fig, out_path.parent, out_path.name)
