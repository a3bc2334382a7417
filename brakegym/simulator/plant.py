"""What a simulation brakes: the plant (shared by the batch) and the per-application conditions."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..physics import CaliperLaw, DiscThermalModel, FrictionLaw, RunningResistanceLaw


@dataclass(frozen=True)
class Plant:
    """What is braked and by which physics: the dynamometer rig or a train.

    Geometry and laws are shared by the whole batch; what differs per application (mass, initial
    state, scattered parameters) is in :class:`BatchConditions`. :mod:`brakegym.plants` builds
    plants from configs.
    """

    name: str
    n_axles: int
    discs_per_axle: int
    wheel_radius_m: float
    friction_radius_m: float
    friction: FrictionLaw
    thermal: DiscThermalModel
    caliper: CaliperLaw
    running_resistance: RunningResistanceLaw
    max_command: float  # largest cylinder pressure command, bar (clamp force in N on the rig)

    @property
    def n_discs(self) -> int:
        return self.n_axles * self.discs_per_axle

    @property
    def disc_shape(self) -> tuple[int, int]:
        return (self.n_axles, self.discs_per_axle)

    @property
    def radius_ratio(self) -> float:
        """The ratio r_fric / r_wheel, which is the sliding speed per train speed and the brake force per
        friction force."""
        return self.friction_radius_m / self.wheel_radius_m


@dataclass
class BatchConditions:
    """Per-application values of a batch of B applications.

    Disc arrays broadcast to (B, axles, discs per axle), train arrays to (B,). Temperatures in
    kelvin.
    """

    mass_kg: np.ndarray
    initial_speed_mps: np.ndarray
    initial_mu: np.ndarray
    power_coefficient_per_s: np.ndarray
    running_resistance_A_N: np.ndarray
    initial_friction_temperature_K: np.ndarray
    initial_disc_temperature_K: np.ndarray
    ambient_temperature_K: np.ndarray

    @property
    def n_trains(self) -> int:
        return int(np.shape(self.mass_kg)[0])
