"""The recording format (``docs/recording-format.md``): read, validate and write.

A recording is one brake application of one vehicle: ``<stem>.csv`` (the time series) and
``<stem>.json`` (what was measured) in one folder; a data set is a folder of recordings.

A bad recording raises one :class:`RecordingError` that lists every problem found, each as a
:class:`RecordingProblem`: the file, the line (as a user sees it in the CSV: the header is line 1,
the first sample line 2) or column or metadata field, and the value. A rule broken on many lines is
one problem naming the first lines and counting the rest. A folder with bad recordings raises one
:class:`DatasetError` listing every bad recording, or, when asked, goes on with the good ones and
reports the bad ones in :attr:`Dataset.errors`.

Some rules can only be checked once others pass, and are then not reported: a file that cannot be
read or parsed as CSV (not text, malformed quoting) is not checked further; the values of a missing
or duplicated column are not checked; a line with the wrong number of fields is left out of the
value checks; the pressure-column count and the channels' metadata fields (``instrumented_disc``,
``decel_source``) need valid metadata; a metadata field that needs the vehicle (``load``,
``instrumented_disc``) is checked only when ``vehicle`` is valid, and "exactly one of ``load`` and
``mass_kg``" only when every field is.

Nothing is dropped, reordered, clipped or invented: a blank cell is a missing sample (NaN) and
stays one, extra columns are kept as they are.
"""

from __future__ import annotations

import csv
import json
import math
import re
import textwrap
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pandas as pd
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

TIME = "time_s"
SPEED = "speed_mps"
DECEL = "decel_mps2"
DISC_TEMPERATURE = "T_disc_C"
POSITION = "position_m"
PRESSURE_PREFIX = "p_c_bar_"
REQUIRED_COLUMNS = (TIME, SPEED)
OPTIONAL_CHANNELS = (DECEL, DISC_TEMPERATURE, POSITION)
# Gauge pressure range of the format: a brake cylinder never holds more than a few bar, and a
# reading outside 0..10 bar is a sensor or unit fault (psi, kPa), not a pressure.
PRESSURE_RANGE_BAR = (0.0, 10.0)
_PRESSURE_COLUMN = re.compile(re.escape(PRESSURE_PREFIX) + r"(\d+)$")
# Plausible outdoor air for a brake test; outside it the value is a unit mistake (K, F).
AMBIENT_RANGE_C = (-60.0, 60.0)
ABSOLUTE_ZERO_C = -273.15
# A rule broken on many lines names the first line and this many more; the rest are counted.
FURTHER_LINES_SHOWN = 3


def pressure_column(axle: int) -> str:
    """Name of the cylinder-pressure column of 1-based ``axle``."""
    return f"{PRESSURE_PREFIX}{axle}"


# ------------------------------------------------------------------------------------------------
# Problems and errors


@dataclass(frozen=True)
class RecordingProblem:
    """One rule of the format a recording breaks: where, and with what value.

    ``file`` is the file the problem is in (``<stem>.csv`` or ``<stem>.json``; for a recording
    built in code, its name). ``line`` is the line of the file as a user sees it (in the CSV the
    header is line 1) where the rule is first broken, ``column`` the CSV column, ``field`` the metadata field (dotted
    when nested, e.g. ``vehicle.bogies``), ``value`` the offending value as read (a number, the
    cell's text, the metadata value; None where there is none, e.g. a missing column or field);
    each is None where it does not apply. A rule broken on several lines is one problem:
    ``also_lines`` lists the next few of those lines and ``more_lines`` counts the rest.
    ``description`` is what a user reads after the file path, for the first line.
    """

    file: str
    description: str
    line: int | None = None
    column: str | None = None
    field: str | None = None
    value: Any = None
    also_lines: tuple[int, ...] = ()
    more_lines: int = 0

    @property
    def line_count(self) -> int:
        """On how many lines the rule is broken (0 for a problem that is not about lines)."""
        return 0 if self.line is None else 1 + len(self.also_lines) + self.more_lines

    @property
    def detail(self) -> str:
        """The message without the file path: the description, then the further lines."""
        if not self.also_lines:
            return self.description
        lines = ", ".join(str(line) for line in self.also_lines)
        more = f" and {self.more_lines} more" if self.more_lines else ""
        return f"{self.description}; also on line{'s' if self.line_count > 2 else ''} {lines}{more}"

    def __str__(self) -> str:
        return f"{self.file}: {self.detail}"

    def as_dict(self) -> dict[str, Any]:
        """The problem as JSON-ready fields; ``message`` is the text a user reads."""
        return {
            "file": self.file,
            "line": self.line,
            "column": self.column,
            "field": self.field,
            "value": self.value,
            "also_lines": list(self.also_lines),
            "more_lines": self.more_lines,
            "message": str(self),
        }


