"""Diagnosis of recordings (``brakegym diagnose``): locate the mismatch between recordings and the
model, name the missing physics from the effect library (:mod:`brakegym.effects`), fit it, and say
how sure that is.

The stages, in the order :mod:`.pipeline` runs them:

- :mod:`.locate`: noise levels, residual segments and the state axis a residual lives along;
- :mod:`.fitting`: the unmodified model and candidate effects fitted to every recording at once;
- :mod:`.weighting`: effective sample weights of autocorrelated residuals;
- :mod:`.screening`: every effect tried on a grid, cheaply;
- :mod:`.heldout` and :mod:`.judging`: candidates judged on recordings held out of the fit;
- :mod:`.report`: the JSON report, its summary and the effect set of what was selected;
- :mod:`.adhesion`: a fitted adhesion limit read as a rail (Polach's peak adhesion);
- :mod:`.markdown`: the Markdown report and its figures.

:mod:`.rules` holds every threshold.
"""

from .pipeline import Diagnoser, Diagnosis, diagnose
from .report import write_effect_set
from .rules import DiagnosisRules

__all__ = ["Diagnoser", "Diagnosis", "DiagnosisRules", "diagnose", "write_effect_set"]
