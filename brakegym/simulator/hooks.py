"""Extension hooks: new physics without a change of the core loop.

- ``extra_forces``: objects with ``force_N(context) -> (trains,)`` retarding forces (a gradient);
- ``friction_modifiers``: objects with ``scale(context) -> factor`` on the effective coefficient
  of friction of each disc (wet pads, fade, a friction level error); the friction state of Eq. 4
  itself is untouched.

The ``context`` handed to them is a :class:`StageContext`. A hook whose class sets
``constant = True`` promises that its value does not depend on the context: the simulator then
evaluates it once and integrates it in the compiled kernel, instead of calling it at every RK4
stage (:class:`HookArrays`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .state import FRICTION_HEAT, MU, POSITION, SPEED, T_FRIC


@dataclass
class StageContext:
    """What an extension sees at one RK4 stage. Arrays are views: do not write to them."""

    time_s: float
    speed_mps: np.ndarray  # (B,)
    position_m: np.ndarray  # (B,)
    mass_kg: np.ndarray  # (B,)
    mu: np.ndarray  # (A, k, B), the friction state of Eq. 4
    clamp_force_N: np.ndarray  # (A, 1, B)
    friction_temperature_K: np.ndarray  # (A, k, B)
    friction_heat_J: np.ndarray  # (A, k, B), heat that entered each disc so far


def stage_context(
    time_s: float, disc: np.ndarray, train: np.ndarray, mass_kg: np.ndarray, clamp_force_N: np.ndarray
) -> StageContext:
    """The context of the packed states ``disc`` and ``train`` (:mod:`.state`) at ``time_s``."""
    return StageContext(
        time_s, train[SPEED], train[POSITION], mass_kg, disc[MU], clamp_force_N, disc[T_FRIC], disc[FRICTION_HEAT]
    )


class ExtraForce(Protocol):
    """A force term (``constant = True`` on its class: see the module documentation)."""

    def force_N(self, context: StageContext) -> np.ndarray:
        """Retarding force on each train, N, shape (B,); negative pushes the train on."""
        ...


class FrictionModifier(Protocol):
    """A factor on friction (``constant = True`` on its class: see the module documentation)."""

    def scale(self, context: StageContext) -> np.ndarray | float:
        """Factor on each disc's effective coefficient of friction, broadcastable to (A, k, B)."""
        ...


def is_constant(hook: ExtraForce | FrictionModifier) -> bool:
    """Whether a hook promises not to depend on the state or time."""
    return getattr(hook, "constant", False)


def friction_scale(modifiers: Sequence[FrictionModifier], context: StageContext) -> np.ndarray | float:
    """The product of every modifier's factor."""
    scale: np.ndarray | float = 1.0
    for modifier in modifiers:
        scale = scale * modifier.scale(context)
    return scale


def extra_force_N(forces: Sequence[ExtraForce], context: StageContext, n_trains: int) -> np.ndarray:
    """The sum of every extra force, (B,)."""
    extra = np.zeros(n_trains)
    for term in forces:
        extra = extra + term.force_N(context)
    return extra


class HookArrays:
    """The hooks as the compiled kernels take them: a friction scale per disc (A, k, B) and an
    extra force per train (B,), contiguous float arrays.

    Without hooks these are ones and zeros; constant hooks' arrays are computed once for each set of
    hook objects (an environment replaces the hooks when it restarts trains) and kept.
    """

    def __init__(self, disc_shape: tuple[int, int, int]) -> None:
        self.disc_shape = disc_shape
        self.n_trains = disc_shape[-1]
        self.unit_friction_scale = np.ones(disc_shape)
        self.no_extra_force_N = np.zeros(self.n_trains)
        self._constant: tuple[tuple, np.ndarray, np.ndarray] | None = None

    def at(
        self, forces: Sequence[ExtraForce], modifiers: Sequence[FrictionModifier], context: StageContext
    ) -> tuple[np.ndarray, np.ndarray]:
        """The hooks evaluated at ``context``."""
        scale = np.asarray(friction_scale(modifiers, context), dtype=float)
        extra = np.asarray(extra_force_N(forces, context, self.n_trains), dtype=float)
        return (
            np.ascontiguousarray(np.broadcast_to(scale, self.disc_shape)),
            np.ascontiguousarray(np.broadcast_to(extra, (self.n_trains,))),
        )

    def for_step(
        self, forces: Sequence[ExtraForce], modifiers: Sequence[FrictionModifier], context_now
    ) -> tuple[np.ndarray, np.ndarray]:
        """The arrays a whole step integrates with: the unit arrays without hooks, the constant
        hooks' (cached), or every hook at the current state (``context_now()`` builds it)."""
        if not (forces or modifiers):
            return self.unit_friction_scale, self.no_extra_force_N
        if not all(is_constant(hook) for hook in (*forces, *modifiers)):
            return self.at(forces, modifiers, context_now())
        hooks = (*forces, None, *modifiers)
        cached = self._constant
        if cached is None or len(cached[0]) != len(hooks) or any(a is not b for a, b in zip(cached[0], hooks)):
            scale, extra = self.at(forces, modifiers, context_now())
            cached = self._constant = (hooks, scale, extra)
        return cached[1], cached[2]
