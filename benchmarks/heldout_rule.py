"""The held-out rule on its degrees of freedom, read off benchmark rows (not a test).

For every single candidate of the rows that ``bench_diagnosis.py --json`` wrote, that passes
the other rules (relevant in size, and a BIC lower by ``select_delta_bic``; a friction level's
shared-shift test instead where the row records it) and acts on at least
``heldout_min_recordings`` recordings: whether its held-out t passes the rule of brakegym up to
0.2 (``heldout_min_t`` whatever the number of recordings) and the rule now (that t, and a
one-sided p-value of Student's t on the recordings acted on less one of at most
``heldout_max_p``), and whether the effect is in the set (drawn). Printed: the counts of drawn
and not drawn candidates each rule passes, and every candidate the former rule alone passes. The
p-value is computed from the row's t and its recordings, so rows written before the rule changed
can be read.

A friction level is judged by a paired t over every recording's held-out gain, which one
recording's large gain can keep short of the rule while the others all gain a little. Beside
it, a one-sided Wilcoxon signed-rank test on the same gains (``heldout_gain_per_recording``),
which that recording moves no more than any other with the largest gain: printed are the counts
each passes (at ``heldout_max_p``) and every level on which the two disagree.

Usage: ``python benchmarks/heldout_rule.py ROWS.json [ROWS.json ...]``
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from scipy import stats

from brakegym.diagnosis import DiagnosisRules
from brakegym.statistics import paired_t_tail


def judged_singles(rows: list[dict], rules: DiagnosisRules) -> list[dict]:
    """The single candidates of ``rows`` that pass every rule but the held-out one."""
    out = []
    for row in rows:
        drawn = {effect["id"] for effect in row["truth"]}
        for candidate in row.get("candidates") or []:
            if len(candidate["effects"]) != 1 or candidate.get("heldout_t") is None:
                continue
            (effect_id,) = candidate["effects"]
            shift = candidate.get("friction_level_shift")
            if effect_id == "friction_level" and shift is not None:
                other_rules = abs(shift["z"]) >= rules.friction_level_min_z
            elif effect_id == "friction_level":
                other_rules = True  # rows before the shift was recorded: the held-out rule alone
            else:
                other_rules = candidate["delta_bic"] <= rules.select_delta_bic
            recordings = len(candidate["heldout_acts_on"])
            if not (candidate["relevant_size"] and other_rules and recordings >= rules.heldout_min_recordings):
                continue
            t = float(candidate["heldout_t"])
            p = paired_t_tail(t, recordings)
            gains = candidate.get("heldout_gain_per_recording")
            out.append(
                {
                    "rank_p": signed_rank_p(gains) if effect_id == "friction_level" and gains else None,
                    "set": f"{row.get('file', '')}#{row['index']}",
                    "effect": effect_id,
                    "drawn": effect_id in drawn,
                    "recordings": recordings,
                    "t": t,
                    "p": p,
                    "former": t >= rules.heldout_min_t,
                    "now": t >= rules.heldout_min_t and p <= rules.heldout_max_p,
                }
            )
    return out


def signed_rank_p(gains: list[float]) -> float:
    """One-sided p-value of Wilcoxon's signed-rank test that the gains lie above 0 (recordings
    with no gain at all left out; none left: 1)."""
    values = np.asarray(gains, float)
    if not np.any(values != 0.0):
        return 1.0
    return float(stats.wilcoxon(values, alternative="greater").pvalue)


def print_rank_test(singles: list[dict], rules: DiagnosisRules) -> None:
    """The friction levels: the rule now against the signed-rank test, and where they disagree."""
    levels = [c for c in singles if c["rank_p"] is not None]
    if not levels:
        return
    rank = f"signed-rank p <= {rules.heldout_max_p:g}"
    for label, passes in (("the rule now", lambda c: c["now"]), (rank, lambda c: c["rank_p"] <= rules.heldout_max_p)):
        true = sum(1 for c in levels if passes(c) and c["drawn"])
        false = sum(1 for c in levels if passes(c) and not c["drawn"])
        print(f"  friction level, {label}: passes {true} drawn, {false} not drawn")
    print("friction levels on which the two disagree:")
    for c in sorted(levels, key=lambda c: c["rank_p"]):
        if c["now"] != (c["rank_p"] <= rules.heldout_max_p):
            drawn = "drawn" if c["drawn"] else "NOT drawn"
            print(f"  {c['set']}: ({drawn}) t {c['t']:.2f}, p {c['p']:.3f}; signed-rank p {c['rank_p']:.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("rows", nargs="+", metavar="ROWS.json")
    args = parser.parse_args()
    rules = DiagnosisRules()
    rows = []
    for path in args.rows:
        for row in json.loads(Path(path).read_text()):
            rows.append({**row, "file": Path(path).name})
    singles = judged_singles(rows, rules)
    print(f"{len(rows)} sets; {len(singles)} single candidates passing every rule but the held-out one")
    former = f"t >= {rules.heldout_min_t:g}"
    for label, key in ((former, "former"), (f"{former} and p <= {rules.heldout_max_p:g}", "now")):
        true = sum(1 for c in singles if c[key] and c["drawn"])
        false = sum(1 for c in singles if c[key] and not c["drawn"])
        print(f"  {label}: passes {true} drawn, {false} not drawn")
    # The rule now asks the former's t and more, so only the former can pass alone.
    print(f"passed {former} alone:")
    for c in sorted((c for c in singles if c["former"] and not c["now"]), key=lambda c: c["p"]):
        drawn = "drawn" if c["drawn"] else "NOT drawn"
        print(f"  {c['set']}: {c['effect']} ({drawn}) t {c['t']:.2f} over {c['recordings']}, p {c['p']:.3f}")
    passing_true = [c["p"] for c in singles if c["former"] and c["drawn"]]
    if passing_true:
        print(f"largest p of a drawn effect passing {former}: {max(passing_true):.4f}")
    print_rank_test(singles, rules)


if __name__ == "__main__":
    main()
