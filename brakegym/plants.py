"""Configs made into models: the one place where a config file becomes physics.

The physics (:mod:`brakegym.physics`) and the simulator (:mod:`brakegym.simulator`) know nothing of
config files; everything that reads a material, disc, vehicle, rig, pneumatics or scatter set-up
and builds the laws, plants and random draws from it is here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import config as cfg
from .physics import (
    BrakeCylinder,
    CaliperLaw,
    CooledSurface,
    DiscThermalModel,
    FrictionDraw,
    FrictionLaw,
    LoadTransfer,
    PolachLaw,
    RailConditioning,
    RailSections,
    RunningResistanceLaw,
    ScatterPartition,
    StochasticFriction,
    WheelRailContact,
    WheelSlideProtectionValve,
    draw_friction,
    draw_running_resistance,
    friction_from_normals,
    running_resistance_from_normals,
    static_friction_factor,
)
from .simulator import Plant
from .simulator.wheelsets import WheelRailAdhesion


def friction_law(material: cfg.FrictionMaterial) -> FrictionLaw:
    """Paper Eq. 4 with the material's parameters."""
    return FrictionLaw(
        power_coefficient_per_s=material.power_coefficient_per_s,
        power_exponent=material.power_exponent,
        decay_coefficient_per_s=material.decay_coefficient_per_s,
        decay_exponent=material.decay_exponent,
        temperature_coefficient_per_s=material.temperature_coefficient_per_s,
        temperature_exponent=material.temperature_exponent,
        clamp_force_coefficient_per_s=material.clamp_force_coefficient_per_s,
        clamp_force_exponent=material.clamp_force_exponent,
        reference_power_W=material.reference_power_W,
        reference_temperature_K=material.reference_temperature_K,
        reference_clamp_force_N=material.reference_clamp_force_N,
        mu_min=material.mu_min,
        mu_max=material.mu_max,
        min_sliding_speed_mps=material.min_sliding_speed_mps,
    )


def _cooled_surface(law: cfg.ConvectionLaw) -> CooledSurface:
    return CooledSurface(
        h0_W_per_m2K=law.h0_W_per_m2K, h_ref_W_per_m2K=law.h_ref_W_per_m2K, exponent=law.exponent, area_m2=law.area_m2
    )


def thermal_model(disc: cfg.DiscThermal) -> DiscThermalModel:
    """Paper Eqs. 5-10 with the disc's parameters."""
    return DiscThermalModel(
        friction_layer_heat_capacity_J_per_K=disc.friction_layer_heat_capacity_J_per_K,
        disc_body_heat_capacity_J_per_K=disc.disc_body_heat_capacity_J_per_K,
        conductance_W_per_K=disc.conductance_W_per_K,
        conductance_slope_W_per_K2=disc.conductance_slope_W_per_K2,
        conductance_reference_temperature_K=disc.conductance_reference_temperature_K,
        conductance_min_W_per_K=disc.conductance_min_W_per_K,
        heat_fraction_into_disc=disc.heat_fraction_into_disc,
        reference_sliding_speed_mps=disc.reference_sliding_speed_mps,
        surface=_cooled_surface(disc.surface),
        ventilation=_cooled_surface(disc.ventilation),
    )


def running_resistance_law(resistance: cfg.RunningResistance) -> RunningResistanceLaw:
    """Paper Eq. 14 with the vehicle's nominal coefficients."""
    return RunningResistanceLaw(
        A_N=resistance.A_N, B_N_per_mps=resistance.B_N_per_mps, C_N_per_mps2=resistance.C_N_per_mps2
    )


def caliper_law(caliper: cfg.Caliper) -> CaliperLaw:
    """Spec Section 4's caliper of the vehicle."""
    return CaliperLaw(gain_N_per_bar=caliper.gain_N_per_bar, threshold_bar=caliper.threshold_bar)


def brake_cylinder(pneumatics: cfg.Pneumatics) -> BrakeCylinder:
    """Spec Section 4's cylinder response of an actuation (EP, PN)."""
    return BrakeCylinder(dead_time_s=pneumatics.dead_time_s, time_constant_s=pneumatics.time_constant_s)


def wsp_valve(valves: cfg.WspValves) -> WheelSlideProtectionValve:
    """The dump and refill rates of a WSP valve set."""
    return WheelSlideProtectionValve(valves.dump_rate_bar_per_s, valves.refill_rate_bar_per_s)


