"""Physics of the brake, one module per model of Ehret, Hohmann & Heckmann (2022).

- :mod:`.friction`: the dynamic coefficient of friction of one disc unit (paper Eq. 4).
- :mod:`.thermal`: the two-capacity disc temperature model (paper Eqs. 5-10).
- :mod:`.mechanics`: brake force, sliding speed and running resistance (paper Eqs. 11, 12, 14).
- :mod:`.adhesion`: wheel-rail creep and Polach's creep-force law (docs/adhesion.md).
- :mod:`.load_transfer`: the axle loads' change with the deceleration, between and within bogies.
- :mod:`.pneumatics`: brake cylinder (dead time and lag) and caliper (spec Section 4).
- :mod:`.scatter`: the stochastic friction set-ups DS, MCS-100, MCS-75/25 (paper Eq. 13).

Every function works on numpy arrays that broadcast over a batch: trains along the first axis,
then axles and the discs of each axle. Nothing here integrates in time (that is the simulator's
job), and nothing here reads configs: :mod:`brakegym.plants` builds these objects from them.
"""

from .adhesion import PolachLaw, RailConditioning, RailSections, WheelRailContact, static_friction_factor
from .friction import FrictionLaw
from .load_transfer import LoadTransfer
from .mechanics import RunningResistanceLaw, brake_force_N, sliding_speed_mps
from .pneumatics import BrakeCylinder, CaliperLaw, WheelSlideProtectionValve
from .scatter import (
    FrictionDraw,
    ScatterPartition,
    StochasticFriction,
    draw_friction,
    draw_running_resistance,
    friction_from_normals,
    running_resistance_from_normals,
)
from .thermal import CooledSurface, DiscThermalModel, HeatFlows

__all__ = [
    "BrakeCylinder",
    "WheelSlideProtectionValve",
    "CaliperLaw",
    "CooledSurface",
    "DiscThermalModel",
    "FrictionDraw",
    "FrictionLaw",
    "HeatFlows",
    "LoadTransfer",
    "PolachLaw",
    "RailConditioning",
    "RailSections",
    "static_friction_factor",
    "RunningResistanceLaw",
    "ScatterPartition",
    "StochasticFriction",
    "WheelRailContact",
    "brake_force_N",
    "draw_friction",
    "draw_running_resistance",
    "friction_from_normals",
    "running_resistance_from_normals",
    "sliding_speed_mps",
]