def _problem_on_lines(file: str, lines: Sequence[int], description: str, **where: Any) -> RecordingProblem:
    """One problem for a rule broken on ``lines`` (CSV lines, in order; at least one):
    ``description`` speaks of the first, the next few are listed and the rest counted."""
    shown = [int(line) for line in lines[: 1 + FURTHER_LINES_SHOWN]]
    return RecordingProblem(
        file, description, line=shown[0], also_lines=tuple(shown[1:]), more_lines=len(lines) - len(shown), **where
    )


class RecordingError(ValueError):
    """A recording is invalid. The message starts with the file and names the line, column or
    field, and the value, of each problem; ``problems`` holds them as :class:`RecordingProblem`
    records (empty for an error raised with a message only), ``file`` the recording's file (its
    ``<stem>.csv``, or the file the problem is in) when known."""

    def __init__(self, message: str, problems: Sequence[RecordingProblem] = (), file: str | None = None) -> None:
        super().__init__(message)
        self.problems = tuple(problems)
        self.file = file

    @classmethod
    def from_problems(cls, file: str | Path, problems: Sequence[RecordingProblem]) -> RecordingError:
        """The error of recording ``file`` with ``problems`` (at least one): one problem is the
        message; several are listed under ``<file>: N problems``, each line without the path when
        it is ``file``'s own."""
        file = str(file)
        if len(problems) == 1:
            return cls(str(problems[0]), problems, file)
        listed = [problem.detail if problem.file == file else str(problem) for problem in problems]
        message = f"{file}: {len(problems)} problems\n" + "\n".join(f"  {line}" for line in listed)
        return cls(message, problems, file)

    def as_dict(self) -> dict[str, Any]:
        """``{"file": ..., "problems": [...]}`` for JSON output; an error raised with a message
        only gives one problem holding that message."""
        problems = self.problems or (RecordingProblem(self.file or "", str(self)),)
        return {"file": self.file, "problems": [problem.as_dict() for problem in problems]}

    def __reduce__(self):
        return (type(self), (str(self), self.problems, self.file))


class DatasetError(RecordingError):
    """Recordings of a folder are bad. ``errors`` holds one :class:`RecordingError` per bad
    recording, in stem order; ``n_recordings`` counts the folder's recordings, good and bad;
    ``problems`` holds every problem of every bad recording. ``note`` (e.g. how to go on without
    the bad ones) ends the message."""

    def __init__(
        self, folder: str | Path, errors: Sequence[RecordingError], n_recordings: int, note: str | None = None
    ) -> None:
        self.folder = Path(folder)
        self.errors = list(errors)
        self.n_recordings = n_recordings
        self.note = note
        if self.n_good == 0:
            head = f"{folder}: none of the {n_recordings} recordings could be read"
        else:
            head = f"{folder}: {len(self.errors)} of the {n_recordings} recordings are bad"
        body = "\n".join(textwrap.indent(str(error), "  ") for error in self.errors)
        problems = [problem for error in self.errors for problem in error.problems]
        super().__init__(f"{head}:\n{body}" + (f"\n{note}" if note else ""), problems, str(folder))

    @property
    def n_good(self) -> int:
        """How many of the folder's recordings are good."""
        return self.n_recordings - len(self.errors)

    def __reduce__(self):
        return (type(self), (self.folder, self.errors, self.n_recordings, self.note))


