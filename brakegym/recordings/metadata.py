"""``<stem>.json``, what was measured: its schema, and every problem of a metadata file.

Every invalid field is reported. ``load`` and ``instrumented_disc`` are checked against the
vehicle only when ``vehicle`` is valid, and "exactly one of ``load`` and ``mass_kg``" only when
every field is.
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal, Self

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)

from .. import config as cfg
from .columns import ABSOLUTE_ZERO_C, AMBIENT_RANGE_C
from .problems import RecordingError, RecordingProblem


@lru_cache(maxsize=32)
def _named_vehicle(search_path: tuple[str, ...], name: str) -> cfg.Vehicle:
    # Keyed on the config search path too: a user's folder may hold a vehicle of the same name.
    return cfg.load("vehicles", name)


class _InlineVehicleError(ValueError):
    """An inline vehicle object is invalid; ``items`` are pydantic's errors of it."""

    def __init__(self, items: list[dict[str, Any]]) -> None:
        self.items = items
        problems = "; ".join(_describe_field(f"vehicle.{_location(item)}", item) for item in items)
        super().__init__(f"inline vehicle object is invalid: {problems}")


def _resolve_vehicle(vehicle: str | dict[str, Any]) -> cfg.Vehicle:
    """The vehicle config a metadata ``vehicle`` names or holds; ValueError when there is none."""
    if isinstance(vehicle, str):
        known = cfg.available("vehicles")
        if vehicle not in known:
            raise ValueError(f"unknown vehicle; known: {', '.join(known)}")
        return _named_vehicle(tuple(str(f) for f in cfg.search_path()), vehicle)
    try:
        return cfg.Vehicle.model_validate(vehicle)
    except ValidationError as exc:
        raise _InlineVehicleError(exc.errors()) from None


def _vehicle_validated_before(info: ValidationInfo) -> cfg.Vehicle | None:
    """The vehicle of a metadata being validated, or None when its ``vehicle`` field is invalid."""
    vehicle = info.data.get("vehicle")
    return None if vehicle is None else _resolve_vehicle(vehicle)


#: The steepest gradient a profile may give, permil (the library's gradient effect's bound).
MAX_GRADIENT_PERMIL = 40.0


