"""Unit conversions and physical constants, defined once.

Inside the simulator everything is SI with temperatures in kelvin (spec: "Units inside the
simulator: SI, temperatures in kelvin"); interfaces show km/h, bar and degrees Celsius, converted at
the edge with these.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np

#: 0 degC in kelvin.
ZERO_CELSIUS_K = 273.15
#: Standard gravity, m/s^2.
STANDARD_GRAVITY_MPS2 = 9.80665

Number = TypeVar("Number", float, np.ndarray)


def kmh_to_mps(speed_kmh: Number) -> Number:
    return speed_kmh / 3.6


def mps_to_kmh(speed_mps: Number) -> Number:
    return speed_mps * 3.6


def celsius_to_kelvin(temperature_C: Number) -> Number:
    return temperature_C + ZERO_CELSIUS_K


def kelvin_to_celsius(temperature_K: Number) -> Number:
    return temperature_K - ZERO_CELSIUS_K
