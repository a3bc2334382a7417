"""Wheel-rail adhesion (docs/adhesion.md, issue 16): Polach's creep-force law against its analytic
limits, the rail-condition configs, and the simulator's adhesion option against physical limits."""

from __future__ import annotations

import dataclasses
import math
import shutil
from pathlib import Path

import numba
import numpy as np
import pytest
import yaml

from brakegym import config as cfg
from brakegym.applications import TrainApplication, train_conditions, train_stops
from brakegym.physics import FrictionDraw
from brakegym.physics.adhesion import (
    PolachLaw,
    RailConditioning,
    WheelRailContact,
    contact_semi_axis_m,
    creep,
    polach_shape,
    polach_shape_slope,
)
from brakegym.plants import (
    brake_cylinder,
    nominal_draw,
    polach_law,
    train_plant,
    wheel_rail_adhesion,
    wheel_rail_contact,
)
from brakegym.simulator import CommandedPressure, kernel, wheelset_kernel
from brakegym.simulator.state import ANGULAR_SPEED, FRICTION_HEAT, POSITION, SPEED
from brakegym.simulator.wheelsets import DEFAULT_MAX_SUBSTEP_S, AdhesionSimulator, WheelRailAdhesion
from brakegym.simulator.wheelsets_reference import NumpyAdhesionSimulator
from brakegym.units import STANDARD_GRAVITY_MPS2

REPO_CONFIGS = Path(__file__).resolve().parent.parent / "configs"


@pytest.fixture(autouse=True)
def checkout_configs(monkeypatch):
    """This checkout's configs on the search path (an installed brakegym may ship others)."""
    monkeypatch.setenv(cfg.CONFIG_PATH_ENV, str(REPO_CONFIGS))


DRY = PolachLaw(
    static_friction=0.55,
    friction_ratio_at_infinity=0.40,
    friction_decay_s_per_m=0.60,
    adhesion_reduction=1.00,
    slip_reduction=0.40,
)
CONTACT = WheelRailContact(
    semi_axis_a_m=0.0065, semi_axis_b_m=0.0049, reference_wheel_load_N=75e3, kalker_c11=3.9, shear_modulus_Pa=8.0e10
)
WHEEL_LOAD_N = 75e3
STIFFNESS_N = CONTACT.creep_stiffness_N(WHEEL_LOAD_N)


def test_creep_is_slip_over_speed_and_regularised_at_standstill():
    assert creep(30.0, 29.7, 0.5) == pytest.approx(0.01)
    # Below the regularisation speed the slip speed is divided by it, not by v.
    assert creep(0.1, 0.05, 0.5) == pytest.approx(0.1)
    assert creep(0.0, 0.0, 0.5) == 0.0


def test_contact_grows_with_the_cube_root_of_the_load():
    assert contact_semi_axis_m(8 * 75e3, 0.0065, 75e3) == pytest.approx(0.013)
    assert CONTACT.creep_stiffness_N(75e3) == pytest.approx(0.25 * math.pi * 8.0e10 * 0.0065 * 0.0049 * 3.9)


def test_small_creep_gives_kalker_slope_reduced_by_polach():
    """For eps -> 0: F / Q -> (2 mu_0 / pi)(k_A + k_S) eps, eps = stiffness s / (Q mu_0): the slope
    is (2 / pi)(k_A + k_S) stiffness / Q, whatever mu_0."""
    s = 1e-7
    coefficient = DRY.adhesion_coefficient(s, 0.0, WHEEL_LOAD_N, STIFFNESS_N)
    expected_slope = (2 / math.pi) * (DRY.adhesion_reduction + DRY.slip_reduction) * STIFFNESS_N / WHEEL_LOAD_N
    assert coefficient / s == pytest.approx(expected_slope, rel=1e-6)
    assert DRY.creep_slope_at_fixed_friction(s, 0.0, WHEEL_LOAD_N, STIFFNESS_N) == pytest.approx(
        expected_slope, rel=1e-6
    )


def test_adhesion_term_alone_peaks_at_k_A_eps_one_at_mu_over_pi():
    """Without the slip term (k_S = 0) and without falling friction (A = 1), F / Q =
    (2 mu / pi) k_A eps / (1 + (k_A eps)^2) peaks at k_A eps = 1 with mu / pi."""
    law = PolachLaw(0.4, 1.0, 0.0, 0.5, 0.0)
    peak, at_creep = law.peak_adhesion(30.0, WHEEL_LOAD_N, STIFFNESS_N, n_creeps=200001)
    assert peak == pytest.approx(0.4 / math.pi, rel=1e-8)
    expected_creep = 1.0 / law.adhesion_reduction * WHEEL_LOAD_N * 0.4 / STIFFNESS_N
    assert at_creep == pytest.approx(expected_creep, rel=1e-3)


