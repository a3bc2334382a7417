"""Executors on this machine: in this process, or in worker processes.

:class:`InlineExecutor` runs the tasks one after the other in this process; the compiled kernel
shares each batch of trains out over its threads (every core unless
:func:`~brakegym.simulator.kernel.set_kernel_threads` says fewer), so one process uses the machine.
:class:`LocalExecutor` runs them in worker processes, one kernel thread each. Where the platform
can fork, the workers are forked after the kernels are loaded here
(:func:`~brakegym.simulator.kernel.warm_up`) and inherit them; a thread pool does not survive a
fork, which is one more reason why a worker runs single-threaded. Elsewhere they are spawned and
load the kernels from numba's disk cache (about a second each).
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool

from .base import Executor, Item, Progress, Result, WorkerContext, ordered_results, run_task

# Tasks submitted ahead per worker: enough that a worker never waits for the next task, few enough
# that finished results waiting for an earlier one stay few.
_AHEAD_PER_WORKER = 2


class InlineExecutor(Executor):
    """The tasks one after the other in this process, with the kernel on ``kernel_threads``
    threads (None: as this process has it, every core by default)."""

    def __init__(self, kernel_threads: int | None = None):
        if kernel_threads is not None and kernel_threads < 1:
            raise ValueError(f"kernel threads {kernel_threads}: need at least 1")
        self.kernel_threads = kernel_threads

    @property
    def workers(self) -> int:
        return 1

    def map(
        self,
        function: Callable[[Item], Result],
        items: Sequence[Item],
        sizes: Sequence[int] | None = None,
        progress: Progress | None = None,
    ) -> Iterator[Result]:
        if self.kernel_threads is None:
            yield from _in_turn(function, items, sizes, progress)
            return
        from ..simulator import kernel

        before = kernel.kernel_threads()
        kernel.set_kernel_threads(self.kernel_threads)  # refuses more threads than numba has
        try:
            yield from _in_turn(function, items, sizes, progress)
        finally:
            kernel.set_kernel_threads(before)

    def __repr__(self) -> str:
        threads = "" if self.kernel_threads is None else f"kernel_threads={self.kernel_threads}"
        return f"InlineExecutor({threads})"


class LocalExecutor(Executor):
    """The tasks in ``workers`` worker processes on this machine, one kernel thread each.

    The processes are started for each :meth:`map` and end with it, so that they see this
    process as it is when the map begins (its configs, its loaded kernels)."""

    def __init__(self, workers: int):
        if workers < 1:
            raise ValueError(f"workers {workers}: need at least 1")
        self._workers = workers

    @property
    def workers(self) -> int:
        return self._workers

    def map(
        self,
        function: Callable[[Item], Result],
        items: Sequence[Item],
        sizes: Sequence[int] | None = None,
        progress: Progress | None = None,
    ) -> Iterator[Result]:
        if not items:
            return
        from ..simulator import kernel

        fork = "fork" in multiprocessing.get_all_start_methods()
        if fork:
            # Loaded once here, the compiled kernels are inherited by every forked worker.
            kernel.warm_up()
        context = WorkerContext.capture(kernel_threads=1)
        pool = ProcessPoolExecutor(
            min(self._workers, len(items)),
            mp_context=multiprocessing.get_context("fork" if fork else "spawn"),
        )
        try:
            yield from ordered_results(
                lambda index, item: pool.submit(run_task, function, index, item, context),
                items,
                _AHEAD_PER_WORKER * self._workers,
                sizes,
                progress,
                lost=_lost_worker,
            )
        finally:
            pool.shutdown(wait=True, cancel_futures=True)

    def __repr__(self) -> str:
        return f"LocalExecutor(workers={self._workers})"


def _in_turn(
    function: Callable[[Item], Result], items: Sequence[Item], sizes: Sequence[int] | None, progress: Progress | None
) -> Iterator[Result]:
    for index, item in enumerate(items):
        result = run_task(function, index, item, None)
        if progress is not None:
            progress(sizes[index] if sizes is not None else 1)
        yield result


def _lost_worker(error: BaseException) -> str | None:
    if isinstance(error, BrokenProcessPool):
        return "a worker process ended abruptly (killed, or out of memory) while the task ran"
    return None
