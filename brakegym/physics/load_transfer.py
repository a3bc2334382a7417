"""Load transfer between and within bogies while the train decelerates (docs/adhesion.md, "Load
transfer").

Each car body's inertia force m_body a acts at its centre of gravity, h above the rail; the car's
two bogies react it, so the leading bogie gains m_body a h / L_pivot and the trailing one loses as
much (L_pivot the bogie-pivot spacing). Within each bogie, the bogie's own inertia force
m_bogie a at h_bogie is reacted by its axles: on a rigid frame with equally spaced axles at x_j
from its centre (positive forwards), axle j gains m_bogie a h_bogie x_j / sum x_k^2 (for two
axles, m_bogie a h_bogie / wheelbase). Every gain has its loss: the axle loads still sum to the
weight. Axle 0 leads (the simulator's axle offsets run backwards from the train's position).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["LoadTransfer"]


@dataclass(frozen=True)
class LoadTransfer:
    """The geometry and masses of a vehicle's cars that move load between its axles when it
    decelerates: the car body's centre-of-gravity height above the rail, the spacing of its two
    bogies' pivots, the bogie wheelbase, a complete bogie's mass (frame and wheelsets) and its
    centre-of-gravity height. Cars have two bogies each; the vehicle has ``bogies`` of
    ``axles_per_bogie`` axles, the first bogie leading."""

    body_cg_height_m: float
    bogie_pivot_spacing_m: float
    bogie_wheelbase_m: float
    bogie_mass_kg: float
    bogie_cg_height_m: float
    bogies: int
    axles_per_bogie: int

    def __post_init__(self) -> None:
        for name in ("body_cg_height_m", "bogie_pivot_spacing_m", "bogie_wheelbase_m", "bogie_cg_height_m"):
            if not getattr(self, name) > 0:
                raise ValueError(f"load transfer {name} = {getattr(self, name)}: must be positive")
        if not self.bogie_mass_kg >= 0:
            raise ValueError(f"load transfer bogie_mass_kg = {self.bogie_mass_kg}: must not be negative")
        if self.bogies < 2 or self.bogies % 2:
            raise ValueError(
                f"load transfer: {self.bogies} bogies; cars of two bogies each need an even number "
                "(articulated trains, bogies shared between cars, are not modelled)"
            )
        if self.axles_per_bogie < 1:
            raise ValueError(f"load transfer: axles_per_bogie = {self.axles_per_bogie}: need at least one")

    @property
    def n_cars(self) -> int:
        return self.bogies // 2

    @property
    def n_axles(self) -> int:
        return self.bogies * self.axles_per_bogie

    def car_body_mass_kg(self, body_mass_kg: np.ndarray) -> np.ndarray:
        """Each car's body mass (B,) of trains whose translating mass is ``body_mass_kg`` (B,): the
        train's share per car less its two bogies."""
        body = np.asarray(body_mass_kg, dtype=float) / self.n_cars - 2.0 * self.bogie_mass_kg
        if np.any(body <= 0):
            raise ValueError(
                f"load transfer: two bogies of {self.bogie_mass_kg} kg outweigh a car's share "
                f"{np.min(body_mass_kg) / self.n_cars:.0f} kg of the train's mass"
            )
        return body

    def axle_load_gain_N_per_mps2(self, body_mass_kg: np.ndarray) -> np.ndarray:
        """How much each axle's normal load (both wheels) rises per m/s^2 of the train's
        deceleration (A, B), trains of translating mass ``body_mass_kg`` (B,): positive on the
        leading bogie of each car and the leading axle of each bogie; each car's column sums to 0."""
        body = self.car_body_mass_kg(body_mass_kg)
        k = self.axles_per_bogie
        between = body * (self.body_cg_height_m / self.bogie_pivot_spacing_m) / k
        # Axle positions along the bogie from its centre, the leading axle forwards (x > 0).
        if k > 1:
            x = self.bogie_wheelbase_m * (0.5 - np.arange(k) / (k - 1))
            within = self.bogie_mass_kg * self.bogie_cg_height_m * x / np.sum(x * x)
        else:
            within = np.zeros(1)
        gain = np.empty((self.n_axles, np.size(body)))
        for bogie in range(self.bogies):
            sign = 1.0 if bogie % 2 == 0 else -1.0
            for axle in range(k):
                gain[bogie * k + axle] = sign * between + within[axle]
        return gain
