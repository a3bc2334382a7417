"""Rare-event estimation of response tails: quantiles and exceedance probabilities down to 1e-9.

Pure mathematics, independent of the brake model: the estimators work on any vectorised response
function of standard-normal inputs (see :mod:`.estimators`).

- :mod:`.streams`: counter-based standard normals, the same for a sample whatever the batching.
- :mod:`.estimators`: :func:`brute_force` (Monte Carlo), :func:`subset_simulation` and
  :func:`importance_sampling` (cross entropy), each returning a :class:`TailEstimate` with 95 %
  intervals, and its estimate as a :class:`WeightedTail`.
"""

from .estimators import TailEstimate, WeightedTail, brute_force, importance_sampling, subset_simulation
from .streams import derived_seed, standard_normals, uniforms

__all__ = [
    "TailEstimate",
    "WeightedTail",
    "brute_force",
    "derived_seed",
    "importance_sampling",
    "standard_normals",
    "subset_simulation",
    "uniforms",
]
