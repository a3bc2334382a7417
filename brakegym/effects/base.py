"""The base of the effect library: parameters with physical bounds, the effect class, and the
modified model an effect set builds.

An effect switches physics the nominal model leaves out on in a simulation without touching the
simulator's core loop: through its hooks (:mod:`brakegym.simulator.hooks`), through the batch
conditions or plant (mass, running resistance), or, for sensor effects, in the measurement model
(:class:`SensorModel`). Parameter values are floats, or arrays with one value per application of
the batch (so that a fit can simulate several parameter sets in one batch).

An effect also says what the diagnosis (:mod:`brakegym.diagnosis`) needs to know of it: whether a
fitted size matters physically, where in its bounds the data point a search to start, how much of
the brake force it leaves, and which measurements would confirm it or separate it from a
look-alike. The diagnosis hands it the :class:`Evidence` of a set of recordings.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from .. import config as cfg
from ..simulator import BatchConditions, ExtraForce, FrictionModifier, Plant, PressureSource, Simulator
from ..units import STANDARD_GRAVITY_MPS2
from .hooks import AdhesionCap, AdhesionSectionCap, Value, WheelBrakeForceUnderAdhesion


@dataclass(frozen=True)
class ParameterSpec:
    """One parameter of an effect.

    ``lower``..``upper`` bound what a fit may explore. A bound is physical where the truth can sit
    on it (a running resistance's B >= 0, a loss of 0: ``lower_is_physical``,
    ``upper_is_physical``); otherwise it ends the search range at sizes past which the effect is
    no longer plausible, and a fit that ends there is not named by the diagnosis (the data want
    the effect beyond what the library gives it, standing in for something else). ``no_effect`` is the value
    at which the effect is absent; it may lie outside the bounds (an adhesion limit is absent at
    infinite adhesion) and is None when it depends on the vehicle (see
    :meth:`Effect.no_effect_values`). ``synth_ranges`` are the intervals ``brakegym synth`` draws
    from when a parameter is not given: inside the bounds, and away from the no-effect value, so
    that a drawn effect is a real one (its smallest sizes near the detection limit).
    ``log_grid``: the diagnosis screens the parameter at geometrically spaced points, for a
    parameter that acts through its order of magnitude over bounds spanning decades.
    ``difference_step``: the step of the diagnosis's finite-difference Jacobian, as a share of
    ``upper - lower``. Where the replay crosses a parameter's threshold on its time grid (a fade's
    onset), the chi^2 along it is rough at small steps: the derivatives read the roughness, the
    fit's trust region shrinks and the fit crawls along its valley. Such a parameter (a fade's
    onset, a wet pad's drying energy) takes a step of 1 % instead of the default 0.1 %; see the
    coverage measurements in the diagnosis docs.
    ``locates``: the parameter says where or when the effect acts (a section's start and length, a
    fade's onset, the energy over which wet pads dry), not how large it is; the diagnosis's
    held-out prediction does not hold such a parameter at its no-effect value where the other
    recordings do not inform it (:mod:`brakegym.diagnosis.heldout`), since that value alone does
    not say the effect is absent where they show it.
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
    lower_is_physical: bool = False
    upper_is_physical: bool = False
    difference_step: float = 1e-3
    locates: bool = False

    def __post_init__(self) -> None:
        if not 0.0 < self.difference_step < 0.5:
            raise ValueError(f"parameter {self.name!r}: difference_step {self.difference_step!r} is not in (0, 0.5)")

    def check(self, effect_id: str, value: Value) -> np.ndarray:
        array = np.asarray(value, dtype=float)
        if array.ndim > 1:
            raise ValueError(
                f"effect {effect_id!r}: parameter {self.name!r} must be a number or one value per application"
            )
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

    def range_position(self, value: float) -> float:
        """Where ``value`` lies in the bounds: 0 at the lower, 1 at the upper (along the logarithm
        for a ``log_grid`` parameter)."""
        if self.log_grid:
            return math.log(value / self.lower) / math.log(self.upper / self.lower)
        return (value - self.lower) / (self.upper - self.lower)

    def at_range_end(self, value: float, share: float) -> bool:
        """Whether ``value`` lies within ``share`` of the range (of its logarithm for a
        ``log_grid`` parameter) of a bound that is not physical."""
        position = self.range_position(value)
        return (position <= share and not self.lower_is_physical) or (
            position >= 1.0 - share and not self.upper_is_physical
        )

    def spans_range(self, low: float, high: float, share: float) -> bool:
        """Whether an interval ``low``..``high`` reaches within ``share`` of the range of both
        bounds, physical or not: the data do not bound the parameter, and such an interval holds
        any truth."""
        return self.range_position(low) <= share and self.range_position(high) >= 1.0 - share

    def inside_bounds(self, value: float) -> float:
        """``value``, or the nearer bound where it lies outside them: a fit's start (a fit explores
        only inside the bounds)."""
        return float(min(max(value, self.lower), self.upper))

    def grid(self, points: int) -> np.ndarray:
        """``points`` values across the bounds: the midpoints of equal parts (of geometric parts
        for a ``log_grid`` parameter), never a bound itself."""
        midpoints = (np.arange(points) + 0.5) / points
        if self.log_grid:
            return self.lower * (self.upper / self.lower) ** midpoints
        return self.lower + midpoints * (self.upper - self.lower)


#: The train's length in metres, over which effects on part of the line spread it (ASSUMED, a
#: two-car unit of the emu_8axle's eight axles; the vehicle configs carry no length).
TRAIN_LENGTH_M = 50.0


@dataclass(frozen=True)
class LocatedStretch:
    """A stretch of the line where the unmodified model's residual deceleration steps, as the
    diagnosis locates it (:mod:`brakegym.diagnosis.position_steps`), in metres along the line
    (each recording's own odometry where the recordings are not placed on it)."""

    start_m: float
    end_m: float
    decel_step_mps2: float  # on the stretch minus off it (positive: the train slows more there)
    peak_decel_mps2: float  # the measured deceleration of the hardest braking on it

    @property
    def gradient_permil(self) -> float:
        """The gradient whose force leaves this step (its deceleration over g, x 1000)."""
        return 1000.0 * self.decel_step_mps2 / STANDARD_GRAVITY_MPS2

    def section(self, train_length_m: float) -> tuple[float, float]:
        """(start_m, length_m) of a section whose effect ramps in over one train length from its
        start and out from its end (the train's weight or axles spread over ``train_length_m``):
        the step's edges lie half a train length beyond the section's ends."""
        start = max(self.start_m - 0.5 * train_length_m, 0.0)
        return start, self.end_m - 0.5 * train_length_m - start


@dataclass(frozen=True)
class Evidence:
    """What a set of recordings shows of itself, as the diagnosis tells it to the effects.

    Peaks are ``inf`` where the recordings do not measure the quantity.
    """

    peak_decel_mps2: float  # the highest 99th percentile of a recording's measured deceleration
    peak_disc_C: float  # the highest measured disc temperature
    friction_factors: np.ndarray  # each recording's friction factor fitted with the unmodified model
    nominal_resistance: cfg.RunningResistance  # the vehicle's running resistance and its scatter
    peak_friction_surface_C: float = float("inf")  # the hottest friction surface of a candidate's fitted replays
    run_distance_m: float = float("inf")  # the longest distance a recording covers from its first sample
    #: where the unmodified model's residual locates something that acts on part of the line
    stretches: tuple[LocatedStretch, ...] = ()
    #: two steps located one after the other, the second in what the first leaves of the
    #: residual: a profile of two sections (empty unless both are located)
    profile_stretches: tuple[LocatedStretch, ...] = ()


def on_part_of_the_run(start_m: float, end_m: float, evidence: Evidence) -> bool:
    """Whether a section from ``start_m`` to ``end_m`` lies on the recordings' run and begins or
    ends inside it by a train length: one that covers every recording from end to end acts on the
    whole line, and the effect of the whole line says so."""
    inside = start_m >= TRAIN_LENGTH_M or end_m <= evidence.run_distance_m - TRAIN_LENGTH_M
    return inside and start_m < evidence.run_distance_m


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
    track's rise over run in the direction of travel, per application (a gradient that changes
    along the line is a :class:`~brakegym.effects.hooks.GradientProfileForce` among the
    ``extra_forces``).
    """

    plant: Plant
    conditions: BatchConditions
    gravitational_mass_kg: np.ndarray
    extra_forces: list[ExtraForce] = field(default_factory=list)
    friction_modifiers: list[FrictionModifier] = field(default_factory=list)
    sensors: SensorModel = field(default_factory=SensorModel)
    grade: Value = 0.0
    #: brake forces that act through the wheels besides the pads' (a synthetic truth's
    #: electrodynamic brake): an adhesion cap holds them with the pads' (see
    #: :class:`~brakegym.effects.hooks.AdhesionCap`)
    wheel_brake_forces: list[ExtraForce] = field(default_factory=list)
    #: (B,) where along the line each run begins, m (a recording's ``line_position_m``; 0 where
    #: positions are each run's own odometry): an effect on part of the line places itself by it
    line_position_at_start_m: np.ndarray | None = None
    #: (B,) +1 where a run goes towards growing line positions, -1 where towards falling ones
    line_direction_sign: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.line_position_at_start_m is None:
            self.line_position_at_start_m = np.zeros(self.n_trains)
        if self.line_direction_sign is None:
            self.line_direction_sign = np.ones(self.n_trains)
        for name in ("line_position_at_start_m", "line_direction_sign"):
            if np.shape(getattr(self, name)) != (self.n_trains,):
                raise ValueError(
                    f"{name}: one value per run ({self.n_trains}) expected, got shape {np.shape(getattr(self, name))}"
                )
        if not np.all(np.abs(self.line_direction_sign) == 1.0):
            raise ValueError(f"line_direction_sign: +1 or -1 per run, got {self.line_direction_sign}")

    def in_run_odometry(self, start_m: np.ndarray, end_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A stretch of line from ``start_m`` to ``end_m`` ((B,), along the line) in each run's
        own metres travelled from its start, where the simulator's position counts: (nearer end,
        farther end) as the run meets them."""
        offset = np.asarray(self.line_position_at_start_m, dtype=float)
        sign = np.asarray(self.line_direction_sign, dtype=float)
        near = np.where(sign > 0, start_m - offset, offset - end_m)
        far = np.where(sign > 0, end_m - offset, offset - start_m)
        return near, far

    @property
    def n_trains(self) -> int:
        return self.conditions.n_trains

    def simulator(
        self, pressure: PressureSource, step_s: float, simulator_class: type[Simulator] = Simulator
    ) -> Simulator:
        """A simulator of this modified model (``simulator_class``: the compiled one, or the numpy
        reference that synthetic truth may be integrated with)."""
        return simulator_class(
            self.plant,
            self.conditions,
            pressure,
            step_s=step_s,
            extra_forces=self.forces_on_train(),
            friction_modifiers=self.friction_modifiers,
        )

    def forces_on_train(self) -> list[ExtraForce]:
        """The extra forces, and the wheel brake forces held at any adhesion cap among the
        friction modifiers."""
        if not self.wheel_brake_forces:
            return list(self.extra_forces)
        caps = tuple(m for m in self.friction_modifiers if isinstance(m, AdhesionCap | AdhesionSectionCap))
        if not caps:
            return [*self.extra_forces, *self.wheel_brake_forces]
        n_axles = self.plant.n_axles
        return [*self.extra_forces, *(WheelBrakeForceUnderAdhesion(f, caps, n_axles) for f in self.wheel_brake_forces)]


