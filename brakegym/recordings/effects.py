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
| ``running_resistance`` | ``A_N``, ``B_Nspm``, ``C_Ns2pm2`` | F_R = A + B v + C v^2 replaces the nominal |
| ``speed_sensor_scale`` | ``scale`` | measured speed and odometry = scale x true |
| ``temperature_sensor_lag`` | ``tau_s`` | first-order lag of the measured disc temperature |

An effect set is loadable from YAML (``configs/effects/<name>.yaml``, schema
:class:`brakegym.config.EffectSet`) with :func:`load_effects`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Mapping, Sequence

import numpy as np

from .. import config as cfg
from ..physics import RunningResistance
from ..simulator import BatchConditions, ExtraForce, FrictionModifier, Plant, PressureSource, Simulator, StageContext

STANDARD_GRAVITY_MPS2 = 9.80665
KELVIN = 273.15

Value = float | np.ndarray


@dataclass(frozen=True)
class ParameterSpec:
    """One parameter of an effect.

    ``lower``..``upper`` are physical bounds (what a fit may explore). ``no_effect`` is the value
    at which the effect is absent; it may lie outside the bounds (an adhesion limit is absent at
    infinite adhesion) and is None when it depends on the vehicle (see
    :meth:`Effect.no_effect_values`). ``synth_ranges`` are the intervals ``brakegym synth`` draws
    from when a parameter is not given: inside the bounds, and away from the no-effect value, so
    that a drawn effect is a real one (its smallest sizes near the detection limit).
    ``log_grid``: the diagnosis screens the parameter at geometrically spaced points, for a
    parameter that acts through its order of magnitude over bounds spanning decades.
    """

    name: str
    unit: str
    lower: float
    upper: float
    no_effect: float | None
    synth_ranges: tuple[tuple[float, float], ...]
    integer: bool = False
    description: str = ""
    log_grid: bool = False

    def check(self, effect_id: str, value: Value) -> np.ndarray:
        array = np.asarray(value, dtype=float)
        if array.ndim > 1:
            raise ValueError(f"effect {effect_id!r}: parameter {self.name!r} must be a number or one value per application")
        if np.any(np.isnan(array)):
            raise ValueError(f"effect {effect_id!r}: parameter {self.name!r} = {value!r} is not a number")
        absent = np.full(array.shape, False) if self.no_effect is None else array == self.no_effect
        outside = ((array < self.lower) | (array > self.upper)) & ~absent
        if np.any(outside):
            shown = array[outside].flat[0]
            unit = f" {self.unit}" if self.unit else ""
            raise ValueError(
                f"effect {effect_id!r}: parameter {self.name!r} = {shown:g}{unit} lies outside its bounds "
                f"{self.lower:g}..{self.upper:g}{unit}"
            )
        if self.integer and np.any((array != np.round(array)) & ~absent):
            raise ValueError(f"effect {effect_id!r}: parameter {self.name!r} = {value!r} must be a whole number")
        return array


@dataclass
class SensorModel:
    """How the sensors see the true states (see :mod:`.measurement`)."""

    speed_scale: Value = 1.0  # measured over true, speed and odometry alike (wheel diameter)
    temperature_lag_s: Value = 0.0  # first-order lag of the disc-temperature sensor


@dataclass
class EffectedModel:
    """A plant and batch with effects switched on: what to hand to :class:`Simulator`, and what
    the measurement model needs.

    ``conditions.mass_kg`` is the inertial mass (a rotating-mass effect raises it);
    ``gravitational_mass_kg`` stays the train's mass for gravity and axle loads. ``grade`` is the
    track's rise over run in the direction of travel, per application.
    """

    plant: Plant
    conditions: BatchConditions
    gravitational_mass_kg: np.ndarray
    extra_forces: list[ExtraForce] = field(default_factory=list)
    friction_modifiers: list[FrictionModifier] = field(default_factory=list)
    sensors: SensorModel = field(default_factory=SensorModel)
    grade: Value = 0.0

    @property
    def n_trains(self) -> int:
        return self.conditions.n_trains

    def simulator(self, pressure: PressureSource, step_s: float) -> Simulator:
        """A simulator of this modified model."""
        return Simulator(
            self.plant,
            self.conditions,
            pressure,
            step_s=step_s,
            extra_forces=self.extra_forces,
            friction_modifiers=self.friction_modifiers,
        )


