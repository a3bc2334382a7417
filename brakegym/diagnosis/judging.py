"""Judging fitted candidates: which effect (or pair) the data select, which the data cannot tell
apart, and which act on too few recordings to confirm.

A candidate is selected when

- it lowers the effective-sample BIC (chi^2 counted with the effective sample weights of
  :mod:`.weighting`, plus ``log(n_eff)`` per parameter) by at least ``select_delta_bic``,
- it lowers the error on recordings held out of the fit (:mod:`.heldout`) consistently over the
  recordings it acts on: the paired t of each recording's share of held-out error removed reaches
  ``heldout_min_t`` and its one-sided p-value is at most ``heldout_max_p`` (Student's t on the
  recordings less one degrees of freedom, so that two recordings must agree far more closely than
  eight), over the recordings whose held-out prediction it moves by ``heldout_moves_sigma``
  somewhere or whose held-out error it changes by ``heldout_acts_share``, at least
  ``heldout_min_recordings`` of them (a recording it leaves alone is no evidence either way, and
  the gains of those it acts on differ by orders of magnitude: a thermal fade that only the
  hottest stops reach), and
- its fitted size is physically relevant (:meth:`brakegym.effects.Effect.is_relevant`), and
- no parameter ends at a bound of its search range that is not physical
  (``range_end_share``): a thermal fade with its onset at the lowest the library allows, or wet
  pads drying over the longest, stands in for something the library does not describe.

Of the passing singles the one with the lowest held-out error is selected, and a pair with it
replaces it by the same rules, judged against the single: the pair must lower the BIC by
``select_delta_bic`` below the single's and remove held-out error consistently over the recordings
the second effect acts on (of the passing pairs, the one with the lowest held-out error). A pair
that holds another passing single instead, a look-alike of the selected one, replaces the
selection where it replaces both singles by those rules: the second effect of the truth can lower
the held-out error beside the one look-alike and not beside the other. An
effect that holds another as a special case (:attr:`brakegym.effects.base.Effect.extends`: a section
holds the whole-line gradient, a profile of two sections one section) must beat it by the same
rules where both are fitted, as a single and in a pair with the same partner. The pairs
include those of the forward step (:mod:`.pipeline`): the selected single with the effects that
screen best on top of it. Where a pair is selected, the next passing singles are fitted in its
single's place beside its second effect; such a swapped pair replaces the selected one where it
beats it by every rule, and is named indistinguishable from it by the rule for two singles below
(three failed brake units and a rotating mass of 0.23 take the same share of the brake force).
A pair that does not replace the single, but whose second effect is
relevant, whose held-out error is within ``indistinguishable_heldout`` of the single's or lower,
and that passes one of the two rules against the single (a BIC lower by ``select_delta_bic``, or
the held-out rule) is named indistinguishable from the single (``single_or_pair``), with the
measurement that would separate the two effects.

Another passing single is named indistinguishable from the selected one when its held-out error
is within ``indistinguishable_heldout`` and either its BIC is within ``similar_bic`` or the
recordings do not tell the two held-out errors apart (their paired differences fail the held-out
rule): in large data two confounders' BICs can differ by hundreds while neither predicts a
held-out recording better. A relevant single with a BIC gain that acts on at most ``unconfirmed_max_recordings``
recordings and removes ``unconfirmed_min_gain`` of their held-out error is reported unconfirmed (a
t over one or two recordings is no evidence of consistency).

A friction level added to a reference (the unmodified model, or a selected single without one) is
judged as what the data hold of it: a shift shared by the recordings' friction factors, against
their scatter about it (:func:`friction_level_shift`). The data rows see only each recording's
factor, so the level's whole evidence is the n factors: in place of the BIC rule, its shift must
be ``friction_level_min_z`` standard errors of the factors' mean, and its held-out rule is the
paired t of the held-out error it removes over every recording (the level acts on each one's
friction; each recording's factor, predicted by the level fitted without it, is the part that
changes). The BIC's penalty of log(effective samples) and margin of 10 would ask for a shift of
7-8 % on 8 recordings, and a shift that moves the factors' prior rows by less than a noise sigma
acted on no recording at all.
The thresholds are :class:`.rules.DiagnosisRules`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..effects import EFFECTS, Evidence, FrictionLevel, in_library_order, special_cases
from ..statistics import paired_t, paired_t_p_value
from .fitting import FRICTION_FACTOR, FitProblem, FitResult
from .heldout import HeldOut, held_out
from .rules import DiagnosisRules
from .weighting import Weighting


@dataclass
class Candidate:
    """A fitted effect or pair, with what judging it found."""

    effect_ids: tuple[str, ...]
    fit: FitResult
    chi2_eff: float
    delta_bic: float  # against the unmodified model
    heldout: HeldOut
    relevant: bool = True
    #: the parameters fitted at a bound of their search range that is not physical
    at_range_end: list[str] = field(default_factory=list)
    passes: bool = False  # beats the unmodified model by every rule (singles)
    acting_gain: float = math.nan  # mean share of held-out error removed over the recordings it acts on
    #: whether it passed the BIC rule (or for an added friction level, its shared-shift test) and
    #: the held-out rule against the last reference it was judged against
    passes_bic_rule: bool = False
    passes_heldout_rule: bool = False
    report: dict[str, Any] = field(default_factory=dict)  # what the report says of it


@dataclass(frozen=True)
class FrictionLevelShift:
    """A fitted friction level read as the shift shared by the recordings' friction factors."""

    level: float  # the fitted mu_scale: where the factors' prior is centred
    scatter: float  # per-recording friction scatter about the level the test assumes
    standard_error: float  # of the factors' mean: scatter / sqrt(n)
    z: float  # (level - 1) / standard_error

    def as_dict(self) -> dict[str, float]:
        return {
            "level": round(self.level, 5),
            "scatter": round(self.scatter, 5),
            "standard_error": round(self.standard_error, 5),
            "z": round(self.z, 2),
        }


