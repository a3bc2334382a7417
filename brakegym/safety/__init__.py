"""Braking distances as a safety engineer needs them: the distance a train's emergency brake
exceeds only with a small probability (the ETCS confidence levels), from the stochastic inputs of a
safety case (``configs/safety_cases/``).

- :mod:`.model`: a safety case as a response function, standard-normal points to braking
  distances (:class:`BrakingModel`), whole or split by the number of failed brake units
  (:meth:`BrakingModel.strata`).
- :mod:`.tail`: the braking distance at a probability, or the probability of a distance, with
  95 % intervals (:func:`~.tail.braking_distance_tail`, ``brakegym tail``).
- :mod:`.etcs`: the ETCS emergency brake model, A_brake_emergency and Kdry_rst(V, EBCL) per speed
  band and confidence level (:func:`~.etcs.kdry_table`, ``brakegym kdry``); :mod:`.osrd` exports
  it to OSRD's rolling-stock schema and reads it back; :mod:`.figures` draws it.
- :mod:`.conventional`: the braking distance as the conventional calculation gives it (constant
  mean pad friction, equivalent response time, speed steps), for comparison.
"""

from .conventional import ConventionalStop, conventional_stop
from .model import BrakingModel, InputLayout

__all__ = ["BrakingModel", "ConventionalStop", "InputLayout", "conventional_stop"]
