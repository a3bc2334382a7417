"""The train's ETCS emergency brake model from a safety case: the nominal emergency deceleration
per speed band (A_brake_emergency) and the rolling-stock correction factor for dry rails,
Kdry_rst(V, EBCL), at the confidence levels EBCL that ETCS's national value M_NVEBCL selects.

ETCS (SUBSET-026, section 3.13.6.2.1) decelerates the train on its emergency brake at
``A_brake_safe(V) = Kdry_rst(V, EBCL) (Kwet_rst(V) + M_NVAVADH (1 - Kwet_rst(V))) A_brake_emergency(V)``
after the emergency brake's build-up time ``T_be``: the train data give ``A_brake_emergency`` as
a step function of speed and ``Kdry_rst`` per speed band and confidence level, the deceleration
that the train reaches with probability EBCL over the nominal. Here:

- a stop is an emergency brake command at the train's maximum speed, as the safety case's model
  simulates it (:class:`~brakegym.safety.model.BrakingModel`);
- ``T_be`` is the equivalent response time of the conventional calculation (the delay to 10 % of
  the brake force plus half the build-up to 95 %: :mod:`.conventional`), from the nominal
  cylinder; a stop's deceleration in a speed band is the constant deceleration that covers the
  band in the same distance, the top band from the state at ``T_be``
  (:meth:`~brakegym.safety.model.BrakingModel.band_decelerations_mps2`);
- ``A_brake_emergency`` of a band is the deceleration of the nominal stop (every input at its
  nominal value, no brake unit failed);
- ``Kdry_rst(band, EBCL)`` is the band deceleration's ``1 - EBCL`` quantile over the nominal,
  estimated with a rare-event estimator on the strata of failed units
  (:func:`~brakegym.reliability.mixture_tail`), with its 95 % interval; ``M_NVEBCL = 0`` means
  EBCL = 50 % and ``n >= 1`` means ``1 - 10^-n``, as in SUBSET-026's table of national values.

The export is the ``etcs_brake_params`` object of OSRD's rolling-stock schema
(:mod:`.osrd`); what the braking model does not give (Kwet_rst, the gradient corrections, the
traction cut-off time) comes from the safety case's ``etcs.not_modelled`` with its source.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import config as cfg
from ..defaults import DEFAULT_STEP_S, DEFAULT_TAIL_CHUNK_STOPS
from ..execution import Executor
from ..reliability import TailEstimate, derived_seed, mixture_tail
from .conventional import conventional_stop
from .model import BrakingModel
from .tail import on_executor

CONFIDENCE_LEVELS = tuple(range(10))  # M_NVEBCL


def confidence(level: int) -> float:
    """EBCL of ``M_NVEBCL = level``: 0.5 for 0, ``1 - 10^-level`` for 1 ... 9."""
    if level not in CONFIDENCE_LEVELS:
        raise ValueError(f"confidence level {level}: M_NVEBCL is 0 ... 9")
    return 0.5 if level == 0 else 1.0 - 10.0**-level


def confidence_label(level: int) -> str:
    """EBCL of M_NVEBCL ``level`` in per cent, all its nines shown: ``"50 %"``, ``"99.9 %"``,
    ``"99.9999999 %"``."""
    return f"{100 * confidence(level):.{max(0, level - 2)}f} %"


def shortfall_probability(level: int) -> float:
    """The probability that the deceleration falls below its EBCL quantile, ``1 - EBCL``."""
    return 0.5 if level == 0 else 10.0**-level


@dataclass(frozen=True)
class BandDecelerationShortfall:
    """A response for the tail estimators: minus the deceleration of one speed band, so that
    larger is worse (a stop that brakes less)."""

    model: BrakingModel
    speed_edges_kmh: tuple[float, ...]
    build_up_time_s: float
    band: int

    def __call__(self, u: np.ndarray, failed_units: int | None = None) -> np.ndarray:
        decelerations = self.model.band_decelerations_mps2(u, self.speed_edges_kmh, self.build_up_time_s, failed_units)
        return -decelerations[:, self.band]


@dataclass(frozen=True)
class KdryTable:
    """Kdry_rst per speed band and confidence level, with the nominal and the conventional
    decelerations of the bands."""

    case: str
    vehicle: str
    load: str
    method: str
    seed: int
    speed_edges_kmh: tuple[float, ...]  # from 0 to the maximum speed
    build_up_time_s: float  # T_be
    nominal_deceleration_mps2: np.ndarray  # (bands,): A_brake_emergency
    conventional_deceleration_mps2: np.ndarray  # (bands,)
    levels: tuple[int, ...]  # M_NVEBCL
    kdry: np.ndarray  # (bands, levels)
    kdry_ci95: np.ndarray  # (bands, levels, 2)
    model_evaluations: int
    seconds: float
    estimates: tuple[tuple[TailEstimate, ...], ...] = field(repr=False)  # (bands, levels)

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``brakegym kdry``."""
        bands = [
            {
                "speed_low_kmh": low,
                "speed_high_kmh": high,
                "nominal_deceleration_mps2": float(self.nominal_deceleration_mps2[band]),
                "conventional_deceleration_mps2": float(self.conventional_deceleration_mps2[band]),
                "kdry": {
                    str(level): {
                        "ebcl": confidence(level),
                        "value": float(self.kdry[band, column]),
                        "ci95": [float(value) for value in self.kdry_ci95[band, column]],
                        "model_evaluations": self.estimates[band][column].model_evaluations,
                    }
                    for column, level in enumerate(self.levels)
                },
            }
            for band, (low, high) in enumerate(zip(self.speed_edges_kmh, self.speed_edges_kmh[1:]))
        ]
        return {
            "safety_case": self.case,
            "vehicle": self.vehicle,
            "load": self.load,
            "method": self.method,
            "seed": self.seed,
            "build_up_time_s": self.build_up_time_s,
            "bands": bands,
            "model_evaluations": self.model_evaluations,
            "seconds": self.seconds,
        }


