"""Validated environment configs (HighwayEnv style: defaults from YAML, merged with the user's).

Each environment has a default config in ``configs/environments/<name>.yaml``; the ``config``
argument of ``gymnasium.make`` (a dict, or the path of a YAML file) is merged into it key by key
(nested mappings are merged, everything else replaced) and the result validated. Errors name the
file or argument, the field and the value, like every other brakegym config.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal, Mapping

import yaml
from pydantic import Field, ValidationError, model_validator

from .. import config as cfg


class SensorNoise(cfg._Strict):
    """Standard deviations of zero-mean Gaussian noise added to each measured channel."""

    speed_mps: float = Field(ge=0)
    decel_mps2: float = Field(ge=0)
    pressure_bar: float = Field(ge=0)
    temperature_C: float = Field(ge=0)
    distance_m: float = Field(ge=0)


class Range(cfg._Strict):
    """A closed interval drawn uniformly at reset; ``low == high`` fixes the value."""

    low: float
    high: float

    @model_validator(mode="after")
    def _ordered(self) -> "Range":
        if self.high < self.low:
            raise ValueError(f"high {self.high} is below low {self.low}")
        return self


class RewardWeights(cfg._Strict):
    """Weights of the named reward terms (each term is reported in ``info["reward_terms"]``)."""

    tracking_per_mps2_s: float = Field(ge=0)  # deceleration error, integrated over time
    jerk_per_mps3: float = Field(ge=0)  # |change of deceleration| / control step
    stop_success: float = Field(ge=0)  # terminal bonus for a successful stop
    stop_error_per_m: float = Field(ge=0)  # terminal penalty per metre of stop error
    distance_per_km: float = Field(ge=0)  # per km travelled (EmergencyStop: shorter is better)
    overheat: float = Field(ge=0)  # terminal penalty when a disc exceeds its limit


class BrakeEnvConfig(cfg._Strict):
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

    @model_validator(mode="after")
    def _timing(self) -> "BrakeEnvConfig":
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


class StationStopConfig(BrakeEnvConfig):
    """The train approaches a platform and stops with its reference point on the mark."""

    # The mark is placed where braking at this constant deceleration, after the brake's
    # response time, stops the train: it sets how hard the task is.
    required_deceleration_mps2: Range
    response_allowance_s: float = Field(ge=0)
    success_tolerance_m: float = Field(gt=0)
    overrun_limit_m: float = Field(gt=0)


class DecelTrackingConfig(BrakeEnvConfig):
    """Follow a demanded deceleration: service-brake steps as a brake control unit receives them."""

    demand_levels_mps2: list[float] = Field(min_length=1)
    first_demand_time_s: float = Field(ge=0)
    demand_hold_s: Range  # how long each level is held

    @model_validator(mode="after")
    def _levels_positive(self) -> "DecelTrackingConfig":
        bad = [level for level in self.demand_levels_mps2 if not level > 0]
        if bad:
            raise ValueError(f"demand_levels_mps2 must be positive, got {bad}")
        if self.demand_hold_s.low <= 0:
            raise ValueError(f"demand_hold_s.low = {self.demand_hold_s.low} must be positive")
        return self


class EmergencyStopConfig(BrakeEnvConfig):
    """Stop as short as possible without any disc exceeding its temperature limit."""

    disc_temperature_limit_C: float


CONFIG_MODELS: dict[str, type[BrakeEnvConfig]] = {
    "station_stop": StationStopConfig,
    "decel_tracking": DecelTrackingConfig,
    "emergency_stop": EmergencyStopConfig,
}


def _merged(base: dict[str, Any], update: Mapping[str, Any]) -> dict[str, Any]:
    merged = dict(base)
    for key, value in update.items():
        if isinstance(value, Mapping) and isinstance(merged.get(key), dict):
            merged[key] = _merged(merged[key], value)
        else:
            merged[key] = value
    return merged


def default_config(name: str) -> dict[str, Any]:
    """The default config of environment ``name`` as a plain dict, read from
    ``configs/environments/<name>.yaml``."""
    if name not in CONFIG_MODELS:
        raise cfg.ConfigError(f"unknown environment config {name!r}; known: {sorted(CONFIG_MODELS)}")
    path = cfg.config_dir() / "environments" / f"{name}.yaml"
    if not path.is_file():
        raise cfg.ConfigError(f"environment config file {path} is missing")
    return yaml.safe_load(path.read_text())


def environment_config(name: str, user: Mapping[str, Any] | str | Path | None = None) -> BrakeEnvConfig:
    """Defaults of environment ``name`` merged with ``user`` (a dict or a YAML file), validated,
    with the referenced vehicle, pneumatics and set-up checked to exist."""
    source = f"configs/environments/{name}.yaml"
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
        data = _merged(data, user)
    try:
        env_config = CONFIG_MODELS[name].model_validate(data)
    except ValidationError as exc:
        raise cfg.ConfigError(cfg._describe_validation_error(Path(source), exc)) from None
    vehicle = cfg.load("vehicles", env_config.vehicle)
    cfg.load("pneumatics", env_config.actuation)
    cfg.load("setups", env_config.setup)
    unknown = [load for load in env_config.loads if load not in vehicle.loads]
    if unknown:
        raise cfg.ConfigError(f"{source}: field 'loads' = {unknown}: not loads of vehicle {vehicle.name!r} ({sorted(vehicle.loads)})")
    if env_config.effects is not None:
        from ..recordings.effects import load_effects  # the recordings package needs pandas: only here

        try:
            load_effects(env_config.effects)
        except (cfg.ConfigError, ValueError) as exc:
            raise cfg.ConfigError(f"{source}: field 'effects' = {env_config.effects!r}: {exc}") from None
    if env_config.instrumented_disc > vehicle.n_discs:
        raise cfg.ConfigError(
            f"{source}: field 'instrumented_disc' = {env_config.instrumented_disc}: vehicle "
            f"{vehicle.name!r} has {vehicle.n_discs} discs"
        )
    return env_config
