"""Where the brake-cylinder pressures come from: commanded through the cylinders, or prescribed.

The brake-cylinder pressure is not an RK4 state: its dead time and lag are solved exactly within
each step (:mod:`brakegym.physics.pneumatics`), which keeps the pneumatic response free of step
error. A pressure source gives the pressures at the start, middle and end of the coming step, as
RK4's stages use them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

from ..physics import BrakeCylinder, WheelSlideProtectionValve
from ..physics.pneumatics import VALVE_APPLY
from . import kernel
from .state import CylinderState


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
    solved exactly. The cylinders are stepped by the compiled :func:`~.kernel.commanded_pressures`,
    here and inside the simulator's fused steps alike.
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
        self._dead_steps = np.array([c.dead_time_steps(step_s) for c in cylinders], dtype=np.int64)
        self._half_lag = np.array([c.lag_factor(0.5 * step_s) for c in cylinders], dtype=float)
        self._full_lag = np.array([c.lag_factor(step_s) for c in cylinders], dtype=float)
        self._pressure = np.broadcast_to(np.asarray(initial_pressure_bar, dtype=float), (n_trains, n_axles)).copy()
        # Ring buffer of past commands: the cylinder of train b sees the command given
        # dead_steps[b] steps ago. Before any command, the target is the initial pressure.
        self._history = np.repeat(self._pressure[None], int(self._dead_steps.max()) + 1, axis=0)
        self._step = 0
        self._command = self._pressure.copy()
        self._stages = np.empty((3, n_trains, n_axles))

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

    def stage_pressures_bar(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The pressures at the start, middle and end of the coming step (:class:`PressureSource`)."""
        stages = np.empty_like(self._stages)  # new arrays each step: the caller may keep them
        kernel.commanded_pressures(
            self._step,
            self._history,
            self._dead_steps,
            self._half_lag,
            self._full_lag,
            self._pressure,
            self._command,
            stages,
        )
        self._stages = stages
        return stages[0], stages[1], stages[2]

    def advance(self) -> None:
        self._pressure = self._stages[2]
        self._step += 1

    def kernel_state(self) -> CylinderState:
        """What the compiled steps run these cylinders from: the command history (advanced in
        place), a copy of the pressures (the kernel advances it) and the rest. See
        :meth:`advanced_by`."""
        return CylinderState(
            self._history, self._dead_steps, self._half_lag, self._full_lag, self._pressure.copy(), self._command
        )

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
        """The pressures at the start, middle and end of the coming step (:class:`PressureSource`)."""
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
        weight[inside] = (times[inside] - self.time_s[lower[inside]]) / (
            self.time_s[upper[inside]] - self.time_s[lower[inside]]
        )
        rows = self.trace_bar[lower] + weight[:, None, None] * (self.trace_bar[upper] - self.trace_bar[lower])
        rows[index < 0] = self.trace_bar[0]
        rows[index >= last] = self.trace_bar[-1]
        return rows

    def advance(self) -> None:
        self._step += 1

    def advance_by(self, n_steps: int) -> None:
        self._step += n_steps


class ValvedPressure:
    """Cylinder pressures behind wheel-slide protection valves (:class:`PressureSource`).

    The brake control's pressures come from ``supply`` (its commands set with :meth:`set_command`);
    each valve, one per axle or per bogie (``valve_of_axle`` (A,): the valve of each axle),
    dumps, holds or applies (:data:`~brakegym.physics.pneumatics.VALVE_DUMP`, ...) as set with
    :meth:`set_valves`, held over each step. The pressures are advanced in two half steps, so the
    RK4 stages get the pressures at the step's start, middle and end. With every valve applying
    the cylinders have the supply's pressures, bit for bit.
    """

    def __init__(self, supply: CommandedPressure, valve: WheelSlideProtectionValve, valve_of_axle: Sequence[int]):
        self.supply = supply
        self.valve = valve
        self.valve_of_axle = np.asarray(valve_of_axle, dtype=np.int64)
        n_trains, n_axles = supply.pressure_bar.shape
        if self.valve_of_axle.shape != (n_axles,):
            raise ValueError(f"valve_of_axle {list(valve_of_axle)}: need one valve index per axle ({n_axles})")
        self.n_valves = int(self.valve_of_axle.max()) + 1
        self.step_s = supply.step_s
        self._pressure = supply.pressure_bar.copy()
        self._valves = np.full((n_trains, self.n_valves), VALVE_APPLY, dtype=np.int64)
        self._stages: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    @property
    def pressure_bar(self) -> np.ndarray:
        return self._pressure

    @property
    def supply_bar(self) -> np.ndarray:
        """The brake control's pressure before the valves (B, A)."""
        return self.supply.pressure_bar

    @property
    def command_bar(self) -> np.ndarray:
        return self.supply.command_bar

    @property
    def valves(self) -> np.ndarray:
        """The valve commands now (B, valves)."""
        return self._valves

    def set_command(self, command_bar: np.ndarray) -> None:
        """The brake control's command per axle (B, A) (:meth:`CommandedPressure.set_command`)."""
        self.supply.set_command(command_bar)

    def set_valves(self, valves: np.ndarray) -> None:
        """Valve commands (B, valves) from now on: each VALVE_DUMP, VALVE_HOLD or VALVE_APPLY."""
        valves = np.broadcast_to(np.asarray(valves), self._valves.shape)
        if not np.isin(valves, (-1, 0, 1)).all():
            raise ValueError(f"valve commands must be -1 (dump), 0 (hold) or 1 (apply), got {np.unique(valves)}")
        self._valves = valves.astype(np.int64)

    def reset_trains(self, index: np.ndarray, pressure_bar: float = 0.0) -> None:
        """:meth:`CommandedPressure.reset_trains`, the valves of those trains back to apply."""
        self.supply.reset_trains(index, pressure_bar)
        self._pressure[index] = pressure_bar
        self._valves[index] = VALVE_APPLY

    def stage_pressures_bar(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        supply = self.supply.stage_pressures_bar()
        valve_of_axle = self._valves[:, self.valve_of_axle]
        half = 0.5 * self.step_s
        start = self._pressure.copy()
        middle = self.valve.pressure_after(start, supply[0], supply[1], valve_of_axle, half)
        end = self.valve.pressure_after(middle, supply[1], supply[2], valve_of_axle, half)
        self._stages = (start, middle, end)
        return self._stages

    def advance(self) -> None:
        if self._stages is None:
            raise RuntimeError("ValvedPressure.advance before stage_pressures_bar: no step to advance over")
        self.supply.advance()
        self._pressure = self._stages[2]
        self._stages = None