def friction_level_shift(problem: FitProblem, fit: FitResult) -> FrictionLevelShift:
    """The shared-shift test of the friction level of ``fit`` (:func:`shared_friction_shift`)."""
    level = float(fit.parameters[FrictionLevel.parameters[0].name])
    factors = fit.x[problem.nuisance_block(FRICTION_FACTOR, len(fit.free))]
    return shared_friction_shift(level, factors, problem.prior_sigma)


def shared_friction_shift(level: float, factors: np.ndarray, prior_sigma: float) -> FrictionLevelShift:
    """The shared-shift test of a friction ``level`` against the recordings' whole friction
    ``factors`` (level times each one's scatter). With n recordings whose factors scatter by sigma
    about a level, the level is known to sigma / sqrt(n), and a level that differs from 1 by more
    than a few of those is a shift shared by all recordings, not scatter. Sigma is the larger of
    the friction-factor prior's ``prior_sigma`` (the campaign's scatter, ASSUMED) and the factors'
    own spread about the level: recordings that scatter more than the prior says leave their mean
    less certain, and never more certain than the prior says."""
    n = len(factors)
    own = float(np.std(np.asarray(factors) / level, ddof=1)) if n > 1 else 0.0
    scatter = max(prior_sigma, own)
    standard_error = scatter / math.sqrt(n)
    return FrictionLevelShift(level, scatter, standard_error, (level - 1.0) / standard_error)


def mismatch_explained_share(weighting: Weighting, baseline_residual: np.ndarray, chi2_eff: float) -> float | None:
    """The share of the unmodified model's mismatch beyond sample noise that a fit of effective
    chi^2 ``chi2_eff`` removes: (chi^2 unmodified - chi^2 fit) / (chi^2 unmodified - chi^2 of
    noise alone), the noise's being the effective samples plus one per friction-factor prior row.
    None where the unmodified model is within noise.

    The mismatch includes what one friction factor per recording cannot absorb of the friction
    scatter between discs, so an effect the data hold takes less than all of it, and a friction
    level, seen through the factors' shared shift rather than the samples, takes next to none.
    Reported, not used by any rule: an effect that takes a small part of a larger mismatch (an
    adhesion limit standing in for physics outside the library) shows here."""
    noise_chi2 = weighting.n_eff_total + weighting.problem.n
    base_chi2 = weighting.chi2(baseline_residual)
    if base_chi2 <= noise_chi2:
        return None
    return (base_chi2 - chi2_eff) / (base_chi2 - noise_chi2)


