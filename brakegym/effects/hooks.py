"""The hooks effects put into the simulator (:mod:`brakegym.simulator.hooks`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..simulator import ExtraForce, FrictionModifier, Plant, StageContext

# A parameter's value: one number, or one per train (or per disc).
Value = float | np.ndarray


@dataclass(frozen=True)
class ConstantForce:
    """A retarding force per train that does not change during the run (a gradient)."""

    force: np.ndarray  # (B,)
    constant: ClassVar[bool] = True  # the simulator integrates it in its compiled kernel

    def force_N(self, context: StageContext) -> np.ndarray:
        return self.force


@dataclass(frozen=True)
class GradientProfileForce:
    """The force of a line's gradient that changes along the track, m g p(x) / 1000 for the
    section under the train at position x (each train its own profile; a train leads with its
    reference point, so the whole train is taken to be on one section). Per train (B, S) section
    starts, padded with +inf, and gradients in permil; ``weight_N`` (B,) is m g."""

    weight_N: np.ndarray  # (B,)
    starts_m: np.ndarray  # (B, S)
    gradient_permil: np.ndarray  # (B, S)

    def grade_at(self, position_m: np.ndarray, train: int | slice = slice(None)) -> np.ndarray:
        """Rise over run under trains ``train`` at positions ``position_m`` ((B,), or any shape
        for one train)."""
        starts, gradients = self.starts_m[train], self.gradient_permil[train]
        position = np.asarray(position_m, dtype=float)
        if starts.ndim == 1:
            section = np.maximum(np.searchsorted(starts, position, side="right") - 1, 0)
            return gradients[section] / 1000.0
        section = np.maximum((position[:, None] >= starts).sum(axis=1) - 1, 0)
        return np.take_along_axis(gradients, section[:, None], axis=1)[:, 0] / 1000.0

    def force_N(self, context: StageContext) -> np.ndarray:
        return self.weight_N * self.grade_at(context.position_m)


@dataclass(frozen=True)
class GradientSectionForce:
    """The force of one section of gradient from ``start_m`` to ``end_m`` (per train, (B,)), level
    track on either side: m g p / 1000 times the share of the train's length on the section. The
    train's weight is spread evenly over ``train_length_m`` behind its reference point, so the force
    ramps up over one train length as the train runs onto the section and down as it leaves: a
    force continuous in the section's ends, which a fit can then move by finite differences (a
    point train's force jumps between two time steps, and its derivative in the ends is zero or
    infinite)."""

    weight_N: np.ndarray  # (B,), m g
    start_m: np.ndarray  # (B,)
    end_m: np.ndarray  # (B,)
    gradient_permil: np.ndarray  # (B,)
    train_length_m: float

    def grade_at(self, position_m: np.ndarray, train: int | slice = slice(None)) -> np.ndarray:
        """Mean rise over run under trains ``train`` whose reference points are at ``position_m``
        ((B,), or any shape for one train)."""
        position = np.asarray(position_m, dtype=float)
        start, end = self.start_m[train], self.end_m[train]
        on_section = np.minimum(position, end) - np.maximum(position - self.train_length_m, start)
        return self.gradient_permil[train] / 1000.0 * np.clip(on_section, 0.0, None) / self.train_length_m

    def force_N(self, context: StageContext) -> np.ndarray:
        return self.weight_N * self.grade_at(context.position_m)


@dataclass(frozen=True)
class ConstantFrictionFactor:
    factor: Value  # scalar, (B,) or (A, k, B)
    constant: ClassVar[bool] = True

    def scale(self, context: StageContext) -> Value:
        return self.factor


@dataclass(frozen=True)
class WetPadFactor:
    """1 - loss exp(-E / E_dry), E the friction heat that has entered the disc so far."""

    initial_loss: Value
    drying_energy_J: Value

    def scale(self, context: StageContext) -> np.ndarray:
        return 1.0 - self.initial_loss * np.exp(-context.friction_heat_J / self.drying_energy_J)


@dataclass(frozen=True)
class FadeFactor:
    """(1 - loss)^(max(T_fric - onset, 0) / 100 K): the share ``loss`` is lost per 100 K above
    the onset, compounded, so the factor stays positive however hot the disc gets."""

    onset_K: Value
    log_keep_per_100K: Value  # log(1 - loss)

    def scale(self, context: StageContext) -> np.ndarray:
        excess_K = np.maximum(context.friction_temperature_K - self.onset_K, 0.0)
        return np.exp(self.log_keep_per_100K * excess_K * 0.01)


@dataclass(frozen=True)
class AdhesionCap:
    """Caps each axle's brake force at adhesion x axle load x g.

    A wheel-slide protection releases the brake to keep the wheels rolling at the adhesion limit:
    modelled as a factor on the friction force of the axle's discs (force and heat follow it; the
    friction state of Eq. 4 is driven by the clamp force as measured). It must see the factors of
    the other friction effects (``upstream``) to know the force it caps.

    ``wheel_brake_forces``: brake forces that also act through the wheels (an electrodynamic
    brake), each shared evenly by the axles (ASSUMED: the vehicle configs do not say which axles
    are motored). The limit holds their sum with the pads' force: the pads get what the wheel
    forces leave of it, and the wheel forces themselves are held at the limit
    (:meth:`capped_wheel_force_N`, :class:`WheelBrakeForceUnderAdhesion`).
    """

    limit_N: np.ndarray  # (B,), per axle
    upstream: tuple[FrictionModifier, ...]
    plant: Plant
    wheel_brake_forces: tuple[ExtraForce, ...] = ()

    def wheel_force_per_axle_N(self, context: StageContext) -> np.ndarray | float:
        """(B,): each axle's share of the wheel brake forces (0.0 without any)."""
        if not self.wheel_brake_forces:
            return 0.0
        return sum(force.force_N(context) for force in self.wheel_brake_forces) / self.plant.n_axles

    def capped_wheel_force_N(self, axle_force_N: np.ndarray, context: StageContext) -> np.ndarray:
        """(A, B): each axle's wheel brake force ``axle_force_N`` held at the limit."""
        return np.minimum(axle_force_N, self.limit_N)

    def scale(self, context: StageContext) -> np.ndarray:
        mu = self.plant.friction.bounded(context.mu)
        for modifier in self.upstream:
            mu = mu * modifier.scale(context)
        axle_force = (mu * context.clamp_force_N).sum(axis=1) * self.plant.radius_ratio  # (A, B)
        limit = np.maximum(self.limit_N - self.wheel_force_per_axle_N(context), 0.0)  # what the pads may take
        safe = np.where(axle_force > limit, axle_force, 1.0)
        return np.where(axle_force > limit, limit / safe, 1.0)[:, None, :]


