"""Wheel-rail adhesion: creep and Polach's creep-force law (docs/adhesion.md).

    s     = (v - u) / max(v, v_reg)                 longitudinal creep, u = omega r the wheel speed
    mu(w) = mu_0 [(1 - A) exp(-B abs(w)) + A]          friction falling with the slip speed w = v - u
    eps   = G pi a b c_11 / (4 Q mu) abs(s)            gradient of the tangential stress
    F / Q = (2 mu / pi) [k_A eps / (1 + (k_A eps)^2) + arctan(k_S eps)]   (sign of s)

O. Polach, *Creep forces in simulations of traction vehicles running on adhesion limit*, Wear 258
(2005) 992-1000, without lateral creep and spin (straight track). Q is the wheel load, a and b the
Hertz contact's semi-axes (rolling and lateral direction), G the shear modulus and c_11 Kalker's
coefficient. Braking makes s > 0 and a retarding force F > 0.

Module-level functions are the equations (scalars or arrays, every parameter explicit);
:class:`PolachLaw` and :class:`WheelRailContact` hold the parameters of a rail condition and of a
vehicle's contact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .elementary import fractional_power


def creep(speed_mps, wheel_speed_mps, regularisation_speed_mps):
    """Longitudinal creep s = (v - u) / max(v, v_reg): the slip speed over the train speed, with
    the train speed kept above ``regularisation_speed_mps`` so that s stays finite at standstill."""
    return (speed_mps - wheel_speed_mps) / np.maximum(speed_mps, regularisation_speed_mps)


def friction_coefficient(slip_speed_mps, static_friction, friction_ratio_at_infinity, friction_decay_s_per_m):
    """mu(w) = mu_0 [(1 - A) exp(-B abs(w)) + A], Polach's friction falling with the slip speed w
    (mu_0 at w = 0, mu_0 A as w grows without bound)."""
    decay = np.exp(-friction_decay_s_per_m * np.abs(slip_speed_mps))
    return static_friction * ((1.0 - friction_ratio_at_infinity) * decay + friction_ratio_at_infinity)


def contact_semi_axis_m(wheel_load_N, reference_semi_axis_m, reference_wheel_load_N):
    """A Hertz contact semi-axis at ``wheel_load_N``: it grows as the cube root of the load."""
    return reference_semi_axis_m * fractional_power(wheel_load_N * (1.0 / reference_wheel_load_N), 1.0 / 3.0)


def creep_stiffness_N(shear_modulus_Pa, semi_axis_a_m, semi_axis_b_m, kalker_c11):
    """G pi a b c_11 / 4: the tangential force per unit creep of Kalker's linear theory over 4/3
    (Polach's eps is this times abs(s) over Q mu). Depends on the contact only."""
    return 0.25 * np.pi * shear_modulus_Pa * semi_axis_a_m * semi_axis_b_m * kalker_c11


def stress_gradient(creep_, creep_stiffness_N_, wheel_load_N, friction):
    """Polach's eps = (G pi a b c_11 / 4) abs(s) / (Q mu), the gradient of the tangential stress in
    the adhesion area (dimensionless)."""
    return creep_stiffness_N_ * np.abs(creep_) / (wheel_load_N * friction)


def polach_shape(gradient, adhesion_reduction, slip_reduction):
    """k_A eps / (1 + (k_A eps)^2) + arctan(k_S eps): the share of pi / 2 of mu transmitted (0 at
    eps = 0, rising to a peak, then to pi / 2 as eps grows)."""
    reduced = adhesion_reduction * gradient
    return reduced / (1.0 + reduced * reduced) + np.arctan(slip_reduction * gradient)


def polach_shape_slope(gradient, adhesion_reduction, slip_reduction):
    """d/d eps of :func:`polach_shape` (negative past the adhesion term's peak at k_A eps = 1)."""
    reduced = adhesion_reduction * gradient
    sliding = slip_reduction * gradient
    denominator = 1.0 + reduced * reduced
    return adhesion_reduction * (1.0 - reduced * reduced) / (denominator * denominator) + slip_reduction / (
        1.0 + sliding * sliding
    )


def adhesion_coefficient(
    creep_,
    slip_speed_mps,
    wheel_load_N,
    creep_stiffness_N_,
    static_friction,
    friction_ratio_at_infinity,
    friction_decay_s_per_m,
    adhesion_reduction,
    slip_reduction,
):
    """F / Q of Polach's law: the share of the wheel load the rail transmits at creep ``creep_``
    and slip speed ``slip_speed_mps``, with the sign of the creep."""
    friction = friction_coefficient(slip_speed_mps, static_friction, friction_ratio_at_infinity, friction_decay_s_per_m)
    gradient = stress_gradient(creep_, creep_stiffness_N_, wheel_load_N, friction)
    return np.sign(creep_) * (2.0 / np.pi) * friction * polach_shape(gradient, adhesion_reduction, slip_reduction)


def creep_slope_at_fixed_friction(
    creep_,
    slip_speed_mps,
    wheel_load_N,
    creep_stiffness_N_,
    static_friction,
    friction_ratio_at_infinity,
    friction_decay_s_per_m,
    adhesion_reduction,
    slip_reduction,
):
    """d(F / Q) / ds with mu held at mu(w), clipped at zero: the stiff, stabilising part of the
    law's slope (the falling friction mu(w) is the slow part, left out)."""
    friction = friction_coefficient(slip_speed_mps, static_friction, friction_ratio_at_infinity, friction_decay_s_per_m)
    gradient = stress_gradient(creep_, creep_stiffness_N_, wheel_load_N, friction)
    slope = polach_shape_slope(gradient, adhesion_reduction, slip_reduction)
    return np.maximum((2.0 / np.pi) * creep_stiffness_N_ / wheel_load_N * slope, 0.0)


def static_friction_factor(relative_sigma, standard_normal):
    """A rail's mu_0 over its nominal, lognormal with mean 1 and relative standard deviation
    ``relative_sigma``: exp(sigma_ln z - sigma_ln^2 / 2), sigma_ln^2 = ln(1 + relative_sigma^2),
    z ``standard_normal``. Lognormal because mu_0 is positive whatever the draw, with no bound to
    choose and no truncation to renormalise (docs/adhesion.md)."""
    log_sigma = np.sqrt(np.log1p(np.square(relative_sigma)))
    return np.exp(log_sigma * standard_normal - 0.5 * log_sigma * log_sigma)


@dataclass(frozen=True)
class PolachLaw:
    """Polach's creep-force law of one rail condition (Polach 2005, Eqs. 11 and 20)."""

    static_friction: float  # mu_0, at zero slip speed
    friction_ratio_at_infinity: float  # A = mu_inf / mu_0
    friction_decay_s_per_m: float  # B
    adhesion_reduction: float  # k_A, reduces Kalker's stiffness in the adhesion area
    slip_reduction: float  # k_S, in the slip area

    def friction(self, slip_speed_mps):
        return friction_coefficient(
            slip_speed_mps, self.static_friction, self.friction_ratio_at_infinity, self.friction_decay_s_per_m
        )

    def adhesion_coefficient(self, creep_, slip_speed_mps, wheel_load_N, creep_stiffness_N_):
        """F / Q (:func:`adhesion_coefficient`)."""
        return adhesion_coefficient(
            creep_,
            slip_speed_mps,
            wheel_load_N,
            creep_stiffness_N_,
            self.static_friction,
            self.friction_ratio_at_infinity,
            self.friction_decay_s_per_m,
            self.adhesion_reduction,
            self.slip_reduction,
        )

    def creep_force_N(self, creep_, slip_speed_mps, wheel_load_N, creep_stiffness_N_):
        """Longitudinal force of one wheel on the rail, N (retarding for s > 0)."""
        return wheel_load_N * self.adhesion_coefficient(creep_, slip_speed_mps, wheel_load_N, creep_stiffness_N_)

    def creep_slope_at_fixed_friction(self, creep_, slip_speed_mps, wheel_load_N, creep_stiffness_N_):
        """d(F / Q) / ds at fixed friction (:func:`creep_slope_at_fixed_friction`)."""
        return creep_slope_at_fixed_friction(
            creep_,
            slip_speed_mps,
            wheel_load_N,
            creep_stiffness_N_,
            self.static_friction,
            self.friction_ratio_at_infinity,
            self.friction_decay_s_per_m,
            self.adhesion_reduction,
            self.slip_reduction,
        )

    def peak_adhesion(self, speed_mps, wheel_load_N, creep_stiffness_N_, max_creep=1.0, n_creeps=20001):
        """(the largest F / Q, the creep where it lies) at train speed ``speed_mps``, searched on a
        logarithmic grid of creeps up to ``max_creep`` (for reports and tests, not the simulator):
        two floats for a number, two arrays of its shape for an array of speeds."""
        creeps = np.geomspace(1e-6, max_creep, n_creeps)
        speed = np.asarray(speed_mps, dtype=float)
        grid = creeps.reshape(-1, *([1] * speed.ndim))
        coefficients = self.adhesion_coefficient(grid, grid * speed, wheel_load_N, creep_stiffness_N_)
        best = np.argmax(coefficients, axis=0)
        peak = np.take_along_axis(coefficients, best[None], axis=0)[0]
        if speed.ndim == 0:
            return float(peak), float(creeps[best])
        return peak, creeps[best]

    def with_peak_adhesion(
        self, peak_adhesion, speed_mps, wheel_load_N, creep_stiffness_N_, tolerance=1e-6, n_creeps=20001
    ) -> PolachLaw:
        """This law with the mu_0 whose :meth:`peak_adhesion` at ``speed_mps`` is
        ``peak_adhesion`` (the other parameters kept), found by bisection on mu_0 to within
        ``tolerance`` of the peak. The peak grows with mu_0: proportionally when the friction does
        not fall with the slip speed (B = 0: mu_0 then only rescales the creep axis), a little
        less when it does (a larger mu_0 moves the peak to a larger slip speed)."""
        if not 0.0 < peak_adhesion < 1.0:
            raise ValueError(f"peak_adhesion {peak_adhesion}: must lie between 0 and 1")

        def peak(static_friction: float) -> float:
            law = replace(self, static_friction=static_friction)
            return law.peak_adhesion(speed_mps, wheel_load_N, creep_stiffness_N_, n_creeps=n_creeps)[0]

        # Bracket by doubling and halving: F / Q can exceed mu_0 (the adhesion term adds up to
        # mu / pi to the slip term's 2 mu / pi arctan), so mu_0 = peak is no bound.
        low, high = 0.5 * peak_adhesion, peak_adhesion
        while peak(low) > peak_adhesion:
            low, high = 0.5 * low, low
        while peak(high) < peak_adhesion:
            low, high = high, 2.0 * high
            if high > 10.0:
                raise ValueError(f"no mu_0 up to 10 gives a peak adhesion of {peak_adhesion} at {speed_mps} m/s")
        while True:
            middle = 0.5 * (low + high)
            value = peak(middle)
            if abs(value - peak_adhesion) <= tolerance or high - low < 1e-12:
                return replace(self, static_friction=middle)
            low, high = (middle, high) if value < peak_adhesion else (low, middle)


@dataclass(frozen=True)
class RailConditioning:
    """The conditioning of a contaminated rail by the axles that run over it: each axle closes the
    share ``per_axle`` of the gap between the mu_0 it finds and the cleaned rail's,
    ``cleaned_friction_ratio`` times the contaminated one, so that axle k (0 the leading one)
    brakes on mu_0 (1 + (R - 1)(1 - (1 - c)^k)). The defaults leave every axle on mu_0 (factors
    of exactly 1). A static picture of the train's own passage (docs/adhesion.md, "Rail
    conditioning"): how much an axle cleans does not depend on whether it slides."""

    cleaned_friction_ratio: float = 1.0
    per_axle: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.cleaned_friction_ratio) and self.cleaned_friction_ratio >= 1.0):
            raise ValueError(f"cleaned_friction_ratio {self.cleaned_friction_ratio}: must be at least 1")
        if not 0.0 <= self.per_axle < 1.0:
            raise ValueError(f"per_axle {self.per_axle}: must lie in [0, 1)")

    def axle_factors(self, n_axles: int) -> np.ndarray:
        """Each axle's factor on mu_0 (n_axles,), the leading axle first."""
        cleaned = 1.0 - (1.0 - self.per_axle) ** np.arange(n_axles)
        return 1.0 + (self.cleaned_friction_ratio - 1.0) * cleaned


