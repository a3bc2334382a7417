"""Stochastic friction (paper Eq. 13 and Sec. 6.2; spec Section 5).

    mu_0 ~ N(mu_0_nominal, sigma_mu0),   a ~ N(a_nominal, sigma_a)

One draw per simulated brake application and disc. A set-up splits each sigma into a global part,
drawn once per application and shared by its discs, and an individual part drawn per disc around
it (the paper's partition of sigma, not of variance):

- DS: no scatter (fractions 0, 0);
- MCS-100: independent draws per disc (0, 1);
- MCS-75/25: global 0.75 sigma, individual 0.25 sigma;
- shared: one draw per application for all discs (1, 0), a single-disc equivalent.

The running resistance's A scatters per application in the set-ups that say so. The temperature
model has no scatter (paper Sec. 5).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class StochasticFriction:
    """The scatter of paper Eq. 13 for one pad material: mu_0 ~ N(initial_mu, initial_mu_sigma)
    and a ~ N(power_coefficient_per_s, power_coefficient_sigma_per_s); a drawn mu_0 must lie in
    [mu_min, mu_max]. ``material`` names the material in error messages."""

    initial_mu: float
    initial_mu_sigma: float
    power_coefficient_per_s: float
    power_coefficient_sigma_per_s: float
    mu_min: float
    mu_max: float
    material: str = ""


@dataclass(frozen=True)
class ScatterPartition:
    """A Monte-Carlo set-up (spec Section 5): the fractions of each sigma drawn globally per
    application and individually per disc, and whether the running resistance's A scatters."""

    global_fraction: float
    individual_fraction: float
    resistance_scatter: bool


@dataclass(frozen=True)
class FrictionDraw:
    """Per-disc friction parameters of a batch, shape (applications, axles, discs per axle)."""

    initial_mu: np.ndarray
    power_coefficient_per_s: np.ndarray


def partitioned(
    nominal: float, sigma: float, partition: ScatterPartition, global_part: np.ndarray, individual_part: np.ndarray
) -> np.ndarray:
    """One scattered parameter from standard normals: ``nominal + sigma (f_global g + f_individual
    i)``, ``global_part`` g (applications, 1, 1) shared by the discs of an application and
    ``individual_part`` i (applications, axles, discs per axle) per disc."""
    return nominal + sigma * (partition.global_fraction * global_part + partition.individual_fraction * individual_part)


def friction_from_normals(
    friction: StochasticFriction,
    partition: ScatterPartition,
    global_normals: np.ndarray,
    individual_normals: np.ndarray,
) -> FrictionDraw:
    """The friction of applications given their standard normals: ``global_normals``
    (applications, 2) and ``individual_normals`` (applications, 2, axles, discs per axle), index 0
    for mu_0 and 1 for a. A mu_0 outside the model's bounds is refused, not moved."""
    shared = global_normals[:, :, None, None]
    initial_mu = partitioned(
        friction.initial_mu, friction.initial_mu_sigma, partition, shared[:, 0], individual_normals[:, 0]
    )
    power_coefficient = partitioned(
        friction.power_coefficient_per_s,
        friction.power_coefficient_sigma_per_s,
        partition,
        shared[:, 1],
        individual_normals[:, 1],
    )
    if np.any(initial_mu < friction.mu_min) or np.any(initial_mu > friction.mu_max):
        raise ValueError(
            f"a drawn initial mu lies outside [{friction.mu_min}, {friction.mu_max}]: the scatter "
            f"sigma {friction.initial_mu_sigma} of material {friction.material!r} is too large"
        )
    return FrictionDraw(initial_mu=initial_mu, power_coefficient_per_s=power_coefficient)


def draw_friction(
    rng: np.random.Generator,
    friction: StochasticFriction,
    partition: ScatterPartition,
    n_applications: int,
    disc_shape: tuple[int, int],
) -> FrictionDraw:
    """Draw mu_0 and a for ``n_applications`` applications of discs shaped ``disc_shape``
    (axles, discs per axle) from ``rng`` (:func:`friction_from_normals`). Values are not clipped:
    mu_0 stays within the model's bounds by construction of the sigmas (a draw outside them is
    refused, not moved)."""
    # The global and the individual normals are always drawn, whatever the fractions, so that one
    # seed gives the same stream of random numbers in every set-up (common random numbers across
    # set-ups): for mu_0 first, then for a.
    shapes = ((n_applications, 1, 1), (n_applications, *disc_shape))
    mu_global, mu_individual = (rng.standard_normal(shape) for shape in shapes)
    a_global, a_individual = (rng.standard_normal(shape) for shape in shapes)
    return friction_from_normals(
        friction,
        partition,
        np.stack([mu_global[:, 0, 0], a_global[:, 0, 0]], axis=1),
        np.stack([mu_individual, a_individual], axis=1),
    )


def draw_running_resistance(
    rng: np.random.Generator, A_N: float, A_sigma_N: float, partition: ScatterPartition, n_applications: int
) -> np.ndarray:
    """A of F_R per application, N(A_N, A_sigma_N) where the set-up scatters it, else ``A_N``.

    As in the spec, the draw is not truncated: with sigma 1600 N around 2500 N about 6 % of the
    draws are negative (a net push), which the paper's Gaussian allows."""
    return running_resistance_from_normals(A_N, A_sigma_N, partition, rng.standard_normal(n_applications))


def running_resistance_from_normals(
    A_N: float, A_sigma_N: float, partition: ScatterPartition, normals: np.ndarray
) -> np.ndarray:
    """A of F_R per application given one standard normal each (``normals``, (applications,)):
    ``A_N + A_sigma_N * normal`` where the set-up scatters it, else ``A_N``."""
    if not partition.resistance_scatter:
        return np.full(len(normals), A_N)
    return A_N + A_sigma_N * normals
