"""Validated configuration files.

Every physical constant of the simulator lives in a YAML file under ``configs/``, one folder per
kind (``materials``, ``discs``, ``pneumatics``, ``rigs``, ``vehicles``, ``setups``, ``campaigns``),
one file per named item. A user adds a vehicle or a pad material by adding a file; the file's
``name`` must equal its stem. Units are part of every field name.

Loading validates with pydantic; any problem raises :class:`ConfigError` naming the file, the field
and the offending value.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Literal, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

CONFIG_DIR_ENV = "BRAKEGYM_CONFIG_DIR"

class ConfigError(ValueError):
    """A configuration file or value is invalid; the message names file, field and value."""


class _Strict(BaseModel):
    # Unknown keys are refused: a typo in a field name must not fall back to a default silently.
    model_config = ConfigDict(extra="forbid", frozen=True)


class FrictionScatter(_Strict):
    """Standard deviations of paper Eq. 13: mu_0 ~ N(mu_0, sigma), a ~ N(a, sigma)."""

    initial_mu_sigma: float = Field(ge=0)
    power_coefficient_sigma_per_s: float = Field(ge=0)


class FrictionMaterial(_Strict):
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
    def _bounds_ordered(self) -> "FrictionMaterial":
        if not self.mu_min < self.mu_max:
            raise ValueError(f"mu_min ({self.mu_min}) must be below mu_max ({self.mu_max})")
        if not self.mu_min <= self.initial_mu <= self.mu_max:
            raise ValueError(
                f"initial_mu ({self.initial_mu}) must lie in [mu_min, mu_max] = "
                f"[{self.mu_min}, {self.mu_max}]"
            )
        return self


class ConvectionLaw(_Strict):
    """h(v) = h0 + (h_ref - h0) (v_fric / v_ref)^exponent (paper Eq. 10) over an area."""

    h0_W_per_m2K: float = Field(ge=0)
    h_ref_W_per_m2K: float = Field(ge=0)
    exponent: float = Field(gt=0)
    area_m2: float = Field(gt=0)


class DiscThermal(_Strict):
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


class Pneumatics(_Strict):
    """Brake-cylinder pressure response: a dead time, then a first-order lag (spec Section 4)."""

    name: str
    description: str = ""
    dead_time_s: float = Field(ge=0)
    time_constant_s: float = Field(gt=0)


class LoadCase(_Strict):
    """One dynamometer load case of paper Table 1."""

    name: str
    initial_speed_kmh: float = Field(gt=0)
    mass_kg: float = Field(gt=0)
    clamp_force_kN: float = Field(gt=0)
    applications_per_specimen: list[int]

    @model_validator(mode="after")
    def _counts_non_negative(self) -> "LoadCase":
        for index, count in enumerate(self.applications_per_specimen):
            if count < 0:
                raise ValueError(
                    f"applications_per_specimen[{index}] = {count}: must not be negative"
                )
        return self


class Dynamometer(_Strict):
    """The dynamometer test rig: one disc unit braking a flywheel (paper Table 1, Eq. 11)."""

    name: str
    description: str = ""
    material: str
    disc: str
    wheel_radius_m: float = Field(gt=0)
    friction_radius_m: float = Field(gt=0)
    clamp_force_time_constant_s: float = Field(gt=0)
    ambient_temperature_C: float = Field(gt=-273.15)
    initial_disc_temperature_C: float = Field(gt=-273.15)
    specimens: list[str] = Field(min_length=1)
    load_cases: list[LoadCase] = Field(min_length=1)

    @model_validator(mode="after")
    def _cases_consistent(self) -> "Dynamometer":
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


class VehicleLoad(_Strict):
    mass_per_disc_kg: float = Field(gt=0)


class RunningResistance(_Strict):
    """F_R(v) = A + B v + C v^2 (paper Eq. 14), with the MCS scatter of A."""

    A_N: float
    B_N_per_mps: float
    C_N_per_mps2: float
    A_sigma_N: float = Field(ge=0)


class Caliper(_Strict):
    """F_C = k_c max(p_c - p_0, 0) per disc unit (spec Section 4)."""

    gain_N_per_bar: float = Field(gt=0)
    threshold_bar: float = Field(ge=0)


BrakeMode = Literal["emergency", "service"]


class Vehicle(_Strict):
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
    ambient_temperature_C: float = Field(gt=-273.15)
    initial_disc_temperature_C: float = Field(gt=-273.15)

    @model_validator(mode="after")
    def _pressures_consistent(self) -> "Vehicle":
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


class ScatterSetup(_Strict):
    """A Monte-Carlo set-up (spec Section 5): fractions of each sigma drawn globally per
    application and individually per disc, and whether running resistance scatters."""

    name: str
    description: str = ""
    global_fraction: float = Field(ge=0)
    individual_fraction: float = Field(ge=0)
    resistance_scatter: bool


class FieldCampaign(_Strict):
    """Field campaign: a factorial of applications minus exclusions, repeated per set-up."""

    name: str
    description: str = ""
    vehicle: str
    repetitions: int = Field(ge=1)
    command_time_s: float = Field(ge=0)
    factors: dict[str, list[Any]]
    exclude: list[dict[str, Any]] = []

    @model_validator(mode="after")
    def _factors_known(self) -> "FieldCampaign":
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


class DynoCampaign(_Strict):
    name: str
    description: str = ""
    rig: str


class EffectConfig(_Strict):
    """One effect of :mod:`brakegym.recordings.effects` switched on, with every parameter given."""

    id: str
    parameters: dict[str, float]

    @model_validator(mode="after")
    def _known_effect(self) -> "EffectConfig":
        # The library defines the ids, parameter names and bounds; imported here, not at the top,
        # because it builds on the simulator, which builds on this module.
        from .recordings.effects import validate_effect_config

        validate_effect_config(self.id, self.parameters)
        return self


class EffectSet(_Strict):
    """A set of effects that modify the nominal model (``configs/effects/``): usable in the
    simulator through ``brakegym.recordings.effects.load_effects`` and ``apply_effects`` (or
    ``replay_batch(recordings, effects)``), and in the environments through their ``effects``
    config field (``gymnasium.make(id, config={"effects": name_or_path})``), where they are applied
    afresh to each train's episode."""

    name: str
    description: str = ""
    effects: list[EffectConfig]

    @model_validator(mode="after")
    def _each_effect_once(self) -> "EffectSet":
        ids = [effect.id for effect in self.effects]
        repeated = sorted({i for i in ids if ids.count(i) > 1})
        if repeated:
            raise ValueError(f"effects: {repeated} appear more than once")
        return self


