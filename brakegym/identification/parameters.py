"""Which parameters an identification may fit, their bounds, and how a parameter vector becomes
the material and disc configs the simulator is built from.

The bounds live in ``configs/identification/<name>.yaml`` (validated here with pydantic, like the
other configs); a parameter is named by its symbol (``a``, ``x``, ``C_fric``, ...) and maps onto a
field of the material config (paper Eq. 4) or of the disc config (paper Eqs. 5-10, nested fields
with a dot, e.g. ``surface.h_ref_W_per_m2K``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from .. import config as cfg

KIND = "identification"
# Parameters the simulator takes per application (BatchConditions), not per plant: runs that
# differ only in these share one batch.
PER_APPLICATION_FIELDS = ("initial_mu", "power_coefficient_per_s")


class ParameterBound(cfg.StrictModel):
    """One fittable parameter: its symbol, the config field it sets and its physical bounds."""

    symbol: str
    field: str
    lower: float
    upper: float

    @model_validator(mode="after")
    def _ordered(self) -> ParameterBound:
        if not (np.isfinite(self.lower) and np.isfinite(self.upper) and self.lower < self.upper):
            raise ValueError(f"{self.symbol}: bounds [{self.lower}, {self.upper}] must be finite with lower < upper")
        owner_and_field(self.field)  # raises on an unknown field
        return self


class Interval(cfg.StrictModel):
    lower: float = Field(ge=0)
    upper: float = Field(gt=0)

    @model_validator(mode="after")
    def _ordered(self) -> Interval:
        if not self.lower < self.upper:
            raise ValueError(f"lower ({self.lower}) must be below upper ({self.upper})")
        return self


class IdentifiabilityRule(cfg.StrictModel):
    max_relative_ci_half_width: float = Field(gt=0)
    min_normalised_singular_value: float = Field(gt=0, lt=1)


class StochasticSettings(cfg.StrictModel):
    initial_mu_sigma: Interval
    power_coefficient_sigma_per_s: Interval
    global_fraction: Interval
    sensitivity_relative_step: float = Field(gt=0, lt=0.1)
    bootstrap_resamples: int = Field(ge=20)
    bootstrap_seed: int = Field(ge=0)

    @model_validator(mode="after")
    def _fraction_range(self) -> StochasticSettings:
        if self.global_fraction.upper > 1:
            raise ValueError(f"global_fraction.upper = {self.global_fraction.upper}: a fraction of sigma is at most 1")
        return self


ChannelName = Literal["mu", "T_fric_C", "speed_mps", "decel_mps2", "T_disc_C"]


class IdentificationConfig(cfg.StrictModel):
    """``configs/identification/<name>.yaml``: bounds, subsets, channel weights, rules."""

    name: str
    description: str = ""
    parameters: list[ParameterBound] = Field(min_length=1)
    parameter_sets: dict[str, list[str]] = {}
    channel_scales: dict[ChannelName, float]
    jacobian_relative_step: float = Field(gt=0, lt=0.1)
    max_function_evaluations: int = Field(ge=1)
    identifiability: IdentifiabilityRule
    stochastic: StochasticSettings

    @model_validator(mode="after")
    def _consistent(self) -> IdentificationConfig:
        symbols = [p.symbol for p in self.parameters]
        fields = [p.field for p in self.parameters]
        for what, names in (("symbol", symbols), ("field", fields)):
            repeated = sorted({n for n in names if names.count(n) > 1})
            if repeated:
                raise ValueError(f"parameters: {what} {repeated} appears more than once")
        for set_name, members in self.parameter_sets.items():
            unknown = [m for m in members if m not in symbols]
            if unknown:
                raise ValueError(f"parameter_sets.{set_name}: unknown symbol(s) {unknown}; known: {symbols}")
            if set_name in symbols:
                raise ValueError(f"parameter_sets.{set_name}: a set must not share its name with a parameter")
        for channel, scale in self.channel_scales.items():
            if not (np.isfinite(scale) and scale > 0):
                raise ValueError(f"channel_scales.{channel} = {scale}: must be a positive finite number")
        return self

    def bound(self, symbol: str) -> ParameterBound:
        for parameter in self.parameters:
            if parameter.symbol == symbol:
                return parameter
        raise cfg.ConfigError(
            f"identification config {self.name!r}: unknown parameter {symbol!r}; known: "
            f"{[p.symbol for p in self.parameters]} and sets {sorted(self.parameter_sets)}"
        )

    def resolve(self, names: Sequence[str]) -> list[ParameterBound]:
        """Parameters named by symbol or set name (``friction``), in the order given, each once."""
        if not names:
            raise cfg.ConfigError("no parameters to identify were named")
        symbols: list[str] = []
        for name in names:
            for symbol in self.parameter_sets.get(name, [name]):
                if symbol not in symbols:
                    symbols.append(symbol)
        return [self.bound(symbol) for symbol in symbols]

    def channel_scale(self, channel: str) -> float:
        if channel not in self.channel_scales:
            raise cfg.ConfigError(
                f"identification config {self.name!r}: no channel_scales entry for channel {channel!r}"
            )
        return self.channel_scales[channel]  # type: ignore[index]


def load_identification_config(name_or_path: str | Path = "default") -> IdentificationConfig:
    """``identification/<name>.yaml`` on the config search path, or a YAML file given by path."""
    path = Path(name_or_path)
    source = path if path.suffix in (".yaml", ".yml") else cfg.find(KIND, str(name_or_path))
    return cfg.load_file(source, IdentificationConfig)


def owner_and_field(field: str) -> tuple[Literal["material", "disc"], tuple[str, ...]]:
    """Which config a field belongs to and its path in it; unknown or non-numeric fields raise."""
    path = tuple(field.split("."))
    for owner, model in (("material", cfg.FrictionMaterial), ("disc", cfg.DiscThermal)):
        current: type | None = model
        for part in path:
            fields = getattr(current, "model_fields", {})
            if part not in fields:
                current = None
                break
            current = fields[part].annotation
        if current is float:
            return owner, path  # type: ignore[return-value]
    raise ValueError(
        f"field {field!r} is not a numeric field of the material config (FrictionMaterial) or the disc config "
        "(DiscThermal; nested fields with a dot, e.g. surface.h_ref_W_per_m2K)"
    )


def _get(model: cfg.StrictModel, path: tuple[str, ...]) -> float:
    value = model
    for part in path:
        value = getattr(value, part)
    return float(value)  # type: ignore[arg-type]


def _set(data: dict, path: tuple[str, ...], value: float) -> None:
    for part in path[:-1]:
        data = data[part]
    data[path[-1]] = float(value)


@dataclass(frozen=True)
class ParameterSpace:
    """The fitted parameters, in order, over a base material and disc: turns a vector of values
    into validated configs (a value the config refuses raises, it is not moved)."""

    parameters: tuple[ParameterBound, ...]
    material: cfg.FrictionMaterial
    disc: cfg.DiscThermal

    @property
    def symbols(self) -> list[str]:
        return [p.symbol for p in self.parameters]

    @property
    def lower(self) -> np.ndarray:
        return np.array([p.lower for p in self.parameters])

    @property
    def upper(self) -> np.ndarray:
        return np.array([p.upper for p in self.parameters])

    def base_values(self) -> np.ndarray:
        """The parameters' values in the base material and disc configs."""
        values = []
        for parameter in self.parameters:
            owner, path = owner_and_field(parameter.field)
            values.append(_get(self.material if owner == "material" else self.disc, path))
        return np.array(values)

    def check_inside(self, values: np.ndarray, what: str) -> None:
        for parameter, value in zip(self.parameters, values):
            if not (parameter.lower < value < parameter.upper):
                raise ValueError(
                    f"{what}: {parameter.symbol} ({parameter.field}) = {value:.6g} is not strictly inside its "
                    f"bounds [{parameter.lower:.6g}, {parameter.upper:.6g}]"
                )

    def configs(self, values: np.ndarray) -> tuple[cfg.FrictionMaterial, cfg.DiscThermal]:
        """Material and disc configs with ``values`` set, validated like a config file."""
        material = self.material.model_dump()
        disc = self.disc.model_dump()
        for parameter, value in zip(self.parameters, values):
            owner, path = owner_and_field(parameter.field)
            _set(material if owner == "material" else disc, path, value)
        return cfg.FrictionMaterial.model_validate(material), cfg.DiscThermal.model_validate(disc)

    def plant_key(self, values: np.ndarray) -> tuple[float, ...]:
        """The values that must be the same for runs to share one simulator batch (all but the
        per-application ones)."""
        return tuple(float(v) for p, v in zip(self.parameters, values) if p.field not in PER_APPLICATION_FIELDS)