class Effect:
    """Base of the candidate effects; subclasses set ``id``, ``parameters`` and ``apply``."""

    id: ClassVar[str]
    parameters: ClassVar[tuple[ParameterSpec, ...]]
    sensor: ClassVar[bool] = False  # acts on the measurement, not on the physics
    # Effects apply in ascending order; the adhesion limit must see every other friction factor.
    order: ClassVar[int] = 0

    def __init__(self, **values: Value) -> None:
        names = [p.name for p in self.parameters]
        unknown = sorted(set(values) - set(names))
        if unknown:
            raise ValueError(f"effect {self.id!r}: unknown parameter(s) {unknown}; its parameters are {names}")
        missing = [n for n in names if n not in values]
        if missing:
            raise ValueError(f"effect {self.id!r}: parameter(s) {missing} not given")
        self.values: dict[str, Value] = {}
        for spec in self.parameters:
            array = spec.check(self.id, values[spec.name])
            self.values[spec.name] = float(array) if array.ndim == 0 else array

    def __getitem__(self, name: str) -> Value:
        return self.values[name]

    def __repr__(self) -> str:
        shown = ", ".join(f"{k}={v!r}" for k, v in self.values.items())
        return f"{type(self).__name__}({shown})"

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, Effect)
            and other.id == self.id
            and all(np.array_equal(self.values[k], other.values[k]) for k in self.values)
        )

    @classmethod
    def spec(cls, name: str) -> ParameterSpec:
        for spec in cls.parameters:
            if spec.name == name:
                return spec
        raise KeyError(f"effect {cls.id!r} has no parameter {name!r}")

    @classmethod
    def no_effect_values(cls, vehicle: cfg.Vehicle | None = None) -> dict[str, float]:
        """Parameter values at which the effect is absent."""
        values = {}
        for spec in cls.parameters:
            if spec.no_effect is None:
                raise ValueError(f"effect {cls.id!r}: the no-effect value of {spec.name!r} depends on the vehicle")
            values[spec.name] = spec.no_effect
        return values

    def as_config(self) -> dict[str, Any]:
        """The YAML/JSON form: ``{"id": ..., "parameters": {...}}`` (scalar parameters only)."""
        return {"id": self.id, "parameters": {k: float(v) for k, v in self.values.items()}}

    def apply(self, model: EffectedModel) -> None:
        """Switch the effect on in ``model`` (in place)."""
        raise NotImplementedError


def _per_train(value: Value, n_trains: int, what: str) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.ndim == 1 and len(array) != n_trains:
        raise ValueError(f"{what}: {len(array)} values for a batch of {n_trains} applications")
    return np.broadcast_to(array, (n_trains,)).copy()


# ------------------------------------------------------------------------------------------------
# Hooks (the simulator's extension points)


@dataclass(frozen=True)
class ConstantForce:
    """A retarding force per train that does not change during the run (a gradient)."""

    force: np.ndarray  # (B,)
    constant: ClassVar[bool] = True  # the simulator integrates it in its compiled kernel

    def force_N(self, context: StageContext) -> np.ndarray:
        return self.force


@dataclass(frozen=True)
class ConstantFrictionFactor:
    factor: Value  # scalar, (B,) or (A, k, B)
    constant: ClassVar[bool] = True

    def scale(self, context: StageContext) -> Value:
        return self.factor


@dataclass(frozen=True)
class WetPadFactor:
    """1 - loss exp(-E / E_dry), E the friction heat that has entered the disc so far."""

    initial_loss: Value
    drying_energy_J: Value

    def scale(self, context: StageContext) -> np.ndarray:
        return 1.0 - self.initial_loss * np.exp(-context.friction_heat_J / self.drying_energy_J)


@dataclass(frozen=True)
class FadeFactor:
    """(1 - loss)^(max(T_fric - onset, 0) / 100 K): the share ``loss`` is lost per 100 K above
    the onset, compounded, so the factor stays positive however hot the disc gets."""

    onset_K: Value
    log_keep_per_100K: Value  # log(1 - loss)

    def scale(self, context: StageContext) -> np.ndarray:
        excess_K = np.maximum(context.friction_temperature_K - self.onset_K, 0.0)
        return np.exp(self.log_keep_per_100K * excess_K * 0.01)


