"""Disc temperature: two lumped heat capacities per disc (paper Eqs. 5-10, Table 3; spec Section 2).

    C_fric dT_fric/dt = Q_fric - Q_surf - Q_cond
    C_disc dT_disc/dt = Q_cond - Q_vent
    Q_fric = 0.5 mu F_C v_fric                       (Eq. 6: the disc's share of the friction power)
    Q_cond = G(T_m) (T_fric - T_disc),  T_m = (T_fric + T_disc) / 2,  G floored at G_min  (Eqs. 7, 8)
    Q_surf = h_surf(v_fric) A_surf (T_fric - T_inf)  (Eq. 9), Q_vent alike for the disc body
    h(v_fric) = h0 + (h_ref - h0) (v_fric / v_ref)^ex (Eq. 10)

Temperatures in kelvin, heat flows in watts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import ConvectionLaw, DiscThermal


@dataclass(frozen=True)
class HeatFlows:
    """Heat flows of one evaluation, W; arrays broadcast over (trains, axles, discs)."""

    friction_W: np.ndarray  # Q_fric, into the friction layer
    surface_W: np.ndarray  # Q_surf, friction layer to air
    conduction_W: np.ndarray  # Q_cond, friction layer to disc body
    ventilation_W: np.ndarray  # Q_vent, disc body to air


@dataclass(frozen=True)
class DiscThermalModel:
    friction_layer_heat_capacity_J_per_K: float
    disc_body_heat_capacity_J_per_K: float
    conductance_W_per_K: float
    conductance_slope_W_per_K2: float
    conductance_reference_temperature_K: float
    conductance_min_W_per_K: float
    heat_fraction_into_disc: float
    reference_sliding_speed_mps: float
    surface: ConvectionLaw
    ventilation: ConvectionLaw

    @classmethod
    def from_config(cls, disc: DiscThermal) -> "DiscThermalModel":
        return cls(**{k: getattr(disc, k) for k in cls.__dataclass_fields__})

    def _film_conductance_W_per_K(self, law: ConvectionLaw, sliding_speed_mps: np.ndarray) -> np.ndarray:
        """h(v) A of Eq. 10 for one cooled surface."""
        ratio = np.maximum(sliding_speed_mps, 0.0) * (1.0 / self.reference_sliding_speed_mps)
        h = law.h0_W_per_m2K + (law.h_ref_W_per_m2K - law.h0_W_per_m2K) * ratio**law.exponent
        return h * law.area_m2

    def conductance_W_per_K_at(self, mean_temperature_K: np.ndarray) -> np.ndarray:
        """G(T_m) of Eq. 8, floored at G_min (G would turn negative at high temperature)."""
        g = self.conductance_W_per_K + self.conductance_slope_W_per_K2 * (
            mean_temperature_K - self.conductance_reference_temperature_K
        )
        return np.maximum(g, self.conductance_min_W_per_K)

    def heat_flows(
        self,
        friction_power_W: np.ndarray,
        friction_temperature_K: np.ndarray,
        disc_temperature_K: np.ndarray,
        sliding_speed_mps: np.ndarray,
        ambient_temperature_K: np.ndarray | float,
    ) -> HeatFlows:
        """All four heat flows. ``friction_power_W`` is mu F_C v_fric of the whole unit; the disc
        takes ``heat_fraction_into_disc`` of it (0.5, Eq. 6)."""
        conduction = self.conductance_W_per_K_at(0.5 * (friction_temperature_K + disc_temperature_K)) * (
            friction_temperature_K - disc_temperature_K
        )
        surface = self._film_conductance_W_per_K(self.surface, sliding_speed_mps) * (
            friction_temperature_K - ambient_temperature_K
        )
        ventilation = self._film_conductance_W_per_K(self.ventilation, sliding_speed_mps) * (
            disc_temperature_K - ambient_temperature_K
        )
        return HeatFlows(
            friction_W=self.heat_fraction_into_disc * friction_power_W,
            surface_W=surface,
            conduction_W=conduction,
            ventilation_W=ventilation,
        )

    def temperature_rates_K_per_s(self, flows: HeatFlows) -> tuple[np.ndarray, np.ndarray]:
        """(dT_fric/dt, dT_disc/dt) of Eq. 5."""
        friction_layer = (flows.friction_W - flows.surface_W - flows.conduction_W) * (
            1.0 / self.friction_layer_heat_capacity_J_per_K
        )
        disc_body = (flows.conduction_W - flows.ventilation_W) * (1.0 / self.disc_body_heat_capacity_J_per_K)
        return friction_layer, disc_body
