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

The rules are applied twice: to the effects drawn, and to the effects expressed in the data (the
key's ``expected_selected``: an effect is expressed when it moves some sample of some channel by at
least one noise sigma; a fade onset above every disc temperature reached is drawn but not in the
data, and the right verdict on such a set is the one for the effects that are). Rows written
before the key recorded expression get it by synthesizing their set again (same seed, same bytes).

Parameter recovery, on sets where a true effect was selected: the fitted value against the
truth, and whether the truth lies inside the reported 95 % interval.

Usage: ``python benchmarks/bench_diagnosis.py --sets 20 --seed 1 [--recordings 8] [--json out.json]``.
With ``--json`` each set's row is written as soon as it is done; an interrupted run (Ctrl-C)
prints the summary of the sets finished so far. Runs with different seeds can go on side by side
(one per core) and be summarized together:
``python benchmarks/bench_diagnosis.py --summarize seed1.json seed2.json``.
After a change to the diagnosis, the sets it is about can be diagnosed again from earlier rows:
``python benchmarks/bench_diagnosis.py --rerun seed1.json seed2.json --where adhesion_limit --json new.json``.
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

from brakegym.diagnosis import diagnose
from brakegym.effects import EFFECTS
from brakegym.recordings.synth import synthesize

DEFAULT_RECORDINGS = 8
CANDIDATE_KEYS = (
    "effects",
    "parameters",
    "delta_bic",
    "relevant_size",
    "heldout_gain",
    "heldout_t",
    "heldout_acts_on",
    "heldout_gain_per_recording",
)


def judge(truth: list[str], selected: list[str], indistinguishable: list[list[str]]) -> tuple[str, bool]:
    """(kind, hit) by the pass rules above."""
    named = set(selected) | {e for pair in indistinguishable for e in pair}
    kind = "none" if not truth else ("single" if len(truth) == 1 else "pair")
    if kind == "none":
        return kind, not selected
    if kind == "single":
        return kind, truth[0] in named
    return kind, bool(set(truth) & set(selected))


def expressed_effects(row: dict[str, Any]) -> list[str]:
    """The row's effects that are in the data (see the module docstring)."""
    if "expressed" in row:
        return row["expressed"]
    if not row["truth"]:
        return []
    with tempfile.TemporaryDirectory() as tmp:
        key = synthesize(
            Path(tmp) / "set",
            row.get("recordings", DEFAULT_RECORDINGS),
            row["seed"],
            random_effects=True,
            base_offset=row["base_offset"],
            key_path=Path(tmp) / "key.json",
        ).key
    if [e["parameters"] for e in key["effects"]] != [e["parameters"] for e in row["truth"]]:
        raise ValueError(
            f"set {row['index']} (seed {row['seed']}): synthesized again, it draws other effects than the row's"
        )
    return key["expected_selected"]


def run_set(
    index: int, seed: int, free: bool, offset: bool, recordings: int, args: argparse.Namespace, tmp: Path
) -> dict[str, Any]:
    """Synthesize one set, diagnose it blind, and judge the verdict against the key."""
    started = time.time()
    # Named by the set seed: a rerun may hold the same index from several runs.
    folder = tmp / f"set_{seed}"
    result = synthesize(
        folder, recordings, seed, random_effects=not free, base_offset=offset, key_path=tmp / f"key_{seed}.json"
    )
    truth = [e["id"] for e in result.key["effects"]]
    report = diagnose(folder, top_singles=args.top_singles, pairs_from=args.pairs_from).report
    selected = report["selected"]
    kind, hit = judge(truth, selected, report["indistinguishable"])
    chosen = next((c for c in report["candidates"] if c["effects"] == selected), None) if selected else None
    return {
        "index": index,
        "seed": seed,
        "recordings": recordings,
        "kind": kind,
        "truth": result.key["effects"],
        "base_offset": offset,
        "selected": selected,
        "parameters": report["parameters"],
        "ci95": chosen["ci95"] if chosen else {},
        "indistinguishable": report["indistinguishable"],
        "signature_correlations": report["signature_correlations"],
        "unconfirmed": [u["effects"] for u in report["unconfirmed"]],
        "hit": bool(hit),
        "expressed": result.key["expected_selected"],
        "seconds": round(time.time() - started, 1),
        # What a change to the selection rules can be judged on again without diagnosing anew.
        "chi2_eff_unmodified": report["chi2_eff_unmodified"],
        "screening": report["screening"],
        "candidates": [{key: c.get(key) for key in CANDIDATE_KEYS} for c in report["candidates"]],
    }