@dataclass(frozen=True)
class WheelRailContact:
    """The Hertz contact of a vehicle's wheel on the rail: semi-axes a (rolling direction) and b at
    a reference wheel load, scaled with the cube root of the load; Kalker's c_11 for its b / a;
    the shear modulus of steel."""

    semi_axis_a_m: float
    semi_axis_b_m: float
    reference_wheel_load_N: float
    kalker_c11: float
    shear_modulus_Pa: float

    def creep_stiffness_N(self, wheel_load_N):
        """G pi a b c_11 / 4 at ``wheel_load_N`` (:func:`creep_stiffness_N`)."""
        a = contact_semi_axis_m(wheel_load_N, self.semi_axis_a_m, self.reference_wheel_load_N)
        b = contact_semi_axis_m(wheel_load_N, self.semi_axis_b_m, self.reference_wheel_load_N)
        return creep_stiffness_N(self.shear_modulus_Pa, a, b, self.kalker_c11)


@dataclass(frozen=True)
class RailSections:
    """A line whose rail condition changes along the track: section i runs from ``starts_m[i]``
    to the next start (the last to the end of the line), with the creep-force law ``laws[i]``.
    Positions count along the track from where the simulation starts the train."""

    starts_m: tuple[float, ...]
    laws: tuple[PolachLaw, ...]

    def __post_init__(self) -> None:
        if len(self.starts_m) != len(self.laws) or not self.laws:
            raise ValueError(f"{len(self.starts_m)} section starts for {len(self.laws)} laws: need one each")
        if self.starts_m[0] != 0.0 or any(b <= a for a, b in zip(self.starts_m, self.starts_m[1:])):
            raise ValueError(f"section starts {self.starts_m}: must begin at 0 and rise")

    def section_at(self, position_m: np.ndarray) -> np.ndarray:
        """The index of the section at each of ``position_m`` (before the line's start, 0)."""
        return np.maximum(np.searchsorted(self.starts_m, position_m, side="right") - 1, 0)

    def law_at(self, position_m: np.ndarray) -> PolachLaw:
        """The law at each of ``position_m``, its parameters arrays shaped like the positions
        (before the line's start, the first section's)."""
        section = self.section_at(position_m)
        table = np.array(
            [
                [
                    law.static_friction,
                    law.friction_ratio_at_infinity,
                    law.friction_decay_s_per_m,
                    law.adhesion_reduction,
                    law.slip_reduction,
                ]
                for law in self.laws
            ]
        )
        return PolachLaw(*np.moveaxis(table[section], -1, 0))