def test_shape_slope_is_the_derivative_of_the_shape():
    eps = np.array([0.01, 0.5, 1.0, 3.0, 40.0])
    h = 1e-6
    numeric = (polach_shape(eps + h, 0.8, 0.3) - polach_shape(eps - h, 0.8, 0.3)) / (2 * h)
    np.testing.assert_allclose(polach_shape_slope(eps, 0.8, 0.3), numeric, rtol=1e-6)


def test_falling_branch_past_the_peak_down_to_mu_0_A():
    speed = 30.0
    peak, at_creep = DRY.peak_adhesion(speed, WHEEL_LOAD_N, STIFFNESS_N)
    creeps = np.array([at_creep, 2 * at_creep, 0.1, 0.5])
    coefficients = DRY.adhesion_coefficient(creeps, creeps * speed, WHEEL_LOAD_N, STIFFNESS_N)
    assert np.all(np.diff(coefficients) < 0)
    # A locked wheel at high slip speed: mu(w) -> mu_0 A, and the shape tends to pi / 2 as
    # eps grows, short of it by about (1 / k_S - 1 / k_A) / eps (here eps ~ 470: 0.2 %).
    locked = DRY.adhesion_coefficient(1.0, 1e3, WHEEL_LOAD_N, STIFFNESS_N)
    mu_inf = DRY.static_friction * DRY.friction_ratio_at_infinity
    eps = STIFFNESS_N / (WHEEL_LOAD_N * mu_inf)
    remainder = (2 / math.pi) * (1 / DRY.slip_reduction - 1 / DRY.adhesion_reduction) / eps
    assert locked == pytest.approx(mu_inf * (1 - remainder), rel=1e-4)
    # Past the adhesion peak the slope at fixed friction may turn negative: it is clipped at 0.
    assert DRY.creep_slope_at_fixed_friction(creeps, creeps * speed, WHEEL_LOAD_N, STIFFNESS_N).min() >= 0.0


def test_force_is_odd_in_creep():
    creeps = np.array([1e-4, 3e-3, 0.05, 0.7])
    forward = DRY.creep_force_N(creeps, creeps * 20, WHEEL_LOAD_N, STIFFNESS_N)
    backward = DRY.creep_force_N(-creeps, -creeps * 20, WHEEL_LOAD_N, STIFFNESS_N)
    np.testing.assert_array_equal(backward, -forward)
    assert DRY.creep_force_N(0.0, 0.0, WHEEL_LOAD_N, STIFFNESS_N) == 0.0


@pytest.mark.parametrize("name", ["dry", "wet", "low"])
@pytest.mark.parametrize("factor", [0.6, 1.3, 2.0])
def test_mu_0_times_f_peaks_at_f_times_the_nominal_peak_at_f_times_the_speed(name, factor):
    """Polach's F / Q is (2 mu / pi) G(C s / (Q mu)), mu = mu_0 ((1 - A) exp(-B s v) + A): with
    mu_0 times f, the creep s = f s' gives f times the nominal F / Q at creep s' and speed f v, so
    the peak at v is f times the nominal peak at f v (what the environment's ideal distance uses
    for a scattered rail). Up to the creep grid's resolution; an array of speeds gives each
    speed's own peak."""
    law = polach_law(cfg.load("rail_conditions", name))
    scaled = dataclasses.replace(law, static_friction=factor * law.static_friction)
    speeds = np.array([1.0, 10.0, 30.0, 45.0])
    peak_scaled, _ = scaled.peak_adhesion(speeds, WHEEL_LOAD_N, STIFFNESS_N)
    peak_nominal, _ = law.peak_adhesion(factor * speeds, WHEEL_LOAD_N, STIFFNESS_N)
    np.testing.assert_allclose(peak_scaled, factor * peak_nominal, rtol=1e-6)
    one_by_one = [scaled.peak_adhesion(v, WHEEL_LOAD_N, STIFFNESS_N)[0] for v in speeds]
    np.testing.assert_array_equal(peak_scaled, one_by_one)


