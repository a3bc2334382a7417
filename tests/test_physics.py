"""Physics modules and simulator: energy balance, analytic limits, spec constants."""

import dataclasses
import math

import numpy as np
import pytest

from brakegym import config as cfg
from brakegym.applications import TrainApplication, train_stops
from brakegym.physics import BrakeCylinder
from brakegym.plants import caliper_law, dynamometer_plant, friction_law, thermal_model, train_plant
from brakegym.simulator import BatchConditions, CommandedPressure, Simulator
from brakegym.units import ZERO_CELSIUS_K


@pytest.fixture(scope="module")
def vehicle():
    return cfg.load("vehicles", "emu_8axle")


@pytest.fixture(scope="module")
def friction():
    return friction_law(cfg.load("materials", "ehret2022"))


@pytest.fixture(scope="module")
def thermal():
    return thermal_model(cfg.load("discs", "ehret2022_disc"))


def test_friction_rate_matches_eq4_by_hand(friction):
    mu, force, v_fric, temperature = 0.35, 33000.0, 15.0, 400.0
    expected = (
        -0.008 * (mu * force * v_fric / 1e5) ** 0.994
        - 0.010 * mu**0.533
        - 0.042 * (mu * temperature / 273.15) ** 1.581
        + 0.036 * (force / 4e4) ** 0.367
    )
    got = friction.rate_per_s(np.array(mu), np.array(force), np.array(v_fric), np.array(temperature))
    assert float(got) == pytest.approx(expected, rel=1e-12)


def test_friction_state_held_when_released_or_standing(friction):
    mu = np.full(3, 0.35)
    rate = friction.rate_per_s(mu, np.array([0.0, 33e3, 33e3]), np.array([10.0, 0.0, 0.0005]), np.full(3, 400.0))
    np.testing.assert_array_equal(rate, 0.0)


def test_caliper_gives_table4_clamp_forces(vehicle):
    caliper = caliper_law(vehicle.caliper)
    forces = caliper.clamp_force_N(np.array([3.05, 3.30, 3.97, 4.05, 0.2]))
    np.testing.assert_allclose(forces, [33000, 36000, 44040, 45000, 0], atol=1.0)


def test_conductance_floor(thermal):
    # G = 691 - 1.31 (T_m - 273.15 K) would be negative above 527 degC; the spec floors it at 10 W/K.
    assert thermal.conductance_W_per_K_at(np.array(273.15 + 600.0)) == pytest.approx(10.0)
    assert thermal.conductance_W_per_K_at(np.array(273.15 + 100.0)) == pytest.approx(691 - 131.0)


def test_heat_transfer_coefficient_eq10(thermal):
    flows = thermal.heat_flows(np.array(0.0), np.array(400.0), np.array(300.0), np.array(20.0), 293.15)
    # At v_fric = v_ref, h = h_ref: Q_surf = 30 * 0.35 * (400 - 293.15).
    assert float(flows.surface_W) == pytest.approx(30 * 0.35 * (400 - 293.15))
    assert float(flows.ventilation_W) == pytest.approx(30 * 0.90 * (300 - 293.15))


def test_cylinder_pressure_follows_dead_time_and_lag(vehicle):
    """Spec Section 4: EP, 0.2 s dead time then 0.8 s lag, exact at every step."""
    app = TrainApplication(load="empty", brake_mode="emergency", actuation="EP", initial_speed_kmh=120.0)
    summary = train_stops(vehicle, [app], step_s=0.1, record_every=1, until_time_s=5.0)
    traj = summary.trajectory
    t = traj.time_s
    expected = np.where(t > 1.2, 3.3 * (1 - np.exp(-(t - 1.2) / 0.8)), 0.0)
    np.testing.assert_allclose(traj.pressure_bar[:, 0, :], np.repeat(expected[:, None], 8, axis=1), atol=1e-12)


def test_dead_time_must_divide_step():
    with pytest.raises(ValueError, match="dead time 0.2 s is not a whole number of time steps of 0.15 s"):
        BrakeCylinder(0.2, 0.8).dead_time_steps(0.15)


def _constant_friction_plant(mu_constant_law):
    rig = cfg.load("rigs", "dynamometer")
    return dataclasses.replace(dynamometer_plant(rig), friction=mu_constant_law)


def test_constant_friction_stop_matches_kinematics(friction):
    """Analytic limit: with Eq. 4 switched off (all coefficients zero) and the clamp force applied
    at once, the rig decelerates uniformly: s = v0^2 m r_w / (2 mu F_C r_f)."""
    frozen = dataclasses.replace(
        friction,
        power_coefficient_per_s=0.0,
        decay_coefficient_per_s=0.0,
        temperature_coefficient_per_s=0.0,
        clamp_force_coefficient_per_s=0.0,
    )
    plant = _constant_friction_plant(frozen)
    mass, v0, mu, force = 8000.0, 30.0, 0.4, 30000.0
    conditions = BatchConditions(
        mass_kg=np.array([mass]),
        initial_speed_mps=np.array([v0]),
        initial_mu=np.full((1, 1, 1), mu),
        power_coefficient_per_s=np.zeros((1, 1, 1)),
        running_resistance_A_N=np.zeros(1),
        initial_friction_temperature_K=np.full((1, 1, 1), 323.15),
        initial_disc_temperature_K=np.full((1, 1, 1), 323.15),
        ambient_temperature_K=np.array([293.15]),
    )
    pressure = CommandedPressure([BrakeCylinder(0.0, 1e-9)], 1, 0.2, initial_pressure_bar=force)
    sim = Simulator(plant, conditions, pressure, step_s=0.2)
    while sim.moving.any():
        sim.step()
    deceleration = mu * force * plant.radius_ratio / mass
    assert sim.stop_time_s[0] == pytest.approx(v0 / deceleration, rel=1e-9)
    assert sim.train[1, 0] == pytest.approx(v0**2 / (2 * deceleration), rel=1e-9)


