"""Running a campaign's stops in chunks, in worker processes.

Chunk composition is fixed by the caller, so the results do not depend on the number of workers.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Sequence

import numpy as np

from ..applications import StopSummary
from ..simulator import kernel

# Stops run in chunks of this many trains: big enough that numpy's per-call overhead vanishes,
# small enough that the chunks spread over the worker processes.
CHUNK_TRAINS = 1100

Job = tuple[Callable[..., StopSummary], tuple]


def chunks(order: np.ndarray, size: int) -> list[np.ndarray]:
    """``order`` in consecutive pieces of ``size``."""
    return [order[i : i + size] for i in range(0, len(order), size)]


def _call(job: Job) -> StopSummary:
    function, arguments = job
    return function(*arguments)


def _single_threaded_worker() -> None:
    # The workers share the cores already; and a forked process must not touch the parent's
    # thread pool, which did not come with it.
    kernel.set_kernel_threads(1)


def run_chunks(
    jobs: list[Job],
    workers: int,
    progress: Callable[[int], None] | None = None,
    sizes: Sequence[int] | None = None,
) -> list[StopSummary]:
    """Run ``function(*arguments)`` for every job, in ``workers`` forked processes when more than
    one (the stop bookkeeping between the compiled steps holds the GIL, so threads gain little).
    Chunk composition is fixed by the caller, so the results do not depend on ``workers``."""
    results: list[StopSummary] = []
    if workers <= 1 or len(jobs) == 1 or "fork" not in multiprocessing.get_all_start_methods():
        iterator = map(_call, jobs)
        pool = None
    else:
        # Loaded once here, the compiled kernels are inherited by every forked worker.
        kernel.warm_up()
        pool = multiprocessing.get_context("fork").Pool(min(workers, len(jobs)), initializer=_single_threaded_worker)
        iterator = pool.imap(_call, jobs)
    try:
        for index, result in enumerate(iterator):
            results.append(result)
            if progress is not None:
                progress(sizes[index] if sizes is not None else 1)
    finally:
        if pool is not None:
            pool.close()
            pool.join()
    return results


def scatter_back(n: int, indices: list[np.ndarray], parts: list[np.ndarray]) -> np.ndarray:
    """The rows ``parts[k]`` of chunk ``indices[k]`` put back in application order, (n, ...)."""
    first = parts[0]
    out = np.empty((n, *first.shape[1:]), dtype=first.dtype)
    for chunk, part in zip(indices, parts):
        out[chunk] = part
    return out
