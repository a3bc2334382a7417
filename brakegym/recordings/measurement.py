"""What the sensors of a recording report of the simulated true states.

The simulator is fixed-step; recordings are sampled at their own, possibly uneven, instants. The
states are integrated on the simulator's grid (:class:`GridTrajectory`) and evaluated at any
instant by interpolation that is as accurate as the integration:

- speed and position: cubic Hermite between grid points, with their known derivatives (-decel
  and speed). At the 0.2 s step the error is O(h^4), far below a speed sensor's noise; a linear
  interpolation would leave h^2/8 x jerk, up to about 0.005 m/s at brake onset;
- the step in which the train stops: the simulator's own assumption inside that step (speed
  falling linearly to zero at the interpolated stop instant), so speed, position and
  deceleration agree with what it integrated;
- deceleration and temperatures: linear (their curvature gives errors of a few mm/s^2 and
  hundredths of a kelvin at 0.2 s, well under sensor noise).

Sensor models (effects in :mod:`.effects` change them):

- speed and odometry: ``speed_scale`` x true (a wheel-diameter error scales both);
- deceleration, ``decel_source`` ``accelerometer``: specific force, decel_true - g x grade (it does
  not see the slope's gravity component while moving, and reads it at standstill), the grade of a
  line's gradient profile at the train's position included;
  ``speed``: the derivative of the measured speed, ``speed_scale`` x decel_true;
- ``T_disc_C``: the friction-surface temperature of the instrumented disc through a first-order
  lag ``temperature_lag_s`` (exact for an input linear within each step), in degC.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..effects import EffectedModel
from ..effects.hooks import GradientProfileForce, GradientSectionForce
from ..units import STANDARD_GRAVITY_MPS2, ZERO_CELSIUS_K
from .columns import DECEL, DISC_TEMPERATURE, POSITION, SPEED


@dataclass
class GridTrajectory:
    """True states of a batch on the simulator's grid. ``time_s`` (N,) from the start of the run;
    train arrays (N, B); disc arrays (N, discs, B); axle arrays (N, axles, B)."""

    time_s: np.ndarray
    speed_mps: np.ndarray
    position_m: np.ndarray
    decel_mps2: np.ndarray  # -dv/dt of the motion (gravity included), zero at standstill
    friction_temperature_K: np.ndarray
    friction_heat_J: np.ndarray  # heat that has entered each disc
    clamp_force_N: np.ndarray  # per axle (each disc unit of the axle alike)
    pressure_bar: np.ndarray  # cylinder pressure per axle
    mu: np.ndarray  # friction state of Eq. 4 (bounded)
    stop_time_s: np.ndarray  # (B,), nan where the train did not stop


def first_order_lag(time_s: np.ndarray, signal: np.ndarray, tau_s: float) -> np.ndarray:
    """Response of tau dy/dt = u - y to ``signal`` u given at ``time_s`` (first axis), exact when
    u is linear between the given instants; y starts at u (a sensor at rest with its reading).

    With a = exp(-h / tau) over a step h and u going linearly from u_k to u_k+1:
    y_k+1 = u_k+1 + a (y_k - u_k) - (u_k+1 - u_k) tau (1 - a) / h.
    """
    signal = np.asarray(signal, dtype=float)
    if tau_s < 0:
        raise ValueError(f"time constant {tau_s} s must not be negative")
    if tau_s == 0:
        return signal.copy()
    steps = np.diff(time_s)
    decay = np.exp(-steps / tau_s)
    ramp_gain = tau_s * (1.0 - decay) / steps
    lagged = np.empty_like(signal)
    lagged[0] = signal[0]
    for k in range(len(steps)):
        change = signal[k + 1] - signal[k]
        lagged[k + 1] = signal[k + 1] + decay[k] * (lagged[k] - signal[k]) - change * ramp_gain[k]
    return lagged


class MeasurementModel:
    """The channels one application's sensors report, at any instant of its run.

    ``index`` picks the application in the batch of ``grid``; ``instrumented_disc`` is 1-based
    (None: no temperature channel); ``decel_source`` None: no deceleration channel.
    """

    def __init__(
        self,
        grid: GridTrajectory,
        index: int,
        model: EffectedModel,
        decel_source: str | None,
        instrumented_disc: int | None,
    ) -> None:
        self.grid = grid
        self.index = index
        self.decel_source = decel_source
        self.instrumented_disc = instrumented_disc
        self.speed_scale = float(np.broadcast_to(model.sensors.speed_scale, (model.n_trains,))[index])
        self.temperature_lag_s = float(np.broadcast_to(model.sensors.temperature_lag_s, (model.n_trains,))[index])
        self.grade = float(np.broadcast_to(model.grade, (model.n_trains,))[index])
        # Gradients that change along the line (a known profile, a section): their forces are
        # among the extra forces.
        self.line_gradients = [
            force for force in model.extra_forces if isinstance(force, GradientProfileForce | GradientSectionForce)
        ]
        self.stop_time_s = float(grid.stop_time_s[index])
        self._speed = grid.speed_mps[:, index]
        self._position = grid.position_m[:, index]
        self._decel = grid.decel_mps2[:, index]
        if instrumented_disc is not None:
            surface_K = grid.friction_temperature_K[:, instrumented_disc - 1, index]
            self._surface_C = surface_K - ZERO_CELSIUS_K
            self._sensor_C = first_order_lag(grid.time_s, surface_K, self.temperature_lag_s) - ZERO_CELSIUS_K
        stop = self.stop_time_s
        # The step in which the train stops: v falls linearly to 0 at the stop instant.
        self._stop_step = int(np.searchsorted(grid.time_s, stop, side="left")) - 1 if np.isfinite(stop) else -1

    # -- true states -------------------------------------------------------------------------
    def kinematics(self, time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """True (speed, position, deceleration) at ``time_s`` (from the start of the run)."""
        t = np.asarray(time_s, dtype=float)
        grid_t = self.grid.time_s
        k = np.clip(np.searchsorted(grid_t, t, side="right") - 1, 0, len(grid_t) - 2)
        t0, h = grid_t[k], grid_t[k + 1] - grid_t[k]
        s = (t - t0) / h
        s2, s3 = s * s, s * s * s
        h00, h10, h01, h11 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2
        v, x, d = self._speed, self._position, self._decel
        speed = h00 * v[k] - h10 * h * d[k] + h01 * v[k + 1] - h11 * h * d[k + 1]
        position = h00 * x[k] + h10 * h * v[k] + h01 * x[k + 1] + h11 * h * v[k + 1]
        decel = d[k] + s * (d[k + 1] - d[k])
        if self._stop_step >= 0:
            in_step = k == self._stop_step
            if in_step.any():
                ks = self._stop_step
                duration = self.stop_time_s - grid_t[ks]
                constant_decel = v[ks] / duration
                elapsed = np.minimum(t[in_step], self.stop_time_s) - grid_t[ks]
                speed[in_step] = v[ks] - constant_decel * elapsed
                position[in_step] = x[ks] + v[ks] * elapsed - 0.5 * constant_decel * elapsed**2
                decel[in_step] = np.where(t[in_step] < self.stop_time_s, constant_decel, 0.0)
        return speed, position, decel

    def surface_temperature_C(self, time_s: np.ndarray) -> np.ndarray:
        """True friction-surface temperature of the instrumented disc."""
        return np.interp(time_s, self.grid.time_s, self._surface_C)

    def disc_state(self, values: np.ndarray, time_s: np.ndarray) -> np.ndarray:
        """A (N, ...) grid array of this application, linearly interpolated."""
        return np.interp(time_s, self.grid.time_s, values)

    # -- what the sensors report ---------------------------------------------------------------
    def channels(self, time_s: np.ndarray) -> dict[str, np.ndarray]:
        """The recording's channels as its sensors would report the simulation, noise-free."""
        t = np.asarray(time_s, dtype=float)
        speed, position, decel = self.kinematics(t)
        out = {SPEED: self.speed_scale * speed, POSITION: self.speed_scale * position}
        if self.decel_source == "accelerometer":
            grade = self.grade
            for line in self.line_gradients:
                grade = grade + line.grade_at(position, self.index)
            out[DECEL] = decel - STANDARD_GRAVITY_MPS2 * grade
        elif self.decel_source == "speed":
            out[DECEL] = self.speed_scale * decel
        elif self.decel_source is not None:
            raise ValueError(f"unknown decel_source {self.decel_source!r}")
        if self.instrumented_disc is not None:
            out[DISC_TEMPERATURE] = np.interp(t, self.grid.time_s, self._sensor_C)
        return out