def speed_band_edges_kmh(case: cfg.SafetyCase) -> tuple[float, ...]:
    """The edges of the case's ETCS speed bands, from 0 to the maximum speed."""
    return (0.0, *case.etcs.speed_band_edges_kmh, case.etcs.maximum_speed_kmh)


def nominal_band_decelerations(model: BrakingModel) -> tuple[np.ndarray, float]:
    """The deceleration of each ETCS speed band in the nominal stop of ``model`` (every input
    nominal, no unit failed; commanded at the maximum speed), and the build-up time it counts
    from: the equivalent response time of the conventional calculation."""
    build_up = conventional_stop(model).equivalent_response_time_s
    point = np.zeros((1, model.dims))
    return model.band_decelerations_mps2(point, speed_band_edges_kmh(model.case), build_up, failed_units=0)[0], build_up


def kdry_table(
    case: cfg.SafetyCase,
    load: str,
    *,
    method: str = "is",
    seed: int = 0,
    levels: tuple[int, ...] = CONFIDENCE_LEVELS,
    step_s: float = DEFAULT_STEP_S,
    executor: Executor | None = None,
    chunk_stops: int = DEFAULT_TAIL_CHUNK_STOPS,
    progress: Callable[[int], None] | None = None,
    **settings: Any,
) -> KdryTable:
    """Kdry_rst of ``case``'s train with ``load`` for every speed band of its ETCS model and every
    confidence level of ``levels``, by ``method`` (``"subset"`` or ``"is"``) with ``seed``;
    ``settings`` go to the estimator. Each band and level has its own random stream, derived from
    ``seed``. The stops run in this process, or on ``executor`` in tasks of ``chunk_stops`` stops,
    with the same result bit for bit. ``progress(1)`` is called as each band and level is done."""
    start = time.perf_counter()
    if method not in ("subset", "is"):
        raise ValueError(f"method {method!r}: Kdry needs a rare-event estimator, 'subset' or 'is'")
    if case.brake_mode != "emergency":
        raise ValueError(
            f"safety case {case.name!r} brakes in mode {case.brake_mode!r}: Kdry_rst is the emergency brake's"
        )
    for level in levels:
        confidence(level)
    model = BrakingModel(case, load, case.etcs.maximum_speed_kmh, step_s)
    edges = speed_band_edges_kmh(case)
    conventional = conventional_stop(model)
    nominal, build_up = nominal_band_decelerations(model)
    estimates = []
    for band in range(len(edges) - 1):
        response, band_settings = on_executor(
            BandDecelerationShortfall(model, edges, build_up, band), executor, chunk_stops, settings
        )
        strata = model.strata(response)
        row = []
        for level in levels:
            row.append(
                mixture_tail(
                    strata,
                    model.dims,
                    derived_seed(seed, band, level),
                    method,
                    probability=shortfall_probability(level),
                    **band_settings,
                )
            )
            if progress is not None:
                progress(1)
        estimates.append(tuple(row))
    # The quantile of -a is minus the deceleration's lower quantile; its interval turns round.
    kdry = np.array([[-estimate.threshold for estimate in row] for row in estimates]) / nominal[:, None]
    interval = np.array([[[-high, -low] for low, high in (e.threshold_ci95 for e in row)] for row in estimates])
    return KdryTable(
        case=case.name,
        vehicle=case.vehicle,
        load=load,
        method=method,
        seed=seed,
        speed_edges_kmh=edges,
        build_up_time_s=build_up,
        nominal_deceleration_mps2=nominal,
        conventional_deceleration_mps2=conventional.band_decelerations_mps2(edges),
        levels=tuple(levels),
        kdry=kdry,
        kdry_ci95=interval / nominal[:, None, None],
        model_evaluations=sum(e.model_evaluations for row in estimates for e in row),
        seconds=time.perf_counter() - start,
        estimates=tuple(estimates),
    )
