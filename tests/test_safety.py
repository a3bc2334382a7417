"""Safety cases as response functions (brakegym.safety): the point u = 0 is the nominal stop, each
input moves the distance the way physics says, and a stop with every brake failed runs out as
running resistance alone allows."""

import json
import math

import numpy as np
import pytest
from scipy import integrate, special, stats

from brakegym import config as cfg
from brakegym.applications import TrainApplication, train_stops
from brakegym.execution import DaskExecutor, LocalExecutor
from brakegym.physics import BrakeCylinder, CaliperLaw
from brakegym.safety import BrakingModel, InputLayout
from brakegym.safety.conventional import conventional_stop, equivalent_response_time_s, time_to_force_share_s
from brakegym.safety.etcs import (
    confidence,
    confidence_label,
    kdry_table,
    nominal_band_decelerations,
    speed_band_edges_kmh,
)
from brakegym.safety.osrd import (
    CURVES,
    TIMES,
    OsrdFormatError,
    export_kdry_table,
    read_etcs_brake_params,
    write_etcs_brake_params,
)
from brakegym.safety.tail import braking_distance_tail
from brakegym.simulator.metrics import SpeedCrossings

CASE = "emu_8axle"


def _case(**changes):
    """The shipped case with some inputs changed: ``mass={"relative_sigma": 0.0}``."""
    case = cfg.load("safety_cases", CASE)
    updates = {name: getattr(case, name).model_copy(update=fields) for name, fields in changes.items()}
    return case.model_copy(update=updates)


@pytest.fixture(scope="module")
def model():
    return BrakingModel(cfg.load("safety_cases", CASE), "empty", 160.0)


def test_layout_counts_every_input(model):
    vehicle = cfg.load("vehicles", "emu_8axle")
    per_axle = InputLayout.of(vehicle.n_axles, vehicle.n_discs, pressure_per_axle=True)
    per_train = InputLayout.of(vehicle.n_axles, vehicle.n_discs, pressure_per_axle=False)
    # 2 global + 2 x 16 individual friction, A, mass, pressures, time constant, 16 units
    assert per_axle.dims == 2 + 32 + 1 + 1 + 8 + 1 + 16 == model.dims
    assert per_train.dims == per_axle.dims - 7
    columns = np.concatenate(
        [
            np.arange(per_axle.dims)[block]
            for block in (
                per_axle.friction_global,
                per_axle.friction_individual,
                slice(per_axle.resistance, per_axle.resistance + 1),
                slice(per_axle.mass, per_axle.mass + 1),
                per_axle.pressure,
                slice(per_axle.time_constant, per_axle.time_constant + 1),
                per_axle.units,
            )
        ]
    )
    assert np.array_equal(columns, np.arange(per_axle.dims))  # each column once, none left over


def test_zero_point_is_the_nominal_stop(model):
    nominal = train_stops(
        model.vehicle, [TrainApplication("empty", "emergency", "EP", 160.0, command_time_s=0.0)]
    ).braking_distance_m
    assert model(np.zeros((1, model.dims))) == pytest.approx(nominal, rel=1e-12)


def test_a_stop_does_not_depend_on_its_batch(model):
    u = np.random.default_rng(3).standard_normal((6, model.dims))
    alone = np.concatenate([model(u[i : i + 1]) for i in range(len(u))])
    assert np.array_equal(model(u), alone)


def test_inputs_move_the_distance_the_physical_way(model):
    layout = model.layout

    def distance_with(column, value):
        u = np.zeros((1, model.dims))
        u[0, column] = value
        return model(u)[0]

    nominal = distance_with(0, 0.0)
    assert distance_with(layout.mass, 2.0) > nominal  # heavier train
    assert distance_with(layout.friction_global.start, -2.0) > nominal  # lower mu_0
    assert distance_with(layout.resistance, -2.0) > nominal  # less running resistance
    assert distance_with(layout.pressure, -2.0) > nominal  # lower pressure on the first axle
    assert distance_with(layout.time_constant, 2.0) > nominal  # slower cylinder
    assert distance_with(layout.units.start, -5.0) > nominal  # first disc unit failed (Phi(-5) < 1e-3)
    assert distance_with(layout.units.start, -3.0) == nominal  # Phi(-3) > 1e-3: it works