def valve_of_axle(vehicle: cfg.Vehicle, valves: cfg.WspValves) -> np.ndarray:
    """Which valve each axle of ``vehicle`` hangs on (A,): its own, or its bogie's."""
    axles = np.arange(vehicle.n_axles)
    return axles if valves.valve_per == "axle" else axles // vehicle.axles_per_bogie


def polach_law(condition: cfg.RailCondition) -> PolachLaw:
    """Polach's creep-force law of a rail condition (docs/adhesion.md)."""
    return PolachLaw(
        static_friction=condition.static_friction,
        friction_ratio_at_infinity=condition.friction_ratio_at_infinity,
        friction_decay_s_per_m=condition.friction_decay_s_per_m,
        adhesion_reduction=condition.adhesion_reduction,
        slip_reduction=condition.slip_reduction,
    )


def wheel_rail_contact(vehicle: cfg.Vehicle) -> WheelRailContact:
    """The Hertz contact of the vehicle's wheels on the rail (docs/adhesion.md)."""
    contact = vehicle.wheelsets.contact
    return WheelRailContact(
        semi_axis_a_m=contact.semi_axis_a_m,
        semi_axis_b_m=contact.semi_axis_b_m,
        reference_wheel_load_N=contact.reference_wheel_load_N,
        kalker_c11=contact.kalker_c11,
        shear_modulus_Pa=contact.shear_modulus_Pa,
    )


def rail_conditioning(condition: cfg.RailCondition) -> RailConditioning:
    """How the axles of a train condition a rail in ``condition`` (docs/adhesion.md)."""
    return RailConditioning(
        cleaned_friction_ratio=condition.cleaned_friction_ratio, per_axle=condition.conditioning_per_axle
    )


def rail_sections(line: cfg.Line) -> RailSections:
    """The creep-force law of each section of ``line``; an unknown rail condition names the line
    and the section."""
    laws = tuple(polach_law(condition) for condition in rail_conditions_of(line))
    return RailSections(starts_m=tuple(section.start_m for section in line.sections), laws=laws)


def rail_conditions_of(rail: cfg.RailCondition | cfg.Line) -> list[cfg.RailCondition]:
    """The rail conditions of a rail: itself, or each section's of a line (in section order); an
    unknown rail condition names the line and the section."""
    if isinstance(rail, cfg.RailCondition):
        return [rail]
    conditions = []
    for index, section in enumerate(rail.sections):
        try:
            conditions.append(cfg.load("rail_conditions", section.rail_condition))
        except cfg.ConfigError as error:
            raise cfg.ConfigError(f"line {rail.name!r}, sections[{index}].rail_condition: {error}") from None
    return conditions


def rail_static_friction_relative_sigma(rail: cfg.RailCondition | cfg.Line) -> float:
    """The relative scatter of mu_0 per stop of a rail: its condition's, or on a line the largest
    of its sections' (one factor scales every section of a stop's line: the same weather along
    it; the widest scatter is the cautious choice)."""
    return max(condition.static_friction_relative_sigma for condition in rail_conditions_of(rail))


def rail_friction_factor_for_samples(
    rail: cfg.RailCondition | cfg.Line, seed: int, sample_index: np.ndarray
) -> np.ndarray:
    """The factor on the rail's mu_0 of the stops ``sample_index`` of a campaign seeded ``seed``
    (:func:`brakegym.physics.adhesion.static_friction_factor`, lognormal, mean 1), each stop's from
    one normal of its own counter-based stream: the same for a stop whatever the others drawn with
    it, and the friction and running-resistance draws unchanged."""
    normals = _campaign_normals(seed, RAIL_ADHESION_STREAM, sample_index, 1)[:, 0]
    return static_friction_factor(rail_static_friction_relative_sigma(rail), normals)


def load_transfer(vehicle: cfg.Vehicle) -> LoadTransfer:
    """The load transfer between and within the bogies of ``vehicle`` while it brakes
    (docs/adhesion.md, "Load transfer"), from its ``wheelsets.car_geometry``."""
    geometry = vehicle.wheelsets.car_geometry
    if geometry is None:
        raise cfg.ConfigError(
            f"vehicle {vehicle.name!r}, wheelsets.car_geometry: missing; load transfer needs the car "
            "body's centre-of-gravity height, the bogie-pivot spacing and the bogies' wheelbase, mass "
            "and centre-of-gravity height"
        )
    return LoadTransfer(
        body_cg_height_m=geometry.body_cg_height_m,
        bogie_pivot_spacing_m=geometry.bogie_pivot_spacing_m,
        bogie_wheelbase_m=geometry.bogie_wheelbase_m,
        bogie_mass_kg=geometry.bogie_mass_kg,
        bogie_cg_height_m=geometry.bogie_cg_height_m,
        bogies=vehicle.bogies,
        axles_per_bogie=vehicle.axles_per_bogie,
    )


