"""The compiled kernels against the numpy reference, the two compiled paths against each other,
determinism, and the elementary functions the kernels compute powers with."""

import math

import numba
import numpy as np
import pytest

from brakegym import config as cfg
from brakegym.applications import TrainApplication, train_stops
from brakegym.campaigns import field_applications, train_monte_carlo
from brakegym.execution import LocalExecutor
from brakegym.physics import BrakeCylinder, FrictionDraw, draw_friction
from brakegym.physics.elementary import fractional_power
from brakegym.plants import dynamometer_plant, scatter_partition, stochastic_friction, train_plant
from brakegym.simulator import (
    DISC_STATES,
    TRAIN_STATES,
    BatchConditions,
    CommandedPressure,
    NumpyReferenceSimulator,
    PrescribedPressure,
    Simulator,
    kernel,
    kernel_math,
)


@pytest.fixture(scope="module")
def vehicle():
    return cfg.load("vehicles", "emu_8axle")


@pytest.fixture(scope="module")
def plant(vehicle):
    return train_plant(vehicle)


# ------------------------------------------------------------------------------------------------
# Elementary functions


@numba.njit(**kernel_math.JIT_OPTIONS)
def _exp_each(x, out):
    for i in range(x.size):
        out[i] = kernel_math.exp(x[i])


@numba.njit(**kernel_math.JIT_OPTIONS)
def _log_each(x, out):
    for i in range(x.size):
        out[i] = kernel_math.log(x[i])


@numba.njit(**kernel_math.JIT_OPTIONS)
def _power_each(base, exponent, out):
    for i in range(base.size):
        out[i] = fractional_power(base[i], exponent)


def _ulp_error(got, reference):
    return np.max(np.abs(got - reference) / np.spacing(np.abs(reference)))


def test_exp_and_log_within_one_ulp():
    rng = np.random.default_rng(0)
    x = rng.uniform(-708.0, 709.7, 100_000)
    out = np.empty_like(x)
    _exp_each(x, out)
    assert _ulp_error(out, np.array([math.exp(v) for v in x])) <= 1.0
    y = np.exp(rng.uniform(-700.0, 700.0, 100_000))
    y[:5] = [1.0, 2.0, 0.5, 1.0 - 2**-52, 5e-320]  # around 1 and a subnormal
    _log_each(y, out)
    assert _ulp_error(out, np.array([math.log(v) for v in y])) <= 1.0


def test_exp_and_log_special_values():
    out = np.empty(7)
    _exp_each(np.array([0.0, -np.inf, np.inf, np.nan, 710.0, -708.5, -1000.0]), out)
    np.testing.assert_array_equal(out, [1.0, 0.0, np.inf, np.nan, np.inf, 0.0, 0.0])
    _log_each(np.array([1.0, 0.0, -0.0, -1.0, np.inf, np.nan, -np.inf]), out)
    np.testing.assert_array_equal(out, [0.0, -np.inf, -np.inf, np.nan, np.inf, np.nan, np.nan])


@pytest.mark.parametrize("exponent", [0.994, 0.533, 1.581, 0.367, 0.4, 0.6])
def test_fractional_power_over_the_model_range(exponent):
    """Bases from 1e-6 to 1e3 cover every power of Eqs. 4 and 10 in this model; ln x is carried
    in two parts into e^(y ln x), so the power is within 1 ulp however large |y ln x| is."""
    rng = np.random.default_rng(1)
    base = np.exp(rng.uniform(math.log(1e-6), math.log(1e3), 100_000))
    out = np.empty_like(base)
    _power_each(base, exponent, out)
    assert _ulp_error(out, np.power(base, exponent)) <= 1.0
    _power_each(np.array([0.0, 1.0, np.inf, np.nan]), exponent, out[:4])
    np.testing.assert_array_equal(out[:4], [0.0, 1.0, np.inf, np.nan])


