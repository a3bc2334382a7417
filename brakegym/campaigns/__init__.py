"""Monte-Carlo campaigns of the paper: the dynamometer campaign (Table 1) and the field campaign
(Table 4), in the set-ups DS, MCS-100, MCS-75/25 (spec Section 5), with the statistics of spec
Section 6 (:mod:`brakegym.statistics`).

Stop ``i`` of a campaign draws its scatter from the seed and ``i`` alone (counter-based streams,
:meth:`~brakegym.plants.TrainScatter.draw_for_samples`), and the stops run in chunks of
consecutive stops on any executor (:mod:`brakegym.execution`), so the same seed gives the same
campaign bit for bit whatever the executor, the number of workers or the chunk size. A campaign's
rows stay in memory, or go to Parquet files in a folder, resumable after an interruption.

- :mod:`.dyno`: the dynamometer campaign; :mod:`.field`: train stops and the field campaign;
  :mod:`.rail`: the field campaign on a rail condition, with adhesion and WSP;
- :mod:`.chunks`: chunks, running them, their rows; :mod:`.store`: a campaign's folder;
- :mod:`.trends`: the paper's trends recomputed; :mod:`.figures`: figures after the paper's.
"""

from .dyno import DynoCampaignResult, dyno_applications, dyno_campaign
from .field import FieldCampaignResult, field_applications, field_campaign, train_monte_carlo
from .rail import RAIL_STOP_COLUMNS, rail_field_campaign
from .store import CampaignFolderError

__all__ = [
    "RAIL_STOP_COLUMNS",
    "CampaignFolderError",
    "DynoCampaignResult",
    "FieldCampaignResult",
    "dyno_applications",
    "dyno_campaign",
    "field_applications",
    "field_campaign",
    "rail_field_campaign",
    "train_monte_carlo",
]
