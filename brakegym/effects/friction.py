"""Effects on the friction of the pads: a level, wet pads, fade, and the adhesion limit on the
whole line or on a stretch of it."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from .. import config as cfg
from ..units import STANDARD_GRAVITY_MPS2, ZERO_CELSIUS_K
from .base import TRAIN_LENGTH_M, Effect, EffectedModel, Evidence, ParameterSpec, on_part_of_the_run, per_train
from .hooks import AdhesionCap, AdhesionSectionCap, ConstantFrictionFactor, FadeFactor, WetPadFactor


class FrictionLevel(Effect):
    """The pads' friction level differs from the nominal material: mu_eff = mu_scale x mu.

    The data see a level only through each recording's friction factor times the level: its
    evidence is that the recordings' factors sit off 1 together, beyond their scatter.
    """

    id = "friction_level"
    parameters = (ParameterSpec("mu_scale", "", 0.5, 1.5, 1.0, ((0.75, 0.95), (1.05, 1.25))),)
    # A set's mean friction may sit up to one sigma of mu_0 (about 3 %) off nominal.
    RELEVANT_CHANGE = 0.04
    separating_measurements = {
        "rotating_mass": "the disc temperature over a whole stop (a heavier inertia brings more energy per stop "
        "into the discs, a friction level only changes how fast) and a coasting phase (inertia slows the coasting "
        "deceleration, friction does not act there)",
        "brake_unit_failure": "a temperature sensor on a disc of the rear brake units (a failed unit stays cold, a "
        "friction level heats every disc alike)",
        "speed_sensor_scale": "the kinematic consistency of speed against an accelerometer (a wheel-diameter error "
        "scales speed and odometry, not the accelerometer) or an independent position reference",
    }

    @classmethod
    def is_relevant(cls, parameters: Mapping[str, float], evidence: Evidence) -> bool:
        return abs(parameters["mu_scale"] - 1.0) >= cls.RELEVANT_CHANGE

    @classmethod
    def screening_points(cls, evidence: Evidence) -> list[np.ndarray]:
        """The level the recordings' friction factors k_i share, as one set-wide factor s times
        scatter about 1: the s minimising sum (k_i / s - 1)^2, the prior's chi^2 (the data see
        only the products k_i s, which it keeps)."""
        k = np.asarray(evidence.friction_factors, dtype=float)
        return [np.array([float(np.sum(k**2) / np.sum(k))])]

    @classmethod
    def brake_force_share(cls, parameters: Mapping[str, float], n_discs: int) -> float:
        return float(parameters["mu_scale"])

    def apply(self, model: EffectedModel) -> None:
        model.friction_modifiers.append(ConstantFrictionFactor(per_train(self["mu_scale"], model.n_trains, "mu_scale")))


class WetPads(Effect):
    """Wet pads: friction reduced by ``initial_loss`` at the start, recovering exponentially as
    the friction heat that entered the disc grows: mu_eff = mu (1 - loss exp(-E / E_dry))."""

    id = "wet_pads"
    parameters = (
        ParameterSpec(
            "initial_loss",
            "",
            0.0,
            0.8,
            0.0,
            ((0.15, 0.5),),
            description="share of mu lost at the start",
            lower_is_physical=True,
        ),
        # exp(-E / E_dry): 0.7 and 1.7 MJ are far apart, 5 and 8 MJ nearly alike, so the energy is
        # screened on a geometric grid; a linear grid's points (1.7, 5.0, 8.3 MJ) start a fit of
        # pads that dry within 1 MJ in a second, worse valley at 5-7 MJ.
        ParameterSpec(
            "drying_energy_MJ",
            "MJ",
            0.05,
            10.0,
            None,
            ((0.2, 1.5),),
            description="heat into one disc that dries it by a factor e",
            log_grid=True,
            difference_step=1e-2,
            locates=True,
        ),
    )
    RELEVANT_LOSS = 0.08
    confirming_measurement = "more stops in the conditions of {where} (wet pads act until the pads have dried)"
    separating_measurements = {
        "thermal_fade": "stops from a low speed with a hot disc (fade depends on temperature, wet pads on the "
        "energy dissipated since the start)",
    }

    @classmethod
    def is_relevant(cls, parameters: Mapping[str, float], evidence: Evidence) -> bool:
        return parameters["initial_loss"] >= cls.RELEVANT_LOSS

    @classmethod
    def no_effect_values(cls, vehicle: cfg.Vehicle | None = None) -> dict[str, float]:
        # Without loss the drying energy is irrelevant; any value in the bounds does.
        return {"initial_loss": 0.0, "drying_energy_MJ": 1.0}

    def apply(self, model: EffectedModel) -> None:
        n = model.n_trains
        model.friction_modifiers.append(
            WetPadFactor(
                per_train(self["initial_loss"], n, "initial_loss"),
                per_train(self["drying_energy_MJ"], n, "drying_energy_MJ") * 1e6,
            )
        )


class ThermalFade(Effect):
    """Friction fades above an onset temperature of the friction surface: mu_eff = mu (1 -
    loss)^((T_fric - onset) / 100 K), i.e. ``loss_per_100K`` of mu lost per 100 K, compounded."""

    id = "thermal_fade"
    parameters = (
        ParameterSpec("onset_C", "degC", 80.0, 600.0, None, ((120.0, 250.0),), difference_step=1e-2, locates=True),
        ParameterSpec("loss_per_100K", "", 0.0, 0.6, 0.0, ((0.1, 0.4),), lower_is_physical=True),
    )
    # The share of mu a fade must take at the hottest friction surface reached, as large as a
    # relevant friction level.
    RELEVANT_LOSS = 0.04
    # Onsets screened beside the grid, as shares of the peak measured disc temperature in degC:
    # only onsets below the hottest friction surface act at all, and a grid's onsets (167, 340,
    # 513 degC) can leave a fade above 220 degC in stops that peak near 250 degC between a point
    # that fades every stop and points that fade none.
    ONSET_PEAK_SHARES = (0.65, 0.75, 0.85, 0.95)
    confirming_measurement = (
        "more stops that heat the discs as far as {where} did (the fade acts above {onset_C:.0f} degC only)"
    )

    @classmethod
    def is_relevant(cls, parameters: Mapping[str, float], evidence: Evidence) -> bool:
        """The friction it takes away at the hottest friction surface of the fitted replays. (It
        acts on the surface temperature, which runs tens of kelvin above the measured disc.)"""
        above_K = max(evidence.peak_friction_surface_C - parameters["onset_C"], 0.0)
        return 1.0 - (1.0 - parameters["loss_per_100K"]) ** (above_K / 100.0) >= cls.RELEVANT_LOSS

    @classmethod
    def screening_points(cls, evidence: Evidence) -> list[np.ndarray]:
        """Onsets at shares of the peak measured disc temperature, each with three losses."""
        if not math.isfinite(evidence.peak_disc_C):
            return []
        onsets = [evidence.peak_disc_C * share for share in cls.ONSET_PEAK_SHARES]
        return [np.array([onset, loss]) for onset in onsets for loss in cls.spec("loss_per_100K").grid(3)]

    @classmethod
    def no_effect_values(cls, vehicle: cfg.Vehicle | None = None) -> dict[str, float]:
        return {"onset_C": 300.0, "loss_per_100K": 0.0}

    def apply(self, model: EffectedModel) -> None:
        n = model.n_trains
        model.friction_modifiers.append(
            FadeFactor(
                per_train(self["onset_C"], n, "onset_C") + ZERO_CELSIUS_K,
                np.log1p(-per_train(self["loss_per_100K"], n, "loss_per_100K")),
            )
        )


class AdhesionLimit(Effect):
    """Wheel-rail adhesion limits each axle's brake force to adhesion x axle load x g, the axle
    load being the train's (gravitational) mass shared evenly by its axles."""

    id = "adhesion_limit"
    parameters = (ParameterSpec("adhesion", "", 0.02, 0.5, math.inf, ((0.05, 0.09),)),)
    order = 100
    # A cap counts when it holds the deceleration below the measured peak.
    RELEVANT_BELOW_PEAK = 0.97
    # Start points as shares of the peak measured deceleration / g (see screening_points).
    PLATEAU_SHARES = (0.80, 0.85, 0.88, 0.91, 0.94, 0.97, 1.0)
    confirming_measurement = "more stops braked as hard as {where} (the limit acts at the highest decelerations only)"

    @classmethod
    def is_relevant(cls, parameters: Mapping[str, float], evidence: Evidence) -> bool:
        return parameters["adhesion"] * STANDARD_GRAVITY_MPS2 < cls.RELEVANT_BELOW_PEAK * evidence.peak_decel_mps2

    @classmethod
    def screening_points(cls, evidence: Evidence) -> list[np.ndarray]:
        """A cap shows as the plateau of the measured deceleration, so the adhesion lies a little
        below peak deceleration / g (the cap acts on the brake force, which the rotating masses'
        inertia and running resistance turn into a slightly different deceleration). Its chi^2
        valley is about 0.005 wide in adhesion, a tenth of a grid step: a cap 0.01 too high
        leaves the emergency stops untouched, 0.01 too low stops every application short."""
        if not math.isfinite(evidence.peak_decel_mps2):
            return []
        plateau = evidence.peak_decel_mps2 / STANDARD_GRAVITY_MPS2
        return [np.array([plateau * share]) for share in cls.PLATEAU_SHARES]

    def apply(self, model: EffectedModel) -> None:
        model.friction_modifiers.append(_axle_cap(model, per_train(self["adhesion"], model.n_trains, "adhesion")))