# ------------------------------------------------------------------------------------------------
# Rail conditions and the vehicle's wheelsets as configs


@pytest.mark.parametrize("name", ["dry", "wet", "low", "low_conditioned"])
def test_rail_condition_gives_its_peak_adhesion(name):
    """Each file's peak_adhesion is what its Polach parameters give at the emu_8axle's contact,
    empty, 30 m/s, within 0.01 (the files state it rounded)."""
    vehicle = cfg.load("vehicles", "emu_8axle")
    condition = cfg.load("rail_conditions", name)
    assert condition.source.strip()
    wheel_load_N = vehicle.mass_kg("empty") * STANDARD_GRAVITY_MPS2 / (2 * vehicle.n_axles)
    stiffness_N = wheel_rail_contact(vehicle).creep_stiffness_N(wheel_load_N)
    peak, _ = polach_law(condition).peak_adhesion(30.0, wheel_load_N, stiffness_N)
    assert peak == pytest.approx(condition.peak_adhesion, abs=0.01)


def test_conditioning_raises_mu_0_axle_by_axle_towards_the_cleaned_rail():
    """Axle k brakes on mu_0 (1 + (R - 1)(1 - (1 - c)^k)): the leading axle on the rail's own,
    each following one on more, all below the cleaned rail's R mu_0; no conditioning gives factors
    of exactly 1 (the kernel's arithmetic unchanged); the config's numbers reach the adhesion
    option, and bad values are refused."""
    factors = RailConditioning(cleaned_friction_ratio=2.0, per_axle=0.1).axle_factors(8)
    assert factors[0] == 1.0
    assert np.all(np.diff(factors) > 0) and factors[-1] < 2.0
    assert factors[-1] == pytest.approx(1.0 + (1.0 - 0.9**7))
    np.testing.assert_array_equal(RailConditioning().axle_factors(8), np.ones(8))
    vehicle = cfg.load("vehicles", "emu_8axle")
    conditioned = wheel_rail_adhesion(vehicle, cfg.load("rail_conditions", "low_conditioned"))
    np.testing.assert_array_equal(conditioned.axle_conditioning(8), factors[None, :])
    assert wheel_rail_adhesion(vehicle, cfg.load("rail_conditions", "low")).conditioning is None
    with pytest.raises(ValueError, match="cleaned_friction_ratio"):
        RailConditioning(cleaned_friction_ratio=0.5)
    with pytest.raises(ValueError, match="per_axle"):
        RailConditioning(per_axle=1.0)


def test_low_adhesion_is_in_the_wsp_test_range():
    assert 0.05 <= cfg.load("rail_conditions", "low").peak_adhesion <= 0.10


@pytest.fixture
def config_copy(tmp_path, monkeypatch):
    target = tmp_path / "configs"
    shutil.copytree(REPO_CONFIGS, target)
    monkeypatch.setenv(cfg.CONFIG_PATH_ENV, str(target))
    return target


def _edit(path: Path, change) -> None:
    data = yaml.safe_load(path.read_text())
    change(data)
    path.write_text(yaml.safe_dump(data))


@pytest.mark.parametrize(
    ("field", "value"),
    [("static_friction", -0.2), ("friction_ratio_at_infinity", 1.5), ("slip_reduction", 0.0), ("source", "")],
)
def test_bad_rail_condition_names_file_field_value(config_copy, field, value):
    path = config_copy / "rail_conditions" / "wet.yaml"
    _edit(path, lambda data: data.update({field: value}))
    with pytest.raises(cfg.ConfigError) as info:
        cfg.load("rail_conditions", "wet")
    message = str(info.value)
    assert str(path) in message and f"field '{field}' = {value!r}" in message


def test_wheelset_inertia_above_the_train_mass_is_refused(config_copy):
    path = config_copy / "vehicles" / "emu_8axle.yaml"
    _edit(path, lambda data: data["wheelsets"].update(inertia_kgm2=5e3))
    with pytest.raises(cfg.ConfigError, match=r"wheelsets.inertia_kgm2 = 5000.0") as info:
        cfg.load("vehicles", "emu_8axle")
    assert str(path) in str(info.value)


def test_vehicle_without_wheelsets_block_takes_the_documented_defaults(config_copy):
    path = config_copy / "vehicles" / "emu_8axle.yaml"
    _edit(path, lambda data: data.pop("wheelsets"))
    assert cfg.load("vehicles", "emu_8axle").wheelsets == cfg.Wheelsets()