def _refuse(file: str | Path, description: str) -> RecordingError:
    """The error of a recording that cannot be checked further, with its one problem."""
    return RecordingError.from_problems(file, [RecordingProblem(str(file), description)])


# ------------------------------------------------------------------------------------------------
# Metadata


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

    @property
    def vehicle_config(self) -> cfg.Vehicle:
        return self._vehicle

    @property
    def train_mass_kg(self) -> float:
        """The train mass: ``mass_kg`` when given, else the vehicle's mass for ``load``."""
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


def _read_metadata(path: Path) -> tuple[RecordingMetadata | None, list[RecordingProblem]]:
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
    metadata, problems = _read_metadata(path)
    if problems:
        raise RecordingError.from_problems(path, problems)
    assert metadata is not None
    return metadata


# ------------------------------------------------------------------------------------------------
# The recording
def _read_only(values: np.ndarray) -> np.ndarray:
    values = values.copy(order="K") if values.base is not None or not values.flags.owndata else values
    values.flags.writeable = False
    return values


@dataclass(frozen=True, eq=False)
class Recording:
    """One brake application: the samples (a DataFrame, one column per CSV column, in file order)
    and the validated metadata. Constructing one validates it, so a Recording is always valid.

    Known channels are float64 with NaN for missing samples; extra columns are float64 when every
    filled cell is a number, else kept as the text that was read. The samples are read-only: the
    arrays of :meth:`channel` and the properties are taken from the DataFrame once (a fit replays
    a recording thousands of times) and cannot be written to; build a new Recording to change one.
    """

    stem: str
    metadata: RecordingMetadata
    data: pd.DataFrame
    source: Path | None = None  # the CSV file it was read from, if any
    line_numbers: np.ndarray | None = field(default=None, repr=False)  # CSV line of each sample

    def __post_init__(self) -> None:
        problems = _sample_problems(self.name, self.data, self.metadata, self.csv_lines)
        if problems:
            raise RecordingError.from_problems(self.name, problems)

    # -- identification ---------------------------------------------------------------------
    @property
    def name(self) -> str:
        """How messages refer to this recording: its CSV file, else its stem."""
        return str(self.source) if self.source is not None else f"recording {self.stem!r}"

    @property
    def csv_lines(self) -> np.ndarray:
        """The CSV line of each sample: as read, else as :func:`write_recording` would write it."""
        if self.line_numbers is not None:
            return np.asarray(self.line_numbers)
        return np.arange(len(self.data)) + 2  # the header is line 1

    def line_of(self, row: int) -> int:
        """The CSV line of sample ``row`` (0-based)."""
        return int(self.csv_lines[row])

    # -- what was braked ----------------------------------------------------------------------
    @property
    def vehicle(self) -> cfg.Vehicle:
        return self.metadata.vehicle_config

    @property
    def mass_kg(self) -> float:
        return self.metadata.train_mass_kg

    # -- samples ------------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.data)

    @property
    def time_s(self) -> np.ndarray:
        return self.channel(TIME)

    @property
    def speed_mps(self) -> np.ndarray:
        return self.channel(SPEED)

    @property
    def pressure_columns(self) -> list[str]:
        return [pressure_column(axle) for axle in range(1, self.vehicle.n_axles + 1)]

    @cached_property
    def pressures_bar(self) -> np.ndarray:
        """Cylinder pressures (samples, axles), NaN where missing (read-only)."""
        return _read_only(self.data[self.pressure_columns].to_numpy(dtype=float))

    def channel(self, name: str) -> np.ndarray | None:
        """A column as floats (read-only), or None when the recording does not have it."""
        if name not in self._columns:
            present = name in self.data.columns
            self._columns[name] = _read_only(self.data[name].to_numpy(dtype=float)) if present else None
        return self._columns[name]

    @cached_property
    def _columns(self) -> dict[str, np.ndarray | None]:
        return {}

    @property
    def initial_disc_C(self) -> float | None:
        """``initial_disc_C`` of the metadata, else the first temperature sample, else None."""
        if self.metadata.initial_disc_C is not None:
            return self.metadata.initial_disc_C
        temperature = self.channel(DISC_TEMPERATURE)
        if temperature is None or math.isnan(temperature[0]):
            return None
        return float(temperature[0])




