"""Validated environment configs (HighwayEnv style: defaults from YAML, merged with the user's).

Each environment has a default config in ``configs/environments/<name>.yaml`` (found on the config
search path, :mod:`brakegym.config.library`); the ``config`` argument of ``gymnasium.make`` (a dict,
or the path of a YAML file) is merged into it key by key (nested mappings are merged, everything
else replaced) and the result validated by the task's config model, a :class:`BrakeEnvConfig`.
Errors name the file or argument, the field and the value, like every other brakegym config.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import Field, model_validator

from .. import config as cfg


class SensorNoise(cfg.StrictModel):
    """Standard deviations of zero-mean Gaussian noise added to each measured channel."""

    speed_mps: float = Field(ge=0)
    decel_mps2: float = Field(ge=0)
    pressure_bar: float = Field(ge=0)
    temperature_C: float = Field(ge=0)
    distance_m: float = Field(ge=0)


class Range(cfg.StrictModel):
    """A closed interval drawn uniformly at reset; ``low == high`` fixes the value."""

    low: float
    high: float

    @model_validator(mode="after")
    def _ordered(self) -> Range:
        if self.high < self.low:
            raise ValueError(f"high {self.high} is below low {self.low}")
        return self


class RewardWeights(cfg.StrictModel):
    """Weights of the named reward terms (each term is reported in ``info["reward_terms"]``)."""

    tracking_per_mps2_s: float = Field(ge=0)  # deceleration error, integrated over time
    jerk_per_mps3: float = Field(ge=0)  # |change of deceleration| / control step
    stop_success: float = Field(ge=0)  # terminal bonus for a successful stop
    stop_error_per_m: float = Field(ge=0)  # terminal penalty per metre of stop error
    distance_per_km: float = Field(ge=0)  # per km travelled (EmergencyStop: shorter is better)
    overheat: float = Field(ge=0)  # terminal penalty when a disc exceeds its limit


class WheelRailOption(cfg.StrictModel):
    """Wheel-rail adhesion and wheel-slide protection valves in every train (docs/adhesion.md):
    the rail in one condition throughout (``rail_condition``, a name of
    ``configs/rail_conditions/``) or a line of sections (``line``, a name of ``configs/lines/``),
    exactly one of the two; the WSP valves (``wsp_valves``, a name of ``configs/wsp_valves/``); and
    the wheel-speed sensors' Gaussian noise and resolution (the speed a reading is rounded to);
    whether load moves between the bogies and axles as the trains decelerate
    (``load_transfer``, docs/adhesion.md; off by default); and whether each episode draws its
    own rail (``rail_scatter``: every section's mu_0 times a lognormal factor of mean 1 and the
    condition's ``static_friction_relative_sigma``, as a campaign on a rail draws each stop's;
    off: every episode on the rail as configured)."""

    rail_condition: str | None = None
    line: str | None = None
    wsp_valves: str
    wheel_speed_noise_mps: float = Field(ge=0)
    wheel_speed_resolution_mps: float = Field(ge=0)
    load_transfer: bool = False
    rail_scatter: bool = False

    @model_validator(mode="after")
    def _one_rail(self) -> WheelRailOption:
        if (self.rail_condition is None) == (self.line is None):
            raise ValueError(f"give exactly one of rail_condition ({self.rail_condition!r}) and line ({self.line!r})")
        return self


class BrakeEnvConfig(cfg.StrictModel):
    """What every brakegym environment shares: the train, its brake, sensors and timing."""

    name: str
    description: str = ""
    vehicle: str
    actuation: str  # a pneumatics config: EP | PN
    setup: str  # friction scatter set-up: ds | mcs-100 | mcs-75-25 | shared
    loads: list[str] = Field(min_length=1)  # drawn uniformly at reset
    control_groups: Literal["train", "bogie", "axle"]
    policy_frequency_hz: float = Field(gt=0)
    simulation_frequency_hz: float = Field(gt=0)
    max_episode_time_s: float = Field(gt=0)
    observed_temperatures: Literal["all", "instrumented"]
    instrumented_disc: int = Field(ge=1)  # 1-based, as in the recording format
    sensor_noise: SensorNoise
    initial_speed_kmh: Range
    initial_disc_temperature_C: Range
    carry_over_thermal_state: bool  # next episode starts with the discs as the last one ended
    reward: RewardWeights
    # An effect set (the name of one in configs/effects/ or a YAML path, e.g. what `brakegym
    # diagnose --effects-out` writes): physics the nominal model leaves out, in every train.
    effects: str | None = None
    # Wheel-rail adhesion with WSP valves (the train no longer rolls perfectly); none: the paper's
    # single mass in perfect rolling.
    wheel_rail: WheelRailOption | None = None

    @model_validator(mode="after")
    def _timing(self) -> BrakeEnvConfig:
        substeps = self.simulation_frequency_hz / self.policy_frequency_hz
        if abs(substeps - round(substeps)) > 1e-9 or round(substeps) < 1:
            raise ValueError(
                f"simulation_frequency_hz {self.simulation_frequency_hz} must be a whole multiple of "
                f"policy_frequency_hz {self.policy_frequency_hz}"
            )
        if self.initial_speed_kmh.low <= 0:
            raise ValueError(f"initial_speed_kmh.low = {self.initial_speed_kmh.low} must be positive")
        return self

    @property
    def substeps(self) -> int:
        """Physics steps per control step."""
        return int(round(self.simulation_frequency_hz / self.policy_frequency_hz))

    @property
    def control_step_s(self) -> float:
        return 1.0 / self.policy_frequency_hz

    @property
    def physics_step_s(self) -> float:
        return 1.0 / self.simulation_frequency_hz


def merged(base: dict[str, Any], update: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` with ``update`` merged in key by key: nested mappings merged, everything else
    replaced."""
    result = dict(base)
    for key, value in update.items():
        if isinstance(value, Mapping) and isinstance(result.get(key), dict):
            result[key] = merged(result[key], value)
        else:
            result[key] = value
    return result


