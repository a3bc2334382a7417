"""Rare-event estimation of response tails: quantiles and exceedance probabilities down to 1e-9.

Pure mathematics, independent of the brake model: the estimators work on any vectorised response
function of standard-normal inputs (see :mod:`.estimators`).

- :mod:`.streams`: counter-based standard normals, the same for a sample whatever the batching.
- :mod:`.estimators`: :func:`brute_force` (Monte Carlo), :func:`subset_simulation` and
  :func:`importance_sampling` (cross entropy), each returning a :class:`TailEstimate` with 95 %
  intervals, and its estimate as a :class:`WeightedTail`.
- :mod:`.mixture`: :func:`mixture_tail`, the tail of a mixture of responses (a response with a
  discrete input, one component per value) from an estimate per component.

The estimators are imported on first use of their names: they need :mod:`scipy.stats` (about
0.8 s to import), which the campaigns, drawing from :mod:`.streams` alone, should not pay for.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .streams import derived_seed, standard_normals, uniforms

if TYPE_CHECKING:
    from .estimators import TailEstimate, WeightedTail, brute_force, importance_sampling, subset_simulation
    from .mixture import mixture_tail

_LAZY = {
    "TailEstimate": "estimators",
    "WeightedTail": "estimators",
    "brute_force": "estimators",
    "importance_sampling": "estimators",
    "subset_simulation": "estimators",
    "mixture_tail": "mixture",
}

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


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *_LAZY])
