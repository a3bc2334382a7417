"""The braking distance as the conventional brake calculation gives it, for comparison with the
dynamic model's distribution.

The conventional calculation (the step method of the railway brake-calculation standards, e.g.
ISO 20138-1 and EN 14531-1, as this module reads them) idealises the brake: nothing until the
equivalent response time ``t_e = t_a + t_b / 2``, the full brake force from then on, where ``t_a``
is the delay from the command to 10 % of the final brake force and ``t_b`` the build-up from 10 %
to 95 %; and a constant mean pad friction coefficient ``mu_m`` instead of one that changes with
sliding speed, power and temperature (paper Eq. 4). The distance is summed over speed steps, each
step braked at the brake force plus the running resistance at its mean speed:

    s = v_0 t_e + sum_i (v_i^2 - v_{i+1}^2) / (2 a_i),   a_i = (F_B + F_R(v_i,mean)) / m

with ``F_B = mu_m sum_discs F_C r_fric / r_wheel``. The train coasts without resistance until
``t_e``. What the dynamic model adds is the friction's fall at high power, which the constant
``mu_m`` misses: from high speed the conventional distance can be shorter than most of the dynamic
model's distribution (``brakegym tail`` prints both).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..physics import BrakeCylinder, CaliperLaw
from ..physics.mechanics import running_resistance_N
from ..units import kmh_to_mps
from .model import BrakingModel

# The brake-force shares that bound the build-up in the equivalent response time.
DELAY_SHARE = 0.10
BUILT_UP_SHARE = 0.95


@dataclass(frozen=True)
class ConventionalStop:
    """A stop by the conventional calculation."""

    initial_speed_kmh: float
    mean_pad_friction: float
    equivalent_response_time_s: float
    brake_force_N: float
    speed_edges_kmh: np.ndarray  # from v_0 down to 0
    decelerations_mps2: np.ndarray  # one per speed step
    braking_distance_m: float

    def band_decelerations_mps2(self, speed_edges_kmh) -> np.ndarray:
        """The constant deceleration that covers each band between consecutive
        ``speed_edges_kmh`` (rising, within 0 and v_0) in the same distance as the speed steps,
        from the equivalent response time on: ETCS's view of the conventional calculation."""
        edges = kmh_to_mps(np.asarray(speed_edges_kmh, dtype=float))
        steps_high, steps_low = kmh_to_mps(self.speed_edges_kmh[:-1]), kmh_to_mps(self.speed_edges_kmh[1:])
        decelerations = []
        for low, high in zip(edges[:-1], edges[1:]):
            top, bottom = np.minimum(steps_high, high), np.maximum(steps_low, low)
            inside = top > bottom
            distance = np.sum((top[inside] ** 2 - bottom[inside] ** 2) / (2.0 * self.decelerations_mps2[inside]))
            decelerations.append((high**2 - low**2) / (2.0 * distance))
        return np.array(decelerations)

    def as_dict(self) -> dict[str, float]:
        return {
            "braking_distance_m": self.braking_distance_m,
            "mean_pad_friction": self.mean_pad_friction,
            "equivalent_response_time_s": self.equivalent_response_time_s,
            "brake_force_N": self.brake_force_N,
        }


def time_to_force_share_s(cylinder: BrakeCylinder, caliper: CaliperLaw, pressure_bar: float, share: float) -> float:
    """When the clamp force reaches ``share`` of its final value after a step command to
    ``pressure_bar``: the dead time, then the lagged pressure's time to the caliper's threshold
    plus ``share`` of the way from there to the final pressure."""
    threshold = caliper.threshold_bar
    if not pressure_bar > threshold:
        raise ValueError(f"cylinder pressure {pressure_bar} bar gives no clamp force (threshold {threshold} bar)")
    needed = threshold + share * (pressure_bar - threshold)
    return cylinder.dead_time_s - cylinder.time_constant_s * math.log(1.0 - needed / pressure_bar)


def equivalent_response_time_s(cylinder: BrakeCylinder, caliper: CaliperLaw, pressure_bar: float) -> float:
    """``t_a + t_b / 2``: the delay to 10 % of the brake force plus half its build-up to 95 %."""
    delay = time_to_force_share_s(cylinder, caliper, pressure_bar, DELAY_SHARE)
    built_up = time_to_force_share_s(cylinder, caliper, pressure_bar, BUILT_UP_SHARE)
    return delay + 0.5 * (built_up - delay)


def conventional_stop(model: BrakingModel) -> ConventionalStop:
    """The conventional calculation for ``model``'s train, load, brake mode and initial speed,
    with the mean pad friction and the speed step of its safety case."""
    settings = model.case.conventional
    plant, vehicle = model.plant, model.vehicle
    pressure = model.nominal_pressure_bar
    t_e = equivalent_response_time_s(model.cylinder, plant.caliper, pressure)
    clamp_force = float(plant.caliper.clamp_force_N(np.array(pressure)))
    brake_force = settings.mean_pad_friction * clamp_force * vehicle.n_discs * plant.radius_ratio
    steps = max(1, math.ceil(model.initial_speed_kmh / settings.speed_step_kmh))
    edges_kmh = np.linspace(model.initial_speed_kmh, 0.0, steps + 1)
    edges = kmh_to_mps(edges_kmh)
    mean_speed = 0.5 * (edges[:-1] + edges[1:])
    resistance = vehicle.running_resistance
    resistance_N = running_resistance_N(mean_speed, resistance.A_N, resistance.B_N_per_mps, resistance.C_N_per_mps2)
    deceleration = (brake_force + resistance_N) / vehicle.mass_kg(model.load)
    distance = float(edges[0] * t_e) + float(np.sum((edges[:-1] ** 2 - edges[1:] ** 2) / (2.0 * deceleration)))
    return ConventionalStop(
        initial_speed_kmh=model.initial_speed_kmh,
        mean_pad_friction=settings.mean_pad_friction,
        equivalent_response_time_s=t_e,
        brake_force_N=brake_force,
        speed_edges_kmh=edges_kmh,
        decelerations_mps2=deceleration,
        braking_distance_m=distance,
    )
