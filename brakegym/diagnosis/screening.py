"""Screening: every effect of the library tried on a grid inside its bounds, cheaply, to find where
a full fit should start and which effects are worth one.

Each effect is screened at the points of a grid (:meth:`brakegym.effects.ParameterSpec.grid`)
and at the points the data point at (:meth:`brakegym.effects.Effect.screening_points`), all points
of an effect simulated in one batch, each point's nuisance (initial speed, initial disc
temperature, friction factor of every recording) refitted by chord iterations
(:meth:`.fitting.FitProblem.chord_refit`). The best point of each effect then has its nuisance
refitted on fresh Jacobians (the chord's is the baseline's) and is refined by one
profiled Gauss-Newton step: a grid this coarse leaves a small effect between two points. The
best points of the grid's other valleys (its local minima; on a grid of 2-3 points per parameter,
its other points) go with it, as starts for a full fit where the chi^2 has more than one valley.

Screened against a fit with effects (``given``: the selected single of the forward step), every
other effect is tried on top of that fit's effects, their parameters held at its values and each
point's nuisance refitted from its nuisance: a second effect whose imprint the first one's
residual hides in the unmodified model's residual shows there.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..effects import EFFECTS, Evidence, FrictionLevel, in_library_order
from .fitting import FRICTION_FACTOR, RESISTANCE_DEVIATION, FitProblem, FitResult, NuisanceProfile
from .rules import DiagnosisRules
from .weighting import Weighting


@dataclass
class ScreenedPoint:
    """An effect's best screened point: its effective chi^2 with the nuisance refitted."""

    chi2: float
    fixed: dict[str, float]  # integer parameters held at a whole value
    theta: np.ndarray  # the free effect parameters
    nuisance: np.ndarray  # [v0 (n), T0 (n), k (n), dA (n)]
    #: the best points of the grid's other valleys (its local minima but the one of this point),
    #: best first, then on a grid too coarse to show valleys its other points: starts for a full
    #: fit where the chi^2 has more than one valley
    other_valleys: tuple[ScreenedPoint, ...] = ()


def grid(effect_id: str, rules: DiagnosisRules) -> list[tuple[dict[str, float], np.ndarray]]:
    """Start points inside the bounds: (fixed integer parameters, free values). An effect with an
    integer parameter is screened at each whole value from 1 (0 is no effect); one that is not
    ``grid_screened`` at none (only at its screening points)."""
    cls = EFFECTS[effect_id]
    if not cls.grid_screened:
        return []
    integer = [s for s in cls.parameters if s.integer]
    if integer:
        spec = integer[0]
        top = int(min(spec.upper, rules.max_failed_units_screened))
        return [({spec.name: float(u)}, np.zeros(0)) for u in range(max(int(spec.lower), 1), top + 1)]
    specs = cls.parameters
    axes = [spec.grid(rules.grid_points(len(specs))) for spec in specs]
    return [({}, np.array(point)) for point in itertools.product(*axes)]


def _grid_shape(effect_id: str, rules: DiagnosisRules) -> tuple[int, ...]:
    specs = EFFECTS[effect_id].parameters
    return (rules.grid_points(len(specs)),) * len(specs)


def _grid_neighbours(index: tuple[int, ...], shape: tuple[int, ...]) -> list[tuple[int, ...]]:
    """The grid points one step from ``index`` along each parameter's axis."""
    out = []
    for axis in range(len(shape)):
        for offset in (-1, 1):
            other = list(index)
            other[axis] += offset
            if 0 <= other[axis] < shape[axis]:
                out.append(tuple(other))
    return out


def grid_minima(effect_id: str, rules: DiagnosisRules, chi2s: np.ndarray) -> list[int]:
    """The indices of the local minima of ``chi2s`` over :func:`grid`'s points of an effect
    without integer parameters (in its order): the points below every neighbour along each
    parameter's axis."""
    shape = _grid_shape(effect_id, rules)
    values = np.asarray(chi2s, dtype=float).reshape(shape)
    return [
        int(np.ravel_multi_index(index, shape))
        for index in np.ndindex(shape)
        if all(values[index] < values[other] for other in _grid_neighbours(index, shape))
    ]


