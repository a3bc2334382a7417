"""The diagnosis's parametric bootstrap drawn at a coverage set's truth and at its fit (not a test).

The bootstrap of the selected model (:func:`brakegym.diagnosis.bootstrap.bootstrap`) draws its
replicates at the fitted values and reads the interval off their spread. Where that spread
changes along the way from the fit to the truth (a thermal fade's loss is read more sharply at a
smaller loss, its onset less so), an interval read off replicates drawn at the fit alone cannot
hold the truth however many there are. This script shows by how much, on the sets a coverage run
missed.

For each row of a coverage run (``benchmarks/bench_coverage.py --json ROWS.json``; ``--seed``
picks rows by their synth seed) the set is synthesized again, and at two points, the key's true
parameters and the row's fitted ones, it prints

- the effective chi^2 with the effect's parameters held there and every recording's nuisance
  fitted (from the unmodified model's and from the nuisance gridded with the effect acting, the
  lower kept), and the unmodified model's: whether the data prefer the fit to the truth, and by
  how much;
- the bootstrap drawn there with the diagnosis's replicates, seed, scatter set-up and fit
  iterations: the replicates' mean and standard deviation per parameter, and its interval.

Usage: ``python benchmarks/bootstrap_at_truth.py --rows ROWS.json [--seed S ...] [--replicates B]
[--json OUT.json]``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from bench_coverage import synthesized_set

from brakegym.diagnosis import Diagnoser, DiagnosisRules
from brakegym.diagnosis.bootstrap import bootstrap, bootstrap_seed
from brakegym.diagnosis.fitting import FitResult
from brakegym.diagnosis.weighting import Weighting
from brakegym.effects import EFFECTS

#: iterations of each nuisance fit with the effect's parameters held
HELD_FIT_ITERATIONS = 16


def held_fit(
    diagnoser: Diagnoser, effect_id: str, values: dict[str, float], unmodified: FitResult, weighting: Weighting
) -> FitResult:
    """``effect_id`` with every parameter held at ``values`` and each recording's nuisance
    fitted, from the unmodified model's nuisance and from the one gridded with the effect acting;
    the fit of lower effective chi^2 (under ``weighting``, the unmodified model's)."""
    problem = diagnoser.problem
    gridded = problem.gridded_start([effect_id], values, [], np.zeros(0))
    fits = [
        problem.fit([effect_id], start, fixed=values, max_iterations=HELD_FIT_ITERATIONS)
        for start in (unmodified.nuisance, gridded)
    ]
    return min(fits, key=lambda fit: weighting.chi2(fit.residual))


def at_point(
    diagnoser: Diagnoser,
    effect_id: str,
    values: dict[str, float],
    unmodified: FitResult,
    weighting: Weighting,
    replicates: int,
) -> dict[str, Any]:
    """The effective chi^2 and the bootstrap at the effect's parameters ``values``."""
    problem, rules = diagnoser.problem, diagnoser.rules
    held = held_fit(diagnoser, effect_id, values, unmodified, weighting)
    integer = {spec.name: values[spec.name] for spec in EFFECTS[effect_id].parameters if spec.integer}
    free = problem.free_parameters([effect_id], integer)
    theta = np.array([values[parameter.name] for parameter in free])
    fit = FitResult((effect_id,), integer, free, np.concatenate([theta, held.nuisance]), held.residual, held.jacobian)
    result = bootstrap(
        problem,
        fit,
        diagnoser.noise_models,
        replicates,
        rules.fit_iterations,
        bootstrap_seed(problem.recordings, (effect_id,)),
        rules.bootstrap_scatter_setup,
        diagnoser.decel_bias_sigma,
    )
    out: dict[str, Any] = {"values": values, "chi2_eff": float(weighting.chi2(held.residual))}
    if result is not None:
        out["bootstrap_mean"] = dict(zip(result.names, result.estimates.mean(axis=0).round(5).tolist()))
        out["bootstrap_std"] = dict(zip(result.names, result.estimates.std(axis=0, ddof=1).round(5).tolist()))
        out["ci95_bootstrap"] = result.ci95
    return out


def probe_row(row: dict[str, Any], replicates: int) -> dict[str, Any]:
    """The chi^2 and the bootstrap at a coverage row's truth and at its fit."""
    effect_id = row["effect"]
    with tempfile.TemporaryDirectory() as tmp:
        result = synthesized_set(effect_id, row["seed"], row["recordings"], row["measurement_chain"], Path(tmp))
        diagnoser = Diagnoser(result.recordings)
        unmodified = diagnoser.unmodified_fit()
        weighting = diagnoser.weighting(unmodified)
        truth = {k: float(v) for k, v in result.key["effects"][0]["parameters"].items()}
        fitted = {**truth, **{k: float(v) for k, v in row["fitted"].items()}}
        return {
            "effect": effect_id,
            "seed": row["seed"],
            "chi2_eff_unmodified": float(weighting.chi2(unmodified.residual)),
            "truth": at_point(diagnoser, effect_id, truth, unmodified, weighting, replicates),
            "fitted": at_point(diagnoser, effect_id, fitted, unmodified, weighting, replicates),
        }


def print_probe(probe: dict[str, Any]) -> None:
    print(f"{probe['effect']} seed {probe['seed']}: unmodified chi2_eff {probe['chi2_eff_unmodified']:.1f}")
    for point in ("truth", "fitted"):
        entry = probe[point]
        print(f"  at the {point:6s} {json.dumps(entry['values'])}: chi2_eff {entry['chi2_eff']:.1f}")
        for name in entry.get("bootstrap_std", {}):
            print(
                f"    {name:24s} replicates' mean {entry['bootstrap_mean'][name]:.5g} "
                f"sd {entry['bootstrap_std'][name]:.4g}, interval {entry['ci95_bootstrap'][name]}"
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--rows", required=True, nargs="+", metavar="ROWS.json", help="rows of bench_coverage.py --json"
    )
    parser.add_argument("--seed", type=int, action="append", help="only the row of this synth seed (repeatable)")
    parser.add_argument("--replicates", type=int, help="bootstrap replicates (default: the diagnosis's)")
    parser.add_argument("--json", help="write the probes")
    args = parser.parse_args()
    rows = [row for path in args.rows for row in json.loads(Path(path).read_text())]
    rows = [row for row in rows if row.get("fitted") and (not args.seed or row["seed"] in args.seed)]
    if not rows:
        parser.error("no fitted row of these seeds in the rows given")
    replicates = args.replicates if args.replicates is not None else DiagnosisRules().bootstrap_replicates
    probes = []
    for row in rows:
        probes.append(probe_row(row, replicates))
        print_probe(probes[-1])
        if args.json:
            Path(args.json).write_text(json.dumps(probes, indent=1) + "\n")


if __name__ == "__main__":
    main()
