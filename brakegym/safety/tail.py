"""The braking distance that a train's emergency brake exceeds with a given probability, or the
probability that it exceeds a given distance: the tail of a safety case's braking distance.

Subset simulation and importance sampling run on the model split by the number of failed brake
units (:meth:`~brakegym.safety.model.BrakingModel.strata`, combined by
:func:`~brakegym.reliability.mixture_tail`): within a stratum the distance is a continuous function
of the normals with one exceedance region, which both estimators need. Brute force, the reference,
runs on the whole model, each unit failing with its probability, so that it shares nothing with
the other two but the simulation.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import config as cfg
from ..defaults import DEFAULT_STEP_S, DEFAULT_TAIL_CHUNK_STOPS, TAIL_METHODS
from ..execution import Executor, RowsOnExecutor
from ..reliability import TailEstimate, brute_force, mixture_tail
from .conventional import ConventionalStop, conventional_stop
from .model import BrakingModel

# Brute force's default sample: this many expected exceedances of the asked probability.
BRUTE_FORCE_EXCEEDANCES = 100
# The most stops brute force runs unless told otherwise (about an hour on two cores from 160 km/h).
BRUTE_FORCE_DEFAULT_LIMIT = 10_000_000


@dataclass(frozen=True)
class BrakingTail:
    """A tail estimate of a safety case's braking distance with what it was asked and the
    deterministic references beside it."""

    case: str
    vehicle: str
    load: str
    initial_speed_kmh: float
    seed: int
    estimate: TailEstimate
    nominal_braking_distance_m: float  # every input at its nominal value, no unit failed
    conventional: ConventionalStop

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``brakegym tail``: the estimate's stable keys (probability,
        braking_distance_m, ci95_m, model_evaluations, method, seconds, probability_ci95,
        threshold), then what was asked and the references."""
        estimate = self.estimate
        return {
            **estimate.as_dict(),
            "target": estimate.target,
            "coefficient_of_variation": estimate.coefficient_of_variation,
            "safety_case": self.case,
            "vehicle": self.vehicle,
            "load": self.load,
            "v0_kmh": self.initial_speed_kmh,
            "seed": self.seed,
            "nominal_braking_distance_m": self.nominal_braking_distance_m,
            "conventional": self.conventional.as_dict(),
            "diagnostics": estimate.diagnostics,
        }


def braking_distance_tail(
    case: cfg.SafetyCase,
    load: str,
    initial_speed_kmh: float,
    *,
    probability: float | None = None,
    distance_m: float | None = None,
    method: str = "subset",
    seed: int = 0,
    step_s: float = DEFAULT_STEP_S,
    samples: int | None = None,
    executor: Executor | None = None,
    chunk_stops: int = DEFAULT_TAIL_CHUNK_STOPS,
    **settings: Any,
) -> BrakingTail:
    """The braking distance exceeded with ``probability``, or the probability of exceeding
    ``distance_m`` (exactly one), with 95 % intervals, by ``method`` (``"subset"``, ``"is"`` or
    ``"brute"``). ``samples`` is brute force's sample size (default: 100 expected exceedances of
    ``probability``); ``settings`` go to the estimator (``n_per_level``, ``batch_size``, ...).
    The stops run in this process, or on ``executor`` in tasks of ``chunk_stops`` stops, with the
    same result bit for bit."""
    if method not in TAIL_METHODS:
        raise ValueError(f"method {method!r}: choose one of {list(TAIL_METHODS)}")
    if (probability is None) == (distance_m is None):
        raise ValueError("give exactly one of probability and distance_m")
    if probability is not None and not 0 < probability < 1:
        raise ValueError(f"probability {probability}: must lie strictly between 0 and 1")
    if distance_m is not None and not (math.isfinite(distance_m) and distance_m > 0):
        raise ValueError(f"distance {distance_m} m: must be a positive finite number")
    model = BrakingModel(case, load, initial_speed_kmh, step_s)
    response, settings = on_executor(model.braking_distance_m, executor, chunk_stops, settings)
    if method == "brute":
        estimate = brute_force(
            response,
            model.dims,
            seed,
            samples or brute_force_samples(probability),
            probability=probability,
            threshold=distance_m,
            **settings,
        )
    else:
        if samples is not None:
            raise ValueError("samples is brute force's sample size; subset and is take n_per_level")
        estimate = mixture_tail(
            model.strata(response), model.dims, seed, method, probability=probability, threshold=distance_m, **settings
        )
    return BrakingTail(
        case=case.name,
        vehicle=case.vehicle,
        load=load,
        initial_speed_kmh=initial_speed_kmh,
        seed=seed,
        estimate=estimate,
        nominal_braking_distance_m=model.nominal_braking_distance_m(),
        conventional=conventional_stop(model),
    )


def on_executor(
    response: Callable[..., np.ndarray], executor: Executor | None, chunk_stops: int, settings: dict[str, Any]
) -> tuple[Callable[..., np.ndarray], dict[str, Any]]:
    """``response`` evaluated on ``executor`` in tasks of ``chunk_stops`` stops (as it is without
    one), and the estimator's ``settings`` with a batch size that gives every worker a few tasks at
    once, unless they set one."""
    if executor is None:
        return response, settings
    distributed = RowsOnExecutor(response, executor, chunk_stops)
    return distributed, {"batch_size": distributed.batch_rows(), **settings}


def brute_force_samples(probability: float | None) -> int:
    """Brute force's default sample: 100 expected exceedances of ``probability``, at least 10^4;
    refused above 10^7 (``samples`` sets more)."""
    if probability is None:
        raise ValueError("brute force with a distance needs its sample size (samples)")
    needed = max(10_000, math.ceil(BRUTE_FORCE_EXCEEDANCES / probability))
    if needed > BRUTE_FORCE_DEFAULT_LIMIT:
        raise ValueError(
            f"brute force at probability {probability} needs about {needed:.1e} stops for "
            f"{BRUTE_FORCE_EXCEEDANCES} exceedances; use --method subset or is, or set the sample size"
        )
    return needed
