"""Dynamic coefficient of friction of a disc unit (paper Eq. 4, Table 2; spec Section 1).

    dmu/dt = - a (mu F_C v_fric / P_ref)^x - b mu^y - c (mu T_fric / T_ref)^z + d (F_C / F_ref)^r

The first three terms lower mu with friction power, with mu itself and with the friction-layer
temperature; the last raises it with clamp force. The state evolves only while the pads are
clamped and the disc slides; otherwise it is held (spec rule, so that released brakes and
standstill stay defined).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import FrictionMaterial

ArrayLike = float | np.ndarray


@dataclass(frozen=True)
class FrictionLaw:
    """Parameters of Eq. 4. ``power_coefficient_per_s`` (a) may be an array: the scatter of
    Eq. 13 gives each disc its own value."""

    power_coefficient_per_s: ArrayLike  # a
    power_exponent: float  # x
    decay_coefficient_per_s: float  # b
    decay_exponent: float  # y
    temperature_coefficient_per_s: float  # c
    temperature_exponent: float  # z
    clamp_force_coefficient_per_s: float  # d
    clamp_force_exponent: float  # r
    reference_power_W: float
    reference_temperature_K: float
    reference_clamp_force_N: float
    mu_min: float
    mu_max: float
    min_sliding_speed_mps: float

    @classmethod
    def from_config(cls, material: FrictionMaterial) -> "FrictionLaw":
        return cls(
            power_coefficient_per_s=material.power_coefficient_per_s,
            power_exponent=material.power_exponent,
            decay_coefficient_per_s=material.decay_coefficient_per_s,
            decay_exponent=material.decay_exponent,
            temperature_coefficient_per_s=material.temperature_coefficient_per_s,
            temperature_exponent=material.temperature_exponent,
            clamp_force_coefficient_per_s=material.clamp_force_coefficient_per_s,
            clamp_force_exponent=material.clamp_force_exponent,
            reference_power_W=material.reference_power_W,
            reference_temperature_K=material.reference_temperature_K,
            reference_clamp_force_N=material.reference_clamp_force_N,
            mu_min=material.mu_min,
            mu_max=material.mu_max,
            min_sliding_speed_mps=material.min_sliding_speed_mps,
        )

    def bounded(self, mu: np.ndarray) -> np.ndarray:
        """mu kept inside [mu_min, mu_max] so that the fractional powers stay real (spec)."""
        return np.clip(mu, self.mu_min, self.mu_max)

    def rate_per_s(
        self,
        mu: np.ndarray,
        clamp_force_N: np.ndarray,
        sliding_speed_mps: np.ndarray,
        friction_temperature_K: np.ndarray,
        power_coefficient_per_s: ArrayLike | None = None,
    ) -> np.ndarray:
        """dmu/dt of Eq. 4, zero where the unit is released or not sliding.

        ``clamp_force_N`` is the total clamp force of the unit (both pads, F_C = 2 F_N),
        ``sliding_speed_mps`` the disc speed at the friction radius (>= 0).
        """
        a = self.power_coefficient_per_s if power_coefficient_per_s is None else power_coefficient_per_s
        mu = self.bounded(mu)
        friction_power_ratio = mu * clamp_force_N * sliding_speed_mps * (1.0 / self.reference_power_W)
        rate = self.clamp_force_coefficient_per_s * (
            clamp_force_N * (1.0 / self.reference_clamp_force_N)
        ) ** self.clamp_force_exponent
        rate = rate - a * friction_power_ratio**self.power_exponent
        rate = rate - self.decay_coefficient_per_s * mu**self.decay_exponent
        rate = rate - self.temperature_coefficient_per_s * (
            mu * friction_temperature_K * (1.0 / self.reference_temperature_K)
        ) ** self.temperature_exponent
        sliding = (clamp_force_N > 0.0) & (sliding_speed_mps > self.min_sliding_speed_mps)
        return np.where(sliding, rate, 0.0)
