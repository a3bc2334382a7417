"""Stochastic friction set-ups (spec Section 5), campaigns and their statistics (Section 6)."""

import numpy as np
import pytest
from scipy import stats

from brakegym import config as cfg
from brakegym.applications import TrainApplication
from brakegym.campaigns import dyno_applications, field_applications, field_campaign, train_monte_carlo
from brakegym.execution import LocalExecutor
from brakegym.physics import draw_friction, draw_running_resistance
from brakegym.plants import friction_for_samples, scatter_partition, stochastic_friction, train_scatter
from brakegym.statistics import envelope, sample_statistics

N = 4000


@pytest.fixture(scope="module")
def material():
    return cfg.load("materials", "ehret2022")


def _rng_draw(material, setup_name, seed=7):
    """A friction draw from a numpy generator (the environments' and synthetic recordings' way)."""
    return draw_friction(
        np.random.default_rng(seed),
        stochastic_friction(material),
        scatter_partition(cfg.load("setups", setup_name)),
        N,
        (8, 2),
    )


def _per_sample_draw(material, setup_name, seed=7):
    """A friction draw from the per-sample streams (the campaigns' way)."""
    partition = scatter_partition(cfg.load("setups", setup_name))
    return friction_for_samples(stochastic_friction(material), partition, (8, 2), seed, np.arange(N))


@pytest.fixture(params=[_rng_draw, _per_sample_draw], ids=["generator", "per-sample"])
def draw_with(request):
    return request.param


def test_ds_is_nominal(material, draw_with):
    draw = draw_with(material, "ds")
    assert np.all(draw.initial_mu == 0.35) and np.all(draw.power_coefficient_per_s == 0.008)


def test_mcs100_independent_discs(material, draw_with):
    draw = draw_with(material, "mcs-100")
    mu = draw.initial_mu.reshape(N, 16)
    assert mu.std(ddof=1) == pytest.approx(0.01, rel=0.03)
    assert draw.power_coefficient_per_s.std(ddof=1) == pytest.approx(0.001, rel=0.03)
    # Independent discs: the correlation between two discs of one train is about zero.
    assert abs(np.corrcoef(mu[:, 0], mu[:, 1])[0, 1]) < 0.06


def test_mcs7525_partition_of_sigma(material, draw_with):
    """Global part 0.75 sigma shared by the discs, individual part 0.25 sigma per disc."""
    mu = draw_with(material, "mcs-75-25").initial_mu.reshape(N, 16)
    within = mu - mu.mean(axis=1, keepdims=True)
    assert within.std(ddof=1) * np.sqrt(16 / 15) == pytest.approx(0.25 * 0.01, rel=0.03)
    assert mu.std(ddof=1) == pytest.approx(np.hypot(0.75, 0.25) * 0.01, rel=0.03)
    expected_correlation = 0.75**2 / (0.75**2 + 0.25**2)
    assert np.corrcoef(mu[:, 0], mu[:, 5])[0, 1] == pytest.approx(expected_correlation, abs=0.03)


def test_shared_draw_is_one_value_per_application(material, draw_with):
    mu = draw_with(material, "shared").initial_mu.reshape(N, 16)
    assert np.all(mu == mu[:, :1])


def test_draws_are_normal(material, draw_with):
    a = draw_with(material, "mcs-100").power_coefficient_per_s.ravel()
    assert stats.normaltest(a).pvalue > 1e-3


def test_per_sample_draws_do_not_depend_on_the_other_samples_drawn():
    """A campaign sample's friction and resistance depend on the seed and its index alone: any
    split of the indices, in any order, gives the same numbers bit for bit."""
    scatter = train_scatter(cfg.load("vehicles", "emu_8axle"), cfg.load("setups", "mcs-75-25"))
    whole, resistance = scatter.draw_for_samples(5, np.arange(1000))
    for part in (np.arange(3), np.arange(999, 499, -7), np.array([17])):
        draw, part_resistance = scatter.draw_for_samples(5, part)
        assert np.array_equal(draw.initial_mu, whole.initial_mu[part])
        assert np.array_equal(draw.power_coefficient_per_s, whole.power_coefficient_per_s[part])
        assert np.array_equal(part_resistance, resistance[part])
    other, other_resistance = scatter.draw_for_samples(6, np.arange(1000))
    assert not np.any(other.initial_mu == whole.initial_mu) and not np.any(other_resistance == resistance)


@pytest.mark.parametrize("per_sample", [False, True], ids=["generator", "per-sample"])
def test_running_resistance_scatter(per_sample):
    vehicle = cfg.load("vehicles", "emu_8axle")
    rng = np.random.default_rng(3)
    resistance = vehicle.running_resistance
    if per_sample:
        scattered = train_scatter(vehicle, cfg.load("setups", "mcs-100")).draw_for_samples(3, np.arange(N))[1]
    else:
        scattered = draw_running_resistance(
            rng, resistance.A_N, resistance.A_sigma_N, scatter_partition(cfg.load("setups", "mcs-100")), N
        )
    assert scattered.mean() == pytest.approx(2500, abs=4 * 1600 / np.sqrt(N))
    assert scattered.std(ddof=1) == pytest.approx(1600, rel=0.04)
    fixed = draw_running_resistance(
        rng, resistance.A_N, resistance.A_sigma_N, scatter_partition(cfg.load("setups", "ds")), 10
    )
    assert np.all(fixed == 2500)


