"""The diagnosis's rules: every threshold of the screening and the selection, in one place.

A blind benchmark (``benchmarks/bench_diagnosis.py``) judges the diagnosis with the rules fixed
before it runs, on seeds they were not tuned on: change a rule, and it must be judged on new seeds.
``docs/diagnosis.md`` explains the method they serve, and its history page when each was set.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from ..recordings.columns import DECEL, DISC_TEMPERATURE, SPEED


def _default_noise_windows_s() -> dict[str, float]:
    return {SPEED: 2.0, DECEL: 1.0, DISC_TEMPERATURE: 3.0}


@dataclass(frozen=True)
class DiagnosisRules:
    """The thresholds of :class:`~brakegym.diagnosis.pipeline.Diagnoser`."""

    # -- noise ----------------------------------------------------------------------------------
    #: per channel, the span (s) of the cubic smooth whose residual gives its noise model
    #: (:mod:`.noise`); each channel takes as many of its own samples as span it. The signal must be
    #: a cubic over the span: a deceleration rises within about a second of brake onset (on
    #: effect-free 10 Hz sets a 3 s span reads white 0.020 m/s^2 as 0.025 with rho 0.3, 1 s reads
    #: 0.021 with rho 0.03), a speed and a disc temperature curve over longer.
    noise_window_s: Mapping[str, float] = field(default_factory=_default_noise_windows_s)

    # -- selection ----------------------------------------------------------------------------
    #: a candidate must lower the effective-sample BIC by at least this much (negative)
    select_delta_bic: float = -10.0
    #: BICs closer than this (with held-out errors within ``indistinguishable_heldout``) make two
    #: candidates indistinguishable
    similar_bic: float = 100.0
    #: the paired t over recordings of the share of held-out error a candidate removes must reach
    #: this, on the recordings it acts on ...
    heldout_min_t: float = 2.0
    #: ... and its one-sided p-value (Student's t on the recordings acted on less one degrees of
    #: freedom) must be at most this. Over 7-8 recordings t = 2 is p = 0.04-0.05; over 2-5 the
    #: t distribution's tails are wider (t = 2 is p = 0.15 over 2, 0.07 over 4), and a t of 2 alone
    #: would accept a consistency that chance gives them
    heldout_max_p: float = 0.05
    #: a recording counts as acted on when the candidate moves its held-out prediction this many
    #: noise sigmas somewhere ...
    heldout_moves_sigma: float = 1.0
    #: ... or changes its held-out error by this share, either way (a speed-sensor scale that the
    #: initial speeds partly absorb moves most rows by less than a sigma, yet changes whole
    #: recordings' errors by 10-24 %)
    heldout_acts_share: float = 0.10
    #: the paired t needs at least this many recordings acted on
    heldout_min_recordings: int = 2
    #: a size resting on one recording (``one_recording_share``) that the other recordings alone
    #: would not tell from its no-effect value by this many standard errors is held at that value
    #: in that recording's held-out prediction (:mod:`.heldout`: without it nothing says the
    #: effect is there)
    heldout_unseen_z: float = 2.0
    #: a recording left out is predicted from a full fit to the others (:mod:`.heldout`) where
    #: their one Gauss-Newton step left its linear range: their effective chi^2 at the stepped
    #: point fell by less than this share of what the step's quadratic model promised ...
    heldout_linear_min_ratio: float = 0.25
    #: ... and stands more than this above that model (below it, the two differ by noise)
    heldout_linear_chi2_slack: float = 1.0
    #: a candidate fitted within this share of a parameter's range (of its logarithm on a log
    #: grid) of a bound that is not physical is not selected: the data want the effect beyond the
    #: sizes the library gives it (:meth:`brakegym.effects.ParameterSpec.at_range_end`)
    range_end_share: float = 0.005
    #: a relevant candidate with a BIC gain that acts on at most this many recordings cannot show
    #: a consistent held-out gain; it is reported unconfirmed (not selected) ...
    unconfirmed_max_recordings: int = 2
    #: ... when it removes at least this share of their held-out error on average
    unconfirmed_min_gain: float = 0.10
    #: two passing candidates whose held-out errors are within this share may be indistinguishable
    indistinguishable_heldout: float = 0.10
    #: in place of the BIC rule, a friction level added to a reference must lie this many standard
    #: errors of the factors' mean off 1, a shift shared by the recordings' friction factors
    #: (:func:`.judging.friction_level_shift`). Its evidence is
    #: n factors, not the samples: the BIC's penalty of log(effective samples) per parameter and
    #: its margin of 10 ask for a shift of 7-8 % on 8 recordings, however tightly they agree.
    friction_level_min_z: float = 2.0

    # -- the verdict without an effect ----------------------------------------------------------
    #: a residual that explains at least this share of its variance along one state axis (eta^2)
    #: is described as unexplained physics when no effect is selected
    unexplained_eta2: float = 0.10
    #: a channel whose residual RMS is this many noise levels or more is a mismatch
    mismatch_rms_over_noise: float = 2.0
    #: before the verdict "unexplained", a library effect's signature (:mod:`.signatures`) matches
    #: the residual deceleration of a phase (the coasting, the braking) when its least-squares fit
    #: removes this share of what the bin means along that residual's best state axis remove (its
    #: eta^2). Relative, not a share of
    #: the whole mean square: the deceleration differentiated from the speed signal is mostly
    #: noise, and no function of the state removes half of it. ASSUMED: a signature that
    #: explains four fifths of what the best axis does has found its structure; the fit and the
    #: rules of the selection judge what it starts
    fallback_share_of_eta2: float = 0.8
    #: the most matched signatures whose effects the fallback fits in full, best share first (each
    #: costs a candidate's fit and its held-out prediction)
    fallback_max_fits: int = 2

    # -- effects along the line ------------------------------------------------------------------
    #: bins of position, m, in which a step of the residual along position is searched
    #: (:mod:`brakegym.diagnosis.position_steps`); a fifth of a train length
    position_step_bin_m: float = 10.0
    #: a step along position is screened as a gradient section when it explains this share of the
    #: braking residual deceleration's variance about each recording's mean
    position_step_min_share: float = 0.05

    # -- screening ------------------------------------------------------------------------------
    #: grid points per parameter of a one-parameter effect, an even number since the middle of
    #: symmetric bounds (often the no-effect value) is no start; 3 per parameter for two, 2 for three
    grid_points_1d: int = 8
    #: the most failed brake units screened (from 1)
    max_failed_units_screened: int = 4
    #: chord iterations that refit each screened point's nuisance
    screen_chord_iterations: int = 3
    #: Levenberg-Marquardt iterations on fresh Jacobians that then refit the nuisance of each
    #: effect's best screened point (0 turns this off)
    screen_nuisance_iterations: int = 4
    #: effective chi^2 a screened effect must gain over the unmodified model to be fitted in full
    screen_min_gain: float = 1.0
    #: screened effects fitted in full, best first
    top_singles: int = 3
    #: pairs are fitted among this many best singles
    pairs_from: int = 2
    #: in the forward step, this many effects, those that screen best on top of the selected
    #: single, are fitted as pairs with it (0 turns the forward step off)
    forward_pairs: int = 2
    #: where a pair is selected, the passing singles after its single (lowest held-out error
    #: first, at most this many) are each fitted in the single's place beside the pair's second
    #: effect: a look-alike of the single (three failed brake units and a rotating mass of 0.23)
    #: is then replaced or named indistinguishable as it would be alone (0 turns this off)
    swapped_pairs: int = 2
    #: iterations of a candidate's full fit
    fit_iterations: int = 8
    #: a single's full fit starts from the best points of this many valleys (local minima) of
    #: its screening grid: its best screened point's, and the best of the others (1: that one
    #: alone); the fit of least chi^2 is kept
    screen_valleys: int = 2
    #: a grid point whose chi^2 is the baseline's within this share of it is a point where the
    #: effect acts on nothing (a fade whose onset the discs never reach): no valley, and no start
    #: for a full fit, whose steps could not leave it
    no_effect_chi2_share: float = 1e-4

    # -- intervals ------------------------------------------------------------------------------
    #: replicates of the parametric bootstrap of the selected model's parameters (:mod:`.bootstrap`);
    #: each refits the selected model once, so the cost grows linearly; below 3, no bootstrap
    bootstrap_replicates: int = 12
    #: replicates drawn at each end of each parameter's bootstrap interval (the effect's
    #: parameters at that end, the others along the replicates' regression), which move the end
    #: out to where the fitted value is the 2.5 % point of the replicates drawn there: an
    #: estimator whose spread or bias grows away from the fit (a thermal fade's) is covered more
    #: often (12: fade coverage 34/37 against 32/37). Each end costs as many refits: five times
    #: the bootstrap's for a two-parameter effect, about 1.5-3 times the whole diagnosis's time
    #: on a fade; 0 (or below 3) leaves the ends untested
    bootstrap_end_replicates: int = 12
    #: a parameter whose information the other recordings hold less than this share of, with
    #: one recording left out, rests on that recording alone (reported, ``resting_on_one_recording``;
    #: see also ``heldout_unseen_z``)
    one_recording_share: float = 0.1
    #: the scatter set-up (``configs/setups``) the bootstrap draws each application's friction and
    #: running resistance from, ASSUMED to be the one ``brakegym synth`` writes its sets with
    bootstrap_scatter_setup: str = "mcs-75-25"

    def grid_points(self, n_parameters: int) -> int:
        """Screening grid points per parameter of an effect with ``n_parameters`` parameters."""
        return {1: self.grid_points_1d, 2: 3, 3: 2}[n_parameters]
