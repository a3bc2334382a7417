"""Parameter identification: fit the model to dynamometer curves and train recordings.

- :mod:`.parameters`: fittable parameters and their bounds (``configs/identification/``).
- :mod:`.cases`: load cases to fit (dyno mean curves, train recordings), predicted in batches.
- :mod:`.deterministic`: multi-case least squares with intervals and identifiability verdicts.
- :mod:`.stochastic`: the scatter of mu_0 and a and the global/individual split (paper Eq. 13).

Kept apart from the physics and the simulator: it only builds configs and runs the simulator.
"""

from .cases import (
    DynoCurves,
    RecordingCases,
    Series,
    dyno_curves_from_campaign,
    read_dyno_curves,
    recording_cases,
    write_dyno_curves,
)
from .deterministic import IdentificationResult, ParameterEstimate, identify
from .parameters import IdentificationConfig, ParameterSpace, load_identification_config

__all__ = [
    "DynoCurves",
    "IdentificationConfig",
    "IdentificationResult",
    "ParameterEstimate",
    "ParameterSpace",
    "RecordingCases",
    "Series",
    "dyno_curves_from_campaign",
    "identify",
    "load_identification_config",
    "read_dyno_curves",
    "recording_cases",
    "write_dyno_curves",
]
