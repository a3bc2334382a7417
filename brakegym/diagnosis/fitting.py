"""Fit candidate effects to all recordings of a set at once, with per-recording nuisance states.

The parameter vector of a fit is ``[effect parameters..., v0 (n), T0 (n), k (n), dA (n)]``:

- the effect parameters are shared by every recording (a set-wide effect, inside its bounds);
- ``v0``: each recording's initial speed as its speed sensor reads it (the true initial speed
  times a ``speed_sensor_scale`` in the fit), ``T0``: its initial disc temperature (nuisance
  parameters: an initial-state error must not pose as an effect; a recording without an initial
  disc temperature starts from :func:`.inputs.initial_disc_temperature`). In sensor units the bounds
  around the measured initial speed hold whatever the scale; in true units a scale of 0.955 puts
  the initial speed of a 150 km/h stop 2 m/s above the measured one, beyond the bounds, and the
  bound pulls the fitted scale towards 1;
- ``k``: each recording's friction factor, the friction scatter between applications (MCS: a
  global draw per application). It is held to 1 by a Gaussian prior of the scatter's size, so a
  shift shared by all recordings costs n times the prior: only a set-wide effect (a friction
  level, a heavier train, a failed unit) explains a shift beyond what the scatter explains.
  With the ``friction_level`` effect in a fit, ``k`` is the recording's whole friction factor
  (level times scatter) and the prior holds k / level to 1: the fitted level is the shift the
  factors share, and the data rows do not depend on it, so its evidence is the n factors alone
  (judged as such: :func:`.judging.friction_level_shift`);
- ``dA``: each recording's running resistance A less the model's (the vehicle's nominal A, or a
  ``running_resistance`` effect's), the resistance's scatter between applications (MCS: a draw
  per application). It is held to 0 by a Gaussian prior of the vehicle's ``A_sigma_N``, as ``k``
  is held to 1. Where the wheel-rail adhesion caps the braking force, the friction factor no
  longer scales a recording's deceleration, and without ``dA`` an application's own resistance
  (1600 N is 0.004 m/s^2 on a 400 t train, ten times the noise's share over a long stop) is left
  for an effect to explain.

Residuals are measured minus simulated, divided by each channel's noise, on the samples while
moving (deceleration also without the samples next to the measured stop, where traces that stop
a sample apart leave a step-sized spike). Every simulation of a fit (the point and its finite
differences) runs as one batch of :func:`brakegym.recordings.replay.replay_batch`: each copy of
the set gets its own parameter values, and because recordings do not interact, perturbing one nuisance of every
recording in the same copy gives the whole nuisance block of the Jacobian at once.

Integer parameters (``failed_units``) are not fitted continuously: each whole value is a
separate candidate.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from .. import config as cfg
from ..effects import EFFECTS, FrictionLevel, ParameterSpec, SpeedSensorScale
from ..physics.scatter import FrictionDraw
from ..recordings.columns import DECEL, DISC_TEMPERATURE, SPEED
from ..recordings.format import Recording
from ..recordings.replay import STANDSTILL_SPEED_MPS, Replay, replay_batch, standstill_index
from .inputs import initial_disc_temperature

FIT_CHANNELS = (SPEED, DECEL, DISC_TEMPERATURE)
# Deceleration samples this close to the measured stop are left out of the fit (the step at
# standstill is a sample wide: a stop 0.05 s early reads as a 1 m/s^2 residual).
STOP_GUARD_S = 0.5
# The nuisance kinds, in the order of their blocks of n columns after the effect parameters.
INITIAL_SPEED, INITIAL_DISC_TEMPERATURE, FRICTION_FACTOR, RESISTANCE_DEVIATION = range(4)
NUISANCE_KINDS = 4
NUISANCE_BOUNDS = {"v0_mps": 1.5, "T0_K": 25.0, "k": (0.6, 1.4), "dA_sigmas": 4.0}
NUISANCE_STEPS = (0.01, 0.2, 0.002, 100.0)  # finite-difference steps of v0 (m/s), T0 (K), k, dA (N)
NUISANCE_SCALES = (0.1, 1.0, 0.01, 200.0)  # their typical sizes, for the trust region
NUISANCE_ITERATIONS = 12
POLISH_STEPS = 2  # Gauss-Newton steps after the trust-region fit
FRICTION_FACTOR_GRID = 17  # 0.05 apart over the bounds of k
NUISANCE_RELATIVE_TOLERANCE = 1e-4  # a recording's nuisance has converged when its SSE gains less


def friction_scatter_sigma(vehicle: cfg.Vehicle) -> float:
    """Relative scatter of a whole application's braking friction: the spread of mu_0 and, with
    the same weight, of the power coefficient a (a 12 % change of a moves the friction level over
    a stop by about a third of that; measured on effect-free synthetic sets, where the fitted
    ``k`` spread 3-5 %)."""
    material = cfg.load("materials", vehicle.material)
    relative_mu = material.scatter.initial_mu_sigma / material.initial_mu
    relative_a = material.scatter.power_coefficient_sigma_per_s / material.power_coefficient_per_s
    return float(np.hypot(relative_mu, relative_a / 3.0))


def recording_sse(residual: np.ndarray, rows: np.ndarray) -> float:
    """The sum of squares of one recording's rows of a weighted residual (``rows``: its row
    indices or mask), as the nuisance fits compare a recording's points."""
    part = residual[rows]
    return float(part @ part)