def test_mass_scatter_is_a_lognormal_mass(model):
    """With only the mass scattering, the point u_mass = z is the nominal stop of a train of mass
    m exp(sigma z)."""
    z, sigma = 2.5, cfg.load("safety_cases", CASE).mass.relative_sigma
    u = np.zeros((1, model.dims))
    u[0, model.layout.mass] = z
    vehicle = model.vehicle
    heavier = vehicle.model_copy(
        update={
            "loads": {
                "empty": vehicle.load("empty").model_copy(
                    update={"mass_per_disc_kg": vehicle.load("empty").mass_per_disc_kg * np.exp(sigma * z)}
                )
            }
        }
    )
    expected = train_stops(heavier, [TrainApplication("empty", "emergency", "EP", 160.0, command_time_s=0.0)])
    assert model(u)[0] == pytest.approx(expected.braking_distance_m[0], rel=1e-12)


def test_no_failures_when_units_never_fail():
    model = BrakingModel(_case(brake_units={"failure_probability_per_demand": 0.0}), "empty", 100.0)
    u = np.zeros((1, model.dims))
    u[0, model.layout.units] = -30.0
    assert model.working_units(u).all()


def test_every_brake_failed_coasts_on_running_resistance():
    """Analytic limit: no brake force, m dv/dt = -(A + B v + C v^2), so the distance is the
    integral of m v / (A + B v + C v^2) from 0 to v0."""
    model = BrakingModel(_case(brake_units={"failure_probability_per_demand": 1.0}), "empty", 100.0)
    resistance, mass = model.vehicle.running_resistance, model.vehicle.mass_kg("empty")
    expected, _ = integrate.quad(
        lambda v: mass * v / (resistance.A_N + resistance.B_N_per_mps * v + resistance.C_N_per_mps2 * v * v),
        0.0,
        100.0 / 3.6,
    )
    assert model(np.zeros((1, model.dims)))[0] == pytest.approx(expected, rel=1e-6)


def test_pressure_per_train_moves_every_axle():
    model = BrakingModel(_case(cylinder_pressure={"per": "train"}), "normal", 100.0)
    u = np.zeros((2, model.dims))
    u[1, model.layout.pressure] = 1.0
    commands = model.pressure_commands_bar(u)
    assert commands.shape == (2, 8)
    assert np.allclose(commands[1] - commands[0], model.case.cylinder_pressure.sigma_bar)


@pytest.mark.parametrize(
    ("points", "message"),
    [(np.zeros((2, 3)), "need \\(n, 61\\)"), (np.full((1, 61), np.nan), "not finite"), (np.zeros(61), "need")],
)
def test_bad_points_are_refused(model, points, message):
    with pytest.raises(ValueError, match=message):
        model(points)


def test_bad_case_inputs_are_refused():
    with pytest.raises(cfg.ConfigError, match="unknown load 'heavy'"):
        BrakingModel(cfg.load("safety_cases", CASE), "heavy", 100.0)
    with pytest.raises(ValueError, match="initial speed -5"):
        BrakingModel(cfg.load("safety_cases", CASE), "empty", -5.0)


# ------------------------------------------------------------------------------------------------
# The conventional calculation


def test_equivalent_response_time_of_a_lagged_cylinder():
    """Analytic: with no caliper threshold, the force share is 1 - exp(-(t - t_d) / tau), so
    t_a = t_d - tau ln 0.9, t_95 = t_d - tau ln 0.05 and t_e = (t_a + t_95) / 2."""
    cylinder, caliper = BrakeCylinder(0.2, 0.8), CaliperLaw(12000.0, 0.0)
    t_a, t_95 = 0.2 - 0.8 * math.log(0.9), 0.2 - 0.8 * math.log(0.05)
    assert equivalent_response_time_s(cylinder, caliper, 3.3) == pytest.approx(0.5 * (t_a + t_95), rel=1e-12)
    # A threshold delays the start of the force: later 10 % point, shorter build-up.
    assert time_to_force_share_s(cylinder, CaliperLaw(12000.0, 0.3), 3.3, 0.1) > t_a
    with pytest.raises(ValueError, match="no clamp force"):
        time_to_force_share_s(cylinder, CaliperLaw(12000.0, 0.3), 0.2, 0.1)


