"""A model form for synthetic truth that differs from the fitted model the way a real train does
(``configs/model_forms/<name>.yaml``, ``brakegym synth --model-form NAME``).

- **Integration**: a much finer step than a replay's, and optionally the numpy reference
  integrator (:class:`~brakegym.simulator.reference.NumpyReferenceSimulator`) instead of the
  compiled kernel.
- **Small unmodelled forces**: a slowly varying resistance per application (wind, curves),
  F = amplitude sin(2 pi t / period + phase), amplitude and period drawn per application.
- **Effects outside the library** (no effect of :mod:`brakegym.effects` has their form):
  pad friction that depends on the contact pressure, mu x (F_clamp / F_ref)^(-exponent) on every
  disc; and an electrodynamic brake blended into some service stops, a retarding force from the
  brake command on that fades out linearly below a speed and does not heat the discs. It acts
  through the wheels, so an adhesion effect of the set holds it with the pads' force
  (:attr:`brakegym.effects.base.EffectedModel.wheel_brake_forces`; shared evenly by the axles,
  ASSUMED: the vehicle configs do not say which are motored).

What was drawn goes to the set's key (:func:`key_entry`), the out-of-library effects under
``out_of_library`` with the recordings they act on: a diagnosis must not name a library effect for
them. Loading validates; errors name the file, the field and the value.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import Field, model_validator

from .. import config as cfg
from ..simulator import Simulator, StageContext
from ..simulator.reference import NumpyReferenceSimulator
from ..units import kmh_to_mps

KIND = "model_forms"
# Command instants are drawn on a 0.1 s grid: the truth step must divide it.
COMMAND_GRID_S = 0.1


class SlowResistance(cfg.StrictModel):
    """A slowly varying retarding force per application (wind, curves), not in the model."""

    amplitude_range_N: tuple[float, float] = Field(default=(500.0, 2000.0))
    period_range_s: tuple[float, float] = Field(default=(30.0, 120.0))

    @model_validator(mode="after")
    def _ordered(self) -> SlowResistance:
        for name in ("amplitude_range_N", "period_range_s"):
            low, high = getattr(self, name)
            if not 0 <= low <= high or (name == "period_range_s" and low <= 0):
                raise ValueError(f"{name} = [{low}, {high}]: need 0 <= low <= high (a period above 0)")
        return self


class ContactPressureFriction(cfg.StrictModel):
    """Pad friction falling with the contact pressure: mu x (F_clamp / F_ref)^(-exponent).

    F_ref defaults to the friction model's own reference clamp force (40 kN, the material's
    ``reference_clamp_force_N``; Table 4's stops ran at 33-45 kN): there the law leaves the
    model's friction as it is. A lower F_ref multiplies every stop by a constant as well,
    (40 kN / F_ref)^(-exponent), which is a friction level of the library and not physics
    outside it: at 20 kN every recording's friction is about 7 % low."""

    exponent: float = Field(default=0.1, ge=0, le=0.5)
    reference_clamp_force_kN: float = Field(default=40.0, gt=0)
    # Below this share of F_ref the factor is held (a pad barely touching has no contact law).
    floor_share: float = Field(default=0.1, gt=0, le=1)


class ElectrodynamicBrake(cfg.StrictModel):
    """A retarding force blended into some service stops (an ED brake), not in the model."""

    share_of_service_stops: float = Field(default=0.5, ge=0, le=1)
    force_kN: float = Field(default=20.0, ge=0)
    fade_out_speed_kmh: float = Field(default=10.0, gt=0)  # the force falls linearly to 0 below it


class ModelForm(cfg.StrictModel):
    """``configs/model_forms/<name>.yaml`` (see the module documentation)."""

    name: str
    description: str = ""
    truth_step_s: float = Field(default=0.01, gt=0, le=0.05)
    integrator: Literal["kernel", "reference"] = "kernel"
    slow_resistance: SlowResistance | None = None
    contact_pressure_friction: ContactPressureFriction | None = None
    electrodynamic_brake: ElectrodynamicBrake | None = None

    @model_validator(mode="after")
    def _step_on_the_command_grid(self) -> ModelForm:
        steps = COMMAND_GRID_S / self.truth_step_s
        if abs(steps - round(steps)) > 1e-9:
            raise ValueError(
                f"truth_step_s = {self.truth_step_s}: must divide {COMMAND_GRID_S} s (brake commands are drawn on that "
                "grid)"
            )
        return self

    @property
    def simulator_class(self) -> type[Simulator]:
        return NumpyReferenceSimulator if self.integrator == "reference" else Simulator


def load_model_form(name_or_path: str | Path) -> ModelForm:
    """A model form by name (``configs/model_forms/<name>.yaml`` on the config search path) or from
    a YAML file; errors name the file, the field and the value."""
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.is_file():
        return cfg.load_file(path, ModelForm)
    return cfg.load_file(cfg.find(KIND, str(name_or_path)), ModelForm)


# ------------------------------------------------------------------------------------------------
# The hooks (brakegym.simulator.hooks) that put the model form into a truth simulation


@dataclass(frozen=True)
class SlowlyVaryingForce:
    """amplitude sin(2 pi t / period + phase) per train, N."""

    amplitude_N: np.ndarray  # (B,)
    period_s: np.ndarray
    phase_rad: np.ndarray

    def force_N(self, context: StageContext) -> np.ndarray:
        return self.amplitude_N * np.sin(2 * np.pi * context.time_s / self.period_s + self.phase_rad)