# ------------------------------------------------------------------------------------------------
# The simulator with the adhesion option: physical limits


def _adhesion(condition: str, **changes) -> WheelRailAdhesion:
    vehicle = cfg.load("vehicles", "emu_8axle")
    return dataclasses.replace(wheel_rail_adhesion(vehicle, cfg.load("rail_conditions", condition)), **changes)


class WheelObserver:
    """After each step: the largest creep of a rolling wheel above 5 m/s, the steps with a wheel
    locked while the train runs, and whether a wheel locked over a whole step heated its discs."""

    def __init__(self) -> None:
        self.max_rolling_creep = 0.0
        self.locked_steps = 0
        self.heat_of_locked_discs_J = 0.0
        self.locked_positions_m: list[float] = []
        self._before: tuple[np.ndarray, np.ndarray] | None = None

    def update(self, sim: AdhesionSimulator) -> None:
        speed = sim.train[SPEED]
        wheels = sim.wheel_speed_mps
        fast = (speed > 5.0) & sim.moving
        if fast.any():
            creeps = (speed - wheels)[:, fast] / speed[fast]
            rolling = creeps[creeps < 0.5]
            self.max_rolling_creep = max(self.max_rolling_creep, float(rolling.max(initial=0.0)))
        locked = (wheels == 0.0) & sim.moving
        self.locked_positions_m.extend(np.broadcast_to(sim.train[POSITION], locked.shape)[locked].tolist())
        heat = sim.disc[FRICTION_HEAT].sum(axis=1)  # (A, B)
        if self._before is not None:
            was_locked, heat_before = self._before
            whole_step = was_locked & locked
            self.locked_steps += int(whole_step.sum())
            self.heat_of_locked_discs_J += float(np.abs(heat - heat_before)[whole_step].sum())
        self._before = (locked, heat.copy())


def _stop(condition: str | None, initial_speed_kmh: float = 120.0, line: str | None = None, **changes):
    vehicle = cfg.load("vehicles", "emu_8axle")
    observer = WheelObserver()
    if line is not None:
        adhesion = wheel_rail_adhesion(vehicle, cfg.load("lines", line))
    else:
        adhesion = None if condition is None else _adhesion(condition, **changes)
    summary = train_stops(
        vehicle,
        [TrainApplication("empty", "emergency", "EP", initial_speed_kmh)],
        adhesion=adhesion,
        observers=[observer] if adhesion else (),
    )
    return summary, observer


@pytest.fixture(scope="module")
def stops(request):
    """The golden train case (120 km/h, empty, emergency, EP) without adhesion, on a dry and on
    a low-adhesion rail."""
    with cfg.config_path(REPO_CONFIGS):
        return {condition: _stop(condition) for condition in (None, "dry", "low", "low_conditioned")}


def test_dry_rail_stops_like_the_model_without_adhesion(stops):
    """Issue 16: dry rails with the adhesion model on give the golden train case within 0.5 %."""
    without, _ = stops[None]
    dry, _ = stops["dry"]
    assert dry.stop_distance_m[0] == pytest.approx(without.stop_distance_m[0], rel=5e-3)
    assert dry.stop_time_s[0] == pytest.approx(without.stop_time_s[0], rel=5e-3)


def test_pure_rolling_when_the_brake_force_is_far_below_the_adhesion(stops):
    """Dry rail: the brake asks about 0.1 of the weight, the rail gives 0.36; the wheels roll with
    a creep near the law's linear slope (demand / slope ~ 0.1 %) and slip next to no energy."""
    dry, observer = stops["dry"]
    assert observer.locked_steps == 0
    assert 0.0 < observer.max_rolling_creep < 3e-3
    assert dry.slip_work_J.sum() < 2e-3 * dry.initial_kinetic_energy_J[0]


@pytest.mark.parametrize("condition", ["dry", "low", "low_conditioned"])
def test_kinetic_energy_lost_is_disc_slip_and_resistance_work(stops, condition):
    summary, _ = stops[condition]
    dissipated = summary.brake_work_J + summary.slip_work_J.sum(axis=1) + summary.resistance_work_J
    assert dissipated[0] == pytest.approx(summary.initial_kinetic_energy_J[0], rel=5e-3)


