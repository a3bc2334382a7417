"""Braking distances as a safety engineer needs them: the distance a train's emergency brake
exceeds only with a small probability (the ETCS confidence levels), from the stochastic inputs of a
safety case (``configs/safety_cases/``).

- :mod:`.model`: a safety case as a response function, standard-normal points to braking
  distances (:class:`BrakingModel`).
"""

from .model import BrakingModel, InputLayout

__all__ = ["BrakingModel", "InputLayout"]
