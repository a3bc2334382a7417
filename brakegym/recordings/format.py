"""The recording format (``docs/recording-format.md``): read, validate and write.

A recording is one brake application of one vehicle: ``<stem>.csv`` (the time series) and
``<stem>.json`` (what was measured) in one folder; a data set is a folder of recordings.

Every problem raises :class:`RecordingError`, whose message names the file, the line (as a user
sees it in the CSV: the header is line 1, the first sample line 2) or column, and the value.
Nothing is dropped, reordered, clipped or invented: a blank cell is a missing sample (NaN) and
stays one, extra columns are kept as they are.
"""

from __future__ import annotations

import csv
import json
import math
import re
from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from pathlib import Path
from typing import Any, Iterator, Literal

import numpy as np
import pandas as pd
from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, model_validator

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


class RecordingError(ValueError):
    """A recording is invalid; the message names file, line or column, and value."""


def pressure_column(axle: int) -> str:
    """Name of the cylinder-pressure column of 1-based ``axle``."""
    return f"{PRESSURE_PREFIX}{axle}"


# ------------------------------------------------------------------------------------------------
# Metadata


@lru_cache(maxsize=32)
def _named_vehicle(search_path: tuple[str, ...], name: str) -> cfg.Vehicle:
    # Keyed on the config search path too: a user's folder may hold a vehicle of the same name.
    return cfg.load("vehicles", name)


