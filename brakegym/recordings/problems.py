"""What is wrong with a recording: each broken rule as a :class:`RecordingProblem` (file, line,
column or field, value), a bad recording as one :class:`RecordingError` listing its problems, and a
folder's bad recordings as one :class:`DatasetError`."""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

# A rule broken on many lines names the first line and this many more; the rest are counted.
FURTHER_LINES_SHOWN = 3


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
        """The message without the file path (the description, then the further lines)."""
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


def problem_on_lines(file: str, lines: Sequence[int], description: str, **where: Any) -> RecordingProblem:
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


def refuse(file: str | Path, description: str) -> RecordingError:
    """The error of a recording that cannot be checked further, with its one problem."""
    return RecordingError.from_problems(file, [RecordingProblem(str(file), description)])