class SectionProfile(BaseModel):
    """Sections of gradient along a coordinate, section i from ``start_m[i]`` to the next start
    (the last to the end) at ``gradient_permil[i]``; the fields and checks that
    :class:`GradientProfile` and :class:`LineGradientProfile` share."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    start_m: list[float] = Field(min_length=1)
    gradient_permil: list[float] = Field(min_length=1)

    @field_validator("start_m")
    @classmethod
    def _starts_rise(cls, starts: list[float]) -> list[float]:
        if any(not b > a for a, b in zip(starts, starts[1:])) or not all(map(_finite, starts)):
            raise ValueError("section starts must be finite and rise")
        return starts

    @field_validator("gradient_permil")
    @classmethod
    def _gradients_in_range(cls, gradients: list[float]) -> list[float]:
        bad = [g for g in gradients if not (_finite(g) and abs(g) <= MAX_GRADIENT_PERMIL)]
        if bad:
            raise ValueError(f"gradients {bad} lie outside +-{MAX_GRADIENT_PERMIL} permil")
        return gradients

    @model_validator(mode="after")
    def _one_gradient_per_section(self) -> Self:
        if len(self.start_m) != len(self.gradient_permil):
            raise ValueError(
                f"{len(self.start_m)} section starts for {len(self.gradient_permil)} gradients: need one each"
            )
        return self


class GradientProfile(SectionProfile):
    """The line's gradient along a recording, where it is known (docs/recording-format.md): section
    i runs from ``start_m[i]`` metres travelled from the recording's first sample to the next start
    (the last to the end of the run), at ``gradient_permil[i]`` (rise over run x 1000 in the
    direction of travel, + uphill). The replay puts it into the model, so the diagnosis looks only
    for what is not known."""

    @field_validator("start_m")
    @classmethod
    def _starts_from_zero(cls, starts: list[float]) -> list[float]:
        if starts[0] != 0.0:
            raise ValueError("the first section must start at 0 m (the recording's first sample)")
        return starts


class LineGradientProfile(SectionProfile):
    """The line's known gradient in positions along the line (docs/recording-format.md), for
    recordings placed on it (``line_position_m``): section i runs from line position
    ``start_m[i]`` to the next start (the last to the end of the line), at ``gradient_permil[i]``
    (rise over run x 1000 towards growing positions). The first section also holds before its
    start. Each recording runs over its own part of it (:meth:`along_run`)."""

    def along_run(self, line_position_m: float, direction_sign: float) -> GradientProfile:
        """The profile under a run that begins at ``line_position_m`` and runs towards growing
        (``direction_sign`` +1) or falling (-1) positions: sections from its first sample, each
        gradient in its direction of travel (a run back climbs a rise as a fall)."""
        starts = np.asarray(self.start_m, dtype=float)
        gradients = np.asarray(self.gradient_permil, dtype=float)
        if direction_sign > 0:
            # The section under the first sample, then each one whose start lies ahead.
            first = max(int(np.searchsorted(starts, line_position_m, side="right")) - 1, 0)
            ahead = np.arange(first + 1, len(starts))
            run_starts = [0.0, *(starts[ahead] - line_position_m)]
            run_gradients = [gradients[first], *gradients[ahead]]
        else:
            # The section just behind the first sample, then each one whose start the run passes
            # going back (entering the section before it).
            first = max(int(np.searchsorted(starts, line_position_m, side="left")) - 1, 0)
            passed = np.arange(first, 0, -1)
            run_starts = [0.0, *(line_position_m - starts[passed])]
            run_gradients = [-gradients[first], *(-gradients[passed - 1])]
        return GradientProfile(
            start_m=[float(x) for x in run_starts], gradient_permil=[float(g) + 0.0 for g in run_gradients]
        )


def _finite(value: float) -> bool:
    return value == value and abs(value) != float("inf")


class RecordingMetadata(BaseModel):
    """``<stem>.json``: what was measured. Unknown keys are refused (a misspelt
    ``initial_disc_C`` must not silently fall back to the first temperature sample).

    Every invalid field is reported. ``load`` and ``instrumented_disc`` are checked against the
    vehicle only when ``vehicle`` is valid, and "exactly one of ``load`` and ``mass_kg``" only
    when every field is."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    vehicle: str | dict[str, Any]  # a vehicle config name, or an inline vehicle object
    load: str | None = None  # a load of the vehicle, or give mass_kg instead
    mass_kg: float | None = Field(default=None, gt=0)
    brake_mode: Literal["emergency", "service"]
    actuation: str
    instrumented_disc: int | None = None  # 1-based disc index of T_disc_C
    ambient_C: float = Field(ge=AMBIENT_RANGE_C[0], le=AMBIENT_RANGE_C[1])
    initial_disc_C: float | None = Field(default=None, gt=ABSOLUTE_ZERO_C, lt=1000.0)
    decel_source: Literal["accelerometer", "speed"] | None = None
    pad_set: str | None = None
    gradient_profile: GradientProfile | None = None  # the line's known gradient along the run
    #: the line's known gradient in positions along the line; only with ``line_position_m``, and
    #: not with ``gradient_profile``
    line_gradient_profile: LineGradientProfile | None = None
    #: where along the line the first sample was taken, metres, counted in the direction of travel
    #: (docs/recording-format.md): it places the recordings of a set on one line
    line_position_m: float | None = Field(default=None, allow_inf_nan=False)
    #: the way the recording runs along the line, towards growing positions (the default) or
    #: falling ones (a stop on the way back); only with ``line_position_m``
    line_direction: Literal["increasing", "decreasing"] | None = None
    notes: str | None = None

    _vehicle: cfg.Vehicle = PrivateAttr()

    @field_validator("vehicle")
    @classmethod
    def _known_vehicle(cls, vehicle: str | dict[str, Any]) -> str | dict[str, Any]:
        _resolve_vehicle(vehicle)
        return vehicle

    @field_validator("load")
    @classmethod
    def _load_of_the_vehicle(cls, load: str | None, info: ValidationInfo) -> str | None:
        vehicle = _vehicle_validated_before(info)
        if load is not None and vehicle is not None and load not in vehicle.loads:
            raise ValueError(f"unknown load of vehicle {vehicle.name!r}; known: {sorted(vehicle.loads)}")
        return load

    @field_validator("actuation")
    @classmethod
    def _known_actuation(cls, actuation: str) -> str:
        actuations = cfg.available("pneumatics")
        if actuation not in actuations:
            raise ValueError(f"unknown actuation; known: {', '.join(actuations)}")
        return actuation

    @field_validator("instrumented_disc")
    @classmethod
    def _disc_of_the_vehicle(cls, disc: int | None, info: ValidationInfo) -> int | None:
        vehicle = _vehicle_validated_before(info)
        if disc is not None and vehicle is not None and not 1 <= disc <= vehicle.n_discs:
            raise ValueError(f"must lie in 1..{vehicle.n_discs} (the discs of vehicle {vehicle.name!r})")
        return disc

    @model_validator(mode="after")
    def _load_or_mass(self) -> RecordingMetadata:
        if (self.load is None) == (self.mass_kg is None):
            raise ValueError(
                f"give exactly one of 'load' and 'mass_kg' (load = {self.load!r}, mass_kg = {self.mass_kg!r})"
            )
        self._vehicle = _resolve_vehicle(self.vehicle)
        return self

    @model_validator(mode="after")
    def _direction_with_a_position(self) -> RecordingMetadata:
        if self.line_direction is not None and self.line_position_m is None:
            raise ValueError(
                f"'line_direction' = {self.line_direction!r} needs 'line_position_m' (where on the line the "
                "recording begins)"
            )
        return self

    @model_validator(mode="after")
    def _line_profile_on_the_line(self) -> RecordingMetadata:
        if self.line_gradient_profile is not None and self.line_position_m is None:
            raise ValueError("'line_gradient_profile' needs 'line_position_m' (where on the line the recording begins)")
        if self.line_gradient_profile is not None and self.gradient_profile is not None:
            raise ValueError(
                "give the line's known gradient once: 'gradient_profile' (from the recording's first sample) or "
                "'line_gradient_profile' (in positions along the line), not both"
            )
        return self

    @property
    def run_gradient_profile(self) -> GradientProfile | None:
        """The run's known gradient profile counted from its first sample, which is
        ``gradient_profile`` or the run's part of ``line_gradient_profile`` (None where neither is
        given)."""
        if self.line_gradient_profile is None:
            return self.gradient_profile
        return self.line_gradient_profile.along_run(self.line_position_m, self.line_direction_sign)

    @property
    def line_direction_sign(self) -> float:
        """+1 where the recording runs towards growing line positions, -1 where towards falling."""
        return -1.0 if self.line_direction == "decreasing" else 1.0

    def on_line_m(self, odometry_m: np.ndarray) -> np.ndarray:
        """Positions along the line of the points ``odometry_m`` metres travelled from the first
        sample (the odometry itself where the recording is not placed on the line)."""
        return (self.line_position_m or 0.0) + self.line_direction_sign * np.asarray(odometry_m, dtype=float)

    @property
    def vehicle_config(self) -> cfg.Vehicle:
        return self._vehicle

    @property
    def train_mass_kg(self) -> float:
        """The train mass, ``mass_kg`` when given, else the vehicle's mass for ``load``."""
        if self.mass_kg is not None:
            return self.mass_kg
        assert self.load is not None
        return self._vehicle.mass_kg(self.load)


