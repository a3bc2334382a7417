"""Monte-Carlo campaigns of the paper: the dynamometer campaign (Table 1) and the field campaign
(Table 4), in the set-ups DS, MCS-100, MCS-75/25 (spec Section 5), with the statistics of spec
Section 6 (:mod:`brakegym.statistics`).

All random numbers of a campaign come from one ``numpy.random.Generator`` seeded by the caller and
are drawn up front in a fixed order, and the stops run in chunks of fixed composition
(:mod:`.runner`), so the same seed gives the same campaign bit for bit whatever the number of
worker processes.

- :mod:`.dyno`: the dynamometer campaign; :mod:`.field`: train stops and the field campaign;
- :mod:`.trends`: the paper's trends recomputed; :mod:`.figures`: figures after the paper's.
"""

from .dyno import DynoCampaignResult, dyno_applications, dyno_campaign
from .field import FieldCampaignResult, field_applications, field_campaign, train_monte_carlo

__all__ = [
    "DynoCampaignResult",
    "FieldCampaignResult",
    "dyno_applications",
    "dyno_campaign",
    "field_applications",
    "field_campaign",
    "train_monte_carlo",
]
