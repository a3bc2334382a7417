"""Judging on recordings held out of the fit: leave one recording out, refit the effect's
parameters on the others, and predict the recording left out.

The refit is one weighted Gauss-Newton step from the fit to every recording, kept inside the
parameter bounds; the recording left out is then simulated with those parameters, its own
nuisance refitted by chord iterations as in screening.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize

from ..statistics import conditional_information
from .fitting import FitProblem, FitResult
from .weighting import Weighting


@dataclass
class HeldOut:
    """The leave-one-recording-out prediction of a fit."""

    residual: np.ndarray  # every row predicted with the effect fitted without its recording
    sse: np.ndarray  # per recording, effective (its friction-factor prior row included)
    steps: np.ndarray  # (recordings, effect parameters): each recording's leave-out change
    # (recordings, effect parameters): the share of each effect parameter's information (the other
    # effect parameters free, every recording's nuisance projected out) that the other recordings
    # hold; near 0 where one recording holds the parameter alone
    others_share: np.ndarray


def held_out(problem: FitProblem, weighting: Weighting, fit: FitResult, chord_iterations: int) -> HeldOut:
    """Each recording predicted with the effect parameters fitted without it."""
    p = len(fit.free)
    steps = np.zeros((problem.n, p))
    others_share = np.ones((problem.n, p))
    held = fit.residual.copy()
    if p:
        blocks, information = _projected_information(problem, weighting, fit)
        steps = _leave_one_out_steps(problem, fit, blocks, information)
        others_share = _others_share(information)
        held = _simulated(problem, fit, steps, chord_iterations)
    return HeldOut(held, weighting.recording_sse(held), steps, others_share)


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
) -> np.ndarray:
    """Per recording, the change of the effect parameters when it is left out: one weighted
    Gauss-Newton step of the others' data, each recording's nuisance projected out, bounded."""
    p = len(fit.free)
    r = fit.residual
    total = np.sum(information, axis=0)
    lower, upper = problem.bounds(fit.free)
    theta = fit.x[:p]
    steps = np.zeros((problem.n, p))
    for i, (rows, a, w) in enumerate(blocks):
        others = total - information[i] + 1e-9 * np.eye(p)
        pull = a.T @ (w * r[rows])
        # The others' optimum inside the parameter bounds (the quadratic s'Os - 2 s'g as a bounded
        # least-squares problem through O = L L'). Unbounded, a recording that holds most of an
        # effect's evidence leaves the others' matrix nearly singular: the hottest stop of a
        # thermal fade, left out, can step the loss tenfold and its prediction go wild.
        cholesky = np.linalg.cholesky(others)
        solution = optimize.lsq_linear(
            cholesky.T, np.linalg.solve(cholesky, pull), bounds=(lower[:p] - theta, upper[:p] - theta), method="bvls"
        )
        steps[i] = solution.x
    return steps


def _others_share(information: list[np.ndarray]) -> np.ndarray:
    """Per recording and effect parameter, the share of the parameter's information that the
    other recordings hold (1 for a parameter no recording informs)."""
    summed = np.sum(information, axis=0)
    total = conditional_information(summed)
    shares = np.ones((len(information), total.size))
    informed = total > 0
    for i, own in enumerate(information):
        others = conditional_information(summed - own)
        shares[i, informed] = np.minimum(others[informed] / total[informed], 1.0)
    return shares


def _simulated(problem: FitProblem, fit: FitResult, steps: np.ndarray, chord_iterations: int) -> np.ndarray:
    """Each recording simulated with its leave-one-out effect parameters, its own nuisance refitted
    by chord iterations. The linear prediction ``r + a step`` is not enough: a recording that holds
    most of an effect's evidence, left out, moves the parameters far (a thermal fade's onset by
    tens of kelvin), beyond the range where the prediction is linear."""
    p = len(fit.free)
    lower, upper = problem.bounds(fit.free)
    points = np.tile(fit.x, (problem.n, 1))
    points[:, :p] = np.clip(points[:, :p] + steps, lower[:p], upper[:p])
    profile = problem.profiler(fit.jacobian[:, p:])
    projected, _ = problem.chord_refit(fit.effect_ids, fit.fixed, fit.free, points, profile, chord_iterations)
    held = fit.residual.copy()
    for i in range(problem.n):
        rows = problem.recording_of == i
        held[rows] = projected[i][rows]
    return held