def test_low_adhesion_locks_the_wheels_and_their_discs_stay_cold(stops):
    """Without WSP the emergency brake locks the wheels on the low rail; a locked wheel's discs get
    no friction heat while its tread slides (slip work instead)."""
    low, observer = stops["low"]
    dry, _ = stops["dry"]
    assert observer.locked_steps > 100
    assert observer.heat_of_locked_discs_J == 0.0
    assert low.slip_work_J.sum() > 0.5 * low.initial_kinetic_energy_J[0]
    assert low.friction_heat_J.sum() < 0.2 * dry.friction_heat_J.sum()


def test_a_conditioned_rail_stops_the_train_shorter(stops):
    """Without WSP the wheels lock on the low rail; on the one the axles condition for each other
    the following axles find more friction (some of them keep rolling), and the train stops
    shorter."""
    low, _ = stops["low"]
    conditioned, observer = stops["low_conditioned"]
    assert observer.locked_steps > 100  # the leading axles still lock
    assert conditioned.stop_distance_m[0] < 0.95 * low.stop_distance_m[0]


@pytest.mark.parametrize("condition", ["low", "low_conditioned"])
def test_no_stop_shorter_than_the_adhesion_allows(stops, condition):
    """The body decelerates by at most (mean over the axles of each one's peak adhesion x weight
    + F_R) / M, all axles braked: the braking distance is at least v0^2 / (2 a_max), a_max with the
    largest peak adhesion from standstill to v0 and the resistance at v0; on the conditioned rail
    each axle's peak with its own mu_0."""
    vehicle = cfg.load("vehicles", "emu_8axle")
    mass_kg = vehicle.mass_kg("empty")
    wheel_load_N = mass_kg * STANDARD_GRAVITY_MPS2 / (2 * vehicle.n_axles)
    adhesion = _adhesion(condition)
    stiffness_N = adhesion.contact.creep_stiffness_N(wheel_load_N)
    v0 = 120 / 3.6
    axle_laws = [
        dataclasses.replace(adhesion.law, static_friction=adhesion.law.static_friction * factor)
        for factor in adhesion.axle_conditioning(vehicle.n_axles)[0]
    ]
    peak = max(
        np.mean([law.peak_adhesion(v, wheel_load_N, stiffness_N)[0] for law in axle_laws])
        for v in np.linspace(0.5, v0, 12)
    )
    body_mass_kg = mass_kg - vehicle.n_axles * adhesion.wheelset_inertia_kgm2 / vehicle.wheel_radius_m**2
    resistance = vehicle.running_resistance
    resistance_N = resistance.A_N + resistance.B_N_per_mps * v0 + resistance.C_N_per_mps2 * v0**2
    max_deceleration = (peak * mass_kg * STANDARD_GRAVITY_MPS2 + resistance_N) / body_mass_kg
    summary, _ = stops[condition]
    assert summary.braking_distance_m[0] >= v0**2 / (2 * max_deceleration)


def test_wheelset_substeps_converge_against_a_tenth_of_them():
    """Low rail from 80 km/h (wheels lock): the 10 ms substeps against 1 ms ones."""
    coarse, _ = _stop("low", 80.0)
    fine, _ = _stop("low", 80.0, max_substep_s=DEFAULT_MAX_SUBSTEP_S / 10)
    assert coarse.stop_distance_m[0] == pytest.approx(fine.stop_distance_m[0], rel=5e-3)
    assert coarse.slip_work_J.sum() == pytest.approx(fine.slip_work_J.sum(), rel=5e-3)
    assert coarse.brake_work_J[0] == pytest.approx(fine.brake_work_J[0], rel=5e-3)


def test_adhesion_option_refuses_hooks():
    vehicle = cfg.load("vehicles", "emu_8axle")
    with pytest.raises(ValueError, match="without extra forces"):
        train_stops(
            vehicle,
            [TrainApplication("empty", "emergency", "EP", 120.0)],
            adhesion=_adhesion("dry"),
            extra_forces=[object()],
        )


# ------------------------------------------------------------------------------------------------
# A line of sections: a low-adhesion patch


def test_wheels_lock_on_the_low_adhesion_patch_only(stops):
    """lines/low_patch: dry, low from 200 m to 500 m, dry again. The wheels lock on the patch and
    roll again after it (within the few metres a wheel needs to spin up); the stop lies between
    the dry one and the all-low one."""
    patch, observer = _stop(None, line="low_patch")
    line = cfg.load("lines", "low_patch")
    start, end = line.sections[1].start_m, line.sections[2].start_m
    assert observer.locked_steps > 10
    assert min(observer.locked_positions_m) >= start
    assert max(observer.locked_positions_m) <= end + 10.0
    assert stops["dry"][0].stop_distance_m[0] < patch.stop_distance_m[0] < stops["low"][0].stop_distance_m[0]


