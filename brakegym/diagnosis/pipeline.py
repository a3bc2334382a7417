"""``brakegym diagnose``: locate the mismatch between recordings and the model, name the missing
physics from the effect library, fit it, and say how sure that is. A pipeline of stages:

1. **Noise**: each channel's AR(1) noise model from the recordings themselves
   (:func:`.locate.estimate_noise_models`); its level is the sigma the fit divides the channel's
   residuals by.
2. **Fit the unmodified model** to the recordings with their pressure transducers' zero offsets
   removed (:func:`.inputs.zero_corrected`), each recording's initial speed, initial disc
   temperature and friction factor fitted to convergence as nuisance parameters (:mod:`.fitting`);
   its residual's autocorrelation, and the noise's where that is larger, sets the effective sample
   weights (:mod:`.weighting`).
3. **Locate** where its residuals exceed the noise (segments) and the axis of the state along
   which they live (:mod:`.locate`).
4. **Screen** every effect of the library cheaply (:mod:`.screening`).
5. **Fit** the best ``top_singles`` effects in full (only those whose screening beats the
   unmodified model), each from its best screened point, from that point with the nuisance
   gridded with the effect acting and from the best point of its grid's second valley, the best
   fit kept (``Diagnoser._fit_screened``); and the pairs of the best ``pairs_from``; the
   friction level too where its screened point shows a shift shared by the recordings' friction
   factors (:func:`.judging.shared_friction_shift`), however it ranks; and the effects screened
   where the data locate them (a section, a stretch), beside the grid-screened ones.
6. **Fallback as a screening source**: with no single passing the rules of :mod:`.judging` and a
   residual the data-driven description would call unexplained, each library effect whose
   signature the residual matches (:mod:`.signatures`) is fitted from the start the signature
   gives, and judged with the singles. The screening's coarse grid can miss an effect's valley
   (a running resistance with a large quadratic term) that its signature in the residual shows.
7. **Forward step**: with a single selected by the rules of :mod:`.judging`, every other effect is
   screened again on top of it (its parameters held, the nuisance refitted from its fit), and the
   best ``forward_pairs`` of those that gain on it are fitted in full as pairs with it. A second
   effect is often hidden in the unmodified model's residual by the first one's (a friction level
   under a running resistance 30 times its imprint), so neither the screening against the
   unmodified model nor the pairs of the best singles reach it.
8. **Judge** them by BIC, held-out error and physical relevance (:mod:`.judging`); a pair replaces
   the selected single only when it beats the single by the same rules.
9. **Report** parameters with 95 % intervals, residuals before and after, candidates the data
   cannot tell apart (two singles, or the selected single and a pair with it) and what would
   separate them, and with no effect selected but a residual beyond noise, a data-driven
   description of what is unexplained (:mod:`.report`).

The thresholds are :class:`.rules.DiagnosisRules`; what the diagnosis needs to know of each effect
its class says (:class:`brakegym.effects.Effect`). ``docs/diagnosis.md`` describes the method and
its blind benchmark.

The linear algebra runs on one BLAS thread (:mod:`brakegym.execution.blas`): a verdict that turns
on the last bits (two candidates a hair apart) would otherwise depend on the machine's cores.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..effects import (
    EFFECTS,
    TRAIN_LENGTH_M,
    Evidence,
    FrictionLevel,
    in_library_order,
    nested_effects,
    special_cases,
)
from ..execution.blas import on_one_blas_thread
from ..plants import train_plant
from ..recordings.columns import DECEL, DISC_TEMPERATURE
from ..recordings.format import Recording, read_dataset
from .adhesion import read_adhesion
from .bootstrap import add_bootstrap_intervals
from .fitting import FRICTION_FACTOR, FitProblem, FitResult
from .inputs import (
    accelerometer_bias_sigma,
    beyond_the_search_note,
    chain_report,
    line_reach_m,
    on_set_line,
    zero_corrected,
)
from .judging import Candidate, Judge, shared_friction_shift
from .locate import (
    NOISE_CHANNELS,
    ResidualTrace,
    attribution,
    describe_unexplained,
    estimate_noise_models,
    residual_trace,
    segments,
)
from .noise import noise_model_entry
from .position_steps import PositionStep, find_position_step
from .report import build_report, candidate_entries
from .rules import DiagnosisRules
from .screening import ScreenedPoint, Screening, integer_neighbours
from .signatures import FallbackScreening, FallbackTry, match_signatures
from .weighting import CHANNEL_NAMES, Weighting

__all__ = ["Diagnoser", "Diagnosis", "diagnose", "look_alike_swaps", "pairing_pool"]


@dataclass
class Diagnosis:
    """A diagnosis: its ``report`` (what ``brakegym diagnose --json`` writes), and the recordings,
    the unmodified model's fit and the selected candidate behind it."""

    report: dict[str, Any]
    recordings: list[Recording]
    baseline: FitResult
    selected: Candidate | None
    problem: FitProblem


