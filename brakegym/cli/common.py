"""What every subcommand of the command line shares: argument types that refuse bad values with a
message, the error that ends a command with exit status 2, the JSON writer and progress bars."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

EXIT_USAGE = 2


class UsageError(Exception):
    """A command-line argument is invalid (the command ends with its message and status 2)."""


def _number(name: str, text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None


def _finite(name: str, holds: Callable[[float], bool], requirement: str) -> Callable[[str], float]:
    """An argument type: a finite number for which ``holds`` is true (``requirement`` says so)."""

    def parse(text: str) -> float:
        value = _number(name, text)
        if not (math.isfinite(value) and holds(value)):
            raise argparse.ArgumentTypeError(f"{name} must be {requirement}, got {text!r}")
        return value

    return parse


def finite_positive(name: str) -> Callable[[str], float]:
    """An argument type: a positive finite number."""
    return _finite(name, lambda value: value > 0, "a positive finite number")


def finite_non_negative(name: str) -> Callable[[str], float]:
    """An argument type: a finite number >= 0."""
    return _finite(name, lambda value: value >= 0, "a non-negative finite number")


def fraction(name: str) -> Callable[[str], float]:
    """An argument type: a number in [0, 1]."""
    return _finite(name, lambda value: 0.0 <= value <= 1.0, "a number in [0, 1]")


def integer_at_least(name: str, minimum: int) -> Callable[[str], int]:
    """An argument type: a whole number of at least ``minimum``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {text!r}") from None
        if value < minimum:
            bound = "must not be negative" if minimum == 0 else f"must be at least {minimum}"
            raise argparse.ArgumentTypeError(f"{name} {bound}, got {text!r}")
        return value

    return parse


def non_negative_int(name: str) -> Callable[[str], int]:
    return integer_at_least(name, 0)


def positive_int(name: str) -> Callable[[str], int]:
    return integer_at_least(name, 1)


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, tuple):
        return list(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def write_json(path: str | None, payload: Any) -> None:
    """Write ``payload`` as indented JSON to ``path`` (nothing when None), folders created."""
    if path is None:
        return
    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(json.dumps(payload, indent=2, default=_json_default) + "\n")
    except OSError as exc:
        raise UsageError(f"--json {path}: cannot write ({exc.strerror})") from exc


def progress(total: int, description: str, unit: str = "stop"):
    """A progress bar on stderr (off when stderr is not a terminal)."""
    from tqdm import tqdm

    return tqdm(total=total, desc=description, unit=unit, file=sys.stderr, disable=None, leave=False)