def grid_valley(effect_id: str, rules: DiagnosisRules, chi2s: np.ndarray, theta: np.ndarray) -> int:
    """The index of the grid point (in :func:`grid`'s order) where steepest descent over
    ``chi2s`` ends from the grid point nearest ``theta`` (per parameter, on a log scale for a
    ``log_grid`` one): the local minimum of the valley that holds ``theta``, also where
    ``theta`` is a screening point between the grid's points."""
    specs = EFFECTS[effect_id].parameters
    shape = _grid_shape(effect_id, rules)
    values = np.asarray(chi2s, dtype=float).reshape(shape)
    index = []
    for spec, value, points in zip(specs, theta, shape):
        axis = spec.grid(points)
        if spec.log_grid:
            axis, value = np.log(axis), np.log(max(value, spec.lower))
        index.append(int(np.argmin(np.abs(axis - value))))
    current = tuple(index)
    while True:
        lowest = min(_grid_neighbours(current, shape), key=lambda other: values[other], default=current)
        if not values[lowest] < values[current]:
            return int(np.ravel_multi_index(current, shape))
        current = lowest


def integer_neighbours(effect_id: str, fixed: dict[str, float]) -> list[dict[str, float]]:
    """The values one above and below a screened integer parameter, inside its bounds and the
    grid's (from 1: 0 is no effect)."""
    integer = [spec for spec in EFFECTS[effect_id].parameters if spec.integer]
    if not integer:
        return []
    spec = integer[0]
    value = fixed[spec.name]
    return [{spec.name: v} for v in (value - 1.0, value + 1.0) if max(spec.lower, 1.0) <= v <= spec.upper]