@dataclass
class Samples:
    """Which samples of one recording enter the fit, and their measured values."""

    rows: dict[str, np.ndarray]
    measured: dict[str, np.ndarray]


def fit_samples(recording: Recording) -> Samples:
    speed = recording.speed_mps
    stop = standstill_index(speed, STANDSTILL_SPEED_MPS)
    last = len(speed) if stop is None else stop + 1
    moving = np.arange(len(speed)) < last
    rows, measured = {}, {}
    for channel in FIT_CHANNELS:
        values = recording.channel(channel)
        if values is None:
            continue
        use = ~np.isnan(values)
        if channel in (SPEED, DECEL):
            use &= moving
        if channel == DECEL and stop is not None:
            use &= np.abs(recording.time_s - recording.time_s[stop]) > STOP_GUARD_S
        rows[channel] = np.flatnonzero(use)
        measured[channel] = values[rows[channel]]
    return Samples(rows, measured)


@dataclass(frozen=True)
class FreeParameter:
    effect_id: str
    spec: ParameterSpec

    @property
    def name(self) -> str:
        return self.spec.name


@dataclass
class FitResult:
    """A fitted candidate (``effect_ids`` empty: the unmodified model)."""

    effect_ids: tuple[str, ...]
    fixed: dict[str, float]  # integer parameters held at a whole value
    free: list[FreeParameter]
    x: np.ndarray  # [effect parameters, v0 (n), T0 (n), k (n), dA (n)]
    residual: np.ndarray  # normalised, data rows then the n friction and n resistance prior rows
    jacobian: np.ndarray
    replays: list[Replay] = field(repr=False, default_factory=list)

    @property
    def parameters(self) -> dict[str, float]:
        values = {p.name: float(v) for p, v in zip(self.free, self.x[: len(self.free)])}
        values.update(self.fixed)
        return values

    @property
    def nuisance(self) -> np.ndarray:
        """Each recording's nuisance after the effect parameters, as v0 (n), T0 (n), k (n) and dA (n) in turn."""
        return self.x[len(self.free) :]


