"""Judging on recordings held out of the fit: leave one recording out, refit the effect's
parameters on the others, and predict the recording left out.

The refit is one weighted Gauss-Newton step from the fit to every recording, kept inside the
parameter bounds; the recording left out is then simulated with those parameters, its own
nuisance refitted by chord iterations as in screening.

A size (``ParameterSpec.is_size``) that only the recording left out informs (the others hold
less than ``uninformed_share`` of its information, the curvature of the chi^2 along it) is not
refitted for its prediction: the others' step along it is their noise divided by next to
nothing, and runs to a bound. It is predicted as the others know it, at its no-effect value: the
part of the effect it sizes is absent (the second section of a profile that only this recording
brakes across). Every other parameter takes the others' step as before; held at the fit, a
place only the recording informs (a fade's onset that only the hottest stop reaches) would carry
the recording's own data into its prediction.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import optimize

from .fitting import FitProblem, FitResult
from .weighting import Weighting


@dataclass
class HeldOut:
    """The leave-one-recording-out prediction of a fit."""

    residual: np.ndarray  # every row predicted with the effect fitted without its recording
    sse: np.ndarray  # per recording, effective (its friction-factor prior row included)
    steps: np.ndarray  # (recordings, effect parameters): each recording's leave-out change
    #: per recording, the sizes only it informs, at their no-effect values in its prediction
    uninformed: list[tuple[str, ...]] = field(default_factory=list)


@dataclass
class _Information:
    """Each recording's part of the Gauss-Newton normal equations of the effect parameters, its
    own nuisance projected out: its information matrix and its pull (the gradient of its chi^2)."""

    matrices: np.ndarray  # (recordings, p, p)
    pulls: np.ndarray  # (recordings, p)

    @property
    def total(self) -> np.ndarray:
        return self.matrices.sum(axis=0)


def held_out(
    problem: FitProblem, weighting: Weighting, fit: FitResult, chord_iterations: int, uninformed_share: float
) -> HeldOut:
    """Each recording predicted with the effect parameters fitted without it."""
    p = len(fit.free)
    if not p:
        return HeldOut(
            fit.residual.copy(), weighting.recording_sse(fit.residual), np.zeros((problem.n, 0)), [()] * problem.n
        )
    information = _information(problem, weighting, fit)
    steps = np.array([_bounded_step(problem, fit, information, i, np.full(p, True)) for i in range(problem.n)])
    points = np.tile(fit.x, (problem.n, 1))
    uninformed = []
    for i in range(problem.n):
        alone = _informed_alone(information, i, uninformed_share) & np.array([f.spec.is_size for f in fit.free])
        step = steps[i] if not alone.any() else _bounded_step(problem, fit, information, i, ~alone)
        points[i, :p] = _predicted_parameters(problem, fit, step, alone)
        uninformed.append(tuple(fit.free[j].name for j in np.flatnonzero(alone)))
    held = _simulated(problem, fit, points, chord_iterations)
    return HeldOut(held, weighting.recording_sse(held), steps, uninformed)


def _information(problem: FitProblem, weighting: Weighting, fit: FitResult) -> _Information:
    p = len(fit.free)
    matrices, pulls = np.zeros((problem.n, p, p)), np.zeros((problem.n, p))
    for i in range(problem.n):
        rows = np.flatnonzero(problem.recording_of == i)
        q, _ = np.linalg.qr(fit.jacobian[np.ix_(rows, problem.nuisance_columns(p, i))])
        effect = fit.jacobian[rows, :p]
        a = effect - q @ (q.T @ effect)
        w = weighting.weights[rows]
        matrices[i] = a.T @ (w[:, None] * a)
        pulls[i] = a.T @ (w * fit.residual[rows])
    return _Information(matrices, pulls)


def _informed_alone(information: _Information, i: int, uninformed_share: float) -> np.ndarray:
    """The parameters of which the recordings other than ``i`` hold less than
    ``uninformed_share`` of the information (the diagonal of the information matrix: each
    parameter moved alone)."""
    total = np.diag(information.total)
    others = total - np.diag(information.matrices[i])
    return (total > 0) & (others < uninformed_share * total)


def _bounded_step(
    problem: FitProblem, fit: FitResult, information: _Information, i: int, moved: np.ndarray
) -> np.ndarray:
    """The change of the effect parameters ``moved`` when recording ``i`` is left out (the others
    held at the fit): one weighted Gauss-Newton step of the others' data, bounded."""
    p = len(fit.free)
    step = np.zeros(p)
    if not moved.any():
        return step
    index = np.flatnonzero(moved)
    others = (information.total - information.matrices[i])[np.ix_(index, index)] + 1e-9 * np.eye(index.size)
    pull = information.pulls[i][index]
    lower, upper = problem.bounds(fit.free)
    theta = fit.x[:p][index]
    # The others' optimum inside the parameter bounds (the quadratic s'Os - 2 s'g as a bounded
    # least-squares problem through O = L L'). Unbounded, a recording that holds most of an
    # effect's evidence leaves the others' matrix nearly singular: the hottest stop of a
    # thermal fade, left out, can step the loss tenfold and its prediction go wild.
    cholesky = np.linalg.cholesky(others)
    solution = optimize.lsq_linear(
        cholesky.T,
        np.linalg.solve(cholesky, pull),
        bounds=(lower[:p][index] - theta, upper[:p][index] - theta),
        method="bvls",
    )
    step[index] = solution.x
    return step


def _predicted_parameters(problem: FitProblem, fit: FitResult, step: np.ndarray, alone: np.ndarray) -> np.ndarray:
    """The effect parameters a recording is predicted with: the fit moved by its leave-out step,
    inside the bounds, and each size ``alone`` at its no-effect value (which may lie outside the
    bounds: an adhesion limit is absent at infinite adhesion)."""
    p = len(fit.free)
    lower, upper = problem.bounds(fit.free)
    values = np.clip(fit.x[:p] + step, lower[:p], upper[:p])
    for j in np.flatnonzero(alone):
        values[j] = fit.free[j].spec.no_effect
    return values


def _simulated(problem: FitProblem, fit: FitResult, points: np.ndarray, chord_iterations: int) -> np.ndarray:
    """Each recording simulated with its own row of ``points``, its own nuisance refitted by
    chord iterations. The linear prediction ``r + a step`` is not enough: a recording that holds
    most of an effect's evidence, left out, moves the parameters far (a thermal fade's onset by
    tens of kelvin), beyond the range where the prediction is linear."""
    p = len(fit.free)
    profile = problem.profiler(fit.jacobian[:, p:])
    projected, _ = problem.chord_refit(fit.effect_ids, fit.fixed, fit.free, points, profile, chord_iterations)
    held = fit.residual.copy()
    for i in range(problem.n):
        rows = problem.recording_of == i
        held[rows] = projected[i][rows]
    return held