def summarize(rows: list[dict[str, Any]], args: argparse.Namespace, seconds: float) -> None:
    hits, totals = Counter(), Counter()
    confusion: dict[str, Counter] = defaultdict(Counter)
    # (truth, fitted, inside the interval, exactly the effects drawn selected)
    recovery: dict[str, list[tuple[float, float, bool, bool]]] = defaultdict(list)
    for row in rows:
        totals[row["kind"]] += 1
        hits[row["kind"]] += row["hit"]
        truth_label = "+".join(e["id"] for e in row["truth"]) or (
            "none (base offset)" if row["base_offset"] else "none"
        )
        confusion[truth_label]["+".join(row["selected"]) or "nothing"] += 1
        for effect in row["truth"]:
            if effect["id"] not in row["selected"]:
                continue
            for name, true_value in effect["parameters"].items():
                if name in row["parameters"] and name in row["ci95"]:
                    low, high = row["ci95"][name]
                    recovery[f"{effect['id']}.{name}"].append(
                        (
                            float(true_value),
                            float(row["parameters"][name]),
                            bool(low <= true_value <= high),
                            sorted(row["selected"]) == sorted(e["id"] for e in row["truth"]),
                        )
                    )
    print()
    for kind in ("single", "pair", "none"):
        if totals[kind]:
            print(f"{kind:7s} sets: {hits[kind]}/{totals[kind]} hits ({100 * hits[kind] / totals[kind]:.0f} %)")
    print(f"all     sets: {sum(hits.values())}/{sum(totals.values())}")
    expressed_hits, expressed_totals = Counter(), Counter()
    unexpressed = Counter()
    for row in rows:
        expressed = expressed_effects(row)
        kind, hit = judge(expressed, row["selected"], row["indistinguishable"])
        expressed_totals[kind] += 1
        expressed_hits[kind] += hit
        for effect in row["truth"]:
            if effect["id"] not in expressed:
                unexpressed[effect["id"]] += 1
    print("\njudged by the effects expressed in the data (moving some sample by >= 1 noise sigma):")
    for kind in ("single", "pair", "none"):
        if expressed_totals[kind]:
            print(
                f"{kind:7s} sets: {expressed_hits[kind]}/{expressed_totals[kind]} hits "
                f"({100 * expressed_hits[kind] / expressed_totals[kind]:.0f} %)"
            )
    print(f"all     sets: {sum(expressed_hits.values())}/{sum(expressed_totals.values())}")
    print("drawn but not expressed: " + (", ".join(f"{k}: {v}" for k, v in unexpressed.most_common()) or "none"))
    named_pairs = sum(bool(row["indistinguishable"]) for row in rows)
    print(f"sets with candidates named indistinguishable: {named_pairs}")
    # Rows written before the report had the key count as naming nothing unconfirmed.
    flagged = [row for row in rows if row.get("unconfirmed")]
    in_data = sum(any(set(ids) <= set(expressed_effects(row)) for ids in row["unconfirmed"]) for row in flagged)
    free = sum(not row["truth"] for row in flagged)
    print(
        f"sets with an unconfirmed candidate (not selected: acts on too few recordings): {len(flagged)}; "
        f"an effect in the data: {in_data}; in effect-free sets: {free}"
    )
    print("\nconfusion (truth -> selected):")
    for truth_label in sorted(confusion):
        print(f"  {truth_label:40s} " + ", ".join(f"{k}: {v}" for k, v in confusion[truth_label].most_common()))
    if recovery:
        print(
            "\nparameter recovery where the effect was selected (median |fitted - truth| / |truth|; "
            "truth inside the 95 % interval,\n"
            "in all those sets and in those where exactly the effects drawn were selected, the model then being right):"
        )
        for name in sorted(recovery):
            values = recovery[name]
            errors = [abs(f - t) / max(abs(t), 1e-9) for t, f, _, _ in values]
            covered = sum(c for _, _, c, _ in values)
            exact = [c for _, _, c, right in values if right]
            print(
                f"  {name:40s} n={len(values):3d}  median error {100 * float(np.median(errors)):5.1f} %  "
                f"covered {covered}/{len(values)}"
                f"  (exact model: {sum(exact)}/{len(exact)})"
            )
    # Rows written before the count was recorded hold the default.
    counts = sorted({row.get("recordings", DEFAULT_RECORDINGS) for row in rows})
    shown = "/".join(str(c) for c in counts)
    print(
        f"\nlibrary: {', '.join(EFFECTS)}; {shown} recordings per set; {len(rows)} sets, {seconds:.0f} s of diagnosis"
    )


