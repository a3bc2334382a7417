"""How much each residual row of a fit is worth: effective sample weights, and the sums the
diagnosis judges candidates by (chi^2, per-channel RMS, the likeness of two corrections).

An information criterion that counts every sample of an autocorrelated residual as independent
over-rewards tiny effects, and an interval that does is too narrow. Each channel's rows are
weighted by its effective sample share, ``(1 - rho) / (1 + rho)``
(:func:`brakegym.statistics.effective_sample_share`), for rho the larger of

- the pooled lag-1 autocorrelation of the unmodified model's residual (its misfit, smooth in
  time, is what candidates are judged against), and
- the lag-1 autocorrelation of the channel's noise (:mod:`.noise`, per sample of the channel's
  own sampling, as the fit's rows are): a residual that is all noise cannot hold more independent
  samples than its noise, whatever the nuisance fit took out of its correlation.

The rows are already divided by the noise level (the AR(1) model's marginal sigma), so a
channel's effective chi^2 is its share times the sum of its squares.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from ..recordings.columns import DECEL, DISC_TEMPERATURE, SPEED
from ..statistics import effective_sample_share, lag1_autocorrelation
from .fitting import FIT_CHANNELS, FitProblem

CHANNEL_NAMES = {SPEED: "speed", DECEL: "decel", DISC_TEMPERATURE: "T_disc"}


class Weighting:
    """Effective sample weights of a fit problem's rows, from a reference residual (the
    unmodified model's) and each channel's noise autocorrelation ``noise_rho`` (lag 1, per sample
    of the channel; a channel left out counts its residual's alone); prior rows weigh 1."""

    def __init__(self, problem: FitProblem, residual: np.ndarray, noise_rho: Mapping[str, float]) -> None:
        self.problem = problem
        self.weights = np.ones(len(residual))
        self.channel_shares: dict[str, float] = {}
        for index, channel in enumerate(FIT_CHANNELS):
            rows = problem.channel_of == index
            if not rows.any():
                continue
            per_recording = [residual[rows & (problem.recording_of == i)] for i in range(problem.n)]
            rho = max(lag1_autocorrelation(per_recording), noise_rho.get(channel, -1.0))
            share = effective_sample_share(rho)
            self.weights[rows] = share
            self.channel_shares[channel] = share
        #: effective samples of the measured rows (prior rows not counted)
        self.n_eff_total = float(np.sum(self.weights[problem.channel_of >= 0]))

    def chi2(self, residual: np.ndarray) -> float:
        """The effective chi^2 of a normalised residual."""
        return float(np.sum(self.weights * residual**2))

    def rms(self, residual: np.ndarray) -> dict[str, float]:
        """Per channel, the RMS of the residual in the channel's units (rounded for a report)."""
        problem = self.problem
        out = {}
        for index, channel in enumerate(FIT_CHANNELS):
            rows = problem.channel_of == index
            if rows.any():
                out[channel] = round(float(np.sqrt(np.mean(residual[rows] ** 2)) * problem.noise[channel]), 4)
        return out

    def recording_sse(self, residual: np.ndarray) -> np.ndarray:
        """Per recording, the effective sum of squares of its rows (its prior rows included: a
        set-wide friction shift shows in the friction factor's, not in the data rows)."""
        weighted = self.weights * residual**2
        return np.array([np.sum(weighted[self.problem.recording_of == i]) for i in range(self.problem.n)])

    def signature_correlation(self, base_residual: np.ndarray, first: np.ndarray, second: np.ndarray) -> float:
        """How alike the data see two fitted candidates: the cosine between their changes to the
        unmodified model's residual over the measured rows (effective weights; each fit's own
        nuisance included). Near 1, the two corrections have the same shape in every channel."""
        rows = self.problem.channel_of >= 0
        weights = self.weights[rows]
        a, b = (base_residual - first)[rows], (base_residual - second)[rows]
        norm = math.sqrt(float(np.sum(weights * a * a)) * float(np.sum(weights * b * b)))
        return float(np.sum(weights * a * b)) / norm if norm > 0 else math.nan