class RecordingMetadata(BaseModel):
    """``<stem>.json``: what was measured. Unknown keys are refused (a misspelt
    ``initial_disc_C`` must not silently fall back to the first temperature sample)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    vehicle: str | dict[str, Any]  # a vehicle config name, or an inline vehicle object
    load: str | None = None  # a load of the vehicle, or give mass_kg instead
    mass_kg: float | None = Field(default=None, gt=0)
    brake_mode: Literal["emergency", "service"]
    actuation: str
    instrumented_disc: int | None = None  # 1-based disc index of T_disc_C
    ambient_C: float = Field(ge=AMBIENT_RANGE_C[0], le=AMBIENT_RANGE_C[1])
    initial_disc_C: float | None = Field(default=None, gt=-273.15, lt=1000.0)
    decel_source: Literal["accelerometer", "speed"] | None = None
    pad_set: str | None = None
    notes: str | None = None

    _vehicle: cfg.Vehicle = PrivateAttr()

    @model_validator(mode="after")
    def _consistent_with_vehicle(self) -> "RecordingMetadata":
        if isinstance(self.vehicle, str):
            known = cfg.available("vehicles")
            if self.vehicle not in known:
                raise ValueError(f"field 'vehicle' = {self.vehicle!r}: unknown vehicle; known: {', '.join(known)}")
            vehicle = _named_vehicle(tuple(str(f) for f in cfg.search_path()), self.vehicle)
        else:
            try:
                vehicle = cfg.Vehicle.model_validate(self.vehicle)
            except ValidationError as exc:
                problems = "; ".join(
                    f"field 'vehicle.{'.'.join(str(p) for p in item['loc'])}' = "
                    f"{'(missing)' if item['type'] == 'missing' else repr(item.get('input'))}: {item['msg']}"
                    for item in exc.errors()
                )
                raise ValueError(f"inline vehicle object is invalid: {problems}") from None
        if (self.load is None) == (self.mass_kg is None):
            raise ValueError(
                f"give exactly one of 'load' and 'mass_kg' (load = {self.load!r}, mass_kg = {self.mass_kg!r})"
            )
        if self.load is not None and self.load not in vehicle.loads:
            raise ValueError(
                f"field 'load' = {self.load!r}: unknown load of vehicle {vehicle.name!r}; known: {sorted(vehicle.loads)}"
            )
        actuations = cfg.available("pneumatics")
        if self.actuation not in actuations:
            raise ValueError(f"field 'actuation' = {self.actuation!r}: unknown actuation; known: {', '.join(actuations)}")
        if self.instrumented_disc is not None and not 1 <= self.instrumented_disc <= vehicle.n_discs:
            raise ValueError(
                f"field 'instrumented_disc' = {self.instrumented_disc}: must lie in 1..{vehicle.n_discs} "
                f"(the discs of vehicle {vehicle.name!r})"
            )
        self._vehicle = vehicle
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


def _describe_metadata_error(path: str, error: ValidationError) -> str:
    lines = [f"{path}: invalid recording metadata"]
    for item in error.errors():
        where = ".".join(str(part) for part in item["loc"])
        if item["type"] == "value_error" and not where:
            # Our own cross-field checks already name the field and value.
            lines.append(f"  {item['ctx']['error']}")
            continue
        value = "(missing)" if item["type"] == "missing" else repr(item.get("input"))
        lines.append(f"  field '{where or '(top level)'}' = {value}: {item['msg']}")
    return "\n".join(lines)


def read_metadata(json_path: str | Path) -> RecordingMetadata:
    """Parse and validate ``<stem>.json``."""
    path = Path(json_path)
    if not path.is_file():
        raise RecordingError(f"{path}: metadata file missing (every <stem>.csv needs a <stem>.json beside it)")
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(f"{path}: cannot read metadata ({exc})") from exc
    except json.JSONDecodeError as exc:
        raise RecordingError(f"{path}: not valid JSON: {exc}") from exc
    if not isinstance(data, dict):
        raise RecordingError(f"{path}: expected a JSON object of fields, got {type(data).__name__}")
    try:
        return RecordingMetadata.model_validate(data)
    except ValidationError as exc:
        raise RecordingError(_describe_metadata_error(str(path), exc)) from None
    except cfg.ConfigError as exc:
        raise RecordingError(f"{path}: {exc}") from exc


# ------------------------------------------------------------------------------------------------
# The recording


def _read_only(values: np.ndarray) -> np.ndarray:
    values = values.copy(order="K") if values.base is not None or not values.flags.owndata else values
    values.flags.writeable = False
    return values


def _line(row: int) -> int:
    """The CSV line a user sees for sample ``row`` (0-based): the header is line 1."""
    return row + 2


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
        _validate_samples(self)

    # -- identification ---------------------------------------------------------------------
    @property
    def name(self) -> str:
        """How messages refer to this recording: its CSV file, else its stem."""
        return str(self.source) if self.source is not None else f"recording {self.stem!r}"

    def line_of(self, row: int) -> int:
        if self.line_numbers is not None:
            return int(self.line_numbers[row])
        return _line(row)

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
            self._columns[name] = _read_only(self.data[name].to_numpy(dtype=float)) if name in self.data.columns else None
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


def _check_header(name: str, columns: list[str], vehicle: cfg.Vehicle) -> None:
    """Column rules: no duplicates, the required columns, one pressure column per axle."""
    duplicates = sorted({c for c in columns if columns.count(c) > 1})
    if duplicates:
        raise RecordingError(f"{name}: column(s) {duplicates} appear more than once in the header")
    missing = [c for c in REQUIRED_COLUMNS if c not in columns]
    if missing:
        raise RecordingError(f"{name}: missing required column(s) {missing}; the header has {columns}")
    numbered = [(int(match.group(1)), c) for c in columns if (match := _PRESSURE_COLUMN.match(c))]
    found = [c for _, c in sorted(numbered)]
    expected = [pressure_column(axle) for axle in range(1, vehicle.n_axles + 1)]
    if found != expected:
        raise RecordingError(
            f"{name}: pressure columns {found} do not match vehicle {vehicle.name!r} with {vehicle.n_axles} "
            f"axles: expected exactly {expected[0]} .. {expected[-1]}"
        )


def _validate_samples(recording: Recording) -> None:
    """Rules of the spec on a parsed recording; the first violation raises."""
    name, data, meta = recording.name, recording.data, recording.metadata
    columns = list(data.columns)
    _check_header(name, columns, recording.vehicle)
    expected = recording.pressure_columns
    if len(data) < 2:
        raise RecordingError(f"{name}: {len(data)} sample(s); a recording needs at least 2")
    for column in (*REQUIRED_COLUMNS, *expected, *[c for c in OPTIONAL_CHANNELS if c in columns]):
        if not pd.api.types.is_float_dtype(data[column].dtype):
            raise RecordingError(f"{name}: column {column!r} must hold numbers (dtype {data[column].dtype})")
        values = data[column].to_numpy()
        bad = np.flatnonzero(np.isinf(values))
        if bad.size:
            row = int(bad[0])
            raise RecordingError(f"{name}: line {recording.line_of(row)}, column {column!r}: {float(values[row])} is not finite")

    time = data[TIME].to_numpy()
    blank = np.flatnonzero(np.isnan(time))
    if blank.size:
        raise RecordingError(
            f"{name}: line {recording.line_of(int(blank[0]))}, column {TIME!r} is blank: every sample needs its time"
        )
    steps = np.diff(time)
    bad = np.flatnonzero(steps <= 0)
    if bad.size:
        row = int(bad[0]) + 1
        raise RecordingError(
            f"{name}: line {recording.line_of(row)}, column {TIME!r} = {float(time[row])!r}: time must be strictly "
            f"increasing (line {recording.line_of(row - 1)} has {float(time[row - 1])!r})"
        )
    speed = data[SPEED].to_numpy()
    bad = np.flatnonzero(speed < 0)
    if bad.size:
        row = int(bad[0])
        raise RecordingError(f"{name}: line {recording.line_of(row)}, column {SPEED!r} = {float(speed[row])!r}: speed must not be negative")
    low, high = PRESSURE_RANGE_BAR
    for column in expected:
        values = data[column].to_numpy()
        bad = np.flatnonzero((values < low) | (values > high))
        if bad.size:
            row = int(bad[0])
            raise RecordingError(
                f"{name}: line {recording.line_of(row)}, column {column!r} = {float(values[row])!r}: pressure outside "
                f"{low:g}..{high:g} bar"
            )
        if np.all(np.isnan(values)):
            raise RecordingError(f"{name}: column {column!r} has no sample at all")
    if DISC_TEMPERATURE in columns:
        values = data[DISC_TEMPERATURE].to_numpy()
        bad = np.flatnonzero(values <= -273.15)
        if bad.size:
            row = int(bad[0])
            raise RecordingError(
                f"{name}: line {recording.line_of(row)}, column {DISC_TEMPERATURE!r} = {float(values[row])!r}: below absolute zero"
            )
        if meta.instrumented_disc is None:
            raise RecordingError(f"{name}: has a {DISC_TEMPERATURE!r} column but its metadata names no 'instrumented_disc'")
    if DECEL in columns and meta.decel_source is None:
        raise RecordingError(f"{name}: has a {DECEL!r} column but its metadata gives no 'decel_source'")


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


def _read_cells(path: Path) -> tuple[list[str], list[list[str]], list[int]]:
    try:
        handle = path.open(newline="")
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read ({exc.strerror})") from exc
    rows: list[list[str]] = []
    lines: list[int] = []
    with handle:
        reader = csv.reader(handle)
        try:
            header = next(reader, None)
            if header is None:
                raise RecordingError(f"{path}: empty file (expected a header line)")
            empty_line: int | None = None
            for row in reader:
                if not row:
                    # An empty line ends nothing: only trailing empty lines are harmless.
                    empty_line = empty_line or reader.line_num
                    continue
                if empty_line is not None:
                    raise RecordingError(f"{path}: line {empty_line} is empty between samples")
                if len(row) != len(header):
                    raise RecordingError(
                        f"{path}: line {reader.line_num} has {len(row)} fields, the header has {len(header)}"
                    )
                rows.append(row)
                lines.append(reader.line_num)
        except csv.Error as exc:
            raise RecordingError(f"{path}: line {reader.line_num}: malformed CSV ({exc})") from exc
        except UnicodeDecodeError as exc:
            raise RecordingError(f"{path}: not a text file ({exc})") from exc
    return header, rows, lines


def _build_frame(path: Path, header: list[str], rows: list[list[str]], lines: list[int], numeric: set[str]) -> pd.DataFrame:
    columns: dict[str, Any] = {}
    for index, name in enumerate(header):
        cells = [row[index] for row in rows]
        if name in numeric:
            values = np.empty(len(cells))
            for i, cell in enumerate(cells):
                try:
                    values[i] = _parse_number(cell)
                except ValueError:
                    raise RecordingError(f"{path}: line {lines[i]}, column {name!r}: {cell!r} is not a finite number") from None
            columns[name] = values
        else:
            # Extra column: numbers when every filled cell is one, else the text as read.
            try:
                columns[name] = np.array([_parse_number(cell) for cell in cells], dtype=float)
            except ValueError:
                columns[name] = pd.array(cells, dtype=object)
    return pd.DataFrame(columns, columns=header)


def read_recording(csv_path: str | Path) -> Recording:
    """Read and validate ``<stem>.csv`` and the ``<stem>.json`` beside it."""
    path = Path(csv_path)
    if path.suffix != ".csv":
        raise RecordingError(f"{path}: a recording's time series is a .csv file")
    if not path.is_file():
        raise RecordingError(f"{path}: no such file")
    metadata = read_metadata(path.with_suffix(".json"))
    header, rows, lines = _read_cells(path)
    vehicle = metadata.vehicle_config
    _check_header(str(path), header, vehicle)
    numeric = {*REQUIRED_COLUMNS, *OPTIONAL_CHANNELS, *(pressure_column(a) for a in range(1, vehicle.n_axles + 1))}
    numeric |= {c for c in header if _PRESSURE_COLUMN.match(c)}
    frame = _build_frame(path, header, rows, lines, numeric)
    return Recording(stem=path.stem, metadata=metadata, data=frame, source=path, line_numbers=np.asarray(lines))


@dataclass
class Dataset:
    """The recordings of a folder that could be read, and an error for each one that could not."""

    folder: Path
    recordings: list[Recording]
    errors: list[RecordingError]

    def __iter__(self) -> Iterator[Recording]:
        return iter(self.recordings)

    def __len__(self) -> int:
        return len(self.recordings)


def read_dataset(folder: str | Path, skip_bad: bool = False) -> Dataset:
    """Read every recording (``<stem>.csv`` + ``<stem>.json``) of ``folder``, in stem order.

    Without ``skip_bad`` the first bad recording raises its :class:`RecordingError`; with it, the
    bad ones are reported in ``Dataset.errors`` and the good ones returned. Other files are not
    recordings and are ignored; a ``.json`` without its ``.csv`` is a bad recording.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise RecordingError(f"{folder}: not a folder of recordings")
    stems = sorted({p.stem for p in folder.iterdir() if p.suffix in (".csv", ".json") and p.is_file()})
    if not stems:
        raise RecordingError(f"{folder}: no recordings (no <stem>.csv / <stem>.json files)")
    recordings: list[Recording] = []
    errors: list[RecordingError] = []
    for stem in stems:
        try:
            csv_path = folder / f"{stem}.csv"
            if not csv_path.is_file():
                raise RecordingError(f"{folder / (stem + '.json')}: metadata without its time series {csv_path.name}")
            recordings.append(read_recording(csv_path))
        except RecordingError as exc:
            if not skip_bad:
                raise
            errors.append(exc)
    if not recordings:
        raise RecordingError(
            f"{folder}: none of the {len(stems)} recordings could be read; first error: {errors[0]}"
        )
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
        for row in zip(*column_values):
            writer.writerow([_cell(v) for v in row])
    json_path.write_text(json.dumps(metadata_to_dict(recording.metadata), indent=2) + "\n")
    return csv_path, json_path