class Effect:
    """Base of the candidate effects; subclasses set ``id``, ``parameters``, :meth:`apply` and
    :meth:`is_relevant`, and may say more to the diagnosis (the class attributes and methods
    below)."""

    id: ClassVar[str]
    parameters: ClassVar[tuple[ParameterSpec, ...]]
    sensor: ClassVar[bool] = False  # acts on the measurement, not on the physics
    # Effects apply in ascending order; the adhesion limit must see every other friction factor.
    order: ClassVar[int] = 0
    #: the diagnosis screens it on a grid inside its bounds; an effect that acts on part of the
    #: line is screened only where the data locate it (:meth:`screening_points`)
    grid_screened: ClassVar[bool] = True
    #: What would confirm or reject the effect where it acts on too few recordings to judge it held
    #: out: a template of ``{where}`` (those recordings) and the fitted parameters by name.
    confirming_measurement: ClassVar[str] = "more recordings in the conditions of {where}"
    #: What separates the effect from another (by id) that the data fit equally well; each pair is
    #: written on one of its two classes (see :func:`brakegym.effects.separating_measurement`).
    separating_measurements: ClassVar[Mapping[str, str]] = {}
    #: the id of an effect this one holds as a special case (a profile of two sections holds one
    #: section, a section the whole-line gradient): where both are fitted, this one must beat that
    #: one by every rule, as a pair must beat its single; so must a pair with it beat the same pair
    #: with that one
    extends: ClassVar[str | None] = None

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

    # -- what the diagnosis needs to know -------------------------------------------------------
    @classmethod
    def is_relevant(cls, parameters: Mapping[str, float], evidence: Evidence) -> bool:
        """Whether a fitted size matters physically: larger than the base model's own uncertainty
        (what the friction scatter, the running-resistance scatter or a sensor's tolerance could
        explain as well)."""
        raise NotImplementedError

    @classmethod
    def screening_points(cls, evidence: Evidence) -> list[np.ndarray]:
        """Parameter points (values of the non-integer parameters in order) the data point at,
        screened beside the grid for an effect whose chi^2 valley is narrower than a grid step.
        A point may lie outside the bounds (a step along position steeper than any section the
        library allows); the screening puts it inside them (:meth:`inside_bounds`)."""
        return []

    @classmethod
    def inside_bounds(cls, point: np.ndarray) -> np.ndarray:
        """``point`` (values of the non-integer parameters in order) with each value moved to the
        nearer bound where it lies outside its parameter's bounds. A start, not a fit: a fit that
        ends at the end of a search range is not named by the diagnosis."""
        specs = [spec for spec in cls.parameters if not spec.integer]
        return np.array([spec.inside_bounds(value) for spec, value in zip(specs, point, strict=True)])

    @classmethod
    def brake_force_share(cls, parameters: Mapping[str, float], n_discs: int) -> float:
        """The share of the nominal brake force the effect leaves at ``parameters`` (1 for effects
        that do not scale it uniformly)."""
        return 1.0

    @classmethod
    def resistance_shift_N(cls, parameters: Mapping[str, float], nominal: cfg.RunningResistance) -> float:
        """How far the effect at ``parameters`` moves the running resistance from the vehicle's
        ``nominal`` one at a typical speed, N (0 for effects that leave it alone)."""
        return 0.0


def per_train(value: Value, n_trains: int, what: str) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.ndim == 1 and len(array) != n_trains:
        raise ValueError(f"{what}: {len(array)} values for a batch of {n_trains} applications")
    return np.broadcast_to(array, (n_trains,)).copy()
