"""The ETCS brake model in OSRD's rolling-stock schema: the ``etcs_brake_params`` object of a
rolling stock of OSRD (Open Source Railway Designer, https://osrd.fr), whose ETCS braking curves
(SUBSET-026) read it.

Every field of the object, as OSRD's schema has it (``EtcsBrakeParams``, unknown fields refused):
``gamma_emergency`` (A_brake_emergency), ``gamma_service`` (A_brake_service),
``gamma_normal_service`` (A_brake_normal_service), ``k_dry`` (Kdry_rst), ``k_wet`` (Kwet_rst),
``k_n_pos`` and ``k_n_neg`` (Kn+, Kn-), each a speed-interval curve ``{"boundaries": [...],
"values": [...]}`` (boundaries in m/s, rising; one more value than boundaries, none negative), and
``t_traction_cut_off``, ``t_bs1``, ``t_bs2``, ``t_be`` in s. Kdry_rst is given for one confidence
level, the national value M_NVEBCL that the export is for.

From brakegym: ``gamma_emergency``, ``k_dry`` and ``t_be`` (:mod:`.etcs`), ``gamma_service`` and
``t_bs1 = t_bs2`` from the same model in the service brake mode; ``gamma_normal_service`` is the
service deceleration too (brakegym has no separate normal-service brake). From the safety case's
``etcs.not_modelled``, with their source: ``k_wet``, ``k_n_pos``, ``k_n_neg``,
``t_traction_cut_off``.

:func:`read_etcs_brake_params` reads the object back with OSRD's checks, so that an export that
OSRD would refuse fails here first.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from .. import config as cfg
from ..defaults import DEFAULT_STEP_S
from ..units import kmh_to_mps
from .etcs import KdryTable, nominal_band_decelerations
from .model import BrakingModel

CURVES = ("gamma_emergency", "gamma_service", "gamma_normal_service", "k_dry", "k_wet", "k_n_pos", "k_n_neg")
TIMES = ("t_traction_cut_off", "t_bs1", "t_bs2", "t_be")


class OsrdFormatError(ValueError):
    """An ``etcs_brake_params`` object OSRD would refuse; the message names the field."""


def etcs_brake_params(
    table: KdryTable,
    service_deceleration_mps2: np.ndarray,
    service_build_up_time_s: float,
    level: int,
    wet_rail_factor: float,
    gradient_correction_uphill: float,
    gradient_correction_downhill: float,
    traction_cut_off_time_s: float,
) -> dict[str, Any]:
    """The ``etcs_brake_params`` object of ``table``'s train with Kdry_rst at the confidence level
    ``level`` (M_NVEBCL, one of the table's)."""
    if level not in table.levels:
        raise ValueError(f"confidence level {level} was not computed: the table has {list(table.levels)}")
    boundaries = [float(kmh_to_mps(edge)) for edge in table.speed_edges_kmh[1:-1]]
    bands = len(table.speed_edges_kmh) - 1

    def curve(values) -> dict[str, list[float]]:
        values = np.broadcast_to(np.asarray(values, dtype=float), (bands,))
        return {"boundaries": list(boundaries), "values": [float(value) for value in values]}

    return {
        "gamma_emergency": curve(table.nominal_deceleration_mps2),
        "gamma_service": curve(service_deceleration_mps2),
        "gamma_normal_service": curve(service_deceleration_mps2),
        "k_dry": curve(table.kdry[:, table.levels.index(level)]),
        "k_wet": curve(wet_rail_factor),
        "k_n_pos": curve(gradient_correction_uphill),
        "k_n_neg": curve(gradient_correction_downhill),
        "t_traction_cut_off": float(traction_cut_off_time_s),
        "t_bs1": float(service_build_up_time_s),
        "t_bs2": float(service_build_up_time_s),
        "t_be": float(table.build_up_time_s),
    }


def export_kdry_table(table: KdryTable, case: cfg.SafetyCase, step_s: float = DEFAULT_STEP_S) -> dict[str, Any]:
    """The ``etcs_brake_params`` of ``table`` (computed for ``case``) at the case's export
    confidence level, the service brake simulated in the same model, what the model does not give
    from the case's ``etcs.not_modelled``."""
    service_case = case.model_copy(update={"brake_mode": "service"})
    service, service_build_up = nominal_band_decelerations(
        BrakingModel(service_case, table.load, case.etcs.maximum_speed_kmh, step_s)
    )
    assumed = case.etcs.not_modelled
    return etcs_brake_params(
        table,
        service_deceleration_mps2=service,
        service_build_up_time_s=service_build_up,
        level=case.etcs.export_confidence_level,
        wet_rail_factor=assumed.wet_rail_factor,
        gradient_correction_uphill=assumed.gradient_correction_uphill,
        gradient_correction_downhill=assumed.gradient_correction_downhill,
        traction_cut_off_time_s=assumed.traction_cut_off_time_s,
    )


def write_etcs_brake_params(path: str | Path, params: dict[str, Any]) -> Path:
    """Write the object as JSON, after checking it as :func:`read_etcs_brake_params` does."""
    check_etcs_brake_params(params, str(path))
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(json.dumps(params, indent=2) + "\n")
    return target


def read_etcs_brake_params(path: str | Path) -> dict[str, Any]:
    """An ``etcs_brake_params`` object from a JSON file, checked as OSRD's deserializer checks
    it: every field present and no other, numbers where numbers belong, each curve with one more
    value than boundaries, no negative value or boundary, boundaries strictly rising."""
    try:
        params = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise OsrdFormatError(f"{path}: cannot read as JSON ({exc})") from None
    check_etcs_brake_params(params, str(path))
    return params


def check_etcs_brake_params(params: Any, where: str) -> None:
    """Raise :class:`OsrdFormatError` naming ``where`` and the field if OSRD would refuse
    ``params``."""
    if not isinstance(params, dict):
        raise OsrdFormatError(f"{where}: need a JSON object, got {type(params).__name__}")
    missing = [name for name in (*CURVES, *TIMES) if name not in params]
    unknown = sorted(set(params) - set(CURVES) - set(TIMES))
    if missing or unknown:
        raise OsrdFormatError(f"{where}: missing field(s) {missing}, unknown field(s) {unknown}")
    for name in TIMES:
        if not _is_number(params[name]):
            raise OsrdFormatError(f"{where}: {name} = {params[name]!r}: need a number")
    for name in CURVES:
        _check_curve(params[name], f"{where}: {name}")


def _check_curve(curve: Any, where: str) -> None:
    if not isinstance(curve, dict) or set(curve) != {"boundaries", "values"}:
        raise OsrdFormatError(f"{where}: need exactly the fields boundaries and values")
    boundaries, values = curve["boundaries"], curve["values"]
    if not all(isinstance(part, list) and all(_is_number(x) for x in part) for part in (boundaries, values)):
        raise OsrdFormatError(f"{where}: boundaries and values must be lists of numbers")
    if not values:
        raise OsrdFormatError(f"{where}: curve should have at least 1 value")
    if len(boundaries) != len(values) - 1:
        raise OsrdFormatError(
            f"{where}: {len(boundaries)} boundaries and {len(values)} values: need one more value than boundaries"
        )
    if any(x < 0 for x in values) or any(x < 0 for x in boundaries):
        raise OsrdFormatError(f"{where}: values and boundaries must be >= 0")
    if any(high <= low for low, high in zip(boundaries, boundaries[1:])):
        raise OsrdFormatError(f"{where}: boundaries {boundaries} must be strictly increasing")


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and np.isfinite(value)