def test_fractional_power_special_cases():
    out = np.empty(4)
    _power_each(np.array([0.0, 2.0, 1e-300, np.inf]), 0.0, out)
    np.testing.assert_array_equal(out, 1.0)
    _power_each(np.array([0.0, np.inf, -2.0, 1e-310]), -0.5, out)
    np.testing.assert_array_equal(out[:3], [np.inf, 0.0, np.nan])
    assert out[3] == pytest.approx(1e-310**-0.5, rel=1e-14)  # subnormal base
    _power_each(np.array([2.0]), np.nan, out[:1])
    assert np.isnan(out[0])


# ------------------------------------------------------------------------------------------------
# Kernels against the numpy reference


def test_kernel_state_rows_match_the_simulator():
    disc_rows = {
        "mu": kernel.MU,
        "friction_temperature_K": kernel.T_FRIC,
        "disc_temperature_K": kernel.T_DISC,
        "mu_distance_m": kernel.MU_DISTANCE,
        "friction_heat_J": kernel.FRICTION_HEAT,
        "cooling_heat_J": kernel.COOLING_HEAT,
    }
    train_rows = {
        "speed_mps": kernel.SPEED,
        "position_m": kernel.POSITION,
        "brake_work_J": kernel.BRAKE_WORK,
        "resistance_work_J": kernel.RESISTANCE_WORK,
        "extra_work_J": kernel.EXTRA_WORK,
        "mu_eff_distance_m": kernel.MU_EFF_DISTANCE,
    }
    assert disc_rows == {name: DISC_STATES.index(name) for name in DISC_STATES}
    assert train_rows == {name: TRAIN_STATES.index(name) for name in TRAIN_STATES}
    assert (kernel.N_DISC_STATES, kernel.N_TRAIN_STATES) == (len(DISC_STATES), len(TRAIN_STATES))


class _ArrayScale:
    def __init__(self, scale):
        self.value = scale

    def scale(self, context):
        return self.value


class _ArrayForce:
    def __init__(self, force):
        self.value = force

    def force_N(self, context):
        return self.value


class _ConstantScale(_ArrayScale):
    constant = True


class _ConstantForce(_ArrayForce):
    constant = True


def _random_batch(plant, n, rng):
    shape = (n, *plant.disc_shape)
    return BatchConditions(
        mass_kg=rng.uniform(5e4, 1.5e5, n),
        initial_speed_mps=rng.uniform(0.0, 45.0, n),
        initial_mu=rng.uniform(0.0, 0.9, shape),  # also outside [mu_min, mu_max]: bounded first
        power_coefficient_per_s=rng.normal(0.008, 0.001, shape),
        running_resistance_A_N=rng.normal(2500.0, 1600.0, n),
        initial_friction_temperature_K=rng.uniform(280.0, 1100.0, shape),
        initial_disc_temperature_K=rng.uniform(280.0, 900.0, shape),
        ambient_temperature_K=rng.uniform(260.0, 310.0, n),
    )


