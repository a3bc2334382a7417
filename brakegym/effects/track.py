"""Effects of the line: a gradient, a section of gradient on part of the line, and a running
resistance other than the nominal one."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from .. import config as cfg
from ..physics import RunningResistanceLaw
from ..units import STANDARD_GRAVITY_MPS2
from .base import TRAIN_LENGTH_M, Effect, EffectedModel, Evidence, ParameterSpec, on_part_of_the_run, per_train
from .hooks import ConstantForce, GradientSectionForce


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


class GradientSection(Effect):
    """A gradient on part of the line: level track, then ``section_gradient_permil`` from
    ``section_start_m`` for ``section_length_m``, then level again, in metres along the line: from
    each recording's ``line_position_m`` where the recordings carry it, else from each one's first
    sample (the recordings of the set then start at the same place of the line;
    :mod:`brakegym.recordings.metadata`). The gradient is the rise over run towards growing
    positions: a recording run the other way (``line_direction``) meets it with the other sign.

    The force is the gradient's m g p / 1000 times the share of the train on the section, the
    train's weight spread over ``TRAIN_LENGTH_M`` (:class:`~.hooks.GradientSectionForce`). The
    accelerometer does not see it. The diagnosis screens it only where the residual along
    position shows a step (:attr:`~brakegym.effects.base.Evidence.stretches`): a grid over
    start, length and gradient would cost a batch of simulations on every set for an effect that
    the residual locates.
    """

    id = "gradient_section"
    parameters = (
        ParameterSpec(
            "section_start_m",
            "m",
            0.0,
            2500.0,
            0.0,
            ((100.0, 400.0),),
            description="where the section begins",
            lower_is_physical=True,  # the recordings begin on it
            locates=True,
        ),
        ParameterSpec(
            "section_length_m", "m", 50.0, 2500.0, 0.0, ((250.0, 600.0),), description="how long it is", locates=True
        ),
        ParameterSpec(
            "section_gradient_permil",
            "permil",
            -40.0,
            40.0,
            0.0,
            ((-15.0, -4.0), (4.0, 15.0)),
            description="rise over run x 1000 towards growing positions along the line",
        ),
    )
    TRAIN_LENGTH_M = TRAIN_LENGTH_M
    grid_screened = False
    # A section from the line origin to beyond the recordings' reach is the whole-line gradient:
    # where the data hold that, the gradient's one parameter is named.
    extends = Gradient.id
    separating_measurements = {
        "gradient": "recordings that start at other places of the line (a section stays where it is on the line)",
        "running_resistance": "an accelerometer (it does not see a slope, it does see running resistance)",
        "adhesion_section": "an accelerometer (it does not see a slope, it does see a brake force lost to "
        "adhesion) or applications braked gently across the stretch (a slope acts on them, low adhesion does not)",
    }

    @classmethod
    def is_relevant(cls, parameters: Mapping[str, float], evidence: Evidence) -> bool:
        """A section of at least ``Gradient.RELEVANT_PERMIL`` that begins or ends inside the
        recordings by a train length: one that covers every recording from end to end is the
        constant gradient, and the gradient effect says so."""
        start, end = parameters["section_start_m"], parameters["section_start_m"] + parameters["section_length_m"]
        return abs(parameters["section_gradient_permil"]) >= Gradient.RELEVANT_PERMIL and on_part_of_the_run(
            start, end, evidence
        )

    @classmethod
    def screening_points(cls, evidence: Evidence) -> list[np.ndarray]:
        """The section that would leave each located step: its ends half a train length inside
        the step's edges, its gradient the step's deceleration over g."""
        points = []
        for stretch in evidence.stretches:
            start, length = stretch.section(cls.TRAIN_LENGTH_M)
            points.append(np.array([start, length, stretch.gradient_permil]))
        return points

    def apply(self, model: EffectedModel) -> None:
        model.extra_forces.append(_section_force(model, self, "section"))


class GradientSections(Effect):
    """A profile of two sections of gradient, level track elsewhere: each as a
    :class:`GradientSection` (``first_section_*``, ``second_section_*``; where they overlap their
    gradients add). Screened only where the residual along position locates two steps, the second
    in what the first leaves (:attr:`~brakegym.effects.base.Evidence.profile_stretches`): the
    first section at the nearer of them. Where the data hold one section only, the single
    section's fewer parameters win by the same rules."""

    id = "gradient_sections"
    extends = GradientSection.id  # where the data hold one section, that one is named
    parameters = tuple(
        ParameterSpec(
            f"{which}_{spec.name}",
            spec.unit,
            spec.lower,
            spec.upper,
            spec.no_effect,
            ranges,
            description=f"{spec.description} ({which} section)",
            lower_is_physical=spec.lower_is_physical,
            locates=spec.locates,
        )
        for which, section_ranges in (
            ("first", (((100.0, 300.0),), ((200.0, 400.0),), ((-15.0, -4.0), (4.0, 15.0)))),
            ("second", (((650.0, 850.0),), ((200.0, 400.0),), ((-15.0, -4.0), (4.0, 15.0)))),
        )
        for spec, ranges in zip(GradientSection.parameters, section_ranges, strict=True)
    )
    TRAIN_LENGTH_M = TRAIN_LENGTH_M
    grid_screened = False
    separating_measurements = {
        "gradient_section": "recordings that brake across both sections (each at its place on the line)",
    }

    @classmethod
    def is_relevant(cls, parameters: Mapping[str, float], evidence: Evidence) -> bool:
        """Both sections relevant as single sections are (:meth:`GradientSection.is_relevant`)."""
        return all(
            GradientSection.is_relevant(
                {spec.name: parameters[f"{which}_{spec.name}"] for spec in GradientSection.parameters}, evidence
            )
            for which in ("first", "second")
        )

    @classmethod
    def screening_points(cls, evidence: Evidence) -> list[np.ndarray]:
        """The two sections that would leave the two located steps, the nearer first."""
        if len(evidence.profile_stretches) != 2:
            return []
        sections = sorted(evidence.profile_stretches, key=lambda stretch: stretch.start_m)
        point = []
        for stretch in sections:
            start, length = stretch.section(cls.TRAIN_LENGTH_M)
            point += [start, length, stretch.gradient_permil]
        return [np.array(point)]

    def apply(self, model: EffectedModel) -> None:
        model.extra_forces += [
            _section_force(model, self, "first_section"),
            _section_force(model, self, "second_section"),
        ]


