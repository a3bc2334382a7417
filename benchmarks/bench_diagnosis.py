"""Blind benchmark of ``brakegym diagnose`` on synthetic sets (not a test).

For each set: ``brakegym synth`` with random effects (zero, one or two drawn from the library,
sizes drawn within their synth ranges) or, with probability ``--free-share``, an effect-free set
(half of them with ``--base-offset``); then the diagnosis, which never reads the key. Printed:
the hit rate and the confusion matrix of truth (rows) against what was selected (columns).

Pass rules, fixed before running:
- a set with one effect is a hit when that effect is selected, or named indistinguishable from
  what was selected;
- a set with two effects is a hit when at least one of them is selected (both: full hit, counted
  apart; and apart again, one selected with the pair of both reported as indistinguishable from
  it, ``single_or_pair``);
- an effect-free set is a hit when nothing is selected (its misses are the false positives);
- a set with effects outside the library and none of the library (a model form's, e.g.
  ``real_train``'s contact-pressure friction and ED brake; kind ``unexplained``) is a hit when
  nothing is selected: the right verdict is "unexplained", with no confident wrong name. Whether
  the verdict also says the model misses the data (the report's ``unexplained``) is counted apart.
  A set with library effects as well is judged by those.

The rules are applied twice: to the effects drawn, and to the effects expressed in the data (the
key's ``expected_selected``: an effect is expressed when it moves some sample of some channel by at
least one noise sigma; a fade onset above every disc temperature reached is drawn but not in the
data, and the right verdict on such a set is the one for the effects that are). Rows written
before the key recorded expression get it by synthesizing their set again (same seed, same bytes).

Parameter recovery, on sets where a true effect was selected: the fitted value against the
truth, and whether the truth lies inside the reported 95 % interval.

The summary adds, per method: pairs both ways (both named, at least one), the confusion matrix of
the effects drawn against the verdict (with ``nothing`` and ``unexplained``), the false-naming
rate (sets where an effect not drawn was selected, over all sets and per effect) and the coverage
of the nominal 95 % intervals per parameter on the sets where exactly the effects drawn were
selected, and the sets whose selected model has a parameter the data do not bound (its interval
spans the search range, the report's ``not_bounded_by_data``), with how many of those carry a
false name; ``--summary-json`` writes those numbers.

``--measurement-chain NAME`` and ``--model-form NAME`` synthesize the sets as ``brakegym synth``
does with those options, and ``--random-library along_track`` draws their effects as ``brakegym
synth --random-library along_track`` does: one effect located along the line in every set with
effects, and one of the ten beside it in half of them (rows record all three; ``--rerun`` uses a
row's own). ``--method sindy``
judges the same sets by the sparse-regression baseline (:mod:`brakegym.diagnosis.baseline`, the
``baseline`` extra); a row's ``seconds`` is the method's time alone, without the synthesis.

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

from brakegym.diagnosis import DiagnosisRules, diagnose
from brakegym.diagnosis.judging import not_bounded_by_data
from brakegym.effects import EFFECTS
from brakegym.recordings.chain import load_measurement_chain
from brakegym.recordings.model_form import load_model_form
from brakegym.recordings.synth import RANDOM_LIBRARIES, synthesize

DEFAULT_RECORDINGS = 8
METHODS = ("brakegym", "sindy")
KINDS = ("single", "pair", "none", "unexplained")
# Within this share of the range at both ends, an interval spans the search range (the diagnosis's).
RANGE_END_SHARE = DiagnosisRules().range_end_share
# A verdict's label when no effect is selected.
NOTHING, UNEXPLAINED = "nothing", "unexplained"
CANDIDATE_KEYS = (
    "effects",
    "parameters",
    "delta_bic",
    "mismatch_explained_share",
    "relevant_size",
    "heldout_gain",
    "heldout_t",
    "heldout_p",
    "heldout_acts_on",
    "heldout_gain_per_recording",
    "friction_level_shift",
    "heldout_at_no_effect",
    "resting_on_one_recording",
    "heldout_refitted",
)


def judge(
    truth: list[str], selected: list[str], indistinguishable: list[list[str]], out_of_library: list[str] = ()
) -> tuple[str, bool]:
    """(kind, hit) by the pass rules above; a set without library effects but with effects outside
    the library (``out_of_library``) is of kind ``unexplained``, a hit when nothing is selected."""
    named = set(selected) | {e for pair in indistinguishable for e in pair}
    kind = ("unexplained" if out_of_library else "none") if not truth else ("single" if len(truth) == 1 else "pair")
    if kind in ("none", "unexplained"):
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
            random_library=row.get("random_library", "default"),
            base_offset=row["base_offset"],
            key_path=Path(tmp) / "key.json",
            **synth_options(row.get("measurement_chain"), row.get("model_form")),
        ).key
    if [e["parameters"] for e in key["effects"]] != [e["parameters"] for e in row["truth"]]:
        raise ValueError(
            f"set {row['index']} (seed {row['seed']}): synthesized again, it draws other effects than the row's"
        )
    return key["expected_selected"]


def synth_options(chain: str | None, form: str | None) -> dict[str, Any]:
    """The keyword arguments of :func:`synthesize` for a measurement chain and a model form, given
    by name or file as ``brakegym synth`` takes them (None: the clean logger, the fitted model)."""
    return {
        "measurement_chain": load_measurement_chain(chain) if chain else None,
        "model_form": load_model_form(form) if form else None,
    }


def run_set(
    index: int,
    seed: int,
    free: bool,
    offset: bool,
    recordings: int,
    args: argparse.Namespace,
    tmp: Path,
    chain: str | None = None,
    form: str | None = None,
    library: str = "default",
) -> dict[str, Any]:
    """Synthesize one set (through ``chain`` and ``form``, its effects drawn from ``library``),
    judge it blind by ``args.method``, and judge the verdict against the key."""
    # Named by the set seed: a rerun may hold the same index from several runs.
    folder = tmp / f"set_{seed}"
    result = synthesize(
        folder,
        recordings,
        seed,
        random_effects=not free,
        random_library=library if not free else "default",
        base_offset=offset,
        key_path=tmp / f"key_{seed}.json",
        **synth_options(chain, form),
    )
    # Timed from here: the synthesis (with the reference integrator of a model form, longer than
    # a diagnosis) is not the method's.
    started = time.time()
    truth = [e["id"] for e in result.key["effects"]]
    out_of_library = result.key.get("expected_unexplained", [])
    common = {
        "index": index,
        "seed": seed,
        "recordings": recordings,
        "method": args.method,
        "measurement_chain": chain,
        "model_form": form,
        "random_library": library,
        "truth": result.key["effects"],
        "out_of_library": out_of_library,
        "base_offset": offset,
        "expressed": result.key["expected_selected"],
    }
    if args.method == "sindy":
        from brakegym.diagnosis.baseline import sindy_baseline

        verdict = sindy_baseline(folder)
        kind, hit = judge(truth, verdict["selected"], [], out_of_library)
        return {
            **common,
            "kind": kind,
            "selected": verdict["selected"],
            "parameters": verdict["parameters"],
            "ci95": {},
            "indistinguishable": [],
            "unconfirmed": [],
            "unexplained": verdict["unexplained"],
            "hit": bool(hit),
            "seconds": round(time.time() - started, 1),
            "sindy": {k: verdict[k] for k in verdict if k not in ("selected", "parameters", "unexplained")},
        }
    report = diagnose(folder, top_singles=args.top_singles, pairs_from=args.pairs_from).report
    selected = report["selected"]
    kind, hit = judge(truth, selected, report["indistinguishable"], out_of_library)
    chosen = next((c for c in report["candidates"] if c["effects"] == selected), None) if selected else None
    return {
        **common,
        "kind": kind,
        "selected": selected,
        "parameters": report["parameters"],
        "ci95": chosen["ci95"] if chosen else {},
        # The intervals the reported one is the hull of, for their coverage apart.
        "ci95_gauss_newton_jackknife": chosen.get("ci95_gauss_newton_jackknife", {}) if chosen else {},
        "ci95_bootstrap": chosen.get("ci95_bootstrap", {}) if chosen else {},
        "bootstrap": {key: chosen.get(key) for key in ("bootstrap_replicates", "bootstrap_mean", "bootstrap_std")}
        if chosen
        else {},
        "indistinguishable": report["indistinguishable"],
        "signature_correlations": report["signature_correlations"],
        # A pair with the selected single that the data do not tell from it (not in the judging).
        "single_or_pair": [entry["pair"] for entry in report.get("indistinguishable_single_or_pair", [])],
        "unconfirmed": [u["effects"] for u in report["unconfirmed"]],
        "unexplained": report["unexplained"] is not None,
        "hit": bool(hit),
        "seconds": round(time.time() - started, 1),
        # What a change to the selection rules can be judged on again without diagnosing anew.
        "chi2_eff_unmodified": report["chi2_eff_unmodified"],
        "screening": report["screening"],
        "position_step": report.get("position_step"),
        "fallback_screening": report.get("fallback_screening"),
        "candidates": [{key: c.get(key) for key in CANDIDATE_KEYS} for c in report["candidates"]],
    }


def set_label(row: dict[str, Any]) -> str:
    """A set's effects drawn, for the progress lines and the confusion by combination."""
    label = "+".join(e["id"] for e in row["truth"]) or ("none (base offset)" if row["base_offset"] else "none")
    if row.get("out_of_library"):
        label += " [outside: " + "+".join(row["out_of_library"]) + "]"
    return label


