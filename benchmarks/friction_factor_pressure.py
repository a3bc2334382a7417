"""Do the recordings' friction factors follow their brake pressure? A study, not a test.

Pad friction that falls with the contact pressure (the ``real_train`` model form's
``contact_pressure_friction``, mu x (F_clamp / 40 kN)^-0.1) acts on every recording: under it each
recording's friction factor should fall with its clamp force. This fits the unmodified model to
each folder of recordings (as ``brakegym diagnose`` does first), and regresses the log of each
recording's fitted friction factor on the log of its mean cylinder pressure while braking: the
slope, its standard error and t on n - 2 degrees of freedom. The clamp force is k_c (p - p_0) (spec
Section 4), so a power law in force is steeper in pressure by p / (p - p_0).

    brakegym synth DIR --recordings 8 --seed 273368831 --random-effects \\
        --measurement-chain real --model-form real_train
    python benchmarks/friction_factor_pressure.py DIR [DIR ...]
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np
from scipy import stats

from brakegym.diagnosis.fitting import FRICTION_FACTOR
from brakegym.diagnosis.pipeline import Diagnoser
from brakegym.recordings import read_dataset
from brakegym.recordings.replay import bridged_pressures_bar

#: samples whose mean cylinder pressure exceeds this count as braking, bar
BRAKING_PRESSURE_BAR = 0.3


def factors_and_pressures(folder: str) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Each recording's stem, its friction factor fitted with the unmodified model, and its mean
    cylinder pressure while braking (bar)."""
    recordings = read_dataset(folder).recordings
    diagnoser = Diagnoser(recordings)
    fit = diagnoser.unmodified_fit()
    factors = fit.x[diagnoser.problem.nuisance_block(FRICTION_FACTOR, len(fit.free))]
    pressures = []
    for recording in recordings:
        pressure = np.nanmean(bridged_pressures_bar(recording), axis=1)
        pressures.append(float(np.mean(pressure[pressure > BRAKING_PRESSURE_BAR])))
    return [r.stem for r in recordings], np.asarray(factors), np.asarray(pressures)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", metavar="DIR", help="a folder of recordings")
    args = parser.parse_args()
    for folder in args.folders:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            stems, factors, pressures = factors_and_pressures(folder)
        print(folder)
        for stem, factor, pressure in zip(stems, factors, pressures, strict=True):
            print(f"  {stem:12s} friction factor {factor:.4f}   mean braking pressure {pressure:.2f} bar")
        fit = stats.linregress(np.log(pressures), np.log(factors))
        print(
            f"  log factor on log pressure: slope {fit.slope:+.3f} +- {fit.stderr:.3f}, "
            f"t {fit.slope / fit.stderr:+.2f}, two-sided p {fit.pvalue:.3f} ({len(stems) - 2} degrees of freedom)"
        )


if __name__ == "__main__":
    main()