# ------------------------------------------------------------------------------------------------
# The rules on the samples


def _header_problems(file: str, header: list[str], vehicle: cfg.Vehicle | None) -> list[RecordingProblem]:
    """No duplicate columns, the required columns, and (when the vehicle is known) exactly one
    pressure column per axle."""
    problems = []
    duplicates = sorted({c for c in header if header.count(c) > 1})
    if duplicates:
        problems.append(RecordingProblem(file, f"column(s) {duplicates} appear more than once in the header"))
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        problems.append(RecordingProblem(file, f"missing required column(s) {missing}; the header has {header}"))
    if vehicle is not None:
        numbered = [(int(match.group(1)), c) for c in header if (match := _PRESSURE_COLUMN.match(c))]
        found = [c for _, c in sorted(numbered)]
        expected = [pressure_column(axle) for axle in range(1, vehicle.n_axles + 1)]
        if found != expected:
            problems.append(
                RecordingProblem(
                    file,
                    f"pressure columns {found} do not match vehicle {vehicle.name!r} with {vehicle.n_axles} "
                    f"axles: expected exactly {expected[0]} .. {expected[-1]}",
                )
            )
    return problems


# Cells of a column that could not be read as numbers: their rows (0-based) and their text.
_UnparsedCells = dict[str, tuple[np.ndarray, list[str]]]


class _ValueRules:
    """The rules on the values of one recording's channels; ``problems`` collects each one broken.

    Only the channels (time, speed, pressures, the optional channels) are checked, each when it is
    present once in the header and holds floats. A cell already reported as not a number is a
    blank (NaN) for the other rules, so one bad cell is reported once.
    """

    def __init__(
        self, file: str, data: pd.DataFrame, header: list[str], lines: np.ndarray, unparsed: _UnparsedCells
    ) -> None:
        self.file = file
        self.lines = lines
        self.problems: list[RecordingProblem] = []
        self.values: dict[str, np.ndarray] = {}
        self.reported: dict[str, np.ndarray] = {}
        self.pressure_columns = [c for c in header if _PRESSURE_COLUMN.match(c)]
        for column in (*REQUIRED_COLUMNS, *self.pressure_columns, *OPTIONAL_CHANNELS):
            if column in data.columns and header.count(column) == 1:
                self._take_numbers(column, data[column], unparsed.get(column))

    def check(self) -> list[RecordingProblem]:
        self._time()
        self._below(SPEED, 0.0, "speed must not be negative")
        self._pressures()
        self._below(DISC_TEMPERATURE, ABSOLUTE_ZERO_C, "below absolute zero", inclusive=True)
        return self.problems

    def _on_rows(self, rows: np.ndarray, column: str, description: str, value: Any = None) -> None:
        self.problems.append(_problem_on_lines(self.file, self.lines[rows], description, column=column, value=value))

    def _line(self, row: int) -> int:
        return int(self.lines[row])

    def _take_numbers(self, column: str, series: pd.Series, unparsed: tuple[np.ndarray, list[str]] | None) -> None:
        if not pd.api.types.is_float_dtype(series.dtype):
            description = f"column {column!r} must hold numbers (dtype {series.dtype})"
            self.problems.append(RecordingProblem(self.file, description, column=column))
            return
        values = series.to_numpy(dtype=float)
        reported = np.zeros(len(values), dtype=bool)
        if unparsed is not None:
            rows, cells = unparsed
            description = f"line {self._line(rows[0])}, column {column!r}: {cells[0]!r} is not a finite number"
            self._on_rows(rows, column, description, cells[0])
            reported[rows] = True
        infinite = np.flatnonzero(np.isinf(values))
        if infinite.size:
            first = float(values[infinite[0]])
            description = f"line {self._line(infinite[0])}, column {column!r}: {first} is not finite"
            self._on_rows(infinite, column, description, first)
            reported[infinite] = True
            values = np.where(reported, np.nan, values)
        self.values[column] = values
        self.reported[column] = reported

    def _time(self) -> None:
        time = self.values.get(TIME)
        if time is None:
            return
        blank = np.flatnonzero(np.isnan(time) & ~self.reported[TIME])
        if blank.size:
            description = f"line {self._line(blank[0])}, column {TIME!r} is blank: every sample needs its time"
            self._on_rows(blank, TIME, description)
        present = np.flatnonzero(~np.isnan(time))
        back = np.flatnonzero(np.diff(time[present]) <= 0)  # among the samples that have a time
        if back.size:
            row, before = present[back[0] + 1], present[back[0]]
            value = float(time[row])
            self._on_rows(
                present[back + 1],
                TIME,
                f"line {self._line(row)}, column {TIME!r} = {value!r}: time must be strictly increasing "
                f"(line {self._line(before)} has {float(time[before])!r})",
                value,
            )

    def _below(self, column: str, limit: float, rule: str, inclusive: bool = False) -> None:
        values = self.values.get(column)
        if values is None:
            return
        bad = np.flatnonzero(values <= limit if inclusive else values < limit)
        if bad.size:
            value = float(values[bad[0]])
            self._on_rows(bad, column, f"line {self._line(bad[0])}, column {column!r} = {value!r}: {rule}", value)

    def _pressures(self) -> None:
        low, high = PRESSURE_RANGE_BAR
        for column in self.pressure_columns:
            values = self.values.get(column)
            if values is None:
                continue
            bad = np.flatnonzero((values < low) | (values > high))
            if bad.size:
                value = float(values[bad[0]])
                where = f"line {self._line(bad[0])}, column {column!r} = {value!r}"
                self._on_rows(bad, column, f"{where}: pressure outside {low:g}..{high:g} bar", value)
            if values.size and np.all(np.isnan(values)) and not self.reported[column].any():
                description = f"column {column!r} has no sample at all"
                self.problems.append(RecordingProblem(self.file, description, column=column))


