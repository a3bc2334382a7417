"""The columns of a recording's time series (``docs/recording-format.md``): names with their
units, and the ranges of values the format accepts."""

from __future__ import annotations

import re

from ..units import ZERO_CELSIUS_K

TIME = "time_s"
SPEED = "speed_mps"
DECEL = "decel_mps2"
DISC_TEMPERATURE = "T_disc_C"
POSITION = "position_m"
PRESSURE_PREFIX = "p_c_bar_"
REQUIRED_COLUMNS = (TIME, SPEED)
OPTIONAL_CHANNELS = (DECEL, DISC_TEMPERATURE, POSITION)
# Gauge pressure range of the format: a brake cylinder never holds more than a few bar, and a
# reading outside 0..10 bar is a sensor or unit fault (psi, kPa), not a pressure.
PRESSURE_RANGE_BAR = (0.0, 10.0)
PRESSURE_COLUMN = re.compile(re.escape(PRESSURE_PREFIX) + r"(\d+)$")
# Plausible outdoor air for a brake test; outside it the value is a unit mistake (K, F).
AMBIENT_RANGE_C = (-60.0, 60.0)
ABSOLUTE_ZERO_C = -ZERO_CELSIUS_K


def pressure_column(axle: int) -> str:
    """Name of the cylinder-pressure column of 1-based ``axle``."""
    return f"{PRESSURE_PREFIX}{axle}"