@dataclass(frozen=True)
class AdhesionCap:
    """Caps each axle's brake force at adhesion x axle load x g.

    A wheel-slide protection releases the brake to keep the wheels rolling at the adhesion limit:
    modelled as a factor on the friction force of the axle's discs (force and heat follow it; the
    friction state of Eq. 4 is driven by the clamp force as measured). It must see the factors of
    the other friction effects (``upstream``) to know the force it caps.
    """

    limit_N: np.ndarray  # (B,), per axle
    upstream: tuple[FrictionModifier, ...]
    plant: Plant

    def scale(self, context: StageContext) -> np.ndarray:
        mu = self.plant.friction.bounded(context.mu)
        for modifier in self.upstream:
            mu = mu * modifier.scale(context)
        axle_force = (mu * context.clamp_force_N).sum(axis=1) * self.plant.radius_ratio  # (A, B)
        safe = np.where(axle_force > self.limit_N, axle_force, 1.0)
        return np.where(axle_force > self.limit_N, self.limit_N / safe, 1.0)[:, None, :]


# ------------------------------------------------------------------------------------------------
# The effects


class Gradient(Effect):
    """A constant track gradient: F = m g p / 1000 (the railway convention: the gradient
    resistance in N/kN equals the gradient in permil), positive uphill. The accelerometer
    measures specific force and does not see it; the speed signal does."""

    id = "gradient"
    parameters = (
        ParameterSpec("gradient_permil", "permil", -40.0, 40.0, 0.0, ((-15.0, -2.0), (2.0, 15.0)),
                      description="rise over run x 1000 in the direction of travel"),
    )

    def apply(self, model: EffectedModel) -> None:
        grade = _per_train(self["gradient_permil"], model.n_trains, "gradient_permil") / 1000.0
        model.extra_forces.append(ConstantForce(model.gravitational_mass_kg * STANDARD_GRAVITY_MPS2 * grade))
        model.grade = model.grade + grade


class FrictionLevel(Effect):
    """The pads' friction level differs from the nominal material: mu_eff = mu_scale x mu."""

    id = "friction_level"
    parameters = (ParameterSpec("mu_scale", "", 0.5, 1.5, 1.0, ((0.75, 0.95), (1.05, 1.25))),)

    def apply(self, model: EffectedModel) -> None:
        model.friction_modifiers.append(ConstantFrictionFactor(_per_train(self["mu_scale"], model.n_trains, "mu_scale")))


class WetPads(Effect):
    """Wet pads: friction reduced by ``initial_loss`` at the start, recovering exponentially as
    the friction heat that entered the disc grows: mu_eff = mu (1 - loss exp(-E / E_dry))."""

    id = "wet_pads"
    parameters = (
        ParameterSpec("initial_loss", "", 0.0, 0.8, 0.0, ((0.15, 0.5),), description="share of mu lost at the start"),
        # exp(-E / E_dry): 0.7 and 1.7 MJ are far apart, 5 and 8 MJ nearly alike. On the linear
        # grid (1.7, 5.0, 8.3 MJ) fits of sets drying at 0.6-1.3 MJ ended in a second valley at
        # 5-7 MJ with twice the chi^2 of the truth's.
        ParameterSpec("drying_energy_MJ", "MJ", 0.05, 10.0, None, ((0.2, 1.5),),
                      description="heat into one disc that dries it by a factor e", log_grid=True),
    )

    @classmethod
    def no_effect_values(cls, vehicle: cfg.Vehicle | None = None) -> dict[str, float]:
        # Without loss the drying energy is irrelevant; any value in the bounds does.
        return {"initial_loss": 0.0, "drying_energy_MJ": 1.0}

    def apply(self, model: EffectedModel) -> None:
        n = model.n_trains
        model.friction_modifiers.append(
            WetPadFactor(
                _per_train(self["initial_loss"], n, "initial_loss"),
                _per_train(self["drying_energy_MJ"], n, "drying_energy_MJ") * 1e6,
            )
        )