@pytest.mark.parametrize("with_hooks", [False, True])
def test_stage_rates_match_the_numpy_reference_on_random_states(plant, with_hooks):
    rng = np.random.default_rng(7)
    n = 37  # two full tiles and a partial one
    conditions = _random_batch(plant, n, rng)
    pressure = CommandedPressure([BrakeCylinder(0.2, 0.8)] * n, plant.n_axles, 0.1)
    hooks = {}
    if with_hooks:
        hooks = dict(
            friction_modifiers=[_ArrayScale(rng.uniform(0.5, 1.2, (*plant.disc_shape, n)))],
            extra_forces=[_ArrayForce(rng.normal(0.0, 5e3, n))],
        )
    reference = NumpyReferenceSimulator(plant, conditions, pressure, 0.1, **hooks)
    # Standing trains, overshoot past standstill (negative speed), released and clamped axles.
    reference.train[0, :4] = [0.0, -0.3, 1e-4, 0.0]
    reference.moving = reference.train[0] > 0
    reference.disc[3:] = rng.uniform(0.0, 1e6, reference.disc[3:].shape)
    reference.train[1:] = rng.uniform(0.0, 1e6, reference.train[1:].shape)
    pressure_bar = rng.uniform(0.0, 4.5, (n, plant.n_axles))
    pressure_bar[:3] = 0.0
    clamp = reference.clamp_force_N(pressure_bar)
    expected_disc, expected_train = reference.rates(0.0, reference.disc, reference.train, clamp)

    compiled = Simulator(plant, conditions, pressure, 0.1, **hooks)
    context = compiled.context_at(0.0, reference.disc, reference.train, np.ascontiguousarray(clamp))
    scale, extra = compiled.hooks_at(context)
    disc_rates, train_rates = np.empty_like(reference.disc), np.empty_like(reference.train)
    kernel.stage_rates(
        compiled.plant_parameters,
        reference.disc,
        reference.train,
        reference.moving,
        pressure_bar,
        scale,
        extra,
        compiled.power_coefficient,
        compiled.train_constants,
        disc_rates,
        train_rates,
    )
    # 1e-12 relative to the size of each quantity over the batch (a rate that is a small
    # difference of large heat flows is compared at the scale of those flows).
    for names, got, expected in ((DISC_STATES, disc_rates, expected_disc), (TRAIN_STATES, train_rates, expected_train)):
        for row, name in enumerate(names):
            size = np.max(np.abs(expected[row]))
            np.testing.assert_allclose(got[row], expected[row], rtol=1e-12, atol=1e-12 * size, err_msg=name)


@pytest.mark.parametrize("constant", [False, True])
def test_deceleration_matches_the_numpy_reference(plant, constant):
    """Also with hooks that the kernel integrates as constants: the deceleration must see them."""
    rng = np.random.default_rng(11)
    n = 20
    conditions = _random_batch(plant, n, rng)
    cylinders = [BrakeCylinder(0.2, 0.8)] * n
    pressure = CommandedPressure(cylinders, plant.n_axles, 0.1, initial_pressure_bar=rng.uniform(0, 4.5, (n, 8)))
    force_class, scale_class = (_ConstantForce, _ConstantScale) if constant else (_ArrayForce, _ArrayScale)
    hooks = dict(
        extra_forces=[force_class(rng.normal(0.0, 5e3, n))], friction_modifiers=[scale_class(rng.uniform(0.7, 1.2, n))]
    )
    reference = NumpyReferenceSimulator(plant, conditions, pressure, 0.1, **hooks)
    compiled = Simulator(plant, conditions, pressure, 0.1, **hooks)
    np.testing.assert_allclose(compiled.deceleration_mps2(), reference.deceleration_mps2(), rtol=1e-13)
    plain = Simulator(plant, conditions, pressure, 0.1)
    assert not np.allclose(plain.deceleration_mps2(), compiled.deceleration_mps2())


def _mixed_applications():
    cases = [
        ("empty", "emergency", "EP", 120.0),
        ("max", "service", "PN", 160.0),
        ("normal", "emergency", "PN", 100.0),
        ("empty", "service", "EP", 140.0),
    ]
    return [TrainApplication(load=load, brake_mode=m, actuation=a, initial_speed_kmh=v) for load, m, a, v in cases * 5]


def _scatter_draw(vehicle, plant, n, seed):
    material = cfg.load("materials", vehicle.material)
    return draw_friction(
        np.random.default_rng(seed),
        stochastic_friction(material),
        scatter_partition(cfg.load("setups", "mcs-75-25")),
        n,
        plant.disc_shape,
    )


SUMMARY_FIELDS = (
    "stop_distance_m",
    "stop_time_s",
    "mu_s",
    "mu_s_eff",
    "peak_friction_temperature_C",
    "peak_disc_temperature_C",
    "friction_heat_J",
    "stored_heat_J",
    "cooling_heat_J",
    "brake_work_J",
)


def test_compiled_stops_match_the_numpy_reference(vehicle, plant, monkeypatch):
    """Whole stops, 20 trains of mixed applications with friction scatter: the compiled
    simulator and the numpy one agree to rounding (their fractional powers differ by ulps)."""
    apps = _mixed_applications()
    draw = _scatter_draw(vehicle, plant, len(apps), 3)
    compiled = train_stops(vehicle, apps, draw=draw)
    monkeypatch.setattr("brakegym.applications.Simulator", NumpyReferenceSimulator)
    reference = train_stops(vehicle, apps, draw=draw)
    for name in SUMMARY_FIELDS:
        np.testing.assert_allclose(getattr(compiled, name), getattr(reference, name), rtol=1e-12, err_msg=name)


