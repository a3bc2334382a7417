"""A function of rows evaluated on an executor: the rows cut into chunks, one task each.

The rare-event estimators call a response with a batch of rows (points of the standard-normal
space, one stop each). :class:`RowsOnExecutor` evaluates such a batch on an
:class:`~.base.Executor`, ``chunk_rows`` rows per task, and joins the results in row order. For a
function that treats its rows independently (a train's stop does not depend on the other trains of
its batch) the result is the same bit for bit as ``function(rows)`` in this process, whatever the
executor, the workers or the chunk size.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np

from .base import Executor


class RowsOnExecutor:
    """``function(rows, **keywords)`` on ``executor``, ``chunk_rows`` rows per task.

    ``function`` must pickle for executors that run elsewhere (a bound method of a picklable
    object, such as :class:`~brakegym.safety.model.BrakingModel`); the executor itself stays here.
    Only this process's rows and results travel.
    """

    def __init__(self, function: Callable[..., np.ndarray], executor: Executor, chunk_rows: int):
        if chunk_rows < 1:
            raise ValueError(f"chunk_rows {chunk_rows}: need at least 1 row per task")
        self.function = function
        self.executor = executor
        self.chunk_rows = chunk_rows

    def __call__(self, rows: np.ndarray, **keywords: Any) -> np.ndarray:
        task = functools.partial(self.function, **keywords) if keywords else self.function
        chunks = [rows[begin : begin + self.chunk_rows] for begin in range(0, len(rows), self.chunk_rows)]
        if not chunks:
            return np.asarray(self.function(rows, **keywords))
        results = self.executor.map(task, chunks, [len(chunk) for chunk in chunks])
        return np.concatenate([np.asarray(result) for result in results])

    def batch_rows(self) -> int:
        """The rows to give per call so that every worker has a few tasks at once."""
        return self.chunk_rows * self.executor.workers * 4