@dataclass(frozen=True)
class ContactPressureFactor:
    """(max(F_clamp, floor) / F_ref)^(-exponent) on each disc."""

    exponent: float
    reference_clamp_force_N: float
    floor_N: float

    def scale(self, context: StageContext) -> np.ndarray:
        clamp = np.maximum(context.clamp_force_N, self.floor_N)
        return (clamp / self.reference_clamp_force_N) ** (-self.exponent)


@dataclass(frozen=True)
class BlendedBrakeForce:
    """force from the command instant on, times min(v / v_fade, 1), on the trains that have it."""

    force_N_per_train: np.ndarray  # (B,), 0 where the stop has none
    command_time_s: np.ndarray  # (B,)
    fade_out_speed_mps: float

    def force_N(self, context: StageContext) -> np.ndarray:
        active = context.time_s >= self.command_time_s
        fade = np.clip(context.speed_mps / self.fade_out_speed_mps, 0.0, 1.0)
        return np.where(active, self.force_N_per_train * fade, 0.0)


@dataclass
class DrawnModelForm:
    """What a model form drew for a set's applications, and the hooks that put it into a run."""

    form: ModelForm
    slow_amplitude_N: np.ndarray
    slow_period_s: np.ndarray
    slow_phase_rad: np.ndarray
    electrodynamic: np.ndarray  # (B,) bool: the stop has an ED brake blended in

    def extra_forces(self) -> list:
        """The forces on the train that do not act through the wheels."""
        if self.form.slow_resistance is None:
            return []
        return [SlowlyVaryingForce(self.slow_amplitude_N, self.slow_period_s, self.slow_phase_rad)]

    def wheel_brake_forces(self, command_time_s: np.ndarray) -> list:
        """The brake forces that act through the wheels, as the pads' do: an adhesion cap holds
        them too (:attr:`brakegym.effects.base.EffectedModel.wheel_brake_forces`)."""
        ed = self.form.electrodynamic_brake
        if ed is None or not self.electrodynamic.any():
            return []
        force = np.where(self.electrodynamic, ed.force_kN * 1e3, 0.0)
        return [BlendedBrakeForce(force, command_time_s, kmh_to_mps(ed.fade_out_speed_kmh))]

    def friction_modifiers(self) -> list:
        law = self.form.contact_pressure_friction
        if law is None:
            return []
        reference = law.reference_clamp_force_kN * 1e3
        return [ContactPressureFactor(law.exponent, reference, law.floor_share * reference)]


def draw_model_form(form: ModelForm, rng: np.random.Generator, brake_modes: list[str]) -> DrawnModelForm:
    """Each application's draws: every number is drawn whatever the form switches on, so the
    stream does not depend on it."""
    n = len(brake_modes)
    slow = form.slow_resistance or SlowResistance()
    amplitude = rng.uniform(*slow.amplitude_range_N, size=n)
    period = rng.uniform(*slow.period_range_s, size=n)
    phase = rng.uniform(0.0, 2 * np.pi, size=n)
    share = form.electrodynamic_brake.share_of_service_stops if form.electrodynamic_brake is not None else 0.0
    electrodynamic = (rng.random(n) < share) & (np.asarray(brake_modes) == "service")
    return DrawnModelForm(form, np.round(amplitude, 1), np.round(period, 2), np.round(phase, 4), electrodynamic)


def key_entry(drawn: DrawnModelForm, stems: list[str]) -> dict[str, Any]:
    """The key's ``model_form``: the form, and the out-of-library effects with where they act."""
    form = drawn.form
    out_of_library = []
    if form.contact_pressure_friction is not None:
        out_of_library.append(
            {
                "id": "contact_pressure_friction",
                "parameters": form.contact_pressure_friction.model_dump(mode="json"),
                "recordings": list(stems),
            }
        )
    if form.electrodynamic_brake is not None and drawn.electrodynamic.any():
        out_of_library.append(
            {
                "id": "electrodynamic_brake",
                "parameters": form.electrodynamic_brake.model_dump(mode="json"),
                "recordings": [stem for stem, on in zip(stems, drawn.electrodynamic) if on],
            }
        )
    unmodelled = []
    if form.slow_resistance is not None:
        unmodelled.append({"id": "slow_resistance", "parameters": form.slow_resistance.model_dump(mode="json")})
    return {
        "config": form.model_dump(mode="json"),
        "out_of_library": out_of_library,
        "unmodelled_forces": unmodelled,
    }


def truth_row_entry(drawn: DrawnModelForm, index: int) -> dict[str, Any]:
    """What the key records of application ``index``'s model form."""
    entry: dict[str, Any] = {}
    if drawn.form.slow_resistance is not None:
        entry["slow_resistance"] = {
            "amplitude_N": float(drawn.slow_amplitude_N[index]),
            "period_s": float(drawn.slow_period_s[index]),
            "phase_rad": float(drawn.slow_phase_rad[index]),
        }
    if drawn.form.electrodynamic_brake is not None:
        entry["electrodynamic_brake"] = bool(drawn.electrodynamic[index])
    return entry
