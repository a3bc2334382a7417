"""Figures of the safety results, written as PNG files."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .etcs import KdryTable, confidence_label  # noqa: E402


def _steps(ax, edges_kmh: Sequence[float], values: np.ndarray, **style) -> None:
    """A value per speed band as a step line over speed."""
    ax.stairs(values, edges_kmh, baseline=None, **style)


def kdry_figure(tables: Sequence[KdryTable], path: str | Path) -> Path:
    """One panel per table: the nominal emergency deceleration of each speed band, the safe
    deceleration Kdry_rst x nominal at each computed confidence level with its 95 % interval, and
    the conventional calculation's deceleration."""
    fig, axes = plt.subplots(1, len(tables), figsize=(5.2 * len(tables), 4.0), sharey=True, squeeze=False)
    for ax, table in zip(axes[0], tables):
        edges = np.asarray(table.speed_edges_kmh)
        nominal = table.nominal_deceleration_mps2
        colours = plt.cm.viridis(np.linspace(0.0, 0.9, len(table.levels)))
        for column, (level, colour) in enumerate(zip(table.levels, colours)):
            safe = table.kdry[:, column] * nominal
            low, high = (table.kdry_ci95[:, column, end] * nominal for end in (0, 1))
            _steps(ax, edges, safe, color=colour, label=f"EBCL {confidence_label(level)}")
            centres = 0.5 * (edges[:-1] + edges[1:])
            ax.errorbar(centres, safe, yerr=[safe - low, high - safe], fmt="none", color=colour, capsize=2)
        _steps(ax, edges, nominal, color="black", linewidth=2, label="nominal (A_brake_emergency)")
        _steps(ax, edges, table.conventional_deceleration_mps2, color="tab:red", linestyle="--", label="conventional")
        ax.set_title(f"{table.vehicle}, load {table.load}", fontsize=10)
        ax.set_xlabel("speed [km/h]")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("deceleration [m/s²]")
    # Beside the panels: inside, the ten levels' lines would hide the lowest bands.
    axes[0][-1].legend(fontsize=7, loc="center left", bbox_to_anchor=(1.02, 0.5))
    fig.suptitle(
        f"Emergency brake deceleration per speed band and safe deceleration Kdry_rst x nominal ({tables[0].method})"
    )
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(target, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return target
