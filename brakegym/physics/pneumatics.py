"""Brake cylinder and caliper (spec Section 4; not in the paper's equations, assumed).

The cylinder pressure follows its command after a dead time with a first-order lag, release
alike. The caliper turns the pressure into the clamp force of each disc unit:
F_C = k_c max(p_c - p_0, 0).

The lag is solved exactly for a command held constant over an interval, so the simulator
reproduces it without time-step error.

Wheel-slide protection (WSP) valves sit between the brake control's pressure (the cylinder
pressure above, the *supply*) and the cylinder of one axle or bogie: at rest (``VALVE_APPLY``) the
cylinder takes the supply; ``VALVE_HOLD`` shuts it off; ``VALVE_DUMP`` vents it to the air. The
pressure moves at the valve's rates (:class:`WheelSlideProtectionValve`; docs/adhesion.md).
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


#: WSP valve commands, per axle or bogie and control step.
VALVE_DUMP, VALVE_HOLD, VALVE_APPLY = -1, 0, 1


def valve_pressure_after(
    pressure_bar, supply_bar, next_supply_bar, valve, elapsed_s, dump_rate_bar_per_s, refill_rate_bar_per_s
):
    """The cylinder pressure ``elapsed_s`` on behind a WSP valve held at ``valve``, the supply
    moving from ``supply_bar`` to ``next_supply_bar`` meanwhile.

    Dump: down at ``dump_rate_bar_per_s`` to 0. Hold: kept. Apply: a cylinder at the supply follows
    it (exactly: with the valves at rest the cylinder pressure is the supply's); one below it (after
    a dump or hold) refills at ``refill_rate_bar_per_s``, or as fast as the supply rises if that is
    faster, up to the supply. Never above the supply: a released brake vents through the valve
    whatever it is commanded."""
    dumped = np.maximum(pressure_bar - dump_rate_bar_per_s * elapsed_s, 0.0)
    rise = np.maximum(refill_rate_bar_per_s * elapsed_s, next_supply_bar - supply_bar)
    refilled = np.where(pressure_bar >= supply_bar, next_supply_bar, pressure_bar + rise)
    after = np.where(valve == VALVE_DUMP, dumped, np.where(valve == VALVE_APPLY, refilled, pressure_bar))
    return np.minimum(after, next_supply_bar)


@dataclass(frozen=True)
class WheelSlideProtectionValve:
    """The rates of a WSP valve unit (dump and refill of the cylinder pressure)."""

    dump_rate_bar_per_s: float
    refill_rate_bar_per_s: float

    def pressure_after(self, pressure_bar, supply_bar, next_supply_bar, valve, elapsed_s: float):
        """:func:`valve_pressure_after` with this valve's rates."""
        return valve_pressure_after(
            pressure_bar,
            supply_bar,
            next_supply_bar,
            valve,
            elapsed_s,
            self.dump_rate_bar_per_s,
            self.refill_rate_bar_per_s,
        )