def _section_force(model: EffectedModel, effect: Effect, prefix: str) -> GradientSectionForce:
    """The force of the section whose parameters are ``<prefix>_start_m``, ``<prefix>_length_m``
    and ``<prefix>_gradient_permil`` of ``effect``, placed on each run by its line position."""
    n = model.n_trains
    start = per_train(effect[f"{prefix}_start_m"], n, f"{prefix}_start_m")
    start, end = model.in_run_odometry(start, start + per_train(effect[f"{prefix}_length_m"], n, f"{prefix}_length_m"))
    # Rise over run along growing line positions: a run the other way climbs it as a fall.
    gradient = (
        per_train(effect[f"{prefix}_gradient_permil"], n, f"{prefix}_gradient_permil") * model.line_direction_sign
    )
    return GradientSectionForce(
        model.gravitational_mass_kg * STANDARD_GRAVITY_MPS2, start, end, gradient, TRAIN_LENGTH_M
    )


class RunningResistanceEffect(Effect):
    """The running resistance differs from the vehicle's nominal one: F_R = A + B v + C v^2 with
    these coefficients replaces it (a drawn scatter of A, if any, is added by the caller)."""

    id = "running_resistance"
    parameters = (
        ParameterSpec("A_N", "N", 0.0, 20000.0, None, ((6000.0, 12000.0),), lower_is_physical=True),
        ParameterSpec("B_N_per_mps", "N s/m", 0.0, 300.0, None, ((60.0, 150.0),), lower_is_physical=True),
        ParameterSpec("C_N_per_mps2", "N s^2/m^2", 0.0, 30.0, None, ((8.0, 14.0),), lower_is_physical=True),
    )
    # Relevant when it differs from the nominal by twice the scatter of A at a typical speed.
    RELEVANT_SPEED_MPS = 20.0
    RELEVANT_SIGMAS = 2.0

    @classmethod
    def is_relevant(cls, parameters: Mapping[str, float], evidence: Evidence) -> bool:
        nominal = evidence.nominal_resistance
        return abs(cls.resistance_shift_N(parameters, nominal)) >= cls.RELEVANT_SIGMAS * nominal.A_sigma_N

    @classmethod
    def resistance_shift_N(cls, parameters: Mapping[str, float], nominal: cfg.RunningResistance) -> float:
        """The coefficients' resistance less the nominal one at ``RELEVANT_SPEED_MPS``, N."""
        v = cls.RELEVANT_SPEED_MPS
        fitted = parameters["A_N"] + parameters["B_N_per_mps"] * v + parameters["C_N_per_mps2"] * v * v
        return fitted - (nominal.A_N + nominal.B_N_per_mps * v + nominal.C_N_per_mps2 * v * v)

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