def located_start_max_m() -> float:
    """The furthest start from the line origin that the library's effects on part of the line
    (those screened from a located step, not on a grid) can take: the lowest upper bound of their
    ``*_start_m`` parameters."""
    return min(
        spec.upper
        for effect in EFFECTS.values()
        if not effect.grid_screened
        for spec in effect.parameters
        if spec.name.endswith("start_m")
    )


class Diagnoser:
    """Diagnoses the recordings of one vehicle (see the module documentation)."""

    def __init__(
        self,
        recordings: Sequence[Recording],
        top_singles: int | None = None,
        pairs_from: int | None = None,
        rules: DiagnosisRules | None = None,
    ) -> None:
        # Placed on one line where they carry line positions (counted from the set's origin).
        self.recordings, self.line_origin_m = on_set_line(recordings)
        self.line_reach_m = line_reach_m(self.recordings)
        vehicles = {r.vehicle.name for r in self.recordings}
        if len(vehicles) > 1:
            raise ValueError(
                f"the recordings are of several vehicles {sorted(vehicles)}; diagnose one vehicle at a time"
            )
        overrides = {"top_singles": top_singles, "pairs_from": pairs_from}
        self.rules = dataclasses.replace(
            rules or DiagnosisRules(), **{k: v for k, v in overrides.items() if v is not None}
        )
        self.noise_models = estimate_noise_models(self.recordings, self.rules.noise_window_s)
        # The level of a correlated noise, not what a white-noise estimate takes of it: on a 100 Hz
        # accelerometer with rho 0.8 a white estimate reads half the level, and every threshold
        # in noise sigmas would be twice too lax.
        self.noise = {c: self.noise_models[c].sigma if c in self.noise_models else float("nan") for c in NOISE_CHANNELS}
        fit_noise = {c: v for c, v in self.noise.items() if np.isfinite(v) and v > 0}
        self.decel_bias_sigma = accelerometer_bias_sigma(self.recordings, self.noise_models.get(DECEL))
        # The fit replays each recording with its transducers' identifiable zero offsets removed;
        # the report describes the recordings as they were read.
        self.problem = FitProblem([zero_corrected(r) for r in self.recordings], fit_noise)
        self.n_discs = train_plant(self.recordings[0].vehicle).n_discs
        self._residual: BaselineResidual | None = None

    def _evidence(self, baseline: FitResult, position_steps: Sequence[PositionStep]) -> Evidence:
        """What the set shows of itself; ``position_steps``: the steps along position, the first
        and, in what it leaves, a second (:meth:`_position_steps`), those located screened."""
        decels = [r.channel(DECEL) for r in self.recordings if r.channel(DECEL) is not None]
        temperatures = [r.channel(DISC_TEMPERATURE) for r in self.recordings if r.channel(DISC_TEMPERATURE) is not None]
        located = [step.stretch() for step in position_steps if self._located(step)]
        return Evidence(
            peak_decel_mps2=float(max(np.nanpercentile(d, 99) for d in decels)) if decels else math.inf,
            peak_disc_C=float(max(np.nanmax(t) for t in temperatures)) if temperatures else math.inf,
            friction_factors=baseline.nuisance[self.problem.nuisance_block(FRICTION_FACTOR)],
            nominal_resistance=self.recordings[0].vehicle.running_resistance,
            run_distance_m=max(
                float(np.nanmax(r.recording.metadata.on_line_m(r.states["true_position_m"].to_numpy())))
                for r in baseline.replays
            ),
            stretches=tuple(located[:1]),
            profile_stretches=tuple(located) if len(located) == 2 else (),
        )

    def _located(self, step: PositionStep) -> bool:
        return step.explained_share >= self.rules.position_step_min_share

    def _position_steps(self, weighting: Weighting, baseline: FitResult) -> list[PositionStep]:
        """Where the unmodified model's residual steps along position (an effect on part of the
        line is screened there): the step that explains most, and where it is located, a second
        one in what it leaves (a profile of two sections)."""
        traces = self._baseline_residual(weighting, baseline).traces
        bin_m = self.rules.position_step_bin_m
        first = find_position_step(traces, bin_m, TRAIN_LENGTH_M)
        if first is None:
            return []
        second = find_position_step(traces, bin_m, TRAIN_LENGTH_M, earlier=(first,)) if self._located(first) else None
        return [first] if second is None else [first, second]

    @on_one_blas_thread
    def unmodified_fit(self) -> FitResult:
        """The unmodified model fitted to the recordings: each recording's nuisance alone, from
        two starts (the gridded friction factors, then the centre of the priors), the better one
        kept recording by recording (:meth:`.fitting.FitProblem.refit_nuisance_from_prior_centre`)."""
        problem = self.problem
        first = problem.fit([], problem.gridded_start())
        better = problem.refit_nuisance_from_prior_centre([], {}, [], first.x)
        if np.array_equal(better, first.x):
            return first
        return problem.fit([], better)

    def weighting(self, baseline: FitResult) -> Weighting:
        """The effective sample weights every candidate is judged by, from ``baseline`` (the
        unmodified model's fit) and each channel's noise autocorrelation."""
        noise_rho = {c: m.rho for c, m in self.noise_models.items() if np.isfinite(m.rho)}
        return Weighting(self.problem, baseline.residual, noise_rho)

    @on_one_blas_thread
    def fit_effects(
        self,
        effect_ids: Sequence[str],
        start: dict[str, float] | None = None,
        fixed: dict[str, float] | None = None,
    ) -> Candidate:
        """The named effects fitted without any selection: a model the user knows, or one whose
        intervals are measured where it is right (``benchmarks/bench_coverage.py``). Integer
        parameters are held at ``fixed``. The fit starts at ``start`` (a value for each
        continuous parameter, by name) with each recording's nuisance from the unmodified model's
        fit, or without ``start`` where the diagnosis starts it: each effect fitted alone from its
        screening's starts as the diagnosis fits a single (an integer parameter not in ``fixed``
        takes that fit's value), then all together from those fits' parameters and the better
        one's nuisance. The candidate carries the report entry of a selected model: parameters,
        the 95 % intervals with the bootstrap's, residuals, held-out figures."""
        unknown = sorted(set(effect_ids) - set(EFFECTS))
        if unknown:
            raise ValueError(f"unknown effect(s) {unknown}; the library has {list(EFFECTS)}")
        ids = in_library_order(effect_ids)
        problem, rules, fixed = self.problem, self.rules, dict(fixed or {})
        if start is not None:
            missing = [p.name for p in problem.free_parameters(list(ids), fixed) if p.name not in start] + [
                spec.name for eid in ids for spec in EFFECTS[eid].parameters if spec.integer and spec.name not in fixed
            ]
            if missing:
                raise ValueError(f"effects {list(ids)}: no value for parameter(s) {missing} (integer ones go in fixed)")
        baseline = self.unmodified_fit()
        weighting = self.weighting(baseline)
        evidence = self._evidence(baseline, self._position_steps(weighting, baseline))
        nuisance = baseline.nuisance
        if start is None:
            start, nuisance = self._screened_start(ids, fixed, weighting, evidence, baseline)
        free = problem.free_parameters(list(ids), fixed)
        x0 = np.concatenate([[start[parameter.name] for parameter in free], nuisance])
        fit = problem.fit(list(ids), x0, fixed=fixed, max_iterations=rules.fit_iterations)
        candidate = Judge(problem, weighting, rules, evidence, baseline).candidate(ids, fit)
        candidate_entries(problem, weighting, baseline, [candidate], rules)
        add_bootstrap_intervals(problem, candidate, self.noise_models, rules, self.decel_bias_sigma)
        return candidate

    def _screened_start(
        self,
        ids: tuple[str, ...],
        fixed: dict[str, float],
        weighting: Weighting,
        evidence: Evidence,
        baseline: FitResult,
    ) -> tuple[dict[str, float], np.ndarray]:
        """Where :meth:`fit_effects` starts without given values: each effect fitted alone from
        its screening as the diagnosis fits its singles (``_fit_screened``; an integer
        parameter not held takes the value of that fit, into ``fixed``), and the joint fit from
        their parameters and the better one's nuisance, as the diagnosis fits its pairs: from
        separate screened points a joint fit can end far from the optimum."""
        problem, rules = self.problem, self.rules
        screening = Screening(problem, weighting, rules, evidence, self.n_discs, baseline)
        open_ids = [e for e in ids if any(spec.name not in fixed for spec in EFFECTS[e].parameters)]
        screened = screening.run(open_ids, held=fixed)
        unscreened = sorted(set(open_ids) - set(screened))
        if unscreened:
            raise ValueError(f"effect(s) {unscreened} have no screening point on these recordings; give start values")
        start: dict[str, float] = {}
        nuisance, best_chi2 = baseline.nuisance, math.inf
        held = dict(fixed)
        for effect_id in open_ids:
            point = screened[effect_id]
            vary = not any(spec.integer and spec.name in held for spec in EFFECTS[effect_id].parameters)
            alone = self._fit_screened(screening, effect_id, point, weighting, vary)
            fixed.update(alone.fixed)
            start.update(alone.parameters)
            if weighting.chi2(alone.residual) < best_chi2:
                best_chi2, nuisance = weighting.chi2(alone.residual), alone.nuisance
        return start, nuisance

    @on_one_blas_thread
    def run(self) -> Diagnosis:
        problem, rules = self.problem, self.rules
        baseline = self.unmodified_fit()
        weighting = self.weighting(baseline)
        position_steps = self._position_steps(weighting, baseline)
        evidence = self._evidence(baseline, position_steps)
        judge = Judge(problem, weighting, rules, evidence, baseline)
        screening = Screening(problem, weighting, rules, evidence, self.n_discs, baseline)
        screened = screening.run()
        singles = self._fit_singles(screening, screened, judge, baseline)
        pairs = self._fit_pairs(singles, judge)
        single = judge.best_single(singles)
        fallback = None
        if single is None:
            singles, fallback = self._fallback_screening(weighting, baseline, singles, judge)
            single = judge.best_single(singles)
        forward: dict[str, ScreenedPoint] = {}
        if single is not None and self.rules.forward_pairs > 0:
            forward_pairs, forward = self._forward_pairs(single, pairs, judge, evidence)
            pairs += forward_pairs
        verdict = judge.verdict(singles, pairs)
        if single is not None and verdict.selected is not None and len(verdict.selected.effect_ids) == 2:
            held = judge.held_single(verdict.selected, singles)
            # The forward step screened on top of the selected single only.
            beside_held = forward if held is single else {}
            swapped = self._swapped_pairs(held, verdict.selected, singles, pairs, judge, beside_held)
            pairs += swapped
            verdict = judge.with_swapped_pairs(verdict, swapped)
        mismatch, unexplained = self._locate(weighting, baseline, verdict.selected, bool(verdict.unconfirmed))
        entries = candidate_entries(problem, weighting, baseline, singles + pairs, rules)
        if verdict.selected is not None:
            add_bootstrap_intervals(problem, verdict.selected, self.noise_models, rules, self.decel_bias_sigma)
        report = build_report(
            problem,
            weighting,
            self.noise,
            mismatch,
            unexplained,
            entries,
            verdict,
            screened,
            {c.effect_ids[0] for c in singles},
            judge.chi2_base,
        )
        report["forward_screening"] = forward_screening_entry(single, forward) if forward else None
        report["fallback_screening"] = fallback.report_entry(verdict.selected) if fallback is not None else None
        self._add_data_entries(report, position_steps, verdict.selected)
        return Diagnosis(report, self.recordings, baseline, verdict.selected, problem)

    def _add_data_entries(
        self, report: dict[str, Any], position_steps: list[PositionStep], selected: Candidate | None
    ) -> None:
        """The report's keys on the recordings themselves: the steps along position, where the
        line's positions count from and how far they reach, the measurement chain, each channel's
        noise model, and a selected adhesion limit read as a rail."""
        report["position_step"] = position_steps[0].report_entry() if position_steps else None
        # In what the first step leaves: with it, a profile of two sections is screened.
        report["second_position_step"] = position_steps[1].report_entry() if len(position_steps) > 1 else None
        # Positions of located effects count from here along the line (None: from each
        # recording's first sample).
        report["line_origin_m"] = self.line_origin_m
        # How far along the line from the origin the recordings reach (None: not placed on it).
        reach = self.line_reach_m
        report["line_reach_m"] = None if reach is None else round(reach, 1)
        note = beyond_the_search_note(reach, located_start_max_m())
        if note is not None:
            report["summary"] += " " + note
        report["measurement_chain"] = chain_report(self.recordings)
        report["noise_model"] = {
            CHANNEL_NAMES[channel]: noise_model_entry(model) for channel, model in self.noise_models.items()
        }
        if CHANNEL_NAMES[DECEL] in report["noise_model"]:
            report["noise_model"][CHANNEL_NAMES[DECEL]]["bias_sigma_between_recordings"] = round(
                self.decel_bias_sigma, 5
            )
        if selected is not None and "adhesion_limit" in selected.effect_ids:
            # The cap read as a rail: its peak adhesion, the nearest condition and Polach's mu_0.
            mass_kg = float(np.mean([recording.mass_kg for recording in self.recordings]))
            reading = read_adhesion(report["parameters"]["adhesion"], self.recordings[0].vehicle, mass_kg)
            report["adhesion_limit_rail"] = reading.as_dict()

    def _fit_singles(
        self, screening: Screening, screened: dict[str, ScreenedPoint], judge: Judge, baseline: FitResult
    ) -> list[Candidate]:
        """The best screened effects fitted in full, best BIC first. An effect whose best screened
        point does not beat the unmodified model has its optimum at (or next to) its no-effect
        value: fitting it in full costs the most (several effects run their hooks in Python at
        every RK4 stage) and can only confirm that.

        The ``top_singles`` are the best of the grid-screened effects; an effect screened where
        the data locate it (a section, a stretch) is fitted beside them, not in place of one: a
        step along position that a whole-line effect leaves (an adhesion limit's) makes the
        stretch its look-alike, and it would push the next different effect out. A located effect
        must beat what it holds as a special case (:func:`.judging.nested_candidates`: a profile
        of sections the whole-line gradient), so those are fitted too where their screening
        promises a gain: a profile that follows a gradient over the recordings' reach would
        otherwise meet no gradient to beat."""
        rules = self.rules
        order = sorted(screened, key=lambda e: screened[e].chi2)
        promising = [e for e in order if screened[e].chi2 < judge.chi2_base - rules.screen_min_gain]
        gridded = [e for e in promising if EFFECTS[e].grid_screened]
        located = [e for e in promising if not EFFECTS[e].grid_screened]
        chosen = self._with_shared_shift(gridded, rules.top_singles, screened) + located
        chosen += [e for e in gridded if e not in chosen and any(e in special_cases(x) for x in located)]
        singles = []
        for effect_id in chosen:
            fit = self._fit_screened(screening, effect_id, screened[effect_id], judge.weighting)
            singles.append(judge.candidate((effect_id,), fit))
        singles.sort(key=lambda c: c.delta_bic)
        return singles

    def _fit_screened(
        self,
        screening: Screening,
        effect_id: str,
        point: ScreenedPoint,
        weighting: Weighting,
        vary_integer: bool = True,
    ) -> FitResult:
        """``effect_id`` fitted alone in full from several starts, the fit of least effective
        chi^2 kept:

        - its best screened ``point``, with the point's nuisance;
        - the point with the nuisance gridded with the effect acting
          (:meth:`.fitting.FitProblem.gridded_start`): the point's nuisance comes from the
          unmodified model's, which can lie in a valley of its own;
        - the best points of the grid's other valleys where the effect acts
          (``screen_valleys`` in all; on a grid of 2-3 points per parameter, its next best
          point): wet pads' chi^2 has a second valley, a larger loss drying more slowly against
          friction factors 20 % high, that the coarse grid can rate best;
        - an integer parameter's neighbours (unless not ``vary_integer``): the screening's chord
          iterations leave a few percent of chi^2 unconverged, as much as one failed unit of
          sixteen is worth once the friction factors have absorbed most of it.
        """
        problem, rules = self.problem, self.rules
        free = problem.free_parameters([effect_id], point.fixed)
        gridded = problem.gridded_start([effect_id], point.fixed, free, point.theta)
        starts = [(point.fixed, point.theta, point.nuisance), (point.fixed, point.theta, gridded)]
        starts += [(v.fixed, v.theta, v.nuisance) for v in point.other_valleys[: max(rules.screen_valleys - 1, 0)]]
        for neighbour in integer_neighbours(effect_id, point.fixed) if vary_integer else ():
            starts.append((neighbour, point.theta, screening.starts(effect_id, neighbour, point.theta[None])[0]))
        return self._best_of_starts(effect_id, starts, weighting)

    def _best_of_starts(
        self,
        effect_id: str,
        starts: Sequence[tuple[dict[str, float], np.ndarray, np.ndarray]],
        weighting: Weighting,
    ) -> FitResult:
        """``effect_id`` fitted alone in full from each of ``starts`` (held integer values, free
        parameters, nuisance), the fit of least effective chi^2 kept (a non-finite one last)."""
        iterations = self.rules.fit_iterations
        fits = [
            self.problem.fit([effect_id], np.concatenate([theta, nuisance]), fixed=fixed, max_iterations=iterations)
            for fixed, theta, nuisance in starts
        ]
        return _least_chi2(fits, weighting)

    def _fit_pairs(self, singles: Sequence[Candidate], judge: Judge) -> list[Candidate]:
        """The pairs of the best ``pairs_from`` singles of grid-screened effects, and of the best
        located one where it ranks among the best ``pairs_from`` of all (see ``_fit_singles``),
        fitted from the singles' parameters with the nuisance of the better one (the unmodified
        model's has absorbed what that effect explains: friction factors near 0.75 where units
        failed) and with the unmodified model's (the better single's has absorbed what the other
        effect explains, and can lie in a valley of its own); the fit of least effective chi^2
        is kept."""
        pairs = []
        for a, b in itertools.combinations(pairing_pool(singles, self.rules.pairs_from), 2):
            ids = in_library_order((a.effect_ids[0], b.effect_ids[0]))
            fixed = {**a.fit.fixed, **b.fit.fixed}
            values = {**a.fit.parameters, **b.fit.parameters}
            fits = [
                self._fit_from_values(ids, fixed, values, nuisance)
                for nuisance in (a.fit.nuisance, judge.baseline.nuisance)
            ]
            pairs.append(judge.candidate(ids, _least_chi2(fits, judge.weighting)))
        return pairs

    def _forward_pairs(
        self, single: Candidate, pairs: Sequence[Candidate], judge: Judge, evidence: Evidence
    ) -> tuple[list[Candidate], dict[str, ScreenedPoint]]:
        """The forward step on the rest: every other effect screened on top of the selected
        ``single`` (its parameters held), and the best ``forward_pairs`` of those whose screening
        beats the single by ``screen_min_gain`` fitted in full as pairs with it, from its
        parameters and the screened point's, with the point's nuisance and with the unmodified
        model's (an integer parameter's neighbours too, as for the singles); the fit of least
        effective chi^2 is kept. Pairs already among ``pairs`` are not fitted again. Returns the
        new pairs and the screened points."""
        problem, rules = self.problem, self.rules
        given = Screening(problem, judge.weighting, rules, evidence, self.n_discs, single.fit)
        screened = given.run()
        (selected_id,) = single.effect_ids
        fitted = {frozenset(pair.effect_ids) for pair in pairs}
        order = sorted(screened, key=lambda e: screened[e].chi2)
        promising = [
            e
            for e in order
            if screened[e].chi2 < single.chi2_eff - rules.screen_min_gain and frozenset((selected_id, e)) not in fitted
        ]
        unmodified_nuisance = judge.baseline.nuisance
        new_pairs = []
        for effect_id in self._with_shared_shift(promising, rules.forward_pairs, screened):
            point = screened[effect_id]
            ids = in_library_order((selected_id, effect_id))
            fits = []
            for fixed, nuisance in [(point.fixed, point.nuisance), (point.fixed, unmodified_nuisance)] + [
                (neighbour, given.starts(effect_id, neighbour, point.theta[None])[0])
                for neighbour in integer_neighbours(effect_id, point.fixed)
            ]:
                values = {**single.fit.parameters, **dict(zip(_free_names(problem, effect_id, fixed), point.theta))}
                fits.append(self._fit_from_values(ids, {**single.fit.fixed, **fixed}, values, nuisance))
            new_pairs.append(judge.candidate(ids, _least_chi2(fits, judge.weighting)))
        return new_pairs, screened

    def _swapped_pairs(
        self,
        single: Candidate,
        pair: Candidate,
        singles: Sequence[Candidate],
        pairs: Sequence[Candidate],
        judge: Judge,
        forward: dict[str, ScreenedPoint],
    ) -> list[Candidate]:
        """The selected ``pair`` with each of its effects swapped for a look-alike
        (:func:`look_alike_swaps`), each fitted from the look-alike's own fit and the pair's; one
        that takes the second effect's place also from its point in the forward step's
        screening on top of the single (``forward``), as the forward step's pairs start."""
        swapped = []
        for kept, other in look_alike_swaps(single, pair, singles, pairs, self.rules.swapped_pairs):
            beside_single = kept == single.effect_ids[0]
            screened = forward.get(other.effect_ids[0]) if beside_single else None
            fit = self._fit_swapped(pair, kept, other, screened, judge)
            swapped.append(judge.candidate(fit.effect_ids, fit))
        return swapped

    def _fit_swapped(
        self,
        pair: Candidate,
        kept: str,
        other: Candidate,
        screened: ScreenedPoint | None,
        judge: Judge,
    ) -> FitResult:
        """The pair of ``kept`` (one of ``pair``'s effects) and the single ``other``, fitted from
        ``kept``'s parameters in the pair's fit and ``other``'s own fit, with the nuisance of
        ``other``'s fit (the pair's has absorbed what the swapped-out effect explained) and with
        the unmodified model's; and from ``other``'s ``screened`` point with its nuisance where
        given. The fit of least effective chi^2 is kept. A look-alike's own fit can lie far from
        where it sits beside ``kept`` (a gradient fitted alone where an adhesion limit acts ends
        at twice its size), and its nuisance with it: from there the fit stops in a valley that
        the unmodified model's friction factors lead out of."""
        problem = self.problem
        (other_id,) = other.effect_ids
        ids = in_library_order((other_id, kept))
        kept_names = {spec.name for spec in EFFECTS[kept].parameters}
        kept_fixed = {k: v for k, v in pair.fit.fixed.items() if k in kept_names}
        kept_values = {k: v for k, v in pair.fit.parameters.items() if k in kept_names}
        own = (other.fit.fixed, other.fit.parameters)
        starts = [(*own, other.fit.nuisance), (*own, judge.baseline.nuisance)]
        if screened is not None:
            screened_values = dict(zip(_free_names(problem, other_id, screened.fixed), screened.theta))
            starts.append((screened.fixed, screened_values, screened.nuisance))
        fits = [
            self._fit_from_values(ids, {**other_fixed, **kept_fixed}, {**kept_values, **other_values}, nuisance)
            for other_fixed, other_values, nuisance in starts
        ]
        return _least_chi2(fits, judge.weighting)

    def _fit_from_values(
        self, ids: tuple[str, ...], held: dict[str, float], values: dict[str, float], nuisance: np.ndarray
    ) -> FitResult:
        """``ids`` fitted with ``held`` integer values, from ``values`` (by parameter name; names
        not free are ignored) and ``nuisance``."""
        free = self.problem.free_parameters(list(ids), held)
        start = np.concatenate([[values[parameter.name] for parameter in free], nuisance])
        return self.problem.fit(list(ids), start, fixed=held, max_iterations=self.rules.fit_iterations)

    def _fallback_screening(
        self, weighting: Weighting, baseline: FitResult, singles: Sequence[Candidate], judge: Judge
    ) -> tuple[list[Candidate], FallbackScreening | None]:
        """Before the verdict "unexplained" (no single passes, and the residual is described):
        each library effect whose signature the residual matches (:mod:`.signatures`), fitted from
        the start the signature gives and judged as any single. The start's nuisance is the
        unmodified model's and, as for a screened single, the one gridded with the effect acting
        at the start: the unmodified model's friction factors have absorbed what the effect
        explains (a gradient read off coasting at 21 permil ends at 20.8 permil and four times the
        unmodified chi^2 from the first, at 17.5 permil and a tenth of it from the second). A fit
        that beats the screening's fit of the same effect in chi^2 replaces it among the singles;
        the verdict then judges them all by the same rules. Returns the singles, best BIC first,
        and what the fallback tried (None where it did not run)."""
        problem, rules = self.problem, self.rules
        residual = self._baseline_residual(weighting, baseline)
        if residual.description is None:
            return list(singles), None
        nominal = self.recordings[0].vehicle.running_resistance
        matches = match_signatures(residual.traces, nominal, rules.fallback_share_of_eta2)
        singles = list(singles)
        tries = []
        for match in matches[: rules.fallback_max_fits]:
            start_values = match.start_inside_bounds()
            free = problem.free_parameters([match.effect_id], {})
            theta = np.array([start_values[p.name] for p in free])
            gridded = problem.gridded_start([match.effect_id], {}, free, theta)
            starts = [({}, theta, baseline.nuisance), ({}, theta, gridded)]
            fit = self._best_of_starts(match.effect_id, starts, weighting)
            candidate = judge.candidate((match.effect_id,), fit)
            # Its figures against the unmodified model, for the report also where it is not kept.
            candidate.passes = judge.beats(candidate, 0.0, judge.base_sse, baseline.residual)
            screened = next((c for c in singles if c.effect_ids == candidate.effect_ids), None)
            replaces = screened is None or candidate.chi2_eff < screened.chi2_eff
            if replaces:
                singles = [c for c in singles if c is not screened] + [candidate]
            tries.append(FallbackTry(match, candidate, replaces))
        singles.sort(key=lambda c: c.delta_bic)
        return singles, FallbackScreening(residual.description, tries)

    def _baseline_residual(self, weighting: Weighting, baseline: FitResult) -> BaselineResidual:
        """The unmodified model's residual traces, where they exceed the noise, and their
        data-driven description (computed once)."""
        if self._residual is None:
            problem, rules = self.problem, self.rules
            traces = [residual_trace(r) for r in baseline.replays]
            shares = attribution(traces)
            base_rms = weighting.rms(baseline.residual)
            over_noise = {c: base_rms[c] / problem.noise[c] for c in base_rms}
            channels = [CHANNEL_NAMES[c] for c, ratio in over_noise.items() if ratio >= rules.mismatch_rms_over_noise]
            best_eta = max((max(v.values()) for v in shares.values()), default=0.0)
            described = best_eta >= rules.unexplained_eta2 and bool(channels)
            description = describe_unexplained(traces, shares) if described else None
            self._residual = BaselineResidual(traces, shares, over_noise, channels, description)
        return self._residual

    def _with_shared_shift(self, promising: list[str], count: int, screened: dict[str, ScreenedPoint]) -> list[str]:
        """The first ``count`` of the ``promising`` effects (best screened first), and the friction
        level beyond them where its screened point shows a shift shared by the recordings'
        friction factors (:func:`.judging.shared_friction_shift`). A level's chi^2 gain is its
        factors' prior rows alone, about z^2, which any effect that fits some structure of the
        data outranks (a rotating mass, a speed-sensor scale), so the ranking left it unfitted."""
        chosen = promising[:count]
        level = FrictionLevel.id
        if count > 0 and level in promising[count:]:
            point = screened[level]
            factors = point.nuisance[self.problem.nuisance_block(FRICTION_FACTOR)]
            shift = shared_friction_shift(float(point.theta[0]), factors, self.problem.prior_sigma)
            if abs(shift.z) >= self.rules.friction_level_min_z:
                chosen.append(level)
        return chosen

    def _locate(
        self, weighting: Weighting, baseline: FitResult, selected: Candidate | None, significant_anyway: bool
    ) -> tuple[dict[str, Any], dict[str, Any] | None]:
        """Where the unmodified model misses the data: the mismatch entry of the report, and with
        nothing selected but a residual beyond noise, the data-driven description."""
        residual = self._baseline_residual(weighting, baseline)
        unexplained = residual.description if selected is None else None
        significant = selected is not None or unexplained is not None or significant_anyway
        mismatch = {
            "significant": significant,
            "channels": residual.channels if significant else [],
            "segments": segments(residual.traces, self.problem.noise),
            "rms_over_noise": {CHANNEL_NAMES[c]: round(v, 2) for c, v in residual.over_noise.items()},
            "attribution_eta2": residual.shares,
        }
        return mismatch, unexplained