def _channel_metadata_problems(file: str, header: list[str], metadata: RecordingMetadata) -> list[RecordingProblem]:
    """A channel that needs a metadata field has it."""
    problems = []
    if DISC_TEMPERATURE in header and metadata.instrumented_disc is None:
        problems.append(
            RecordingProblem(
                file, f"has a {DISC_TEMPERATURE!r} column but its metadata names no 'instrumented_disc'",
                column=DISC_TEMPERATURE, field="instrumented_disc",
            )
        )
    if DECEL in header and metadata.decel_source is None:
        problems.append(
            RecordingProblem(
                file, f"has a {DECEL!r} column but its metadata gives no 'decel_source'",
                column=DECEL, field="decel_source",
            )
        )
    return problems


def _sample_problems(
    file: str,
    data: pd.DataFrame,
    metadata: RecordingMetadata | None,
    lines: np.ndarray,
    header: list[str] | None = None,
    unparsed: _UnparsedCells | None = None,
) -> list[RecordingProblem]:
    """Every rule of the spec the samples break. ``lines`` are the CSV lines of the rows;
    ``header`` the columns as read (default: the frame's); ``unparsed`` the cells that were not
    numbers (NaN in ``data``). Without ``metadata`` (invalid), the rules that need it are left out."""
    header = list(data.columns) if header is None else header
    problems = _header_problems(file, header, None if metadata is None else metadata.vehicle_config)
    if len(data) < 2:
        problems.append(RecordingProblem(file, f"{len(data)} sample(s); a recording needs at least 2"))
    problems += _ValueRules(file, data, header, lines, unparsed or {}).check()
    if metadata is not None:
        problems += _channel_metadata_problems(file, header, metadata)
    return problems


# ------------------------------------------------------------------------------------------------
# Reading


def _parse_number(cell: str) -> float:
    """A cell as a float; NaN for a blank cell. Raises ValueError for anything else that is not
    a finite number ('nan' or 'inf' written out are refused: a missing sample is a blank cell)."""
    if cell.strip() == "":
        return math.nan
    value = float(cell)
    if not math.isfinite(value):
        raise ValueError("not finite")
    return value