def test_fused_and_staged_paths_agree(vehicle, plant):
    """A neutral friction modifier sends the simulator down the staged path (Python RK4 around
    the compiled stage rates); it must give what the fused kernel gives."""
    apps = _mixed_applications()
    draw = _scatter_draw(vehicle, plant, len(apps), 5)
    fused = train_stops(vehicle, apps, draw=draw)
    staged = train_stops(vehicle, apps, draw=draw, friction_modifiers=[_ArrayScale(1.0)])
    for name in SUMMARY_FIELDS:
        np.testing.assert_allclose(getattr(staged, name), getattr(fused, name), rtol=1e-12, atol=0.0, err_msg=name)


def test_constant_hooks_run_compiled_and_agree_with_the_staged_path(vehicle, plant):
    """Hooks that declare themselves constant (a friction level, a gradient) are integrated in
    the compiled kernel; they must give what the staged path gives with the same values, and
    their work must close the energy balance."""
    apps = _mixed_applications()
    n = len(apps)
    draw = _scatter_draw(vehicle, plant, n, 7)
    rng = np.random.default_rng(3)
    scale = rng.uniform(0.8, 1.2, (n,))
    force_N = rng.uniform(-8000.0, 8000.0, (n,))
    staged = train_stops(
        vehicle, apps, draw=draw, friction_modifiers=[_ArrayScale(scale)], extra_forces=[_ArrayForce(force_N)]
    )
    compiled = train_stops(
        vehicle, apps, draw=draw, friction_modifiers=[_ConstantScale(scale)], extra_forces=[_ConstantForce(force_N)]
    )
    for name in SUMMARY_FIELDS:
        np.testing.assert_allclose(getattr(compiled, name), getattr(staged, name), rtol=1e-12, atol=0.0, err_msg=name)
    total = compiled.brake_work_J + compiled.resistance_work_J + compiled.extra_work_J
    np.testing.assert_allclose(total, compiled.initial_kinetic_energy_J, rtol=0.005)
    assert np.any(compiled.extra_work_J != 0.0)


def test_fused_and_staged_paths_agree_on_the_dynamometer():
    rig = cfg.load("rigs", "dynamometer")
    plant = dynamometer_plant(rig)
    n = 5
    conditions = BatchConditions(
        mass_kg=np.full(n, 8000.0),
        initial_speed_mps=np.linspace(20.0, 44.0, n),
        initial_mu=np.full((n, 1, 1), 0.35),
        power_coefficient_per_s=np.full((n, 1, 1), 0.008),
        running_resistance_A_N=np.zeros(n),
        initial_friction_temperature_K=np.full((n, 1, 1), 323.15),
        initial_disc_temperature_K=np.full((n, 1, 1), 323.15),
        ambient_temperature_K=np.full(n, 293.15),
    )
    sims = []
    for hooks in ({}, {"friction_modifiers": [_ArrayScale(1.0)]}):
        pressure = CommandedPressure([BrakeCylinder(0.0, 0.6)] * n, 1, 0.2)
        pressure.set_command(np.full((n, 1), 38000.0))
        sim = Simulator(plant, conditions, pressure, 0.2, **hooks)
        while sim.moving.any():
            sim.step()
        sims.append(sim)
    np.testing.assert_array_equal(sims[0].disc, sims[1].disc)
    np.testing.assert_array_equal(sims[0].train, sims[1].train)
    np.testing.assert_array_equal(sims[0].stop_time_s, sims[1].stop_time_s)


# ------------------------------------------------------------------------------------------------
# Determinism and the step record