class AdhesionLimit(Effect):
    """Wheel-rail adhesion limits each axle's brake force to adhesion x axle load x g, the axle
    load being the train's (gravitational) mass shared evenly by its axles."""

    id = "adhesion_limit"
    parameters = (ParameterSpec("adhesion", "", 0.02, 0.5, math.inf, ((0.05, 0.09),)),)
    order = 100

    def apply(self, model: EffectedModel) -> None:
        adhesion = _per_train(self["adhesion"], model.n_trains, "adhesion")
        axle_load_N = model.gravitational_mass_kg / model.plant.n_axles * STANDARD_GRAVITY_MPS2
        model.friction_modifiers.append(
            AdhesionCap(adhesion * axle_load_N, tuple(model.friction_modifiers), model.plant)
        )


class ThermalFade(Effect):
    """Friction fades above an onset temperature of the friction surface: mu_eff = mu (1 -
    loss)^((T_fric - onset) / 100 K), i.e. ``loss_per_100K`` of mu lost per 100 K, compounded."""

    id = "thermal_fade"
    parameters = (
        ParameterSpec("onset_C", "degC", 80.0, 600.0, None, ((120.0, 250.0),)),
        ParameterSpec("loss_per_100K", "", 0.0, 0.6, 0.0, ((0.1, 0.4),)),
    )

    @classmethod
    def no_effect_values(cls, vehicle: cfg.Vehicle | None = None) -> dict[str, float]:
        return {"onset_C": 300.0, "loss_per_100K": 0.0}

    def apply(self, model: EffectedModel) -> None:
        n = model.n_trains
        model.friction_modifiers.append(
            FadeFactor(
                _per_train(self["onset_C"], n, "onset_C") + KELVIN,
                np.log1p(-_per_train(self["loss_per_100K"], n, "loss_per_100K")),
            )
        )


class RotatingMass(Effect):
    """Rotating parts add inertia: the train accelerates as m (1 + mass_factor), while gravity
    and axle loads act on m."""

    id = "rotating_mass"
    parameters = (ParameterSpec("mass_factor", "", -0.2, 0.3, 0.0, ((0.04, 0.15),)),)

    def apply(self, model: EffectedModel) -> None:
        factor = 1.0 + _per_train(self["mass_factor"], model.n_trains, "mass_factor")
        model.conditions = dataclasses.replace(model.conditions, mass_kg=np.asarray(model.conditions.mass_kg) * factor)


class BrakeUnitFailure(Effect):
    """``failed_units`` disc units give no force (and no heat). Which ones: the highest-numbered
    units in the simulator's (and the recording's ``instrumented_disc``) numbering, axle by axle
    from axle 1 and the discs of each axle in turn; i.e. from the rear of the train. On
    ``emu_8axle`` one failed unit is disc 16, two are discs 15 and 16."""

    id = "brake_unit_failure"
    parameters = (ParameterSpec("failed_units", "units", 0.0, 8.0, 0.0, ((1.0, 4.0),), integer=True),)

    def apply(self, model: EffectedModel) -> None:
        plant = model.plant
        failed = _per_train(self["failed_units"], model.n_trains, "failed_units")
        if np.any(failed > plant.n_discs):
            raise ValueError(f"effect 'brake_unit_failure': {failed.max():g} failed units, but {plant.name!r} has {plant.n_discs}")
        disc_number = np.arange(plant.n_discs).reshape(plant.disc_shape)[..., None]  # (A, k, 1)
        working = (disc_number < plant.n_discs - failed).astype(float)  # (A, k, B)
        model.friction_modifiers.append(ConstantFrictionFactor(working))


