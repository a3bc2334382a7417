"""The batched simulator of braking trains and dynamometer stops.

- :mod:`.state`: the packed per-disc and per-train states and their row indices.
- :mod:`.plant`: :class:`Plant` (what is braked) and :class:`BatchConditions` (per application).
- :mod:`.pressure`: where the cylinder pressures come from (commanded, prescribed).
- :mod:`.hooks`: extension points for forces and friction factors the nominal model leaves out.
- :mod:`.integrator`: :class:`Simulator`, fixed-step RK4 in compiled steps (:mod:`.kernel`), on
  every core (:func:`set_kernel_threads` to use fewer).
- :mod:`.reference`: :class:`NumpyReferenceSimulator`, the same model in numpy.
- :mod:`.metrics`: per-application stop summaries (paper Eqs. 3 and 15).
- :mod:`.wheelsets`: :class:`~.wheelsets.AdhesionSimulator`, the wheel-rail adhesion option (numpy;
  docs/adhesion.md).
"""

from .hooks import ExtraForce, FrictionModifier, StageContext
from .integrator import Simulator, StepRecord
from .kernel import kernel_threads, set_kernel_threads
from .metrics import StopMetrics
from .plant import BatchConditions, Plant
from .pressure import CommandedPressure, CylinderState, PrescribedPressure, PressureSource
from .reference import NumpyReferenceSimulator
from .state import DISC_STATES, TRAIN_STATES

__all__ = [
    "DISC_STATES",
    "TRAIN_STATES",
    "BatchConditions",
    "CommandedPressure",
    "CylinderState",
    "ExtraForce",
    "FrictionModifier",
    "NumpyReferenceSimulator",
    "Plant",
    "PrescribedPressure",
    "PressureSource",
    "Simulator",
    "StageContext",
    "StepRecord",
    "StopMetrics",
    "kernel_threads",
    "set_kernel_threads",
]