def test_a_train_is_the_same_alone_and_anywhere_in_a_batch(vehicle, plant):
    """Bit for bit: no result depends on a train's tile or vector lane, nor on how long the
    others take to stop (each train is held from its own standstill: its peak disc temperature
    and the heat stored and given to the air end there)."""
    apps = _mixed_applications()
    draw = _scatter_draw(vehicle, plant, len(apps), 9)
    batch = train_stops(vehicle, apps, draw=draw)
    for index in (0, 7, 19):
        alone = train_stops(
            vehicle,
            apps[index : index + 1],
            draw=FrictionDraw(draw.initial_mu[index : index + 1], draw.power_coefficient_per_s[index : index + 1]),
        )
        for name in SUMMARY_FIELDS:
            np.testing.assert_array_equal(getattr(alone, name)[0], getattr(batch, name)[index], err_msg=name)


def test_same_seed_gives_bit_identical_campaign(vehicle):
    campaign = cfg.load("campaigns", "field2022")
    apps = [app for app in field_applications(campaign)[:6] for _ in range(3)]
    setup = cfg.load("setups", "mcs-75-25")
    first, _, _ = train_monte_carlo(vehicle, apps, setup, seed=4)
    second, _, _ = train_monte_carlo(vehicle, apps, setup, seed=4)
    for name in SUMMARY_FIELDS:
        np.testing.assert_array_equal(getattr(first, name), getattr(second, name), err_msg=name)


@pytest.fixture
def kernel_threads():
    """Restores the process's kernel thread count after a test that changes it."""
    before = kernel.kernel_threads()
    yield
    kernel.set_kernel_threads(before)


@pytest.mark.usefixtures("kernel_threads")
def test_threads_give_the_same_stops_bit_for_bit(vehicle, plant):
    """Tiles shared out over threads: the same numbers as on one thread, whatever the count (the
    threaded kernel is compiled and run even on a one-core machine, with as many threads as numba
    allows)."""
    apps = _mixed_applications() * 3  # several tiles
    draw = _scatter_draw(vehicle, plant, len(apps), 5)
    kernel.set_kernel_threads(1)
    single = train_stops(vehicle, apps, draw=draw)
    for threads in {2, numba.config.NUMBA_NUM_THREADS} - {1}:
        if threads > numba.config.NUMBA_NUM_THREADS:
            continue
        kernel.set_kernel_threads(threads)
        threaded = train_stops(vehicle, apps, draw=draw)
        for name in SUMMARY_FIELDS:
            np.testing.assert_array_equal(getattr(threaded, name), getattr(single, name), err_msg=name)
    with pytest.raises(ValueError, match="kernel threads 0"):
        kernel.set_kernel_threads(0)


@pytest.mark.usefixtures("kernel_threads")
def test_forked_campaign_workers_after_threaded_steps(vehicle):
    """A campaign's forked workers run single-threaded: a process that has run the threaded kernel
    can still fork them, and they give the one-process numbers."""
    campaign = cfg.load("campaigns", "field2022")
    apps = [app for app in field_applications(campaign)[:6] for _ in range(370)]
    setup = cfg.load("setups", "mcs-75-25")
    kernel.set_kernel_threads(numba.config.NUMBA_NUM_THREADS)
    in_process, _, _ = train_monte_carlo(vehicle, apps, setup, seed=4)
    forked, _, _ = train_monte_carlo(vehicle, apps, setup, seed=4, executor=LocalExecutor(2))
    np.testing.assert_array_equal(forked.braking_distance_m, in_process.braking_distance_m)


def test_step_record_keeps_the_pre_step_state(plant):
    rng = np.random.default_rng(2)
    n = 3
    pressure = CommandedPressure([BrakeCylinder(0.2, 0.8)] * n, plant.n_axles, 0.1, initial_pressure_bar=3.3)
    sim = Simulator(plant, _random_batch(plant, n, rng), pressure, 0.1)
    disc_before, train_before, moving_before = sim.disc.copy(), sim.train.copy(), sim.moving
    record = sim.step()
    np.testing.assert_array_equal(record.disc_start, disc_before)
    np.testing.assert_array_equal(record.train_start, train_before)
    assert record.disc_start is not sim.disc and record.train_start is not sim.train
    assert sim.moving is not moving_before  # a new array: a caller's old reference stays valid
    for _ in range(3):
        sim.step()
    np.testing.assert_array_equal(record.disc_start, disc_before)
    np.testing.assert_array_equal(record.train_start, train_before)
    np.testing.assert_array_equal(record.clamp_force_start_N[:, 0, :], sim.clamp_force_N(np.full((n, 8), 3.3))[:, 0, :])


