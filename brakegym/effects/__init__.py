"""The library of candidate effects: physics the nominal model leaves out.

Each effect is a small class with an ``id``, named parameters with physical bounds and a "no
effect" value, and an :meth:`Effect.apply` that switches it on in a simulation without touching
the simulator's core loop: through its hooks (``extra_forces``, ``friction_modifiers``), through
the batch conditions or plant (mass, running resistance), or, for sensor effects, in the
measurement model (:class:`SensorModel`, used by :mod:`.measurement`).

Parameter values are floats, or arrays with one value per application of the batch (so that a fit
can simulate several parameter sets in one batch).

| id | parameters | acts on |
|---|---|---|
| ``gradient`` | ``gradient_permil`` (+ uphill) | extra force m g p/1000; the accelerometer does not see it |
| ``friction_level`` | ``mu_scale`` | every disc's effective mu |
| ``wet_pads`` | ``initial_loss``, ``drying_energy_MJ`` | mu (1 - loss exp(-E/E_dry)), E = heat into that disc |
| ``adhesion_limit`` | ``adhesion`` | brake force per axle <= adhesion x axle load x g |
| ``thermal_fade`` | ``onset_C``, ``loss_per_100K`` | mu (1 - loss)^((T_fric - onset)/100 K) above onset |
| ``rotating_mass`` | ``mass_factor`` | inertia m (1 + f); gravity and axle loads keep m |
| ``brake_unit_failure`` | ``failed_units`` | the highest-numbered disc units give no force |
| ``running_resistance`` | ``A_N``, ``B_N_per_mps``, ``C_N_per_mps2`` | F_R = A + B v + C v^2 replaces the nominal |
| ``speed_sensor_scale`` | ``scale`` | measured speed and odometry = scale x true |
| ``temperature_sensor_lag`` | ``tau_s`` | first-order lag of the measured disc temperature |
| ``gradient_section`` | ``section_start_m``, ``section_length_m``, ``section_gradient_permil`` | m g p/1000 on a part |
| ``adhesion_section`` | ``patch_start_m``, ``patch_length_m``, ``patch_adhesion`` | the adhesion cap on a part |

An effect set is loadable from YAML (``configs/effects/<name>.yaml``, schema
:class:`brakegym.config.EffectSet`) with :func:`load_effects`. Modules: :mod:`.base` (parameters,
the effect class, the modified model), :mod:`.hooks` (what effects put into the simulator), and the
effects by what they act on: :mod:`.track`, :mod:`.friction`, :mod:`.vehicle`, :mod:`.sensors`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from .. import config as cfg
from ..simulator import BatchConditions, ExtraForce, FrictionModifier, Plant
from .base import TRAIN_LENGTH_M, Effect, EffectedModel, Evidence, LocatedStretch, ParameterSpec, SensorModel, Value
from .friction import AdhesionLimit, AdhesionSection, FrictionLevel, ThermalFade, WetPads
from .sensors import SpeedSensorScale, TemperatureSensorLag
from .track import Gradient, GradientSection, GradientSections, RunningResistanceEffect
from .vehicle import BrakeUnitFailure, RotatingMass

EFFECTS: dict[str, type[Effect]] = {
    cls.id: cls
    for cls in (
        Gradient,
        FrictionLevel,
        WetPads,
        AdhesionLimit,
        ThermalFade,
        RotatingMass,
        BrakeUnitFailure,
        RunningResistanceEffect,
        SpeedSensorScale,
        TemperatureSensorLag,
        GradientSection,
        AdhesionSection,
        GradientSections,
    )
}


def in_library_order(effect_ids: Iterable[str]) -> tuple[str, ...]:
    """``effect_ids`` in the order of ``EFFECTS``: the one spelling of a combination of
    effects, so that a pair fitted in either order is one key."""
    order = list(EFFECTS)
    return tuple(sorted(effect_ids, key=order.index))


def special_cases(effect_id: str) -> tuple[str, ...]:
    """The effects (ids) that ``effect_id`` holds as special cases, nearest first: the chain of
    :attr:`~brakegym.effects.base.Effect.extends` (a profile of two sections holds one section,
    which holds the whole-line gradient)."""
    held = []
    extended = effect_class(effect_id).extends
    while extended is not None:
        held.append(extended)
        extended = EFFECTS[extended].extends
    return tuple(held)


def nested_effects(first_id: str, second_id: str) -> bool:
    """Whether one of the two effects holds the other as a special case (:func:`special_cases`):
    a pair of them describes what the one alone does, with one more level of freedom."""
    return first_id in special_cases(second_id) or second_id in special_cases(first_id)


def effect_class(effect_id: str) -> type[Effect]:
    if effect_id not in EFFECTS:
        raise ValueError(f"unknown effect {effect_id!r}; known: {', '.join(EFFECTS)}")
    return EFFECTS[effect_id]


# What separates two effects whose pair no class names.
DEFAULT_SEPARATION = (
    "coasting phases, the disc temperature and the kinematic consistency of speed, deceleration and position"
)


def separating_measurement(first: str, second: str) -> str:
    """The measurement that would tell effects ``first`` and ``second`` (ids) apart."""
    return (
        effect_class(first).separating_measurements.get(second)
        or effect_class(second).separating_measurements.get(first)
        or DEFAULT_SEPARATION
    )


def make_effect(effect_id: str, **parameters: Value) -> Effect:
    """An effect by id, e.g. ``make_effect("gradient", gradient_permil=-5.8)``."""
    return effect_class(effect_id)(**parameters)


def apply_effects(
    plant: Plant,
    conditions: BatchConditions,
    effects: Sequence[Effect] = (),
    friction_modifiers: Sequence[FrictionModifier] = (),
    wheel_brake_forces: Sequence[ExtraForce] = (),
    line_position_at_start_m: np.ndarray | None = None,
    line_direction_sign: np.ndarray | None = None,
) -> EffectedModel:
    """The model with ``effects`` switched on. The inputs are not changed.

    ``friction_modifiers``: factors on the pads' friction from outside the library (a synthetic
    truth's model form), put in before the effects, so that an adhesion cap sees them: adhesion
    limits the force at the wheel, whatever the pads' friction law. ``wheel_brake_forces``: brake
    forces from outside the library that act through the wheels (an electrodynamic brake), which
    an adhesion cap holds with the pads' force (:attr:`brakegym.effects.base.EffectedModel.wheel_brake_forces`).
    ``line_position_at_start_m``: (B,) where along the line each run begins, m (default 0: each
    run's own odometry), and ``line_direction_sign`` (B,) which way it runs (+1, the default:
    towards growing positions; -1), which effects on part of the line are placed by."""
    ids = [e.id for e in effects]
    repeated = sorted({i for i in ids if ids.count(i) > 1})
    if repeated:
        raise ValueError(f"effect(s) {repeated} given more than once")
    model = EffectedModel(
        plant=plant,
        conditions=conditions,
        gravitational_mass_kg=np.asarray(conditions.mass_kg, dtype=float).copy(),
        friction_modifiers=list(friction_modifiers),
        wheel_brake_forces=list(wheel_brake_forces),
        line_position_at_start_m=(
            None if line_position_at_start_m is None else np.array(line_position_at_start_m, dtype=float)
        ),
        line_direction_sign=None if line_direction_sign is None else np.array(line_direction_sign, dtype=float),
    )
    for effect in sorted(effects, key=lambda e: e.order):  # stable: equal orders keep theirs
        effect.apply(model)
    return model


def effects_from_config(effect_set: cfg.EffectSet, source: str = "effect set") -> list[Effect]:
    """The effects of an effect set; an unknown id, parameter or a value out of bounds raises
    :class:`~brakegym.config.ConfigError` naming ``source``, the field and the value."""
    effects = []
    for index, item in enumerate(effect_set.effects):
        try:
            effects.append(make_effect(item.id, **item.parameters))
        except ValueError as exc:
            shown = {"id": item.id, "parameters": item.parameters}
            raise cfg.ConfigError(
                f"{source}: invalid effects config\n  field 'effects.{index}' = {shown}: {exc}"
            ) from None
    return effects


def load_effects(name_or_path: str | Path) -> list[Effect]:
    """Effects of a YAML effect set: a path to a file, or the name of one on the config search
    path (``configs/effects/``)."""
    path = Path(name_or_path)
    source = path if path.suffix in (".yaml", ".yml") or path.is_file() else cfg.find("effects", str(name_or_path))
    return effects_from_config(cfg.load_file(source, cfg.EffectSet), str(source))


__all__ = [
    "DEFAULT_SEPARATION",
    "EFFECTS",
    "TRAIN_LENGTH_M",
    "AdhesionLimit",
    "AdhesionSection",
    "BrakeUnitFailure",
    "Effect",
    "EffectedModel",
    "Evidence",
    "FrictionLevel",
    "Gradient",
    "GradientSection",
    "GradientSections",
    "LocatedStretch",
    "ParameterSpec",
    "RotatingMass",
    "RunningResistanceEffect",
    "SensorModel",
    "SpeedSensorScale",
    "TemperatureSensorLag",
    "ThermalFade",
    "Value",
    "WetPads",
    "apply_effects",
    "effect_class",
    "effects_from_config",
    "in_library_order",
    "load_effects",
    "make_effect",
    "nested_effects",
    "separating_measurement",
    "special_cases",
]
