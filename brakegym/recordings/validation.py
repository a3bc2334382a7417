"""The rules of the format on a recording's samples: the header, every channel's values, and the
metadata fields the channels need. Each rule broken is one
:class:`~brakegym.recordings.problems.RecordingProblem`.

Some rules can only be checked once others pass, and are then not reported: the values of a
missing or duplicated column are not checked; a line with the wrong number of fields is left out
of the value checks; the pressure-column count and the channels' metadata fields
(``instrumented_disc``, ``decel_source``) need valid metadata.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from .. import config as cfg
from .columns import (
    ABSOLUTE_ZERO_C,
    DECEL,
    DISC_TEMPERATURE,
    OPTIONAL_CHANNELS,
    PRESSURE_COLUMN,
    PRESSURE_RANGE_BAR,
    REQUIRED_COLUMNS,
    SPEED,
    TIME,
    pressure_column,
)
from .metadata import RecordingMetadata
from .problems import RecordingProblem, problem_on_lines


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
        numbered = [(int(match.group(1)), c) for c in header if (match := PRESSURE_COLUMN.match(c))]
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
UnparsedCells = dict[str, tuple[np.ndarray, list[str]]]


class _ValueRules:
    """The rules on the values of one recording's channels; ``problems`` collects each one broken.

    Only the channels (time, speed, pressures, the optional channels) are checked, each when it is
    present once in the header and holds floats. A cell already reported as not a number is a
    blank (NaN) for the other rules, so one bad cell is reported once.
    """

    def __init__(
        self, file: str, data: pd.DataFrame, header: list[str], lines: np.ndarray, unparsed: UnparsedCells
    ) -> None:
        self.file = file
        self.lines = lines
        self.problems: list[RecordingProblem] = []
        self.values: dict[str, np.ndarray] = {}
        self.reported: dict[str, np.ndarray] = {}
        self.pressure_columns = [c for c in header if PRESSURE_COLUMN.match(c)]
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
        self.problems.append(problem_on_lines(self.file, self.lines[rows], description, column=column, value=value))

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
                file,
                f"has a {DISC_TEMPERATURE!r} column but its metadata names no 'instrumented_disc'",
                column=DISC_TEMPERATURE,
                field="instrumented_disc",
            )
        )
    if DECEL in header and metadata.decel_source is None:
        problems.append(
            RecordingProblem(
                file,
                f"has a {DECEL!r} column but its metadata gives no 'decel_source'",
                column=DECEL,
                field="decel_source",
            )
        )
    return problems


def sample_problems(
    file: str,
    data: pd.DataFrame,
    metadata: RecordingMetadata | None,
    lines: np.ndarray,
    header: list[str] | None = None,
    unparsed: UnparsedCells | None = None,
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