@dataclass
class _Cells:
    header: list[str]
    rows: list[list[str]]
    lines: list[int]  # the CSV line of each row


def _read_cells(path: Path) -> tuple[_Cells | None, list[RecordingProblem]]:
    """The header and rows of ``path`` with their lines, and the problems of its layout: lines
    with another number of fields than the header (left out of the rows) and empty lines between
    samples. None for the cells when the file cannot be read as CSV at all."""
    file = str(path)
    try:
        handle = path.open(newline="")
    except OSError as exc:
        return None, [RecordingProblem(file, f"cannot read ({exc.strerror})")]
    cells = _Cells([], [], [])
    other_width: list[tuple[int, int]] = []  # (line, number of fields)
    empty_inside: list[int] = []  # first line of each run of empty lines followed by samples
    with handle:
        reader = csv.reader(handle)
        try:
            header = next(reader, None)
            if header is None:
                return None, [RecordingProblem(file, "empty file (expected a header line)")]
            cells.header = header
            empty_line: int | None = None
            for row in reader:
                if not row:
                    # An empty line ends nothing: only trailing empty lines are harmless.
                    empty_line = empty_line or reader.line_num
                    continue
                if empty_line is not None:
                    empty_inside.append(empty_line)
                    empty_line = None
                if len(row) != len(header):
                    other_width.append((reader.line_num, len(row)))
                    continue
                cells.rows.append(row)
                cells.lines.append(reader.line_num)
        except csv.Error as exc:
            line = reader.line_num
            return None, [RecordingProblem(file, f"line {line}: malformed CSV ({exc})", line=line)]
        except UnicodeDecodeError as exc:
            return None, [RecordingProblem(file, f"not a text file ({exc})")]
    problems = []
    if empty_inside:
        problems.append(_problem_on_lines(file, empty_inside, f"line {empty_inside[0]} is empty between samples"))
    if other_width:
        line, width = other_width[0]
        description = f"line {line} has {width} fields, the header has {len(header)}"
        problems.append(_problem_on_lines(file, [line for line, _ in other_width], description, value=width))
    return cells, problems


def _build_frame(cells: _Cells, numeric: set[str]) -> tuple[pd.DataFrame, _UnparsedCells]:
    """The rows as a DataFrame (a duplicated column once, its first occurrence), and the cells of
    the ``numeric`` columns that are not numbers (NaN in the frame)."""
    columns: dict[str, Any] = {}
    unparsed: _UnparsedCells = {}
    for index, name in enumerate(cells.header):
        if name in columns:
            continue
        texts = [row[index] for row in cells.rows]
        if name in numeric:
            values = np.empty(len(texts))
            bad_rows, bad_texts = [], []
            for i, text in enumerate(texts):
                try:
                    values[i] = _parse_number(text)
                except ValueError:
                    values[i] = math.nan
                    bad_rows.append(i)
                    bad_texts.append(text)
            if bad_rows:
                unparsed[name] = (np.asarray(bad_rows), bad_texts)
            columns[name] = values
        else:
            # Extra column: numbers when every filled cell is one, else the text as read.
            try:
                columns[name] = np.array([_parse_number(text) for text in texts], dtype=float)
            except ValueError:
                columns[name] = pd.array(texts, dtype=object)
    return pd.DataFrame(columns), unparsed


def read_recording(csv_path: str | Path) -> Recording:
    """Read and validate ``<stem>.csv`` and the ``<stem>.json`` beside it.

    Every problem found in either file is reported in one :class:`RecordingError` (the module
    documentation says which rules wait for others to pass)."""
    path = Path(csv_path)
    if path.suffix != ".csv":
        raise _refuse(path, "a recording's time series is a .csv file")
    if not path.is_file():
        raise _refuse(path, "no such file")
    file = str(path)
    metadata, metadata_problems = _read_metadata(path.with_suffix(".json"))
    cells, problems = _read_cells(path)
    if cells is not None:
        numeric = {*REQUIRED_COLUMNS, *OPTIONAL_CHANNELS, *(c for c in cells.header if _PRESSURE_COLUMN.match(c))}
        frame, unparsed = _build_frame(cells, numeric)
        lines = np.asarray(cells.lines, dtype=int)
        problems += _sample_problems(file, frame, metadata, lines, cells.header, unparsed)
    problems += metadata_problems
    if problems:
        raise RecordingError.from_problems(file, problems)
    assert cells is not None and metadata is not None
    return Recording(stem=path.stem, metadata=metadata, data=frame, source=path, line_numbers=lines)


