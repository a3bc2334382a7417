"""``brakegym identify``: fit model parameters to measurements.

    brakegym identify parameters --dyno-curves F.csv [--parameters friction] [--json F]
    brakegym identify parameters --recordings DIR --parameters a,c,C_fric [--skip-bad-recordings] [--json F]
    brakegym identify scatter --dyno-csv F.csv [--field-csv F.csv] [--json F]

Errors in arguments, configs or data files end with a message and exit status 2 (raised as
``ConfigError`` or ``ValueError``, which ``brakegym.cli.main`` turns into that).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from .. import config as cfg
from ..defaults import DEFAULT_STEP_S
from ..observables import DYNO_OBSERVABLES, TRAIN_OBSERVABLES
from .common import finite_positive, fraction, write_json
from .recordings import (
    LEFT_OUT_KEY,
    SKIP_BAD_RECORDINGS,
    add_skip_bad_recordings_option,
    read_recordings,
    recordings_left_out,
)

if TYPE_CHECKING:
    import pandas as pd


def _split(text: str) -> float | None:
    """A global fraction in [0, 1], or 'fit'."""
    return None if text == "fit" else fraction("--dyno-split")(text)


def _read_table(path: str, option: str) -> pd.DataFrame:
    import pandas as pd

    try:
        return pd.read_csv(path)
    except FileNotFoundError:
        raise ValueError(f"{option} {path}: no such file") from None
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise ValueError(f"{option} {path}: cannot read as CSV ({exc})") from None


def cmd_parameters(args: argparse.Namespace) -> int:
    from ..identification.cases import read_dyno_curves, recording_cases
    from ..identification.deterministic import identify
    from ..identification.parameters import load_identification_config

    settings = load_identification_config(args.config)
    names = [n.strip() for n in args.parameters.split(",") if n.strip()]
    settings.resolve(names)  # unknown names fail before any simulation
    dataset = None
    if args.dyno_curves:
        if args.skip_bad_recordings:
            raise ValueError(f"{SKIP_BAD_RECORDINGS} applies to --recordings; dyno curves are read whole or refused")
        rig = cfg.load("rigs", args.rig)
        cases = read_dyno_curves(args.dyno_curves, rig, args.step or DEFAULT_STEP_S)
        material_name, disc_name = rig.material, rig.disc
    else:
        folder = Path(args.recordings)
        if not folder.is_dir():
            raise ValueError(f"--recordings {folder}: not a folder")
        if args.step is not None:
            raise ValueError("--step applies to --dyno-curves; recordings replay at their own step")
        dataset = read_recordings(folder, args.skip_bad_recordings, args.command)
        cases = recording_cases(dataset)
        vehicle = cases.recordings[0].vehicle
        material_name, disc_name = vehicle.material, vehicle.disc
    material = cfg.load("materials", args.material or material_name)
    disc = cfg.load("discs", args.disc or disc_name)
    result = identify(cases, names, material, disc, settings)
    print(result.table())
    payload = {
        "command": "identify parameters",
        "config": settings.name,
        "material": material.name,
        "disc": disc.name,
        **result.as_dict(),
    }
    if dataset is not None:
        payload[LEFT_OUT_KEY] = recordings_left_out(dataset)
    write_json(args.json, payload)
    return 0


def cmd_scatter(args: argparse.Namespace) -> int:
    from ..identification.parameters import load_identification_config
    from ..identification.stochastic import dyno_spread_groups, field_spread_groups, identify_scatter

    settings = load_identification_config(args.config)
    if not (args.dyno_csv or args.field_csv):
        raise ValueError("give --dyno-csv and/or --field-csv (tables written by brakegym mcs --csv)")
    groups = []
    if args.dyno_csv:
        rig = cfg.load("rigs", args.rig)
        table = _read_table(args.dyno_csv, "--dyno-csv")
        groups += dyno_spread_groups(table, rig, args.dyno_observable, args.dyno_split, settings=settings)
    if args.field_csv:
        vehicle = cfg.load("vehicles", args.vehicle)
        table = _read_table(args.field_csv, "--field-csv")
        groups += field_spread_groups(
            table, vehicle, args.field_observable, resistance_scatter=not args.no_resistance_scatter, settings=settings
        )
    result = identify_scatter(groups, settings)
    print(result.table())
    write_json(args.json, {"command": "identify scatter", "config": settings.name, **result.as_dict()})
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register ``brakegym identify`` and its two modes."""
    parser = sub.add_parser("identify", help="fit friction/thermal parameters or the friction scatter to data")
    modes = parser.add_subparsers(dest="mode", required=True)

    p = modes.add_parser("parameters", help="deterministic multi-case fit of Eq. 4 and thermal parameters")
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--dyno-curves", help="CSV of mean curves: load_case, t_s, mu, T_fric_C")
    source.add_argument("--recordings", help="folder of train recordings (recording-format.md)")
    p.add_argument(
        "--parameters",
        default="friction",
        help="symbols or sets of the identification config, comma-separated (default friction)",
    )
    p.add_argument(
        "--config", default="default", help="identification config: name in configs/identification/ or a YAML path"
    )
    p.add_argument("--rig", default="dynamometer", help="rig config of the dyno curves (default dynamometer)")
    p.add_argument("--material", help="material config to start from (default: the rig's or vehicle's)")
    p.add_argument("--disc", help="disc config to start from (default: the rig's or vehicle's)")
    p.add_argument("--step", type=finite_positive("--step"), help="integration step in s for dyno curves (default 0.2)")
    p.add_argument("--json", help="write the result as JSON")
    add_skip_bad_recordings_option(p)
    p.set_defaults(func=cmd_parameters)

    p = modes.add_parser("scatter", help="sigma of mu_0 and a, and the global/individual split (Eq. 13)")
    p.add_argument("--dyno-csv", help="dyno applications: brakegym mcs --campaign dyno --csv")
    p.add_argument("--field-csv", help="train applications: brakegym mcs --campaign field --csv")
    p.add_argument("--rig", default="dynamometer")
    p.add_argument("--vehicle", default="emu_8axle")
    p.add_argument("--dyno-observable", choices=sorted(DYNO_OBSERVABLES), default="mu_s")
    p.add_argument("--field-observable", choices=sorted(TRAIN_OBSERVABLES), default="mu_s_eff")
    p.add_argument(
        "--dyno-split",
        type=_split,
        default=0.0,
        help="global fraction of the dyno data's set-up (default 0: independent stops, MCS-100), or 'fit'",
    )
    p.add_argument(
        "--no-resistance-scatter", action="store_true", help="the train data had no running-resistance scatter"
    )
    p.add_argument("--config", default="default")
    p.add_argument("--json", help="write the result as JSON")
    p.set_defaults(func=cmd_scatter)