def test_sample_statistics_intervals():
    x = np.random.default_rng(0).normal(10.0, 2.0, size=50)
    st = sample_statistics(x)
    assert st.mean_ci95[0] < st.mean < st.mean_ci95[1]
    assert st.std_ci95[0] < st.std < st.std_ci95[1]
    # Student t with 49 degrees of freedom, by hand.
    half = 2.009575 * x.std(ddof=1) / np.sqrt(50)
    assert st.mean_ci95[1] - st.mean == pytest.approx(half, rel=1e-5)
    with pytest.raises(ValueError, match="at least 2"):
        sample_statistics([1.0])


def test_confidence_interval_coverage():
    """The 95 % intervals cover the true mean and std in about 95 % of samples."""
    rng = np.random.default_rng(1)
    hits_mean = hits_std = 0
    trials = 2000
    for _ in range(trials):
        st = sample_statistics(rng.normal(0.0, 1.0, size=20))
        hits_mean += st.mean_ci95[0] <= 0.0 <= st.mean_ci95[1]
        hits_std += st.std_ci95[0] <= 1.0 <= st.std_ci95[1]
    assert hits_mean / trials == pytest.approx(0.95, abs=0.015)
    assert hits_std / trials == pytest.approx(0.95, abs=0.015)


def test_envelope_counts_only_braking_applications():
    values = np.array([[1.0, 3.0], [2.0, 4.0], [5.0, 9.0]])
    moving = np.array([[True, True], [True, True], [False, True]])
    mean, std, count = envelope(values, moving)
    np.testing.assert_allclose(mean, [2.0, 3.0, 9.0])
    assert count.tolist() == [2, 2, 1]
    assert np.isnan(std[2]) and std[0] == pytest.approx(np.sqrt(2))


def test_campaign_sizes():
    rig = cfg.load("rigs", "dynamometer")
    assert len(dyno_applications(rig)) == 1950
    campaign = cfg.load("campaigns", "field2022")
    apps = field_applications(campaign)
    assert len(apps) == 88
    assert not any(a.load == "max" and a.initial_speed_kmh == 160 for a in apps)


def test_same_seed_same_stops_bit_for_bit_any_executor_and_chunk_size():
    vehicle = cfg.load("vehicles", "emu_8axle")
    apps = [
        TrainApplication(load=load, brake_mode="emergency", actuation=act, initial_speed_kmh=v)
        for load in ("empty", "max")
        for act in ("EP", "PN")
        for v in (100.0, 140.0)
    ] * 150
    setup = cfg.load("setups", "mcs-75-25")
    one, _, _ = train_monte_carlo(vehicle, apps, setup, seed=11)
    two, _, _ = train_monte_carlo(vehicle, apps, setup, seed=11, executor=LocalExecutor(2), chunk_size=250)
    other, _, _ = train_monte_carlo(vehicle, apps, setup, seed=12)
    assert np.array_equal(one.stop_distance_m, two.stop_distance_m)
    assert np.array_equal(one.mu_s, two.mu_s)
    assert not np.array_equal(one.stop_distance_m, other.stop_distance_m)


def test_sixteen_discs_average_independent_scatter():
    """Paper Sec. 6.2 and spec Section 8: without resistance scatter, MCS-100's spread of mu_s,eff
    is about 1/sqrt(16) of the single-disc-equivalent (shared draw); MCS-75/25 keeps about three
    quarters of it (0.75 sigma is shared). Ranges allow the sampling error of 300 stops."""
    vehicle = cfg.load("vehicles", "emu_8axle")
    app = TrainApplication(load="empty", brake_mode="emergency", actuation="EP", initial_speed_kmh=120.0)
    rel = {}
    for name in ("shared", "mcs-100", "mcs-75-25"):
        setup = cfg.load("setups", name).model_copy(update={"resistance_scatter": False})
        summary, _, _ = train_monte_carlo(vehicle, [app] * 300, setup, seed=5)
        rel[name] = summary.mu_s_eff.std(ddof=1) / summary.mu_s_eff.mean()
    assert 3.2 < rel["shared"] / rel["mcs-100"] < 5.0
    assert 0.65 < rel["mcs-75-25"] / rel["shared"] < 0.9


def test_field_campaign_table_and_summary():
    campaign = cfg.load("campaigns", "field2022").model_copy(update={"repetitions": 3})
    result = field_campaign(campaign, cfg.load("setups", "mcs-100"), seed=1)
    assert len(result.applications) == 88 * 3
    assert result.applications.stop_time_s.notna().all()
    summary = result.application_summary()
    assert len(summary) == 88
    # Emergency stops are shorter than service stops from the same speed and load.
    table = result.applications
    for v0 in (100, 140):
        emergency = table[(table.brake_mode == "emergency") & (table.v0_kmh == v0)].braking_distance_m.mean()
        service = table[(table.brake_mode == "service") & (table.v0_kmh == v0)].braking_distance_m.mean()
        assert emergency < service
