"""Reference wheel-slide protection (WSP) controller: the rule-based logic of a brake control
unit, per axle, on the axles' own speed sensors (docs/adhesion.md).

Each control step, for each axle i with wheel speed u_i (m/s at the tread):

- the reference speed v_ref: the fastest wheel, but falling no faster than
  ``reference_deceleration_mps2`` (when every wheel slides, the fastest one is slower than the
  train), since the train speed is not measured; the variant ``reference_speed: train`` takes the
  train's true speed instead, for comparison;
- slip s_i = (v_ref - u_i) / max(v_ref, ``min_reference_speed_mps``) and the wheel's deceleration
  a_i = (u_i(t - dt) - u_i(t)) / dt;
- dump if s_i > ``dump_slip`` or a_i > ``dump_deceleration_mps2``; else hold if s_i > ``hold_slip``,
  a_i > ``hold_deceleration_mps2`` or the wheel spins back up faster than ``reacceleration_mps2``;
  else apply (the valve at rest: the cylinder refills to the brake control's pressure);
- below a reference speed of ``inactive_below_mps`` every valve is at rest: near standstill the
  slip criterion (creep over at least ``min_reference_speed_mps``) would otherwise cycle the valves
  and leave the train creeping at a few mm/s with its wheels turning.

A valve on a bogie takes the strictest command of its axles (dump before hold before apply).
Vectorised over a batch of trains: (B, A) wheel speeds in, (B, valves) commands out.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field

from .. import config as cfg
from ..physics.pneumatics import VALVE_APPLY, VALVE_DUMP, VALVE_HOLD
from ..wheel_slide import BcuMeasurement


class WspControllerConfig(cfg.StrictModel):
    """Thresholds of the reference WSP controller (``configs/agents/wsp*.yaml``)."""

    name: str
    description: str = ""
    source: str = Field(min_length=1)
    reference_speed: Literal["estimated", "train"]
    reference_deceleration_mps2: float = Field(gt=0)
    min_reference_speed_mps: float = Field(gt=0)
    dump_slip: float = Field(gt=0, lt=1)
    hold_slip: float = Field(gt=0, lt=1)
    dump_deceleration_mps2: float = Field(gt=0)
    hold_deceleration_mps2: float = Field(gt=0)
    reacceleration_mps2: float = Field(gt=0)
    # Below this reference speed the valves stay at rest, so that the brake holds the train to
    # standstill (0: active to the end).
    inactive_below_mps: float = Field(default=0.0, ge=0)


def load_wsp_config(name_or_path: str | Path = "wsp") -> WspControllerConfig:
    """``agents/<name>.yaml`` on the config search path (``wsp``, ``wsp-true-speed``), or a file."""
    path = Path(name_or_path)
    if path.suffix not in (".yaml", ".yml"):
        path = cfg.find("agents", str(name_or_path))
    config = cfg.load_file(path, WspControllerConfig)
    if not config.hold_slip < config.dump_slip:
        raise cfg.ConfigError(f"{path}: hold_slip = {config.hold_slip} must lie below dump_slip = {config.dump_slip}")
    return config


def _wheel_speeds(measurement: BcuMeasurement | np.ndarray) -> np.ndarray:
    return measurement.wheel_speed_mps if isinstance(measurement, BcuMeasurement) else measurement


class WspController:
    """The reference WSP controller for a batch of trains.

    ``valve_of_axle`` (A,): the valve each axle hangs on (:func:`brakegym.plants.valve_of_axle`);
    ``control_step_s``: the time between two calls of :meth:`valves`."""

    def __init__(self, config: WspControllerConfig, valve_of_axle: np.ndarray, control_step_s: float) -> None:
        self.config = config
        self.valve_of_axle = np.asarray(valve_of_axle, dtype=np.int64)
        self.n_valves = int(self.valve_of_axle.max()) + 1
        self.control_step_s = float(control_step_s)
        self.reference_speed_mps = np.zeros(0)
        self._previous_wheel_speed_mps = np.zeros((0, len(self.valve_of_axle)))

    @property
    def uses_train_speed(self) -> bool:
        return self.config.reference_speed == "train"

    def reset(self, measurement: BcuMeasurement | np.ndarray) -> None:
        """Start braking with the wheels at the measured speeds (a
        :class:`~brakegym.wheel_slide.BcuMeasurement`, or the wheel speeds (B, A) alone)."""
        wheels = np.asarray(_wheel_speeds(measurement), dtype=float)
        self.reference_speed_mps = wheels.max(axis=1)
        self._previous_wheel_speed_mps = wheels.copy()

    def valves(self, measurement: BcuMeasurement | np.ndarray, train_speed_mps: np.ndarray | None = None) -> np.ndarray:
        """The valve commands (B, valves) for what is measured now: a
        :class:`~brakegym.wheel_slide.BcuMeasurement` (the train speed in it only for the variant
        that is given it), or the wheel speeds (B, A) and ``train_speed_mps`` (B,)."""
        config = self.config
        if isinstance(measurement, BcuMeasurement):
            train_speed_mps = measurement.train_speed_mps
        wheels = np.asarray(_wheel_speeds(measurement), dtype=float)
        if self.uses_train_speed:
            if train_speed_mps is None:
                raise ValueError(f"WSP controller {config.name!r} uses the true train speed: pass train_speed_mps")
            self.reference_speed_mps = np.asarray(train_speed_mps, dtype=float).copy()
        else:
            floor = self.reference_speed_mps - config.reference_deceleration_mps2 * self.control_step_s
            self.reference_speed_mps = np.maximum(wheels.max(axis=1), floor)
        reference = self.reference_speed_mps[:, None]
        slip = (reference - wheels) / np.maximum(reference, config.min_reference_speed_mps)
        deceleration = (self._previous_wheel_speed_mps - wheels) / self.control_step_s
        self._previous_wheel_speed_mps = wheels.copy()
        dump = (slip > config.dump_slip) | (deceleration > config.dump_deceleration_mps2)
        hold = (
            (slip > config.hold_slip)
            | (deceleration > config.hold_deceleration_mps2)
            | (-deceleration > config.reacceleration_mps2)
        )
        per_axle = np.where(dump, VALVE_DUMP, np.where(hold, VALVE_HOLD, VALVE_APPLY))
        per_axle = np.where(reference < config.inactive_below_mps, VALVE_APPLY, per_axle)
        per_valve = np.full((len(wheels), self.n_valves), VALVE_APPLY, dtype=np.int64)
        np.minimum.at(per_valve.T, self.valve_of_axle, per_axle.T)
        return per_valve