def test_conventional_distance_without_resistance_is_v0_te_plus_v0_squared_over_2a(model):
    """Analytic limit: with no running resistance every speed step brakes at F_B / m, and the
    steps sum to v_0^2 / (2 a)."""
    frictionless = model.vehicle.model_copy(
        update={
            "running_resistance": model.vehicle.running_resistance.model_copy(
                update={"A_N": 0.0, "B_N_per_mps": 0.0, "C_N_per_mps2": 0.0}
            )
        }
    )
    bare = BrakingModel(cfg.load("safety_cases", CASE), "empty", 160.0)
    bare.vehicle = frictionless
    stop = conventional_stop(bare)
    v0 = 160.0 / 3.6
    deceleration = stop.brake_force_N / frictionless.mass_kg("empty")
    expected = v0 * stop.equivalent_response_time_s + v0**2 / (2 * deceleration)
    assert stop.braking_distance_m == pytest.approx(expected, rel=1e-12)
    # The brake force: mu_m times every disc's clamp force at the wheel.
    clamp = bare.plant.caliper.clamp_force_N(np.array(bare.nominal_pressure_bar))
    assert stop.brake_force_N == pytest.approx(0.35 * 16 * clamp * 0.28 / 0.46, rel=1e-12)


def test_running_resistance_shortens_the_conventional_distance(model):
    stop = conventional_stop(model)
    v0 = model.initial_speed_kmh / 3.6
    without = v0 * stop.equivalent_response_time_s + v0**2 / (2 * stop.brake_force_N / model.vehicle.mass_kg("empty"))
    assert stop.braking_distance_m < without
    assert np.all(np.diff(stop.speed_edges_kmh) < 0) and stop.speed_edges_kmh[-1] == 0.0


# ------------------------------------------------------------------------------------------------
# Strata by the number of failed units


def test_strata_are_the_binomial_split(model):
    strata = model.strata()
    weights = np.array([weight for weight, _ in strata])
    assert len(strata) == 17 and weights.sum() == pytest.approx(1.0, rel=1e-12)
    assert weights[2] == pytest.approx(math.comb(16, 2) * 1e-3**2 * (1 - 1e-3) ** 14, rel=1e-12)


def test_a_stratum_is_the_raw_model_with_those_units_failed(model):
    """Stratum k fails the k units of the smallest normals; a point whose normals fail exactly
    those units in the raw model gives the same distance."""
    u = np.random.default_rng(11).standard_normal((1, model.dims))
    units = model.layout.units
    u[0, units] = np.abs(u[0, units])  # every unit works in the raw model
    u[0, units.start + 3] = -3.5  # Phi(-3.5) < 1e-3: fails
    u[0, units.start + 12] = -4.0
    strata = model.strata()
    assert model.working_units(u, 2).sum() == 14
    assert np.array_equal(model.working_units(u, 2), model.working_units(u))
    assert strata[2][1](u)[0] == model(u)[0]
    assert strata[0][1](u)[0] < strata[1][1](u)[0] < strata[2][1](u)[0]
    with pytest.raises(ValueError, match="failed_units 17"):
        model.working_units(u, 17)


# ------------------------------------------------------------------------------------------------
# Tails (brakegym.safety.tail)


def _reduced(**inputs):
    """The shipped case with nothing scattered (set-up DS, no tolerances, no unit failures), then
    ``inputs`` changed."""
    quiet = {
        "scatter": {"setup": "ds"},
        "mass": {"relative_sigma": 0.0},
        "cylinder_pressure": {"sigma_bar": 0.0},
        "response_time": {"time_constant_relative_sigma": 0.0},
        "brake_units": {"failure_probability_per_demand": 0.0},
    }
    for name, fields in inputs.items():
        quiet[name] = {**quiet.get(name, {}), **fields}
    return _case(**quiet)


@pytest.mark.parametrize("method", ["subset", "is"])
def test_tail_of_a_lognormal_mass_is_the_stop_of_the_quantile_mass(method):
    """Exact: with only the mass scattering (log-normal, sigma 3 %), the distance grows with the
    mass, so the 1e-6 quantile is the nominal stop of the train of mass m exp(sigma z), z the
    standard normal's 1 - 1e-6 quantile."""
    sigma, p = 0.03, 1e-6
    case = _reduced(mass={"relative_sigma": sigma})
    vehicle = cfg.load("vehicles", "emu_8axle")
    empty = vehicle.load("empty")
    heavy = empty.model_copy(update={"mass_per_disc_kg": empty.mass_per_disc_kg * math.exp(-sigma * special.ndtri(p))})
    exact = train_stops(
        vehicle.model_copy(update={"loads": {"empty": heavy}}),
        [TrainApplication("empty", "emergency", "EP", 60.0, command_time_s=0.0)],
    ).braking_distance_m[0]
    result = braking_distance_tail(case, "empty", 60.0, probability=p, method=method, seed=5)
    low, high = result.estimate.threshold_ci95
    assert low <= exact <= high
    assert high - low < 0.01 * exact
    assert result.estimate.threshold == pytest.approx(exact, rel=2e-3)


