"""What every subcommand of the command line shares: argument types that refuse bad values with a
message, the error that ends a command with exit status 2, the JSON writer, progress bars, and the
options that say where a command's stops run and where its rows go (:func:`add_execution_options`,
:func:`executor_from_arguments`)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..defaults import DEFAULT_CHUNK_STOPS
from ..execution.options import EXECUTOR_KINDS

EXIT_USAGE = 2

# In this process, the kernel on every core: on one machine as fast as worker processes
# (benchmarks/bench_campaign.py, docs/speed.md), without their start-up and
# pickling, and on any platform.
DEFAULT_EXECUTOR = "inline"


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


def add_execution_options(parser: argparse.ArgumentParser, chunked_output: bool = True) -> None:
    """Add the options that say where a command's stops run: ``--executor``, ``--workers`` and
    ``--dask-address`` (read them with :func:`executor_from_arguments`); and with
    ``chunked_output``, where the rows of its chunks go: ``--out DIR`` (Parquet), ``--resume`` and
    ``--chunk-size`` (default None: the command's own, ``DEFAULT_CHUNK_STOPS`` for a campaign)."""
    group = parser.add_argument_group("where the stops run")
    group.add_argument(
        "--executor",
        choices=EXECUTOR_KINDS,
        default=DEFAULT_EXECUTOR,
        help="inline: this process, the kernel's threads on every core (the default: as fast as processes "
        "on one machine); local: worker processes; dask: a Dask cluster (--dask-address, or a local one)",
    )
    group.add_argument(
        "--workers",
        type=positive_int("--workers"),
        help="inline: kernel threads; local: worker processes; dask: worker processes of a local cluster "
        "(default: one per core)",
    )
    group.add_argument(
        "--dask-address",
        metavar="ADDRESS",
        help="the scheduler of an existing Dask cluster, e.g. tcp://10.0.0.5:8786 (with --executor dask)",
    )
    if not chunked_output:
        return
    group.add_argument(
        "--out",
        metavar="DIR",
        help="write every stop to Parquet files in DIR as its chunk finishes, one file per chunk, with a "
        "manifest; the summaries are then read from there (for campaigns larger than memory)",
    )
    group.add_argument(
        "--resume",
        action="store_true",
        help="continue the campaign interrupted in --out DIR: its finished chunks are kept (refused if DIR "
        "holds another campaign)",
    )
    group.add_argument(
        "--chunk-size",
        type=positive_int("--chunk-size"),
        help=f"stops per chunk (default {DEFAULT_CHUNK_STOPS}); the results do not depend on it",
    )


def executor_from_arguments(args: argparse.Namespace):
    """The executor the options of :func:`add_execution_options` ask for; use it in a ``with``
    block (a Dask cluster is started or connected to here). A missing package or an unreachable
    cluster is a :class:`UsageError`."""
    from ..execution import ExecutorUnavailable, executor_from_options

    if getattr(args, "resume", False) and getattr(args, "out", None) is None:
        raise UsageError("--resume needs --out DIR, the folder of the campaign to resume")
    if args.dask_address is not None and args.executor != "dask":
        raise UsageError(f"--dask-address is for --executor dask, not {args.executor}")
    if args.dask_address is not None and args.workers is not None:
        raise UsageError("--workers: the Dask cluster at --dask-address has its own workers")
    try:
        return executor_from_options(args.executor, args.workers, args.dask_address)
    except ExecutorUnavailable as exc:
        raise UsageError(f"--executor {args.executor}: {exc}") from exc