def wheel_rail_adhesion(
    vehicle: cfg.Vehicle, rail: cfg.RailCondition | cfg.Line, with_load_transfer: bool = False
) -> WheelRailAdhesion:
    """The adhesion option of ``vehicle`` on a rail in one condition or on a line of sections
    (docs/adhesion.md); ``with_load_transfer``: each axle's normal load changes with the train's
    deceleration (:func:`load_transfer`), else every wheel carries the static share. The rail's
    conditioning by the axles ahead is its condition's (each section's on a line)."""
    conditioning = tuple(rail_conditioning(condition) for condition in rail_conditions_of(rail))
    return WheelRailAdhesion(
        law=rail_sections(rail) if isinstance(rail, cfg.Line) else polach_law(rail),
        contact=wheel_rail_contact(vehicle),
        wheelset_inertia_kgm2=vehicle.wheelsets.inertia_kgm2,
        load_transfer=load_transfer(vehicle) if with_load_transfer else None,
        # None where no section is conditioned: the kernel's factors are then exactly 1.
        conditioning=conditioning if any(c != RailConditioning() for c in conditioning) else None,
    )


# ------------------------------------------------------------------------------------------------
# Plants


def dynamometer_plant(rig: cfg.Dynamometer) -> Plant:
    """The rig: one disc unit, commanded in clamp force (N), no running resistance."""
    material = cfg.load("materials", rig.material)
    return Plant(
        name=rig.name,
        n_axles=1,
        discs_per_axle=1,
        wheel_radius_m=rig.wheel_radius_m,
        friction_radius_m=rig.friction_radius_m,
        friction=friction_law(material),
        thermal=thermal_model(cfg.load("discs", rig.disc)),
        caliper=CaliperLaw.identity(),
        running_resistance=RunningResistanceLaw.none(),
        max_command=max(case.clamp_force_kN for case in rig.load_cases) * 1e3,
    )


_train_plants: dict[tuple[tuple[str, ...], str], Plant] = {}


def train_plant(vehicle: cfg.Vehicle) -> Plant:
    """The train plant of ``vehicle``, built once per vehicle and search path (fits replay a
    vehicle thousands of times)."""
    key = (tuple(str(folder) for folder in cfg.search_path()), vehicle.model_dump_json())
    if key not in _train_plants:
        _train_plants[key] = Plant(
            name=vehicle.name,
            n_axles=vehicle.n_axles,
            discs_per_axle=vehicle.discs_per_axle,
            wheel_radius_m=vehicle.wheel_radius_m,
            friction_radius_m=vehicle.friction_radius_m,
            friction=friction_law(cfg.load("materials", vehicle.material)),
            thermal=thermal_model(cfg.load("discs", vehicle.disc)),
            caliper=caliper_law(vehicle.caliper),
            running_resistance=running_resistance_law(vehicle.running_resistance),
            max_command=vehicle.max_cylinder_pressure_bar,
        )
    return _train_plants[key]


# ------------------------------------------------------------------------------------------------
# Random draws


def stochastic_friction(material: cfg.FrictionMaterial) -> StochasticFriction:
    """Paper Eq. 13's scatter of the material."""
    return StochasticFriction(
        initial_mu=material.initial_mu,
        initial_mu_sigma=material.scatter.initial_mu_sigma,
        power_coefficient_per_s=material.power_coefficient_per_s,
        power_coefficient_sigma_per_s=material.scatter.power_coefficient_sigma_per_s,
        mu_min=material.mu_min,
        mu_max=material.mu_max,
        material=material.name,
    )


def scatter_partition(setup: cfg.ScatterSetup) -> ScatterPartition:
    """A Monte-Carlo set-up (spec Section 5) as the draws take it."""
    return ScatterPartition(
        global_fraction=setup.global_fraction,
        individual_fraction=setup.individual_fraction,
        resistance_scatter=setup.resistance_scatter,
    )


# The per-sample streams of a campaign: each kind of draw from its own stream derived from the
# campaign's seed (reliability.streams.derived_seed), so that adding a kind of draw leaves the others.
FRICTION_STREAM = 0
RUNNING_RESISTANCE_STREAM = 1
# The rail's adhesion (mu_0 of its creep-force law): of a seeded WSP test (brakegym.wsp_test),
# of each stop of a campaign on a rail (rail_friction_factor_for_samples).
RAIL_ADHESION_STREAM = 2


