"""The recording format (``docs/recording-format.md``): read and write recordings and folders of
them.

A recording is one brake application of one vehicle: ``<stem>.csv`` (the time series) and
``<stem>.json`` (what was measured, :mod:`.metadata`) in one folder; a data set is a folder of
recordings. Reading validates (:mod:`.validation`): a bad recording raises one
:class:`~.problems.RecordingError` that lists every problem found, each with the file, the line (as
a user sees it in the CSV: the header is line 1, the first sample line 2) or column or metadata
field, and the value. A folder with bad recordings raises one :class:`~.problems.DatasetError`
listing every bad recording, or, when asked, goes on with the good ones and reports the bad ones in
``Dataset.errors``. A file that cannot be read or parsed as CSV (not text, malformed quoting)
is not checked further.

Nothing is dropped, reordered, clipped or invented: a blank cell is a missing sample (NaN) and
stays one, extra columns are kept as they are.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .. import config as cfg
from .columns import (
    DISC_TEMPERATURE,
    OPTIONAL_CHANNELS,
    PRESSURE_COLUMN,
    REQUIRED_COLUMNS,
    SPEED,
    TIME,
    pressure_column,
)
from .metadata import RecordingMetadata, read_metadata_problems
from .problems import DatasetError, RecordingError, RecordingProblem, problem_on_lines, refuse
from .validation import UnparsedCells, sample_problems


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
        problems = sample_problems(self.name, self.data, self.metadata, self.csv_lines)
        if problems:
            raise RecordingError.from_problems(self.name, problems)

    # -- identification ---------------------------------------------------------------------
    @property
    def name(self) -> str:
        """How messages refer to this recording (its CSV file, else its stem)."""
        return str(self.source) if self.source is not None else f"recording {self.stem!r}"

    @property
    def csv_lines(self) -> np.ndarray:
        """The CSV line of each sample (as read, else as :func:`write_recording` would write it)."""
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
        problems.append(problem_on_lines(file, empty_inside, f"line {empty_inside[0]} is empty between samples"))
    if other_width:
        line, width = other_width[0]
        description = f"line {line} has {width} fields, the header has {len(header)}"
        problems.append(problem_on_lines(file, [line for line, _ in other_width], description, value=width))
    return cells, problems


def _build_frame(cells: _Cells, numeric: set[str]) -> tuple[pd.DataFrame, UnparsedCells]:
    """The rows as a DataFrame (a duplicated column once, its first occurrence), and the cells of
    the ``numeric`` columns that are not numbers (NaN in the frame)."""
    columns: dict[str, Any] = {}
    unparsed: UnparsedCells = {}
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
        raise refuse(path, "a recording's time series is a .csv file")
    if not path.is_file():
        raise refuse(path, "no such file")
    file = str(path)
    metadata, metadata_problems = read_metadata_problems(path.with_suffix(".json"))
    cells, problems = _read_cells(path)
    if cells is not None:
        numeric = {*REQUIRED_COLUMNS, *OPTIONAL_CHANNELS, *(c for c in cells.header if PRESSURE_COLUMN.match(c))}
        frame, unparsed = _build_frame(cells, numeric)
        lines = np.asarray(cells.lines, dtype=int)
        problems += sample_problems(file, frame, metadata, lines, cells.header, unparsed)
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
        raise refuse(folder / f"{stem}.json", f"metadata without its time series {csv_path.name}")
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
