"""A safety case as a response function: each row u of standard-normal values is one emergency
stop, its stochastic inputs obtained from u by the inverse transform of their distributions, and
the response is the stop's braking distance.

The columns of u (:class:`InputLayout`): the friction scatter of paper Eq. 13 (a global normal
for mu_0 and for a, then one per disc for each), the running resistance's A, the train's mass, the
cylinder pressures (one per train or per axle), the cylinders' time constant, and one normal per
disc unit for its availability (a unit fails when Phi(u) is below its failure probability per
demand). An input the case does not scatter keeps its column, which then has no effect, so that a
case's points mean the same inputs whatever it switches off.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import special, stats

from .. import config as cfg
from ..applications import StopSummary, run_commanded_stops, train_conditions
from ..defaults import DEFAULT_STEP_S
from ..effects.hooks import ConstantFrictionFactor
from ..physics import BrakeCylinder, friction_from_normals
from ..plants import brake_cylinder, scatter_partition, stochastic_friction, train_plant
from ..simulator import BatchConditions
from ..simulator.metrics import SpeedCrossings
from ..units import kmh_to_mps

# A stop whose brakes all fail is slowed by running resistance alone; far longer than any stop the
# tails look at, but it ends.
UNBRAKED_STOP_LIMIT_S = 7200.0


@dataclass(frozen=True)
class InputLayout:
    """Which columns of a point u hold which input."""

    friction_global: slice  # 2: mu_0, a
    friction_individual: slice  # 2 x discs: mu_0 of every disc, then a of every disc
    resistance: int
    mass: int
    pressure: slice  # 1 or one per axle
    time_constant: int
    units: slice  # one per disc
    dims: int

    @classmethod
    def of(cls, n_axles: int, n_discs: int, pressure_per_axle: bool) -> InputLayout:
        column = 0

        def take(width: int) -> slice:
            nonlocal column
            block = slice(column, column + width)
            column += width
            return block

        friction_global, friction_individual = take(2), take(2 * n_discs)
        resistance, mass = take(1).start, take(1).start
        pressure = take(n_axles if pressure_per_axle else 1)
        time_constant, units = take(1).start, take(n_discs)
        return cls(friction_global, friction_individual, resistance, mass, pressure, time_constant, units, column)


class BrakingModel:
    """Braking distances of ``case``'s train at ``initial_speed_kmh`` with ``load``, as a function
    of standard-normal points (``model(u)``, u of shape (n, ``model.dims``)).

    The brake is commanded at the start of each stop; the braking distance runs from the command to
    standstill.
    """

    def __init__(self, case: cfg.SafetyCase, load: str, initial_speed_kmh: float, step_s: float = DEFAULT_STEP_S):
        if not initial_speed_kmh > 0:
            raise ValueError(f"initial speed {initial_speed_kmh} km/h: must be positive")
        self.case = case
        self.vehicle = vehicle = cfg.load("vehicles", case.vehicle)
        vehicle.load(load)
        self.load = load
        self.initial_speed_kmh = initial_speed_kmh
        self.step_s = step_s
        self.plant = train_plant(vehicle)
        self.friction = stochastic_friction(cfg.load("materials", vehicle.material))
        setup = cfg.load("setups", case.scatter.setup)
        self.partition = scatter_partition(setup)
        self.resistance_scatter = setup.resistance_scatter
        self.cylinder = brake_cylinder(cfg.load("pneumatics", case.actuation))
        self.nominal_pressure_bar = vehicle.brake_pressure_bar(case.brake_mode, load)
        self.layout = InputLayout.of(vehicle.n_axles, vehicle.n_discs, case.cylinder_pressure.per == "axle")
        failure = case.brake_units.failure_probability_per_demand
        # A unit fails where Phi(u) < q; -inf for q = 0 (never), +inf for q = 1 (always).
        self.unit_failure_below = float(special.ndtri(failure)) if 0 < failure < 1 else (np.inf if failure else -np.inf)

    @property
    def dims(self) -> int:
        """Columns of a point u."""
        return self.layout.dims

    def __call__(self, u: np.ndarray) -> np.ndarray:
        return self.braking_distance_m(u)

    def braking_distance_m(self, u: np.ndarray, failed_units: int | None = None) -> np.ndarray:
        """The braking distance of each stop, m, (n,). With ``failed_units`` k, exactly k units
        fail in every stop (the stratum k of :meth:`strata`) instead of each with its probability."""
        return self.stops(u, failed_units).braking_distance_m

    def band_decelerations_mps2(
        self, u: np.ndarray, speed_edges_kmh: Sequence[float], build_up_time_s: float, failed_units: int | None = None
    ) -> np.ndarray:
        """The deceleration of each speed band of each stop, m/s^2, (n, bands), as ETCS counts it:
        the brake acts in full from the build-up time ``build_up_time_s`` after the command, and
        each band between consecutive ``speed_edges_kmh`` (ascending, from 0 to the initial
        speed) is passed at the constant deceleration that covers it in the same distance,
        (V_high^2 - V_low^2) / (2 distance). The top band starts at the state at the build-up
        time, the bottom band ends at standstill."""
        edges = np.asarray(speed_edges_kmh, dtype=float)
        if edges[0] != 0 or edges[-1] != self.initial_speed_kmh or np.any(np.diff(edges) <= 0):
            raise ValueError(
                f"speed band edges {edges.tolist()} km/h: need 0 first, rising, and the initial speed "
                f"{self.initial_speed_kmh} km/h last"
            )
        inner = kmh_to_mps(edges[1:-1])[::-1]  # passed from the top down
        crossing = SpeedCrossings(len(u), inner, build_up_time_s)
        summary = self.stops(u, failed_units, observers=[crossing])
        if not np.all(crossing.position_m[0] >= crossing.position_at_time_m):
            raise ValueError(
                f"the build-up time {build_up_time_s} s ends below the top band's lower edge {edges[-2]} km/h: "
                f"choose a lower edge"
            )
        speeds = np.vstack([crossing.speed_at_time_mps, np.broadcast_to(inner[:, None], crossing.position_m.shape)])
        speeds = np.vstack([speeds, np.zeros((1, len(u)))])
        positions = np.vstack([crossing.position_at_time_m, crossing.position_m, summary.stop_distance_m])
        decelerations = (speeds[:-1] ** 2 - speeds[1:] ** 2) / (2.0 * (positions[1:] - positions[:-1]))
        return decelerations[::-1].T  # bands from the lowest up

    def stops(self, u: np.ndarray, failed_units: int | None = None, observers: Sequence = ()) -> StopSummary:
        """The stops of the points ``u`` (see :meth:`braking_distance_m`)."""
        u = self._checked(u)
        n = len(u)
        working = self.working_units(u, failed_units)
        hooks = [] if working.all() else [ConstantFrictionFactor(np.moveaxis(working.astype(float), 0, -1))]
        command = self.pressure_commands_bar(u)
        return run_commanded_stops(
            self.plant,
            self.conditions(u),
            self.cylinders(u),
            command=command,
            command_time_s=np.zeros(n),
            nominal_clamp_force_N=self.plant.caliper.clamp_force_N(command),
            step_s=self.step_s,
            friction_modifiers=hooks,
            max_time_s=UNBRAKED_STOP_LIMIT_S,
            observers=observers,
        )

    def nominal_braking_distance_m(self) -> float:
        """The stop with every input at its nominal value (u = 0) and no unit failed."""
        return float(self.braking_distance_m(np.zeros((1, self.dims)), failed_units=0)[0])

    def _checked(self, u: np.ndarray) -> np.ndarray:
        u = np.asarray(u, dtype=float)
        if u.ndim != 2 or u.shape[1] != self.dims:
            raise ValueError(f"points of shape {u.shape}: need (n, {self.dims}) standard-normal values")
        if not np.all(np.isfinite(u)):
            raise ValueError("points hold values that are not finite")
        return u

    def conditions(self, u: np.ndarray) -> BatchConditions:
        """What differs per stop: friction, running resistance, mass."""
        case, layout, n = self.case, self.layout, len(u)
        friction = friction_from_normals(
            self.friction,
            self.partition,
            u[:, layout.friction_global],
            u[:, layout.friction_individual].reshape(n, 2, *self.plant.disc_shape),
        )
        resistance = self.vehicle.running_resistance
        sigma_A = resistance.A_sigma_N if self.resistance_scatter else 0.0
        return train_conditions(
            self.vehicle,
            mass_kg=self.vehicle.mass_kg(self.load) * np.exp(case.mass.relative_sigma * u[:, layout.mass]),
            initial_speed_mps=np.full(n, kmh_to_mps(self.initial_speed_kmh)),
            draw=friction,
            running_resistance_A_N=resistance.A_N + sigma_A * u[:, layout.resistance],
        )

    def working_units(self, u: np.ndarray, failed_units: int | None = None) -> np.ndarray:
        """Whether each disc unit of each stop gives force (n, axles, discs per axle): a unit fails
        where Phi(u) is below its failure probability per demand, or, with ``failed_units`` k, the
        k units of the smallest u fail (for independent normals a uniformly drawn set of k)."""
        units = u[:, self.layout.units]
        if failed_units is None:
            working = units >= self.unit_failure_below
        else:
            if not 0 <= failed_units <= units.shape[1]:
                raise ValueError(f"failed_units {failed_units}: the train has {units.shape[1]} disc units")
            working = np.ones(units.shape, dtype=bool)
            np.put_along_axis(working, np.argsort(units, axis=1)[:, :failed_units], False, axis=1)
        return working.reshape(len(u), *self.plant.disc_shape)

    def strata(self, response: Callable[..., np.ndarray] | None = None) -> list[tuple[float, Callable]]:
        """The model split by the number k of failed units (law of total probability): for each k
        of positive probability, its probability Binomial(k; units, q) and the response with
        exactly k units failed, ``response(u, failed_units=k)`` (default the braking distance).
        The discrete input is gone from each stratum's response, which the rare-event estimators
        need (one failure region per stratum instead of one per set of failed units)."""
        response = response or self.braking_distance_m
        n_units = self.vehicle.n_discs
        failure = self.case.brake_units.failure_probability_per_demand
        weights = stats.binom.pmf(np.arange(n_units + 1), n_units, failure)
        return [
            (float(weight), functools.partial(response, failed_units=k))
            for k, weight in enumerate(weights)
            if weight > 0
        ]

    def pressure_commands_bar(self, u: np.ndarray) -> np.ndarray:
        """The cylinder pressure of each axle (n, axles): the brake mode's pressure within its
        tolerance, between 0 and the vehicle's largest cylinder pressure."""
        tolerance = self.case.cylinder_pressure.sigma_bar * u[:, self.layout.pressure]
        pressure = self.nominal_pressure_bar + np.broadcast_to(tolerance, (len(u), self.plant.n_axles))
        return np.clip(pressure, 0.0, self.vehicle.max_cylinder_pressure_bar)

    def cylinders(self, u: np.ndarray) -> list[BrakeCylinder]:
        """Each stop's brake cylinder: the actuation's dead time, its time constant scattered."""
        scale = np.exp(self.case.response_time.time_constant_relative_sigma * u[:, self.layout.time_constant])
        return [BrakeCylinder(self.cylinder.dead_time_s, self.cylinder.time_constant_s * float(s)) for s in scale]