class AdhesionSection(Effect):
    """A stretch of low adhesion (leaves, grease, wet rail on part of the line): from
    ``patch_start_m`` for ``patch_length_m`` each axle's brake force is capped at ``patch_adhesion``
    x axle load x g, as :class:`AdhesionLimit` caps it on the whole line; in metres along the
    line, as :class:`~.track.GradientSection` places a section.

    The axles are spread over the train's length (:class:`~.hooks.AdhesionSectionCap`), so the
    cap takes hold axle by axle as the train runs onto the stretch. It acts only on applications
    that brake harder than the stretch allows, and the accelerometer sees it (a gradient section
    acts on every application, and the accelerometer does not see it). Screened where the residual
    along position steps down (the train slows less on the stretch), as a section is.
    """

    id = "adhesion_section"
    parameters = (
        ParameterSpec(
            "patch_start_m",
            "m",
            0.0,
            2500.0,
            0.0,
            ((100.0, 400.0),),
            description="where the stretch begins",
            lower_is_physical=True,  # the recordings begin on it
            locates=True,
        ),
        ParameterSpec(
            "patch_length_m", "m", 50.0, 2500.0, 0.0, ((150.0, 500.0),), description="how long it is", locates=True
        ),
        ParameterSpec("patch_adhesion", "", 0.02, 0.5, math.inf, ((0.05, 0.09),)),
    )
    order = AdhesionLimit.order + 1  # it sees the whole line's cap, if any
    TRAIN_LENGTH_M = TRAIN_LENGTH_M
    # Start points as shares of the hardest measured deceleration on the stretch / g: the cap's
    # plateau there, which the rotating masses' inertia and running resistance move a little.
    PLATEAU_SHARES = (0.85, 0.9, 0.95, 1.0, 1.05, 1.1)
    grid_screened = False
    confirming_measurement = "more stops braked as hard as {where} across the stretch"
    separating_measurements = {
        "adhesion_limit": "stops braked as hard on other parts of the line (a stretch stays where it is on the line)",
    }

    @classmethod
    def is_relevant(cls, parameters: Mapping[str, float], evidence: Evidence) -> bool:
        """A cap that holds the deceleration below the measured peak, on a stretch that begins or
        ends inside the recordings (one over the whole run is the adhesion limit)."""
        start = parameters["patch_start_m"]
        caps = parameters["patch_adhesion"] * STANDARD_GRAVITY_MPS2 < (
            AdhesionLimit.RELEVANT_BELOW_PEAK * evidence.peak_decel_mps2
        )
        return caps and on_part_of_the_run(start, start + parameters["patch_length_m"], evidence)

    @classmethod
    def screening_points(cls, evidence: Evidence) -> list[np.ndarray]:
        """Where the residual along position steps down: the stretch's ends half a train length
        inside the step's edges, the adhesion at shares of the plateau of the deceleration there.
        A step up (the train slows more on the stretch) is no loss of adhesion."""
        points = []
        for stretch in evidence.stretches:
            if stretch.decel_step_mps2 >= 0.0 or not math.isfinite(stretch.peak_decel_mps2):
                continue
            start, length = stretch.section(cls.TRAIN_LENGTH_M)
            plateau = stretch.peak_decel_mps2 / STANDARD_GRAVITY_MPS2
            for share in cls.PLATEAU_SHARES:
                points.append(np.array([start, length, plateau * share]))
        return points

    def apply(self, model: EffectedModel) -> None:
        n = model.n_trains
        cap = _axle_cap(model, per_train(self["patch_adhesion"], n, "patch_adhesion"))
        start = per_train(self["patch_start_m"], n, "patch_start_m")
        start, end = model.in_run_odometry(start, start + per_train(self["patch_length_m"], n, "patch_length_m"))
        model.friction_modifiers.append(AdhesionSectionCap(cap, start, end, self.TRAIN_LENGTH_M))


def _axle_cap(model: EffectedModel, adhesion: np.ndarray) -> AdhesionCap:
    """Each axle's brake force capped at ``adhesion`` (per train) x axle load x g, the axle load
    the train's weight shared evenly by its axles; it sees the friction factors and the wheel
    brake forces already in ``model``."""
    axle_load_N = model.gravitational_mass_kg / model.plant.n_axles * STANDARD_GRAVITY_MPS2
    return AdhesionCap(
        adhesion * axle_load_N, tuple(model.friction_modifiers), model.plant, tuple(model.wheel_brake_forces)
    )