class Screening:
    """Screens the effects against the fit ``baseline``: the unmodified model's, or with effects
    (a selected single), on top of which the others are then tried with its parameters held."""

    def __init__(
        self,
        problem: FitProblem,
        weighting: Weighting,
        rules: DiagnosisRules,
        evidence: Evidence,
        n_discs: int,
        baseline: FitResult,
    ) -> None:
        self.problem, self.weighting, self.rules = problem, weighting, rules
        self.evidence, self.n_discs, self.baseline = evidence, n_discs, baseline
        n_given = len(baseline.free)
        #: the effects of ``baseline`` and all their parameters, held in every screened point
        self.given_ids: tuple[str, ...] = tuple(baseline.effect_ids)
        self.given_parameters: dict[str, float] = baseline.parameters
        self.profile: NuisanceProfile = problem.profiler(baseline.jacobian[:, n_given:])

    def _with_given(self, effect_id: str, fixed: dict[str, float]) -> tuple[list[str], dict[str, float]]:
        """The effect ids of a screened point (the given effects with ``effect_id``, in the
        library's order) and its held parameters."""
        ids = list(in_library_order({*self.given_ids, effect_id}))
        return ids, {**self.given_parameters, **fixed}

    def starts(self, effect_id: str, fixed: dict[str, float], thetas: np.ndarray) -> np.ndarray:
        """The nuisance each point (rows of ``thetas``) starts from: the unmodified model's, with
        the friction factors divided by the share of brake force the point leaves and the running
        resistances less the resistance it adds. The unmodified fit's factors have absorbed a
        uniform loss of force (four failed units of sixteen: factors near 0.75), and three chord
        iterations from there rate the true failed units worse than no effect at all; its running
        resistances have absorbed up to their bounds (6400 N) what a set-wide resistance explains,
        which a point of the ``running_resistance`` effect would otherwise count twice.

        A friction level's factors are the unmodified model's as they are: with a level, each
        factor is the product the data see (:meth:`.fitting.FitProblem.simulate`) and the level
        only centres their prior. Divided by the level, they moved every recording's friction by
        it, and the chord iterations did not undo that: on a train-like set with a level of 0.88
        the level the factors share screened at 18 times the unmodified chi^2, and the level was
        never fitted."""
        lower, upper = self.problem.nuisance_bounds()
        factors = self.problem.nuisance_block(FRICTION_FACTOR)
        resistances = self.problem.nuisance_block(RESISTANCE_DEVIATION)
        nominal = self.evidence.nominal_resistance
        names = [parameter.name for parameter in self.problem.free_parameters([effect_id], fixed)]
        starts = np.tile(self.baseline.nuisance, (len(thetas), 1))
        if effect_id == FrictionLevel.id:
            return np.clip(starts, lower, upper)
        for j, theta in enumerate(thetas):
            parameters = {**dict(zip(names, theta)), **fixed}
            starts[j, factors] /= EFFECTS[effect_id].brake_force_share(parameters, self.n_discs)
            starts[j, resistances] -= EFFECTS[effect_id].resistance_shift_N(parameters, nominal)
        return np.clip(starts, lower, upper)

    def screen(
        self, effect_id: str, fixed: dict[str, float], thetas: np.ndarray, nuisances: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Profiled effective chi^2 of each point (rows of ``thetas``) and its refitted nuisance."""
        ids, held = self._with_given(effect_id, fixed)
        free = self.problem.free_parameters(ids, held)
        simulated, points = self.problem.chord_refit(
            ids,
            held,
            free,
            np.concatenate([thetas, nuisances], axis=1),
            self.profile,
            self.rules.screen_chord_iterations,
        )
        return np.array([self.weighting.chi2(residual) for residual in simulated]), points[:, len(free) :]

    def run(
        self, effect_ids: Sequence[str] | None = None, held: Mapping[str, float] | None = None
    ) -> dict[str, ScreenedPoint]:
        """Every effect's best point (but the given ones), refined; in the library's order.
        ``effect_ids`` screens those alone; ``held`` keeps an integer parameter at its value (its
        other grid points are left out)."""
        best: dict[str, ScreenedPoint] = {}
        evidence = self.evidence
        held = dict(held or {})
        for effect_id in EFFECTS:
            if effect_id in self.given_ids or (effect_ids is not None and effect_id not in effect_ids):
                continue
            by_fixed: dict[tuple, list[np.ndarray]] = {}
            effect_grid = grid(effect_id, self.rules)
            # The valleys of a grid over continuous parameters alone (an integer's whole values
            # are screened one by one, with no neighbours to compare).
            has_valleys = bool(effect_grid) and not any(spec.integer for spec in EFFECTS[effect_id].parameters)
            for fixed, theta in effect_grid:
                key = tuple(sorted((name, held.get(name, value)) for name, value in fixed.items()))
                if key in by_fixed and not theta.size:  # every whole value moved onto the held one
                    continue
                by_fixed.setdefault(key, []).append(theta)
            extra = [EFFECTS[effect_id].inside_bounds(point) for point in EFFECTS[effect_id].screening_points(evidence)]
            if extra:
                by_fixed.setdefault((), []).extend(extra)
            grid_points: list[ScreenedPoint] = []
            grid_chi2s = np.zeros(0)
            for fixed_items, thetas in by_fixed.items():
                fixed = dict(fixed_items)
                points = np.array(thetas)
                chi2s, nuisances = self.screen(effect_id, fixed, points, self.starts(effect_id, fixed, points))
                for theta, chi2, nuisance in zip(points, chi2s, nuisances):
                    if effect_id not in best or chi2 < best[effect_id].chi2:
                        best[effect_id] = ScreenedPoint(chi2, fixed, theta, nuisance)
                if has_valleys:
                    grid_chi2s = chi2s[: len(effect_grid)]
                    grid_points = [
                        ScreenedPoint(float(chi2), fixed, theta, nuisance)
                        for chi2, theta, nuisance in zip(grid_chi2s, points, nuisances)
                    ]
            if grid_points:
                point = best[effect_id]
                point.other_valleys = self._other_valleys(effect_id, point, grid_chi2s, grid_points)
        for effect_id, point in best.items():
            point = best[effect_id] = self._nuisance_refitted(effect_id, point)
            refined = self._refined(effect_id, point)
            if refined is not None:
                best[effect_id] = refined
        return best

    def _other_valleys(
        self, effect_id: str, point: ScreenedPoint, chi2s: np.ndarray, grid_points: Sequence[ScreenedPoint]
    ) -> tuple[ScreenedPoint, ...]:
        """The grid's local minima but the one of ``point``'s valley, best first. A grid of fewer
        than 4 points per parameter cannot show two valleys as two minima (on wet pads' 3 x 3 a
        loss of 0.26 drying within 0.7 MJ and one of 0.37 drying within 4.5 MJ descend to the same
        grid point): there its other points follow, best first.

        Points where the effect acts on nothing are left out (their chi^2 is the baseline's within
        ``rules.no_effect_chi2_share``): on a fade's grid the onsets the discs never reach form a
        plateau, which the chord iterations' last digits break into minima; a full fit from
        there has no gradient to follow and ends where it started."""
        own = grid_valley(effect_id, self.rules, chi2s, point.theta)
        baseline_chi2 = self.weighting.chi2(self.baseline.residual)
        acts = np.abs(chi2s - baseline_chi2) > self.rules.no_effect_chi2_share * baseline_chi2
        minima = sorted(
            (j for j in grid_minima(effect_id, self.rules, chi2s) if j != own and acts[j]), key=lambda j: chi2s[j]
        )
        if min(_grid_shape(effect_id, self.rules)) < 4:
            minima += [int(j) for j in np.argsort(chi2s, kind="stable") if j != own and j not in minima and acts[j]]
        return tuple(grid_points[j] for j in minima)

    def _nuisance_refitted(self, effect_id: str, point: ScreenedPoint) -> ScreenedPoint:
        """``point`` with its nuisance refitted by Levenberg-Marquardt on fresh Jacobians
        (:meth:`.fitting.FitProblem.refit_nuisance`, ``rules.screen_nuisance_iterations``),
        kept where it lowers the chi^2.

        The chord iterations step with the baseline's nuisance Jacobian, and where the baseline's
        nuisance has absorbed much of an effect (a steep gradient taken into every recording's
        running resistance, seven of eight at their bound, and initial disc temperature) they
        converge too slowly to follow: the effect's best point, even at its true value, then
        screens above the unmodified model and is never fitted in full."""
        iterations = self.rules.screen_nuisance_iterations
        if iterations <= 0:
            return point
        problem = self.problem
        ids, held = self._with_given(effect_id, point.fixed)
        free = problem.free_parameters(ids, held)
        x = problem.refit_nuisance(
            ids, held, free, np.concatenate([point.theta, point.nuisance]), max_iterations=iterations
        )
        residuals, _ = problem.simulate(ids, held, free, x[None])
        chi2 = self.weighting.chi2(residuals[0])
        if chi2 < point.chi2:
            return dataclasses.replace(point, chi2=float(chi2), nuisance=x[len(free) :])
        return point

    def _refined(self, effect_id: str, point: ScreenedPoint) -> ScreenedPoint | None:
        """One profiled Gauss-Newton step from ``point``, kept where it lowers the chi^2."""
        problem = self.problem
        ids, held = self._with_given(effect_id, point.fixed)
        free = problem.free_parameters(ids, held)
        if not free:
            return None
        sqrt_weights = np.sqrt(self.weighting.weights)
        base_residual, jac = problem.jacobian(
            ids, held, free, np.concatenate([point.theta, point.nuisance]), nuisance_too=False
        )
        projected, _ = self.profile.project(base_residual)
        columns = self.profile.project_columns(jac[:, : len(free)]) * sqrt_weights[:, None]
        step, *_ = np.linalg.lstsq(columns, -projected * sqrt_weights, rcond=None)
        lower, upper = problem.bounds(free)
        refined = np.clip(point.theta + step, lower[: len(free)], upper[: len(free)])
        chi2, nuisance = self.screen(effect_id, point.fixed, refined[None], point.nuisance[None])
        if chi2[0] < point.chi2:
            return dataclasses.replace(point, chi2=float(chi2[0]), theta=refined, nuisance=nuisance[0])
        return None