@dataclass
class Verdict:
    """What the data select, and what they leave open."""

    selected: Candidate | None
    indistinguishable: list[list[str]]  # [selected, other] effect id pairs
    signature_correlations: dict[str, float]  # "selected / other": how alike their corrections are
    unconfirmed: list[Candidate]
    #: (selected single, pair with it) the data cannot tell apart
    single_or_pair: list[tuple[Candidate, Candidate]] = field(default_factory=list)


class Judge:
    """Judges candidates against the unmodified model's fit ``baseline``."""

    def __init__(
        self, problem: FitProblem, weighting: Weighting, rules: DiagnosisRules, evidence: Evidence, baseline: FitResult
    ) -> None:
        self.problem, self.weighting, self.rules, self.evidence = problem, weighting, rules, evidence
        self.baseline = baseline
        self.chi2_base = weighting.chi2(baseline.residual)
        self.log_n = math.log(max(weighting.n_eff_total, 2.0))
        self.base_sse = held_out(problem, weighting, baseline, rules).sse

    def candidate(self, effect_ids: tuple[str, ...], fit: FitResult) -> Candidate:
        """A fit judged: its BIC against the unmodified model, held-out error and relevance."""
        chi2 = self.weighting.chi2(fit.residual)
        n_parameters = len(fit.free) + len(fit.fixed)
        heldout = held_out(self.problem, self.weighting, fit, self.rules, self.baseline)
        candidate = Candidate(effect_ids, fit, chi2, chi2 - self.chi2_base + n_parameters * self.log_n, heldout)
        surface = [np.nanmax(r.states["T_fric_C"]) for r in fit.replays if "T_fric_C" in r.states]
        evidence = dataclasses.replace(
            self.evidence, peak_friction_surface_C=float(max(surface)) if surface else math.inf
        )
        candidate.relevant = all(
            EFFECTS[eid].is_relevant(
                {k: v for k, v in fit.parameters.items() if k in {s.name for s in EFFECTS[eid].parameters}}, evidence
            )
            for eid in effect_ids
        )
        candidate.at_range_end = [
            spec.name
            for eid in effect_ids
            for spec in EFFECTS[eid].parameters
            if not spec.integer
            and spec.name in fit.parameters
            and spec.at_range_end(fit.parameters[spec.name], self.rules.range_end_share)
        ]
        return candidate

    @staticmethod
    def selectable(candidate: Candidate) -> bool:
        """Relevant in size, and no parameter at the end of its search range."""
        return candidate.relevant and not candidate.at_range_end

    def beats(
        self,
        candidate: Candidate,
        reference_bic: float,
        reference_sse: np.ndarray,
        reference_residual: np.ndarray,
        reference_ids: tuple[str, ...] = (),
    ) -> bool:
        """Whether ``candidate`` beats a reference (the unmodified model, or the selected single
        ``reference_ids`` for a pair) by every rule; records its held-out figures in its report. A
        friction level the reference lacks is judged as a shift shared by the recordings' friction
        factors (see the module documentation)."""
        problem, rules = self.problem, self.rules
        d = reference_sse - candidate.heldout.sse
        gain = float(np.sum(d) / max(np.sum(reference_sse), 1e-12))
        shares = d / np.maximum(reference_sse, 1e-12)
        moved = np.abs(candidate.heldout.residual - reference_residual)
        acts_on = np.array(
            [
                bool(np.any(moved[problem.recording_of == i] >= rules.heldout_moves_sigma))
                or abs(shares[i]) >= rules.heldout_acts_share
                for i in range(problem.n)
            ]
        )
        adds_level = FrictionLevel.id in candidate.effect_ids and FrictionLevel.id not in reference_ids
        if adds_level:
            acts_on[:] = True
            bic_rule, gains = self._friction_level_rules(candidate, d)
        else:
            bic_rule = candidate.delta_bic - reference_bic < rules.select_delta_bic
            gains = shares[acts_on] if acts_on.sum() >= rules.heldout_min_recordings else np.zeros(0)
        t, p = paired_t(gains), paired_t_p_value(gains)
        candidate.acting_gain = float(np.mean(shares[acts_on])) if acts_on.any() else math.nan
        candidate.report["heldout_gain"] = round(gain, 4)
        candidate.report["heldout_t"] = round(t, 2) if math.isfinite(t) else None
        candidate.report["heldout_p"] = float(f"{p:.3g}") if math.isfinite(p) else None
        candidate.report["heldout_acts_on"] = [problem.recordings[i].name for i in np.flatnonzero(acts_on)]
        candidate.report["heldout_gain_per_recording"] = [round(float(x), 4) for x in shares]
        candidate.passes_bic_rule = bool(bic_rule)
        candidate.passes_heldout_rule = self._consistent(t, p)
        return self.selectable(candidate) and candidate.passes_bic_rule and candidate.passes_heldout_rule

    def _consistent(self, t: float, p: float) -> bool:
        """The held-out rule on a paired t and its p-value (nan: too few recordings)."""
        return bool(t >= self.rules.heldout_min_t and p <= self.rules.heldout_max_p)

    def _friction_level_rules(self, candidate: Candidate, heldout_removed: np.ndarray) -> tuple[bool, np.ndarray]:
        """The two rules for a friction level added to the reference: whether it passes its
        shared-shift test (in place of the BIC rule; recorded in the report as
        ``friction_level_shift``), and the gains of the held-out rule, the effective held-out
        error removed from each recording, over every recording.

        The held-out error a level removes lies in each recording's friction-factor row, whose
        prior weighs the same in every recording; shares of each recording's whole error would
        divide it by the data rows' error, which differs between recordings for reasons (length,
        channels) that have nothing to do with the level."""
        shift = friction_level_shift(self.problem, candidate.fit)
        candidate.report["friction_level_shift"] = shift.as_dict()
        return abs(shift.z) >= self.rules.friction_level_min_z, heldout_removed

    def best_single(self, singles: Sequence[Candidate]) -> Candidate | None:
        """The passing single with the lowest held-out error (None: none passes); marks each
        single's ``passes``."""
        base_residual = self.baseline.residual
        for candidate in singles:
            candidate.passes = self.beats(candidate, 0.0, self.base_sse, base_residual)
        for candidate in singles:
            if candidate.passes:
                candidate.passes = self._beats_nested(candidate, singles)
        passing = [c for c in singles if c.passes]
        return min(passing, key=lambda c: float(np.sum(c.heldout.sse))) if passing else None

    def _beats_nested(self, candidate: Candidate, others: Sequence[Candidate]) -> bool:
        """Whether ``candidate`` beats every one of ``others`` that it holds as a special case
        (:func:`nested_candidates`) by every rule, as a pair beats its single; True where it holds
        none. Its report's held-out figures are then against that one. Without the rule the larger
        description wins on held-out error alone where the two fit equally well: a section
        spanning nearly all of the recordings beside a whole-line gradient, chosen by rounding in
        the step search."""
        return all(self.replaces(candidate, nested) for nested in nested_candidates(candidate, others))

    def replaces(self, candidate: Candidate, reference: Candidate) -> bool:
        """Whether ``candidate`` beats ``reference`` by every rule (:meth:`beats`) and has the
        lower held-out error, as a pair must to replace its single; records its held-out figures
        against the reference in its report."""
        return self.beats(
            candidate, reference.delta_bic, reference.heldout.sse, reference.heldout.residual, reference.effect_ids
        ) and float(np.sum(candidate.heldout.sse)) < float(np.sum(reference.heldout.sse))

    def verdict(self, singles: Sequence[Candidate], pairs: Sequence[Candidate]) -> Verdict:
        """Select among ``singles`` and ``pairs`` (see the module documentation)."""
        single = self.best_single(singles)
        passing = [c for c in singles if c.passes]
        selected = single
        single_or_pair: list[tuple[Candidate, Candidate]] = []
        if single is not None:
            # Every pair is judged against the single itself, not against a pair that replaced it
            # earlier in the loop.
            with_single = [pair for pair in pairs if single.effect_ids[0] in pair.effect_ids]
            better = [pair for pair in pairs if self._replaces_selection(pair, single, passing)]
            # A pair that holds another passing pair as a special case must beat that one too.
            better = [pair for pair in better if self._beats_nested(pair, better)]
            if better:
                selected = min(better, key=lambda c: float(np.sum(c.heldout.sse)))
            else:
                single_or_pair = [(single, pair) for pair in with_single if self._pair_as_good(single, pair)]
        else:
            for pair in pairs:
                self.beats(pair, 0.0, self.base_sse, self.baseline.residual)
        indistinguishable, correlations = self._indistinguishable(selected, passing)
        return Verdict(selected, indistinguishable, correlations, self._unconfirmed(selected, singles), single_or_pair)

    def _replaces_selection(self, pair: Candidate, single: Candidate, passing: Sequence[Candidate]) -> bool:
        """Whether ``pair`` replaces the selected ``single``: a pair with it by :meth:`replaces`; a
        pair that holds another passing single instead where it replaces both, the single it holds
        (its second effect earns its place) and the selected one (it explains the data better than
        the selection). Where two singles are look-alikes (an adhesion limit and a stretch of low
        adhesion over most of the line), the second effect of the truth can lower the held-out
        error beside the one and not beside the other."""
        if single.effect_ids[0] in pair.effect_ids:
            return self.replaces(pair, single)
        held = [c for c in passing if c.effect_ids[0] in pair.effect_ids]
        return bool(held) and all(self.replaces(pair, c) for c in held) and self.replaces(pair, single)

    @staticmethod
    def held_single(pair: Candidate, singles: Sequence[Candidate]) -> Candidate:
        """The passing single that the selected ``pair`` was judged beside: the best single where
        the pair holds it, else the passing single it holds with the lowest held-out error."""
        passing = sorted((c for c in singles if c.passes), key=lambda c: float(np.sum(c.heldout.sse)))
        return next(c for c in passing if c.effect_ids[0] in pair.effect_ids)

    def _pair_as_good(self, single: Candidate, pair: Candidate) -> bool:
        """Whether ``pair`` (judged against ``single`` by :meth:`beats`, and not passing) explains
        the data as well as the single, by one of the two rules but not both: relevant, a held-out
        error within ``indistinguishable_heldout`` of the single's or lower, and either the BIC
        rule against the single (a BIC lower by ``select_delta_bic``, or for an added friction
        level its shared-shift test) or the held-out rule over the recordings the second effect
        acts on."""
        rules = self.rules
        single_sse = float(np.sum(single.heldout.sse))
        return (
            self.selectable(pair)
            and float(np.sum(pair.heldout.sse)) <= (1.0 + rules.indistinguishable_heldout) * single_sse
            and (pair.passes_bic_rule or pair.passes_heldout_rule)
        )

    def with_swapped_pairs(self, verdict: Verdict, swapped: Sequence[Candidate]) -> Verdict:
        """The verdict on a selected pair, given the pair with its single swapped for a look-alike
        (``swapped``, fitted by :mod:`.pipeline` beside the pair's second effect): a swapped
        pair that beats the selected one by every rule replaces it, and one that the data do not
        tell from it is named indistinguishable, as two singles are."""
        selected = verdict.selected
        if selected is None or len(selected.effect_ids) != 2 or not swapped:
            return verdict
        better = [pair for pair in swapped if self.replaces(pair, selected)]
        if better:
            selected = min(better, key=lambda c: float(np.sum(c.heldout.sse)))
        indistinguishable, correlations = list(verdict.indistinguishable), dict(verdict.signature_correlations)
        for other in [verdict.selected, *swapped]:
            if other is selected or not self._alike(selected, other):
                continue
            shared = set(selected.effect_ids) & set(other.effect_ids)
            (first,) = [e for e in selected.effect_ids if e not in shared]
            (second,) = [e for e in other.effect_ids if e not in shared]
            indistinguishable.append([first, second])
            correlations[f"{first} / {second}"] = self._signature_correlation(selected, other)
        return dataclasses.replace(
            verdict, selected=selected, indistinguishable=indistinguishable, signature_correlations=correlations
        )

    def _alike(self, selected: Candidate, other: Candidate) -> bool:
        """Whether the data do not tell ``other`` from ``selected``: a held-out error within
        ``indistinguishable_heldout`` of the selected one's or lower, and either a BIC within
        ``similar_bic`` or paired held-out differences that fail the held-out rule."""
        rules = self.rules
        best_sse = float(np.sum(selected.heldout.sse))
        close = float(np.sum(other.heldout.sse)) <= (1.0 + rules.indistinguishable_heldout) * best_sse
        similar_bic = abs(other.delta_bic - selected.delta_bic) < rules.similar_bic
        difference = (other.heldout.sse - selected.heldout.sse) / np.maximum(self.base_sse, 1e-12)
        tells_apart = self._consistent(paired_t(difference), paired_t_p_value(difference))
        return close and (similar_bic or not tells_apart)

    def _signature_correlation(self, selected: Candidate, other: Candidate) -> float:
        """How alike the two candidates' corrections to the unmodified model are."""
        return round(
            self.weighting.signature_correlation(self.baseline.residual, selected.fit.residual, other.fit.residual), 3
        )

    def _indistinguishable(
        self, selected: Candidate | None, passing: Sequence[Candidate]
    ) -> tuple[list[list[str]], dict[str, float]]:
        pairs: list[list[str]] = []
        correlations: dict[str, float] = {}
        if selected is None or len(selected.effect_ids) != 1:
            return pairs, correlations
        for other in passing:
            if other is not selected and self._alike(selected, other):
                first, second = selected.effect_ids[0], other.effect_ids[0]
                pairs.append([first, second])
                correlations[f"{first} / {second}"] = self._signature_correlation(selected, other)
        return pairs, correlations

    def _unconfirmed(self, selected: Candidate | None, singles: Sequence[Candidate]) -> list[Candidate]:
        rules = self.rules
        selected_ids = set(selected.effect_ids) if selected else set()
        return [
            c
            for c in singles
            if not c.passes
            and c.effect_ids[0] not in selected_ids
            and self.selectable(c)
            and c.delta_bic < rules.select_delta_bic
            and 1 <= len(c.report["heldout_acts_on"]) <= rules.unconfirmed_max_recordings
            and c.acting_gain >= rules.unconfirmed_min_gain
        ]


