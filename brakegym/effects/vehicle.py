"""Effects of the vehicle: rotating masses and failed brake units."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from .base import Effect, EffectedModel, Evidence, ParameterSpec, per_train
from .hooks import ConstantFrictionFactor


class RotatingMass(Effect):
    """Rotating parts add inertia: the train accelerates as m (1 + mass_factor), while gravity
    and axle loads act on m."""

    id = "rotating_mass"
    parameters = (ParameterSpec("mass_factor", "", -0.2, 0.3, 0.0, ((0.04, 0.15),)),)
    RELEVANT_FACTOR = 0.03
    separating_measurements = {"brake_unit_failure": "a temperature sensor on a rear disc, or a coasting phase"}

    @classmethod
    def is_relevant(cls, parameters: Mapping[str, float], evidence: Evidence) -> bool:
        return abs(parameters["mass_factor"]) >= cls.RELEVANT_FACTOR

    def apply(self, model: EffectedModel) -> None:
        factor = 1.0 + per_train(self["mass_factor"], model.n_trains, "mass_factor")
        model.conditions = dataclasses.replace(model.conditions, mass_kg=np.asarray(model.conditions.mass_kg) * factor)


class BrakeUnitFailure(Effect):
    """``failed_units`` disc units give no force (and no heat). Which ones: the highest-numbered
    units in the simulator's (and the recording's ``instrumented_disc``) numbering, axle by axle
    from axle 1 and the discs of each axle in turn; i.e. from the rear of the train. On
    ``emu_8axle`` one failed unit is disc 16, two are discs 15 and 16."""

    id = "brake_unit_failure"
    parameters = (ParameterSpec("failed_units", "units", 0.0, 8.0, 0.0, ((1.0, 4.0),), integer=True),)

    @classmethod
    def is_relevant(cls, parameters: Mapping[str, float], evidence: Evidence) -> bool:
        return parameters["failed_units"] >= 1

    @classmethod
    def brake_force_share(cls, parameters: Mapping[str, float], n_discs: int) -> float:
        return (n_discs - parameters["failed_units"]) / n_discs

    def apply(self, model: EffectedModel) -> None:
        plant = model.plant
        failed = per_train(self["failed_units"], model.n_trains, "failed_units")
        if np.any(failed > plant.n_discs):
            raise ValueError(
                f"effect 'brake_unit_failure': {failed.max():g} failed units, but {plant.name!r} has {plant.n_discs}"
            )
        disc_number = np.arange(plant.n_discs).reshape(plant.disc_shape)[..., None]  # (A, k, 1)
        working = (disc_number < plant.n_discs - failed).astype(float)  # (A, k, B)
        model.friction_modifiers.append(ConstantFrictionFactor(working))
