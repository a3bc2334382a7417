"""The fallback as a screening source: before the verdict "unexplained", the residual is matched
against the signatures that library effects leave, and each matching effect is fitted from the
start its signature gives.

The screening tries each effect on a coarse grid inside its bounds (two points per parameter of a
running resistance) and refines the best point by one step: an effect whose valley lies between
the grid points (a running resistance near the nominal A and B with a large C) can screen worse
than its confounders, never be fitted in full, and leave a residual that the data-driven
description (:func:`.locate.describe_unexplained`) calls quadratic in speed. Its signature gives
the start the grid missed.

Each signature is a least-squares fit of the unmodified model's residual deceleration (from the
speed signal, pooled over the recordings) on the columns an effect's force leaves there, each
recording divided by its own mass:

- ``deceleration_constant_across_loads``: a force proportional to the mass (``gradient``; its
  gradient in permil is 1000 times the deceleration over g);
- ``force_quadratic_in_speed``: a force A + B v + C v^2 the same across loads (``running_resistance``;
  its coefficients are the nominal ones plus the fitted ones).

It is fitted on the coasting before the brake command first, then on the braking. While braking,
each recording's friction factor of the unmodified fit has absorbed most of a force that acts
all through the stop (a gradient of -5.8 permil leaves a mean residual deceleration near 0 there);
before the brake acts nothing absorbs it, and the residual is the force itself. A recording without
coasting has only its braking.

Every signature is tested on its own axes (speed, the recordings' masses), not only along the axis
the description found best: the eta^2 of a residual that is nearly constant over a stop is alike
along every axis that grows over the stop, and the best of them is often the time since brake
onset. A signature matches in a phase when it removes ``DiagnosisRules.fallback_share_of_eta2``
times as much of that phase's residual mean square as the bin means along its best state axis do
(its eta^2, :func:`.locate.correlation_ratio`); the matching effects, best share first, at most
``DiagnosisRules.fallback_max_fits`` of them, are fitted and judged as any candidate is
(:mod:`.judging`). A signature's coefficients are a start, not an estimate: the fit that follows
judges all samples.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import config as cfg
from ..effects import EFFECTS
from ..units import STANDARD_GRAVITY_MPS2
from .judging import Candidate
from .locate import ATTRIBUTION_BINS, AXES, ResidualTrace, correlation_ratio

__all__ = ["FallbackScreening", "FallbackTry", "SignatureMatch", "match_signatures", "signature_columns"]

#: the library effect that each signature maps to
SIGNATURE_EFFECTS = {
    "deceleration_constant_across_loads": "gradient",
    "force_quadratic_in_speed": "running_resistance",
}


@dataclass(frozen=True)
class SignatureMatch:
    """A library effect's signature found in the residual deceleration, and the effect's start."""

    signature: str
    effect_id: str
    phase: str  # coasting or braking: the samples it was fitted on
    explained_share: float  # of the residual deceleration's mean square in that phase
    start: dict[str, float]  # the effect's parameters the signature's coefficients give

    def start_inside_bounds(self) -> dict[str, float]:
        """The start moved onto the nearest bound where the signature gives one outside (a fit
        explores only inside the bounds); the report keeps both."""
        specs = {spec.name: spec for spec in EFFECTS[self.effect_id].parameters}
        return {name: specs[name].inside_bounds(value) for name, value in self.start.items()}


#: the phases of a stop whose samples the signatures are fitted on, coasting first (before the
#: brake command no friction factor can absorb a force, so its imprint is all there)
PHASES = ("coasting", "braking")


@dataclass
class PhaseSamples:
    """The pooled samples of one phase: residual deceleration, speed, each sample's recording's
    mass, and every state axis (``AXES`` of :mod:`.locate`)."""

    decel: np.ndarray
    speed: np.ndarray
    mass: np.ndarray
    axes: dict[str, np.ndarray]


def phase_samples(traces: Sequence[ResidualTrace], phase: str) -> PhaseSamples:
    """The samples of ``phase`` (``coasting``: moving before the brake acts; ``braking``) where the
    residual deceleration and the speed are known."""
    decel, speed, mass, axes = [], [], [], {axis: [] for axis, _ in AXES}
    for trace in traces:
        in_phase = trace.braking if phase == "braking" else trace.moving & ~trace.braking
        rows = in_phase & ~np.isnan(trace.kinematic_decel) & ~np.isnan(trace.axes["speed_mps"])
        decel.append(trace.kinematic_decel[rows])
        speed.append(trace.axes["speed_mps"][rows])
        mass.append(np.full(int(rows.sum()), trace.recording.mass_kg))
        for axis in axes:
            axes[axis].append(trace.axes[axis][rows])
    return PhaseSamples(
        np.concatenate(decel),
        np.concatenate(speed),
        np.concatenate(mass),
        {axis: np.concatenate(values) for axis, values in axes.items()},
    )


def signature_columns(signature: str, speed_mps: np.ndarray, mass_kg: np.ndarray) -> np.ndarray:
    """The columns of the deceleration a signature's force leaves (rows: samples): 1 for a force
    proportional to the mass, (1, v, v^2) / m for a force the same across loads."""
    if signature == "deceleration_constant_across_loads":
        return np.ones((len(speed_mps), 1))
    if signature == "force_quadratic_in_speed":
        return np.column_stack([np.ones_like(speed_mps), speed_mps, speed_mps**2]) / mass_kg[:, None]
    raise ValueError(f"unknown signature {signature!r}; known: {sorted(SIGNATURE_EFFECTS)}")


def effect_start(signature: str, coefficients: np.ndarray, nominal: cfg.RunningResistance) -> dict[str, float]:
    """The effect's parameters a signature's least-squares coefficients give."""
    if signature == "deceleration_constant_across_loads":
        return {"gradient_permil": float(1000.0 * coefficients[0] / STANDARD_GRAVITY_MPS2)}
    if signature == "force_quadratic_in_speed":
        # The replay already carries the nominal resistance; the residual shows what differs.
        return {
            "A_N": float(nominal.A_N + coefficients[0]),
            "B_N_per_mps": float(nominal.B_N_per_mps + coefficients[1]),
            "C_N_per_mps2": float(nominal.C_N_per_mps2 + coefficients[2]),
        }
    raise ValueError(f"unknown signature {signature!r}; known: {sorted(SIGNATURE_EFFECTS)}")


def match_signatures(
    traces: Sequence[ResidualTrace], nominal: cfg.RunningResistance, share_of_eta2: float
) -> list[SignatureMatch]:
    """Every signature fitted to the pooled residual deceleration of each phase (coasting, then
    braking); a signature matches in a phase when it removes at least ``share_of_eta2`` times the
    best eta^2 of that phase's residual along a state axis (:func:`.locate.correlation_ratio`).
    Each matching signature once, from the phase where it matched first (coasting: its
    coefficients there are the force itself, not what the friction factors left of it), best share
    first (ties in the order of ``SIGNATURE_EFFECTS``). Both shares are against zero: an offset is
    a mismatch too.

    Against eta^2, not the whole mean square: the deceleration is differentiated from the speed
    signal, and its noise leaves most of the mean square to no function of the state at all; the
    bin means along the best axis remove what any function of one axis can. A signature that
    removes about as much has found the structure the residual has."""
    matches: dict[str, SignatureMatch] = {}
    for phase in PHASES:
        samples = phase_samples(traces, phase)
        decel = samples.decel
        total = float(np.mean(decel**2)) if decel.size else 0.0
        if decel.size < 4 * ATTRIBUTION_BINS or total == 0.0:
            continue
        best_eta2 = max(correlation_ratio(values, decel) for values in samples.axes.values())
        if best_eta2 <= 0.0:
            continue
        for signature, effect_id in SIGNATURE_EFFECTS.items():
            if signature in matches:
                continue
            columns = signature_columns(signature, samples.speed, samples.mass)
            # Scaled columns: 1/m, v/m and v^2/m differ by orders of magnitude.
            scale = np.linalg.norm(columns, axis=0)
            scaled, *_ = np.linalg.lstsq(columns / scale, decel, rcond=None)
            coefficients = scaled / scale
            share = 1.0 - float(np.mean((decel - columns @ coefficients) ** 2)) / total
            if share >= share_of_eta2 * best_eta2:
                start = effect_start(signature, coefficients, nominal)
                matches[signature] = SignatureMatch(signature, effect_id, phase, share, start)
    order = list(SIGNATURE_EFFECTS)
    return sorted(matches.values(), key=lambda m: (-m.explained_share, order.index(m.signature)))


@dataclass
class FallbackTry:
    """One matched signature's effect, fitted from its start and judged."""

    match: SignatureMatch
    candidate: Candidate
    #: it fits better than the screening's fit of the same effect (if any), and replaced it among
    #: the singles the verdict judges
    replaced_screened_fit: bool


