"""``brakegym tail | kdry``: braking-distance tails and the ETCS brake model of a safety case.

    brakegym tail --v0 160 --load empty --probability 1e-9 --method is
    brakegym tail --v0 160 --load empty --distance 1400
    brakegym kdry --load empty --figure kdry.png --osrd etcs_brake_params.json

JSON keys written by ``tail`` (``--json``) are a public interface and stay stable: probability,
braking_distance_m, ci95_m, model_evaluations, method, seconds, probability_ci95, threshold, and
what was asked (safety_case, vehicle, load, v0_kmh, seed), the references
(nominal_braking_distance_m, conventional) and the estimator's diagnostics.
"""

from __future__ import annotations

import argparse
import math

from .. import config as cfg
from ..defaults import DEFAULT_STEP_S, DEFAULT_TAIL_CHUNK_STOPS, TAIL_METHODS
from .common import (
    UsageError,
    add_execution_options,
    executor_from_arguments,
    finite_positive,
    non_negative_int,
    positive_int,
    progress,
    write_json,
)


def _probability(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--probability must be a number, got {text!r}") from None
    if not 0 < value < 1:
        raise argparse.ArgumentTypeError(f"--probability must lie strictly between 0 and 1, got {text!r}")
    return value


def safety_case_for(vehicle: str, name: str | None) -> cfg.SafetyCase:
    """The safety case ``name`` (default: the one named as the vehicle), which must be the
    vehicle's."""
    case = cfg.load("safety_cases", name or vehicle)
    if case.vehicle != vehicle:
        raise UsageError(f"safety case {case.name!r} is for vehicle {case.vehicle!r}, not {vehicle!r}")
    return case


def cmd_tail(args: argparse.Namespace) -> int:
    from ..safety.tail import braking_distance_tail

    case = safety_case_for(args.vehicle, args.safety_case)
    settings = {} if args.n_per_level is None else {"n_per_level": args.n_per_level}
    if args.method == "brute" and settings:
        raise UsageError("--n-per-level is for subset and is; brute force takes --samples")
    if args.method != "brute" and args.samples is not None:
        raise UsageError("--samples is brute force's sample size; subset and is take --n-per-level")
    with executor_from_arguments(args) as executor:
        result = braking_distance_tail(
            case,
            args.load,
            args.v0,
            probability=args.probability,
            distance_m=args.distance,
            method=args.method,
            seed=args.seed,
            step_s=args.step,
            samples=args.samples,
            executor=executor,
            chunk_stops=args.chunk_size,
            **settings,
        )
    print(report(result))
    write_json(args.json, result.as_dict())
    return 0


def report(result) -> str:
    """The table ``brakegym tail`` prints."""
    estimate = result.estimate
    low, high = estimate.threshold_ci95
    p_low, p_high = estimate.probability_ci95
    lines = [
        f"braking-distance tail: {result.vehicle}, load {result.load}, {result.initial_speed_kmh:g} km/h, "
        f"safety case {result.case}, method {estimate.method}, seed {result.seed}"
    ]
    if estimate.target == "probability":
        lines.append(
            f"  exceeded with probability {estimate.probability:.3g}: {estimate.threshold:9.1f} m   "
            f"95 % interval {_metres(low)} - {_metres(high)}"
        )
    else:
        lines.append(
            f"  probability of exceeding {estimate.threshold:.1f} m: {estimate.probability:.3e}   "
            f"95 % interval {p_low:.3e} - {p_high:.3e}"
        )
    conventional = result.conventional
    lines += [
        f"  nominal stop (every input nominal, no unit failed): {result.nominal_braking_distance_m:9.1f} m",
        f"  conventional calculation (mean pad friction {conventional.mean_pad_friction:g}, equivalent response "
        f"time {conventional.equivalent_response_time_s:.2f} s): {conventional.braking_distance_m:9.1f} m",
        f"  {estimate.model_evaluations} simulated stops in {estimate.seconds:.1f} s "
        f"(coefficient of variation of the probability {estimate.coefficient_of_variation:.3f})",
    ]
    components = estimate.diagnostics.get("components")
    if components:
        lines.append(f"  {'failed units':>12} {'probability':>12} {'share of the tail':>17}  estimate")
        total = sum(component.get("contribution") or 0.0 for component in components) or 1.0
        skipped = [units for units, component in enumerate(components) if component["status"] == "skipped"]
        for units, component in enumerate(components):
            if units not in skipped:
                share = (component.get("contribution") or 0.0) / total
                lines.append(f"  {units:12d} {component['weight']:12.3e} {share:17.1%}  {component['status']}")
        if skipped:
            weight = sum(components[units]["weight"] for units in skipped)
            lines.append(
                f"  {len(skipped)} more ({_units(skipped)} failed units), {weight:.1e} in all: too rare to matter, "
                f"their weight added to the interval's upper end"
            )
    return "\n".join(lines)


def cmd_kdry(args: argparse.Namespace) -> int:
    from ..safety.etcs import kdry_table, speed_band_edges_kmh
    from ..safety.osrd import export_kdry_table, write_etcs_brake_params

    case = safety_case_for(args.vehicle, args.safety_case)
    if args.osrd and case.etcs.export_confidence_level not in args.levels:
        raise UsageError(
            f"--osrd exports Kdry at the safety case's M_NVEBCL {case.etcs.export_confidence_level}: "
            f"include it in --levels"
        )
    settings = {} if args.n_per_level is None else {"n_per_level": args.n_per_level}
    tables = []
    with executor_from_arguments(args) as executor:
        for load in args.load:
            bar = progress(len(args.levels) * (len(speed_band_edges_kmh(case)) - 1), f"Kdry {load}", "estimate")
            with bar:
                table = kdry_table(
                    case,
                    load,
                    method=args.method,
                    seed=args.seed,
                    levels=tuple(args.levels),
                    step_s=args.step,
                    executor=executor,
                    chunk_stops=args.chunk_size,
                    progress=bar.update,
                    **settings,
                )
            print(kdry_report(table))
            tables.append(table)
    if args.figure:
        from ..safety.figures import kdry_figure  # matplotlib only where a figure is asked for

        print(f"figure: {kdry_figure(tables, args.figure)}")
    if args.osrd:
        for load, table in zip(args.load, tables):
            path = args.osrd if len(tables) == 1 else _with_suffix(args.osrd, load)
            print(f"OSRD etcs_brake_params: {write_etcs_brake_params(path, export_kdry_table(table, case, args.step))}")
    write_json(args.json, [table.as_dict() for table in tables] if len(tables) > 1 else tables[0].as_dict())
    return 0


def kdry_report(table) -> str:
    """The table ``brakegym kdry`` prints: a row per confidence level, a column per speed band."""
    from ..safety.etcs import confidence_label

    edges = table.speed_edges_kmh
    bands = [f"{low:g}-{high:g} km/h" for low, high in zip(edges, edges[1:])]
    width, label_width = 22, 26
    lines = [
        f"Kdry_rst: {table.vehicle}, load {table.load}, safety case {table.case}, method {table.method}, "
        f"seed {table.seed}; T_be {table.build_up_time_s:.2f} s; {table.model_evaluations} simulated stops in "
        f"{table.seconds:.0f} s",
        f"{'':<{label_width}}" + "".join(f"{band:>{width}}" for band in bands),
        f"{'A_brake_emergency':<{label_width}}" + "".join(f"{a:>{width}.3f}" for a in table.nominal_deceleration_mps2),
        f"{'conventional':<{label_width}}" + "".join(f"{a:>{width}.3f}" for a in table.conventional_deceleration_mps2),
    ]
    for column, level in enumerate(table.levels):
        cells = "".join(
            f"{f'{k:.3f} ({low:.3f}-{high:.3f})':>{width}}"
            for k, (low, high) in zip(table.kdry[:, column], table.kdry_ci95[:, column])
        )
        lines.append(f"{f'M_NVEBCL {level} ({confidence_label(level)})':<{label_width}}" + cells)
    return "\n".join(lines)


def _with_suffix(path: str, load: str) -> str:
    """``out.json`` for load ``max`` as ``out_max.json``."""
    stem, dot, extension = path.rpartition(".")
    return f"{stem}_{load}.{extension}" if dot else f"{path}_{load}"


def _levels(text: str) -> list[int]:
    try:
        levels = sorted({int(part) for part in text.split(",")})
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--levels must be whole numbers 0 ... 9 separated by commas, got {text!r}"
        ) from None
    if not all(0 <= level <= 9 for level in levels):
        raise argparse.ArgumentTypeError(f"--levels must lie in 0 ... 9 (M_NVEBCL), got {text!r}")
    return levels


