"""The response whose tail the estimators estimate, and its evaluation: in batches, checked, counted.

A *response* is a function ``response(u) -> y``: ``u`` of shape ``(n, dims)`` holds ``n`` points
of the standard-normal space, ``y`` of shape ``(n,)`` their responses, larger being worse (a
braking distance). Exceedance means ``response(u) > threshold``. The estimators call it through a
:class:`CountedResponse`: with at most ``batch_size`` rows at a time, every row counted in
:attr:`~.results.TailEstimate.model_evaluations`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .checks import check_integer

Response = Callable[[np.ndarray], np.ndarray]
"""The type of a response ``response(u) -> y``, from ``(n, dims)`` standard normals to ``(n,)`` values."""


class CountedResponse:
    """The response called in batches of at most ``batch_size`` rows, its output checked, its
    rows counted."""

    def __init__(self, response: Response, dims: int, batch_size: int) -> None:
        if not callable(response):
            raise ValueError(f"response = {response!r}: need a callable response(u) -> y")
        self.response = response
        self.dims = check_integer("dims", dims, 1)
        self.batch_size = check_integer("batch_size", batch_size, 1)
        self.evaluations = 0

    def __call__(self, points: np.ndarray) -> np.ndarray:
        values = np.empty(len(points))
        for begin in range(0, len(points), self.batch_size):
            batch = points[begin : begin + self.batch_size]
            # Read-only: a response that wrote into its input would corrupt the chains' states.
            batch = batch.view()
            batch.flags.writeable = False
            result = np.asarray(self.response(batch), dtype=np.float64)
            if result.shape != (len(batch),):
                raise ValueError(
                    f"response returned shape {result.shape} for {len(batch)} rows: need one value per row, "
                    f"shape ({len(batch)},)"
                )
            if np.isnan(result).any():
                raise ValueError(f"response returned NaN for rows {np.flatnonzero(np.isnan(result))[:5] + begin}")
            values[begin : begin + len(batch)] = result
            self.evaluations += len(batch)
        return values