@pytest.mark.parametrize("method", ["subset", "is"])
def test_unit_failures_alone_give_the_binomial_tail(method):
    """Exact: with nothing else scattered, the distance with k failed units is one number D_k,
    rising with k, so the probability of exceeding a distance between D_1 and D_2 is the
    probability of at least two failed units, Binomial(16, q)."""
    q = 1e-2
    case = _reduced(brake_units={"failure_probability_per_demand": q})
    model = BrakingModel(case, "empty", 60.0)
    point = np.zeros((1, model.dims))
    one, two = (model.braking_distance_m(point, failed_units=k)[0] for k in (1, 2))
    result = braking_distance_tail(case, "empty", 60.0, distance_m=0.5 * (one + two), method=method, seed=2)
    low, high = result.estimate.probability_ci95
    assert low <= stats.binom.sf(1, 16, q) <= high
    assert result.estimate.probability == pytest.approx(stats.binom.sf(1, 16, q), rel=0.02)


def test_brute_force_agrees_with_subset_and_importance_sampling():
    """The reference: brute force on the whole model (each unit failing with its probability)
    and the stratified estimators on the shipped case, at 1e-2 from 60 km/h; their 95 % intervals
    overlap."""
    case = cfg.load("safety_cases", CASE)
    results = {
        method: braking_distance_tail(case, "empty", 60.0, probability=1e-2, method=method, seed=1).estimate
        for method in ("brute", "subset", "is")
    }
    assert results["brute"].model_evaluations == 10_000
    for method in ("subset", "is"):
        low, high = results[method].threshold_ci95
        brute_low, brute_high = results["brute"].threshold_ci95
        assert max(low, brute_low) <= min(high, brute_high), (method, results[method].threshold_ci95)


def _estimate_numbers(estimate) -> tuple:
    return (
        estimate.threshold,
        estimate.threshold_ci95,
        estimate.probability,
        estimate.probability_ci95,
        estimate.model_evaluations,
    )


@pytest.mark.parametrize("method", ["brute", "is"])
def test_tail_is_the_same_bit_for_bit_on_any_executor(method):
    """Worker processes and a local Dask cluster of two workers, in tasks of 37 stops, give the
    estimate of this process's run bit for bit."""
    case = cfg.load("safety_cases", CASE)
    settings = {"samples": 2000} if method == "brute" else {"n_per_level": 300}

    def tail(executor=None):
        return braking_distance_tail(
            case, "empty", 60.0, probability=2e-2, method=method, seed=3, executor=executor, chunk_stops=37, **settings
        ).estimate

    reference = _estimate_numbers(tail())
    with LocalExecutor(2) as local:
        assert _estimate_numbers(tail(local)) == reference
    with DaskExecutor(workers=2) as dask:
        assert _estimate_numbers(tail(dask)) == reference


def test_tail_input_errors():
    case = cfg.load("safety_cases", CASE)
    with pytest.raises(ValueError, match="exactly one"):
        braking_distance_tail(case, "empty", 60.0, probability=1e-3, distance_m=300.0)
    with pytest.raises(ValueError, match="strictly between 0 and 1"):
        braking_distance_tail(case, "empty", 60.0, probability=1.0)
    with pytest.raises(ValueError, match="method 'mc'"):
        braking_distance_tail(case, "empty", 60.0, probability=1e-3, method="mc")
    with pytest.raises(ValueError, match="about 1.0e\\+11 stops"):
        braking_distance_tail(case, "empty", 60.0, probability=1e-9, method="brute")


# ------------------------------------------------------------------------------------------------
# Speed bands and Kdry (brakegym.safety.etcs)


