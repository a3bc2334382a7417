"""A force on part of the line, located along position: the step of the unmodified model's residual
deceleration that lifts one stretch of the recordings' positions above (or below) the rest.

A gradient that begins part-way along the line acts on every recording where it passes that place;
the unmodified model's fit has no force for it, and each recording's friction factor absorbs the
mean of what is left over its stop. What stays is a step along position: the residual deceleration
(from the speed signal) is higher on the section than off it, by the gradient's g p / 1000. Along
time since brake onset the same step lands at a different time in each recording (each starts at
its own speed), so a description of the residual along one state axis at a time can place it there
(:mod:`.locate`); fitted along position with each recording's own offset, it is found where it is.

The search: the braking samples of every recording, each recording's own mean removed (its
friction factor's share), the positions in bins of ``bin_m``; the stretch [a, b) of whole bins, at
least ``min_length_m`` long, whose indicator explains the most of the residual's variance by least
squares with one offset per recording (exhaustively: cumulative sums make each stretch a few
operations). A stretch that covers every position is no step; a gradient there is the constant
gradient's. The step found is a start for the fit of a
:class:`~brakegym.effects.GradientSection`, and where the train slows less on the stretch, for a
stretch of low adhesion (:class:`~brakegym.effects.AdhesionSection`, which also needs the hardest
deceleration measured on it), screened beside any grid (their
:meth:`~brakegym.effects.Effect.screening_points`); whether either is in the data is decided as
for any effect, by the rules of :mod:`.judging`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..effects import LocatedStretch
from .locate import ResidualTrace

__all__ = ["PositionStep", "find_position_step"]


@dataclass(frozen=True)
class PositionStep:
    """A stretch of position where the residual deceleration differs from the rest of each
    recording's stop."""

    start_m: float
    end_m: float
    decel_step_mps2: float  # on the stretch minus off it (positive: the train slows more there)
    explained_share: float  # of the residual's variance about each recording's own mean
    recordings: int  # how many recordings have braking samples on the stretch
    #: the 90th percentile of the deceleration the speed signals show on the stretch while braking
    #: (a stretch of low adhesion holds the hardest stops at its plateau)
    peak_decel_mps2: float = float("nan")

    @property
    def gradient_permil(self) -> float:
        """The gradient whose force leaves this step (its deceleration over g, x 1000)."""
        return self.stretch().gradient_permil

    def stretch(self) -> LocatedStretch:
        """The step as the effects read it (:attr:`brakegym.effects.base.Evidence.stretches`)."""
        return LocatedStretch(self.start_m, self.end_m, self.decel_step_mps2, self.peak_decel_mps2)

    def report_entry(self) -> dict[str, Any]:
        return {
            "start_m": round(self.start_m, 1),
            "end_m": round(self.end_m, 1),
            "decel_step_mps2": round(self.decel_step_mps2, 5),
            "gradient_permil": round(self.gradient_permil, 3),
            "explained_share": round(self.explained_share, 4),
            "recordings": self.recordings,
            "peak_decel_mps2": round(self.peak_decel_mps2, 4) if np.isfinite(self.peak_decel_mps2) else None,
        }


def _braking_samples(
    traces: Sequence[ResidualTrace], earlier: Sequence[PositionStep] = ()
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per recording (position, residual deceleration about its own mean) while braking, less the
    ``earlier`` steps (each its size times its stretch's indicator about the recording's mean)."""
    out = []
    for trace in traces:
        position = trace.axes["position_m"]
        rows = trace.braking & ~np.isnan(trace.kinematic_decel) & ~np.isnan(position)
        if rows.sum() >= 2:
            decel = trace.kinematic_decel[rows]
            centred = decel - decel.mean()
            for step in earlier:
                on = ((position[rows] >= step.start_m) & (position[rows] < step.end_m)).astype(float)
                centred = centred - step.decel_step_mps2 * (on - on.mean())
            out.append((position[rows], centred))
    return out


def find_position_step(
    traces: Sequence[ResidualTrace], bin_m: float, min_length_m: float, earlier: Sequence[PositionStep] = ()
) -> PositionStep | None:
    """The stretch of position whose step explains most of the braking residual deceleration, with
    one offset per recording (module docstring); None where the recordings do not span two
    stretches of ``min_length_m``. With ``earlier`` steps, in what they leave of the residual (a
    second section of a profile): its share is of that."""
    samples = _braking_samples(traces, earlier)
    if not samples:
        return None
    top = max(float(position.max()) for position, _ in samples)
    n_bins = int(np.ceil(top / bin_m))
    min_bins = max(int(np.ceil(min_length_m / bin_m)), 1)
    if n_bins < 2 * min_bins:
        return None
    # Per recording: cumulative counts and sums of the centred residual at each bin edge.
    counts = np.zeros((len(samples), n_bins + 1))
    sums = np.zeros((len(samples), n_bins + 1))
    total_ss = 0.0
    for r, (position, decel) in enumerate(samples):
        # Positions below the line origin by a little (a run back, whose simulated distance exceeds
        # the measured one) count in the first bin.
        bins = np.clip((position / bin_m).astype(int), 0, n_bins - 1)
        counts[r, 1:] = np.cumsum(np.bincount(bins, minlength=n_bins))
        sums[r, 1:] = np.cumsum(np.bincount(bins, weights=decel, minlength=n_bins))
        total_ss += float(np.sum(decel**2))
    if total_ss == 0.0:
        return None
    n_per_recording = counts[:, -1]
    first, last = np.triu_indices(n_bins + 1, k=min_bins)
    whole = (first == 0) & (last == n_bins)
    first, last = first[~whole], last[~whole]
    inside = counts[:, last] - counts[:, first]  # (R, stretches)
    # Least squares of y = c I + d_r: with each recording centred, c = sum(I y) / sum((I - mean I)^2).
    covariance = (sums[:, last] - sums[:, first]).sum(axis=0)
    variance = (inside - inside**2 / n_per_recording[:, None]).sum(axis=0)
    usable = variance > 0.0
    gain = np.where(usable, covariance**2 / np.where(usable, variance, 1.0), 0.0)
    best = int(np.argmax(gain))
    if gain[best] <= 0.0:
        return None
    start_m, end_m = float(first[best] * bin_m), float(last[best] * bin_m)
    return PositionStep(
        start_m=start_m,
        end_m=end_m,
        decel_step_mps2=float(covariance[best] / variance[best]),
        explained_share=float(gain[best] / total_ss),
        recordings=int(np.sum(inside[:, best] > 0)),
        peak_decel_mps2=_peak_decel_on(traces, start_m, end_m),
    )


def _peak_decel_on(traces: Sequence[ResidualTrace], start_m: float, end_m: float) -> float:
    """The 90th percentile of the measured deceleration while braking from ``start_m`` to
    ``end_m``; nan with no such sample."""
    on_stretch = []
    for trace in traces:
        position = trace.axes["position_m"]
        rows = trace.braking & (position >= start_m) & (position < end_m) & ~np.isnan(trace.measured_decel)
        on_stretch.append(trace.measured_decel[rows])
    decel = np.concatenate(on_stretch)
    return float(np.percentile(decel, 90)) if decel.size else float("nan")
