"""Checks of the estimators' arguments, each raising a ValueError that names the argument and says
what it needs."""

from __future__ import annotations

import math
import numbers


def check_target(probability: float | None, threshold: float | None) -> None:
    """Checks that exactly one of ``probability`` (in (0, 1)) and ``threshold`` (finite) is given."""
    if (probability is None) == (threshold is None):
        raise ValueError(
            f"probability = {probability!r}, threshold = {threshold!r}: give exactly one of them "
            f"(a probability to estimate its quantile, or a threshold to estimate its exceedance probability)"
        )
    if probability is not None and not (isinstance(probability, numbers.Real) and 0.0 < probability < 1.0):
        raise ValueError(f"probability = {probability!r}: need a number in the open interval (0, 1)")
    if threshold is not None and not (isinstance(threshold, numbers.Real) and math.isfinite(threshold)):
        raise ValueError(f"threshold = {threshold!r}: need a finite number")


def check_integer(name: str, value: int, minimum: int) -> int:
    """The argument ``name`` as an ``int``, checked to be an integer (not a bool) of at least ``minimum``."""
    if not isinstance(value, numbers.Integral) or isinstance(value, bool) or value < minimum:
        raise ValueError(f"{name} = {value!r}: need an integer >= {minimum}")
    return int(value)


def check_level_probability(level_probability: float) -> None:
    """Checks that ``level_probability`` is a number in (0, 0.5]."""
    if not (isinstance(level_probability, numbers.Real) and 0.0 < level_probability <= 0.5):
        raise ValueError(f"level_probability = {level_probability!r}: need a number in (0, 0.5]")
