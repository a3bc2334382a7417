"""Batched fixed-step simulator of braking trains and dynamometer stops.

The simulator integrates the physics modules of :mod:`brakegym.physics` for a batch of
applications at once, so one call advances every disc of every train. Inside, the batch is the
*last* axis: disc states are (axles, discs per axle, trains) and train states (trains,), so that
numpy's inner loops run over the long, contiguous train axis (with the trains first, the inner
loops ran over two discs and the simulator was twice as slow). Interfaces (conditions, pressure
sources, results) use trains-first arrays and are transposed at the edge.

Integration is classic fixed-step RK4 (spec Section 3: 0.05 % at 0.1 s against the golden values),
compiled (:mod:`brakegym.kernel`): one call per step without extension hooks, one per RK4 stage with
them. :class:`NumpyReferenceSimulator` integrates the same equations with numpy array operations;
it is the readable reference the compiled kernels are tested and benchmarked against.
The brake-cylinder pressure is not an RK4 state: its lag is solved exactly within each step
(:mod:`brakegym.physics.pneumatics`), which keeps the pneumatic response free of step error.
Motion stops at v = 0 (no reversal); the stop instant is interpolated inside the step, and after it
the train stands still while its discs go on cooling.

Extension points, so that new physics needs no change of the core loop:

- ``extra_forces``: objects with ``force_N(context) -> (trains,)`` retarding forces (a gradient);
- ``friction_modifiers``: objects with ``scale(context) -> factor`` on the effective coefficient of
  friction of each disc (wet pads, fade, a friction level error); the friction state of Eq. 4
  itself is untouched.

The ``context`` handed to them is a :class:`StageContext`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, Sequence

import numpy as np

from . import kernel
from .physics import BrakeCylinder, Caliper, DiscThermalModel, FrictionLaw, RunningResistance
from .physics.mechanics import brake_force_N, effective_mu

# Rows of the packed per-disc state, shape (len(DISC_STATES), axles, discs per axle, trains).
DISC_STATES = (
    "mu",  # dynamic coefficient of friction (Eq. 4)
    "friction_temperature_K",  # T_fric
    "disc_temperature_K",  # T_disc
    "mu_distance_m",  # integral of mu ds, for mu_s (Eq. 3)
    "friction_heat_J",  # integral of Q_fric dt: heat that entered the disc
    "cooling_heat_J",  # integral of (Q_surf + Q_vent) dt: heat given to the air
)
# Rows of the packed per-train state, shape (len(TRAIN_STATES), trains).
TRAIN_STATES = (
    "speed_mps",
    "position_m",
    "brake_work_J",  # integral of F_brake v dt
    "resistance_work_J",  # integral of F_R v dt
    "extra_work_J",  # integral of the extra forces' v dt
    "mu_eff_distance_m",  # integral of mu_eff ds (Eq. 15)
)
MU, T_FRIC, T_DISC, MU_DISTANCE, FRICTION_HEAT, COOLING_HEAT = range(len(DISC_STATES))
SPEED, POSITION, BRAKE_WORK, RESISTANCE_WORK, EXTRA_WORK, MU_EFF_DISTANCE = range(len(TRAIN_STATES))


@dataclass(frozen=True)
class Plant:
    """What is braked and by which physics: the dynamometer rig or a train.

    Geometry and laws are shared by the whole batch; what differs per application (mass, initial
    state, scattered parameters) is in :class:`BatchConditions`.
    """

    name: str
    n_axles: int
    discs_per_axle: int
    wheel_radius_m: float
    friction_radius_m: float
    friction: FrictionLaw
    thermal: DiscThermalModel
    caliper: Caliper
    running_resistance: RunningResistance
    max_command: float  # largest cylinder pressure command, bar (clamp force in N on the rig)

    @property
    def n_discs(self) -> int:
        return self.n_axles * self.discs_per_axle

    @property
    def disc_shape(self) -> tuple[int, int]:
        return (self.n_axles, self.discs_per_axle)

    @property
    def radius_ratio(self) -> float:
        """r_fric / r_wheel: sliding speed per train speed, brake force per friction force."""
        return self.friction_radius_m / self.wheel_radius_m


@dataclass
class BatchConditions:
    """Per-application values of a batch of B applications.

    Disc arrays broadcast to (B, axles, discs per axle), train arrays to (B,). Temperatures in
    kelvin.
    """

    mass_kg: np.ndarray
    initial_speed_mps: np.ndarray
    initial_mu: np.ndarray
    power_coefficient_per_s: np.ndarray
    running_resistance_A_N: np.ndarray
    initial_friction_temperature_K: np.ndarray
    initial_disc_temperature_K: np.ndarray
    ambient_temperature_K: np.ndarray

    @property
    def n_trains(self) -> int:
        return int(np.shape(self.mass_kg)[0])


@dataclass
class StageContext:
    """What an extension sees at one RK4 stage. Arrays are views: do not write to them."""

    time_s: float
    speed_mps: np.ndarray  # (B,)
    position_m: np.ndarray  # (B,)
    mass_kg: np.ndarray  # (B,)
    mu: np.ndarray  # (A, k, B), the friction state of Eq. 4
    clamp_force_N: np.ndarray  # (A, 1, B)
    friction_temperature_K: np.ndarray  # (A, k, B)
    friction_heat_J: np.ndarray  # (A, k, B), heat that entered each disc so far


class ExtraForce(Protocol):
    """A force term. A term whose class sets ``constant = True`` promises that its value does not
    depend on the context (state or time): the simulator then evaluates it once per call of
    :meth:`Simulator.step` and integrates in the compiled kernel, instead of calling it at every
    RK4 stage."""

    def force_N(self, context: StageContext) -> np.ndarray:
        """Retarding force on each train, N, shape (B,); negative pushes the train on."""
        ...


class FrictionModifier(Protocol):
    """A factor on friction; ``constant = True`` as for :class:`ExtraForce`."""

    def scale(self, context: StageContext) -> np.ndarray | float:
        """Factor on each disc's effective coefficient of friction, broadcastable to (A, k, B)."""
        ...