def _campaign_normals(seed: int, stream: int, sample_index: np.ndarray, dims: int) -> np.ndarray:
    # Imported here: the environments import this module but not the campaign streams, and scipy
    # (which the streams need) would add to every environment's start.
    from .reliability.streams import derived_seed, standard_normals

    return standard_normals(derived_seed(seed, stream), np.asarray(sample_index, dtype=np.int64), dims)


def friction_for_samples(
    friction: StochasticFriction,
    partition: ScatterPartition,
    disc_shape: tuple[int, int],
    seed: int,
    sample_index: np.ndarray,
) -> FrictionDraw:
    """The friction of the applications ``sample_index`` of a campaign seeded ``seed`` (paper
    Eq. 13), each from its own counter-based normals: a sample's draw depends only on the seed and
    its index, so any chunking of a campaign gives the same draws bit for bit.

    Sample ``i`` takes ``2 + 2 n`` normals (``n`` discs) of the friction stream: the global normals
    of mu_0 and a, then mu_0 of every disc, then a of every disc (axle by axle), the layout of
    :func:`~brakegym.physics.scatter.friction_from_normals` and of a safety case's points. All are
    drawn whatever the set-up, so one seed gives the same numbers in every set-up (common random
    numbers)."""
    n_discs = disc_shape[0] * disc_shape[1]
    normals = _campaign_normals(seed, FRICTION_STREAM, sample_index, 2 + 2 * n_discs)
    return friction_from_normals(friction, partition, normals[:, :2], normals[:, 2:].reshape(-1, 2, *disc_shape))


@dataclass(frozen=True)
class TrainScatter:
    """The scatter of a vehicle's stops in a set-up, built once from the configs: every disc's
    friction (paper Eq. 13) and each application's running resistance A."""

    friction: StochasticFriction
    partition: ScatterPartition
    resistance_A_N: float
    resistance_sigma_N: float
    disc_shape: tuple[int, int]

    def draw(self, rng: np.random.Generator, n_applications: int) -> tuple[FrictionDraw, np.ndarray]:
        """The friction draw, then the running-resistance draw, in that order from ``rng`` (the
        order every campaign, environment and synthetic set uses, so that a seed means the same
        draws everywhere)."""
        friction = draw_friction(rng, self.friction, self.partition, n_applications, self.disc_shape)
        resistance = draw_running_resistance(
            rng, self.resistance_A_N, self.resistance_sigma_N, self.partition, n_applications
        )
        return friction, resistance

    def draw_for_samples(self, seed: int, sample_index: np.ndarray) -> tuple[FrictionDraw, np.ndarray]:
        """The friction draw and the running resistance A of the applications ``sample_index``
        of a campaign seeded ``seed``, each sample's from its own counter-based normals
        (:func:`friction_for_samples`; A from one normal of the running-resistance stream): the
        same numbers for a sample whatever the other samples drawn with it. The campaigns draw
        this way; the environments and synthetic recordings use :meth:`draw`."""
        friction = friction_for_samples(self.friction, self.partition, self.disc_shape, seed, sample_index)
        normals = _campaign_normals(seed, RUNNING_RESISTANCE_STREAM, sample_index, 1)[:, 0]
        resistance = running_resistance_from_normals(
            self.resistance_A_N, self.resistance_sigma_N, self.partition, normals
        )
        return friction, resistance


def train_scatter(vehicle: cfg.Vehicle, setup: cfg.ScatterSetup) -> TrainScatter:
    """The scatter of ``vehicle``'s stops in ``setup``."""
    resistance = vehicle.running_resistance
    return TrainScatter(
        friction=stochastic_friction(cfg.load("materials", vehicle.material)),
        partition=scatter_partition(setup),
        resistance_A_N=resistance.A_N,
        resistance_sigma_N=resistance.A_sigma_N,
        disc_shape=(vehicle.n_axles, vehicle.discs_per_axle),
    )


def nominal_draw(material: cfg.FrictionMaterial, n_applications: int, disc_shape: tuple[int, int]) -> FrictionDraw:
    """The DS case: every disc at the nominal mu_0 and a."""
    shape = (n_applications, *disc_shape)
    return FrictionDraw(
        initial_mu=np.full(shape, material.initial_mu),
        power_coefficient_per_s=np.full(shape, material.power_coefficient_per_s),
    )
