"""Judging on recordings held out of the fit: leave one recording out, refit the effect's
parameters on the others, and predict the recording left out.

The refit is one weighted Gauss-Newton step of the others' data from the fit to every recording,
kept inside the parameter bounds; the recording left out is then simulated with those parameters,
its own nuisance refitted by chord iterations as in screening. The same simulation gives the
others' chi^2 at the stepped point; where it fell by much less than the step's quadratic model
promised (the trust-region test of a Gauss-Newton step), the step left the range where it is
linear, and the others are fitted in full instead, from the fit to every recording; the recording
left out is then predicted from their optimum (its own nuisance refitted to convergence). Only
the others' data trigger that fit: a trigger on the left-out recording's own prediction (refit
where it came out worse than no effect) would bias the held-out gains upwards.

A size that rests on the recording left out (the others hold less than ``min_others_share`` of its
information) and that the others do not see (from their data alone it would not stand ``unseen_z``
standard errors from its no-effect value, the parameters that place the effect held: the loss of a
thermal fade that only the hottest stop reaches, the gradient of a section inside one stop's reach)
cannot be refitted without that recording: the others' optimum is arbitrary along it, and a bounded
step there lands anywhere in the search range, with a prediction far worse than no effect at all.
Without that recording nothing says the effect is there, so the recording is predicted with that
size at its no-effect value (the other parameters refitted with it held there, the recording's
nuisance refitted from the unmodified model's), and the effect gains nothing on it. Where that
leaves the candidate absent from the recording (every size held, a placing parameter irrelevant
then), the prediction is the unmodified model's fit of the recording itself: a few chord iterations
from there with the candidate's nuisance Jacobian moved it off that optimum, a spurious loss. The
placing parameters (``ParameterSpec.locates``: a section's end, a fade's onset) are held in the
second test because the others may see an effect whose place they cannot tell apart from its size:
stops just above a fade's onset see the fade, but not its onset apart from its loss. Such
parameters keep the others' step; their no-effect values would remove an effect the others show.
Both tests are asked: one very hot stop can hold nine tenths of a fade's information while the next
hottest alone measures its loss to a few percent, and an effect spread evenly over the recordings
(a friction level) rests on none of them, however weak.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize

from ..effects import EFFECTS
from ..statistics import conditional_information
from .fitting import NUISANCE_KINDS, FitProblem, FitResult
from .rules import DiagnosisRules
from .weighting import Weighting


@dataclass
class HeldOut:
    """The leave-one-recording-out prediction of a fit."""

    residual: np.ndarray  # every row predicted with the effect fitted without its recording
    sse: np.ndarray  # per recording, effective (its friction-factor prior row included)
    # (recordings, effect parameters): each recording's leave-out change, every parameter refitted
    # on the others (the jackknife's steps)
    steps: np.ndarray
    # (recordings, effect parameters): the share of each effect parameter's information (the other
    # effect parameters free, every recording's nuisance projected out) that the other recordings
    # hold; near 0 where one recording holds the parameter alone
    others_share: np.ndarray
    # (recordings, effect parameters): held at the no-effect value in the recording's prediction,
    # a size resting on the recording that the others do not see
    held_at_no_effect: np.ndarray
    # (recordings,): predicted from a full fit to the others, their one step having left its
    # linear range
    refitted: np.ndarray


def held_out(
    problem: FitProblem,
    weighting: Weighting,
    fit: FitResult,
    rules: DiagnosisRules,
    reference: FitResult | None = None,
) -> HeldOut:
    """Each recording predicted with the effect parameters fitted without it; with ``reference``
    (the unmodified model's fit), a recording with a size held at no effect starts its nuisance
    refit from the reference's, one where the candidate is then absent is the reference's
    residual, and one whose others' step left the range where it is linear is predicted from a
    fit of the others (without ``reference``, neither: the unmodified model's own held-out
    error)."""
    p = len(fit.free)
    steps = np.zeros((problem.n, p))
    others_share = np.ones((problem.n, p))
    at_no_effect = np.zeros((problem.n, p), dtype=bool)
    refitted = np.zeros(problem.n, dtype=bool)
    held = fit.residual.copy()
    if p:
        blocks, information = _projected_information(problem, weighting, fit)
        steps = _leave_one_out_steps(problem, fit, blocks, information, at_no_effect)
        others_share = _others_share(information)
        no_effect = _no_effect_values(problem, fit)
        if reference is not None:
            unseen = _unseen_sizes(problem, fit, information, no_effect, rules.heldout_unseen_z)
            at_no_effect = (others_share < rules.one_recording_share) & unseen
        lower, upper = problem.bounds(fit.free)
        points = np.tile(fit.x, (problem.n, 1))
        points[:, :p] = np.clip(fit.x[:p] + steps, lower[:p], upper[:p])
        if at_no_effect.any():
            others_steps = _leave_one_out_steps(problem, fit, blocks, information, at_no_effect, no_effect)
            others_fit = np.clip(fit.x[:p] + others_steps, lower[:p], upper[:p])
            points[:, :p] = np.where(at_no_effect, no_effect, others_fit)
            points[at_no_effect.any(axis=1), p:] = reference.nuisance
        if reference is None:
            simulated = _simulated(problem, fit, points, rules.screen_chord_iterations)
        else:
            # The fit itself simulated as the steps are: the trust test compares like with like.
            simulated = _simulated(problem, fit, np.vstack([points, fit.x]), rules.screen_chord_iterations)
            simulated, at_fit = simulated[:-1], simulated[-1]
        for i in range(problem.n):
            rows = problem.recording_of == i
            held[rows] = simulated[i][rows]
        for i in np.flatnonzero(_absent(problem, fit, at_no_effect)):
            rows = problem.recording_of == i
            held[rows] = reference.residual[rows]
        if reference is not None:
            stepped = ~at_no_effect.any(axis=1)
            refitted = _beyond_linear_range(
                weighting, fit, blocks, information, points[:, :p] - fit.x[:p], (at_fit, simulated), stepped, rules
            )
            for i in np.flatnonzero(refitted):
                rows = problem.recording_of == i
                held[rows] = _predicted_from_others_fit(problem, fit, i, rules.fit_iterations)
    return HeldOut(held, weighting.recording_sse(held), steps, others_share, at_no_effect, refitted)


def _beyond_linear_range(
    weighting: Weighting,
    fit: FitResult,
    blocks: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
    information: list[np.ndarray],
    steps: np.ndarray,
    simulated: tuple[np.ndarray, np.ndarray],
    stepped: np.ndarray,
    rules: DiagnosisRules,
) -> np.ndarray:
    """(recordings,): whether the others' step for each recording left out (those ``stepped``;
    the others are False: a size held at no effect may sit at infinity) left the range where
    their chi^2 is quadratic: the others' own effective chi^2 at the stepped point fell by less
    than ``heldout_linear_min_ratio`` of what the quadratic model of the step promised, and
    stands more than ``heldout_linear_chi2_slack`` above that model (the trust-region test of a
    Gauss-Newton step). Only the others' data decide: the recording left out, predicted, says
    nothing here.

    ``simulated``: the residuals at the fit and at each stepped point, every nuisance refitted by
    the same chord iterations. The change is measured between the two, each the best of the
    same number of simulations, not against the fit's own chi^2: the chord iterations from the
    fit can end below it (a nuisance on its bound, a fit stopped short), and a test against the
    fit would then credit the step with what the iterations found."""
    at_fit_simulated, at_steps = simulated
    own_gradient = _gradients(fit, blocks)
    total_information, total_gradient = np.sum(information, axis=0), np.sum(own_gradient, axis=0)
    chi2_at_fit = weighting.recording_sse(at_fit_simulated)
    beyond = np.zeros(len(blocks), dtype=bool)
    for i in np.flatnonzero(stepped):
        step = steps[i]
        at_fit = float(chi2_at_fit.sum() - chi2_at_fit[i])
        quadratic = (
            at_fit
            + 2.0 * step @ (total_gradient - own_gradient[i])
            + step @ (total_information - information[i]) @ step
        )
        chi2_stepped = weighting.recording_sse(at_steps[i])
        achieved = float(chi2_stepped.sum() - chi2_stepped[i])
        beyond[i] = (
            achieved - quadratic > rules.heldout_linear_chi2_slack
            and at_fit - achieved < rules.heldout_linear_min_ratio * (at_fit - quadratic)
        )
    return beyond


def _predicted_from_others_fit(problem: FitProblem, fit: FitResult, left_out: int, fit_iterations: int) -> np.ndarray:
    """The rows of recording ``left_out`` predicted with the effect parameters of a full fit to
    the other recordings (started at ``fit``), its own nuisance refitted to convergence from
    ``fit``'s: where the others' one Gauss-Newton step left its linear range, their own optimum
    is the prediction the held-out rule means."""
    n, p = problem.n, len(fit.free)
    others = [j for j in range(n) if j != left_out]
    nuisance = fit.nuisance.reshape(NUISANCE_KINDS, n)
    others_problem = FitProblem([problem.recordings[j] for j in others], problem.noise)
    start = np.concatenate([fit.x[:p], nuisance[:, others].reshape(-1)])
    others_fit = others_problem.fit(list(fit.effect_ids), start, dict(fit.fixed), max_iterations=fit_iterations)
    own_problem = FitProblem([problem.recordings[left_out]], problem.noise)
    point = np.concatenate([others_fit.x[:p], nuisance[:, left_out]])
    point = own_problem.refit_nuisance(fit.effect_ids, fit.fixed, fit.free, point)
    residuals, _ = own_problem.simulate(fit.effect_ids, fit.fixed, fit.free, point[None])
    problem.simulations += others_problem.simulations + own_problem.simulations
    # The one recording's rows (data, then its prior rows) are, in order, its rows in ``problem``.
    return residuals[0]


def _absent(problem: FitProblem, fit: FitResult, at_no_effect: np.ndarray) -> np.ndarray:
    """(recordings,): whether the candidate is absent from each recording's prediction: every
    size held at its no-effect value (a placing parameter says nothing then) and every integer
    parameter at its no-effect value (a failed unit stays failed)."""
    absent = _no_effect_by_effect(problem, fit)
    if any(
        value != absent[eid][name] for eid in fit.effect_ids for name, value in fit.fixed.items() if name in absent[eid]
    ):
        return np.zeros(problem.n, dtype=bool)
    locates = np.array([parameter.spec.locates for parameter in fit.free], dtype=bool)
    return np.all(at_no_effect | locates, axis=1) & at_no_effect.any(axis=1)


def _unseen_sizes(
    problem: FitProblem, fit: FitResult, information: list[np.ndarray], no_effect: np.ndarray, unseen_z: float
) -> np.ndarray:
    """(recordings, effect parameters): the sizes that the other recordings alone would not tell
    from their no-effect values by ``unseen_z`` standard errors, the placing parameters held and
    the other sizes free (the distance to a no-effect value beyond the bounds counted to the
    bound)."""
    sizes = np.flatnonzero([not parameter.spec.locates for parameter in fit.free])
    unseen = np.zeros((problem.n, len(fit.free)), dtype=bool)
    if sizes.size == 0:
        return unseen
    lower, upper = problem.bounds(fit.free)
    theta = fit.x[sizes]
    distance = np.abs(theta - np.clip(no_effect[sizes], lower[sizes], upper[sizes]))
    for i, others in enumerate(_others_information([own[np.ix_(sizes, sizes)] for own in information])):
        unseen[i, sizes] = distance * np.sqrt(np.maximum(others, 0.0)) < unseen_z
    return unseen


def _no_effect_values(problem: FitProblem, fit: FitResult) -> np.ndarray:
    """The value at which each effect parameter of ``fit`` is absent (may lie outside its bounds:
    an adhesion limit is absent at infinite adhesion)."""
    absent = _no_effect_by_effect(problem, fit)
    return np.array([absent[parameter.effect_id][parameter.name] for parameter in fit.free])


def _no_effect_by_effect(problem: FitProblem, fit: FitResult) -> dict[str, dict[str, float]]:
    """Per effect of ``fit``, the value at which each of its parameters is absent."""
    vehicle = problem.recordings[0].vehicle
    return {eid: EFFECTS[eid].no_effect_values(vehicle) for eid in fit.effect_ids}


def _projected_information(
    problem: FitProblem, weighting: Weighting, fit: FitResult
) -> tuple[list[tuple[np.ndarray, np.ndarray, np.ndarray]], list[np.ndarray]]:
    """Per recording, its rows, the effect columns of the Jacobian with its nuisance projected
    out, their weights, and the weighted information matrix those columns give."""
    p = len(fit.free)
    blocks, information = [], []
    for i in range(problem.n):
        rows = np.flatnonzero(problem.recording_of == i)
        columns = problem.nuisance_columns(p, i)
        q, _ = np.linalg.qr(fit.jacobian[np.ix_(rows, columns)])
        effect = fit.jacobian[rows, :p]
        a = effect - q @ (q.T @ effect)
        w = weighting.weights[rows]
        blocks.append((rows, a, w))
        information.append(a.T @ (w[:, None] * a))
    return blocks, information


def _leave_one_out_steps(
    problem: FitProblem,
    fit: FitResult,
    blocks: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
    information: list[np.ndarray],
    held: np.ndarray,
    held_at: np.ndarray | None = None,
) -> np.ndarray:
    """Per recording, the change of the effect parameters when it is left out: one weighted
    Gauss-Newton step of the others' data, each recording's nuisance projected out, bounded. The
    parameters ``held`` (recordings, effect parameters) for that recording do not step; with
    ``held_at`` (per effect parameter) the others' step is the one with them moved there (to the
    nearer bound beyond the bounds), else with them where they are.

    The step descends the others' own gradient, not the recording's gradient turned round: the
    two are the same only where the whole set's weighted gradient vanishes, and it does not. The
    fit minimises the unweighted chi^2, in a bounded number of iterations, and the effective
    sample weights differ by channel; on a concealed profile the set's gradient was larger than
    any one recording's, and a step on the recording's alone raised the others' effective chi^2
    by 50 to 500 for every recording left out."""
    p = len(fit.free)
    total = np.sum(information, axis=0)
    gradients = _gradients(fit, blocks)
    total_gradient = np.sum(gradients, axis=0)
    lower, upper = problem.bounds(fit.free)
    theta = fit.x[:p]
    held_step = np.zeros(p) if held_at is None else np.clip(held_at, lower[:p], upper[:p]) - theta
    steps = np.zeros((problem.n, p))
    for i in range(problem.n):
        free, fixed = np.flatnonzero(~held[i]), np.flatnonzero(held[i])
        if free.size == 0:
            continue
        others = total - information[i]
        pull = -(total_gradient - gradients[i])[free]
        if fixed.size:
            pull = pull - others[np.ix_(free, fixed)] @ held_step[fixed]
        others = others[np.ix_(free, free)] + 1e-9 * np.eye(free.size)
        # The others' optimum inside the parameter bounds (the quadratic s'Os - 2 s'g as a bounded
        # least-squares problem through O = L L'). Unbounded, a recording that holds most of an
        # effect's evidence leaves the others' matrix nearly singular: the hottest stop of a
        # thermal fade, left out, can step the loss tenfold and its prediction go wild.
        cholesky = np.linalg.cholesky(others)
        solution = optimize.lsq_linear(
            cholesky.T,
            np.linalg.solve(cholesky, pull),
            bounds=(lower[free] - theta[free], upper[free] - theta[free]),
            method="bvls",
        )
        steps[i, free] = solution.x
    return steps


def _gradients(fit: FitResult, blocks: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> list[np.ndarray]:
    """Per recording, the gradient of its effective chi^2 over the effect parameters (half of
    it), its nuisance projected out."""
    return [a.T @ (w * fit.residual[rows]) for rows, a, w in blocks]


def _others_information(information: list[np.ndarray]) -> list[np.ndarray]:
    """Per recording, the information the other recordings hold on each parameter, the other
    parameters free."""
    summed = np.sum(information, axis=0)
    return [conditional_information(summed - own) for own in information]


def _others_share(information: list[np.ndarray]) -> np.ndarray:
    """Per recording and effect parameter, the share of the parameter's information that the
    other recordings hold (1 for a parameter no recording informs)."""
    total = conditional_information(np.sum(information, axis=0))
    shares = np.ones((len(information), total.size))
    informed = total > 0
    for i, others in enumerate(_others_information(information)):
        shares[i, informed] = np.minimum(others[informed] / total[informed], 1.0)
    return shares


def _simulated(problem: FitProblem, fit: FitResult, points: np.ndarray, chord_iterations: int) -> np.ndarray:
    """(recordings, rows): every recording simulated at each leave-one-out point (a row of
    ``points``: effect parameters, then nuisance), each nuisance refitted by chord iterations.
    Row i's rows of recording i are its prediction; the others' rows are their own fit at that
    point. The linear prediction ``r + a step`` is not enough: a recording that holds most of an
    effect's evidence, left out, moves the parameters far (a thermal fade's onset by tens of
    kelvin), beyond the range where the prediction is linear."""
    p = len(fit.free)
    profile = problem.profiler(fit.jacobian[:, p:])
    simulated, _ = problem.chord_refit(fit.effect_ids, fit.fixed, fit.free, points, profile, chord_iterations)
    return simulated
