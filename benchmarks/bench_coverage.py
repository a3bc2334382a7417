"""Coverage of the diagnosis's 95 % intervals where the model is right (not a test).

For each effect of ``--random-effects``' library (or those given with ``--effect``) and each of
``--sets-per-effect`` sets: ``brakegym synth`` writes a set with that effect alone, its size drawn
within the effect's synth ranges (clean 10 Hz recordings, or through ``--measurement-chain``);
the effect is then fitted as the diagnosis fits a selected model
(:meth:`brakegym.diagnosis.Diagnoser.fit_effects`: every recording's nuisance, the Gauss-Newton /
jackknife interval, the parametric bootstrap, their hull as ``ci95``), and each parameter's
interval is checked against the key's value.

What it measures is the intervals, not the selection: the fit starts where the diagnosis starts
a single's (its screening's starts), with an integer parameter (failed units) held at the key's
value; whether the diagnosis selects the effect is ``bench_diagnosis.py``'s question. A set whose effect moves no
sample by a noise sigma (``expressed`` false in the key: a fade onset above every disc temperature
reached) has nothing to measure and is counted apart. Every set's scatter between applications is
drawn as ``synth`` draws it, so the truth differs from the fitted model by that scatter as a real
fleet's stops do.

Printed per effect and parameter: the sets, how many intervals hold the truth (the reported
``ci95``, and its two parts), with the Clopper-Pearson 95 % interval of that rate, and the median
relative error; per effect, the sets where every parameter's interval holds it. An interval that
spans its parameter's whole search range (the report's ``not_bounded_by_data``) holds any truth:
such intervals are counted apart (``spans range``), and a set with one is not counted as covered
for its effect ("every interval holds the truth" asks that the data bound them). A parameter that
one recording holds alone (the report's ``resting_on_one_recording``: a fade only the hottest stop
reaches) has a jackknife interval stepped towards its bounds, which often holds the truth by being
wide without spanning the range: such parameters and their sets are counted apart too (``rests on
one``), so that a coverage rate shows how much of it they make. The diagnosis reports the
bootstrap's interval alone for them; per effect the summary also counts the sets that the hull of
both parts for every parameter (the diagnosis's rule before) would have covered.

Usage: ``python benchmarks/bench_coverage.py --sets-per-effect 4 --seed 1 --json cov1.json``.
Runs with different seeds can go on side by side (one per core) and be summarized together:
``python benchmarks/bench_coverage.py --summarize cov1.json cov2.json``. Single sets of a run (its
rows name each set's effect and synth seed) again, with today's diagnosis:
``--set thermal_fade:200304 --set wet_pads:200202``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from brakegym.diagnosis import Diagnoser
from brakegym.diagnosis.bootstrap import merged_intervals
from brakegym.diagnosis.judging import not_bounded_by_data
from brakegym.diagnosis.rules import DiagnosisRules
from brakegym.effects import EFFECTS
from brakegym.recordings.chain import load_measurement_chain
from brakegym.recordings.synth import RANDOM_EFFECT_IDS, EffectRequest, SynthResult, synthesize

DEFAULT_RECORDINGS = 8
# The interval kinds a row keeps: the reported one and its two parts.
INTERVALS = ("ci95", "ci95_gauss_newton_jackknife", "ci95_bootstrap")
# Within this share of the range at both ends, an interval spans the search range (the diagnosis's).
RANGE_END_SHARE = DiagnosisRules().range_end_share


def set_seed(seed: int, index: int, effect_index: int) -> int:
    """The synth seed of the ``index``-th set of the effect at ``effect_index`` in a run of ``seed``."""
    return 100_000 * seed + 100 * index + effect_index


def synthesized_set(effect_id: str, seed: int, recordings: int, chain: str | None, folder: Path) -> SynthResult:
    """A coverage set: ``effect_id`` alone, written under ``folder``."""
    return synthesize(
        folder / "set",
        recordings,
        seed,
        effects=[EffectRequest(effect_id)],
        key_path=folder / "key.json",
        measurement_chain=load_measurement_chain(chain) if chain else None,
    )


def measure_set(
    effect_id: str, seed: int, recordings: int, chain: str | None, end_replicates: int | None = None
) -> dict[str, Any]:
    """One set: synthesized with ``effect_id`` alone, the effect fitted as the diagnosis fits it
    (an integer parameter held at the key's value); ``end_replicates``: the rule
    ``bootstrap_end_replicates`` (the bootstrap's interval ends tested; None: the diagnosis's
    default; 0: untested)."""
    if end_replicates is None:
        end_replicates = DiagnosisRules().bootstrap_end_replicates
    with tempfile.TemporaryDirectory() as tmp:
        result = synthesized_set(effect_id, seed, recordings, chain, Path(tmp))
        (entry,) = result.key["effects"]
        truth = entry["parameters"]
        row: dict[str, Any] = {
            "effect": effect_id,
            "seed": seed,
            "recordings": recordings,
            "measurement_chain": chain,
            "truth": truth,
            "expressed": entry["imprint"]["expressed"],
            "end_replicates": end_replicates,
        }
        if not row["expressed"]:
            return row
        integer = {spec.name for spec in EFFECTS[effect_id].parameters if spec.integer}
        started = time.time()
        rules = DiagnosisRules(bootstrap_end_replicates=end_replicates)
        candidate = Diagnoser(result.recordings, rules=rules).fit_effects(
            [effect_id], fixed={k: v for k, v in truth.items() if k in integer}
        )
        row["seconds"] = round(time.time() - started, 1)
    report = candidate.report
    row["fitted"] = report["parameters"]
    row["resting_on_one_recording"] = sorted(report["resting_on_one_recording"])
    for kind in (*INTERVALS, "ci95_bootstrap_at_fit"):
        row[kind] = {k: v for k, v in report.get(kind, {}).items() if k not in integer}
    return row


def clopper_pearson(hits: int, n: int) -> tuple[float, float]:
    """The exact 95 % interval of a rate of ``hits`` in ``n``."""
    low = 0.0 if hits == 0 else float(stats.beta.ppf(0.025, hits, n - hits + 1))
    high = 1.0 if hits == n else float(stats.beta.ppf(0.975, hits + 1, n - hits))
    return low, high


def hull_of_both(row: dict[str, Any]) -> dict[str, list[float]]:
    """Per parameter of a row's ``ci95``, the hull of its Gauss-Newton/jackknife interval and its
    bootstrap's (the first alone where the row has no bootstrap's): the diagnosis's merge with no
    parameter taken as resting on one recording."""
    return merged_intervals(row["ci95_gauss_newton_jackknife"], row["ci95_bootstrap"])


def all_covered(row: dict[str, Any], intervals: dict[str, list[float]]) -> bool:
    """Every parameter's interval holds the truth and none spans its search range."""
    if not_bounded_by_data([row["effect"]], intervals, RANGE_END_SHARE):
        return False
    return all(low <= row["truth"][name] <= high for name, (low, high) in intervals.items())


