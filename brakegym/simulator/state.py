"""The simulator's packed states: which quantity each row holds.

Inside the simulator the batch is the *last* axis: the per-disc states are one array
(len(DISC_STATES), axles, discs per axle, trains) and the per-train states one array
(len(TRAIN_STATES), trains), so that numpy's inner loops and the compiled kernel's vector loops run
over the long, contiguous train axis. The row constants below are the only definition of the
layout; the compiled kernel (:mod:`.kernel`) reads the same ones. The brake cylinders' state is
:class:`CylinderState`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

# Rows of the packed per-disc state.
DISC_STATES = (
    "mu",  # dynamic coefficient of friction (Eq. 4)
    "friction_temperature_K",  # T_fric
    "disc_temperature_K",  # T_disc
    "mu_distance_m",  # integral of mu ds, for mu_s (Eq. 3)
    "friction_heat_J",  # integral of Q_fric dt: heat that entered the disc
    "cooling_heat_J",  # integral of (Q_surf + Q_vent) dt: heat given to the air
)
MU, T_FRIC, T_DISC, MU_DISTANCE, FRICTION_HEAT, COOLING_HEAT = range(len(DISC_STATES))
N_DISC_STATES = len(DISC_STATES)

# Rows of the packed per-train state.
TRAIN_STATES = (
    "speed_mps",
    "position_m",
    "brake_work_J",  # integral of F_brake v dt
    "resistance_work_J",  # integral of F_R v dt
    "extra_work_J",  # integral of the extra forces' v dt
    "mu_eff_distance_m",  # integral of mu_eff ds (Eq. 15)
)
SPEED, POSITION, BRAKE_WORK, RESISTANCE_WORK, EXTRA_WORK, MU_EFF_DISTANCE = range(len(TRAIN_STATES))
N_TRAIN_STATES = len(TRAIN_STATES)


# Rows of the packed per-axle state of the wheel-rail adhesion option (rows, axles, trains).
WHEELSET_STATES = (
    "angular_speed_rad_per_s",  # omega of the wheelset
    "slip_work_J",  # integral of F_creep (v - omega r) dt: the work of the treads sliding on the rail
)
ANGULAR_SPEED, SLIP_WORK = range(len(WHEELSET_STATES))


class CylinderState(NamedTuple):
    """The brake cylinders of a batch as the compiled kernel runs them
    (:func:`brakegym.simulator.kernel.commanded_pressures`). An empty ``history`` (H = 0) means no
    cylinders: the kernel then takes the stage pressures it is given."""

    history: np.ndarray  # (H, B, A): ring of past commands, bar
    dead_steps: np.ndarray  # (B,): each train's dead time in steps
    half_lag: np.ndarray  # (B,): exp(-dt / (2 tau)), the share of the gap left after half a step
    full_lag: np.ndarray  # (B,): exp(-dt / tau)
    pressure_bar: np.ndarray  # (B, A): the cylinder pressures now (the kernel advances them)
    command_bar: np.ndarray  # (B, A): the command given now

    @classmethod
    def none(cls, n_trains: int, n_axles: int) -> CylinderState:
        zeros = np.zeros(n_trains)
        return cls(
            np.zeros((0, n_trains, n_axles)),
            np.zeros(n_trains, dtype=np.int64),
            zeros,
            zeros,
            np.zeros((n_trains, n_axles)),
            np.zeros((n_trains, n_axles)),
        )