def default_config(name: str) -> dict[str, Any]:
    """The default config of environment ``name`` as a plain dict, read from
    ``environments/<name>.yaml`` on the config search path."""
    return cfg.read_yaml(cfg.find("environments", name))


def load_environment_config(
    name: str, model: type[BrakeEnvConfig], user: Mapping[str, Any] | str | Path | None = None
) -> BrakeEnvConfig:
    """Defaults of environment ``name`` merged with ``user`` (a dict or a YAML file), validated as
    ``model``, with the referenced vehicle, pneumatics, set-up and effect set checked to exist."""
    source = f"environments/{name}.yaml"
    data = default_config(name)
    if isinstance(user, (str, Path)):
        path = Path(user)
        try:
            loaded = yaml.safe_load(path.read_text())
        except (OSError, yaml.YAMLError) as exc:
            raise cfg.ConfigError(f"{path}: cannot read environment config: {exc}") from exc
        if not isinstance(loaded, dict):
            raise cfg.ConfigError(f"{path}: expected a mapping of fields, got {type(loaded).__name__}")
        user, source = loaded, f"{path} (over {source})"
    elif user:
        source = f"config argument (over {source})"
    if user:
        data = merged(data, user)
    env_config = cfg.validate(data, model, source)
    vehicle = cfg.load("vehicles", env_config.vehicle)
    cfg.load("pneumatics", env_config.actuation)
    cfg.load("setups", env_config.setup)
    unknown = [load for load in env_config.loads if load not in vehicle.loads]
    if unknown:
        raise cfg.ConfigError(
            f"{source}: field 'loads' = {unknown}: not loads of vehicle {vehicle.name!r} ({sorted(vehicle.loads)})"
        )
    if env_config.effects is not None:
        # Imported here: the effect library builds on the simulator, which a config needs not load.
        from ..effects import load_effects

        try:
            load_effects(env_config.effects)
        except (cfg.ConfigError, ValueError) as exc:
            raise cfg.ConfigError(f"{source}: field 'effects' = {env_config.effects!r}: {exc}") from None
    if env_config.wheel_rail is not None:
        option = env_config.wheel_rail
        if env_config.effects is not None:
            raise cfg.ConfigError(
                f"{source}: field 'effects' = {env_config.effects!r}: effects do not run with 'wheel_rail' "
                "(the adhesion simulator has no hooks)"
            )
        if option.rail_condition is not None:
            cfg.load("rail_conditions", option.rail_condition)
        else:
            cfg.load("lines", option.line)
        cfg.load("wsp_valves", option.wsp_valves)
    if env_config.instrumented_disc > vehicle.n_discs:
        raise cfg.ConfigError(
            f"{source}: field 'instrumented_disc' = {env_config.instrumented_disc}: vehicle "
            f"{vehicle.name!r} has {vehicle.n_discs} discs"
        )
    return env_config
