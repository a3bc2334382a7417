"""Reset options: values given to ``reset(options={...})`` that fix what is otherwise drawn."""

from __future__ import annotations

from typing import Any

import numpy as np

# Reset options every environment accepts (a task adds its own).
FLEET_OPTIONS = ("initial_speed_kmh", "load", "setup", "initial_disc_temperature_C")


def option_values(value: Any, n: int, name: str) -> np.ndarray:
    """A reset option given as one number or one per restarted train, as ``n`` floats."""
    array = np.asarray(value, dtype=float)
    if array.ndim == 0:
        return np.full(n, float(array))
    if array.shape != (n,):
        raise ValueError(f"reset option {name!r}: expected a number or {n} values, got shape {array.shape}")
    return array.copy()