@dataclass
class Dataset:
    """The recordings of a folder that could be read, and an error for each one that could not
    (each with its ``problems``; ``as_dict()`` gives it for JSON output)."""

    folder: Path
    recordings: list[Recording]
    errors: list[RecordingError]

    def __iter__(self) -> Iterator[Recording]:
        return iter(self.recordings)

    def __len__(self) -> int:
        return len(self.recordings)


def _read_stem(folder: Path, stem: str) -> Recording:
    csv_path = folder / f"{stem}.csv"
    if not csv_path.is_file():
        raise _refuse(folder / f"{stem}.json", f"metadata without its time series {csv_path.name}")
    return read_recording(csv_path)


def read_dataset(folder: str | Path, skip_bad: bool = False) -> Dataset:
    """Read every recording (``<stem>.csv`` + ``<stem>.json``) of ``folder``, in stem order.

    Every recording is read and every bad one reported: without ``skip_bad`` any bad recording
    raises one :class:`DatasetError` listing them all, each with its problems; with it, the bad
    ones are reported in ``Dataset.errors`` and the good ones returned. A folder without a good
    recording raises in both modes. Every ``.csv`` and ``.json`` file is part of a recording (a
    ``.json`` without its ``.csv`` is a bad one); other files are not recordings and are ignored.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise RecordingError(f"{folder}: not a folder of recordings", file=str(folder))
    stems = sorted({p.stem for p in folder.iterdir() if p.suffix in (".csv", ".json") and p.is_file()})
    if not stems:
        raise RecordingError(f"{folder}: no recordings (no <stem>.csv / <stem>.json files)", file=str(folder))
    recordings: list[Recording] = []
    errors: list[RecordingError] = []
    for stem in stems:
        try:
            recordings.append(_read_stem(folder, stem))
        except RecordingError as exc:
            errors.append(exc)
    if errors and not (skip_bad and recordings):
        raise DatasetError(folder, errors, len(stems))
    return Dataset(folder=folder, recordings=recordings, errors=errors)


# ------------------------------------------------------------------------------------------------
# Writing


def _cell(value: Any) -> str:
    if isinstance(value, (float, np.floating)):
        # repr of a Python float is the shortest text that parses back to the same bits.
        return "" if math.isnan(value) else repr(float(value))
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    return "" if value is None else str(value)


def metadata_to_dict(metadata: RecordingMetadata) -> dict[str, Any]:
    return metadata.model_dump(mode="json", exclude_none=True)


def write_recording(recording: Recording, folder: str | Path, stem: str | None = None) -> tuple[Path, Path]:
    """Write ``<stem>.csv`` and ``<stem>.json`` into ``folder`` (created if needed); reading them
    back gives the same samples bit for bit and the same metadata. Returns both paths."""
    folder = Path(folder)
    stem = stem or recording.stem
    if not stem or "/" in stem or stem.startswith("."):
        raise RecordingError(f"invalid recording stem {stem!r}")
    folder.mkdir(parents=True, exist_ok=True)
    csv_path, json_path = folder / f"{stem}.csv", folder / f"{stem}.json"
    columns = list(recording.data.columns)
    column_values = [recording.data[c].tolist() for c in columns]
    with csv_path.open("w", newline="") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(columns)
        for row in zip(*column_values, strict=True):
            writer.writerow([_cell(v) for v in row])
    json_path.write_text(json.dumps(metadata_to_dict(recording.metadata), indent=2) + "\n")
    return csv_path, json_path