KINDS: dict[str, type[BaseModel]] = {
    "materials": FrictionMaterial,
    "discs": DiscThermal,
    "pneumatics": Pneumatics,
    "rigs": Dynamometer,
    "vehicles": Vehicle,
    "setups": ScatterSetup,
    "campaigns": FieldCampaign,
    "effects": EffectSet,
}

M = TypeVar("M", bound=BaseModel)


def config_dir() -> Path:
    """The folder holding the configs: $BRAKEGYM_CONFIG_DIR, else the repository's ``configs/``."""
    override = os.environ.get(CONFIG_DIR_ENV)
    if override:
        path = Path(override)
    else:
        path = Path(__file__).resolve().parent.parent / "configs"
    if not path.is_dir():
        raise ConfigError(
            f"config folder {path} does not exist; set {CONFIG_DIR_ENV} to the brakegym configs/ folder"
        )
    return path


def _describe_validation_error(path: Path, error: ValidationError) -> str:
    lines = [f"{path}: invalid {error.title} config"]
    for item in error.errors():
        field = ".".join(str(part) for part in item["loc"]) or "(top level)"
        value = item.get("input")
        if item["type"] == "missing":
            shown = "(missing)"
        elif isinstance(value, dict):
            shown = "{...}"
        else:
            shown = repr(value)
        lines.append(f"  field '{field}' = {shown}: {item['msg']}")
    return "\n".join(lines)


def load_file(path: str | Path, model: type[M]) -> M:
    """Parse and validate one YAML file as ``model``; errors name the file, field and value."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read config file ({exc.strerror})") from exc
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML: {exc}") from exc
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of fields, got {type(data).__name__}")
    try:
        item = model.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(_describe_validation_error(path, exc)) from None
    name = getattr(item, "name", None)
    if name is not None and name != path.stem:
        raise ConfigError(f"{path}: field 'name' = {name!r} must equal the file's stem {path.stem!r}")
    return item


def available(kind: str) -> list[str]:
    """Names of the configs of one kind (e.g. ``available("vehicles")``)."""
    if kind not in KINDS:
        raise ConfigError(f"unknown config kind {kind!r}; kinds are {sorted(KINDS)}")
    folder = config_dir() / kind
    return sorted(p.stem for p in folder.glob("*.yaml")) if folder.is_dir() else []


def load(kind: str, name: str) -> Any:
    """Load the config ``configs/<kind>/<name>.yaml``; unknown names list the known ones."""
    if kind not in KINDS:
        raise ConfigError(f"unknown config kind {kind!r}; kinds are {sorted(KINDS)}")
    path = config_dir() / kind / f"{name}.yaml"
    if not path.is_file():
        known = ", ".join(available(kind)) or "none"
        raise ConfigError(f"unknown {kind[:-1]} {name!r}: no file {path}; known: {known}")
    if kind == "campaigns":
        data = yaml.safe_load(path.read_text()) or {}
        model: type[BaseModel] = DynoCampaign if "rig" in data else FieldCampaign
        return load_file(path, model)
    return load_file(path, KINDS[kind])


def kmh_to_mps(speed_kmh: float) -> float:
    return speed_kmh / 3.6


def celsius_to_kelvin(temperature_C: float) -> float:
    return temperature_C + 273.15
