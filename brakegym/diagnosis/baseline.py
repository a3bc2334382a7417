"""A baseline for the diagnosis: sparse regression (SINDy's sequentially thresholded least
squares, PySINDy's ``STLSQ``) of the residual between the recordings and the nominal model on a
library of candidate terms, each term mapped to an effect of the library.

This is what a user would reach for without :mod:`brakegym.diagnosis`: replay every recording
with the nominal model from its measured initial state (transducer zero offsets removed, as the
diagnosis does), take the residuals, and regress them on terms built from the replayed states.
It needs the ``baseline`` extra (``pip install brakegym[baseline]``: PySINDy); the benchmark
(``benchmarks/bench_diagnosis.py --method sindy``) judges it on the same sets as the diagnosis.
It is no part of ``brakegym diagnose``.

The regression stacks up to three blocks of rows, each divided by its noise level (so every row
is in noise sigmas), over the samples where the train moves:

- ``kinematic``: minus the time derivative of the speed residual (what the train's motion did
  that the model did not), m/s^2;
- ``decel``: the deceleration channel's residual (an accelerometer, or differentiated speed);
- ``temperature``: the disc temperature residual, K.

The candidate terms (columns; zero in the blocks they do not act on) and the effects they name:

| term | column | blocks | effect, parameter from the coefficient c |
|---|---|---|---|
| ``gravity`` | 1 | those from speed | ``gradient``, gradient_permil = 1000 c / g |
| ``force_per_mass`` | 1 / m | motion | ``running_resistance`` (A + c) |
| ``speed_force_per_mass`` | v / m | motion | ``running_resistance`` (B + c) |
| ``speed2_force_per_mass`` | v^2 / m | motion | ``running_resistance`` (C + c) |
| ``brake@<stem>`` | a_brake on that recording's rows | motion | ``friction_level`` (see below) |
| ``brake_squared`` | a_brake^2 | motion | ``adhesion_limit`` (a cap flattens the largest decelerations) |
| ``brake_hot`` | a_brake max(T - 150 degC, 0) / 100 K | motion | ``thermal_fade``, loss_per_100K = -c |
| ``brake_wet`` | a_brake exp(-E / 0.5 MJ) | motion | ``wet_pads``, initial_loss = -c |
| ``speed_scale`` | a (brake and resistance) | those from speed | ``speed_sensor_scale``, scale = 1 + c |
| ``temperature_rate`` | -dT/dt | temperature | ``temperature_sensor_lag``, tau_s = c |

(a_brake: the replay's deceleration less the nominal running resistance over the mass; T and E
the replay's friction-surface temperature and heat per disc; "motion": the kinematic and the
deceleration blocks; "those from speed": the kinematic block, and the deceleration block when the
deceleration is differentiated speed, since an accelerometer sees neither a gradient nor the speed
sensor's scale.) The fade onset (150 degC) and the drying energy (0.5 MJ) are fixed inside the
library's synth ranges (ASSUMED: a linear library cannot fit them). Each recording has a friction
term of its own (its friction scatter), as the diagnosis fits a friction factor per recording;
``friction_level`` is named when the mean of their coefficients is 0.04 or more off 0 (the
effect's relevant change), mu_scale = 1 + that mean: without them the friction
scatter of eight recordings leaves a residual of several noise sigmas that the other terms take up.
Each recording has a term of its own in the temperature block too, its replayed temperature rise
(the heat its friction scatter brings; it names no effect). Rows where the measured or the
replayed speed is below ``MIN_SPEED_MPS`` are left out of the motion blocks.
``brake_unit_failure`` and ``rotating_mass`` have no term: a failed unit removes a share of the
brake force, which the friction terms take, and a rotating mass scales the whole deceleration,
brake plus resistance, a sum of the other columns (a column for it would make the library
singular).

Each column is scaled to unit RMS over the stacked rows, so a coefficient is the RMS of the term's
contribution in noise sigmas, and STLSQ keeps the terms above ``THRESHOLD_NOISE_SIGMAS`` (fixed
before the benchmark ran, not tuned on it). An effect is named when one of its terms is kept.
With nothing named, the verdict is ``unexplained`` when the residual's RMS exceeds
``UNEXPLAINED_RMS_OVER_NOISE`` noise sigmas, else nothing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.signal import savgol_coeffs

from ..effects import EFFECTS, FrictionLevel
from ..recordings import Recording, read_dataset
from ..recordings.columns import DECEL, DISC_TEMPERATURE, SPEED
from ..recordings.replay import replay_batch
from ..units import STANDARD_GRAVITY_MPS2
from .inputs import initial_disc_temperature, zero_corrected
from .locate import SMOOTH_WINDOW, estimate_noise_models, residual_trace
from .rules import DiagnosisRules

#: A kept term moves the stacked residual by at least this RMS, in noise sigmas (ASSUMED).
THRESHOLD_NOISE_SIGMAS = 0.5
#: PySINDy's ridge weight, on the unit-RMS columns (its default).
RIDGE_ALPHA = 0.05
#: With nothing named, a residual RMS above this many noise sigmas is unexplained (ASSUMED).
UNEXPLAINED_RMS_OVER_NOISE = 2.0
FADE_ONSET_C = 150.0
DRYING_ENERGY_MJ = 0.5

#: Each term and the effect it names (the per-recording friction terms come after these).
TERM_EFFECTS = {
    "gravity": "gradient",
    "force_per_mass": "running_resistance",
    "speed_force_per_mass": "running_resistance",
    "speed2_force_per_mass": "running_resistance",
    "brake_squared": "adhesion_limit",
    "brake_hot": "thermal_fade",
    "brake_wet": "wet_pads",
    "speed_scale": "speed_sensor_scale",
    "temperature_rate": "temperature_sensor_lag",
}
TERMS = tuple(TERM_EFFECTS)
BLOCKS = ("kinematic", "decel", "temperature")
FRICTION_PREFIX = "brake@"
HEAT_PREFIX = "heat@"
#: Below this speed in m/s, measured or replayed, rows are left out of the motion blocks, since
#: near the stop the two stand still at different instants and the deceleration residual there is
#: a step of the full deceleration that no term describes.
MIN_SPEED_MPS = 1.0

EXTRA_HINT = "the SINDy baseline needs PySINDy: pip install 'brakegym[baseline]'"


def stlsq(features: np.ndarray, target: np.ndarray, threshold: float, alpha: float = RIDGE_ALPHA) -> np.ndarray:
    """PySINDy's sequentially thresholded least squares of ``target`` (rows) on ``features``
    (rows, terms): the sparse coefficients, one per term."""
    try:
        import pysindy
    except ImportError as exc:
        raise ImportError(f"{EXTRA_HINT} ({exc})") from None
    features = np.asarray(features, dtype=float)
    target = np.asarray(target, dtype=float)
    if features.ndim != 2 or target.shape != (features.shape[0],):
        raise ValueError(f"stlsq: features {features.shape} and target {target.shape} do not match as (rows, terms)")
    if not (np.all(np.isfinite(features)) and np.all(np.isfinite(target))):
        raise ValueError("stlsq: features and target must be finite")
    optimizer = pysindy.STLSQ(threshold=threshold, alpha=alpha)
    optimizer.fit(features, target[:, None])
    return np.asarray(optimizer.coef_, dtype=float)[0]


@dataclass
class Regression:
    """The stacked rows of a set: ``features`` (rows, terms) and ``target`` (rows), both in noise
    sigmas of their block, each row's block, and the terms (``TERMS``, then one friction
    term per recording)."""

    terms: list[str]
    features: np.ndarray
    target: np.ndarray
    block: np.ndarray  # index into BLOCKS
    noise: dict[str, float]


def _present(time_s: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    present = ~np.isnan(values)
    return time_s[present], values[present]


def _block_rows(
    target: np.ndarray, columns: dict[str, np.ndarray], rows: np.ndarray, sigma: float, block: int, terms: list[str]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    features = np.zeros((int(rows.sum()), len(terms)))
    for name, values in columns.items():
        features[:, terms.index(name)] = values[rows] / sigma
    return features, target[rows] / sigma, np.full(int(rows.sum()), block)


def regression_rows(recordings: Sequence[Recording]) -> Regression:
    """The residuals of the nominal replay of ``recordings`` and the candidate terms at every
    sample (see the module documentation)."""
    if not recordings:
        raise ValueError("the SINDy baseline needs at least one recording")
    corrected = [zero_corrected(r) for r in recordings]
    replays = replay_batch(corrected, initial_disc_C=[initial_disc_temperature(r).value_C for r in corrected])
    noise_models = estimate_noise_models(corrected, DiagnosisRules().noise_window_s)
    noise = {channel: float(model.sigma) for channel, model in noise_models.items()}
    resistance = recordings[0].vehicle.running_resistance
    terms = [*TERMS, *(FRICTION_PREFIX + r.stem for r in recordings), *(HEAT_PREFIX + r.stem for r in recordings)]
    if len(set(terms)) != len(terms):
        raise ValueError(f"the SINDy baseline needs distinct recording stems, got {[r.stem for r in recordings]}")
    parts = []
    kinematic_sigmas = []
    for recording, replayed in zip(corrected, replays):
        trace = residual_trace(replayed)
        states = replayed.states
        time = recording.time_s
        speed = states["true_speed_mps"].to_numpy()
        decel = states["true_decel_mps2"].to_numpy()
        mass = recording.mass_kg
        resisting = (resistance.A_N + resistance.B_N_per_mps * speed + resistance.C_N_per_mps2 * speed**2) / mass
        brake = decel - resisting
        surface_C = states["T_fric_C"].to_numpy() if "T_fric_C" in states else np.zeros(len(time))
        heat_MJ = states["friction_heat_MJ_per_disc"].to_numpy()
        motion = {
            "force_per_mass": np.full(len(time), 1.0 / mass),
            "speed_force_per_mass": speed / mass,
            "speed2_force_per_mass": speed**2 / mass,
            FRICTION_PREFIX + recording.stem: brake,
            "brake_squared": brake**2,
            "brake_hot": brake * np.maximum(surface_C - FADE_ONSET_C, 0.0) / 100.0,
            "brake_wet": brake * np.exp(-heat_MJ / DRYING_ENERGY_MJ),
        }
        from_speed = {"gravity": np.ones(len(time)), "speed_scale": decel}
        measured_speed = recording.speed_mps
        # The kinematic deceleration's noise: the speed noise through the differentiating smooth.
        speed_step = float(np.nanmedian(np.diff(time[~np.isnan(measured_speed)])))
        kernel = savgol_coeffs(SMOOTH_WINDOW, 2, deriv=1, delta=speed_step)
        sigma_k = noise[SPEED] * float(np.sqrt(np.sum(kernel**2)))
        kinematic_sigmas.append(sigma_k)
        fast = (speed >= MIN_SPEED_MPS) & (np.interp(time, *_present(time, measured_speed)) >= MIN_SPEED_MPS)
        rows = fast & ~np.isnan(measured_speed) & np.isfinite(trace.kinematic_decel)
        parts.append(_block_rows(trace.kinematic_decel, {**motion, **from_speed}, rows, sigma_k, 0, terms))
        if trace.decel is not None and DECEL in noise:
            rows = fast & np.isfinite(trace.decel)
            columns = dict(motion)
            if recording.metadata.decel_source == "speed":
                columns.update(from_speed)
            parts.append(_block_rows(trace.decel, columns, rows, noise[DECEL], 1, terms))
        if trace.temperature is not None and DISC_TEMPERATURE in noise:
            simulated = replayed.channels[DISC_TEMPERATURE]
            rate = np.gradient(simulated, time)
            rows = np.isfinite(trace.temperature) & np.isfinite(rate)
            columns = {"temperature_rate": -rate, HEAT_PREFIX + recording.stem: simulated - simulated[0]}
            parts.append(_block_rows(trace.temperature, columns, rows, noise[DISC_TEMPERATURE], 2, terms))
    noise["kinematic_decel"] = float(np.median(kinematic_sigmas))
    features, target, block = (np.concatenate(p) for p in zip(*parts))
    return Regression(terms, features, target, block, noise)


def _parameters(effect_id: str, coefficients: dict[str, float], recordings: Sequence[Recording]) -> dict[str, float]:
    """The effect's parameters read off its terms' coefficients (see the module documentation);
    those a linear library cannot give are left out."""
    c = coefficients
    if effect_id == "gradient":
        return {"gradient_permil": 1000.0 * c["gravity"] / STANDARD_GRAVITY_MPS2}
    if effect_id == "friction_level":
        return {"mu_scale": 1.0 + _mean_friction(c)}
    if effect_id == "thermal_fade":
        return {"onset_C": FADE_ONSET_C, "loss_per_100K": -c["brake_hot"]}
    if effect_id == "wet_pads":
        return {"initial_loss": -c["brake_wet"], "drying_energy_MJ": DRYING_ENERGY_MJ}
    if effect_id == "speed_sensor_scale":
        return {"scale": 1.0 + c["speed_scale"]}
    if effect_id == "temperature_sensor_lag":
        return {"tau_s": c["temperature_rate"]}
    if effect_id == "running_resistance":
        nominal = recordings[0].vehicle.running_resistance
        return {
            "A_N": nominal.A_N + c["force_per_mass"],
            "B_N_per_mps": nominal.B_N_per_mps + c["speed_force_per_mass"],
            "C_N_per_mps2": nominal.C_N_per_mps2 + c["speed2_force_per_mass"],
        }
    return {}


def _mean_friction(coefficients: dict[str, float]) -> float:
    """The mean of the per-recording friction terms' coefficients (a common friction level; 0
    without such terms)."""
    values = [v for t, v in coefficients.items() if t.startswith(FRICTION_PREFIX)]
    return float(np.mean(values)) if values else 0.0


def sindy_verdict(regression: Regression, recordings: Sequence[Recording]) -> dict[str, Any]:
    """The effects named by the kept terms, their parameters, and the raw coefficients."""
    terms = regression.terms
    scale = np.sqrt(np.mean(regression.features**2, axis=0))
    usable = scale > 0
    normalized = np.zeros(len(terms))
    normalized[usable] = stlsq(
        regression.features[:, usable] / scale[usable], regression.target, THRESHOLD_NOISE_SIGMAS
    )
    coefficients = np.where(usable, normalized / np.where(usable, scale, 1.0), 0.0)
    by_term = {term: float(coefficients[i]) for i, term in enumerate(terms)}
    kept = [term for i, term in enumerate(terms) if normalized[i] != 0.0]
    named = {TERM_EFFECTS[t] for t in kept if t in TERM_EFFECTS}
    if abs(_mean_friction(by_term)) >= FrictionLevel.RELEVANT_CHANGE:
        named.add(FrictionLevel.id)
    # In the library's order, as the diagnosis reports a pair.
    selected = [e for e in EFFECTS if e in named]
    parameters: dict[str, float] = {}
    for effect_id in selected:
        parameters.update({k: round(float(v), 6) for k, v in _parameters(effect_id, by_term, recordings).items()})
    rms_before = float(np.sqrt(np.mean(regression.target**2)))
    after = regression.target - regression.features @ coefficients
    rms_after = float(np.sqrt(np.mean(after**2)))
    return {
        "selected": selected,
        "parameters": parameters,
        "kept_terms": kept,
        "contribution_noise_sigmas": {t: round(float(abs(normalized[i])), 4) for i, t in enumerate(terms)},
        "coefficients": {t: float(f"{v:.6g}") for t, v in by_term.items()},
        "residual_rms_over_noise_before": round(rms_before, 3),
        "residual_rms_over_noise_after": round(rms_after, 3),
        "unexplained": not selected and rms_before > UNEXPLAINED_RMS_OVER_NOISE,
        "rows": {block: int(np.sum(regression.block == i)) for i, block in enumerate(BLOCKS)},
        "noise": {k: round(v, 5) for k, v in regression.noise.items()},
    }


def sindy_baseline(dataset: str | Path | Sequence[Recording]) -> dict[str, Any]:
    """The baseline's verdict on a folder of recordings (or the recordings given): ``selected``
    (effect ids, in the library's order), ``parameters`` (those a linear library gives),
    ``kept_terms``, ``coefficients`` (each term's, in its column's units),
    ``contribution_noise_sigmas``, the residual's RMS before and after (noise sigmas),
    ``unexplained`` (bool) and the rows of each block."""
    recordings = read_dataset(dataset).recordings if isinstance(dataset, str | Path) else list(dataset)
    return sindy_verdict(regression_rows(recordings), recordings)