def test_band_decelerations_cover_the_braking_distance(model):
    """Invariant: the bands' distances, (V_high^2 - V_low^2) / (2 a), plus the distance to the
    build-up time, add up to the braking distance."""
    u = np.random.default_rng(4).standard_normal((3, model.dims))
    edges, build_up = (0.0, 40.0, 80.0, 120.0, 160.0), 1.5
    decelerations = model.band_decelerations_mps2(u, edges, build_up)
    crossing = SpeedCrossings(3, np.array([]), build_up)
    distance = model.stops(u, observers=[crossing]).braking_distance_m
    speeds = np.array(edges) / 3.6
    top = np.vstack([speeds[1:-1, None].repeat(3, axis=1), crossing.speed_at_time_mps[None]])
    bands = (top**2 - speeds[:-1, None] ** 2) / (2 * decelerations.T)
    np.testing.assert_allclose(crossing.position_at_time_m + bands.sum(axis=0), distance, rtol=1e-12)


def test_band_decelerations_of_a_train_without_brakes_are_its_running_resistance():
    """Analytic: with every unit failed, m dv/dt = -F_R(v), so a band's distance is the integral
    of m v / F_R(v) over its speeds (the top band from the speed at the build-up time)."""
    model = BrakingModel(_case(brake_units={"failure_probability_per_demand": 1.0}), "empty", 100.0)
    resistance, mass = model.vehicle.running_resistance, model.vehicle.mass_kg("empty")
    edges, build_up = (0.0, 30.0, 60.0, 100.0), 1.5
    u = np.zeros((1, model.dims))
    crossing = SpeedCrossings(1, np.array([]), build_up)
    model.stops(u, observers=[crossing])
    decelerations = model.band_decelerations_mps2(u, edges, build_up)[0]
    highs = [30.0 / 3.6, 60.0 / 3.6, crossing.speed_at_time_mps[0]]
    for band, (low, high) in enumerate(zip([0.0, 30.0 / 3.6, 60.0 / 3.6], highs)):
        distance, _ = integrate.quad(
            lambda v: mass * v / (resistance.A_N + resistance.B_N_per_mps * v + resistance.C_N_per_mps2 * v * v),
            low,
            high,
        )
        assert decelerations[band] == pytest.approx((high**2 - low**2) / (2 * distance), rel=1e-4)


def test_band_edges_must_span_the_stop(model):
    with pytest.raises(ValueError, match="need 0 first"):
        model.band_decelerations_mps2(np.zeros((1, model.dims)), (0.0, 80.0, 150.0), 1.5)
    with pytest.raises(ValueError, match="build-up time 30.0 s ends below"):
        model.band_decelerations_mps2(np.zeros((1, model.dims)), (0.0, 150.0, 160.0), 30.0)


def test_conventional_band_decelerations_are_the_step_decelerations(model):
    """With bands on the speed steps' edges, a band of one step brakes at that step's
    deceleration."""
    stop = conventional_stop(model)
    edges = stop.speed_edges_kmh[::-1]  # rising, 5 km/h apart
    np.testing.assert_allclose(stop.band_decelerations_mps2(edges), stop.decelerations_mps2[::-1], rtol=1e-12)


def _slow_train(case, maximum_speed_kmh=60.0, edges=(20.0, 40.0)):
    """``case`` with its ETCS model at a lower maximum speed: shorter stops for tests."""
    etcs = case.etcs.model_copy(update={"maximum_speed_kmh": maximum_speed_kmh, "speed_band_edges_kmh": list(edges)})
    return case.model_copy(update={"etcs": etcs})


def test_kdry_of_a_lognormal_mass_is_the_deceleration_of_the_quantile_mass():
    """Exact: with only the mass scattering, every band's deceleration falls as the mass grows,
    so Kdry at M_NVEBCL n is the deceleration of the train of mass m exp(sigma z_n) over the
    nominal, z_n the standard normal's EBCL quantile."""
    sigma = 0.03
    case = _slow_train(_reduced(mass={"relative_sigma": sigma}))
    table = kdry_table(case, "empty", method="is", seed=3, levels=(0, 4))
    model = BrakingModel(case, "empty", 60.0)
    nominal, build_up = nominal_band_decelerations(model)
    np.testing.assert_allclose(table.nominal_deceleration_mps2, nominal, rtol=1e-12)
    for column, level in enumerate((0, 4)):
        u = np.zeros((1, model.dims))
        u[0, model.layout.mass] = special.ndtri(confidence(level))
        exact = model.band_decelerations_mps2(u, speed_band_edges_kmh(case), build_up)[0] / nominal
        # Six 95 % intervals miss one of them a quarter of the time: each estimate is checked
        # within three of its interval's half-widths (about six standard errors) instead.
        half_width = 0.5 * (table.kdry_ci95[:, column, 1] - table.kdry_ci95[:, column, 0])
        assert np.all(np.abs(table.kdry[:, column] - exact) <= 3 * half_width), (level, table.kdry[:, column], exact)
        np.testing.assert_allclose(table.kdry[:, column], exact, rtol=2e-3)