def nested_candidates(candidate: Candidate, others: Sequence[Candidate]) -> list[Candidate]:
    """Those of ``others`` that ``candidate`` holds as a special case: its effects with one of them
    replaced by an effect that one holds (:func:`brakegym.effects.special_cases`: a profile holds
    a section and the whole-line gradient), in the library's order."""
    by_ids = {c.effect_ids: c for c in others}
    nested = []
    for effect_id in candidate.effect_ids:
        for held in special_cases(effect_id):
            if held in candidate.effect_ids:
                continue
            ids = in_library_order(held if e == effect_id else e for e in candidate.effect_ids)
            if ids in by_ids:
                nested.append(by_ids[ids])
    return nested


def not_bounded_by_data(effect_ids: Sequence[str], ci95: Mapping[str, Sequence[float]], share: float) -> list[str]:
    """The parameters of ``effect_ids`` whose interval in ``ci95`` spans their search range (within
    ``share`` of it at both ends, :meth:`brakegym.effects.ParameterSpec.spans_range`): the data
    do not bound them, and such an interval holds any truth."""
    return [
        spec.name
        for effect_id in effect_ids
        for spec in EFFECTS[effect_id].parameters
        if not spec.integer and spec.name in ci95 and spec.spans_range(*ci95[spec.name], share)
    ]