@dataclass(frozen=True)
class AdhesionSectionCap:
    """Caps the brake force of the axles on a stretch of low adhesion, from ``start_m`` to
    ``end_m`` (per train, (B,)), as :class:`AdhesionCap` caps it on the whole line.

    The axles are spread evenly over ``train_length_m`` behind the train's reference point (axle
    ``a`` at ``(a + 1/2) L / A`` behind it, the leading axle first). Each axle's cap phases in and
    out over its share ``L / A`` of the train's length, so that the train's brake capacity ramps
    over one train length as it runs onto the stretch, as a section's gradient force does
    (:class:`GradientSectionForce`): a factor continuous in the stretch's ends, which a fit can move
    by finite differences.
    """

    cap: AdhesionCap  # the cap as it would act on the whole line
    start_m: np.ndarray  # (B,)
    end_m: np.ndarray  # (B,)
    train_length_m: float

    def share_on_stretch(self, position_m: np.ndarray) -> np.ndarray:
        """(A, B): how much of each axle's share of the train is on the stretch, 0..1, with the
        train's reference points at ``position_m`` (B,)."""
        n_axles = self.cap.plant.n_axles
        spacing = self.train_length_m / n_axles
        axle_m = np.asarray(position_m, dtype=float)[None, :] - spacing * (np.arange(n_axles)[:, None] + 0.5)
        front = np.minimum(axle_m + 0.5 * spacing, self.end_m)
        back = np.maximum(axle_m - 0.5 * spacing, self.start_m)
        return np.clip(front - back, 0.0, spacing) / spacing

    def capped_wheel_force_N(self, axle_force_N: np.ndarray, context: StageContext) -> np.ndarray:
        """(A, B): each axle's wheel brake force held at the limit while the axle is on the
        stretch, phased in as the pads' cap is."""
        share = self.share_on_stretch(context.position_m)
        return axle_force_N - share * (axle_force_N - self.cap.capped_wheel_force_N(axle_force_N, context))

    def scale(self, context: StageContext) -> np.ndarray:
        share = self.share_on_stretch(context.position_m)[:, None, :]
        return 1.0 - share * (1.0 - self.cap.scale(context))


@dataclass(frozen=True)
class WheelBrakeForceUnderAdhesion:
    """A brake force that acts through the wheels (an electrodynamic brake), shared evenly by the
    axles and held on each at the adhesion caps ``caps`` (:class:`AdhesionCap`,
    :class:`AdhesionSectionCap`), which give the pads what it leaves of their limit."""

    force: ExtraForce
    caps: tuple[AdhesionCap | AdhesionSectionCap, ...]
    n_axles: int

    def force_N(self, context: StageContext) -> np.ndarray:
        total = np.asarray(self.force.force_N(context), dtype=float)
        axle_force = np.broadcast_to(total / self.n_axles, (self.n_axles, total.shape[-1]))
        for cap in self.caps:
            axle_force = cap.capped_wheel_force_N(axle_force, context)
        return axle_force.sum(axis=0)
