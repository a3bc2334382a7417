"""The diagnosis's ``adhesion_limit`` read in terms of the simulator's adhesion (docs/adhesion.md,
"One adhesion for the diagnosis and the simulator").

The effect caps each axle's brake force at adhesion x axle load x g. That is the brake force an
ideal wheel-slide protection gets out of a rail: every axle held at the peak of the rail's creep
curve (Polach's law), no axle sliding past it. So the fitted ``adhesion`` is the peak adhesion
coefficient of the rail at the vehicle's contact, as :meth:`brakegym.physics.PolachLaw.peak_adhesion`
gives it; a real WSP, cycling about the peak, uses a share of it (its utilisation), and the
diagnosis of stops braked through one fits that share of the peak.

:func:`read_adhesion` names the rail condition (``configs/rail_conditions/``) whose peak at the
vehicle's contact lies nearest the fitted adhesion, and the mu_0 that, with that condition's other
Polach parameters, gives the fitted adhesion as its peak (:meth:`~brakegym.physics.PolachLaw.with_peak_adhesion`).
The cap does not depend on speed; Polach's peak falls a little with speed (the friction falls with
the slip speed), so the reading is given at a speed, 30 m/s by default (the configs' own
``peak_adhesion``'s).
"""

from __future__ import annotations

from dataclasses import dataclass

from .. import config as cfg
from ..plants import polach_law, wheel_rail_contact
from ..units import STANDARD_GRAVITY_MPS2

#: The train speed at which a fitted adhesion is read as a rail, m/s.
READING_SPEED_MPS = 30.0


@dataclass(frozen=True)
class AdhesionReading:
    """A fitted ``adhesion_limit`` as a rail: the fitted adhesion (the rail's peak adhesion
    coefficient), the nearest rail condition and its own peak, the mu_0 of that condition's law
    that gives the fitted peak, and the contact and speed they hold at."""

    adhesion: float
    nearest_condition: str
    condition_peak_adhesion: float
    static_friction: float
    speed_mps: float
    wheel_load_N: float

    def as_dict(self) -> dict[str, object]:
        """The report's entry (``brakegym diagnose --json``, key ``adhesion_limit_rail``)."""
        return {
            "peak_adhesion": round(self.adhesion, 5),
            "nearest_rail_condition": self.nearest_condition,
            "rail_condition_peak_adhesion": round(self.condition_peak_adhesion, 5),
            "polach_static_friction": round(self.static_friction, 5),
            "speed_mps": self.speed_mps,
            "wheel_load_N": round(self.wheel_load_N, 1),
        }


def read_adhesion(
    adhesion: float,
    vehicle: cfg.Vehicle,
    mass_kg: float,
    speed_mps: float = READING_SPEED_MPS,
    conditions: list[str] | None = None,
) -> AdhesionReading:
    """The fitted ``adhesion`` of ``vehicle`` at a train mass of ``mass_kg`` read as a rail (see
    the module documentation), among the rail conditions ``conditions`` (default: every one on the
    config search path)."""
    if not 0.0 < adhesion < 1.0:
        raise ValueError(f"adhesion {adhesion}: a peak adhesion coefficient lies between 0 and 1")
    names = conditions if conditions is not None else cfg.available("rail_conditions")
    if not names:
        raise ValueError("no rail condition to read the adhesion against")
    wheel_load_N = mass_kg * STANDARD_GRAVITY_MPS2 / (2 * vehicle.n_axles)
    stiffness_N = wheel_rail_contact(vehicle).creep_stiffness_N(wheel_load_N)
    laws = {name: polach_law(cfg.load("rail_conditions", name)) for name in names}
    peaks = {name: law.peak_adhesion(speed_mps, wheel_load_N, stiffness_N)[0] for name, law in laws.items()}
    nearest = min(peaks, key=lambda name: abs(peaks[name] - adhesion))
    law = laws[nearest].with_peak_adhesion(adhesion, speed_mps, wheel_load_N, stiffness_N)
    return AdhesionReading(adhesion, nearest, peaks[nearest], law.static_friction, speed_mps, wheel_load_N)