def summarize(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per effect and parameter: sets, intervals holding the truth (each kind), median error."""
    per_parameter: dict[str, dict[str, Any]] = defaultdict(
        lambda: {"sets": 0, "errors": [], "spans_range": 0, "rests_on_one": 0, **{k: 0 for k in INTERVALS}}
    )
    per_effect: dict[str, dict[str, int]] = defaultdict(
        lambda: {
            "sets": 0,
            "all_covered": 0,
            "all_covered_hull_of_both": 0,
            "spanning_range": 0,
            "resting_on_one_recording": 0,
            "covered_resting_on_one_recording": 0,
            "resting_not_recorded": 0,
            "not_expressed": 0,
        }
    )
    for row in rows:
        effect = per_effect[row["effect"]]
        if not row["expressed"]:
            effect["not_expressed"] += 1
            continue
        effect["sets"] += 1
        reported = row["ci95"]
        unbounded = not_bounded_by_data([row["effect"]], reported, RANGE_END_SHARE)
        # Rows written before the report had the key say nothing either way.
        resting = row.get("resting_on_one_recording")
        effect["resting_not_recorded"] += resting is None
        resting = set(resting or ())
        for name, truth in row["truth"].items():
            if name not in reported:  # an integer parameter, held at the truth
                continue
            entry = per_parameter[f"{row['effect']}.{name}"]
            entry["sets"] += 1
            entry["errors"].append(abs(row["fitted"][name] - truth) / max(abs(truth), 1e-9))
            entry["spans_range"] += name in unbounded
            entry["rests_on_one"] += name in resting
            for kind in INTERVALS:
                low, high = row[kind].get(name, (np.nan, np.nan))
                entry[kind] += bool(low <= truth <= high)
        covered = all_covered(row, reported)
        effect["spanning_range"] += bool(unbounded)
        effect["all_covered"] += covered
        effect["all_covered_hull_of_both"] += all_covered(row, hull_of_both(row))
        effect["resting_on_one_recording"] += bool(resting)
        effect["covered_resting_on_one_recording"] += bool(resting) and covered
    parameters = {}
    for name, entry in sorted(per_parameter.items()):
        n = entry["sets"]
        parameters[name] = {
            "sets": n,
            **{f"covered_{kind}": entry[kind] for kind in INTERVALS},
            "spans_search_range": entry["spans_range"],
            "rests_on_one_recording": entry["rests_on_one"],
            "coverage_ci95_clopper_pearson": [round(v, 3) for v in clopper_pearson(entry["ci95"], n)],
            "median_relative_error": float(np.median(entry["errors"])),
        }
    return {"parameters": parameters, "effects": dict(sorted(per_effect.items()))}


def print_summary(summary: dict[str, Any]) -> None:
    print(
        f"{'parameter':40s} {'sets':>4s} {'ci95':>9s} {'its 95 % CI':>13s} {'GN/jackknife':>12s} "
        f"{'bootstrap':>9s} {'spans range':>11s} {'rests on one':>12s} {'median error':>12s}"
    )
    for name, entry in summary["parameters"].items():
        n = entry["sets"]
        low, high = entry["coverage_ci95_clopper_pearson"]
        print(
            f"{name:40s} {n:4d} {entry['covered_ci95']:4d}/{n:<4d} {100 * low:5.0f}-{100 * high:3.0f} % "
            f"{entry['covered_ci95_gauss_newton_jackknife']:7d}/{n:<4d} {entry['covered_ci95_bootstrap']:4d}/{n:<4d} "
            f"{entry['spans_search_range']:6d}/{n:<4d} {entry['rests_on_one_recording']:7d}/{n:<4d} "
            f"{100 * entry['median_relative_error']:11.1f} %"
        )
    total = sum(e["sets"] for e in summary["effects"].values())
    covered = sum(e["all_covered"] for e in summary["effects"].values())
    print("\nper effect, sets where every parameter's ci95 holds the truth and none spans its search range:")
    for effect, entry in summary["effects"].items():
        notes = [f"{entry['spanning_range']} with an interval over the search range"] if entry["spanning_range"] else []
        if entry["resting_on_one_recording"]:
            notes.append(
                f"{entry['resting_on_one_recording']} resting on one recording, "
                f"{entry['covered_resting_on_one_recording']} of them covered"
            )
        if entry["resting_not_recorded"]:
            notes.append(f"{entry['resting_not_recorded']} from rows without resting_on_one_recording")
        notes += [f"{entry['not_expressed']} not expressed"] if entry["not_expressed"] else []
        notes.append(f"{entry['all_covered_hull_of_both']} with the hull of both parts for every parameter")
        shown = f" ({'; '.join(notes)})" if notes else ""
        print(f"  {effect:26s} {entry['all_covered']:3d}/{entry['sets']:<3d}{shown}")
    print(f"  {'all':26s} {covered:3d}/{total:<3d}")


def parse_set(parser: argparse.ArgumentParser, text: str) -> tuple[str, int]:
    """``EFFECT:SEED`` as (effect id, synth seed); a malformed one is refused by name."""
    effect_id, _, seed = text.partition(":")
    if not seed.strip().isdigit():
        parser.error(f"--set {text!r}: expected EFFECT:SEED, a synth seed of whole digits after the colon")
    return effect_id, int(seed)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--summarize", nargs="+", metavar="ROWS.json", help="summarize earlier runs' rows")
    parser.add_argument("--sets-per-effect", type=int, default=4)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--recordings", type=int, default=DEFAULT_RECORDINGS)
    parser.add_argument("--effect", action="append", help="an effect id (repeatable; default: synth's random library)")
    parser.add_argument(
        "--set", action="append", metavar="EFFECT:SEED", help="one set: an effect id and its synth seed (repeatable)"
    )
    parser.add_argument("--measurement-chain", help="a measurement chain of configs/chains (default: clean 10 Hz)")
    parser.add_argument(
        "--end-replicates",
        type=int,
        default=None,
        help="replicates testing each end of the bootstrap's intervals (DiagnosisRules.bootstrap_end_replicates; "
        "default: the diagnosis's; 0: the ends untested)",
    )
    parser.add_argument("--json", help="write every set's row (after each set)")
    parser.add_argument("--summary-json", metavar="FILE", help="write the summary's numbers as JSON")
    args = parser.parse_args()
    if args.summarize:
        rows = [row for path in args.summarize for row in json.loads(Path(path).read_text())]
    else:
        named = [parse_set(parser, text) for text in args.set or []]
        effects = [effect_id for effect_id, _ in named] or args.effect or list(RANDOM_EFFECT_IDS)
        unknown = sorted(set(effects) - set(EFFECTS))
        if unknown:
            parser.error(f"unknown effect(s) {unknown}; the library has {list(EFFECTS)}")
        sets = named or [
            (effect_id, set_seed(args.seed, index, list(EFFECTS).index(effect_id)))
            for index in range(args.sets_per_effect)
            for effect_id in effects
        ]
        rows = []
        for effect_id, seed in sets:
            row = measure_set(effect_id, seed, args.recordings, args.measurement_chain, args.end_replicates)
            rows.append(row)
            shown = {k: row.get(k) for k in ("truth", "fitted", "ci95")}
            print(f"{effect_id:24s} seed {seed}: {json.dumps(shown)}", flush=True)
            if args.json:
                Path(args.json).write_text(json.dumps(rows, indent=1) + "\n")
    summary = summarize(rows)
    print()
    print_summary(summary)
    if args.summary_json:
        Path(args.summary_json).write_text(json.dumps(summary, indent=1) + "\n")


if __name__ == "__main__":
    main()