@pytest.mark.parametrize("actuation,v0", [("EP", 160.0), ("PN", 100.0)])
def test_train_energy_balance(vehicle, actuation, v0):
    """Kinetic energy lost = friction work + running-resistance work; heat into the discs =
    Q_fric = 0.5 x friction work = heat stored + heat given to the air (each within 0.5 %)."""
    app = TrainApplication(load="normal", brake_mode="service", actuation=actuation, initial_speed_kmh=v0)
    s = train_stops(vehicle, [app])
    kinetic = s.initial_kinetic_energy_J[0]
    assert s.brake_work_J[0] + s.resistance_work_J[0] == pytest.approx(kinetic, rel=0.005)
    assert s.friction_heat_J.sum() == pytest.approx(0.5 * s.brake_work_J[0], rel=0.005)
    np.testing.assert_allclose(s.stored_heat_J + s.cooling_heat_J, s.friction_heat_J, rtol=0.005)


def test_extra_force_extension_enters_energy_balance(vehicle):
    """An optional module (here a constant 1 % downhill gradient) adds to the force balance
    without touching the core loop, and its work closes the energy balance."""

    class Gradient:
        def __init__(self, gradient_permil):
            self.gradient_permil = gradient_permil

        def force_N(self, context):
            return context.mass_kg * 9.81 * self.gradient_permil / 1000.0

    app = TrainApplication(load="empty", brake_mode="emergency", actuation="EP", initial_speed_kmh=120.0)
    level = train_stops(vehicle, [app])
    downhill = train_stops(vehicle, [app], extra_forces=[Gradient(-10.0)])
    assert downhill.stop_distance_m[0] > level.stop_distance_m[0] * 1.05
    total = downhill.brake_work_J + downhill.resistance_work_J + downhill.extra_work_J
    assert total[0] == pytest.approx(downhill.initial_kinetic_energy_J[0], rel=0.005)


def test_friction_modifier_scales_brake_force(vehicle):
    """A friction modifier of 0.8 on every disc lengthens a stop like a 20 % weaker brake."""

    class Level:
        def scale(self, context):
            return 0.8

    app = TrainApplication(load="empty", brake_mode="emergency", actuation="EP", initial_speed_kmh=100.0)
    nominal = train_stops(vehicle, [app])
    weak = train_stops(vehicle, [app], friction_modifiers=[Level()])
    assert weak.braking_distance_m[0] > 1.15 * nominal.braking_distance_m[0]
    assert weak.mu_s_eff[0] == pytest.approx(0.8 * nominal.mu_s_eff[0], rel=0.03)


def test_mu_eff_of_a_ds_train_equals_mean_disc_mu(vehicle):
    """Eq. 15 with the nominal running resistance: in DS the resistance cancels and mu_eff is the
    clamp-force-weighted mean of the discs' mu, all equal here."""
    app = TrainApplication(load="max", brake_mode="emergency", actuation="EP", initial_speed_kmh=140.0)
    s = train_stops(vehicle, [app])
    assert s.mu_s_eff[0] == pytest.approx(s.mu_s[0].mean(), rel=1e-3)


def test_standstill_is_final_and_discs_cool(vehicle):
    app = TrainApplication(load="empty", brake_mode="emergency", actuation="EP", initial_speed_kmh=100.0)
    s = train_stops(vehicle, [app], record_every=1, until_time_s=60.0)
    traj = s.trajectory
    after = traj.time_s > s.stop_time_s[0]
    assert np.all(traj.speed_mps[after] == 0.0)
    assert np.all(np.diff(traj.position_m[after, 0]) == 0.0)
    assert np.all(np.diff(traj.friction_temperature_C[after, 0, 0]) < 0)
    assert np.all(np.diff(traj.mu[after, 0, 0]) == 0.0)


def test_batch_composition_does_not_change_results(vehicle):
    """A train's stop is the same alone or in a batch with others."""
    apps = [
        TrainApplication(load="empty", brake_mode="emergency", actuation="EP", initial_speed_kmh=120.0),
        TrainApplication(load="max", brake_mode="service", actuation="PN", initial_speed_kmh=160.0),
    ]
    together = train_stops(vehicle, apps)
    alone = train_stops(vehicle, apps[1:])
    assert together.stop_distance_m[1] == pytest.approx(alone.stop_distance_m[0], rel=1e-12)
    assert together.stop_distance_m[0] != together.stop_distance_m[1]


def test_train_plant_geometry(vehicle):
    plant = train_plant(vehicle)
    assert plant.n_discs == 16 and plant.disc_shape == (8, 2)
    assert vehicle.mass_kg("empty") == pytest.approx(16 * 7574)
    assert math.isclose(plant.radius_ratio, 0.28 / 0.46)
    assert ZERO_CELSIUS_K == 273.15
