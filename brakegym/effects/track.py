"""Effects of the line: a gradient and a running resistance other than the nominal one."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from .. import config as cfg
from ..physics import RunningResistanceLaw
from ..units import STANDARD_GRAVITY_MPS2
from .base import Effect, EffectedModel, Evidence, ParameterSpec, per_train
from .hooks import ConstantForce


class Gradient(Effect):
    """A constant track gradient: F = m g p / 1000 (the railway convention: the gradient
    resistance in N/kN equals the gradient in permil), positive uphill. The accelerometer
    measures specific force and does not see it; the speed signal does."""

    id = "gradient"
    parameters = (
        ParameterSpec(
            "gradient_permil",
            "permil",
            -40.0,
            40.0,
            0.0,
            ((-15.0, -2.0), (2.0, 15.0)),
            description="rise over run x 1000 in the direction of travel",
        ),
    )
    RELEVANT_PERMIL = 1.0
    separating_measurements = {
        "running_resistance": "an accelerometer (it does not see a slope, it does see running resistance) or "
        "coasting at several speeds (a gradient is constant, resistance grows with speed)",
        "friction_level": "coasting phases (a gradient acts without the brake) and an accelerometer",
    }

    @classmethod
    def is_relevant(cls, parameters: Mapping[str, float], evidence: Evidence) -> bool:
        return abs(parameters["gradient_permil"]) >= cls.RELEVANT_PERMIL

    def apply(self, model: EffectedModel) -> None:
        grade = per_train(self["gradient_permil"], model.n_trains, "gradient_permil") / 1000.0
        model.extra_forces.append(ConstantForce(model.gravitational_mass_kg * STANDARD_GRAVITY_MPS2 * grade))
        model.grade = model.grade + grade


class RunningResistanceEffect(Effect):
    """The running resistance differs from the vehicle's nominal one: F_R = A + B v + C v^2 with
    these coefficients replaces it (a drawn scatter of A, if any, is added by the caller)."""

    id = "running_resistance"
    parameters = (
        ParameterSpec("A_N", "N", 0.0, 20000.0, None, ((6000.0, 12000.0),)),
        ParameterSpec("B_N_per_mps", "N s/m", 0.0, 300.0, None, ((60.0, 150.0),)),
        ParameterSpec("C_N_per_mps2", "N s^2/m^2", 0.0, 30.0, None, ((8.0, 14.0),)),
    )
    # Relevant when it differs from the nominal by twice the scatter of A at a typical speed.
    RELEVANT_SPEED_MPS = 20.0
    RELEVANT_SIGMAS = 2.0

    @classmethod
    def is_relevant(cls, parameters: Mapping[str, float], evidence: Evidence) -> bool:
        nominal, v = evidence.nominal_resistance, cls.RELEVANT_SPEED_MPS
        fitted = parameters["A_N"] + parameters["B_N_per_mps"] * v + parameters["C_N_per_mps2"] * v * v
        expected = nominal.A_N + nominal.B_N_per_mps * v + nominal.C_N_per_mps2 * v * v
        return abs(fitted - expected) >= cls.RELEVANT_SIGMAS * nominal.A_sigma_N

    @classmethod
    def no_effect_values(cls, vehicle: cfg.Vehicle | None = None) -> dict[str, float]:
        if vehicle is None:
            raise ValueError("effect 'running_resistance': the no-effect values are the vehicle's nominal coefficients")
        nominal = vehicle.running_resistance
        return {"A_N": nominal.A_N, "B_N_per_mps": nominal.B_N_per_mps, "C_N_per_mps2": nominal.C_N_per_mps2}

    def apply(self, model: EffectedModel) -> None:
        n = model.n_trains
        a = per_train(self["A_N"], n, "A_N")
        b, c = self["B_N_per_mps"], self["C_N_per_mps2"]
        model.plant = dataclasses.replace(
            model.plant,
            running_resistance=RunningResistanceLaw(
                A_N=a,
                B_N_per_mps=b if np.ndim(b) == 0 else per_train(b, n, "B_N_per_mps"),
                C_N_per_mps2=c if np.ndim(c) == 0 else per_train(c, n, "C_N_per_mps2"),
            ),
        )
        model.conditions = dataclasses.replace(model.conditions, running_resistance_A_N=a)
