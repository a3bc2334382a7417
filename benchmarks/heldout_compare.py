"""Two runs of the blind benchmark on the same sets, compared on their held-out figures (not a test).

Reads the rows that ``bench_diagnosis.py --json`` wrote for a run (``OLD``) and for its rerun with
changed code (``NEW``, e.g. ``--rerun OLD --json NEW``), matches the sets by seed and the
candidates by their effects, and prints: how many sets changed their verdict (the selected
effects), how many candidates changed their fitted parameters (a change upstream of the held-out
step: those are left out of the rest), how many of the others changed their held-out gains, how
many have a size held at its no-effect value in a held-out prediction (the rows'
``heldout_at_no_effect``; rows written before the key count as none), how many candidates'
held-out t crossed ``heldout_min_t`` either way, and how many have a recording predicted more than
``WILD_GAIN`` times worse than with no effect (a held-out gain below ``-WILD_GAIN``) in each run,
with those mended and those new. Every changed verdict and t that crossed is listed.

Usage: ``python benchmarks/heldout_compare.py OLD.json NEW.json``
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from brakegym.diagnosis import DiagnosisRules

#: A held-out gain below minus this: the recording's prediction is this many times worse than the
#: unmodified model's (gain = 1 - error / unmodified error).
WILD_GAIN = 5.0


def is_wild(candidate: dict) -> bool:
    """Whether some recording's held-out gain of ``candidate`` lies below ``-WILD_GAIN``."""
    gains = candidate.get("heldout_gain_per_recording") or []
    return any(gain is not None and gain < -WILD_GAIN for gain in gains)


def crosses(old_t: float | None, new_t: float | None, min_t: float) -> bool:
    """Whether a held-out t moved across ``min_t`` (a missing t never crosses)."""
    return old_t is not None and new_t is not None and (old_t >= min_t) != (new_t >= min_t)


def compare(old_rows: list[dict], new_rows: list[dict], min_t: float) -> dict:
    """The counts and lists printed by this script; a set of ``new_rows`` missing from
    ``old_rows`` is an error naming its seed."""
    old_by_seed = {row["seed"]: row for row in old_rows}
    counts = dict.fromkeys(
        ("sets", "candidates", "refitted", "changed", "held", "wild_before", "wild_after", "mended", "new_wild"), 0
    )
    verdicts, crossed = [], []
    for row in new_rows:
        if row["seed"] not in old_by_seed:
            raise ValueError(f"set seed {row['seed']} (index {row['index']}) is not in the old rows")
        old = old_by_seed[row["seed"]]
        counts["sets"] += 1
        if old["selected"] != row["selected"]:
            verdicts.append((row["index"], old["selected"], row["selected"]))
        old_candidates = {tuple(c["effects"]): c for c in old["candidates"] or []}
        for candidate in row["candidates"] or []:
            before = old_candidates.get(tuple(candidate["effects"]))
            if before is None:
                continue
            counts["candidates"] += 1
            if before.get("parameters") != candidate.get("parameters"):
                counts["refitted"] += 1
                continue
            counts["changed"] += before.get("heldout_gain_per_recording") != candidate.get("heldout_gain_per_recording")
            counts["held"] += bool(candidate.get("heldout_at_no_effect"))
            wild_before, wild_after = is_wild(before), is_wild(candidate)
            counts["wild_before"] += wild_before
            counts["wild_after"] += wild_after
            counts["mended"] += wild_before and not wild_after
            counts["new_wild"] += wild_after and not wild_before
            if crosses(before.get("heldout_t"), candidate.get("heldout_t"), min_t):
                crossed.append((row["index"], candidate["effects"], before["heldout_t"], candidate["heldout_t"]))
    return {**counts, "verdicts_changed": verdicts, "t_crossed": crossed}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("old", metavar="OLD.json")
    parser.add_argument("new", metavar="NEW.json")
    args = parser.parse_args()
    min_t = DiagnosisRules().heldout_min_t
    result = compare(json.loads(Path(args.old).read_text()), json.loads(Path(args.new).read_text()), min_t)
    print(f"{result['sets']} sets, {len(result['verdicts_changed'])} verdicts changed")
    for index, before, after in result["verdicts_changed"]:
        print(f"  set #{index}: {before} -> {after}")
    print(
        f"{result['candidates']} candidates in both runs, {result['refitted']} with other fitted parameters; of the "
        f"rest, held-out gains changed on {result['changed']}, a size held at no effect on {result['held']}"
    )
    print(f"held-out t crossing {min_t:g}: {len(result['t_crossed'])}")
    for index, effects, before, after in result["t_crossed"]:
        print(f"  set #{index} {effects}: {before} -> {after}")
    print(
        f"a recording's held-out gain below -{WILD_GAIN:g}: {result['wild_before']} before, "
        f"{result['wild_after']} after ({result['mended']} mended, {result['new_wild']} new)"
    )


if __name__ == "__main__":
    main()
