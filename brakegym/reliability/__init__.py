"""Rare-event estimation of response tails: quantiles and exceedance probabilities down to 1e-9.

Pure mathematics, independent of the brake model: the estimators work on any vectorised response
function of standard-normal inputs, ``response(u) -> y``, larger being worse (see
:mod:`.response`). Each estimator takes either

- ``probability=p``: the quantile ``y_p`` with ``P(response > y_p) = p``, and its 95 % interval;
- ``threshold=b``: the exceedance probability ``P(response > b)``, and its 95 % interval;

and returns a :class:`TailEstimate`, which carries its estimate as a :class:`WeightedTail`. The
response is called with at most ``batch_size`` rows at a time, and every row is counted in
:attr:`~.results.TailEstimate.model_evaluations`.

- :mod:`.streams`: counter-based standard normals, the same for a sample whatever the batching.
- :mod:`.response`: what a response is, and its evaluation in batches, checked and counted.
- :mod:`.checks`: the estimators' argument checks.
- :mod:`.results`: :class:`TailEstimate` and :class:`WeightedTail`; the 95 % intervals and the
  empirical CCDF that the estimators read quantiles off.
- :mod:`.montecarlo`: :func:`brute_force`, plain Monte Carlo with Clopper-Pearson and
  distribution-free order-statistic intervals.
- :mod:`.subset`: :func:`subset_simulation`, subset simulation (Au & Beck 2001) with adaptive
  conditional sampling (Papaioannou et al. 2015).
- :mod:`.importance`: :func:`importance_sampling`, cross-entropy importance sampling (Rubinstein
  & Kroese 2004) with a mean-shifted Gaussian density.
- :mod:`.mixture`: :func:`mixture_tail`, the tail of a mixture of responses (a response with a
  discrete input, one component per value) from an estimate per component.

Determinism. All randomness comes from :mod:`.streams`: the seed's own stream for Monte Carlo and
subset simulation's level 0, streams derived from the seed (:func:`derived_seed`) for the
Markov-chain proposals (stream 1) and the importance-sampling runs (streams 2 and 3; the
components of :func:`mixture_tail` get 4 and 5). The same seed gives the same estimate bit for bit
whatever ``batch_size`` is (for a response that treats rows independently).

The estimators are imported on first use of their names: they need :mod:`scipy.stats` (about
0.8 s to import), which the campaigns, drawing from :mod:`.streams` alone, should not pay for.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .streams import derived_seed, standard_normals, uniforms

if TYPE_CHECKING:
    from .importance import importance_sampling
    from .mixture import mixture_tail
    from .montecarlo import brute_force
    from .results import TailEstimate, WeightedTail
    from .subset import subset_simulation

_LAZY = {
    "TailEstimate": "results",
    "WeightedTail": "results",
    "brute_force": "montecarlo",
    "importance_sampling": "importance",
    "subset_simulation": "subset",
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