def _units(counts: list[int]) -> str:
    return f"{counts[0]}" if len(counts) == 1 else f"{counts[0]} to {counts[-1]}"


def _metres(value: float) -> str:
    return f"{value:.1f} m" if math.isfinite(value) else "unbounded"


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register ``tail``."""
    p = sub.add_parser(
        "tail",
        help="the braking distance exceeded with a small probability (down to 1e-9), or the probability "
        "of exceeding a distance, for a safety case",
    )
    p.add_argument("--vehicle", default="emu_8axle", help="vehicle config (default emu_8axle)")
    p.add_argument("--load", required=True, help="load case of the vehicle (empty, normal, max, ...)")
    p.add_argument("--v0", type=finite_positive("--v0"), required=True, help="speed at the brake command, km/h")
    p.add_argument(
        "--safety-case", help="stochastic inputs (configs/safety_cases/; default: the one named as the vehicle)"
    )
    target = p.add_mutually_exclusive_group(required=True)
    target.add_argument("--probability", type=_probability, help="exceedance probability, e.g. 1e-9")
    target.add_argument("--distance", type=finite_positive("--distance"), help="braking distance in m")
    p.add_argument("--method", choices=TAIL_METHODS, default="subset", help="estimator (default subset)")
    p.add_argument("--seed", type=non_negative_int("--seed"), default=0, help="random seed (default 0)")
    p.add_argument("--n-per-level", type=positive_int("--n-per-level"), help="samples per level (subset, is)")
    p.add_argument("--samples", type=positive_int("--samples"), help="brute force's sample size")
    p.add_argument(
        "--step",
        type=finite_positive("--step"),
        default=DEFAULT_STEP_S,
        help=f"integration step in s (default {DEFAULT_STEP_S})",
    )
    p.add_argument("--json", help="write the result as JSON")
    _add_execution_options(p)
    p.set_defaults(func=cmd_tail)

    p = sub.add_parser(
        "kdry",
        help="the ETCS emergency brake model of a safety case: nominal deceleration per speed band and the "
        "correction factor Kdry_rst at the confidence levels M_NVEBCL 0-9, an OSRD export",
    )
    p.add_argument("--vehicle", default="emu_8axle", help="vehicle config (default emu_8axle)")
    p.add_argument("--load", required=True, action="append", help="load case; repeat for several (empty, max, ...)")
    p.add_argument(
        "--safety-case", help="stochastic inputs and ETCS speed bands (default: the one named as the vehicle)"
    )
    p.add_argument("--method", choices=("is", "subset"), default="is", help="rare-event estimator (default is)")
    p.add_argument("--seed", type=non_negative_int("--seed"), default=0, help="random seed (default 0)")
    p.add_argument(
        "--levels", type=_levels, default=list(range(10)), help="M_NVEBCL levels, comma-separated (default 0,...,9)"
    )
    p.add_argument("--n-per-level", type=positive_int("--n-per-level"), help="samples per level of the estimator")
    p.add_argument(
        "--step",
        type=finite_positive("--step"),
        default=DEFAULT_STEP_S,
        help=f"integration step in s (default {DEFAULT_STEP_S})",
    )
    p.add_argument("--json", help="write the tables as JSON")
    p.add_argument("--figure", help="write the deceleration figure (PNG)")
    p.add_argument("--osrd", help="write OSRD's etcs_brake_params (JSON; one file per load, suffixed by it)")
    _add_execution_options(p)
    p.set_defaults(func=cmd_kdry)


def _add_execution_options(parser: argparse.ArgumentParser) -> None:
    add_execution_options(parser, chunked_output=False)
    parser.add_argument(
        "--chunk-size",
        type=positive_int("--chunk-size"),
        default=DEFAULT_TAIL_CHUNK_STOPS,
        help=f"stops per task of the estimator's batches (default {DEFAULT_TAIL_CHUNK_STOPS}); the results do "
        "not depend on it",
    )
