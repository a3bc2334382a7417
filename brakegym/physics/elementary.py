"""The two elementary operations the physics formulas use beyond arithmetic.

Each formula of :mod:`brakegym.physics` is written once, as a function of scalars or numpy arrays,
and runs both as numpy code and, compiled, inside the simulator's kernel. For numpy the functions
here are numpy's own; :mod:`brakegym.simulator.kernel_math` gives the compiled code its own implementations
of the same mathematics (see there for why), so a formula calls these names rather than ``**`` or
``np.where``.
"""

from __future__ import annotations

import numpy as np


def fractional_power(base, exponent):
    """``base ** exponent`` for ``base >= 0`` (the fractional powers of Eqs. 4 and 10).

    Negative bases are outside the domain (nan in the compiled code whatever the exponent)."""
    return np.power(base, exponent)


def select(condition, value, otherwise):
    """``value`` where ``condition`` holds, else ``otherwise`` (both are evaluated)."""
    return np.where(condition, value, otherwise)
