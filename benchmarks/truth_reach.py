"""How closely the diagnosis's model reaches a synthesized set at its truth, under each scatter (not a test).

Synthesizes one set (``--seed``, random library effects without a base offset, as
``bench_diagnosis.py`` draws its clean sets) under several scatter set-ups. The applications, the
effects and the noise come from streams of their own, so the sets differ in their scatter alone.
Each is evaluated with the key's effects at their true parameters, every recording's nuisance
(initial speed, disc temperature, friction factor) refitted to convergence
(``FitProblem.refit_nuisance``), and the script prints per recording the effective chi^2 (its
friction-factor prior row included) over the recording's effective samples, and the fitted
friction factor. Near 1 the model reaches the data at the truth; far above it, with friction
factors on their bounds, the synthesized data vary something that the nuisance does not hold,
and a diagnosis on that set judges fits that cannot reach it.

Set-ups: ``ds`` (no scatter), ``mcs-75-25`` (what ``brakegym synth`` writes), and three written to
a temporary config folder: the friction drawn per application only (``global_fraction`` 0.75),
per disc only (``individual_fraction`` 0.25), and the running resistance's A per application only.

Usage: ``python benchmarks/truth_reach.py --seed 1442919330`` (clean seed 18's set 43: a gradient
with an adhesion limit); ``--recordings`` (default 8).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from brakegym.config import config_path
from brakegym.diagnosis.fitting import FRICTION_FACTOR
from brakegym.diagnosis.pipeline import Diagnoser
from brakegym.effects import EFFECTS, in_library_order
from brakegym.recordings import read_dataset
from brakegym.recordings.synth import synthesize

#: set-ups written for this script: (global_fraction, individual_fraction, resistance_scatter)
ONE_SCATTER_SETUPS = {
    "friction-per-application": (0.75, 0.0, False),
    "friction-per-disc": (0.0, 0.25, False),
    "resistance-per-application": (0.0, 0.0, True),
}
SETUPS = ("ds", *ONE_SCATTER_SETUPS, "mcs-75-25")


def write_setups(folder: Path) -> None:
    """The one-scatter set-ups of ``ONE_SCATTER_SETUPS`` as config files under ``folder``."""
    (folder / "setups").mkdir(parents=True)
    for name, (global_fraction, individual_fraction, resistance) in ONE_SCATTER_SETUPS.items():
        (folder / "setups" / f"{name}.yaml").write_text(
            f"name: {name}\ndescription: one scatter of mcs-75-25 alone (benchmarks/truth_reach.py)\n"
            f"global_fraction: {global_fraction}\nindividual_fraction: {individual_fraction}\n"
            f"resistance_scatter: {str(resistance).lower()}\n"
        )


def truth_reach(folder: Path, key: dict) -> tuple[float, np.ndarray, np.ndarray]:
    """Total effective chi^2, per recording chi^2 over effective samples, and friction factors of
    the set in ``folder`` with the effects of ``key`` at their true parameters."""
    diagnoser = Diagnoser(read_dataset(folder).recordings)
    problem = diagnoser.problem
    baseline = diagnoser.unmodified_fit()
    weighting = diagnoser.weighting(baseline)
    true_values = {name: value for effect in key["effects"] for name, value in effect["parameters"].items()}
    ids = in_library_order(tuple(effect["id"] for effect in key["effects"]))
    fixed = {spec.name: true_values[spec.name] for eid in ids for spec in EFFECTS[eid].parameters if spec.integer}
    free = problem.free_parameters(list(ids), fixed)
    start = np.concatenate([[true_values[p.name] for p in free], baseline.nuisance])
    x = problem.refit_nuisance(ids, fixed, free, start)
    residual = problem.simulate(ids, fixed, free, x[None])[0][0]
    measured = problem.channel_of >= 0
    samples = np.array([weighting.weights[measured & (problem.recording_of == i)].sum() for i in range(problem.n)])
    factors = x[problem.nuisance_block(FRICTION_FACTOR, len(free))]
    return weighting.chi2(residual), weighting.recording_sse(residual) / samples, factors


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, required=True, help="the set's seed (bench_diagnosis.py prints each set's)")
    parser.add_argument("--recordings", type=int, default=8)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        scratch = Path(scratch)
        write_setups(scratch / "configs")
        with config_path(scratch / "configs"):
            for setup in SETUPS:
                folder = scratch / setup
                key_path = scratch / f"{setup}_key.json"
                synthesize(
                    folder,
                    args.recordings,
                    args.seed,
                    random_effects=True,
                    base_offset=False,
                    key_path=key_path,
                    scatter_setup=setup,
                )
                key = json.loads(key_path.read_text())
                chi2, per_sample, factors = truth_reach(folder, key)
                truth = ", ".join(f"{e['id']} {e['parameters']}" for e in key["effects"]) or "no effect"
                print(f"{setup:27s} chi^2 {chi2:8.1f}  truth: {truth}")
                print(f"{'':27s} chi^2 / effective samples per recording {np.round(per_sample, 1).tolist()}")
                print(f"{'':27s} friction factors {np.round(factors, 3).tolist()}", flush=True)


if __name__ == "__main__":
    main()
