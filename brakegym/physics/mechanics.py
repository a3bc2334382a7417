"""Longitudinal mechanics (paper Eqs. 11, 12, 14; spec Section 3).

Dynamometer: one disc unit brakes a flywheel of effective mass m_eff. Train: a single mass
m = sum of m_eff,i, perfect rolling, decelerated by the brake forces of all discs at the wheel and
by the running resistance F_R(v) = A + B v + C v^2.

Module-level functions are the equations (scalars or arrays, every parameter explicit), shared by
the numpy code and the simulator's compiled kernel (:mod:`brakegym.simulator.kernel`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .elementary import select


def sliding_speed_mps(speed_mps: np.ndarray, friction_radius_m: float, wheel_radius_m: float) -> np.ndarray:
    """Disc speed at the friction radius, v_fric = v r_fric / r_wheel (Eq. 12)."""
    return speed_mps * (friction_radius_m / wheel_radius_m)


def brake_force_N(friction_force_N: np.ndarray, friction_radius_m: float, wheel_radius_m: float) -> np.ndarray:
    """Retarding force at the wheel-rail contact of each train: sum over its discs of
    mu_i F_C,i r_fric / r_wheel (Eq. 11, the brake torque over the wheel radius).

    ``friction_force_N`` is mu F_C per disc with the trains on the last axis, e.g.
    (axles, discs per axle, trains); the result is (trains,).
    """
    per_disc = friction_force_N.reshape(-1, friction_force_N.shape[-1])
    return per_disc.sum(axis=0) * (friction_radius_m / wheel_radius_m)


def running_resistance_N(speed_mps, A_N, B_N_per_mps, C_N_per_mps2):
    """F_R(v) = A + B v + C v^2 (Eq. 14)."""
    return A_N + speed_mps * (B_N_per_mps + C_N_per_mps2 * speed_mps)


def effective_mu(retarding_force_N, nominal_resistance_N, weighted_clamp_force_N):
    """mu_eff of Eq. 15: (m d - F_R,nominal(v)) / sum (r_fric / r_wheel) F_C, with m d the actual
    retarding force; zero while no clamp force acts (``weighted_clamp_force_N`` = 0)."""
    clamped = weighted_clamp_force_N > 0.0
    denominator = select(clamped, weighted_clamp_force_N, 1.0)
    return select(clamped, (retarding_force_N - nominal_resistance_N) / denominator, 0.0)


@dataclass(frozen=True)
class RunningResistanceLaw:
    """F_R(v) = A + B v + C v^2 (Eq. 14). ``A_N`` may be an array, one value per train (the
    running-resistance scatter of the MCS set-ups)."""

    A_N: float | np.ndarray
    B_N_per_mps: float
    C_N_per_mps2: float

    @classmethod
    def none(cls) -> RunningResistanceLaw:
        """No resistance: the dynamometer."""
        return cls(A_N=0.0, B_N_per_mps=0.0, C_N_per_mps2=0.0)

    def force_N(self, speed_mps: np.ndarray, A_N: float | np.ndarray | None = None) -> np.ndarray:
        return running_resistance_N(speed_mps, self.A_N if A_N is None else A_N, self.B_N_per_mps, self.C_N_per_mps2)
