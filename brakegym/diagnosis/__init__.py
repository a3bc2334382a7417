"""Diagnosis of recordings (``brakegym diagnose``): locate the mismatch between recordings and the
model, name the missing physics from the effect library (:mod:`brakegym.effects`), fit it, and say
how sure that is.

- :mod:`.locate`: noise levels, residual segments and the state axis a residual lives along;
- :mod:`.fitting`: the unmodified model and candidate effects fitted to every recording at once;
- :mod:`.pipeline`: screen, fit, judge and report;
- :mod:`.markdown`: the Markdown report and its figures.
"""

from .pipeline import Diagnosis, diagnose, write_effect_set

__all__ = ["Diagnosis", "diagnose", "write_effect_set"]