class PressureSource(Protocol):
    """Brake-cylinder pressure per axle, bar, shape (B, A), at the start, middle and end of the
    coming step; ``advance`` then moves to the end of it."""

    def stage_pressures_bar(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    def advance(self) -> None: ...

    @property
    def pressure_bar(self) -> np.ndarray: ...


class CommandedPressure:
    """Pressure commands through each train's brake cylinder: dead time, then first-order lag.

    Commands set with :meth:`set_command` take effect ``dead_time`` later. Dead times must be
    whole numbers of steps, so the delayed command is constant within a step and the lag is
    solved exactly.
    """

    def __init__(
        self,
        cylinders: Sequence[BrakeCylinder],
        n_axles: int,
        step_s: float,
        initial_pressure_bar: np.ndarray | float = 0.0,
    ) -> None:
        n_trains = len(cylinders)
        self.step_s = step_s
        dead_steps = [c.dead_time_steps(step_s) for c in cylinders]
        half_lag = [c.lag_factor(0.5 * step_s) for c in cylinders]
        full_lag = [c.lag_factor(step_s) for c in cylinders]
        self._dead_steps = np.array(dead_steps, dtype=np.int64)
        # One kind of cylinder for the whole batch (the usual case) needs no per-train indexing
        # and scalar lag factors: the same numbers, fewer array operations per step.
        self._uniform = len(set(dead_steps)) == 1 and len(set(half_lag)) == 1 and len(set(full_lag)) == 1
        if self._uniform:
            self._half_lag, self._full_lag = half_lag[0], full_lag[0]
        else:
            self._half_lag, self._full_lag = np.array(half_lag)[:, None], np.array(full_lag)[:, None]
        self._pressure = np.broadcast_to(np.asarray(initial_pressure_bar, dtype=float), (n_trains, n_axles)).copy()
        # Ring buffer of past commands: the cylinder of train b sees the command given
        # dead_steps[b] steps ago. Before any command, the target is the initial pressure.
        self._history = np.repeat(self._pressure[None], int(self._dead_steps.max()) + 1, axis=0)
        self._rows = np.arange(n_trains)
        # The same factors per train, for the compiled steps (Simulator.step(n_steps)).
        self._lag_per_train = (np.array(half_lag, dtype=float), np.array(full_lag, dtype=float))
        self._step = 0
        self._command = self._pressure.copy()

    @property
    def pressure_bar(self) -> np.ndarray:
        return self._pressure

    @property
    def command_bar(self) -> np.ndarray:
        return self._command

    def set_command(self, command_bar: np.ndarray) -> None:
        """Command per axle (B, A) from now on. Values are used as given: range checks belong to
        the caller, who knows where the command came from."""
        command = np.array(command_bar, dtype=float)  # a copy: the caller may reuse its array
        if command.shape != self._pressure.shape:
            command = np.broadcast_to(command, self._pressure.shape).copy()
        self._command = command

    def reset_trains(self, index: np.ndarray, pressure_bar: float = 0.0) -> None:
        """Give the trains ``index`` a new start: cylinders at ``pressure_bar``, commanded so, and
        no earlier commands waiting in their dead time (an environment restarting episodes)."""
        self._pressure[index] = pressure_bar
        self._history[:, index] = pressure_bar
        self._command[index] = pressure_bar

    def _target(self) -> np.ndarray:
        slots = len(self._history)
        self._history[self._step % slots] = self._command
        if self._uniform:
            return self._history[(self._step - int(self._dead_steps[0])) % slots]
        return self._history[(self._step - self._dead_steps) % slots, self._rows]

    def stage_pressures_bar(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        target = self._target()
        gap = self._pressure - target
        self._end = target + gap * self._full_lag
        return self._pressure, target + gap * self._half_lag, self._end

    def advance(self) -> None:
        self._pressure = self._end
        self._step += 1

    def kernel_state(self) -> tuple[np.ndarray, ...]:
        """What :func:`brakegym.kernel.fused_rk4_steps` runs these cylinders from: the command
        history (advanced in place), dead steps, half-step and full-step lag factors per train, a
        copy of the pressures (the kernel advances it) and the command. See :meth:`advanced_by`."""
        half_lag, full_lag = self._lag_per_train
        return self._history, self._dead_steps, half_lag, full_lag, self._pressure.copy(), self._command

    def advanced_by(self, n_steps: int, pressure_bar: np.ndarray) -> None:
        """Take over the end of ``n_steps`` steps the compiled kernel ran from :meth:`kernel_state`."""
        self._pressure = pressure_bar
        self._step += n_steps


class PrescribedPressure:
    """Pressure traces given in advance (recorded or scheduled), linearly interpolated.

    ``time_s`` (T,) strictly increasing, ``pressure_bar`` (T, B, A); held at the last value past
    the end of the trace.
    """

    def __init__(self, time_s: np.ndarray, pressure_bar: np.ndarray, step_s: float, start_time_s: float = 0.0):
        self.time_s = np.asarray(time_s, dtype=float)
        self.trace_bar = np.asarray(pressure_bar, dtype=float)
        if self.time_s.ndim != 1 or self.trace_bar.ndim != 3 or len(self.time_s) != len(self.trace_bar):
            raise ValueError("PrescribedPressure needs time_s (T,) and pressure_bar (T, trains, axles)")
        if np.any(np.diff(self.time_s) <= 0):
            raise ValueError("PrescribedPressure: time_s must be strictly increasing")
        self.step_s = step_s
        self._t0 = start_time_s
        self._step = 0
        # The last few pressures asked for: a step asks for its start, middle and end, the next
        # starts where it ended, and observers ask for the current pressure again.
        self._recent: dict[float, np.ndarray] = {}

    def _at(self, time_s: float) -> np.ndarray:
        recent = self._recent.get(time_s)
        if recent is None:
            # Shared by every caller, which must not change it. (Not flagged read-only: numba
            # types read-only arrays apart and would compile the kernels again for them.)
            recent = self._recent[time_s] = self._interpolated(time_s)
            if len(self._recent) > 4:
                del self._recent[next(iter(self._recent))]
        return recent

    def _interpolated(self, time_s: float) -> np.ndarray:
        index = int(np.searchsorted(self.time_s, time_s, side="right")) - 1
        if index < 0:
            return self.trace_bar[0]
        if index >= len(self.time_s) - 1:
            return self.trace_bar[-1]
        weight = (time_s - self.time_s[index]) / (self.time_s[index + 1] - self.time_s[index])
        return self.trace_bar[index] + weight * (self.trace_bar[index + 1] - self.trace_bar[index])

    @property
    def pressure_bar(self) -> np.ndarray:
        return self._at(self._t0 + self._step * self.step_s)

    def stage_pressures_bar(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = self._t0 + self._step * self.step_s
        # The end as the next step will compute its start, so that the two are the same number.
        return self._at(t), self._at(t + 0.5 * self.step_s), self._at(self._t0 + (self._step + 1) * self.step_s)

    def half_step_pressures_bar(self, n_steps: int) -> np.ndarray:
        """The pressures of the next ``n_steps`` steps at every half step, (2 n_steps + 1, B, A):
        the rows :meth:`stage_pressures_bar` gives step by step, the same numbers."""
        steps = self._step + np.arange(n_steps + 1)
        starts = self._t0 + steps * self.step_s
        times = np.empty(2 * n_steps + 1)
        times[0::2] = starts
        times[1::2] = starts[:-1] + 0.5 * self.step_s
        # _interpolated for all the times at once: the same elementwise arithmetic.
        last = len(self.time_s) - 1
        index = np.searchsorted(self.time_s, times, side="right") - 1
        inside = (index >= 0) & (index < last)
        lower = np.clip(index, 0, last - 1) if last > 0 else np.zeros_like(index)
        upper = np.minimum(lower + 1, last)
        weight = np.zeros(len(times))
        weight[inside] = (times[inside] - self.time_s[lower[inside]]) / (self.time_s[upper[inside]] - self.time_s[lower[inside]])
        rows = self.trace_bar[lower] + weight[:, None, None] * (self.trace_bar[upper] - self.trace_bar[lower])
        rows[index < 0] = self.trace_bar[0]
        rows[index >= last] = self.trace_bar[-1]
        return rows

    def advance(self) -> None:
        self._step += 1

    def advance_by(self, n_steps: int) -> None:
        self._step += n_steps


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
        Where the cylinder pressures come from (:class:`CommandedPressure` or
        :class:`PrescribedPressure`); its step must equal ``step_s``.
    step_s:
        Integration step. 0.1 s reproduces the golden values within 0.05 %.

    ``hold_standing_trains`` (an attribute, False unless set) holds every train that stands still
    at the start of a step: its states no longer change (a standing disc would otherwise go on
    cooling). :func:`brakegym.applications.run_stops` sets it while it runs stops to standstill,
    so that each stop's summary ends at its own standstill and the kernel skips the standing trains.
    """

    def __init__(
        self,
        plant: Plant,
        conditions: BatchConditions,
        pressure: PressureSource,
        step_s: float = 0.1,
        extra_forces: Sequence[ExtraForce] = (),
        friction_modifiers: Sequence[FrictionModifier] = (),
        nominal_running_resistance: RunningResistance | None = None,
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
        self._constants = np.empty((kernel.N_TRAIN_CONSTANTS, n))
        self._constants[kernel.INVERSE_MASS_PER_KG] = 1.0 / self.mass_kg
        self._constants[kernel.RESISTANCE_A_N] = conditions.running_resistance_A_N
        self._constants[kernel.AMBIENT_K] = conditions.ambient_temperature_K
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
            self._constants[row] = value
        self.power_coefficient = self.to_internal(conditions.power_coefficient_per_s)
        self._parameters = kernel.plant_parameters(plant)

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
        # What the compiled kernel integrates with when no hook takes part.
        self._unit_friction_scale = np.ones(self.disc.shape[1:])
        self._no_extra_force_N = np.zeros(n)
        # The arrays of constant hooks, with the hook objects they were computed from.
        self._constant_hooks: tuple[tuple, np.ndarray, np.ndarray] | None = None

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
        self._inverse_mass[index] = 1.0 / self.mass_kg[index]
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
        return self._constants[kernel.RESISTANCE_A_N]

    @property
    def ambient_K(self) -> np.ndarray:
        return self._constants[kernel.AMBIENT_K]

    @property
    def _inverse_mass(self) -> np.ndarray:
        return self._constants[kernel.INVERSE_MASS_PER_KG]

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
        return any(not getattr(hook, "constant", False) for hook in (*self.extra_forces, *self.friction_modifiers))

    def _context(self, time_s: float, disc: np.ndarray, train: np.ndarray, clamp_force: np.ndarray) -> StageContext:
        return StageContext(
            time_s,
            train[SPEED],
            train[POSITION],
            self.mass_kg,
            disc[MU],
            clamp_force,
            disc[T_FRIC],
            disc[FRICTION_HEAT],
        )

    def _friction_scale(self, context: StageContext) -> np.ndarray | float:
        scale: np.ndarray | float = 1.0
        for modifier in self.friction_modifiers:
            scale = scale * modifier.scale(context)
        return scale

    def _extra_force_N(self, context: StageContext) -> np.ndarray:
        extra = np.zeros(self.n_trains)
        for term in self.extra_forces:
            extra = extra + term.force_N(context)
        return extra

    def _hook_arrays(self, context: StageContext) -> tuple[np.ndarray, np.ndarray]:
        """The hooks at one state as the compiled kernels take them: friction scale (A, k, B) and
        extra force (B,), contiguous float arrays."""
        scale = np.asarray(self._friction_scale(context), dtype=float)
        extra = np.asarray(self._extra_force_N(context), dtype=float)
        return (
            np.ascontiguousarray(np.broadcast_to(scale, self.disc.shape[1:])),
            np.ascontiguousarray(np.broadcast_to(extra, (self.n_trains,))),
        )

    def _step_hook_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """The hooks as the compiled step takes them at the current state: the unit arrays
        without hooks; constant hooks' arrays computed once for each set of hook objects (an
        environment replaces them when it restarts trains), as they cannot depend on the state."""
        if not (self.extra_forces or self.friction_modifiers):
            return self._unit_friction_scale, self._no_extra_force_N
        if self.has_hooks:
            clamp_force = self.clamp_force_N(np.asarray(self.pressure.pressure_bar, dtype=float))
            return self._hook_arrays(self._context(self.time_s, self.disc, self.train, clamp_force))
        hooks = (*self.extra_forces, None, *self.friction_modifiers)
        cached = self._constant_hooks
        if cached is None or len(cached[0]) != len(hooks) or any(a is not b for a, b in zip(cached[0], hooks)):
            clamp_force = self.clamp_force_N(np.asarray(self.pressure.pressure_bar, dtype=float))
            scale, extra = self._hook_arrays(self._context(self.time_s, self.disc, self.train, clamp_force))
            cached = self._constant_hooks = (hooks, scale, extra)
        return cached[1], cached[2]

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
            cylinders = self._no_cylinders
            stage_pressures = np.ascontiguousarray(self.pressure.half_step_pressures_bar(n_steps), dtype=float)
        else:
            if n_steps != 1:
                raise ValueError(f"{type(self.pressure).__name__} gives the pressures of one step at a time")
            cylinders = self._no_cylinders
            stage_pressures = np.ascontiguousarray(np.stack(self.pressure.stage_pressures_bar()), dtype=float)
        friction_scale, extra_force_N = self._step_hook_arrays()
        kernel.fused_rk4_steps(
            self._parameters, self.step_index, n_steps, self.step_s, self.power_coefficient, self._constants,
            friction_scale, extra_force_N, disc0, train0, moving0, self.hold_standing_trains, cylinders, stage_pressures,
            discs, trains, movings, stop_fraction, self.stop_time_s, clamp,
        )  # fmt: skip
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
            commanded.advanced_by(n_steps, cylinders[4])
        elif isinstance(self.pressure, PrescribedPressure):
            self.pressure.advance_by(n_steps)
        else:
            self.pressure.advance()
        self.step_index += n_steps
        self.last_step = record
        return record, all_discs, all_trains, all_movings

    @property
    def _no_cylinders(self) -> tuple[np.ndarray, ...]:
        """An empty history: the kernel then takes the stage pressures it is given."""
        n, axles = self.n_trains, self.plant.n_axles
        none = np.zeros(n)
        return np.zeros((0, n, axles)), np.zeros(n, dtype=np.int64), none, none, np.zeros((n, axles)), np.zeros((n, axles))

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
            scale, extra = self._hook_arrays(self._context(time_s, disc, train, clamp_force))
            kernel.stage_rates(
                self._parameters, disc, train, moving0, pressure, scale, extra, self.power_coefficient,
                self._constants, disc_rates[stage], train_rates[stage],
            )  # fmt: skip
            if fraction_for_next is not None:
                disc = disc0 + fraction_for_next * disc_rates[stage]
                train = train0 + fraction_for_next * train_rates[stage]
        disc1, train1 = np.empty_like(disc0), np.empty_like(train0)
        moving1 = np.empty_like(moving0)
        stop_fraction = np.empty(self.n_trains)
        kernel.finish_rk4_step(
            self._parameters, t, h, disc0, train0, moving0, self.hold_standing_trains, disc_rates, train_rates, disc1,
            train1, moving1, stop_fraction, self.stop_time_s,
        )  # fmt: skip
        record = StepRecord(t, disc0, train0, f_start, f_end, stop_fraction)
        return self._advance(record, disc1, train1, moving1)

    def _advance(self, record: StepRecord, disc1: np.ndarray, train1: np.ndarray, moving1: np.ndarray) -> StepRecord:
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

    def deceleration_at_mps2(self, disc: np.ndarray, train: np.ndarray, moving: np.ndarray, pressure_bar: np.ndarray) -> np.ndarray:
        """:meth:`deceleration_mps2` at another state of these trains (a row of
        :meth:`trajectory`), with the cylinder pressures (B, A) of that moment; hooks that
        depend on the state are evaluated at the current state, so use it without them."""
        clamp_force = np.ascontiguousarray(self.clamp_force_N(pressure_bar), dtype=float)
        scale, extra = self._step_hook_arrays()  # constant hooks too
        out = np.empty(self.n_trains)
        kernel.deceleration_mps2(self._parameters, disc, train, moving, clamp_force, scale, extra, self._constants, out)
        return out

    def state_view(self, name: str) -> np.ndarray:
        """A named state (from DISC_STATES or TRAIN_STATES), as a view."""
        if name in DISC_STATES:
            return self.disc[DISC_STATES.index(name)]
        if name in TRAIN_STATES:
            return self.train[TRAIN_STATES.index(name)]
        raise KeyError(f"unknown state {name!r}; known: {DISC_STATES + TRAIN_STATES}")


class NumpyReferenceSimulator(Simulator):
    """The same model as :class:`Simulator`, integrated with numpy array operations only.

    Readable and slow (about 60 array passes per RK4 stage): the reference the compiled kernels
    are tested against (``tests/test_kernel.py``) and benchmarked against
    (``benchmarks/bench_step.py``). Same interface and results within rounding.
    """

    def _forces(
        self, time_s: float, disc: np.ndarray, train: np.ndarray, clamp_force: np.ndarray
    ) -> tuple[np.ndarray, ...]:
        """Friction force per disc and the train forces at one state."""
        plant = self.plant
        mu = plant.friction.bounded(disc[MU])
        context = self._context(time_s, disc, train, clamp_force) if self.extra_forces or self.friction_modifiers else None
        effective = mu * self._friction_scale(context) if self.friction_modifiers else mu  # type: ignore[arg-type]
        friction_force = effective * clamp_force
        brake = brake_force_N(friction_force, plant.friction_radius_m, plant.wheel_radius_m)
        resistance = plant.running_resistance.force_N(train[SPEED], self.resistance_A_N)
        extra = self._extra_force_N(context) if self.extra_forces else np.zeros_like(brake)  # type: ignore[arg-type]
        return mu, friction_force, brake, resistance, extra

    def _rates(
        self, time_s: float, disc: np.ndarray, train: np.ndarray, clamp_force: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        plant = self.plant
        speed = train[SPEED]
        # Stages may overshoot past standstill inside the stopping step: the forces extrapolate
        # smoothly there (for the stop interpolation), the sliding speed does not go negative.
        sliding = np.maximum(speed, 0.0) * plant.radius_ratio
        mu, friction_force, brake, resistance, extra = self._forces(time_s, disc, train, clamp_force)
        friction_power = friction_force * sliding
        flows = plant.thermal.heat_flows(friction_power, disc[T_FRIC], disc[T_DISC], sliding, self.ambient_K)
        d_disc = np.empty_like(disc)
        # mu is bounded once, in _forces.
        d_disc[MU] = plant.friction.rate_of_bounded_mu_per_s(
            mu, clamp_force, sliding, disc[T_FRIC], self.power_coefficient
        )
        d_disc[T_FRIC], d_disc[T_DISC] = plant.thermal.temperature_rates_K_per_s(flows)
        d_disc[MU_DISTANCE] = mu * speed
        d_disc[FRICTION_HEAT] = flows.friction_W
        d_disc[COOLING_HEAT] = flows.surface_W + flows.ventilation_W

        total = brake + resistance + extra
        d_train = np.empty_like(train)
        d_train[SPEED] = np.where(self.moving, -total * self._inverse_mass, 0.0)
        d_train[POSITION] = speed
        d_train[BRAKE_WORK] = brake * speed
        d_train[RESISTANCE_WORK] = resistance * speed
        d_train[EXTRA_WORK] = extra * speed
        # Eq. 15 with the actual retarding force; it is only integrated after the clamp force
        # has reached 95 % of its nominal value.
        weighted_clamp = clamp_force.sum(axis=(0, 1)) * (plant.discs_per_axle * plant.radius_ratio)
        nominal_resistance = self.nominal_running_resistance.force_N(speed)
        d_train[MU_EFF_DISTANCE] = effective_mu(total, nominal_resistance, weighted_clamp) * speed
        return d_disc, d_train

    def step(self, n_steps: int = 1) -> StepRecord:
        """Advance every train by ``n_steps`` steps, one at a time."""
        if n_steps < 1:
            raise ValueError(f"n_steps = {n_steps}: must be at least 1")
        for _ in range(n_steps):
            record = self._step_once()
        return record

    def _step_once(self) -> StepRecord:
        h = self.step_s
        t = self.time_s
        p_start, p_mid, p_end = self.pressure.stage_pressures_bar()
        f_start, f_mid, f_end = (self.clamp_force_N(p) for p in (p_start, p_mid, p_end))
        disc0, train0 = self.disc, self.train

        k1d, k1t = self._rates(t, disc0, train0, f_start)
        k2d, k2t = self._rates(t + 0.5 * h, disc0 + 0.5 * h * k1d, train0 + 0.5 * h * k1t, f_mid)
        k3d, k3t = self._rates(t + 0.5 * h, disc0 + 0.5 * h * k2d, train0 + 0.5 * h * k2t, f_mid)
        k4d, k4t = self._rates(t + h, disc0 + h * k3d, train0 + h * k3t, f_end)
        disc1 = disc0 + (h / 6.0) * (k1d + 2.0 * (k2d + k3d) + k4d)
        train1 = train0 + (h / 6.0) * (k1t + 2.0 * (k2t + k3t) + k4t)

        stop_fraction = np.full(self.n_trains, np.nan)
        stopping = self.moving & (train1[SPEED] <= 0.0)
        if stopping.any():
            v0 = train0[SPEED, stopping]
            v1 = train1[SPEED, stopping]
            theta = v0 / (v0 - v1)
            stop_fraction[stopping] = theta
            # The deceleration is nearly constant over one step, so speed falls linearly to
            # zero at theta and the distance grows by the area of that triangle.
            disc1[..., stopping] = disc0[..., stopping] + theta * (disc1[..., stopping] - disc0[..., stopping])
            train1[:, stopping] = train0[:, stopping] + theta * (train1[:, stopping] - train0[:, stopping])
            train1[POSITION, stopping] = train0[POSITION, stopping] + 0.5 * v0 * theta * h
            train1[SPEED, stopping] = 0.0
            self.stop_time_s[stopping] = t + theta * h
        disc1[MU] = self.plant.friction.bounded(disc1[MU])
        if self.hold_standing_trains:
            held = ~self.moving
            disc1[..., held] = disc0[..., held]
            train1[:, held] = train0[:, held]
        record = StepRecord(t, disc0, train0, f_start, f_end, stop_fraction)
        return self._advance(record, disc1, train1, self.moving & ~stopping)

    def deceleration_mps2(self) -> np.ndarray:
        clamp_force = self.clamp_force_N(self.pressure.pressure_bar)
        _, _, brake, resistance, extra = self._forces(self.time_s, self.disc, self.train, clamp_force)
        return np.where(self.moving, (brake + resistance + extra) * self._inverse_mass, 0.0)


class StopMetrics:
    """Summaries of a stop per application (paper Eqs. 3 and 15), updated after each step.

    ``nominal_clamp_force_N`` (B, A) is the clamp force each axle is commanded to reach; the mean
    COF over distance runs from where the clamp force first reaches 95 % of it to standstill.
    Internally arrays are (axles, trains) like the simulator's.
    """

    def __init__(self, sim: Simulator, nominal_clamp_force_N: np.ndarray, threshold: float = 0.95) -> None:
        self.nominal_clamp_force_N = np.asarray(nominal_clamp_force_N, dtype=float).T.copy()  # (A, B)
        self.threshold = threshold
        axles, n = self.nominal_clamp_force_N.shape
        self.onset_position_m = np.full((axles, n), np.nan)
        self.onset_time_s = np.full((axles, n), np.nan)
        self.onset_mu_distance = np.full((axles, sim.plant.discs_per_axle, n), np.nan)
        self.train_onset_position_m = np.full(n, np.nan)
        self.train_onset_mu_eff_distance = np.full(n, np.nan)
        self.peak_friction_temperature_K = sim.disc[T_FRIC].copy()
        self.peak_disc_temperature_K = sim.disc[T_DISC].copy()

    @staticmethod
    def _crossing(start: np.ndarray, end: np.ndarray, level: np.ndarray) -> np.ndarray:
        """Fraction of the step at which a linearly varying value reaches ``level``."""
        span = end - start
        safe = np.where(span > 0, span, 1.0)
        return np.clip(np.where(span > 0, (level - start) / safe, 0.0), 0.0, 1.0)

    def update(self, sim: Simulator) -> None:
        record = sim.last_step
        assert record is not None
        np.maximum(self.peak_friction_temperature_K, sim.disc[T_FRIC], out=self.peak_friction_temperature_K)
        np.maximum(self.peak_disc_temperature_K, sim.disc[T_DISC], out=self.peak_disc_temperature_K)

        level = self.threshold * self.nominal_clamp_force_N
        force_start = record.clamp_force_start_N[:, 0, :]
        force_end = record.clamp_force_end_N[:, 0, :]
        new_axle = np.isnan(self.onset_position_m) & (self.nominal_clamp_force_N > 0) & (force_end >= level)
        if new_axle.any():
            theta = self._crossing(force_start, force_end, level)
            position = record.train_start[POSITION] + theta * (sim.train[POSITION] - record.train_start[POSITION])
            mu_distance = record.disc_start[MU_DISTANCE] + theta[:, None, :] * (
                sim.disc[MU_DISTANCE] - record.disc_start[MU_DISTANCE]
            )
            self.onset_position_m = np.where(new_axle, position, self.onset_position_m)
            self.onset_time_s = np.where(new_axle, record.time_start_s + theta * sim.step_s, self.onset_time_s)
            self.onset_mu_distance = np.where(new_axle[:, None, :], mu_distance, self.onset_mu_distance)

        total_level = level.sum(axis=0)
        total_start, total_end = force_start.sum(axis=0), force_end.sum(axis=0)
        new_train = np.isnan(self.train_onset_position_m) & (total_level > 0) & (total_end >= total_level)
        if new_train.any():
            theta = self._crossing(total_start, total_end, total_level)
            self.train_onset_position_m = np.where(
                new_train,
                record.train_start[POSITION] + theta * (sim.train[POSITION] - record.train_start[POSITION]),
                self.train_onset_position_m,
            )
            self.train_onset_mu_eff_distance = np.where(
                new_train,
                record.train_start[MU_EFF_DISTANCE]
                + theta * (sim.train[MU_EFF_DISTANCE] - record.train_start[MU_EFF_DISTANCE]),
                self.train_onset_mu_eff_distance,
            )

    def mean_mu_over_distance(self, sim: Simulator) -> np.ndarray:
        """mu_s of Eq. 3 per disc, trains x discs (B, A * k); nan where the 95 % point was never
        reached."""
        distance = sim.train[POSITION] - self.onset_position_m
        return sim.to_external((sim.disc[MU_DISTANCE] - self.onset_mu_distance) / distance[:, None, :])

    def distance_after_onset_m(self, sim: Simulator) -> np.ndarray:
        """s_2 of Eq. 3, per train: from the train's 95 % clamp-force point to standstill."""
        return sim.train[POSITION] - self.train_onset_position_m

    def effective_mu_over_distance(self, sim: Simulator) -> np.ndarray:
        """mu_s,eff: Eq. 15's mu_eff averaged over distance like Eq. 3, per train."""
        distance = sim.train[POSITION] - self.train_onset_position_m
        return (sim.train[MU_EFF_DISTANCE] - self.train_onset_mu_eff_distance) / distance