def test_a_line_of_one_section_is_its_rail_condition(config_copy, stops):
    path = config_copy / "lines" / "low_patch.yaml"
    _edit(path, lambda data: data.update(sections=[{"start_m": 0.0, "rail_condition": "dry"}]))
    uniform, _ = _stop(None, line="low_patch")
    np.testing.assert_array_equal(uniform.stop_distance_m, stops["dry"][0].stop_distance_m)
    np.testing.assert_array_equal(uniform.slip_work_J, stops["dry"][0].slip_work_J)


@pytest.mark.parametrize(
    ("sections", "message"),
    [
        ([{"start_m": 5.0, "rail_condition": "dry"}], "sections[0].start_m = 5.0: the first section must start at 0"),
        (
            [{"start_m": 0.0, "rail_condition": "dry"}, {"start_m": 0.0, "rail_condition": "low"}],
            "sections[1].start_m = 0.0: must lie beyond",
        ),
    ],
)
def test_bad_line_names_file_field_value(config_copy, sections, message):
    path = config_copy / "lines" / "low_patch.yaml"
    _edit(path, lambda data: data.update(sections=sections))
    with pytest.raises(cfg.ConfigError) as info:
        cfg.load("lines", "low_patch")
    assert str(path) in str(info.value) and message in str(info.value)


def test_unknown_rail_condition_of_a_line_names_line_and_section(config_copy):
    path = config_copy / "lines" / "low_patch.yaml"
    _edit(path, lambda data: data["sections"][1].update(rail_condition="icy"))
    vehicle = cfg.load("vehicles", "emu_8axle")
    with pytest.raises(
        cfg.ConfigError, match=r"line 'low_patch', sections\[1\].rail_condition: unknown rail condition 'icy'"
    ):
        wheel_rail_adhesion(vehicle, cfg.load("lines", "low_patch"))


# ------------------------------------------------------------------------------------------------
# The compiled kernel against the numpy reference


def _batch(simulator_class, adhesion: WheelRailAdhesion, n_trains: int = 5, seed: int = 7):
    """A batch of emu_8axle stops with everything different per train and per disc: loads, speeds,
    per-axle commands, scattered mu_0 and a; EP cylinders, step 0.2 s."""
    vehicle = cfg.load("vehicles", "emu_8axle")
    plant = train_plant(vehicle)
    rng = np.random.default_rng(seed)
    nominal = nominal_draw(cfg.load("materials", vehicle.material), n_trains, plant.disc_shape)
    shape = nominal.initial_mu.shape
    draw = FrictionDraw(
        initial_mu=nominal.initial_mu * (1.0 + 0.05 * rng.standard_normal(shape)),
        power_coefficient_per_s=nominal.power_coefficient_per_s * (1.0 + 0.1 * rng.standard_normal(shape)),
    )
    conditions = train_conditions(
        vehicle,
        mass_kg=np.linspace(vehicle.mass_kg("empty"), vehicle.mass_kg("max"), n_trains),
        initial_speed_mps=np.linspace(15.0, 45.0, n_trains),
        draw=draw,
        running_resistance_A_N=np.full(n_trains, vehicle.running_resistance.A_N),
    )
    pressure = CommandedPressure([brake_cylinder(cfg.load("pneumatics", "EP"))] * n_trains, plant.n_axles, 0.2)
    pressure.set_command(rng.uniform(1.0, 4.0, (n_trains, plant.n_axles)))
    return simulator_class(plant, conditions, pressure, adhesion, step_s=0.2)


def _assert_same_states(compiled: AdhesionSimulator, reference: NumpyAdhesionSimulator) -> None:
    for name in ("disc", "train", "wheelset", "stop_time_s"):
        np.testing.assert_allclose(getattr(compiled, name), getattr(reference, name), rtol=1e-11, atol=1e-9)
    np.testing.assert_array_equal(compiled.moving, reference.moving)