class FitProblem:
    """Recordings of one vehicle, their noise levels and the row layout of the residual."""

    def __init__(self, recordings: Sequence[Recording], noise: dict[str, float]) -> None:
        self.recordings = list(recordings)
        self.n = len(self.recordings)
        self.noise = noise
        self.samples = [fit_samples(r) for r in self.recordings]
        vehicle = self.recordings[0].vehicle
        self.prior_sigma = friction_scatter_sigma(vehicle)
        self.resistance_sigma_N = vehicle.running_resistance.A_sigma_N
        if self.prior_sigma <= 0 or self.resistance_sigma_N <= 0:
            raise ValueError(
                f"vehicle {vehicle.name!r}: the diagnosis holds each application's friction and running resistance "
                f"to their scatter, which must be positive (friction {self.prior_sigma}, running_resistance.A_sigma_N "
                f"{self.resistance_sigma_N} N)"
            )
        recording_of, channel_of = [], []
        for i, samples in enumerate(self.samples):
            for channel, rows in samples.rows.items():
                recording_of.append(np.full(len(rows), i))
                channel_of.append(np.full(len(rows), FIT_CHANNELS.index(channel)))
        # Prior rows: recording i, channel -1 (friction factor), then channel -2 (resistance).
        self.recording_of = np.concatenate(recording_of + [np.arange(self.n), np.arange(self.n)])
        self.channel_of = np.concatenate(channel_of + [np.full(self.n, -1), np.full(self.n, -2)])
        self.n_data_rows = int(np.sum(self.channel_of >= 0))
        self.initial_nuisance = self._initial_nuisance()
        self.simulations = 0  # trains simulated, for the record

    def _initial_nuisance(self) -> np.ndarray:
        v0 = np.array([r.speed_mps[0] for r in self.recordings])
        T0 = np.array([initial_disc_temperature(r).value_C for r in self.recordings], dtype=float)
        return np.concatenate([v0, T0, np.ones(self.n), np.zeros(self.n)])

    def nuisance_block(self, kind: int, n_free: int = 0) -> slice:
        """Columns of every recording's nuisance of ``kind`` (``FRICTION_FACTOR``, ...) after
        ``n_free`` effect parameters."""
        return slice(n_free + kind * self.n, n_free + (kind + 1) * self.n)

    def gridded_start(
        self,
        effect_ids: Sequence[str] = (),
        fixed: dict[str, float] | None = None,
        free: Sequence[FreeParameter] = (),
        theta: np.ndarray | None = None,
    ) -> np.ndarray:
        """The measured initial state, with each recording's friction factor taken from a grid
        over its bounds (all grid values simulated in one batch): the friction factor and the
        initial speed lie along a narrow curved valley (a faster start and more friction stop at
        the same point), from which a local fit started at k = 1 does not always find its way.

        With effects (``effect_ids``, their free parameters at ``theta``), the grid is searched
        with them acting: a start for their fit that owes nothing to the unmodified model's
        nuisance. That nuisance has absorbed what the effect explains, and more than the force:
        under a 13 permil gradient through a real measurement chain its friction factors sit
        15-25 % high and its initial disc temperatures up to 20 K off, a valley from which the
        gradient's fit ends at half its value and ten times the chi^2 it reaches from here."""
        n = self.n
        theta = np.zeros(0) if theta is None else np.asarray(theta, dtype=float)
        low, high = NUISANCE_BOUNDS["k"]
        factors = np.linspace(low, high, FRICTION_FACTOR_GRID)
        points = np.tile(np.concatenate([theta, self.initial_nuisance]), (len(factors), 1))
        points[:, self.nuisance_block(FRICTION_FACTOR, len(theta))] = factors[:, None]
        residuals, _ = self.simulate(list(effect_ids), dict(fixed or {}), list(free), points)
        start = self.initial_nuisance.copy()
        start[self.nuisance_block(FRICTION_FACTOR)] = [
            factors[int(np.argmin(np.sum(residuals[:, self.recording_of == i] ** 2, axis=1)))] for i in range(n)
        ]
        return start

    def nuisance_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        start = self.initial_nuisance
        n = self.n
        dv, dT = NUISANCE_BOUNDS["v0_mps"], NUISANCE_BOUNDS["T0_K"]
        k_low, k_high = NUISANCE_BOUNDS["k"]
        dA = NUISANCE_BOUNDS["dA_sigmas"] * self.resistance_sigma_N
        v0, T0 = start[self.nuisance_block(INITIAL_SPEED)], start[self.nuisance_block(INITIAL_DISC_TEMPERATURE)]
        lower = np.concatenate([np.maximum(v0 - dv, 0.0), T0 - dT, np.full(n, k_low), np.full(n, -dA)])
        upper = np.concatenate([v0 + dv, T0 + dT, np.full(n, k_high), np.full(n, dA)])
        return lower, upper

    # -- simulation ------------------------------------------------------------------------
    def simulate(
        self,
        effect_ids: Sequence[str],
        fixed: dict[str, float],
        free: Sequence[FreeParameter],
        points: np.ndarray,
        scatter: tuple[FrictionDraw, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, list[list[Replay]]]:
        """Residuals (m, rows) of ``m`` parameter points (m, len(free) + 4n), in one batch;
        ``scatter``: a friction draw in place of the nominal one and a running-resistance
        deviation added to the points' dA, per simulated train (m n)
        (:func:`~brakegym.recordings.replay.replay_batch`)."""
        points = np.atleast_2d(points)
        m, n = len(points), self.n
        p = len(free)
        theta = points[:, :p]
        v0, T0, k, dA = (points[:, self.nuisance_block(kind, p)].reshape(-1) for kind in range(NUISANCE_KINDS))
        values: dict[str, dict[str, np.ndarray]] = {eid: {} for eid in effect_ids}
        for j, parameter in enumerate(free):
            values[parameter.effect_id][parameter.name] = np.repeat(theta[:, j], n)
        for eid in effect_ids:
            for spec in EFFECTS[eid].parameters:
                if spec.name in fixed:
                    values[eid][spec.name] = np.full(m * n, fixed[spec.name])
        # With a friction level, each recording's friction factor k is the product that the data
        # see (level times the recording's own scatter), and the prior holds k / level to 1: the
        # data rows then do not depend on the level at all, and its finite difference cannot
        # pick up the truncation error of two nearly cancelling columns.
        level = np.ones(m * n)
        effects = []
        for eid in effect_ids:
            if eid == FrictionLevel.id:
                level = np.broadcast_to(values[eid]["mu_scale"], (m * n,))
                continue
            effects.append(EFFECTS[eid](**values[eid]))
        lower, upper = FrictionLevel.parameters[0].lower, FrictionLevel.parameters[0].upper
        effects.append(FrictionLevel(mu_scale=np.clip(k, lower, upper)))
        true_v0 = v0 / values[SpeedSensorScale.id]["scale"] if SpeedSensorScale.id in values else v0
        friction_draw, drawn_dA = scatter if scatter is not None else (None, 0.0)
        replays = replay_batch(
            self.recordings * m,
            effects,
            initial_speed_mps=true_v0,
            initial_disc_C=T0,
            friction_draw=friction_draw,
            running_resistance_deviation_N=dA + drawn_dA,
        )
        self.simulations += m * n
        residuals = np.empty((m, len(self.recording_of)))
        grouped = []
        for c in range(m):
            group = replays[c * n : (c + 1) * n]
            grouped.append(group)
            own = slice(c * n, (c + 1) * n)
            residuals[c] = self._residual(group, k[own] / level[own], dA[own])
        return residuals, grouped

    def _residual(self, replays: Sequence[Replay], scatter: np.ndarray, resistance_N: np.ndarray) -> np.ndarray:
        """Data rows, then two prior rows per recording: its friction scatter factor, then its
        running resistance's deviation, each over its sigma."""
        parts = []
        for replayed, samples in zip(replays, self.samples):
            for channel, rows in samples.rows.items():
                simulated = replayed.channels[channel][rows]
                parts.append((samples.measured[channel] - simulated) / self.noise[channel])
        parts.append((scatter - 1.0) / self.prior_sigma)
        parts.append(resistance_N / self.resistance_sigma_N)
        return np.concatenate(parts)

    # -- fitting ---------------------------------------------------------------------------
    def jacobian(
        self,
        effect_ids,
        fixed,
        free,
        x: np.ndarray,
        base: np.ndarray | None = None,
        nuisance_too: bool = True,
        effect_too: bool = True,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Finite-difference Jacobian at ``x``: one copy per effect parameter and one per
        nuisance kind (every recording perturbed in the same copy); columns left out are zero."""
        p, n = len(free), self.n
        lower, upper = self.bounds(free)
        copies, steps = [], []
        for j, parameter in enumerate(free if effect_too else ()):
            step = parameter.spec.difference_step * (parameter.spec.upper - parameter.spec.lower)
            step = step if x[j] + step <= upper[j] else -step
            point = x.copy()
            point[j] += step
            copies.append(point)
            steps.append(step)
        for kind, step in enumerate(NUISANCE_STEPS if nuisance_too else ()):
            block = self.nuisance_block(kind, p)
            direction = np.where(x[block] + step <= upper[block], step, -step)
            point = x.copy()
            point[block] += direction
            copies.append(point)
            steps.append(direction)
        if base is None:
            copies.insert(0, x)
        residuals, _ = self.simulate(effect_ids, fixed, free, np.array(copies))
        if base is None:
            base, residuals = residuals[0], residuals[1:]
        jac = np.zeros((len(base), p + NUISANCE_KINDS * n))
        p_copies = p if effect_too else 0
        for j in range(p_copies):
            jac[:, j] = (residuals[j] - base) / steps[j]
        rows_of = self.recording_of
        for kind in range(NUISANCE_KINDS if nuisance_too else 0):
            difference = residuals[p_copies + kind] - base
            for i in range(n):
                rows = rows_of == i
                jac[rows, p + kind * n + i] = difference[rows] / steps[p_copies + kind][i]
        return base, jac

    def refit_nuisance(
        self,
        effect_ids: Sequence[str],
        fixed: dict[str, float],
        free: Sequence[FreeParameter],
        x: np.ndarray,
        max_iterations: int = NUISANCE_ITERATIONS,
    ) -> np.ndarray:
        """``x`` with each recording's nuisance (v0, T0, k, dA) refitted to convergence at fixed
        effect parameters: Levenberg-Marquardt on each recording's own 4 x 4 block, with its own
        damping, all recordings and the four finite-difference copies simulated in one batch per
        iteration.

        A joint trust-region fit over every recording's nuisance moves them all by one step size:
        one recording far from its start (a friction factor 20 % off) holds the others back, the
        unmodified model stops unconverged well above its optimal chi^2, and every candidate (even
        one at its no-effect value) then looks like an improvement."""
        p, n = len(free), self.n
        lower, upper = self.bounds(free)
        x = np.clip(np.asarray(x, dtype=float), lower, upper)
        residual, jac = self.jacobian(effect_ids, fixed, free, x, effect_too=False)
        blocks = [np.flatnonzero(self.recording_of == i) for i in range(n)]
        columns = [self.nuisance_columns(p, i) for i in range(n)]
        sse = np.array([recording_sse(residual, rows) for rows in blocks])
        damping = np.full(n, 1e-3)
        converged = np.zeros(n, dtype=bool)
        for _ in range(max_iterations):
            trial = x.copy()
            for i in np.flatnonzero(~converged):
                rows, cols = blocks[i], columns[i]
                block = jac[np.ix_(rows, cols)]
                normal = block.T @ block
                scaled = normal + damping[i] * np.diag(np.maximum(np.diag(normal), 1e-12))
                trial[cols] = x[cols] + np.linalg.solve(scaled, -block.T @ residual[rows])
            trial = np.clip(trial, lower, upper)
            trial_residual, trial_jac = self.jacobian(effect_ids, fixed, free, trial, effect_too=False)
            for i in np.flatnonzero(~converged):
                rows, cols = blocks[i], columns[i]
                trial_sse = recording_sse(trial_residual, rows)
                if trial_sse < sse[i]:
                    # Only a small gain of a nearly undamped (Gauss-Newton) step means convergence:
                    # a heavily damped step gains little anywhere.
                    small_gain = (sse[i] - trial_sse) <= NUISANCE_RELATIVE_TOLERANCE * sse[i]
                    converged[i] = small_gain and damping[i] <= 1e-2
                    x[cols] = trial[cols]
                    residual[rows] = trial_residual[rows]
                    jac[rows] = trial_jac[rows]
                    sse[i] = trial_sse
                    damping[i] = max(damping[i] / 4.0, 1e-6)
                else:
                    damping[i] *= 8.0
                    converged[i] = damping[i] > 1e4
            if converged.all():
                break
        return x

    def refit_nuisance_from_prior_centre(
        self,
        effect_ids: Sequence[str],
        fixed: dict[str, float],
        free: Sequence[FreeParameter],
        x: np.ndarray,
    ) -> np.ndarray:
        """``x`` with each recording's nuisance replaced by a second refit, started at the centre
        of its priors (the measured initial speed and disc temperature, friction factor 1, no
        resistance deviation), where that one ends at a lower sum of squares of the recording's
        rows. At fixed effect parameters each recording's rows depend on its own nuisance alone,
        so the better of the two is chosen recording by recording.

        The gridded start (:meth:`gridded_start`) picks each friction factor by the data alone,
        and from there a recording can settle in a valley away from its priors' centre: a factor
        at its start and a running resistance at its bound that together mimic the data about as
        well as the physics does, while the friction and resistance priors pay for both. The
        unmodified model then stands too high, and every candidate gains what it would have
        gained by a refit of that recording's nuisance alone."""
        p = len(free)
        x = np.asarray(x, dtype=float)
        centre = x.copy()
        centre[p:] = self.initial_nuisance
        second = self.refit_nuisance(effect_ids, fixed, free, centre)
        residuals, _ = self.simulate(effect_ids, fixed, free, np.array([x, second]))
        chosen = x.copy()
        for i in range(self.n):
            rows = self.recording_of == i
            first_sse, second_sse = (recording_sse(r, rows) for r in residuals)
            if second_sse < first_sse:
                columns = self.nuisance_columns(p, i)
                chosen[columns] = second[columns]
        return chosen

    def bounds(self, free: Sequence[FreeParameter]) -> tuple[np.ndarray, np.ndarray]:
        lower, upper = self.nuisance_bounds()
        return (
            np.concatenate([[f.spec.lower for f in free], lower]),
            np.concatenate([[f.spec.upper for f in free], upper]),
        )

    def fit(
        self,
        effect_ids: Sequence[str],
        start: np.ndarray,
        fixed: dict[str, float] | None = None,
        max_iterations: int = 12,
    ) -> FitResult:
        """Least squares from ``start`` within the bounds; ``fixed`` holds integer parameters."""
        fixed = dict(fixed or {})
        free = self.free_parameters(effect_ids, fixed)
        lower, upper = self.bounds(free)
        start = np.clip(start, lower, upper)
        cache: dict[bytes, np.ndarray] = {}

        def residual(x: np.ndarray) -> np.ndarray:
            key = x.tobytes()
            if key not in cache:
                cache.clear()
                cache[key] = self.simulate(effect_ids, fixed, free, x[None])[0][0]
            return cache[key]

        def jacobian(x: np.ndarray) -> np.ndarray:
            return self.jacobian(effect_ids, fixed, free, x, cache.get(x.tobytes()))[1]

        if free:
            span = upper - lower
            scale = np.concatenate([0.05 * span[: len(free)], np.repeat(NUISANCE_SCALES, self.n)])
            solution = least_squares(
                residual,
                start,
                jac=jacobian,
                bounds=(lower, upper),
                x_scale=scale,
                method="trf",
                max_nfev=max_iterations,
                xtol=1e-4,
                ftol=1e-5,
            )
            start = solution.x
        # The joint fit may stop before each recording's nuisance has converged: finish it, so
        # that every candidate and the unmodified model are compared at their own optimum.
        x = self.refit_nuisance(effect_ids, fixed, free, start)
        for _ in range(POLISH_STEPS if free else 0):
            x = self._gauss_newton_step(effect_ids, fixed, free, x)
        residuals, replays = self.simulate(effect_ids, fixed, free, x[None])
        base, jac = self.jacobian(effect_ids, fixed, free, x, residuals[0])
        return FitResult(tuple(effect_ids), fixed, free, x, base, jac, replays[0])

    # -- candidates, with the nuisance profiled out linearly ------------------------------------
    def profiler(self, nuisance_jacobian: np.ndarray) -> NuisanceProfile:
        return NuisanceProfile(self, nuisance_jacobian)

    def chord_refit(
        self,
        effect_ids: Sequence[str],
        fixed: dict[str, float],
        free: Sequence[FreeParameter],
        points: np.ndarray,
        profile: NuisanceProfile,
        iterations: int,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Each point (rows: effect parameters, then nuisance) with its nuisance refitted by
        ``iterations`` chord iterations: Gauss-Newton steps with a fixed nuisance Jacobian
        (``profile``: the unmodified model's in the screening, the candidate's in the held-out
        prediction), each followed by a simulation at the moved point. Returns, per recording,
        the residuals of the best of those simulations (least sum of squares) and the points
        they were simulated at.

        The residuals are simulated, never the linear step's projection: the projection is
        optimistic by the nuisance's curvature, and more so the further a point lies from the
        fit the Jacobian was taken at, so projected residuals favoured a candidate's held-out
        prediction (stepped parameters, a projection) over the unmodified model's converged fit.
        Each step is solved without the nuisance bounds and the point then clipped to them.

        One linear step is not enough: an effect that moves the stop by seconds (a 7 permil
        gradient) needs a friction factor 8 % off, far outside the linear range of the samples
        near the stop, and a single step rates such a gradient worse than no effect at all.

        A recording whose simulated sum of squares grew over the last step goes back to the
        point before it and is not moved again. Near a recording's optimum its friction factor,
        initial speed and running resistance lie along a narrow curved valley, and the straight
        steps of a fixed Jacobian climb out of it: from a converged fit, three unguarded steps
        raised one recording's sum of squares by 2.6 (the held-out loss of a friction level,
        which leaves the data rows alone)."""
        p, n = len(free), self.n
        lower, upper = self.nuisance_bounds()
        points = points.copy()
        rows_of = [self.recording_of == i for i in range(n)]
        columns_of = [np.array(self.nuisance_columns(p, i)) for i in range(n)]
        best_sse = np.full((len(points), n), np.inf)
        held = np.zeros((len(points), n), dtype=bool)
        best_residual = np.empty((len(points), len(self.recording_of)))
        best_points = points.copy()
        for iteration in range(iterations + 1):
            residuals, _ = self.simulate(list(effect_ids), fixed, free, points)
            for j, residual in enumerate(residuals):
                for i in range(n):
                    rows, columns = rows_of[i], columns_of[i]
                    sse = recording_sse(residual, rows)
                    if held[j, i] or sse > best_sse[j, i]:
                        held[j, i] = True
                        continue
                    best_sse[j, i] = sse
                    best_residual[j, rows] = residual[rows]
                    best_points[j, columns] = points[j, columns]
                if iteration == iterations:
                    continue
                _, step = profile.project(residual)
                step_at = np.clip(points[j, p:] + step, lower, upper)
                for i in np.flatnonzero(~held[j]):
                    columns = columns_of[i]
                    points[j, columns] = step_at[columns - p]
        return best_residual, best_points

    def _gauss_newton_step(self, effect_ids, fixed, free, x: np.ndarray) -> np.ndarray:
        """One Gauss-Newton step on every parameter at once, kept when it lowers the SSE (then
        the nuisance refitted again).

        The trust-region fit crawls along directions that the data leave flat and only the
        friction-factor prior bends: a friction level against every recording's friction factor
        (the data see only their product) can stop far from a level of 0.8. The Gauss-Newton
        step solves that near-linear direction in one go."""
        lower, upper = self.bounds(free)
        residual, jac = self.jacobian(effect_ids, fixed, free, x)
        scale = np.maximum(np.linalg.norm(jac, axis=0), 1e-12)
        step, *_ = np.linalg.lstsq(jac / scale, -residual, rcond=None)
        trial = np.clip(x + step / scale, lower, upper)
        trial_residual, _ = self.simulate(effect_ids, fixed, free, trial[None])
        if trial_residual[0] @ trial_residual[0] < residual @ residual:
            return self.refit_nuisance(effect_ids, fixed, free, trial)
        return x

    def nuisance_columns(self, n_free: int, i: int) -> list[int]:
        """Columns of recording ``i``'s v0, T0, k and dA after ``n_free`` effect parameters."""
        return [n_free + kind * self.n + i for kind in range(NUISANCE_KINDS)]

    def free_parameters(self, effect_ids: Sequence[str], fixed: dict[str, float]) -> list[FreeParameter]:
        return [
            FreeParameter(eid, spec)
            for eid in effect_ids
            for spec in EFFECTS[eid].parameters
            if spec.name not in fixed and not spec.integer
        ]


class NuisanceProfile:
    """Each recording's nuisance refitted by one linear least-squares step, without bounds,
    with a fixed nuisance Jacobian (block diagonal: 4 columns per recording)."""

    def __init__(self, problem: FitProblem, nuisance_jacobian: np.ndarray) -> None:
        self.problem = problem
        self.jacobian = nuisance_jacobian
        self.blocks = []
        for i in range(problem.n):
            rows = np.flatnonzero(problem.recording_of == i)
            columns = problem.nuisance_columns(0, i)
            block = nuisance_jacobian[np.ix_(rows, columns)]
            q, r = np.linalg.qr(block)
            self.blocks.append((rows, columns, q, r))

    def project(self, residual: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The residual after the linear nuisance refit, and the nuisance step."""
        out = residual.copy()
        step = np.zeros(NUISANCE_KINDS * self.problem.n)
        for rows, columns, q, r in self.blocks:
            coefficients = q.T @ residual[rows]
            out[rows] = residual[rows] - q @ coefficients
            step[columns] = -np.linalg.solve(r, coefficients)
        return out, step

    def project_columns(self, columns: np.ndarray) -> np.ndarray:
        out = columns.copy()
        for rows, _, q, _ in self.blocks:
            out[rows] = columns[rows] - q @ (q.T @ columns[rows])
        return out