def _location(item: dict[str, Any]) -> str:
    return ".".join(str(part) for part in item["loc"])


def _describe_field(where: str, item: dict[str, Any]) -> str:
    """``field '<where>' = <value>: <what is wrong>`` of one pydantic error."""
    value = "(missing)" if item["type"] == "missing" else repr(item.get("input"))
    cause = item.get("ctx", {}).get("error") if item["type"] == "value_error" else None
    # Our own validators' messages read better without pydantic's "Value error, " prefix.
    return f"field '{where}' = {value}: {cause if cause is not None else item['msg']}"


def _field_problem(file: str, where: str, item: dict[str, Any]) -> RecordingProblem:
    value = None if item["type"] == "missing" else item.get("input")
    return RecordingProblem(file, _describe_field(where, item), field=where, value=value)


def _metadata_problems(file: str, error: ValidationError) -> list[RecordingProblem]:
    """One problem per invalid field (per invalid field of an inline vehicle object)."""
    problems = []
    for item in error.errors():
        where = _location(item)
        cause = item.get("ctx", {}).get("error") if item["type"] == "value_error" else None
        if isinstance(cause, _InlineVehicleError):
            problems += [_field_problem(file, f"{where}.{_location(inner)}", inner) for inner in cause.items]
        elif cause is not None and not where:
            # A check across fields: its message names the fields and values.
            problems.append(RecordingProblem(file, str(cause)))
        else:
            problems.append(_field_problem(file, where or "(top level)", item))
    return problems


def read_metadata_problems(path: Path) -> tuple[RecordingMetadata | None, list[RecordingProblem]]:
    """The metadata of ``path``, or None and every problem found."""
    file = str(path)
    if not path.is_file():
        return None, [RecordingProblem(file, "metadata file missing (every <stem>.csv needs a <stem>.json beside it)")]
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        return None, [RecordingProblem(file, f"cannot read metadata ({exc})")]
    except json.JSONDecodeError as exc:
        return None, [RecordingProblem(file, f"not valid JSON: {exc}", line=exc.lineno)]
    if not isinstance(data, dict):
        return None, [RecordingProblem(file, f"expected a JSON object of fields, got {type(data).__name__}")]
    try:
        return RecordingMetadata.model_validate(data), []
    except ValidationError as exc:
        return None, _metadata_problems(file, exc)
    except cfg.ConfigError as exc:
        return None, [RecordingProblem(file, str(exc))]


def read_metadata(json_path: str | Path) -> RecordingMetadata:
    """Parse and validate ``<stem>.json``; every invalid field is reported in one RecordingError."""
    path = Path(json_path)
    metadata, problems = read_metadata_problems(path)
    if problems:
        raise RecordingError.from_problems(path, problems)
    assert metadata is not None
    return metadata