@pytest.mark.parametrize(
    "rail",
    ["dry", "low", "low_patch_with_axle_offsets", "wet_scattered_per_train", "low_conditioned"],
    ids=["dry", "low", "patch-offsets", "wet-per-train", "low-conditioned"],
)
def test_compiled_adhesion_step_is_the_numpy_reference(rail):
    """Trains stopping, standing and cooling in one batch (not held), wheels rolling, locking and
    spinning up again on a patch with the axles spread along the train, and each train on its own
    rail (mu_0 scaled per train, from a wet rail that holds to a low one that locks), and on a rail
    each axle conditions for the next: the compiled kernel and the numpy scheme agree to round-off
    at every step."""
    vehicle = cfg.load("vehicles", "emu_8axle")
    if rail == "wet_scattered_per_train":
        adhesion = dataclasses.replace(_adhesion("wet"), static_friction_factor=(1.3, 1.0, 0.5, 0.2, 0.25))
    elif rail == "low_patch_with_axle_offsets":
        adhesion = dataclasses.replace(
            wheel_rail_adhesion(vehicle, cfg.load("lines", "low_patch")),
            axle_offsets_m=tuple(np.linspace(0.0, 95.0, vehicle.n_axles)),
        )
    else:
        adhesion = _adhesion(rail)
    compiled, reference = _batch(AdhesionSimulator, adhesion), _batch(NumpyAdhesionSimulator, adhesion)
    stopped_some, locked_some = False, False
    for _ in range(150):
        compiled.step()
        reference.step()
        _assert_same_states(compiled, reference)
        stopped_some |= bool((~compiled.moving).any() and compiled.moving.any())
        locked_some |= bool(((compiled.wheel_speed_mps == 0.0) & compiled.moving).any())
    assert stopped_some
    assert locked_some == (rail != "dry")


def test_compiled_adhesion_holds_standing_trains_like_the_reference():
    adhesion = _adhesion("low")
    compiled, reference = _batch(AdhesionSimulator, adhesion), _batch(NumpyAdhesionSimulator, adhesion)
    for sim in (compiled, reference):
        sim.hold_standing_trains = True
        sim.step(250)
    _assert_same_states(compiled, reference)
    standing = ~compiled.moving
    assert standing.any()
    before = compiled.disc[..., standing].copy()
    compiled.step()
    np.testing.assert_array_equal(compiled.disc[..., standing], before)


def test_compiled_adhesion_is_the_same_bit_for_bit_run_again_on_any_number_of_threads():
    adhesion = _adhesion("low")
    n_trains = 3 * wheelset_kernel.TRAINS_PER_THREAD
    threads = kernel.kernel_threads()
    try:
        runs = []
        for n_threads in (1, 2, 1):
            kernel.set_kernel_threads(min(n_threads, numba.config.NUMBA_NUM_THREADS))
            sim = _batch(AdhesionSimulator, adhesion, n_trains=n_trains)
            sim.step(60)
            runs.append(sim)
    finally:
        kernel.set_kernel_threads(threads)
    for sim in runs[1:]:
        for name in ("disc", "train", "wheelset"):
            np.testing.assert_array_equal(getattr(sim, name), getattr(runs[0], name))


def test_reset_trains_starts_those_trains_afresh():
    """A reset train runs on as a new simulator's train would, bit for bit (its body mass, wheel
    loads and wheel speeds set again); the other trains go on as if nothing happened."""
    adhesion = _adhesion("low")
    sim, fresh, untouched = (_batch(AdhesionSimulator, adhesion) for _ in range(3))
    sim.step(40)
    untouched.step(40)
    index = np.array([0])
    conditions = dataclasses.replace(
        sim.conditions,
        **{
            field.name: np.asarray(getattr(sim.conditions, field.name))[index]
            for field in dataclasses.fields(sim.conditions)
        },
    )
    sim.reset_trains(index, conditions)
    sim.pressure.reset_trains(index)
    sim.pressure.set_command(
        np.where(np.arange(sim.n_trains)[:, None] == 0, fresh.pressure.command_bar, sim.pressure.command_bar)
    )
    np.testing.assert_array_equal(sim.wheelset[..., 0], fresh.wheelset[..., 0])
    sim.step(30)
    fresh.step(30)
    untouched.step(30)
    for name in ("disc", "train", "wheelset"):
        np.testing.assert_array_equal(getattr(sim, name)[..., 0], getattr(fresh, name)[..., 0])
        np.testing.assert_array_equal(getattr(sim, name)[..., 1:], getattr(untouched, name)[..., 1:])
    assert (sim.wheel_speed_mps[:, 0] == 0.0).any()  # the reset train's wheels locked again


