"""Blind benchmark of ``brakegym diagnose`` on synthetic sets (not a test).

For each set: ``brakegym synth`` with random effects (zero, one or two drawn from the library,
sizes drawn within their synth ranges) or, with probability ``--free-share``, an effect-free set
(half of them with ``--base-offset``); then the diagnosis, which never reads the key. Printed:
the hit rate and the confusion matrix of truth (rows) against what was selected (columns).

Pass rules, fixed before running:
- a set with one effect is a hit when that effect is selected, or named indistinguishable from
  what was selected;
- a set with two effects is a hit when at least one of them is selected (both: full hit, counted
  apart);
- an effect-free set is a hit when nothing is selected (its misses are the false positives).

Parameter recovery, on sets where a true effect was selected: the fitted value against the
truth, and whether the truth lies inside the reported 95 % interval.

Usage: ``python benchmarks/bench_diagnosis.py --sets 20 --seed 1 [--recordings 8] [--json out.json]``.
With ``--json`` each set's row is written as soon as it is done; an interrupted run (Ctrl-C)
prints the summary of the sets finished so far. Runs with different seeds can go on side by side
(one per core) and be summarized together:
``python benchmarks/bench_diagnosis.py --summarize seed1.json seed2.json``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from brakegym.recordings.diagnosis import diagnose
from brakegym.recordings.effects import EFFECTS
from brakegym.recordings.synth import synthesize


def run_set(index: int, seed: int, free: bool, offset: bool, args: argparse.Namespace, tmp: Path) -> dict[str, Any]:
    """Synthesize one set, diagnose it blind, and judge the verdict against the key."""
    started = time.time()
    folder = tmp / f"set_{index:04d}"
    result = synthesize(folder, args.recordings, seed, random_effects=not free, base_offset=offset,
                        key_path=tmp / f"key_{index:04d}.json")
    truth = [e["id"] for e in result.key["effects"]]
    report = diagnose(folder, top_singles=args.top_singles, pairs_from=args.pairs_from).report
    selected = report["selected"]
    named = set(selected) | {e for pair in report["indistinguishable"] for e in pair}
    kind = "none" if not truth else ("single" if len(truth) == 1 else "pair")
    if kind == "none":
        hit = not selected
    elif kind == "single":
        hit = truth[0] in named
    else:
        hit = bool(set(truth) & set(selected))
    chosen = next((c for c in report["candidates"] if c["effects"] == selected), None) if selected else None
    return {
        "index": index, "seed": seed, "recordings": args.recordings, "kind": kind, "truth": result.key["effects"], "base_offset": offset,
        "selected": selected, "parameters": report["parameters"], "ci95": chosen["ci95"] if chosen else {},
        "indistinguishable": report["indistinguishable"], "hit": bool(hit), "seconds": round(time.time() - started, 1),
    }


def summarize(rows: list[dict[str, Any]], args: argparse.Namespace, seconds: float) -> None:
    hits, totals = Counter(), Counter()
    confusion: dict[str, Counter] = defaultdict(Counter)
    recovery: dict[str, list[tuple[float, float, bool]]] = defaultdict(list)
    for row in rows:
        totals[row["kind"]] += 1
        hits[row["kind"]] += row["hit"]
        truth_label = "+".join(e["id"] for e in row["truth"]) or ("none (base offset)" if row["base_offset"] else "none")
        confusion[truth_label]["+".join(row["selected"]) or "nothing"] += 1
        for effect in row["truth"]:
            if effect["id"] not in row["selected"]:
                continue
            for name, true_value in effect["parameters"].items():
                if name in row["parameters"] and name in row["ci95"]:
                    low, high = row["ci95"][name]
                    recovery[f"{effect['id']}.{name}"].append(
                        (float(true_value), float(row["parameters"][name]), bool(low <= true_value <= high))
                    )
    print()
    for kind in ("single", "pair", "none"):
        if totals[kind]:
            print(f"{kind:7s} sets: {hits[kind]}/{totals[kind]} hits ({100 * hits[kind] / totals[kind]:.0f} %)")
    print(f"all     sets: {sum(hits.values())}/{sum(totals.values())}")
    print("\nconfusion (truth -> selected):")
    for truth_label in sorted(confusion):
        print(f"  {truth_label:40s} " + ", ".join(f"{k}: {v}" for k, v in confusion[truth_label].most_common()))
    if recovery:
        print("\nparameter recovery where the effect was selected (median |fitted - truth| / |truth|; truth inside the 95 % interval):")
        for name in sorted(recovery):
            values = recovery[name]
            errors = [abs(f - t) / max(abs(t), 1e-9) for t, f, _ in values]
            covered = sum(c for _, _, c in values)
            print(f"  {name:40s} n={len(values):3d}  median error {100 * float(np.median(errors)):5.1f} %  covered {covered}/{len(values)}")
    # Rows written before the count was recorded hold the default (--recordings).
    counts = sorted({row.get("recordings", args.recordings) for row in rows})
    shown = "/".join(str(c) for c in counts)
    print(f"\nlibrary: {', '.join(EFFECTS)}; {shown} recordings per set; {len(rows)} sets, {seconds:.0f} s of diagnosis")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--summarize", nargs="+", metavar="ROWS.json",
                        help="summarize the rows that earlier runs wrote with --json, and run nothing")
    parser.add_argument("--sets", type=int)
    parser.add_argument("--seed", type=int)
    parser.add_argument("--recordings", type=int, default=8)
    parser.add_argument("--free-share", type=float, default=0.3, help="share of effect-free sets (default 0.3)")
    parser.add_argument("--top-singles", type=int, default=3)
    parser.add_argument("--pairs-from", type=int, default=2)
    parser.add_argument("--json", help="write every set's truth and verdict (after each set)")
    args = parser.parse_args()
    if args.summarize:
        rows = []
        for path in args.summarize:
            rows += json.loads(Path(path).read_text())
        summarize(rows, args, sum(row["seconds"] for row in rows))
        return
    if args.sets is None or args.seed is None:
        parser.error("--sets and --seed are required unless --summarize is given")
    rng = np.random.default_rng(args.seed)
    rows: list[dict[str, Any]] = []
    started = time.time()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for index in range(args.sets):
                # Drawn in this order whatever happens in the set, so that the n-th set is the
                # same in a shorter run.
                seed = int(rng.integers(2**31))
                free = bool(rng.random() < args.free_share)
                offset = free and bool(rng.random() < 0.5)
                row = run_set(index, seed, free, offset, args, Path(tmp))
                rows.append(row)
                truth_label = "+".join(e["id"] for e in row["truth"]) or ("none (base offset)" if offset else "none")
                print(f"[{index + 1}/{args.sets}] {time.time() - started:.0f} s  truth {truth_label:40s} "
                      f"selected {row['selected']} {'hit' if row['hit'] else 'MISS'}", flush=True)
                if args.json:
                    Path(args.json).write_text(json.dumps(rows, indent=2) + "\n")
    except KeyboardInterrupt:
        print(f"\ninterrupted after {len(rows)} sets")
    summarize(rows, args, time.time() - started)


if __name__ == "__main__":
    main()