def test_confidence_levels_are_subset_026s_national_values():
    """M_NVEBCL 0 is 50 %, n >= 1 is 1 - 10^-n; the labels show every nine."""
    assert confidence(0) == 0.5 and confidence(3) == pytest.approx(0.999, abs=1e-15)
    assert confidence(9) == pytest.approx(1 - 1e-9, abs=1e-16)
    assert [confidence_label(n) for n in (0, 1, 3, 9)] == ["50 %", "90 %", "99.9 %", "99.9999999 %"]
    with pytest.raises(ValueError):
        confidence(10)


def test_kdry_is_the_same_bit_for_bit_on_worker_processes():
    case = _slow_train(cfg.load("safety_cases", CASE))
    here = kdry_table(case, "empty", method="is", seed=2, levels=(0, 2), n_per_level=300)
    with LocalExecutor(2) as local:
        there = kdry_table(case, "empty", method="is", seed=2, levels=(0, 2), n_per_level=300, executor=local)
    assert np.array_equal(here.kdry, there.kdry) and np.array_equal(here.kdry_ci95, there.kdry_ci95)
    assert here.model_evaluations == there.model_evaluations


def test_kdry_falls_with_the_confidence_level_and_the_export_reads_back(tmp_path):
    case = _slow_train(cfg.load("safety_cases", CASE))
    case = case.model_copy(update={"etcs": case.etcs.model_copy(update={"export_confidence_level": 3})})
    table = kdry_table(case, "empty", method="is", seed=1, levels=(0, 1, 3))
    assert np.all(np.diff(table.kdry, axis=1) < 0)  # a higher confidence, a lower safe deceleration
    assert np.all(np.abs(table.kdry[:, 0] - 1.0) < 0.01)  # the median stop brakes as the nominal one
    assert np.all(table.kdry[:, 2] < 1.0) and np.all(table.kdry[:, 2] > 0.5)
    params = export_kdry_table(table, case)
    path = write_etcs_brake_params(tmp_path / "etcs_brake_params.json", params)
    back = read_etcs_brake_params(path)
    assert back["k_dry"]["values"] == pytest.approx(table.kdry[:, 2].tolist(), rel=1e-15)
    assert back["gamma_emergency"]["values"] == pytest.approx(table.nominal_deceleration_mps2.tolist(), rel=1e-15)
    assert back["gamma_emergency"]["boundaries"] == pytest.approx([20 / 3.6, 40 / 3.6], rel=1e-15)
    assert back["t_be"] == table.build_up_time_s and back["k_wet"]["values"] == [0.8, 0.8, 0.8]
    # The service brake decelerates less than the emergency brake (lower cylinder pressure).
    assert all(s < e for s, e in zip(back["gamma_service"]["values"], back["gamma_emergency"]["values"]))


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda p: p.update(k_dri=p.pop("k_dry")), r"missing field\(s\) \['k_dry'\], unknown field\(s\) \['k_dri'\]"),
        (lambda p: p["k_dry"]["values"].pop(), "k_dry: 2 boundaries and 2 values"),
        (lambda p: p["k_wet"]["values"].__setitem__(0, -0.1), "k_wet: values and boundaries must be >= 0"),
        (lambda p: p["gamma_service"].update(boundaries=[5.0, 5.0]), "must be strictly increasing"),
        (lambda p: p.update(t_be="1.5"), "t_be = '1.5': need a number"),
    ],
)
def test_an_export_osrd_would_refuse_is_refused(tmp_path, change, message):
    curve = {"boundaries": [5.0, 10.0], "values": [1.0, 0.9, 0.8]}
    params = {name: {"boundaries": list(curve["boundaries"]), "values": list(curve["values"])} for name in CURVES}
    params.update({name: 1.0 for name in TIMES})
    change(params)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(params))
    with pytest.raises(OsrdFormatError, match=message):
        read_etcs_brake_params(path)
    assert str(path) in str(pytest.raises(OsrdFormatError, read_etcs_brake_params, path).value)
