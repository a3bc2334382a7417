"""``brakegym wsp-test``: the wheel-slide protection test of UIC 541-05 / EN 15595
(docs/adhesion.md, "WSP test").

    brakegym wsp-test --vehicle emu_8axle --load empty --condition low --wsp reference --v0 120
    brakegym wsp-test --load empty --condition low --wsp none --v0 120 --json none.json --figure none.png
    brakegym wsp-test --load empty --line low_patch --wsp my_wsp.yaml --v0 120 --seed 7
    brakegym wsp-test --load empty --condition low --wsp reference --v0 120 --load-transfer

JSON keys written by ``wsp-test`` (``--json``) are a public interface and stay stable:
stop_distance_m, dry_stop_distance_m, distance_extension_pct, adhesion_utilisation,
max_locked_time_s, slide_energy_MJ; and what was asked (vehicle, load, condition or line, wsp,
valves, v0_kmh, seed, load_transfer), ideal_distance_m, adhesion_utilisation_definition and its source,
each axle's locked times and slide energy (brakegym.wsp_test.wsp_test).
"""

from __future__ import annotations

import argparse

from ..defaults import DEFAULT_WSP_CONTROL_STEP_S
from .common import finite_positive, non_negative_int, write_json


def cmd_wsp_test(args: argparse.Namespace) -> int:
    from ..wsp_test import wsp_test

    # The parser lets through one of --condition and --line at most; neither is the low rail.
    condition = args.condition if args.condition is not None or args.line is not None else "low"
    result = wsp_test(
        args.vehicle,
        args.load,
        args.v0,
        args.wsp,
        condition=condition,
        line=args.line,
        seed=args.seed,
        setup=args.setup,
        valves=args.valves,
        control_step_s=args.control_step,
        load_transfer=args.load_transfer,
    )
    report = result.as_json()
    seed = "nominal" if args.seed is None else f"seed {args.seed}"
    seed += ", load transfer" if args.load_transfer else ""
    print(
        f"WSP test: {report['vehicle']} {report['load']}, {report['rail']}, WSP {report['wsp']} "
        f"({report['valves']} valves), emergency EP from {report['v0_kmh']:g} km/h, {seed}"
    )
    rows = (
        ("stop distance", f"{report['stop_distance_m']:.1f} m"),
        ("dry stop distance", f"{report['dry_stop_distance_m']:.1f} m"),
        ("distance extension", f"{report['distance_extension_pct']:+.1f} %"),
        ("ideal distance (perfect WSP)", f"{report['ideal_distance_m']:.1f} m"),
        ("adhesion utilisation", f"{report['adhesion_utilisation']:.3f}"),
        ("longest locked axle", f"{report['max_locked_time_s']:.2f} s"),
        ("slide energy", f"{report['slide_energy_MJ']:.2f} MJ"),
    )
    for name, value in rows:
        print(f"  {name:<27} {value}")
    write_json(args.json, report)
    if args.figure:
        from ..wsp_figures import wsp_test_figure  # matplotlib only where a figure is asked for

        print(f"figure: {wsp_test_figure(result.traces, report, args.figure)}")
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register ``wsp-test``."""
    p = sub.add_parser(
        "wsp-test",
        help="the WSP test of UIC 541-05 / EN 15595: an emergency stop on a low-adhesion rail with a WSP "
        "against the dry stop; distance extension, adhesion utilisation, locked time, slide energy",
    )
    p.add_argument("--vehicle", default="emu_8axle", help="vehicle config (default emu_8axle)")
    p.add_argument("--load", required=True, help="load case of the vehicle (empty, normal, max, ...)")
    rail = p.add_mutually_exclusive_group()
    rail.add_argument("--condition", help="rail condition (configs/rail_conditions/; default low)")
    rail.add_argument("--line", help="a line of rail sections instead (configs/lines/, e.g. low_patch)")
    p.add_argument(
        "--wsp",
        required=True,
        help="none, reference (configs/agents/wsp.yaml), reference-true-speed, ppo (the shipped PPO policy), "
        "a controller YAML of the reference kind, or a trained policy folder",
    )
    p.add_argument("--v0", type=finite_positive("--v0"), required=True, help="speed at the brake command, km/h")
    p.add_argument(
        "--seed",
        type=non_negative_int("--seed"),
        help="draw the discs' friction, the running resistance and the rail's adhesion from this seed "
        "(default: the nominal stop)",
    )
    p.add_argument("--setup", default="mcs-100", help="scatter set-up of the friction with --seed (default mcs-100)")
    p.add_argument("--valves", default="axle", help="WSP valve set (configs/wsp_valves/: axle, bogie; default axle)")
    p.add_argument(
        "--control-step",
        type=finite_positive("--control-step"),
        default=DEFAULT_WSP_CONTROL_STEP_S,
        help=f"WSP control and integration step in s (default {DEFAULT_WSP_CONTROL_STEP_S})",
    )
    p.add_argument(
        "--load-transfer",
        action="store_true",
        help="move load between the bogies and axles as the train decelerates (the vehicle's "
        "wheelsets.car_geometry; docs/adhesion.md)",
    )
    p.add_argument("--json", help="write the results as JSON")
    p.add_argument("--figure", help="write speeds, pressures, creeps and adhesion over time (PNG)")
    p.set_defaults(func=cmd_wsp_test)
