"""Which sets of a blind-benchmark run a section's screening reaches (not a test).

For each row of the given ``bench_diagnosis.py --json`` files the set is synthesized again (same
seed, same bytes), the unmodified model fitted, and the step of its residual along position
searched (:mod:`brakegym.diagnosis.position_steps`). Printed per set: its seed, the effects drawn,
the step and its share of the braking residual's variance, and whether that share reaches
``DiagnosisRules.position_step_min_share``: only there is a ``gradient_section`` screened, and only
there can a diagnosis with the section differ from one without it. Those seeds are printed last,
for ``bench_diagnosis.py --rerun ROWS.json --set-seed SEED ...``.

Usage: ``python benchmarks/position_step_scan.py out/bench/diag_seed15.json [...]``.
"""

from __future__ import annotations

import argparse
import tempfile
import warnings
from pathlib import Path

from bench_diagnosis import rerun_jobs, synthesize_set

from brakegym.diagnosis.locate import residual_trace
from brakegym.diagnosis.pipeline import Diagnoser
from brakegym.diagnosis.position_steps import find_position_step
from brakegym.diagnosis.rules import DiagnosisRules
from brakegym.effects import GradientSection
from brakegym.recordings import read_dataset


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rows", nargs="+", help="bench_diagnosis.py --json files")
    args = parser.parse_args()
    rules = DiagnosisRules()
    reached = []
    for _, seed, free, offset, recordings, chain, form in rerun_jobs(args.rows, None, None):
        with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            folder, result = synthesize_set(seed, free, offset, recordings, Path(tmp), chain, form)
            replays = Diagnoser(read_dataset(folder).recordings).unmodified_fit().replays
        step = find_position_step(
            [residual_trace(r) for r in replays], rules.position_step_bin_m, GradientSection.TRAIN_LENGTH_M
        )
        share = step.explained_share if step is not None else 0.0
        screened = share >= rules.position_step_min_share
        if screened:
            reached.append(seed)
        drawn = "+".join(e["id"] for e in result.key["effects"]) or "none"
        where = f"{step.start_m:g}-{step.end_m:g} m, {step.gradient_permil:+.2f} permil" if step else "-"
        print(f"{seed:>11} {drawn:<45} {where:<32} share {share:.3f}{'  screened' if screened else ''}", flush=True)
    print(f"{len(reached)} sets reach the share {rules.position_step_min_share:g}:")
    print(" ".join(f"--set-seed {seed}" for seed in reached))


if __name__ == "__main__":
    main()
