"""Rare-event estimation of response tails: quantiles and exceedance probabilities down to 1e-9.

Pure mathematics, independent of the brake model: the estimators work on any vectorised response
function of standard-normal inputs (see :mod:`.estimators`).

- :mod:`.streams`: counter-based standard normals, the same for a sample whatever the batching.
- :mod:`.estimators`: :func:`brute_force` (Monte Carlo), :func:`subset_simulation` and
  :func:`importance_sampling` (cross entropy), each returning a :class:`TailEstimate` with 95 %
  intervals, and its estimate as a :class:`WeightedTail`.
- :mod:`.mixture`: :func:`mixture_tail`, the tail of a mixture of responses (a response with a
  discrete input, one component per value) from an estimate per component.
"""

from .estimators import TailEstimate, WeightedTail, importance_sampling
from .mixture import mixture_tail
from .montecarlo import brute_force
from .streams import derived_seed, standard_normals, uniforms
from .subset import subset_simulation

__all__ = [
    "TailEstimate",
    "WeightedTail",
    "brute_force",
    "derived_seed",
    "importance_sampling",
    "mixture_tail",
    "standard_normals",
    "subset_simulation",
    "uniforms",
]
