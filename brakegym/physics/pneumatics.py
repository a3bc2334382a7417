"""Brake cylinder and caliper (spec Section 4; not in the paper's equations, assumed).

The cylinder pressure follows its command after a dead time with a first-order lag, release
alike. The caliper turns the pressure into the clamp force of each disc unit:
F_C = k_c max(p_c - p_0, 0).

The lag is solved exactly for a command held constant over an interval, so the simulator
reproduces it without time-step error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def clamp_force_from_pressure_N(pressure_bar, gain_N_per_bar, threshold_bar):
    """F_C = k_c max(p_c - p_0, 0) of one disc unit (spec Section 4)."""
    return gain_N_per_bar * np.maximum(pressure_bar - threshold_bar, 0.0)


@dataclass(frozen=True)
class BrakeCylinder:
    dead_time_s: float
    time_constant_s: float

    def lag_factor(self, elapsed_s: float) -> float:
        """exp(-t / tau): the share of the distance to the target still left after ``elapsed_s``."""
        return math.exp(-elapsed_s / self.time_constant_s)

    def pressure_after(self, pressure: np.ndarray, target: np.ndarray, elapsed_s: float) -> np.ndarray:
        """Exact lag response to a target held for ``elapsed_s`` (the dead time already spent)."""
        return target + (pressure - target) * self.lag_factor(elapsed_s)

    def dead_time_steps(self, step_s: float) -> int:
        """The dead time in whole integration steps; the simulator needs it to divide exactly so
        that the delayed command never switches inside a step."""
        steps = self.dead_time_s / step_s
        rounded = round(steps)
        if abs(steps - rounded) > 1e-9 * max(1.0, steps):
            raise ValueError(
                f"brake cylinder dead time {self.dead_time_s} s is not a whole number of time steps "
                f"of {step_s} s; choose a step that divides it"
            )
        return int(rounded)


@dataclass(frozen=True)
class CaliperLaw:
    gain_N_per_bar: float
    threshold_bar: float

    @classmethod
    def identity(cls) -> CaliperLaw:
        """For a rig whose actuator is commanded in clamp force directly (the dynamometer)."""
        return cls(gain_N_per_bar=1.0, threshold_bar=0.0)

    def clamp_force_N(self, pressure_bar: np.ndarray) -> np.ndarray:
        return clamp_force_from_pressure_N(pressure_bar, self.gain_N_per_bar, self.threshold_bar)

    def pressure_for_clamp_force_bar(self, clamp_force_N: float) -> float:
        """The cylinder pressure that gives ``clamp_force_N`` (for commands stated as force)."""
        return clamp_force_N / self.gain_N_per_bar + (self.threshold_bar if clamp_force_N > 0 else 0.0)