def row_method(row: dict[str, Any]) -> str:
    """The method that judged a row (rows written before there was a choice: the diagnosis)."""
    return row.get("method", "brakegym")


def truth_labels(row: dict[str, Any]) -> list[str]:
    """The confusion matrix's row labels of a set: its drawn effects, else ``unexplained`` (only
    effects outside the library) or ``nothing``."""
    ids = [e["id"] for e in row["truth"]]
    return ids or [UNEXPLAINED if row.get("out_of_library") else NOTHING]


def verdict_labels(row: dict[str, Any]) -> list[str]:
    """The confusion matrix's column labels of a verdict: the effects selected, else
    ``unexplained`` (the verdict says the model misses the data) or ``nothing``."""
    return list(row["selected"]) or [UNEXPLAINED if row.get("unexplained") else NOTHING]


def pair_named_or_alternative(row: dict[str, Any]) -> bool:
    """Whether a set of two effects has both selected, or one of them selected with the pair of
    both reported as its alternative (the report's ``indistinguishable_single_or_pair``: the
    data do not tell the single from the pair). Rows written before they kept that key count as
    both named only."""
    truth = {e["id"] for e in row["truth"]}
    selected = set(row["selected"])
    if truth <= selected:
        return True
    return bool(selected) and selected < truth and any(set(pair) == truth for pair in row.get("single_or_pair", []))


