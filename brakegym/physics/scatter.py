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

from ..config import FrictionMaterial, RunningResistance, ScatterSetup


@dataclass(frozen=True)
class FrictionDraw:
    """Per-disc friction parameters of a batch, shape (applications, axles, discs per axle)."""

    initial_mu: np.ndarray
    power_coefficient_per_s: np.ndarray


def _partitioned_normal(
    rng: np.random.Generator,
    nominal: float,
    sigma: float,
    setup: ScatterSetup,
    disc_shape: tuple[int, ...],
    n_applications: int,
) -> np.ndarray:
    shape = (n_applications, *disc_shape)
    # Both draws always happen, whatever the fractions, so that one seed gives the same stream
    # of random numbers in every set-up (common random numbers across set-ups).
    global_part = rng.standard_normal((n_applications,) + (1,) * len(disc_shape))
    individual_part = rng.standard_normal(shape)
    return nominal + sigma * (setup.global_fraction * global_part + setup.individual_fraction * individual_part)


def draw_friction(
    rng: np.random.Generator,
    material: FrictionMaterial,
    setup: ScatterSetup,
    n_applications: int,
    disc_shape: tuple[int, int],
) -> FrictionDraw:
    """Draw mu_0 and a for ``n_applications`` applications of discs shaped ``disc_shape``
    (axles, discs per axle). Values are not clipped: mu_0 stays within the model's bounds by
    construction of the sigmas (a draw outside them is refused, not moved)."""
    initial_mu = _partitioned_normal(
        rng, material.initial_mu, material.scatter.initial_mu_sigma, setup, disc_shape, n_applications
    )
    power_coefficient = _partitioned_normal(
        rng,
        material.power_coefficient_per_s,
        material.scatter.power_coefficient_sigma_per_s,
        setup,
        disc_shape,
        n_applications,
    )
    if np.any(initial_mu < material.mu_min) or np.any(initial_mu > material.mu_max):
        raise ValueError(
            f"a drawn initial mu lies outside [{material.mu_min}, {material.mu_max}]: the scatter "
            f"sigma {material.scatter.initial_mu_sigma} of material {material.name!r} is too large"
        )
    return FrictionDraw(initial_mu=initial_mu, power_coefficient_per_s=power_coefficient)


def draw_running_resistance(
    rng: np.random.Generator, resistance: RunningResistance, setup: ScatterSetup, n_applications: int
) -> np.ndarray:
    """A of F_R per application, N(A, sigma_A) where the set-up scatters it, else nominal.

    As in the spec, the draw is not truncated: with sigma 1600 N around 2500 N about 6 % of the
    draws are negative (a net push), which the paper's Gaussian allows."""
    draw = rng.standard_normal(n_applications)
    if not setup.resistance_scatter:
        return np.full(n_applications, resistance.A_N)
    return resistance.A_N + resistance.A_sigma_N * draw