@dataclass
class BaselineResidual:
    """The unmodified model's residual: its traces, eta^2 per axis, RMS over noise per channel,
    the channels beyond ``mismatch_rms_over_noise`` and the data-driven description (None where
    no axis reaches ``unexplained_eta2`` or no channel is a mismatch)."""

    traces: list[ResidualTrace]
    shares: dict[str, dict[str, float]]
    over_noise: dict[str, float]
    channels: list[str]
    description: dict[str, Any] | None


def _least_chi2(fits: Sequence[FitResult], weighting: Weighting) -> FitResult:
    """The fit of least effective chi^2 of ``fits`` (a non-finite one last)."""
    chi2s = [weighting.chi2(f.residual) for f in fits]
    return fits[min(range(len(fits)), key=lambda j: (not np.isfinite(chi2s[j]), chi2s[j]))]


def _free_names(problem: FitProblem, effect_id: str, fixed: dict[str, float]) -> list[str]:
    """The names of ``effect_id``'s free parameters with ``fixed`` held, in the screening's order."""
    return [parameter.name for parameter in problem.free_parameters([effect_id], fixed)]


def pairing_pool(singles: Sequence[Candidate], count: int) -> list[Candidate]:
    """The singles whose pairs are fitted: the best ``count`` of grid-screened effects, and the
    best of those screened where the data locate them (a section, a stretch) where it ranks among
    the best ``count`` of all; ``singles`` best BIC first, and so is the pool."""
    pool = [c for c in singles if EFFECTS[c.effect_ids[0]].grid_screened][:count]
    pool += [c for c in singles[:count] if not EFFECTS[c.effect_ids[0]].grid_screened][:1]
    return sorted(pool, key=lambda c: c.delta_bic)