@pytest.mark.parametrize("source", ["prescribed", "commanded"])
def test_trajectory_in_one_call_is_step_by_step_bit_for_bit(plant, source):
    """Simulator.trajectory (one compiled call, every step's state kept) against step() one step
    at a time, with a pressure that changes within the steps, trains that stop inside the run."""
    rng = np.random.default_rng(5)
    n, n_steps, step_s = 4, 60, 0.1

    def pressure_source():
        if source == "commanded":
            pressure = CommandedPressure([BrakeCylinder(0.2, 0.8)] * n, plant.n_axles, step_s)
            pressure.set_command(np.full((n, plant.n_axles), 3.8))
            return pressure
        knots = np.linspace(0.0, n_steps * step_s, 37)  # not on the half steps
        trace = np.clip(
            np.linspace(0.0, 4.5, len(knots))[:, None, None] + rng.normal(0, 0.2, (len(knots), n, plant.n_axles)),
            0,
            None,
        )
        return PrescribedPressure(knots, trace, step_s)

    batch = _random_batch(plant, n, np.random.default_rng(6))
    batch.initial_speed_mps[:] = [3.0, 8.0, 15.0, 30.0]
    stepped = Simulator(plant, batch, pressure_source(), step_s)
    rng = np.random.default_rng(5)
    whole = Simulator(plant, batch, pressure_source(), step_s)
    discs, trains, movings = whole.trajectory(n_steps)
    assert len(discs) == len(trains) == len(movings) == n_steps + 1
    for step in range(n_steps + 1):
        if step:
            stepped.step()
        np.testing.assert_array_equal(discs[step], stepped.disc)
        np.testing.assert_array_equal(trains[step], stepped.train)
        np.testing.assert_array_equal(movings[step], stepped.moving)
    assert movings[0].all() and not movings[-1][0]  # the slowest train stopped within the run
    np.testing.assert_array_equal(whole.stop_time_s, stepped.stop_time_s)
    np.testing.assert_array_equal(whole.pressure.pressure_bar, stepped.pressure.pressure_bar)
    assert whole.step_index == stepped.step_index == n_steps


def test_kernel_cache_stamp_covers_the_physics_sources(tmp_path):
    """numba checks only the file of a cached function; the kernels inline the physics modules,
    so their cache stamp is a digest of every source they compile."""
    names = {path.name for path in kernel._CACHE_SOURCES}
    physics = {"friction.py", "thermal.py", "mechanics.py", "pneumatics.py", "elementary.py"}
    assert {"kernel.py", "kernel_math.py"} | physics <= names
    copies = []
    for path in kernel._CACHE_SOURCES:
        copy = tmp_path / path.name
        copy.write_bytes(path.read_bytes())
        copies.append(copy)
    assert kernel.cache_sources_digest(copies) == kernel._SOURCES_DIGEST
    friction = tmp_path / "friction.py"
    friction.write_text(friction.read_text() + "\n# an edit\n")
    assert kernel.cache_sources_digest(copies) != kernel._SOURCES_DIGEST