class RunningResistanceEffect(Effect):
    """The running resistance differs from the vehicle's nominal one: F_R = A + B v + C v^2 with
    these coefficients replaces it (a drawn scatter of A, if any, is added by the caller)."""

    id = "running_resistance"
    parameters = (
        ParameterSpec("A_N", "N", 0.0, 20000.0, None, ((6000.0, 12000.0),)),
        ParameterSpec("B_Nspm", "N s/m", 0.0, 300.0, None, ((60.0, 150.0),)),
        ParameterSpec("C_Ns2pm2", "N s^2/m^2", 0.0, 30.0, None, ((8.0, 14.0),)),
    )

    @classmethod
    def no_effect_values(cls, vehicle: cfg.Vehicle | None = None) -> dict[str, float]:
        if vehicle is None:
            raise ValueError("effect 'running_resistance': the no-effect values are the vehicle's nominal coefficients")
        nominal = vehicle.running_resistance
        return {"A_N": nominal.A_N, "B_Nspm": nominal.B_N_per_mps, "C_Ns2pm2": nominal.C_N_per_mps2}

    def apply(self, model: EffectedModel) -> None:
        n = model.n_trains
        a = _per_train(self["A_N"], n, "A_N")
        b, c = self["B_Nspm"], self["C_Ns2pm2"]
        model.plant = dataclasses.replace(
            model.plant,
            running_resistance=RunningResistance(
                A_N=a,
                B_N_per_mps=b if np.ndim(b) == 0 else _per_train(b, n, "B_Nspm"),
                C_N_per_mps2=c if np.ndim(c) == 0 else _per_train(c, n, "C_Ns2pm2"),
            ),
        )
        model.conditions = dataclasses.replace(model.conditions, running_resistance_A_N=a)


class SpeedSensorScale(Effect):
    """The speed sensor reports ``scale`` x the true speed (a wheel-diameter error): speed and
    odometry are scaled together, a deceleration differentiated from speed too, the accelerometer
    not."""

    id = "speed_sensor_scale"
    sensor = True
    parameters = (ParameterSpec("scale", "", 0.9, 1.1, 1.0, ((0.95, 0.99), (1.01, 1.05))),)

    def apply(self, model: EffectedModel) -> None:
        model.sensors.speed_scale = model.sensors.speed_scale * _per_train(self["scale"], model.n_trains, "scale")


class TemperatureSensorLag(Effect):
    """The disc-temperature sensor lags the friction surface: tau dT_meas/dt = T_fric - T_meas,
    discretised exactly (see :func:`.measurement.first_order_lag`)."""

    id = "temperature_sensor_lag"
    sensor = True
    parameters = (ParameterSpec("tau_s", "s", 0.0, 60.0, 0.0, ((2.0, 20.0),)),)

    def apply(self, model: EffectedModel) -> None:
        model.sensors.temperature_lag_s = _per_train(self["tau_s"], model.n_trains, "tau_s")


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
    )
}


def effect_class(effect_id: str) -> type[Effect]:
    if effect_id not in EFFECTS:
        raise ValueError(f"unknown effect {effect_id!r}; known: {', '.join(EFFECTS)}")
    return EFFECTS[effect_id]


def make_effect(effect_id: str, **parameters: Value) -> Effect:
    """An effect by id, e.g. ``make_effect("gradient", gradient_permil=-5.8)``."""
    return effect_class(effect_id)(**parameters)


def validate_effect_config(effect_id: str, parameters: Mapping[str, float]) -> None:
    """Raise ValueError naming the problem if the id or parameters are not a valid effect (used by
    the config schema)."""
    make_effect(effect_id, **parameters)


def apply_effects(plant: Plant, conditions: BatchConditions, effects: Sequence[Effect] = ()) -> EffectedModel:
    """The model with ``effects`` switched on. The inputs are not changed."""
    ids = [e.id for e in effects]
    repeated = sorted({i for i in ids if ids.count(i) > 1})
    if repeated:
        raise ValueError(f"effect(s) {repeated} given more than once")
    model = EffectedModel(
        plant=plant,
        conditions=conditions,
        gravitational_mass_kg=np.asarray(conditions.mass_kg, dtype=float).copy(),
    )
    for effect in sorted(effects, key=lambda e: e.order):  # stable: equal orders keep theirs
        effect.apply(model)
    return model


def effects_from_config(effect_set: cfg.EffectSet) -> list[Effect]:
    return [make_effect(item.id, **item.parameters) for item in effect_set.effects]


def load_effects(name_or_path: str | Path) -> list[Effect]:
    """Effects of a YAML effect set: a path to a file, or the name of one in ``configs/effects/``."""
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.is_file():
        return effects_from_config(cfg.load_file(path, cfg.EffectSet))
    return effects_from_config(cfg.load("effects", str(name_or_path)))
