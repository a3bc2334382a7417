"""Disc temperature: two lumped heat capacities per disc (paper Eqs. 5-10, Table 3; spec Section 2).

    C_fric dT_fric/dt = Q_fric - Q_surf - Q_cond
    C_disc dT_disc/dt = Q_cond - Q_vent
    Q_fric = 0.5 mu F_C v_fric                       (Eq. 6: the disc's share of the friction power)
    Q_cond = G(T_m) (T_fric - T_disc),  T_m = (T_fric + T_disc) / 2,  G floored at G_min  (Eqs. 7, 8)
    Q_surf = h_surf(v_fric) A_surf (T_fric - T_inf)  (Eq. 9), Q_vent alike for the disc body
    h(v_fric) = h0 + (h_ref - h0) (v_fric / v_ref)^ex (Eq. 10)

Temperatures in kelvin, heat flows in watts.

The equations are the module-level functions (scalars or arrays, every parameter explicit): the
methods of :class:`DiscThermalModel` call them with numpy arrays, and the simulator's compiled
kernel (:mod:`brakegym.simulator.kernel`) compiles the same functions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .elementary import fractional_power


def film_conductance_W_per_K(
    sliding_speed_mps, h0_W_per_m2K, h_ref_W_per_m2K, exponent, area_m2, reference_sliding_speed_mps
):
    """h(v_fric) A of Eq. 10 for one cooled surface. It depends on the sliding speed alone, the
    same for every disc of a train."""
    ratio = np.maximum(sliding_speed_mps, 0.0) * (1.0 / reference_sliding_speed_mps)
    h = h0_W_per_m2K + (h_ref_W_per_m2K - h0_W_per_m2K) * fractional_power(ratio, exponent)
    return h * area_m2


def contact_conductance_W_per_K(
    mean_temperature_K, conductance_W_per_K, conductance_slope_W_per_K2, reference_temperature_K, minimum_W_per_K
):
    """G(T_m) of Eq. 8, floored at G_min (G would turn negative at high temperature)."""
    g = conductance_W_per_K + conductance_slope_W_per_K2 * (mean_temperature_K - reference_temperature_K)
    return np.maximum(g, minimum_W_per_K)


def heat_flows_W(
    friction_power_W,
    friction_temperature_K,
    disc_temperature_K,
    surface_conductance_W_per_K,
    ventilation_conductance_W_per_K,
    contact_conductance_W_per_K,
    ambient_temperature_K,
    heat_fraction_into_disc,
):
    """(Q_fric, Q_surf, Q_cond, Q_vent) of Eqs. 6, 7 and 9. ``friction_power_W`` is mu F_C v_fric
    of the whole unit, of which the disc takes ``heat_fraction_into_disc`` (0.5, Eq. 6); the
    conductances are h A of both surfaces (:func:`film_conductance_W_per_K`) and G(T_m)
    (:func:`contact_conductance_W_per_K`)."""
    conduction = contact_conductance_W_per_K * (friction_temperature_K - disc_temperature_K)
    surface = surface_conductance_W_per_K * (friction_temperature_K - ambient_temperature_K)
    ventilation = ventilation_conductance_W_per_K * (disc_temperature_K - ambient_temperature_K)
    return heat_fraction_into_disc * friction_power_W, surface, conduction, ventilation


def temperature_rates_K_per_s(
    friction_W,
    surface_W,
    conduction_W,
    ventilation_W,
    friction_layer_heat_capacity_J_per_K,
    disc_body_heat_capacity_J_per_K,
):
    """(dT_fric/dt, dT_disc/dt) of Eq. 5."""
    friction_layer = (friction_W - surface_W - conduction_W) * (1.0 / friction_layer_heat_capacity_J_per_K)
    disc_body = (conduction_W - ventilation_W) * (1.0 / disc_body_heat_capacity_J_per_K)
    return friction_layer, disc_body


@dataclass(frozen=True)
class HeatFlows:
    """Heat flows of one evaluation, W; arrays broadcast over (trains, axles, discs)."""

    friction_W: np.ndarray  # Q_fric, into the friction layer
    surface_W: np.ndarray  # Q_surf, friction layer to air
    conduction_W: np.ndarray  # Q_cond, friction layer to disc body
    ventilation_W: np.ndarray  # Q_vent, disc body to air


@dataclass(frozen=True)
class CooledSurface:
    """A surface cooled by the air: film coefficient h(v_fric) = h0 + (h_ref - h0)
    (v_fric / v_ref)^exponent (Eq. 10) over ``area_m2``."""

    h0_W_per_m2K: float
    h_ref_W_per_m2K: float
    exponent: float
    area_m2: float


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
    surface: CooledSurface  # the friction surfaces (Q_surf)
    ventilation: CooledSurface  # the ventilation channels of the disc body (Q_vent)

    def _film_conductance_W_per_K(self, law: CooledSurface, sliding_speed_mps: np.ndarray) -> np.ndarray:
        """h(v) A of Eq. 10 for one cooled surface."""
        return film_conductance_W_per_K(
            sliding_speed_mps,
            law.h0_W_per_m2K,
            law.h_ref_W_per_m2K,
            law.exponent,
            law.area_m2,
            self.reference_sliding_speed_mps,
        )

    def conductance_W_per_K_at(self, mean_temperature_K: np.ndarray) -> np.ndarray:
        """G(T_m) of Eq. 8, floored at G_min (G would turn negative at high temperature)."""
        return contact_conductance_W_per_K(
            mean_temperature_K,
            self.conductance_W_per_K,
            self.conductance_slope_W_per_K2,
            self.conductance_reference_temperature_K,
            self.conductance_min_W_per_K,
        )

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
        friction, surface, conduction, ventilation = heat_flows_W(
            friction_power_W,
            friction_temperature_K,
            disc_temperature_K,
            self._film_conductance_W_per_K(self.surface, sliding_speed_mps),
            self._film_conductance_W_per_K(self.ventilation, sliding_speed_mps),
            self.conductance_W_per_K_at(0.5 * (friction_temperature_K + disc_temperature_K)),
            ambient_temperature_K,
            self.heat_fraction_into_disc,
        )
        return HeatFlows(friction_W=friction, surface_W=surface, conduction_W=conduction, ventilation_W=ventilation)

    def temperature_rates_K_per_s(self, flows: HeatFlows) -> tuple[np.ndarray, np.ndarray]:
        """(dT_fric/dt, dT_disc/dt) of Eq. 5."""
        return temperature_rates_K_per_s(
            flows.friction_W,
            flows.surface_W,
            flows.conduction_W,
            flows.ventilation_W,
            self.friction_layer_heat_capacity_J_per_K,
            self.disc_body_heat_capacity_J_per_K,
        )
