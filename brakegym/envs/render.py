"""Rendering of a single-train environment: a dashboard (``rgb_array``, ``human``) and a text
line (``ansi``).

The dashboard shows speed over distance (with the mark of a station stop), deceleration and its
demand over time, the cylinder pressures and the friction-surface temperature of every disc.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..units import mps_to_kmh


class Dashboard:
    def __init__(self, env: Any):
        self.env = env
        self.figure = None
        self.clear()

    def clear(self) -> None:
        self.rows: list[dict[str, Any]] = []

    def record(self, observation: np.ndarray, info: dict[str, Any]) -> None:
        self.rows.append(
            {
                "time_s": info["time_s"],
                "speed_kmh": mps_to_kmh(info["speed_mps"]),
                "position_m": info["position_m"],
                "deceleration_mps2": info["deceleration_mps2"],
                "demand_mps2": info.get("demand_mps2", np.nan),
                "pressure_bar": np.array(info["cylinder_pressure_bar"], copy=True),
                "temperature_C": np.array(info["friction_temperature_C"], copy=True),
                "mark_m": info.get("mark_m", np.nan),
                "distance_to_go_m": info.get("distance_to_go_m", np.nan),
            }
        )

    def text(self) -> str:
        row = self.rows[-1]
        parts = [
            f"t={row['time_s']:6.1f} s",
            f"v={row['speed_kmh']:6.1f} km/h",
            f"a={row['deceleration_mps2']:5.2f} m/s2",
            f"p=[{' '.join(f'{p:.2f}' for p in row['pressure_bar'])}] bar",
            f"T_max={row['temperature_C'].max():6.1f} C",
        ]
        if np.isfinite(row["distance_to_go_m"]):
            parts.insert(3, f"to go={row['distance_to_go_m']:8.2f} m")
        if np.isfinite(row["demand_mps2"]):
            parts.insert(3, f"demand={row['demand_mps2']:4.2f} m/s2")
        return "  ".join(parts) + "\n"

    def _draw(self, figure) -> None:
        figure.clear()
        axes = figure.subplots(2, 2)
        rows = self.rows
        time = np.array([r["time_s"] for r in rows])
        position = np.array([r["position_m"] for r in rows])
        speed = np.array([r["speed_kmh"] for r in rows])
        ax = axes[0, 0]
        ax.plot(position, speed, color="C0")
        mark = rows[-1]["mark_m"]
        if np.isfinite(mark):
            ax.axvline(mark, color="C3", linestyle="--", label="mark")
            ax.legend(loc="upper right")
        ax.set_xlabel("distance (m)")
        ax.set_ylabel("speed (km/h)")
        ax = axes[0, 1]
        ax.plot(time, [r["deceleration_mps2"] for r in rows], label="deceleration")
        demand = np.array([r["demand_mps2"] for r in rows])
        if np.isfinite(demand).any():
            ax.step(time, demand, where="post", color="C3", label="demand")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("deceleration (m/s$^2$)")
        ax.legend(loc="upper right")
        ax = axes[1, 0]
        pressures = np.array([r["pressure_bar"] for r in rows])
        ax.plot(time, pressures, linewidth=0.8)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("cylinder pressure (bar)")
        ax = axes[1, 1]
        temperatures = rows[-1]["temperature_C"]
        ax.bar(np.arange(1, len(temperatures) + 1), temperatures, color="C1")
        ax.set_xlabel("disc")
        ax.set_ylabel("friction-surface temperature (°C)")
        figure.suptitle(f"{self.env.config.name}: t = {time[-1]:.1f} s")
        figure.tight_layout()

    def rgb_array(self) -> np.ndarray:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        figure = Figure(figsize=(8, 6), dpi=80)
        canvas = FigureCanvasAgg(figure)
        self._draw(figure)
        canvas.draw()
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()

    def show(self) -> None:
        import matplotlib.pyplot as plt

        if self.figure is None:
            plt.ion()
            self.figure = plt.figure(figsize=(8, 6))
        self._draw(self.figure)
        self.figure.canvas.draw_idle()
        plt.pause(0.001)

    def close(self) -> None:
        if self.figure is not None:
            import matplotlib.pyplot as plt

            plt.close(self.figure)
            self.figure = None