@dataclass
class FallbackScreening:
    """What the fallback tried: the description it started from and each matched signature."""

    description: dict[str, Any]
    tries: list[FallbackTry]

    def report_entry(self, selected: Candidate | None) -> dict[str, Any]:
        """The report's ``fallback_screening``: the description's axis, form and share, and per
        matched signature its effect, start, fit and verdict by the rules of :mod:`.judging`."""
        return {
            "description": {
                "axis": self.description["axis"],
                "form": self.description["form"],
                "explained_share": self.description["explained_share"],
            },
            "signatures": [_try_entry(attempt, selected) for attempt in self.tries],
        }


def _try_entry(attempt: FallbackTry, selected: Candidate | None) -> dict[str, Any]:
    candidate, match = attempt.candidate, attempt.match
    # A single the fallback fitted may be selected alone or in a pair of the forward step.
    if selected is not None and attempt.replaced_screened_fit and candidate.effect_ids[0] in selected.effect_ids:
        verdict = "selected"
    elif candidate.passes:
        verdict = "passes the rules, another candidate selected"
    elif not attempt.replaced_screened_fit:
        verdict = "fits worse than the screening's fit of the same effect"
    else:
        verdict = "fails the rules"
    return {
        "signature": match.signature,
        "phase": match.phase,
        "explained_share": round(match.explained_share, 4),
        "effect": match.effect_id,
        "start": {name: round(value, 5) for name, value in match.start.items()},
        "start_inside_bounds": {name: round(value, 5) for name, value in match.start_inside_bounds().items()},
        "parameters": {name: round(value, 5) for name, value in candidate.fit.parameters.items()},
        "delta_bic": round(candidate.delta_bic, 1),
        "heldout_t": candidate.report.get("heldout_t"),
        "heldout_p": candidate.report.get("heldout_p"),
        "relevant_size": candidate.relevant,
        "at_search_range_end": list(candidate.at_range_end),
        "replaced_screened_fit": attempt.replaced_screened_fit,
        "verdict": verdict,
    }
