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

Usage: ``python benchmarks/bench_diagnosis.py --sets 20 --seed 1 [--recordings 8]``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

from brakegym.recordings.diagnosis import diagnose
from brakegym.recordings.effects import EFFECTS
from brakegym.recordings.synth import synthesize


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=int, required=True)
    parser.add_argument("--seed", type=int, required=True)
    parser.add_argument("--recordings", type=int, default=8)
    parser.add_argument("--free-share", type=float, default=0.3, help="share of effect-free sets (default 0.3)")
    parser.add_argument("--top-singles", type=int, default=3)
    parser.add_argument("--pairs-from", type=int, default=2)
    parser.add_argument("--json", help="write every set's truth and verdict")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    confusion: dict[str, Counter] = defaultdict(Counter)
    hits = Counter()
    totals = Counter()
    rows = []
    started = time.time()
    with tempfile.TemporaryDirectory() as tmp:
        for index in range(args.sets):
            seed = int(rng.integers(2**31))
            folder = Path(tmp) / f"set_{index:04d}"
            free = rng.random() < args.free_share
            offset = free and rng.random() < 0.5
            result = synthesize(folder, args.recordings, seed, random_effects=not free, base_offset=offset,
                                key_path=Path(tmp) / f"key_{index:04d}.json")
            truth = [e["id"] for e in result.key["effects"]]
            report = diagnose(folder, top_singles=args.top_singles, pairs_from=args.pairs_from).report
            selected = report["selected"]
            named = set(selected) | {e for pair in report["indistinguishable"] for e in pair}
            kind = "none" if not truth else ("single" if len(truth) == 1 else "pair")
            hit = (not selected) if kind == "none" else (truth[0] in named if kind == "single" else bool(set(truth) & set(selected)))
            totals[kind] += 1
            hits[kind] += hit
            truth_label = "+".join(truth) or ("none (base offset)" if offset else "none")
            confusion[truth_label]["+".join(selected) or "nothing"] += 1
            rows.append({"seed": seed, "truth": result.key["effects"], "base_offset": result.key["base_offset"],
                         "selected": selected, "parameters": report["parameters"], "indistinguishable": report["indistinguishable"], "hit": bool(hit)})
            print(f"[{index + 1}/{args.sets}] {time.time() - started:.0f} s  truth {truth_label:40s} selected {selected} {'hit' if hit else 'MISS'}", flush=True)
    print()
    for kind in ("single", "pair", "none"):
        if totals[kind]:
            print(f"{kind:7s} sets: {hits[kind]}/{totals[kind]} hits ({100 * hits[kind] / totals[kind]:.0f} %)")
    print(f"all     sets: {sum(hits.values())}/{sum(totals.values())}")
    print("\nconfusion (truth -> selected):")
    for truth_label in sorted(confusion):
        print(f"  {truth_label:40s} " + ", ".join(f"{k}: {v}" for k, v in confusion[truth_label].most_common()))
    print(f"\nlibrary: {', '.join(EFFECTS)}; {args.recordings} recordings per set; {time.time() - started:.0f} s")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2) + "\n")


if __name__ == "__main__":
    main()
