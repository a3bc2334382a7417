"""Validated configuration files.

Every physical constant of the simulator lives in a YAML file, one folder per kind (``materials``,
``discs``, ``pneumatics``, ``rigs``, ``vehicles``, ``setups``, ``campaigns``, ``effects``,
``rail_conditions``, and ``environments``, ``agents``, ``identification`` for the code that owns
their schema), one file per named item. A user adds a vehicle or a pad material by adding a file
to a folder on the search path (:mod:`.library`); the file's ``name`` must equal its stem.
Units are part of every field name.

Loading validates with pydantic (:mod:`.schema`); any problem raises :class:`ConfigError` naming
the file, the field and the offending value.
"""

from .library import (
    CONFIG_PATH_ENV,
    KINDS,
    OTHER_KINDS,
    available,
    config_path,
    describe_validation_error,
    find,
    load,
    load_file,
    read_yaml,
    search_path,
    set_config_path,
    shipped_configs,
    validate,
)
from .schema import (
    BrakeMode,
    Caliper,
    ConfigError,
    ConvectionLaw,
    DiscThermal,
    Dynamometer,
    DynoCampaign,
    EffectConfig,
    EffectSet,
    FieldCampaign,
    FrictionMaterial,
    FrictionScatter,
    LoadCase,
    Pneumatics,
    RailCondition,
    RunningResistance,
    SafetyCase,
    ScatterSetup,
    StrictModel,
    Vehicle,
    VehicleLoad,
    Wheelsets,
)

__all__ = [
    "CONFIG_PATH_ENV",
    "KINDS",
    "OTHER_KINDS",
    "BrakeMode",
    "Caliper",
    "ConfigError",
    "ConvectionLaw",
    "DiscThermal",
    "DynoCampaign",
    "Dynamometer",
    "EffectConfig",
    "EffectSet",
    "FieldCampaign",
    "FrictionMaterial",
    "FrictionScatter",
    "LoadCase",
    "Pneumatics",
    "RunningResistance",
    "RailCondition",
    "SafetyCase",
    "ScatterSetup",
    "StrictModel",
    "Vehicle",
    "Wheelsets",
    "VehicleLoad",
    "available",
    "config_path",
    "describe_validation_error",
    "find",
    "load",
    "load_file",
    "read_yaml",
    "search_path",
    "set_config_path",
    "shipped_configs",
    "validate",
]
