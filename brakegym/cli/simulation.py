"""``brakegym demo | dyno | simulate | mcs | trends``: simulations of the rig and the train.

    brakegym demo      emergency stops of the 16-disc train from 100 and 160 km/h with scatter
    brakegym dyno      the 12 dynamometer load cases (paper Table 1), deterministic
    brakegym simulate  one train stop
    brakegym mcs       a Monte-Carlo campaign: dynamometer (Table 1) or field (Table 4)
    brakegym trends    the paper's trends recomputed

JSON keys written by ``dyno``, ``simulate`` and ``mcs`` are a public interface and stay stable.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from .. import config as cfg
from ..defaults import DEFAULT_CHUNK_STOPS, DEFAULT_STEP_S, DEFAULT_WSP_CONTROL_STEP_S
from .common import (
    UsageError,
    add_execution_options,
    executor_from_arguments,
    finite_non_negative,
    finite_positive,
    non_negative_int,
    positive_int,
    progress,
    write_json,
)

#: A stop counts as one with a locked axle in the summary when an axle stayed locked this long, s.
LOCKED_STOP_S = 0.5

# ------------------------------------------------------------------------------------------------


def cmd_dyno(args: argparse.Namespace) -> int:
    from ..applications import dyno_stops

    rig = cfg.load("rigs", args.rig)
    cases = [rig.load_case(args.case)] if args.case else list(rig.load_cases)
    summary = dyno_stops(rig, cases, step_s=args.step)
    rows = [
        {
            "load_case": case.name,
            "s_m": float(summary.stop_distance_m[i]),
            "s2_m": float(summary.onset_distance_m[i]),
            "mu_s": float(summary.mu_s[i, 0]),
            "t_stop_s": float(summary.stop_time_s[i]),
            "T_fric_max_C": float(summary.peak_friction_temperature_C[i, 0]),
        }
        for i, case in enumerate(cases)
    ]
    print(
        f"{'load case':<13} {'v0 km/h':>8} {'s [m]':>9} {'s2 [m]':>9} {'mu_s':>7} {'t_stop [s]':>10} {'T_max [C]':>9}"
    )
    for case, row in zip(cases, rows):
        print(
            f"{row['load_case']:<13} {case.initial_speed_kmh:8.0f} {row['s_m']:9.2f} {row['s2_m']:9.2f} "
            f"{row['mu_s']:7.4f} {row['t_stop_s']:10.3f} {row['T_fric_max_C']:9.1f}"
        )
    write_json(args.json, rows[0] if args.case else rows)
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    from ..applications import TrainApplication, train_stops
    from ..campaigns import train_monte_carlo

    vehicle = cfg.load("vehicles", args.vehicle)
    vehicle.load(args.load)
    vehicle.brake_pressure_bar(args.mode, args.load)
    cfg.load("pneumatics", args.actuation)
    app = TrainApplication(
        load=args.load,
        brake_mode=args.mode,
        actuation=args.actuation,
        initial_speed_kmh=args.v0,
        command_time_s=args.command_time,
    )
    if args.setup == "ds":
        summary = train_stops(vehicle, [app], step_s=args.step)
    else:
        summary, _, _ = train_monte_carlo(vehicle, [app], cfg.load("setups", args.setup), args.seed, args.step)
    result = {
        "vehicle": vehicle.name,
        "load": args.load,
        "brake_mode": args.mode,
        "actuation": args.actuation,
        "v0_kmh": args.v0,
        "setup": args.setup,
        "seed": args.seed,
        "cylinder_pressure_bar": vehicle.brake_pressure_bar(args.mode, args.load),
        "command_time_s": args.command_time,
        "stop_distance_m": float(summary.stop_distance_m[0]),
        "stop_time_s": float(summary.stop_time_s[0]),
        "braking_distance_m": float(summary.braking_distance_m[0]),
        "braking_time_s": float(summary.braking_time_s[0]),
        "mu_s_eff": float(summary.mu_s_eff[0]),
        "mu_s_mean": float(summary.mean_mu_s[0]),
        "T_fric_max_C": float(summary.peak_temperature_C[0]),
    }
    for key in ("stop_distance_m", "stop_time_s", "braking_distance_m", "braking_time_s", "mu_s_eff", "T_fric_max_C"):
        print(f"{key:<20} {result[key]:10.3f}")
    write_json(args.json, result)
    return 0


def cmd_mcs(args: argparse.Namespace) -> int:
    setup = cfg.load("setups", args.setup)
    on_rail = args.condition is not None or args.line is not None
    if args.campaign == "dyno" and on_rail:
        raise UsageError("--condition and --line are for the field campaign (train stops on a rail)")
    if not on_rail and (args.wsp is not None or args.wsp_valves is not None or args.load_transfer):
        raise UsageError("--wsp, --wsp-valves and --load-transfer need a rail: --condition or --line")
    if args.step is None:
        args.step = DEFAULT_WSP_CONTROL_STEP_S if on_rail else DEFAULT_STEP_S
    if args.campaign == "dyno" and args.chunk_size is not None:
        raise UsageError(
            "--chunk-size is for the field campaign; the dynamometer campaign runs one chunk per load case"
        )
    if args.campaign == "dyno" and args.repetitions is not None:
        raise UsageError("--repetitions is for the field campaign; the dynamometer's applications are in its rig")
    with executor_from_arguments(args) as executor:
        if args.campaign == "dyno":
            payload = _dyno_mcs(args, setup, executor)
        elif on_rail:
            payload = _rail_field_mcs(args, setup, executor)
        else:
            payload = _field_mcs(args, setup, executor)
    write_json(args.json, payload)
    return 0


def _dyno_mcs(args: argparse.Namespace, setup: cfg.ScatterSetup, executor) -> dict[str, object]:
    from .. import campaigns

    rig = cfg.load("rigs", cfg.load("campaigns", "dyno2022").rig)
    total = len(campaigns.dyno_applications(rig))
    with progress(total, "dyno campaign") as bar:
        result = campaigns.dyno_campaign(
            rig,
            setup,
            args.seed,
            step_s=args.step,
            executor=executor,
            progress=bar.update,
            out=args.out,
            resume=args.resume,
        )
    summary = result.load_case_summary()
    print(f"dynamometer campaign, {setup.name}, seed {args.seed}: {len(result.applications)} applications")
    print(f"{'load case':<13} {'n':>4} {'mu_s mean':>9} {'mu_s std':>9} {'s mean [m]':>10} {'s std [m]':>9}")
    for _, row in summary.iterrows():
        print(
            f"{row.load_case:<13} {row.n:4d} {row.mu_s_mean:9.4f} {row.mu_s_std:9.4f} "
            f"{row.s_m_mean:10.1f} {row.s_m_std:9.2f}"
        )
    if args.figures:
        from ..campaigns import figures  # matplotlib only where figures are asked for

        paths = figures.dyno_campaign_figures(result, Path(args.figures)) + [
            figures.mu_trend_figure(Path(args.figures))
        ]
        print("figures: " + ", ".join(str(p) for p in paths))
    if args.csv:
        result.applications.to_csv(args.csv, index=False)
    return {
        "campaign": "dyno",
        "setup": setup.name,
        "seed": args.seed,
        "step_s": args.step,
        "applications": len(result.applications),
        "load_cases": summary.to_dict(orient="records"),
        "specimens": result.specimen_summary().to_dict(orient="records"),
    }


def _field_mcs(args: argparse.Namespace, setup: cfg.ScatterSetup, executor) -> dict[str, object]:
    from .. import campaigns

    campaign = cfg.load("campaigns", "field2022")
    if args.repetitions is not None:
        campaign = campaign.model_copy(update={"repetitions": args.repetitions})
    total = len(campaigns.field_applications(campaign)) * campaign.repetitions
    with progress(total, "field campaign") as bar:
        result = campaigns.field_campaign(
            campaign,
            setup,
            args.seed,
            step_s=args.step,
            executor=executor,
            progress=bar.update,
            chunk_size=args.chunk_size or DEFAULT_CHUNK_STOPS,
            out=args.out,
            resume=args.resume,
        )
    summary = result.application_summary()
    print(
        f"field campaign {campaign.name}, {setup.name}, seed {args.seed}: {summary.shape[0]} field applications "
        f"x {campaign.repetitions} = {result.n_stops} train stops"
    )
    print(f"{'mode':<10} {'v0':>4} {'mu_s,eff mean':>13} {'rel std %':>9} {'braking dist. [m]':>18} {'rel std %':>9}")
    for _, row in result.mode_speed_summary(summary).iterrows():
        mu, distance = row.mu_s_eff_mean, row.braking_distance_m_mean
        print(
            f"{row.brake_mode:<10} {row.v0_kmh:4.0f} {mu:13.4f} {100 * row.mu_s_eff_std / mu:9.2f} "
            f"{distance:18.1f} {100 * row.braking_distance_m_std / distance:9.2f}"
        )
    return {
        **_field_outputs(args, setup, result),
        "field_applications": summary.to_dict(orient="records"),
    }


def _field_outputs(args: argparse.Namespace, setup: cfg.ScatterSetup, result) -> dict[str, object]:
    """A field campaign's ``--figures`` and ``--csv``, written; the JSON keys every field campaign
    reports."""
    if args.figures:
        from ..campaigns import figures

        paths = figures.field_campaign_figures(result, Path(args.figures))
        print("figures: " + ", ".join(str(p) for p in paths))
    if args.csv:
        result.write_csv(args.csv)
    return {
        "campaign": "field",
        "setup": setup.name,
        "seed": args.seed,
        "step_s": args.step,
        "applications": result.n_stops,
    }


def _rail_field_mcs(args: argparse.Namespace, setup: cfg.ScatterSetup, executor) -> dict[str, object]:
    """The field campaign on ``--condition`` or ``--line`` with adhesion, each stop's rail
    scattered, through the WSP of ``--wsp``."""
    from .. import campaigns
    from ..plants import rail_conditions_of

    rail = cfg.load("rail_conditions", args.condition) if args.condition else cfg.load("lines", args.line)
    wsp_name = args.wsp
    if wsp_name is None:
        wsp_name = "none" if all(c.name == "dry" for c in rail_conditions_of(rail)) else "reference"
    wsp = None
    if wsp_name != "none":
        from ..agents.wsp import load_wsp_config

        wsp = load_wsp_config("wsp" if wsp_name == "reference" else wsp_name)
    valves = cfg.load("wsp_valves", args.wsp_valves or "axle")
    campaign = cfg.load("campaigns", "field2022")
    if args.repetitions is not None:
        campaign = campaign.model_copy(update={"repetitions": args.repetitions})
    total = len(campaigns.field_applications(campaign)) * campaign.repetitions
    with progress(total, f"field campaign on {rail.name}") as bar:
        result = campaigns.rail_field_campaign(
            campaign,
            setup,
            args.seed,
            rail,
            valves,
            wsp,
            control_step_s=args.step,
            executor=executor,
            progress=bar.update,
            chunk_size=args.chunk_size or DEFAULT_CHUNK_STOPS,
            out=args.out,
            resume=args.resume,
            load_transfer=args.load_transfer,
        )
    summary = result.application_summary()
    rail_columns = ["braking_distance_m", "rail_peak_adhesion", "slide_energy_MJ", "longest_locked_s"]
    rows = result.rows.concatenated("stops", rail_columns)
    locked_stops = int(np.count_nonzero(rows["longest_locked_s"] > LOCKED_STOP_S))
    print(
        f"field campaign {campaign.name} on {rail.name}, WSP {wsp_name} ({valves.name} valves), {setup.name}, "
        f"seed {args.seed}: {summary.shape[0]} field applications x {campaign.repetitions} = {result.n_stops} "
        f"train stops"
    )
    print(f"{'mode':<10} {'v0':>4} {'braking dist. [m]':>18} {'rel std %':>9}")
    for _, row in result.mode_speed_summary(summary).iterrows():
        distance = row.braking_distance_m_mean
        relative = 100 * row.braking_distance_m_std / distance
        print(f"{row.brake_mode:<10} {row.v0_kmh:4.0f} {distance:18.1f} {relative:9.2f}")
    print(
        f"rail peak adhesion {rows['rail_peak_adhesion'].mean():.4f} (mean; 5-95 %: "
        f"{np.quantile(rows['rail_peak_adhesion'], 0.05):.4f}-{np.quantile(rows['rail_peak_adhesion'], 0.95):.4f}), "
        f"slide energy {rows['slide_energy_MJ'].mean():.2f} MJ (mean), stops with an axle locked over "
        f"{LOCKED_STOP_S} s: {locked_stops}"
    )
    return {
        **_field_outputs(args, setup, result),
        "rail": rail.name,
        "rail_kind": "condition" if args.condition else "line",
        "wsp": wsp_name if wsp is None or wsp_name == "reference" else wsp.name,
        "wsp_valves": valves.name,
        "load_transfer": args.load_transfer,
        "rail_peak_adhesion_mean": float(rows["rail_peak_adhesion"].mean()),
        "slide_energy_MJ_mean": float(rows["slide_energy_MJ"].mean()),
        "longest_locked_s_max": float(rows["longest_locked_s"].max()),
        "stops_with_locked_axle": locked_stops,
        "field_applications": summary.to_dict(orient="records"),
    }


def cmd_trends(args: argparse.Namespace) -> int:
    from ..campaigns.trends import compute_trends

    with executor_from_arguments(args) as executor:
        trends = compute_trends(
            seed=args.seed, train_applications=args.applications, step_s=args.step, executor=executor
        )
    print(trends.table())
    write_json(args.json, trends.as_dict())
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from ..applications import TrainApplication
    from ..campaigns.figures import demo_figure
    from ..statistics import sample_statistics

    vehicle = cfg.load("vehicles", "emu_8axle")
    setup = cfg.load("setups", "mcs-75-25")
    out = Path(args.out)
    summaries = {}
    rows = []
    for v0 in (100.0, 160.0):
        app = TrainApplication(load="empty", brake_mode="emergency", actuation="EP", initial_speed_kmh=v0)
        summary, _, _ = _recorded_monte_carlo(vehicle, app, setup, args.seed + int(v0), args.runs, args.step)
        summaries[f"{v0:.0f} km/h"] = summary
        distance = sample_statistics(summary.braking_distance_m)
        mu_eff = sample_statistics(summary.mu_s_eff)
        rows.append(
            f"| {v0:.0f} | {distance.mean:.1f} | {distance.std:.2f} ({100 * distance.relative_std:.1f} %) | "
            f"{distance.mean_ci95[0]:.1f} - {distance.mean_ci95[1]:.1f} | {mu_eff.mean:.4f} | "
            f"{summary.peak_temperature_C.mean():.0f} |"
        )
    figure = demo_figure(summaries, out / "demo_train_stops.png")
    table = "\n".join(
        [
            "emu_8axle, empty, emergency brake (3.3 bar), EP, MCS-75/25 friction scatter, "
            f"{args.runs} stops per speed, seed {args.seed}",
            "",
            "| v0 [km/h] | braking distance [m] | std [m] | 95 % CI of mean [m] | mu_s,eff | peak T_fric [C] |",
            "|---|---|---|---|---|---|",
            *rows,
        ]
    )
    (out / "demo_table.md").write_text(table + "\n")
    print(table)
    print(f"\nwrote {figure} and {out / 'demo_table.md'}")
    return 0


def _recorded_monte_carlo(vehicle, app, setup, seed, runs, step_s):
    """Monte-Carlo stops with trajectories (the demo wants the curves, not only summaries), stop
    ``i`` with sample ``i``'s scatter of the seed, as in a campaign."""
    from ..applications import train_stops
    from ..plants import train_scatter

    draw, resistance = train_scatter(vehicle, setup).draw_for_samples(seed, np.arange(runs))
    summary = train_stops(vehicle, [app] * runs, draw, resistance, step_s=step_s, record_every=1)
    return summary, draw, resistance


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register ``demo``, ``dyno``, ``simulate``, ``mcs`` and ``trends``."""

    step = dict(
        type=finite_positive("--step"), default=DEFAULT_STEP_S, help=f"integration step in s (default {DEFAULT_STEP_S})"
    )

    p = sub.add_parser(
        "demo", help="train emergency stops from 100 and 160 km/h with friction scatter; figure and table"
    )
    p.add_argument("--out", default="out/demo", help="output folder (default out/demo)")
    p.add_argument("--runs", type=positive_int("--runs"), default=40, help="stops per speed (default 40)")
    p.add_argument("--seed", type=non_negative_int("--seed"), default=2022)
    p.add_argument("--step", **step)
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("dyno", help="deterministic dynamometer stops of the load cases")
    p.add_argument("--case", help="one load case, e.g. V0100_Case1 (default: all)")
    p.add_argument("--rig", default="dynamometer", help="rig config (default dynamometer)")
    p.add_argument("--json", help="write results as JSON")
    p.add_argument("--step", **step)
    p.set_defaults(func=cmd_dyno)

    p = sub.add_parser("simulate", help="one train stop")
    p.add_argument("--vehicle", default="emu_8axle")
    p.add_argument("--load", default="empty", help="vehicle load (empty, normal, max)")
    p.add_argument("--mode", default="emergency", help="brake mode (emergency, service)")
    p.add_argument("--actuation", default="EP", help="pneumatics config (EP, PN)")
    p.add_argument("--v0", type=finite_positive("--v0"), required=True, help="initial speed in km/h")
    p.add_argument(
        "--command-time",
        type=finite_non_negative("--command-time"),
        default=1.0,
        help="brake command time in s (default 1)",
    )
    p.add_argument("--setup", default="ds", help="scatter set-up (default ds)")
    p.add_argument("--seed", type=non_negative_int("--seed"), default=0)
    p.add_argument("--json", help="write results as JSON")
    p.add_argument("--step", **step)
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("mcs", help="Monte-Carlo campaign")
    p.add_argument("--campaign", choices=["dyno", "field"], required=True)
    p.add_argument("--setup", default="mcs-75-25", help="scatter set-up: ds, mcs-100, mcs-75-25, shared")
    p.add_argument("--seed", type=non_negative_int("--seed"), default=0)
    p.add_argument("--json", help="write the summary as JSON")
    p.add_argument("--csv", help="write every simulated application as CSV")
    p.add_argument("--figures", help="folder for PNG figures")
    p.add_argument(
        "--repetitions",
        type=positive_int("--repetitions"),
        help="field campaign: stops per field application (default: the campaign's, 50)",
    )
    p.add_argument(
        "--step",
        type=finite_positive("--step"),
        default=None,
        help=f"integration step in s (default {DEFAULT_STEP_S}; on a rail the WSP's control step, "
        f"{DEFAULT_WSP_CONTROL_STEP_S})",
    )
    rail = p.add_argument_group("on a rail (field campaign; wheel-rail adhesion, docs/adhesion.md)")
    where = rail.add_mutually_exclusive_group()
    where.add_argument(
        "--condition",
        metavar="NAME",
        help="rail condition (configs/rail_conditions: dry, wet, low): adhesion on, each stop's mu_0 scattered "
        "by the condition's static_friction_relative_sigma",
    )
    where.add_argument("--line", metavar="NAME", help="a line of rail sections (configs/lines, e.g. low_patch)")
    rail.add_argument(
        "--wsp",
        metavar="none|reference|PATH",
        help="wheel-slide protection: none, reference (configs/agents/wsp.yaml) or a controller YAML; "
        "default reference, none when every section is dry (a low-adhesion rail without WSP locks every wheel)",
    )
    rail.add_argument("--wsp-valves", metavar="NAME", help="WSP valves (configs/wsp_valves: axle, bogie; default axle)")
    rail.add_argument(
        "--load-transfer",
        action="store_true",
        help="the axle loads move between and within the bogies with the deceleration (docs/adhesion.md)",
    )
    add_execution_options(p)
    p.set_defaults(func=cmd_mcs)

    p = sub.add_parser("trends", help="recompute the paper's trends")
    p.add_argument("--seed", type=non_negative_int("--seed"), default=2022)
    p.add_argument("--applications", type=positive_int("--applications"), default=400, help="train stops per set-up")
    p.add_argument("--json", help="write the trends as JSON")
    p.add_argument("--step", **step)
    add_execution_options(p, chunked_output=False)
    p.set_defaults(func=cmd_trends)