def test_deceleration_is_the_rail_forces_over_the_body_mass():
    """With adhesion the brake acts on the wheels: the body decelerates by the creep forces and
    the running resistance (at the state of any step, given its wheel speeds), not by the disc
    friction the simulator without adhesion would report."""
    sim = _batch(AdhesionSimulator, _adhesion("low"))
    sim.step(30)
    train, wheels = sim.train.copy(), sim.wheel_speed_mps.copy()
    law = sim.adhesion.law_at(train[POSITION])
    forces = sim.creep_force_N(train[SPEED], wheels, law).sum(axis=0)
    resistance = sim.plant.running_resistance.force_N(train[SPEED], sim.resistance_A_N)
    expected = np.where(sim.moving, (forces + resistance) / sim.body_mass_kg, 0.0)
    np.testing.assert_array_equal(sim.deceleration_mps2(), expected)
    # Bounded by the rail: the peak adhesion of the low rail times the weight over the body mass.
    peak = cfg.load("rail_conditions", "low").peak_adhesion
    assert np.all(
        sim.deceleration_mps2() <= (1.05 * peak * sim.mass_kg * STANDARD_GRAVITY_MPS2 + resistance) / sim.body_mass_kg
    )
    moving = sim.moving.copy()
    sim.step()
    np.testing.assert_array_equal(
        sim.deceleration_at_mps2(sim.disc, train, moving, sim.pressure.pressure_bar, wheels), expected
    )
    with pytest.raises(ValueError, match="wheel_speed_mps"):
        sim.deceleration_at_mps2(sim.disc, train, moving, sim.pressure.pressure_bar)


@pytest.mark.parametrize("simulator_class", [AdhesionSimulator, NumpyAdhesionSimulator], ids=["compiled", "numpy"])
def test_trains_with_locked_wheels_near_standstill_stop_and_no_wheel_overtakes_them(simulator_class):
    """Dry rail, the WSP's 20 ms step, trains at walking pace with every wheel locked (as after a
    low-adhesion patch): with the emergency brake applied or with every cylinder vented, the
    rail's force brings each wheel back to the train's speed and no further (nothing drives a
    wheel faster than the train when no traction acts), and the train stops within the time the
    running resistance A alone takes, v0 m / A (the brake only shortens it)."""
    vehicle = cfg.load("vehicles", "emu_8axle")
    plant = train_plant(vehicle)
    initial_speed_mps = np.array([0.02, 0.3, 1.4, 0.02, 0.3, 1.4])
    n_trains = initial_speed_mps.size
    mass_kg = vehicle.mass_kg("empty")
    conditions = train_conditions(
        vehicle,
        mass_kg=np.full(n_trains, mass_kg),
        initial_speed_mps=initial_speed_mps,
        draw=nominal_draw(cfg.load("materials", vehicle.material), n_trains, plant.disc_shape),
        running_resistance_A_N=np.full(n_trains, vehicle.running_resistance.A_N),
    )
    step_s = 0.02
    pressure = CommandedPressure([brake_cylinder(cfg.load("pneumatics", "EP"))] * n_trains, plant.n_axles, step_s)
    braked = np.arange(n_trains) < 3
    command_bar = np.where(braked, vehicle.brake_pressure_bar("emergency", "empty"), 0.0)
    pressure.set_command(np.repeat(command_bar[:, None], plant.n_axles, axis=1))
    sim = simulator_class(plant, conditions, pressure, _adhesion("dry"), step_s=step_s)
    sim.wheelset[ANGULAR_SPEED] = 0.0
    limit_s = initial_speed_mps.max() * mass_kg / vehicle.running_resistance.A_N + 2.0
    largest_overspeed_mps = 0.0
    while sim.moving.any() and sim.time_s < limit_s:
        sim.step()
        overspeed = (sim.wheel_speed_mps - sim.train[SPEED])[:, sim.moving]
        largest_overspeed_mps = max(largest_overspeed_mps, float(overspeed.max(initial=0.0)))
    assert not sim.moving.any(), f"still moving at {sim.time_s:.1f} s: {sim.train[SPEED]} m/s"
    assert largest_overspeed_mps < 1e-3
    # The braked trains stop within seconds, far sooner than on the running resistance alone.
    assert np.all(sim.stop_time_s[braked] < 5.0)