def metrics(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The benchmark's numbers on rows of one method (see the module documentation): hits per
    kind, pairs both ways, the effect-free and out-of-library sets, the confusion matrix, the
    false-naming rate and the interval coverage where the model is right."""
    kinds: dict[str, dict[str, int]] = {}
    for kind in KINDS:
        of_kind = [row for row in rows if row["kind"] == kind]
        if of_kind:
            kinds[kind] = {"sets": len(of_kind), "hits": sum(bool(row["hit"]) for row in of_kind)}
    pairs = [row for row in rows if row["kind"] == "pair"]
    pair_counts = {
        "sets": len(pairs),
        "both_named": sum(set(e["id"] for e in row["truth"]) <= set(row["selected"]) for row in pairs),
        "at_least_one_named": sum(bool({e["id"] for e in row["truth"]} & set(row["selected"])) for row in pairs),
        "both_named_or_alternative": sum(pair_named_or_alternative(row) for row in pairs),
    }
    outside = [row for row in rows if row["kind"] == "unexplained"]
    unexplained_counts = {
        "sets": len(outside),
        "nothing_selected": sum(not row["selected"] for row in outside),
        "said_unexplained": sum(not row["selected"] and bool(row.get("unexplained")) for row in outside),
    }
    confusion: dict[str, Counter] = defaultdict(Counter)
    row_sets: Counter = Counter()
    for row in rows:
        for drawn in truth_labels(row):
            row_sets[drawn] += 1
            for chosen in verdict_labels(row):
                confusion[drawn][chosen] += 1
    false_sets = 0
    per_effect = {}
    unbounded = {"sets": 0, "with_a_false_name": 0}
    for row in rows:
        false_name = bool(set(row["selected"]) - {e["id"] for e in row["truth"]})
        false_sets += false_name
        if not_bounded_by_data(row["selected"], row.get("ci95") or {}, RANGE_END_SHARE):
            unbounded["sets"] += 1
            unbounded["with_a_false_name"] += false_name
    for effect_id in EFFECTS:
        without = [row for row in rows if effect_id not in {e["id"] for e in row["truth"]}]
        falsely = sum(effect_id in row["selected"] for row in without)
        selected = sum(effect_id in row["selected"] for row in rows)
        per_effect[effect_id] = {
            "sets_without_it": len(without),
            "falsely_named": falsely,
            "rate": falsely / len(without) if without else None,
            "times_selected": selected,
        }
    coverage: dict[str, dict[str, Any]] = {}
    values: dict[str, list[tuple[float, float, bool]]] = defaultdict(list)
    right_model = 0
    for row in rows:
        drawn = sorted(e["id"] for e in row["truth"])
        if not drawn or sorted(row["selected"]) != drawn:
            continue
        right_model += 1
        for effect in row["truth"]:
            for name, true_value in effect["parameters"].items():
                if name in row["parameters"] and name in row.get("ci95", {}):
                    low, high = row["ci95"][name]
                    values[f"{effect['id']}.{name}"].append(
                        (float(true_value), float(row["parameters"][name]), bool(low <= true_value <= high))
                    )
    for name in sorted(values):
        errors = [abs(f - t) / max(abs(t), 1e-9) for t, f, _ in values[name]]
        coverage[name] = {
            "sets": len(values[name]),
            "covered": sum(c for _, _, c in values[name]),
            "median_relative_error": float(np.median(errors)),
        }
    return {
        "sets": len(rows),
        "kinds": kinds,
        "pairs": pair_counts,
        "unexplained": unexplained_counts,
        "confusion": {drawn: dict(confusion[drawn]) for drawn in confusion},
        "confusion_row_sets": dict(row_sets),
        "false_naming": {
            "sets_with_a_false_name": false_sets,
            "sets": len(rows),
            "rate": false_sets / len(rows) if rows else None,
            "per_effect": per_effect,
        },
        "not_bounded_by_data": unbounded,
        "coverage": {"right_model_sets": right_model, "parameters": coverage},
        "seconds_per_set": float(np.mean([row["seconds"] for row in rows])) if rows else None,
        "measurement_chains": sorted({str(row.get("measurement_chain")) for row in rows}),
        "model_forms": sorted({str(row.get("model_form")) for row in rows}),
    }


def _percent(part: int, whole: int) -> str:
    return f"{part}/{whole} ({100 * part / whole:.0f} %)" if whole else f"{part}/{whole}"


CONFUSION_ORDER = (NOTHING, UNEXPLAINED, *EFFECTS)


def confusion_legend() -> str:
    """The confusion tables' column numbers."""
    return "  columns: " + ", ".join(f"{i}={label}" for i, label in enumerate(CONFUSION_ORDER))


def confusion_table(numbers: dict[str, Any]) -> list[str]:
    """The confusion matrix as text: effects drawn (rows, with the number of sets) x verdicts
    (columns, numbered as in :func:`confusion_legend`). A set with two effects drawn or selected
    counts in each of their cells."""
    lines = [f"  {'drawn':24s} {'sets':>4s} " + " ".join(f"{i:>3d}" for i in range(len(CONFUSION_ORDER)))]
    for drawn in CONFUSION_ORDER:
        if drawn not in numbers["confusion"]:
            continue
        cells = numbers["confusion"][drawn]
        lines.append(
            f"  {drawn:24s} {numbers['confusion_row_sets'][drawn]:4d} "
            + " ".join(f"{cells.get(label, 0) or '.':>3}" for label in CONFUSION_ORDER)
        )
    return lines


def print_metrics(numbers: dict[str, Any]) -> None:
    """The new tables (pairs both ways, out-of-library sets, confusion, false naming, coverage)."""
    pairs = numbers["pairs"]
    if pairs["sets"]:
        print(
            f"\npairs: both named {_percent(pairs['both_named'], pairs['sets'])}, "
            f"at least one named {_percent(pairs['at_least_one_named'], pairs['sets'])}, "
            f"both named or one selected with the pair reported as its alternative "
            f"{_percent(pairs['both_named_or_alternative'], pairs['sets'])}"
        )
    outside = numbers["unexplained"]
    if outside["sets"]:
        print(
            f"sets with only effects outside the library: nothing selected "
            f"{_percent(outside['nothing_selected'], outside['sets'])}, said unexplained "
            f"{_percent(outside['said_unexplained'], outside['sets'])}"
        )
    print("\nconfusion matrix (effects drawn x verdict):")
    for line in [confusion_legend(), *confusion_table(numbers)]:
        print(line)
    false = numbers["false_naming"]
    print(
        f"\nfalse naming (an effect selected that was not drawn): "
        f"{_percent(false['sets_with_a_false_name'], false['sets'])} of the sets"
    )
    for effect_id, entry in false["per_effect"].items():
        if entry["falsely_named"] or entry["times_selected"]:
            print(
                f"  {effect_id:24s} named in {_percent(entry['falsely_named'], entry['sets_without_it'])} "
                f"of the sets without it; selected {entry['times_selected']} times"
            )
    unbounded = numbers["not_bounded_by_data"]
    print(
        f"selected with a parameter the data do not bound (its 95 % interval spans the search range): "
        f"{unbounded['sets']} sets, {unbounded['with_a_false_name']} of them with a false name"
    )
    coverage = numbers["coverage"]
    print(
        f"\n95 % interval coverage where exactly the effects drawn were selected ({coverage['right_model_sets']} sets):"
    )
    if not coverage["parameters"]:
        print("  no intervals")
    for name, entry in coverage["parameters"].items():
        print(
            f"  {name:40s} covered {_percent(entry['covered'], entry['sets']):14s} "
            f"median error {100 * entry['median_relative_error']:5.1f} %"
        )


def print_side_by_side(by_method: dict[str, dict[str, Any]]) -> None:
    """The methods' confusion matrices next to each other."""
    tables = {method: confusion_table(numbers) for method, numbers in by_method.items()}
    width = max(len(line) for lines in tables.values() for line in lines)
    print("\nconfusion matrices side by side: " + " | ".join(tables))
    print(confusion_legend())
    height = max(len(lines) for lines in tables.values())
    for i in range(height):
        print(" | ".join((lines[i] if i < len(lines) else "").ljust(width) for lines in tables.values()))


def summarize(rows: list[dict[str, Any]], seconds: float, summary_json: str | None = None) -> dict[str, Any]:
    """Print the summary of rows, one block per method and, with several, their confusion
    matrices side by side; write the numbers to ``summary_json``."""
    methods = sorted({row_method(row) for row in rows}, key=lambda m: METHODS.index(m) if m in METHODS else 99)
    by_method = {}
    for method in methods:
        of_method = [row for row in rows if row_method(row) == method]
        print(f"\n===== method: {method} ({len(of_method)} sets) =====")
        summarize_method(of_method, sum(row["seconds"] for row in of_method) if len(methods) > 1 else seconds)
        by_method[method] = metrics(of_method)
        print_metrics(by_method[method])
    if len(by_method) > 1:
        print_side_by_side(by_method)
    if summary_json:
        Path(summary_json).write_text(json.dumps(by_method, indent=2) + "\n")
    return by_method


def summarize_method(rows: list[dict[str, Any]], seconds: float) -> None:
    hits, totals = Counter(), Counter()
    confusion: dict[str, Counter] = defaultdict(Counter)
    # (truth, fitted, inside the interval, exactly the effects drawn selected)
    recovery: dict[str, list[tuple[float, float, bool, bool]]] = defaultdict(list)
    for row in rows:
        totals[row["kind"]] += 1
        hits[row["kind"]] += row["hit"]
        confusion[set_label(row)]["+".join(row["selected"]) or "nothing"] += 1
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
    for kind in KINDS:
        if totals[kind]:
            print(f"{kind:7s} sets: {hits[kind]}/{totals[kind]} hits ({100 * hits[kind] / totals[kind]:.0f} %)")
    print(f"all     sets: {sum(hits.values())}/{sum(totals.values())}")
    expressed_hits, expressed_totals = Counter(), Counter()
    unexpressed = Counter()
    for row in rows:
        expressed = expressed_effects(row)
        kind, hit = judge(expressed, row["selected"], row["indistinguishable"], row.get("out_of_library", []))
        expressed_totals[kind] += 1
        expressed_hits[kind] += hit
        for effect in row["truth"]:
            if effect["id"] not in expressed:
                unexpressed[effect["id"]] += 1
    print("\njudged by the effects expressed in the data (moving some sample by >= 1 noise sigma):")
    for kind in KINDS:
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
    print("\nconfusion by combination (truth -> selected):")
    for label in sorted(confusion):
        print(f"  {label:40s} " + ", ".join(f"{k}: {v}" for k, v in confusion[label].most_common()))
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


def drawn_jobs(
    seed: int,
    sets: int,
    free_share: float,
    recordings: int,
    chain: str | None = None,
    form: str | None = None,
    library: str = "default",
):
    """(index, set seed, effect-free, base offset, recordings, measurement chain, model form,
    random library) of a run's sets."""
    rng = np.random.default_rng(seed)
    for index in range(sets):
        # Drawn in this order whatever happens in the set, so that the n-th set is the same in a
        # shorter run.
        set_seed = int(rng.integers(2**31))
        free = bool(rng.random() < free_share)
        offset = free and bool(rng.random() < 0.5)
        yield index, set_seed, free, offset, recordings, chain, form, library


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
    the sets it is about, without the whole benchmark; each set through the measurement chain
    and the model form its row names."""
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
            yield (
                row["index"],
                row["seed"],
                not ids,
                row["base_offset"],
                row.get("recordings", DEFAULT_RECORDINGS),
                row.get("measurement_chain"),
                row.get("model_form"),
                row.get("random_library", "default"),
            )


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
    parser.add_argument(
        "--skip-sets",
        type=int,
        default=0,
        metavar="N",
        help="begin after the first N sets of --sets/--seed (the n-th set is the same in any run: resume an "
        "interrupted run, its rows in another --json file)",
    )
    parser.add_argument("--recordings", type=int, default=DEFAULT_RECORDINGS)
    parser.add_argument("--free-share", type=float, default=0.3, help="share of effect-free sets (default 0.3)")
    parser.add_argument("--top-singles", type=int, default=3)
    parser.add_argument("--pairs-from", type=int, default=2)
    parser.add_argument("--json", help="write every set's truth and verdict (after each set)")
    parser.add_argument(
        "--measurement-chain",
        metavar="NAME|FILE.yaml",
        help="synthesize every set through this measurement chain (as brakegym synth; e.g. real)",
    )
    parser.add_argument(
        "--model-form",
        metavar="NAME|FILE.yaml",
        help="synthesize every set with this model form (as brakegym synth; e.g. real_train)",
    )
    parser.add_argument(
        "--random-library",
        choices=RANDOM_LIBRARIES,
        default="default",
        help="what a set's effects are drawn from (as brakegym synth --random-library): default, or along_track "
        "(one effect located along the line in every set with effects)",
    )
    parser.add_argument(
        "--method",
        choices=METHODS,
        default="brakegym",
        help="judge the sets by the diagnosis (default) or by the SINDy baseline (needs brakegym[baseline])",
    )
    parser.add_argument("--summary-json", metavar="FILE", help="write the summary's numbers, per method, as JSON")
    args = parser.parse_args()
    if args.summarize:
        rows = []
        for path in args.summarize:
            rows += json.loads(Path(path).read_text())
        summarize(rows, sum(row["seconds"] for row in rows), args.summary_json)
        return
    if args.rerun and args.skip_sets:
        parser.error("--skip-sets belongs to a run of --sets/--seed; with --rerun choose sets by --set-seed")
    if args.rerun and (args.measurement_chain or args.model_form or args.random_library != "default"):
        parser.error(
            "--rerun synthesizes each set through the chain, model form and random library its row names; drop those"
        )
    if args.rerun:
        jobs = list(rerun_jobs(args.rerun, args.where, args.max_sets, args.single, args.set_seed))
    elif args.sets is None or args.seed is None:
        parser.error("--sets and --seed are required unless --summarize or --rerun is given")
    else:
        # Fail on a bad name before the first set.
        synth_options(args.measurement_chain, args.model_form)
        if not 0 <= args.skip_sets < args.sets:
            parser.error(f"--skip-sets {args.skip_sets}: must be at least 0 and below --sets {args.sets}")
        jobs = list(
            drawn_jobs(
                args.seed,
                args.sets,
                args.free_share,
                args.recordings,
                args.measurement_chain,
                args.model_form,
                args.random_library,
            )
        )[args.skip_sets :]
    rows: list[dict[str, Any]] = []
    started = time.time()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for number, (index, seed, free, offset, recordings, chain, form, library) in enumerate(jobs, start=1):
                row = run_set(index, seed, free, offset, recordings, args, Path(tmp), chain, form, library)
                rows.append(row)
                print(
                    f"[{number}/{len(jobs)}] {time.time() - started:.0f} s  truth {set_label(row):40s} "
                    f"selected {row['selected']} {'hit' if row['hit'] else 'MISS'} ({row['seconds']} s)",
                    flush=True,
                )
                if args.json:
                    Path(args.json).write_text(json.dumps(rows, indent=2) + "\n")
    except KeyboardInterrupt:
        print(f"\ninterrupted after {len(rows)} sets")
    summarize(rows, time.time() - started, args.summary_json)


if __name__ == "__main__":
    main()