@pytest.mark.parametrize("cylinder_kinds", ["uniform", "mixed"])
def test_several_steps_in_one_call_equal_single_steps(plant, cylinder_kinds):
    """Simulator.step(n) runs the cylinders' pressure model inside the compiled call: the same
    states, pressures, stop times and last-step record as n single steps, bit for bit, with
    commands changing between calls and trains stopping inside them."""
    rng = np.random.default_rng(11)
    n = 21  # a full tile and a partial one
    cylinders = [BrakeCylinder(0.2, 0.8)] * n
    if cylinder_kinds == "mixed":
        cylinders = [BrakeCylinder(0.1 * (i % 3), 0.5 + 0.1 * (i % 4)) for i in range(n)]
    conditions = _random_batch(plant, n, rng)
    conditions.initial_speed_mps = rng.uniform(0.5, 8.0, n)
    sims = [Simulator(plant, conditions, CommandedPressure(cylinders, plant.n_axles, 0.1), 0.1) for _ in range(2)]
    for call in range(40):
        command = rng.uniform(0.0, 4.5, (n, plant.n_axles))
        n_steps = 1 + call % 3
        for sim in sims:
            sim.pressure.set_command(command)
        many = sims[0].step(n_steps)
        for _ in range(n_steps):
            single = sims[1].step()
        for a, b in ((sims[0].disc, sims[1].disc), (sims[0].train, sims[1].train), (sims[0].moving, sims[1].moving)):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(sims[0].stop_time_s, sims[1].stop_time_s)
        np.testing.assert_array_equal(sims[0].pressure.pressure_bar, sims[1].pressure.pressure_bar)
        assert sims[0].time_s == sims[1].time_s
        assert many.time_start_s == single.time_start_s
        for name in ("disc_start", "train_start", "clamp_force_start_N", "clamp_force_end_N", "stop_fraction"):
            np.testing.assert_array_equal(getattr(many, name), getattr(single, name), err_msg=name)
    assert (~sims[0].moving).sum() >= n // 2, "trains stopped inside the calls"


def test_numpy_reference_cylinders_equal_the_compiled_ones(plant):
    """The kernel's copy of CommandedPressure gives the class's pressures bit for bit."""
    rng = np.random.default_rng(12)
    n = 5
    cylinders = [BrakeCylinder(0.1 * i, 0.4 + 0.2 * i) for i in range(n)]
    conditions = _random_batch(plant, n, rng)
    compiled = Simulator(plant, conditions, CommandedPressure(cylinders, plant.n_axles, 0.1), 0.1)
    python = CommandedPressure(cylinders, plant.n_axles, 0.1)
    for _ in range(30):
        command = rng.uniform(0.0, 4.5, (n, plant.n_axles))
        compiled.pressure.set_command(command)
        python.set_command(command)
        compiled.step()
        python.stage_pressures_bar()
        python.advance()
        np.testing.assert_array_equal(compiled.pressure.pressure_bar, python.pressure_bar)


def test_replaced_constant_hooks_take_effect(plant):
    """The compiled path keeps the arrays of constant hooks between steps; hooks replaced on a
    running simulator (an environment does so when it restarts trains) must be used at once."""
    rng = np.random.default_rng(11)
    conditions = _random_batch(plant, 3, rng)
    conditions = BatchConditions(**{**conditions.__dict__, "initial_speed_mps": np.full(3, 20.0)})
    pressure = CommandedPressure([BrakeCylinder(0.2, 0.8)] * 3, plant.n_axles, 0.1)
    first, second = np.array([1000.0, -2000.0, 0.0]), np.array([5000.0, 3000.0, -4000.0])
    sim = Simulator(plant, conditions, pressure, 0.1, extra_forces=(_ConstantForce(first),))
    sim.step()
    before = sim.deceleration_mps2()
    sim.extra_forces = (_ConstantForce(second),)
    after = sim.deceleration_mps2()
    np.testing.assert_allclose(after - before, (second - first) / conditions.mass_kg, rtol=1e-9)
    state = sim.train.copy()
    sim.step()  # the step integrates the new force too: compare with a simulator built with it
    fresh = Simulator(
        plant,
        conditions,
        CommandedPressure([BrakeCylinder(0.2, 0.8)] * 3, plant.n_axles, 0.1),
        0.1,
        extra_forces=(_ConstantForce(first),),
    )
    fresh.step()
    fresh.extra_forces = (_ConstantForce(second),)
    np.testing.assert_array_equal(fresh.train, state)
    fresh.step()
    np.testing.assert_array_equal(fresh.train, sim.train)
