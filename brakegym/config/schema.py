"""The schema of every config kind: what a YAML file under ``configs/`` may hold.

One pydantic model per kind of file (:class:`FrictionMaterial`, :class:`DiscThermal`,
:class:`Pneumatics`, :class:`Dynamometer`, :class:`Vehicle`, :class:`ScatterSetup`,
:class:`FieldCampaign`, :class:`DynoCampaign`, :class:`EffectSet`) and their parts. Units are part
of every field name. Reading files and finding them on the search path is
:mod:`brakegym.config.library`'s job.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from ..units import ZERO_CELSIUS_K


class ConfigError(ValueError):
    """A configuration file or value is invalid; the message names file, field and value."""


class StrictModel(BaseModel):
    """Base of every config model: unknown keys are refused (a typo in a field name must not fall
    back to a default silently) and a loaded config cannot be changed."""

    model_config = ConfigDict(extra="forbid", frozen=True)


class FrictionScatter(StrictModel):
    """Standard deviations of paper Eq. 13: mu_0 ~ N(mu_0, sigma), a ~ N(a, sigma)."""

    initial_mu_sigma: float = Field(ge=0)
    power_coefficient_sigma_per_s: float = Field(ge=0)


class FrictionMaterial(StrictModel):
    """Pad material: the dynamic coefficient of friction of paper Eq. 4 (symbols in comments)."""

    name: str
    description: str = ""
    power_coefficient_per_s: float = Field(ge=0)  # a
    power_exponent: float = Field(gt=0)  # x
    decay_coefficient_per_s: float = Field(ge=0)  # b
    decay_exponent: float = Field(gt=0)  # y
    temperature_coefficient_per_s: float = Field(ge=0)  # c
    temperature_exponent: float = Field(gt=0)  # z
    clamp_force_coefficient_per_s: float = Field(ge=0)  # d
    clamp_force_exponent: float = Field(gt=0)  # r
    reference_power_W: float = Field(gt=0)
    reference_temperature_K: float = Field(gt=0)
    reference_clamp_force_N: float = Field(gt=0)
    initial_mu: float = Field(gt=0, lt=2)
    mu_min: float = Field(gt=0)
    mu_max: float = Field(gt=0)
    min_sliding_speed_mps: float = Field(ge=0)
    scatter: FrictionScatter

    @model_validator(mode="after")
    def _bounds_ordered(self) -> FrictionMaterial:
        if not self.mu_min < self.mu_max:
            raise ValueError(f"mu_min ({self.mu_min}) must be below mu_max ({self.mu_max})")
        if not self.mu_min <= self.initial_mu <= self.mu_max:
            raise ValueError(
                f"initial_mu ({self.initial_mu}) must lie in [mu_min, mu_max] = [{self.mu_min}, {self.mu_max}]"
            )
        return self


class ConvectionLaw(StrictModel):
    """h(v) = h0 + (h_ref - h0) (v_fric / v_ref)^exponent (paper Eq. 10) over an area."""

    h0_W_per_m2K: float = Field(ge=0)
    h_ref_W_per_m2K: float = Field(ge=0)
    exponent: float = Field(gt=0)
    area_m2: float = Field(gt=0)


class DiscThermal(StrictModel):
    """Two lumped heat capacities per disc (paper Eqs. 5-10, Table 3)."""

    name: str
    description: str = ""
    friction_layer_heat_capacity_J_per_K: float = Field(gt=0)
    disc_body_heat_capacity_J_per_K: float = Field(gt=0)
    conductance_W_per_K: float = Field(gt=0)
    conductance_slope_W_per_K2: float
    conductance_reference_temperature_K: float = Field(gt=0)
    conductance_min_W_per_K: float = Field(gt=0)
    heat_fraction_into_disc: float = Field(gt=0, le=1)
    reference_sliding_speed_mps: float = Field(gt=0)
    surface: ConvectionLaw
    ventilation: ConvectionLaw


class Pneumatics(StrictModel):
    """Brake-cylinder pressure response: a dead time, then a first-order lag (spec Section 4)."""

    name: str
    description: str = ""
    dead_time_s: float = Field(ge=0)
    time_constant_s: float = Field(gt=0)


class WspValves(StrictModel):
    """Wheel-slide protection valves (``configs/wsp_valves/``): one per axle or per bogie, and the
    rates at which they dump and refill the cylinder pressure (docs/adhesion.md), with where the
    numbers come from (a document, or ``ASSUMED: <why>``)."""

    name: str
    description: str = ""
    source: str = Field(min_length=1)
    valve_per: Literal["axle", "bogie"]
    dump_rate_bar_per_s: float = Field(gt=0)
    refill_rate_bar_per_s: float = Field(gt=0)


class LoadCase(StrictModel):
    """One dynamometer load case of paper Table 1."""

    name: str
    initial_speed_kmh: float = Field(gt=0)
    mass_kg: float = Field(gt=0)
    clamp_force_kN: float = Field(gt=0)
    applications_per_specimen: list[int]

    @model_validator(mode="after")
    def _counts_non_negative(self) -> LoadCase:
        for index, count in enumerate(self.applications_per_specimen):
            if count < 0:
                raise ValueError(f"applications_per_specimen[{index}] = {count}: must not be negative")
        return self


class Dynamometer(StrictModel):
    """The dynamometer test rig: one disc unit braking a flywheel (paper Table 1, Eq. 11)."""

    name: str
    description: str = ""
    material: str
    disc: str
    wheel_radius_m: float = Field(gt=0)
    friction_radius_m: float = Field(gt=0)
    clamp_force_time_constant_s: float = Field(gt=0)
    ambient_temperature_C: float = Field(gt=-ZERO_CELSIUS_K)
    initial_disc_temperature_C: float = Field(gt=-ZERO_CELSIUS_K)
    specimens: list[str] = Field(min_length=1)
    load_cases: list[LoadCase] = Field(min_length=1)

    @model_validator(mode="after")
    def _cases_consistent(self) -> Dynamometer:
        seen: set[str] = set()
        for index, case in enumerate(self.load_cases):
            if case.name in seen:
                raise ValueError(f"load_cases[{index}].name = {case.name!r} appears twice")
            seen.add(case.name)
            if len(case.applications_per_specimen) != len(self.specimens):
                raise ValueError(
                    f"load_cases[{index}] ({case.name}): applications_per_specimen has "
                    f"{len(case.applications_per_specimen)} entries, but there are "
                    f"{len(self.specimens)} specimens"
                )
        return self

    def load_case(self, name: str) -> LoadCase:
        for case in self.load_cases:
            if case.name == name:
                return case
        known = ", ".join(c.name for c in self.load_cases)
        raise ConfigError(f"unknown load case {name!r} of rig {self.name!r}; known: {known}")


class VehicleLoad(StrictModel):
    mass_per_disc_kg: float = Field(gt=0)


class RunningResistance(StrictModel):
    """F_R(v) = A + B v + C v^2 (paper Eq. 14), with the MCS scatter of A."""

    A_N: float
    B_N_per_mps: float
    C_N_per_mps2: float
    A_sigma_N: float = Field(ge=0)


class Caliper(StrictModel):
    """F_C = k_c max(p_c - p_0, 0) per disc unit (spec Section 4)."""

    gain_N_per_bar: float = Field(gt=0)
    threshold_bar: float = Field(ge=0)


class WheelRailContactConfig(StrictModel):
    """The Hertz contact of the vehicle's wheel on the rail (docs/adhesion.md): semi-axes a (rolling
    direction) and b at a reference wheel load, scaled with the cube root of the load; Kalker's
    c_11 for its b / a; the shear modulus of wheel and rail steel. The defaults are the emu_8axle's
    (ASSUMED: Hertz for a 0.46 m wheel on a rail head of 0.3 m crown radius at 75 kN, E = 210 GPa,
    Poisson 0.28; c_11 from Kalker's tables for b / a about 0.75)."""

    semi_axis_a_m: float = Field(default=0.0065, gt=0)
    semi_axis_b_m: float = Field(default=0.0049, gt=0)
    reference_wheel_load_N: float = Field(default=75e3, gt=0)
    kalker_c11: float = Field(default=3.9, gt=0)
    shear_modulus_Pa: float = Field(default=8.0e10, gt=0)


class CarGeometry(StrictModel):
    """What moves load between a vehicle's axles while it brakes (docs/adhesion.md, "Load
    transfer"): each car body's centre-of-gravity height above the rail, the spacing of its two
    bogies' pivots, the bogie wheelbase, a complete bogie's mass (frame and wheelsets) and its
    centre-of-gravity height. Cars have two bogies each."""

    body_cg_height_m: float = Field(gt=0, lt=5)
    bogie_pivot_spacing_m: float = Field(gt=0, lt=40)
    bogie_wheelbase_m: float = Field(gt=0, lt=5)
    bogie_mass_kg: float = Field(ge=0)
    bogie_cg_height_m: float = Field(gt=0, lt=2)

    @model_validator(mode="after")
    def _wheelbase_within_pivots(self) -> CarGeometry:
        if not self.bogie_wheelbase_m < self.bogie_pivot_spacing_m:
            raise ValueError(
                f"bogie_wheelbase_m {self.bogie_wheelbase_m} must be shorter than "
                f"bogie_pivot_spacing_m {self.bogie_pivot_spacing_m}"
            )
        return self


class Wheelsets(StrictModel):
    """What the adhesion option needs of a vehicle's wheelsets (docs/adhesion.md). The default
    inertia is ASSUMED: the spin inertia of the Manchester benchmark wheelset (about 110 kg m^2)
    plus two axle-mounted brake discs. The vehicle's loads are effective masses that include this
    inertia (the body mass is m - n_axles J / r^2 with the option on), so it must stay below them."""

    inertia_kgm2: float = Field(default=130.0, gt=0)
    contact: WheelRailContactConfig = WheelRailContactConfig()
    # Needed only by the load-transfer option of the adhesion model; none: the option is refused.
    car_geometry: CarGeometry | None = None


BrakeMode = Literal["emergency", "service"]


class Vehicle(StrictModel):
    """A train: discs grouped as bogies x axles x discs, single-mass longitudinal dynamics."""

    name: str
    description: str = ""
    material: str
    disc: str
    bogies: int = Field(ge=1)
    axles_per_bogie: int = Field(ge=1)
    discs_per_axle: int = Field(ge=1)
    wheel_radius_m: float = Field(gt=0)
    friction_radius_m: float = Field(gt=0)
    loads: dict[str, VehicleLoad] = Field(min_length=1)
    running_resistance: RunningResistance
    caliper: Caliper
    max_cylinder_pressure_bar: float = Field(gt=0)
    brake_pressures_bar: dict[BrakeMode, dict[str, float]]
    ambient_temperature_C: float = Field(gt=-ZERO_CELSIUS_K)
    initial_disc_temperature_C: float = Field(gt=-ZERO_CELSIUS_K)
    wheelsets: Wheelsets = Wheelsets()

    @model_validator(mode="after")
    def _cars_of_two_bogies(self) -> Vehicle:
        if self.wheelsets.car_geometry is not None and self.bogies % 2:
            raise ValueError(
                f"wheelsets.car_geometry: {self.bogies} bogies; cars of two bogies each need an even "
                "number (articulated trains are not modelled)"
            )
        return self

    @model_validator(mode="after")
    def _pressures_consistent(self) -> Vehicle:
        for mode, by_load in self.brake_pressures_bar.items():
            for load, pressure in by_load.items():
                where = f"brake_pressures_bar.{mode}.{load}"
                if load not in self.loads:
                    raise ValueError(f"{where}: unknown load {load!r}; loads are {sorted(self.loads)}")
                if not 0 <= pressure <= self.max_cylinder_pressure_bar:
                    raise ValueError(
                        f"{where} = {pressure}: must lie in 0..max_cylinder_pressure_bar "
                        f"({self.max_cylinder_pressure_bar})"
                    )
        rotating_mass_kg = self.n_axles * self.wheelsets.inertia_kgm2 / self.wheel_radius_m**2
        for load, values in self.loads.items():
            if not rotating_mass_kg < self.n_discs * values.mass_per_disc_kg:
                raise ValueError(
                    f"wheelsets.inertia_kgm2 = {self.wheelsets.inertia_kgm2}: the wheelsets' equivalent mass "
                    f"{rotating_mass_kg:.0f} kg must be below the train mass of load {load!r}"
                )
        return self

    @property
    def n_axles(self) -> int:
        return self.bogies * self.axles_per_bogie

    @property
    def n_discs(self) -> int:
        return self.n_axles * self.discs_per_axle

    def mass_kg(self, load: str) -> float:
        return self.n_discs * self.load(load).mass_per_disc_kg

    def load(self, name: str) -> VehicleLoad:
        if name not in self.loads:
            raise ConfigError(f"unknown load {name!r} of vehicle {self.name!r}; known: {sorted(self.loads)}")
        return self.loads[name]

    def brake_pressure_bar(self, mode: str, load: str) -> float:
        if mode not in self.brake_pressures_bar:
            raise ConfigError(
                f"unknown brake mode {mode!r} of vehicle {self.name!r}; known: {sorted(self.brake_pressures_bar)}"
            )
        by_load = self.brake_pressures_bar[mode]  # type: ignore[index]
        if load not in by_load:
            raise ConfigError(f"vehicle {self.name!r} has no {mode} pressure for load {load!r}")
        return by_load[load]


class ScatterSetup(StrictModel):
    """A Monte-Carlo set-up (spec Section 5): fractions of each sigma drawn globally per
    application and individually per disc, and whether running resistance scatters."""

    name: str
    description: str = ""
    global_fraction: float = Field(ge=0)
    individual_fraction: float = Field(ge=0)
    resistance_scatter: bool


class FieldCampaign(StrictModel):
    """Field campaign: a factorial of applications minus exclusions, repeated per set-up."""

    name: str
    description: str = ""
    vehicle: str
    repetitions: int = Field(ge=1)
    command_time_s: float = Field(ge=0)
    factors: dict[str, list[Any]]
    exclude: list[dict[str, Any]] = []

    @model_validator(mode="after")
    def _factors_known(self) -> FieldCampaign:
        required = {"brake_mode", "load", "pad_set", "actuation", "initial_speed_kmh"}
        missing = required - set(self.factors)
        if missing:
            raise ValueError(f"factors: missing {sorted(missing)}")
        unknown = set(self.factors) - required
        if unknown:
            raise ValueError(f"factors: unknown {sorted(unknown)}; allowed {sorted(required)}")
        for index, rule in enumerate(self.exclude):
            for key in rule:
                if key not in required:
                    raise ValueError(f"exclude[{index}]: unknown factor {key!r}")
        return self


class DynoCampaign(StrictModel):
    name: str
    description: str = ""
    rig: str


class StochasticInput(StrictModel):
    """One stochastic input of a safety case, with where its size comes from: a document and its
    clause, or ``ASSUMED: <why>`` where no source gives it."""

    source: str = Field(min_length=1)


class ScatterSetupInput(StochasticInput):
    """The scatter of paper Eq. 13 and spec Section 5 as a set-up of ``configs/setups/`` has it:
    its split of the friction's sigmas into a global and an individual part, and whether the
    running resistance's A scatters."""

    setup: str


class MassTolerance(StochasticInput):
    """The train's mass within its tolerance: m exp(sigma u), u standard normal (log-normal, so
    that the mass stays positive however far the tail)."""

    relative_sigma: float = Field(ge=0, le=0.5)


class PressureTolerance(StochasticInput):
    """The brake-cylinder pressure within its tolerance: p + sigma u per train or per axle, at most
    the vehicle's ``max_cylinder_pressure_bar`` (the relief valve's limit) and at least 0."""

    sigma_bar: float = Field(ge=0)
    per: Literal["train", "axle"]


class ResponseTimeScatter(StochasticInput):
    """The pneumatic response: the cylinder's time constant tau exp(sigma u) per train. The dead
    time stays fixed: it must be a whole number of integration steps."""

    time_constant_relative_sigma: float = Field(ge=0, le=0.5)


class BrakeUnitAvailability(StochasticInput):
    """Each disc unit fails on a demand with this probability, independently of the others (a
    failed unit gives no force and no heat)."""

    failure_probability_per_demand: float = Field(ge=0, le=1)


class ConventionalCalculation(StochasticInput):
    """The conventional braking-distance calculation beside the dynamic model: a constant mean
    pad friction coefficient, full brake force from an equivalent response time, the distance
    summed over speed steps (:mod:`brakegym.safety.conventional`)."""

    mean_pad_friction: float = Field(gt=0, lt=1)
    speed_step_kmh: float = Field(gt=0, le=50)


class EtcsAssumptions(StochasticInput):
    """Train data an ETCS braking-curve export needs that the braking model does not give."""

    wet_rail_factor: float = Field(gt=0, le=1)  # Kwet_rst
    gradient_correction_uphill: float = Field(ge=0, le=10)  # Kn+, m/s^2 per unit gradient
    gradient_correction_downhill: float = Field(ge=0, le=10)  # Kn-
    traction_cut_off_time_s: float = Field(ge=0)


class EtcsBrakeModel(StrictModel):
    """The train's ETCS emergency brake model: the speed bands of A_brake_emergency and Kdry_rst,
    and the confidence level M_NVEBCL of an export (0: 50 %, n >= 1: 1 - 10^-n)."""

    maximum_speed_kmh: float = Field(gt=0)
    speed_band_edges_kmh: list[float]  # between 0 and the maximum speed, rising
    export_confidence_level: int = Field(ge=0, le=9)
    not_modelled: EtcsAssumptions

    @model_validator(mode="after")
    def _edges_inside(self) -> EtcsBrakeModel:
        edges = [0.0, *self.speed_band_edges_kmh, self.maximum_speed_kmh]
        if any(high <= low for low, high in zip(edges, edges[1:])):
            raise ValueError(
                f"speed_band_edges_kmh {self.speed_band_edges_kmh}: need rising values strictly between 0 and "
                f"maximum_speed_kmh {self.maximum_speed_kmh}"
            )
        return self


class SafetyCase(StrictModel):
    """The stochastic inputs of one train's emergency braking, for braking-distance tails and the
    ETCS correction factors (``configs/safety_cases/``)."""

    name: str
    description: str = ""
    vehicle: str
    brake_mode: BrakeMode = "emergency"
    actuation: str
    scatter: ScatterSetupInput
    mass: MassTolerance
    cylinder_pressure: PressureTolerance
    response_time: ResponseTimeScatter
    brake_units: BrakeUnitAvailability
    conventional: ConventionalCalculation
    etcs: EtcsBrakeModel


class EffectConfig(StrictModel):
    """One effect of :mod:`brakegym.effects` switched on, with every parameter given. The schema
    checks the form; the effect library checks the id, the parameter names and their bounds when
    the set is loaded (:func:`brakegym.effects.load_effects`)."""

    id: str
    parameters: dict[str, float]


class EffectSet(StrictModel):
    """A set of effects that modify the nominal model (``configs/effects/``): usable in the
    simulator through :func:`brakegym.effects.load_effects` and
    :func:`brakegym.effects.apply_effects` (or ``replay_batch(recordings, effects)``), and in the
    environments through their ``effects`` config field
    (``gymnasium.make(id, config={"effects": name_or_path})``), where they are applied afresh to
    each train's episode."""

    name: str
    description: str = ""
    effects: list[EffectConfig]

    @model_validator(mode="after")
    def _each_effect_once(self) -> EffectSet:
        ids = [effect.id for effect in self.effects]
        repeated = sorted({i for i in ids if ids.count(i) > 1})
        if repeated:
            raise ValueError(f"effects: {repeated} appear more than once")
        return self


class RailCondition(StrictModel):
    """A condition of the rail (``configs/rail_conditions/``): the parameters of Polach's
    creep-force law (docs/adhesion.md; O. Polach, Wear 258 (2005) 992-1000), the peak adhesion the
    condition stands for, its scatter, how the axles of a train condition it (each axle closes the
    share ``conditioning_per_axle`` of the gap to ``cleaned_friction_ratio`` times mu_0, so that
    following axles brake on more; the defaults: no conditioning), and where the numbers come from
    (a document, or ``ASSUMED: <why>``)."""

    name: str
    description: str = ""
    source: str = Field(min_length=1)
    static_friction: float = Field(gt=0, le=1)  # mu_0
    friction_ratio_at_infinity: float = Field(gt=0, le=1)  # A = mu_inf / mu_0
    friction_decay_s_per_m: float = Field(ge=0)  # B
    adhesion_reduction: float = Field(gt=0, le=1)  # k_A
    slip_reduction: float = Field(gt=0, le=1)  # k_S
    peak_adhesion: float = Field(gt=0, le=1)  # at the emu_8axle's contact, 30 m/s (a test checks it)
    static_friction_relative_sigma: float = Field(ge=0, lt=0.5)  # scatter of mu_0 per application
    cleaned_friction_ratio: float = Field(default=1.0, ge=1, le=20)  # mu_0 of the cleaned rail over mu_0
    conditioning_per_axle: float = Field(default=0.0, ge=0, lt=1)  # share of the gap each axle closes


class LineSection(StrictModel):
    """A stretch of track from ``start_m`` to the next section's start, on a rail in
    ``rail_condition`` (a name of ``configs/rail_conditions/``)."""

    start_m: float = Field(ge=0)
    rail_condition: str = Field(min_length=1)


class Line(StrictModel):
    """A line made of sections with different rail conditions (``configs/lines/``), e.g. a
    low-adhesion patch from x1 to x2 of a WSP test. Positions count from where the train starts."""

    name: str
    description: str = ""
    source: str = Field(min_length=1)
    sections: list[LineSection] = Field(min_length=1)

    @model_validator(mode="after")
    def _sections_ordered(self) -> Line:
        if self.sections[0].start_m != 0:
            raise ValueError(f"sections[0].start_m = {self.sections[0].start_m}: the first section must start at 0")
        for index in range(1, len(self.sections)):
            before, start = self.sections[index - 1].start_m, self.sections[index].start_m
            if not start > before:
                raise ValueError(
                    f"sections[{index}].start_m = {start}: must lie beyond the section before it ({before})"
                )
        return self
