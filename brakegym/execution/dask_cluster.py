"""The Dask executor: the tasks on a Dask distributed cluster.

Either an existing cluster, given by its scheduler's address (``tcp://host:8786``), whose workers
must have brakegym (and the same versions of numpy and numba, for the same numbers) and the config
folders of this process at the same paths; or a local cluster that the executor starts with N
worker processes of one thread each and closes with itself. Each task runs with one kernel thread,
whatever the cluster's threads per worker.

distributed is an optional dependency (the extra ``dask``); it is imported when an executor is
made, not with this module.
"""

from __future__ import annotations

import logging
import uuid
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from .base import (
    Executor,
    ExecutorUnavailable,
    Item,
    Progress,
    Result,
    WorkerContext,
    available_cores,
    ordered_results,
    run_task,
)

INSTALL_HINT = "pip install 'brakegym[dask]' (or: pip install distributed)"
# How long to wait for an existing scheduler before giving up (distributed retries until then).
CONNECT_TIMEOUT_S = 20.0
# Tasks submitted ahead per worker thread (see local.py).
_AHEAD_PER_THREAD = 2


class DaskExecutor(Executor):
    """The tasks on a Dask cluster: the scheduler at ``address`` (waiting up to
    ``connect_timeout_s`` for it), or else a local cluster of ``workers`` processes (one thread
    each, default one per core) started here and closed by :meth:`close`."""

    def __init__(
        self, address: str | None = None, workers: int | None = None, connect_timeout_s: float = CONNECT_TIMEOUT_S
    ):
        if address is not None and workers is not None:
            raise ValueError(
                f"workers {workers}: the Dask cluster at {address} has its own workers; give the address or a "
                "number of workers for a local cluster, not both"
            )
        if workers is not None and workers < 1:
            raise ValueError(f"workers {workers}: need at least 1")
        try:
            import distributed
        except ImportError:
            raise ExecutorUnavailable(f"the Dask executor needs the package distributed: {INSTALL_HINT}") from None
        self._cluster: Any = None
        if address is None:
            self._cluster = distributed.LocalCluster(
                n_workers=workers or available_cores(),
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.CRITICAL,  # a failed task is raised here as TaskFailed
            )
            self._client = distributed.Client(self._cluster)
        else:
            try:
                self._client = distributed.Client(address, timeout=f"{connect_timeout_s}s")
            except (OSError, TimeoutError) as error:
                raise ExecutorUnavailable(f"cannot reach the Dask scheduler at {address}: {error}") from None
        self.address = self._client.scheduler.address

    @property
    def workers(self) -> int:
        """Worker threads of the cluster now."""
        return max(1, sum(self._client.nthreads().values()))

    def map(
        self,
        function: Callable[[Item], Result],
        items: Sequence[Item],
        sizes: Sequence[int] | None = None,
        progress: Progress | None = None,
    ) -> Iterator[Result]:
        context = WorkerContext.capture(kernel_threads=1)
        prefix = f"brakegym-{uuid.uuid4().hex[:12]}"

        def submit(index: int, item: Item) -> Any:
            return self._client.submit(
                run_task, function, index, item, context, key=f"{prefix}-{index}", pure=False, retries=0
            )

        return ordered_results(submit, items, _AHEAD_PER_THREAD * self.workers, sizes, progress, lost=_lost_task)

    def close(self) -> None:
        """Disconnect; shut the local cluster down if this executor started it."""
        self._client.close()
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    def __repr__(self) -> str:
        return f"DaskExecutor(address={self.address!r})"


def _lost_task(error: BaseException) -> str | None:
    if type(error).__name__ == "KilledWorker":
        return f"the Dask workers that ran the task died ({error})"
    if type(error).__name__ == "CancelledError":
        return "the task was cancelled on the Dask cluster (did the scheduler or the client go away?)"
    return None
