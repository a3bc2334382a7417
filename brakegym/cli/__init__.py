"""The ``brakegym`` command line.

    brakegym demo      emergency stops of the 16-disc train from 100 and 160 km/h with scatter
    brakegym dyno      the 12 dynamometer load cases (paper Table 1), deterministic
    brakegym simulate  one train stop
    brakegym mcs       a Monte-Carlo campaign: dynamometer (Table 1) or field (Table 4)
    brakegym trends    the paper's trends recomputed
    brakegym tail      the braking distance exceeded with a small probability (safety cases)
    brakegym kdry      the ETCS emergency brake model: Kdry_rst per speed band and confidence level
    brakegym wsp-test  the WSP test of UIC 541-05 / EN 15595: a low-adhesion stop with WSP against the dry one
    brakegym train | evaluate | stress   controllers on the environments
    brakegym synth     synthetic recordings with concealed effects
    brakegym diagnose  locate and name the missing physics in recordings
    brakegym identify  fit friction, thermal and scatter parameters to data

One module per group of subcommands (:mod:`.simulation`, :mod:`.safety`, :mod:`.adhesion`, :mod:`.controllers`,
:mod:`.recordings`, :mod:`.identify`), each with an ``add_commands(subparsers)``; what they share is :mod:`.common`.
``--config-path DIR`` (repeatable) puts a folder of the user's own configs on the search path
before ``$BRAKEGYM_CONFIG_PATH`` and the shipped configs. JSON keys the commands write are a public
interface and stay stable. Errors in arguments, configs or data end with a message on stderr and
exit status 2.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from .. import __version__
from .. import config as cfg
from ..execution.base import TaskFailed
from . import adhesion, controllers, identify, recordings, safety, simulation
from .common import EXIT_USAGE, UsageError

COMMAND_GROUPS = (simulation, safety, adhesion, controllers, recordings, identify)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="brakegym",
        description="Railway friction brakes after Ehret, Hohmann & Heckmann (2022): simulations, campaigns, "
        "environments and controllers, diagnosis and identification of recordings.",
    )
    parser.add_argument("--version", action="version", version=f"brakegym {__version__}")
    parser.add_argument(
        "--config-path",
        action="append",
        default=[],
        metavar="DIR",
        help="a folder of your own configs (vehicles/, materials/, effects/, ...), searched before "
        "$BRAKEGYM_CONFIG_PATH and the shipped configs; repeat for several",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    for group in COMMAND_GROUPS:
        group.add_commands(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        cfg.set_config_path(args.config_path, "--config-path")
        return args.func(args)
    except (cfg.ConfigError, UsageError) as exc:
        print(f"brakegym {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except TaskFailed as exc:
        # A task that ran elsewhere (a worker process, a cluster) failed on bad input: its message,
        # as if it had run here. Anything else is a crash, with the traceback where it ran.
        if not isinstance(exc.error, (cfg.ConfigError, ValueError)):
            raise
        print(f"brakegym {args.command}: error: {exc.summary}", file=sys.stderr)
        return EXIT_USAGE
    except ValueError as exc:
        # Invalid combinations found while building the run (a step that does not divide a dead
        # time, a command time off the step grid): input errors, not crashes.
        print(f"brakegym {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except BrokenPipeError:
        # The reader of the output went away (``brakegym dyno | head``): nothing is wrong, and
        # nothing more can be written; stdout is pointed at devnull so that its flush at exit does
        # not fail again.
        sys.stdout = open(os.devnull, "w")
        return 0