def drawn_jobs(seed: int, sets: int, free_share: float, recordings: int):
    """(index, set seed, effect-free, base offset, recordings) of a run's sets."""
    rng = np.random.default_rng(seed)
    for index in range(sets):
        # Drawn in this order whatever happens in the set, so that the n-th set is the same in a
        # shorter run.
        set_seed = int(rng.integers(2**31))
        free = bool(rng.random() < free_share)
        offset = free and bool(rng.random() < 0.5)
        yield index, set_seed, free, offset, recordings


def rerun_jobs(
    paths: list[str],
    where: list[str] | None,
    max_sets: int | None,
    single: bool = False,
    set_seeds: list[int] | None = None,
):
    """The sets of earlier rows again (same seeds, same bytes), those whose drawn effects include
    one of ``where`` (``none``: the effect-free sets), with ``single`` only the one-effect sets,
    with ``set_seeds`` only the sets of those seeds, for a check of a change to the diagnosis on
    the sets it is about, without the whole benchmark."""
    count = 0
    for path in paths:
        for row in json.loads(Path(path).read_text()):
            if set_seeds and row["seed"] not in set_seeds:
                continue
            ids = [e["id"] for e in row["truth"]]
            if where and not any((w == "none" and not ids) or w in ids for w in where):
                continue
            if single and len(ids) != 1:
                continue
            if max_sets is not None and count >= max_sets:
                return
            count += 1
            yield row["index"], row["seed"], not ids, row["base_offset"], row.get("recordings", DEFAULT_RECORDINGS)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--summarize",
        nargs="+",
        metavar="ROWS.json",
        help="summarize the rows that earlier runs wrote with --json, and run nothing",
    )
    parser.add_argument(
        "--rerun",
        nargs="+",
        metavar="ROWS.json",
        help="diagnose the sets of earlier rows again (with --where: only those with these effects)",
    )
    parser.add_argument(
        "--where",
        action="append",
        metavar="EFFECT|none",
        help="with --rerun: sets whose drawn effects include EFFECT, or effect-free ones (repeatable)",
    )
    parser.add_argument("--max-sets", type=int, help="with --rerun: at most this many sets")
    parser.add_argument("--single", action="store_true", help="with --rerun: only the sets with one effect")
    parser.add_argument(
        "--set-seed", type=int, action="append", help="with --rerun: only the set of this seed (a row's 'seed')"
    )
    parser.add_argument("--sets", type=int)
    parser.add_argument("--seed", type=int)
    parser.add_argument("--recordings", type=int, default=DEFAULT_RECORDINGS)
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
    if args.rerun:
        jobs = list(rerun_jobs(args.rerun, args.where, args.max_sets, args.single, args.set_seed))
    elif args.sets is None or args.seed is None:
        parser.error("--sets and --seed are required unless --summarize or --rerun is given")
    else:
        jobs = list(drawn_jobs(args.seed, args.sets, args.free_share, args.recordings))
    rows: list[dict[str, Any]] = []
    started = time.time()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for number, (index, seed, free, offset, recordings) in enumerate(jobs, start=1):
                row = run_set(index, seed, free, offset, recordings, args, Path(tmp))
                rows.append(row)
                truth_label = "+".join(e["id"] for e in row["truth"]) or ("none (base offset)" if offset else "none")
                print(
                    f"[{number}/{len(jobs)}] {time.time() - started:.0f} s  truth {truth_label:40s} "
                    f"selected {row['selected']} {'hit' if row['hit'] else 'MISS'}",
                    flush=True,
                )
                if args.json:
                    Path(args.json).write_text(json.dumps(rows, indent=2) + "\n")
    except KeyboardInterrupt:
        print(f"\ninterrupted after {len(rows)} sets")
    summarize(rows, args, time.time() - started)


if __name__ == "__main__":
    main()