def look_alike_swaps(
    single: Candidate, pair: Candidate, singles: Sequence[Candidate], pairs: Sequence[Candidate], count: int
) -> list[tuple[str, Candidate]]:
    """The pairs to fit beside the selected ``pair`` (``single``, the passing single it holds
    (:meth:`.judging.Judge.held_single`), and a second effect):
    each of its effects (the second first) kept, beside each of the next ``count`` passing
    ``singles`` (lowest held-out error first) in the other's place; as (kept effect id, single).

    The forward step fits pairs with the selected single only, from the effects that screen best
    on top of it: a look-alike of the single (the same loss of brake force as failed units or as a
    rotating mass) would otherwise never meet the pair's second effect, nor a look-alike of the
    second effect (a gradient's loss of deceleration against a failed unit's, on top of an
    adhesion limit) the single. Pairs among ``pairs`` (already fitted), and those of an effect
    with one it holds as a special case (:func:`brakegym.effects.nested_effects`), are left out."""
    (first,) = single.effect_ids
    (second,) = [e for e in pair.effect_ids if e != first]
    fitted = {frozenset(c.effect_ids) for c in pairs}
    others = sorted(
        (c for c in singles if c.passes and c.effect_ids[0] not in pair.effect_ids),
        key=lambda c: float(np.sum(c.heldout.sse)),
    )
    swaps = []
    for kept in (second, first):
        for other in others[:count]:
            ids = frozenset((other.effect_ids[0], kept))
            if ids in fitted or nested_effects(other.effect_ids[0], kept):
                continue
            fitted.add(ids)
            swaps.append((kept, other))
    return swaps


def forward_screening_entry(single: Candidate, screened: dict[str, ScreenedPoint]) -> dict[str, Any]:
    """The report's account of the forward step: each other effect's profiled effective chi^2 on
    top of the selected single, best first, against the single's own (the key is None without a
    selected single)."""
    return {
        "given": list(single.effect_ids),
        "chi2_eff_given": round(float(single.chi2_eff), 1),
        "chi2_eff_profiled": {
            effect_id: round(float(screened[effect_id].chi2), 1)
            for effect_id in sorted(screened, key=lambda e: screened[e].chi2)
        },
    }


def diagnose(
    dataset: str | Path | Sequence[Recording],
    top_singles: int | None = None,
    pairs_from: int | None = None,
    rules: DiagnosisRules | None = None,
) -> Diagnosis:
    """Diagnose a folder of recordings (or the recordings given) under ``rules`` (the defaults
    where None; ``top_singles`` and ``pairs_from`` override theirs) (see the module documentation)."""
    recordings = read_dataset(dataset).recordings if isinstance(dataset, (str, Path)) else list(dataset)
    return Diagnoser(recordings, top_singles, pairs_from, rules).run()
