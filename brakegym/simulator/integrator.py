"""The batched fixed-step simulator of braking trains and dynamometer stops.

:class:`Simulator` integrates the physics of :mod:`brakegym.physics` for a batch of applications
at once, so one call advances every disc of every train. Integration is classic fixed-step RK4
(spec Section 3: 0.05 % at 0.1 s against the golden values), compiled (:mod:`.kernel`): whole
steps in one call without state-dependent hooks (:mod:`brakegym.simulator.hooks`), one call per RK4 stage with them.
The states are packed arrays with the batch last (:mod:`.state`); interfaces (conditions, pressure
sources, results) use trains-first arrays and are transposed at the edge. Motion stops at v = 0
(no reversal); the stop instant is interpolated inside the step, and after it the train stands
still while its discs go on cooling.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..physics import RunningResistanceLaw
from . import kernel
from .hooks import ExtraForce, FrictionModifier, HookArrays, StageContext, is_constant, stage_context
from .plant import BatchConditions, Plant
from .pressure import CommandedPressure, CylinderState, PrescribedPressure, PressureSource
from .state import DISC_STATES, MU, SPEED, T_DISC, T_FRIC, TRAIN_STATES


@dataclass
class StepRecord:
    """What the last step did, for observers (metrics, recorders)."""

    time_start_s: float
    disc_start: np.ndarray
    train_start: np.ndarray
    clamp_force_start_N: np.ndarray  # (A, 1, B)
    clamp_force_end_N: np.ndarray  # (A, 1, B)
    stop_fraction: np.ndarray  # (B,), fraction of the step at which a train stopped; nan if none


class Simulator:
    """Fixed-step RK4 over a batch of trains (or dynamometer stops), compiled.

    Parameters
    ----------
    plant:
        Geometry and physics laws, shared by the batch.
    conditions:
        Per-application masses, initial states and scattered parameters.
    pressure:
        Where the cylinder pressures come from (:class:`.pressure.CommandedPressure` or
        :class:`.pressure.PrescribedPressure`); its step must equal ``step_s``.
    step_s:
        Integration step. 0.1 s reproduces the golden values within 0.05 %.
    extra_forces, friction_modifiers:
        Extension hooks (:mod:`brakegym.simulator.hooks`).
    nominal_running_resistance:
        What Eq. 15's mu_eff is evaluated with (the plant's own if not given).

    Attributes
    ----------
    hold_standing_trains : bool
        False unless set. When true, every train that stands still at the start of a step is held:
        its states no longer change (a standing disc would otherwise go on cooling).
        :func:`brakegym.applications.run_stops` sets it while it runs stops to standstill, so that
        each stop's summary ends at its own standstill and the kernel skips the standing trains.
    """

    def __init__(
        self,
        plant: Plant,
        conditions: BatchConditions,
        pressure: PressureSource,
        step_s: float = 0.1,
        extra_forces: Sequence[ExtraForce] = (),
        friction_modifiers: Sequence[FrictionModifier] = (),
        nominal_running_resistance: RunningResistanceLaw | None = None,
    ) -> None:
        if not step_s > 0:
            raise ValueError(f"step_s = {step_s}: must be positive")
        if getattr(pressure, "step_s", step_s) != step_s:
            raise ValueError(f"pressure source step {pressure.step_s} s differs from simulator step {step_s} s")
        self.plant = plant
        self.conditions = conditions
        self.pressure = pressure
        self.step_s = float(step_s)
        self.extra_forces = tuple(extra_forces)
        self.friction_modifiers = tuple(friction_modifiers)
        # Eq. 15 evaluates mu_eff with the nominal running resistance, not the drawn one.
        self.nominal_running_resistance = nominal_running_resistance or plant.running_resistance

        n = conditions.n_trains
        disc_shape = (*plant.disc_shape, n)
        self.mass_kg = np.array(conditions.mass_kg, dtype=float).reshape(n)  # own copy: reset_trains writes it
        # Everything per train the kernels read, in one array (rows kernel.INVERSE_MASS_PER_KG, ...):
        # one argument per call instead of eight. The running resistance may differ per train in
        # all three coefficients; the drawn A comes with the conditions.
        self.train_constants = np.empty((kernel.N_TRAIN_CONSTANTS, n))
        self.train_constants[kernel.INVERSE_MASS_PER_KG] = 1.0 / self.mass_kg
        self.train_constants[kernel.RESISTANCE_A_N] = conditions.running_resistance_A_N
        self.train_constants[kernel.AMBIENT_K] = conditions.ambient_temperature_K
        resistance, nominal = plant.running_resistance, self.nominal_running_resistance
        for row, value, name in (
            (kernel.RESISTANCE_B_N_PER_MPS, resistance.B_N_per_mps, "running resistance B_N_per_mps"),
            (kernel.RESISTANCE_C_N_PER_MPS2, resistance.C_N_per_mps2, "running resistance C_N_per_mps2"),
            (kernel.NOMINAL_RESISTANCE_A_N, nominal.A_N, "nominal running resistance A_N"),
            (kernel.NOMINAL_RESISTANCE_B_N_PER_MPS, nominal.B_N_per_mps, "nominal running resistance B_N_per_mps"),
            (kernel.NOMINAL_RESISTANCE_C_N_PER_MPS2, nominal.C_N_per_mps2, "nominal running resistance C_N_per_mps2"),
        ):
            if np.ndim(value) and np.shape(value) != (n,):
                raise ValueError(f"{name}: one value or one per train ({n}), got shape {np.shape(value)}")
            self.train_constants[row] = value
        self.power_coefficient = self.to_internal(conditions.power_coefficient_per_s)
        self.plant_parameters = kernel.plant_parameters(plant)

        self.disc = np.zeros((len(DISC_STATES), *disc_shape))
        self.disc[MU] = self.to_internal(conditions.initial_mu)
        self.disc[T_FRIC] = self.to_internal(conditions.initial_friction_temperature_K)
        self.disc[T_DISC] = self.to_internal(conditions.initial_disc_temperature_K)
        self.train = np.zeros((len(TRAIN_STATES), n))
        self.train[SPEED] = conditions.initial_speed_mps
        if np.any(self.train[SPEED] < 0):
            raise ValueError("initial speeds must not be negative")
        self.moving = self.train[SPEED] > 0
        self.stop_time_s = np.full(n, np.nan)
        self.hold_standing_trains = False
        self.step_index = 0
        self.last_step: StepRecord | None = None
        self._hook_arrays = HookArrays(disc_shape)

    def reset_trains(self, index: np.ndarray, conditions: BatchConditions) -> None:
        """Restart the trains ``index`` from ``conditions`` (a batch of ``len(index)``), leaving
        the others as they are: an environment starting new episodes for some of its trains.

        Their integrals (work, heat, mu distance) and position start again at zero; the time of
        the simulator runs on, so time-dependent extensions see the batch's clock.
        """
        index = np.asarray(index, dtype=np.int64)
        n = len(index)
        if conditions.n_trains != n:
            raise ValueError(f"reset_trains: {n} trains to restart but conditions for {conditions.n_trains}")
        shape = (n, *self.plant.disc_shape)

        def internal(per_disc: np.ndarray | float) -> np.ndarray:
            return np.moveaxis(np.broadcast_to(np.asarray(per_disc, dtype=float), shape), 0, -1)

        speed = np.broadcast_to(np.asarray(conditions.initial_speed_mps, dtype=float), (n,))
        if np.any(speed < 0):
            raise ValueError("initial speeds must not be negative")
        self.mass_kg[index] = conditions.mass_kg
        self.inverse_mass_per_kg[index] = 1.0 / self.mass_kg[index]
        self.resistance_A_N[index] = conditions.running_resistance_A_N
        self.ambient_K[index] = conditions.ambient_temperature_K
        if not self.power_coefficient.flags.writeable:  # a broadcast view when all trains shared it
            self.power_coefficient = self.power_coefficient.copy()
        self.power_coefficient[..., index] = internal(conditions.power_coefficient_per_s)
        self.disc[..., index] = 0.0
        self.disc[MU][..., index] = internal(conditions.initial_mu)
        self.disc[T_FRIC][..., index] = internal(conditions.initial_friction_temperature_K)
        self.disc[T_DISC][..., index] = internal(conditions.initial_disc_temperature_K)
        self.train[:, index] = 0.0
        self.train[SPEED, index] = speed
        self.moving[index] = speed > 0
        self.stop_time_s[index] = np.nan

    # ----------------------------------------------------------------------------------------
    # Rows of the per-train constants, as views: writing to them writes what the kernels read.
    @property
    def resistance_A_N(self) -> np.ndarray:
        return self.train_constants[kernel.RESISTANCE_A_N]

    @property
    def ambient_K(self) -> np.ndarray:
        return self.train_constants[kernel.AMBIENT_K]

    @property
    def inverse_mass_per_kg(self) -> np.ndarray:
        """1 / m per train (a view of what the kernels read)."""
        return self.train_constants[kernel.INVERSE_MASS_PER_KG]

    @property
    def time_s(self) -> float:
        return self.step_index * self.step_s

    @property
    def n_trains(self) -> int:
        return len(self.mass_kg)

    def to_internal(self, per_disc: np.ndarray | float) -> np.ndarray:
        """A trains-first disc array (B, A, k), or anything broadcasting to it, in the internal
        batch-last layout (A, k, B)."""
        n = self.n_trains
        full = np.broadcast_to(np.asarray(per_disc, dtype=float), (n, *self.plant.disc_shape))
        return np.ascontiguousarray(np.moveaxis(full, 0, -1))

    def to_external(self, internal: np.ndarray) -> np.ndarray:
        """An internal disc array (A, k, B) as trains x discs (B, A * k)."""
        return internal.reshape(-1, internal.shape[-1]).T.copy()

    def clamp_force_N(self, pressure_bar: np.ndarray) -> np.ndarray:
        """Clamp force per disc unit, internal layout (A, 1, B), from the per-axle cylinder
        pressure (B, A)."""
        return self.plant.caliper.clamp_force_N(pressure_bar).T[:, None, :]

    @property
    def has_hooks(self) -> bool:
        """Whether hooks that depend on the state take part (they need the staged path, which
        calls them at every RK4 stage); constant hooks run in the compiled kernel."""
        return not all(is_constant(hook) for hook in (*self.extra_forces, *self.friction_modifiers))

    def context_at(self, time_s: float, disc: np.ndarray, train: np.ndarray, clamp_force: np.ndarray) -> StageContext:
        """What the hooks see at packed states ``disc`` and ``train`` of these trains."""
        return stage_context(time_s, disc, train, self.mass_kg, clamp_force)

    def _current_context(self) -> StageContext:
        clamp_force = self.clamp_force_N(np.asarray(self.pressure.pressure_bar, dtype=float))
        return self.context_at(self.time_s, self.disc, self.train, clamp_force)

    def hooks_at(self, context: StageContext) -> tuple[np.ndarray, np.ndarray]:
        """Every hook evaluated at ``context``, as the compiled kernels take them: friction scale
        (A, k, B) and extra force (B,)."""
        return self._hook_arrays.at(self.extra_forces, self.friction_modifiers, context)

    def _step_hook_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """The hooks as a whole step integrates them (:meth:`.hooks.HookArrays.for_step`)."""
        return self._hook_arrays.for_step(self.extra_forces, self.friction_modifiers, self._current_context)

    @staticmethod
    def _pressures(source: PressureSource) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The stage pressures as the kernels take them: C-contiguous float arrays (no copy when
        they are already)."""
        start, middle, end = source.stage_pressures_bar()
        return (
            np.ascontiguousarray(start, dtype=float),
            np.ascontiguousarray(middle, dtype=float),
            np.ascontiguousarray(end, dtype=float),
        )

    # ----------------------------------------------------------------------------------------
    def step(self, n_steps: int = 1) -> StepRecord:
        """Advance every train by ``n_steps`` steps and return the record of the last one.

        Without hooks and with :class:`CommandedPressure` the steps run in one compiled call, the
        cylinders' pressure model included (an environment's control step: one call instead of
        one per step); the results are the same as one step at a time, bit for bit."""
        if n_steps < 1:
            raise ValueError(f"n_steps = {n_steps}: must be at least 1")
        if self.has_hooks:
            for _ in range(n_steps):
                record = self._step_staged()
            return record
        if isinstance(self.pressure, (CommandedPressure, PrescribedPressure)):
            return self._steps_fused(n_steps)[0]
        for _ in range(n_steps):
            record = self._steps_fused(1)[0]
        return record

    def trajectory(self, n_steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Advance by ``n_steps`` steps as :meth:`step` does, and return the states at every
        step, the current one first: disc states (n_steps + 1, 6, A, k, B), train states
        (n_steps + 1, 6, B) and moving (n_steps + 1, B); the last rows are the simulator's state
        (read them, do not write to them). Without state-dependent hooks and with a commanded or
        prescribed pressure in one compiled call."""
        if n_steps < 1:
            raise ValueError(f"n_steps = {n_steps}: must be at least 1")
        if self.has_hooks or not isinstance(self.pressure, (CommandedPressure, PrescribedPressure)):
            return self._trajectory_stepwise(n_steps)
        _, discs, trains, movings = self._steps_fused(n_steps, keep_every_step=True)
        return discs, trains, movings

    def _trajectory_stepwise(self, n_steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        discs, trains, movings = [self.disc], [self.train], [self.moving]
        for _ in range(n_steps):
            self.step()
            discs.append(self.disc)
            trains.append(self.train)
            movings.append(self.moving)
        return np.stack(discs), np.stack(trains), np.stack(movings)

    def _steps_fused(
        self, n_steps: int, keep_every_step: bool = False
    ) -> tuple[StepRecord, np.ndarray, np.ndarray, np.ndarray]:
        """``n_steps`` steps in one kernel call (one step for a pressure source that is neither
        commanded nor prescribed); the record of the last and the state buffers (with
        ``keep_every_step``, the states at every step, the current one first)."""
        n, axles = self.n_trains, self.plant.n_axles
        disc0, train0, moving0 = self.disc, self.train, self.moving
        buffers = n_steps if keep_every_step else min(n_steps, 2)
        # With every step kept, the kernel writes behind a first row that holds the current state.
        first = 1 if keep_every_step else 0
        all_discs = np.empty((first + buffers, *disc0.shape))
        all_trains = np.empty((first + buffers, *train0.shape))
        all_movings = np.empty((first + buffers, n), dtype=bool)
        if keep_every_step:
            all_discs[0], all_trains[0], all_movings[0] = disc0, train0, moving0
        discs, trains, movings = all_discs[first:], all_trains[first:], all_movings[first:]
        stop_fraction = np.empty(n)
        clamp = np.empty((2, axles, 1, n))
        commanded = self.pressure if isinstance(self.pressure, CommandedPressure) else None
        if commanded is not None:
            cylinders = commanded.kernel_state()
            stage_pressures = np.empty((3, n, axles))
        elif isinstance(self.pressure, PrescribedPressure):
            cylinders = CylinderState.none(n, axles)
            stage_pressures = np.ascontiguousarray(self.pressure.half_step_pressures_bar(n_steps), dtype=float)
        else:
            if n_steps != 1:
                raise ValueError(f"{type(self.pressure).__name__} gives the pressures of one step at a time")
            cylinders = CylinderState.none(n, axles)
            stage_pressures = np.ascontiguousarray(np.stack(self.pressure.stage_pressures_bar()), dtype=float)
        friction_scale, extra_force_N = self._step_hook_arrays()
        kernel.fused_steps(
            self.plant_parameters,
            self.step_index,
            n_steps,
            self.step_s,
            self.power_coefficient,
            self.train_constants,
            friction_scale,
            extra_force_N,
            disc0,
            train0,
            moving0,
            self.hold_standing_trains,
            cylinders,
            stage_pressures,
            discs,
            trains,
            movings,
            stop_fraction,
            self.stop_time_s,
            clamp,
        )
        last = (n_steps - 1) % buffers
        if n_steps == 1:
            disc_start, train_start = disc0, train0
        else:
            disc_start, train_start = discs[(n_steps - 2) % buffers], trains[(n_steps - 2) % buffers]
        record = StepRecord(
            (self.step_index + n_steps - 1) * self.step_s, disc_start, train_start, clamp[0], clamp[1], stop_fraction
        )
        # New arrays every call: the record keeps the pre-step state, which nothing writes to.
        self.disc, self.train, self.moving = discs[last], trains[last], movings[last]
        if commanded is not None:
            commanded.advanced_by(n_steps, cylinders.pressure_bar)
        elif isinstance(self.pressure, PrescribedPressure):
            self.pressure.advance_by(n_steps)
        else:
            self.pressure.advance()
        self.step_index += n_steps
        self.last_step = record
        return record, all_discs, all_trains, all_movings

    def _step_staged(self) -> StepRecord:
        """RK4 in Python around the compiled stage rates, so that the hooks see every stage."""
        h = self.step_s
        t = self.time_s
        p_start, p_mid, p_end = self._pressures(self.pressure)
        f_start, f_mid, f_end = (np.ascontiguousarray(self.clamp_force_N(p)) for p in (p_start, p_mid, p_end))
        disc0, train0, moving0 = self.disc, self.train, self.moving
        disc_rates = np.empty((4, *disc0.shape))
        train_rates = np.empty((4, *train0.shape))
        disc, train = disc0, train0
        stages = (
            (t, p_start, f_start, 0.5 * h),
            (t + 0.5 * h, p_mid, f_mid, 0.5 * h),
            (t + 0.5 * h, p_mid, f_mid, h),
            (t + h, p_end, f_end, None),
        )
        for stage, (time_s, pressure, clamp_force, fraction_for_next) in enumerate(stages):
            scale, extra = self.hooks_at(self.context_at(time_s, disc, train, clamp_force))
            kernel.stage_rates(
                self.plant_parameters,
                disc,
                train,
                moving0,
                pressure,
                scale,
                extra,
                self.power_coefficient,
                self.train_constants,
                disc_rates[stage],
                train_rates[stage],
            )
            if fraction_for_next is not None:
                disc = disc0 + fraction_for_next * disc_rates[stage]
                train = train0 + fraction_for_next * train_rates[stage]
        disc1, train1 = np.empty_like(disc0), np.empty_like(train0)
        moving1 = np.empty_like(moving0)
        stop_fraction = np.empty(self.n_trains)
        kernel.finish_rk4_step(
            self.plant_parameters,
            t,
            h,
            disc0,
            train0,
            moving0,
            self.hold_standing_trains,
            disc_rates,
            train_rates,
            disc1,
            train1,
            moving1,
            stop_fraction,
            self.stop_time_s,
        )
        record = StepRecord(t, disc0, train0, f_start, f_end, stop_fraction)
        return self.finish_step(record, disc1, train1, moving1)

    def finish_step(self, record: StepRecord, disc1: np.ndarray, train1: np.ndarray, moving1: np.ndarray) -> StepRecord:
        """Take over the states at the end of a step (``disc1``, ``train1``, ``moving1``)."""
        # New arrays every step: the record keeps the pre-step state, which nothing writes to.
        self.disc, self.train, self.moving = disc1, train1, moving1
        self.pressure.advance()
        self.step_index += 1
        self.last_step = record
        return record

    # ----------------------------------------------------------------------------------------
    def deceleration_mps2(self) -> np.ndarray:
        """Instantaneous deceleration of each train at the current state, m/s^2 (positive while
        slowing, zero at standstill)."""
        return self.deceleration_at_mps2(self.disc, self.train, self.moving, self.pressure.pressure_bar)

    def deceleration_at_mps2(
        self, disc: np.ndarray, train: np.ndarray, moving: np.ndarray, pressure_bar: np.ndarray
    ) -> np.ndarray:
        """:meth:`deceleration_mps2` at another state of these trains (a row of
        :meth:`trajectory`), with the cylinder pressures (B, A) of that moment; hooks that
        depend on the state are evaluated at the current state, so use it without them."""
        clamp_force = np.ascontiguousarray(self.clamp_force_N(pressure_bar), dtype=float)
        scale, extra = self._step_hook_arrays()  # constant hooks too
        out = np.empty(self.n_trains)
        kernel.deceleration_mps2(
            self.plant_parameters, disc, train, moving, clamp_force, scale, extra, self.train_constants, out
        )
        return out

    def state_view(self, name: str) -> np.ndarray:
        """A named state (from DISC_STATES or TRAIN_STATES), as a view."""
        if name in DISC_STATES:
            return self.disc[DISC_STATES.index(name)]
        if name in TRAIN_STATES:
            return self.train[TRAIN_STATES.index(name)]
        raise KeyError(f"unknown state {name!r}; known: {DISC_STATES + TRAIN_STATES}")
