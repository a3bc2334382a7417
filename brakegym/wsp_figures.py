"""The figure of a WSP test (:func:`brakegym.wsp_test.wsp_test`), written as a PNG file."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .units import mps_to_kmh  # noqa: E402


def wsp_test_figure(traces: dict[str, np.ndarray], report: dict[str, object], path: str | Path) -> Path:
    """Four panels over time: the train's and each axle's speed; the cylinder pressures and the
    brake control's (supply) pressure; each axle's creep; each axle's adhesion used (creep force
    over its wheel load) against the available (the rail law's peak at that speed and load)."""
    time_s = traces["time_s"]
    n_axles = traces["wheel_speed_mps"].shape[1]
    colours = plt.cm.viridis(np.linspace(0.0, 0.9, n_axles))
    fig, axes = plt.subplots(4, 1, figsize=(9.0, 11.0), sharex=True)
    speed, pressure, creep, adhesion = axes

    speed.plot(time_s, mps_to_kmh(traces["speed_mps"]), color="black", linewidth=2, label="train")
    for axle, colour in enumerate(colours):
        speed.plot(
            time_s,
            mps_to_kmh(traces["wheel_speed_mps"][:, axle]),
            color=colour,
            linewidth=0.8,
            label=f"axle {axle + 1}",
        )
    speed.set_ylabel("speed [km/h]")
    speed.legend(fontsize=7, ncol=3)

    pressure.plot(
        time_s,
        traces["supply_bar"].max(axis=1),
        color="black",
        linewidth=2,
        linestyle="--",
        label="brake control (supply)",
    )
    for axle, colour in enumerate(colours):
        pressure.plot(time_s, traces["pressure_bar"][:, axle], color=colour, linewidth=0.8)
    pressure.set_ylabel("cylinder pressure [bar]")
    pressure.legend(fontsize=7)

    for axle, colour in enumerate(colours):
        creep.plot(time_s, 100.0 * traces["creep"][:, axle], color=colour, linewidth=0.8)
    creep.set_yscale("symlog", linthresh=1.0)
    creep.set_ylabel("creep [%]")

    for axle, colour in enumerate(colours):
        adhesion.plot(time_s, traces["adhesion_used"][:, axle], color=colour, linewidth=0.8)
    adhesion.plot(
        time_s,
        traces["adhesion_available"].mean(axis=1),
        color="black",
        linewidth=2,
        linestyle="--",
        label="available (peak of the law)",
    )
    adhesion.plot(
        time_s,
        traces["adhesion_demanded"].mean(axis=1),
        color="tab:red",
        linewidth=1,
        linestyle=":",
        label="brake demand",
    )
    top = 1.3 * float(np.nanmax(traces["adhesion_available"]))
    adhesion.set_ylim(0.0, top)
    adhesion.set_ylabel("adhesion F / Q")
    adhesion.set_xlabel("time from the brake command [s]")
    adhesion.legend(fontsize=7)

    fig.suptitle(
        f"WSP test: {report['vehicle']} {report['load']}, {report['rail']}, WSP {report['wsp']}, "
        f"{report['v0_kmh']:g} km/h\nstop {report['stop_distance_m']:.0f} m "
        f"(dry {report['dry_stop_distance_m']:.0f} m, "
        f"+{report['distance_extension_pct']:.0f} %), adhesion utilisation {report['adhesion_utilisation']:.2f}, "
        f"longest locked {report['max_locked_time_s']:.1f} s",
        fontsize=9,
    )
    fig.tight_layout()
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(target, dpi=120)
    plt.close(fig)
    return target
