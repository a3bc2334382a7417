"""The baseline a user would write: one ``scipy.integrate.solve_ivp`` call per train stop.

Same model as the batched simulator (it calls the same physics modules), same answers within
solver tolerance; used by ``bench_campaign.py`` for the per-disc-stop speed ratio.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from brakegym import config as cfg
from brakegym.applications import TrainApplication
from brakegym.plants import brake_cylinder, train_plant
from brakegym.units import ZERO_CELSIUS_K


def solve_ivp_stop(
    vehicle: cfg.Vehicle,
    app: TrainApplication,
    initial_mu: np.ndarray,
    power_coefficient: np.ndarray,
    running_resistance_A_N: float,
    rtol: float = 1e-8,
) -> tuple[float, float]:
    """(stop time s, stop distance m) of one train stop; discs as flat arrays of length n."""
    plant = train_plant(vehicle)
    cylinder = brake_cylinder(cfg.load("pneumatics", app.actuation))
    target_bar = vehicle.brake_pressure_bar(app.brake_mode, app.load)
    mass = vehicle.mass_kg(app.load)
    ambient = vehicle.ambient_temperature_C + ZERO_CELSIUS_K
    n = plant.n_discs
    a = power_coefficient.reshape(n)
    start = app.command_time_s + cylinder.dead_time_s

    def pressure(t: float) -> float:
        if t <= start:
            return 0.0
        return target_bar * (1.0 - np.exp(-(t - start) / cylinder.time_constant_s))

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        v, mu, t_fric, t_disc = y[0], y[2 : 2 + n], y[2 + n : 2 + 2 * n], y[2 + 2 * n :]
        v_fric = max(v, 0.0) * plant.radius_ratio
        clamp = plant.caliper.clamp_force_N(np.array(pressure(t)))
        mu_b = plant.friction.bounded(mu)
        friction_force = mu_b * clamp
        flows = plant.thermal.heat_flows(friction_force * v_fric, t_fric, t_disc, v_fric, ambient)
        d_fric, d_disc = plant.thermal.temperature_rates_K_per_s(flows)
        d_mu = plant.friction.rate_per_s(mu, clamp, v_fric, t_fric, a)
        force = friction_force.sum() * plant.radius_ratio + plant.running_resistance.force_N(v, running_resistance_A_N)
        return np.concatenate(([-force / mass, v], d_mu, d_fric, d_disc))

    def standstill(t: float, y: np.ndarray) -> float:
        return y[0]

    standstill.terminal = True
    standstill.direction = -1
    t0 = vehicle.initial_disc_temperature_C + ZERO_CELSIUS_K
    y0 = np.concatenate(([app.initial_speed_kmh / 3.6, 0.0], initial_mu.reshape(n), np.full(2 * n, t0)))
    # max_step keeps the solver from stepping over the brake onset at the command time.
    solution = solve_ivp(rhs, (0.0, 600.0), y0, method="RK45", rtol=rtol, atol=1e-9, events=standstill, max_step=0.5)
    return float(solution.t_events[0][0]), float(solution.y_events[0][0][1])
