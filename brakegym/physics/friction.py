"""Dynamic coefficient of friction of a disc unit (paper Eq. 4, Table 2; spec Section 1).

    dmu/dt = - a (mu F_C v_fric / P_ref)^x - b mu^y - c (mu T_fric / T_ref)^z + d (F_C / F_ref)^r

The first three terms lower mu with friction power, with mu itself and with the friction-layer
temperature; the last raises it with clamp force. The state evolves only while the pads are
clamped and the disc slides; otherwise it is held (spec rule, so that released brakes and
standstill stay defined).

The equations are the module-level functions (scalars or arrays, every parameter explicit): the
methods of :class:`FrictionLaw` call them with numpy arrays, and the simulator's compiled kernel
(:mod:`brakegym.simulator.kernel`) compiles the same functions, so the two cannot drift apart.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .elementary import fractional_power, select

ArrayLike = float | np.ndarray


def bounded_mu(mu, mu_min, mu_max):
    """mu kept inside [mu_min, mu_max] so that the fractional powers stay real (spec)."""
    return np.minimum(np.maximum(mu, mu_min), mu_max)


def friction_evolves(clamp_force_N, sliding_speed_mps, min_sliding_speed_mps):
    """Whether Eq. 4 applies: only while the pads are clamped and the disc slides (spec rule)."""
    return (clamp_force_N > 0.0) & (sliding_speed_mps > min_sliding_speed_mps)


def clamp_force_term_per_s(clamp_force_N, clamp_force_coefficient_per_s, clamp_force_exponent, reference_clamp_force_N):
    """+d (F_C / F_ref)^r, the term of Eq. 4 that raises mu with the clamp force. It depends on
    the clamp force alone, so the kernel evaluates it once per axle, not once per disc."""
    return clamp_force_coefficient_per_s * fractional_power(
        clamp_force_N * (1.0 / reference_clamp_force_N), clamp_force_exponent
    )


def friction_rate_per_s(
    mu,
    clamp_force_N,
    sliding_speed_mps,
    friction_temperature_K,
    clamp_force_term,
    power_coefficient_per_s,
    power_exponent,
    decay_coefficient_per_s,
    decay_exponent,
    temperature_coefficient_per_s,
    temperature_exponent,
    reference_power_W,
    reference_temperature_K,
):
    """dmu/dt of Eq. 4 for an already bounded ``mu`` while the unit evolves (see
    :func:`friction_evolves`); ``clamp_force_term`` is :func:`clamp_force_term_per_s` at
    ``clamp_force_N``. F_C is the unit's total clamp force (both pads), v_fric >= 0."""
    friction_power_ratio = mu * clamp_force_N * sliding_speed_mps * (1.0 / reference_power_W)
    rate = clamp_force_term - power_coefficient_per_s * fractional_power(friction_power_ratio, power_exponent)
    rate = rate - decay_coefficient_per_s * fractional_power(mu, decay_exponent)
    rate = rate - temperature_coefficient_per_s * fractional_power(
        mu * friction_temperature_K * (1.0 / reference_temperature_K), temperature_exponent
    )
    return rate


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

    def bounded(self, mu: np.ndarray) -> np.ndarray:
        """mu kept inside [mu_min, mu_max] so that the fractional powers stay real (spec)."""
        return bounded_mu(mu, self.mu_min, self.mu_max)

    def rate_per_s(
        self,
        mu: np.ndarray,
        clamp_force_N: np.ndarray,
        sliding_speed_mps: np.ndarray,
        friction_temperature_K: np.ndarray,
        power_coefficient_per_s: ArrayLike | None = None,
    ) -> np.ndarray:
        """dmu/dt of Eq. 4, zero where the unit is released or not sliding; ``mu`` is bounded
        first.

        ``clamp_force_N`` is the total clamp force of the unit (both pads, F_C = 2 F_N),
        ``sliding_speed_mps`` the disc speed at the friction radius (>= 0).
        """
        return self.rate_of_bounded_mu_per_s(
            self.bounded(mu), clamp_force_N, sliding_speed_mps, friction_temperature_K, power_coefficient_per_s
        )

    def rate_of_bounded_mu_per_s(
        self,
        mu: np.ndarray,
        clamp_force_N: np.ndarray,
        sliding_speed_mps: np.ndarray,
        friction_temperature_K: np.ndarray,
        power_coefficient_per_s: ArrayLike | None = None,
    ) -> np.ndarray:
        """:meth:`rate_per_s` for a ``mu`` the caller has bounded already (the simulator bounds
        it once for the forces and the rate)."""
        a = self.power_coefficient_per_s if power_coefficient_per_s is None else power_coefficient_per_s
        rate = friction_rate_per_s(
            mu,
            clamp_force_N,
            sliding_speed_mps,
            friction_temperature_K,
            clamp_force_term_per_s(
                clamp_force_N,
                self.clamp_force_coefficient_per_s,
                self.clamp_force_exponent,
                self.reference_clamp_force_N,
            ),
            a,
            self.power_exponent,
            self.decay_coefficient_per_s,
            self.decay_exponent,
            self.temperature_coefficient_per_s,
            self.temperature_exponent,
            self.reference_power_W,
            self.reference_temperature_K,
        )
        return select(friction_evolves(clamp_force_N, sliding_speed_mps, self.min_sliding_speed_mps), rate, 0.0)
