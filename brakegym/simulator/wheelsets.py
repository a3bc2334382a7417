"""The simulator with wheel-rail adhesion: each wheelset turns on its own and creeps on the rail
(docs/adhesion.md). An option, off by default: :class:`AdhesionSimulator` steps with its
own compiled kernel (:mod:`.wheelset_kernel`), so :class:`~.integrator.Simulator` and its kernel
are untouched; :class:`~.wheelsets_reference.NumpyAdhesionSimulator` is the same scheme in numpy,
the reference the kernel is tested against.

Per step of h: the disc states (mu, temperatures, heat integrals) and the disc friction work by
RK4, as without adhesion but with each axle's sliding speed omega r_fric; the wheelsets and the
train speed in n substeps by the linearly implicit Euler method, whose Jacobian (an arrow: each
wheel speed couples only to the train speed) is solved by a Schur complement. The substeps give
the RK4 stages the wheel speeds at t, t + h/2 and t + h. docs/adhesion.md says why.

Wheel speeds are u = omega r (m/s) in the equations; ``state.WHEELSET_STATES`` names the rows of
``AdhesionSimulator.wheelset``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..physics import PolachLaw, RailConditioning, RailSections, RunningResistanceLaw, WheelRailContact
from ..physics.adhesion import creep
from ..physics.load_transfer import LoadTransfer
from ..units import STANDARD_GRAVITY_MPS2
from . import wheelset_kernel
from .integrator import Simulator, StepRecord
from .plant import BatchConditions, Plant
from .pressure import PressureSource
from .state import ANGULAR_SPEED, POSITION, SLIP_WORK, SPEED, WHEELSET_STATES

__all__ = [
    "ANGULAR_SPEED",
    "DEFAULT_MAX_SUBSTEP_S",
    "DEFAULT_REGULARISATION_SPEED_MPS",
    "SLIP_WORK",
    "WHEELSET_STATES",
    "AdhesionSimulator",
    "WheelRailAdhesion",
]

#: Below this train speed the creep divides by it instead of v (ASSUMED, docs/adhesion.md).
DEFAULT_REGULARISATION_SPEED_MPS = 0.5
#: Longest wheelset substep, s (converged to 0.5 % against a tenth of it, docs/adhesion.md).
DEFAULT_MAX_SUBSTEP_S = 0.01


@dataclass(frozen=True)
class WheelRailAdhesion:
    """What the adhesion option adds to a plant: the rail's creep-force law (one for the whole
    line, or :class:`~brakegym.physics.adhesion.RailSections`), the wheels' contact, the inertia
    of each wheelset about its axis, the creep's regularisation speed, the longest wheelset
    substep, how far behind the train's position each axle runs (m, one per axle; all at the
    train's position if not given), which decides when each axle enters a section, and each
    train's own rail: a factor on every section's mu_0, one per train of the batch (a campaign's
    scatter of the rail, docs/adhesion.md; none: every train on the rail as given), the load
    transfer between the axles while braking (none: every wheel carries the static share), and
    the conditioning of the rail by the axles ahead, one per section of the line (none: each axle
    on the section's own mu_0)."""

    law: PolachLaw | RailSections
    contact: WheelRailContact
    wheelset_inertia_kgm2: float
    regularisation_speed_mps: float = DEFAULT_REGULARISATION_SPEED_MPS
    max_substep_s: float = DEFAULT_MAX_SUBSTEP_S
    axle_offsets_m: tuple[float, ...] | None = None
    static_friction_factor: tuple[float, ...] | None = None
    load_transfer: LoadTransfer | None = None
    conditioning: tuple[RailConditioning, ...] | None = None

    def __post_init__(self) -> None:
        if self.static_friction_factor is not None and not all(
            math.isfinite(f) and f > 0 for f in self.static_friction_factor
        ):
            raise ValueError(f"static_friction_factor {self.static_friction_factor}: every factor must be positive")
        if self.conditioning is not None and len(self.conditioning) != self.n_sections:
            raise ValueError(
                f"{len(self.conditioning)} rail conditionings for {self.n_sections} sections: need one each"
            )

    @property
    def n_sections(self) -> int:
        """Sections of the rail (1 on a rail in one condition)."""
        return len(self.law.laws) if isinstance(self.law, RailSections) else 1

    def axle_conditioning(self, n_axles: int) -> np.ndarray:
        """Each section's factor on mu_0 under each axle (S, A): the rail's conditioning by the
        axles ahead, exactly 1 without."""
        if self.conditioning is None:
            return np.ones((self.n_sections, n_axles))
        return np.array([conditioning.axle_factors(n_axles) for conditioning in self.conditioning])

    def law_at(self, position_m: np.ndarray, n_axles: int | None = None) -> PolachLaw:
        """The creep-force law under each axle, train positions ``position_m`` (B,): the law
        itself on a uniform rail, else parameter arrays (A, B); with a conditioning (which needs
        ``n_axles``), mu_0 under each axle times its factor, (A, 1) or (A, B)."""
        if isinstance(self.law, PolachLaw):
            law = self.law
            section = np.zeros((1, 1), dtype=np.int64)
        else:
            offsets = np.zeros(1) if self.axle_offsets_m is None else np.asarray(self.axle_offsets_m)
            axle_position = position_m[None, :] - offsets[:, None]
            law = self.law.law_at(axle_position)
            section = self.law.section_at(axle_position)
        if self.conditioning is None:
            return law
        if n_axles is None:
            raise ValueError("a conditioned rail's law under each axle needs n_axles")
        factors = self.axle_conditioning(n_axles)  # (S, A)
        under_axle = np.take_along_axis(factors.T, np.broadcast_to(section, (n_axles, section.shape[1])), axis=1)
        return dataclasses.replace(law, static_friction=law.static_friction * under_axle)

    def rail_table(self, n_axles: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The rail as the compiled kernel reads it: section starts (S,), each section's Polach
        parameters then each axle's factor on its mu_0 (S, 5 + A: :attr:`axle_conditioning`) and
        the axle offsets (A,); a uniform rail is one section from 0."""
        sections = self.law if isinstance(self.law, RailSections) else RailSections((0.0,), (self.law,))
        laws = np.array(
            [
                [
                    law.static_friction,
                    law.friction_ratio_at_infinity,
                    law.friction_decay_s_per_m,
                    law.adhesion_reduction,
                    law.slip_reduction,
                ]
                for law in sections.laws
            ],
            dtype=float,
        )
        laws = np.concatenate([laws, self.axle_conditioning(n_axles)], axis=1)
        offsets = np.zeros(n_axles) if self.axle_offsets_m is None else np.asarray(self.axle_offsets_m, dtype=float)
        if offsets.shape != (n_axles,):
            raise ValueError(f"axle_offsets_m {self.axle_offsets_m}: need one offset per axle ({n_axles})")
        return np.asarray(sections.starts_m, dtype=float), laws, offsets

    def substeps(self, step_s: float) -> int:
        """Substeps per step: an even number (the RK4 stages need the middle), none longer than
        ``max_substep_s``."""
        n = math.ceil(step_s / self.max_substep_s - 1e-9)
        return n + (n % 2)


class AdhesionSimulator(Simulator):
    """:class:`~.integrator.Simulator` with wheel-rail adhesion (docs/adhesion.md), compiled.

    The train mass of the conditions is the paper's effective mass, with the wheelsets' rotation
    in it; here the wheelsets carry their inertia themselves and the body mass is
    m - n_axles J / r^2. Each wheel presses on the rail with the static share of the weight. No
    extension hooks. The wheelsets start rolling with the train.
    """

    def __init__(
        self,
        plant: Plant,
        conditions: BatchConditions,
        pressure: PressureSource,
        adhesion: WheelRailAdhesion,
        step_s: float = 0.1,
        nominal_running_resistance: RunningResistanceLaw | None = None,
    ) -> None:
        super().__init__(plant, conditions, pressure, step_s, nominal_running_resistance=nominal_running_resistance)
        self.adhesion = adhesion
        self.n_substeps = adhesion.substeps(self.step_s)
        self.wheelset_mass_kg = adhesion.wheelset_inertia_kgm2 / plant.wheel_radius_m**2
        self.wheelset = np.zeros((len(WHEELSET_STATES), plant.n_axles, self.n_trains))
        self.scheme_parameters = np.empty(wheelset_kernel.N_SCHEME_PARAMETERS)
        self.scheme_parameters[wheelset_kernel.STEP_S] = self.step_s
        self.scheme_parameters[wheelset_kernel.N_SUBSTEPS] = self.n_substeps
        self.scheme_parameters[wheelset_kernel.REGULARISATION_SPEED_MPS] = adhesion.regularisation_speed_mps
        self.scheme_parameters[wheelset_kernel.WHEELSET_MASS_KG] = self.wheelset_mass_kg
        self.scheme_parameters[wheelset_kernel.WHEEL_RADIUS_M] = plant.wheel_radius_m
        transfer = adhesion.load_transfer
        if transfer is not None and transfer.n_axles != plant.n_axles:
            raise ValueError(
                f"load transfer of {transfer.bogies} bogies x {transfer.axles_per_bogie} axles on a plant "
                f"of {plant.n_axles} axles"
            )
        self.scheme_parameters[wheelset_kernel.LOAD_TRANSFER] = 0.0 if transfer is None else 1.0
        self.rail_table = adhesion.rail_table(plant.n_axles)
        # Per train, what the kernel reads (rows wheelset_kernel.MASS_KG, ...).
        # With load transfer, each axle's gain and current wheel load follow (wheelset_kernel.AXLE_LOAD_GAIN).
        rows = wheelset_kernel.N_WHEELSET_CONSTANTS + (0 if transfer is None else 2 * plant.n_axles)
        self.wheelset_constants = np.empty((rows, self.n_trains))
        factor = adhesion.static_friction_factor
        if factor is not None and len(factor) != self.n_trains:
            raise ValueError(f"static_friction_factor: {len(factor)} factors for {self.n_trains} trains")
        self.wheelset_constants[wheelset_kernel.STATIC_FRICTION_FACTOR] = 1.0 if factor is None else factor
        self._set_train_loads(np.arange(self.n_trains))

    def _set_train_loads(self, index: np.ndarray) -> None:
        """Body mass, wheel loads and wheel speeds of the trains ``index`` from their mass and
        speed."""
        plant = self.plant
        mass = self.mass_kg[index]
        body = mass - plant.n_axles * self.wheelset_mass_kg
        if np.any(body <= 0):
            raise ValueError(
                f"wheelset inertia {self.adhesion.wheelset_inertia_kgm2} kg m^2 on {plant.n_axles} axles "
                f"outweighs a train mass of {mass.min()} kg"
            )
        wheel_load = mass * STANDARD_GRAVITY_MPS2 / (2 * plant.n_axles)
        self.wheelset_constants[wheelset_kernel.MASS_KG, index] = mass
        self.wheelset_constants[wheelset_kernel.BODY_MASS_KG, index] = body
        self.wheelset_constants[wheelset_kernel.WHEEL_LOAD_N, index] = wheel_load
        self.wheelset_constants[wheelset_kernel.CREEP_STIFFNESS_N, index] = self.adhesion.contact.creep_stiffness_N(
            wheel_load
        )
        transfer = self.adhesion.load_transfer
        if transfer is not None:
            gain = wheelset_kernel.AXLE_LOAD_GAIN
            # Per wheel: half the axle's gain.
            self.wheelset_constants[gain : gain + plant.n_axles, index] = 0.5 * transfer.axle_load_gain_N_per_mps2(body)
            self.wheelset_constants[gain + plant.n_axles :, index] = wheel_load
        self.wheelset[:, :, index] = 0.0
        self.wheelset[ANGULAR_SPEED][:, index] = self.train[SPEED, index] / plant.wheel_radius_m

    def reset_trains(self, index: np.ndarray, conditions: BatchConditions) -> None:
        super().reset_trains(index, conditions)
        self._set_train_loads(np.asarray(index, dtype=np.int64))

    @property
    def has_hooks(self) -> bool:
        return False

    # Rows of the per-train constants, as views: writing to them writes what the kernel reads.
    @property
    def body_mass_kg(self) -> np.ndarray:
        """The body's mass per train, m - n_axles J / r^2 in kg (the wheelsets carry their own inertia)."""
        return self.wheelset_constants[wheelset_kernel.BODY_MASS_KG]

    @property
    def wheel_load_N(self) -> np.ndarray:
        """The static load of each wheel per train, N (:attr:`axle_wheel_load_N`: each axle's own)."""
        return self.wheelset_constants[wheelset_kernel.WHEEL_LOAD_N]

    @property
    def axle_wheel_load_N(self) -> np.ndarray:
        """The wheel load of each axle and train in N, shaped (A, B). Without load transfer the
        static share; with it, the load at the current state (written by the kernel at the end of
        each step)."""
        if self.adhesion.load_transfer is None:
            return np.broadcast_to(self.wheel_load_N, (self.plant.n_axles, self.n_trains))
        first = wheelset_kernel.AXLE_LOAD_GAIN + self.plant.n_axles
        return self.wheelset_constants[first : first + self.plant.n_axles]

    @property
    def axle_creep_stiffness_N(self) -> np.ndarray:
        """Each axle's creep stiffness (A, B) at its :attr:`axle_wheel_load_N`, N."""
        if self.adhesion.load_transfer is None:
            return np.broadcast_to(self.creep_stiffness_N, (self.plant.n_axles, self.n_trains))
        return self.creep_stiffness_N * (self.axle_wheel_load_N / self.wheel_load_N) ** (2.0 / 3.0)

    @property
    def creep_stiffness_N(self) -> np.ndarray:
        """G pi a b c_11 / 4 of each train's contact at its wheel load, N."""
        return self.wheelset_constants[wheelset_kernel.CREEP_STIFFNESS_N]

    @property
    def static_friction_factor(self) -> np.ndarray:
        """The factor on each train's rail mu_0 (B,)."""
        return self.wheelset_constants[wheelset_kernel.STATIC_FRICTION_FACTOR]

    def rail_law_at(self, position_m: np.ndarray) -> PolachLaw:
        """The creep-force law under each axle (:meth:`WheelRailAdhesion.law_at`, the rail's
        conditioning in it), its mu_0 times each train's :attr:`static_friction_factor` where the
        adhesion option gives one."""
        law = self.adhesion.law_at(position_m, self.plant.n_axles)
        if self.adhesion.static_friction_factor is None:
            return law
        return dataclasses.replace(law, static_friction=law.static_friction * self.static_friction_factor)

    @property
    def wheel_speed_mps(self) -> np.ndarray:
        """omega r of each axle (A, B)."""
        return self.wheelset[ANGULAR_SPEED] * self.plant.wheel_radius_m

    def creep_force_N(self, speed_mps: np.ndarray, wheel_speed_mps: np.ndarray, law: PolachLaw) -> np.ndarray:
        """Force of each axle's two wheels on the rail (A, B), retarding the train when the wheel
        turns slower than it runs; ``law`` from :meth:`WheelRailAdhesion.law_at`."""
        slip = speed_mps - wheel_speed_mps
        s = creep(speed_mps, wheel_speed_mps, self.adhesion.regularisation_speed_mps)
        if self.adhesion.load_transfer is None:
            return 2.0 * law.creep_force_N(s, slip, self.wheel_load_N, self.creep_stiffness_N)
        return 2.0 * law.creep_force_N(s, slip, self.axle_wheel_load_N, self.axle_creep_stiffness_N)

    # ----------------------------------------------------------------------------------------
    def _step_once(self) -> StepRecord:
        """One step of every train in the compiled kernel (:func:`.wheelset_kernel.adhesion_step`)."""
        t = self.time_s
        stage_pressures = np.ascontiguousarray(np.stack(self.pressure.stage_pressures_bar()), dtype=float)
        disc0, train0, wheelset0, moving0 = self.disc, self.train, self.wheelset, self.moving
        disc1, train1, wheelset1 = np.empty_like(disc0), np.empty_like(train0), np.empty_like(wheelset0)
        moving1 = np.empty_like(moving0)
        stop_fraction = np.empty(self.n_trains)
        arguments = (
            self.plant_parameters,
            self.scheme_parameters,
            np.ascontiguousarray(self.power_coefficient),
            self.train_constants,
            self.wheelset_constants,
            self.rail_table,
            stage_pressures,
        )
        wheelset_kernel.adhesion_step(
            arguments,
            (disc0, train0, wheelset0),
            moving0,
            self.hold_standing_trains,
            (disc1, train1, wheelset1),
            moving1,
            stop_fraction,
        )
        stopping = ~np.isnan(stop_fraction)
        self.stop_time_s[stopping] = t + stop_fraction[stopping] * self.step_s
        self.wheelset = wheelset1
        record = StepRecord(
            t,
            disc0,
            train0,
            self.clamp_force_N(stage_pressures[0]),
            self.clamp_force_N(stage_pressures[2]),
            stop_fraction,
        )
        return self.finish_step(record, disc1, train1, moving1)

    def step(self, n_steps: int = 1) -> StepRecord:
        """Advance every train by ``n_steps`` steps, one at a time."""
        if n_steps < 1:
            raise ValueError(f"n_steps = {n_steps}: must be at least 1")
        for _ in range(n_steps):
            record = self._step_once()
        return record

    def trajectory(self, n_steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self._trajectory_stepwise(n_steps)

    # ----------------------------------------------------------------------------------------
    def deceleration_mps2(self) -> np.ndarray:
        """The train body's deceleration at the current state, m/s^2 (0 standing)."""
        return self.deceleration_at_mps2(self.disc, self.train, self.moving, self.pressure.pressure_bar)

    def deceleration_at_mps2(
        self,
        disc: np.ndarray,
        train: np.ndarray,
        moving: np.ndarray,
        pressure_bar: np.ndarray,
        wheel_speed_mps: np.ndarray | None = None,
    ) -> np.ndarray:
        """The body's deceleration at another state of these trains, m/s^2 (0 standing): the
        rail's creep forces and the running resistance over the body mass. With adhesion the brake
        acts on the wheels, not on the train: the deceleration depends on the wheel speeds
        ``wheel_speed_mps`` (A, B) of that state, not on the discs and pressures. Without them,
        only the current state (``train`` is ``self.train``) is defined."""
        if wheel_speed_mps is None:
            if train is not self.train:
                raise ValueError(
                    "with wheel-rail adhesion the deceleration of a state other than the current one "
                    "needs that state's wheel_speed_mps (A, B)"
                )
            wheel_speed_mps = self.wheel_speed_mps
        law = self.rail_law_at(train[POSITION])
        force = self.creep_force_N(train[SPEED], wheel_speed_mps, law).sum(axis=0)
        resistance = self.plant.running_resistance.force_N(train[SPEED], self.resistance_A_N)
        return np.where(moving, (force + resistance) / self.body_mass_kg, 0.0)

    def kinetic_energy_J(self) -> np.ndarray:
        """1/2 M v^2 + sum over the wheelsets of 1/2 J omega^2, per train."""
        wheels = 0.5 * self.adhesion.wheelset_inertia_kgm2 * (self.wheelset[ANGULAR_SPEED] ** 2).sum(axis=0)
        return 0.5 * self.body_mass_kg * self.train[SPEED] ** 2 + wheels
