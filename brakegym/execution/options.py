"""An executor from the command line's options (``--executor``, ``--workers``,
``--dask-address``)."""

from __future__ import annotations

from .base import Executor, available_cores

#: The executors by name, as ``--executor`` takes them.
EXECUTOR_KINDS = ("inline", "local", "dask")


def executor_from_options(kind: str = "inline", workers: int | None = None, address: str | None = None) -> Executor:
    """The executor ``kind`` (one of :data:`EXECUTOR_KINDS`):

    - ``"inline"``: this process, the kernel on ``workers`` threads (default: every core);
    - ``"local"``: ``workers`` worker processes (default: one per core);
    - ``"dask"``: the Dask scheduler at ``address``, or a local cluster of ``workers`` processes
      (default: one per core).

    A Dask cluster is started or connected to here; close the executor when done.
    """
    if kind not in EXECUTOR_KINDS:
        raise ValueError(f"executor {kind!r}: choose one of {list(EXECUTOR_KINDS)}")
    if workers is not None and workers < 1:
        raise ValueError(f"workers {workers}: need at least 1")
    if address is not None and kind != "dask":
        raise ValueError(f"a scheduler address ({address}) is for the dask executor, not {kind!r}")
    if kind == "inline":
        from .local import InlineExecutor

        return InlineExecutor(kernel_threads=workers)
    if kind == "local":
        from .local import LocalExecutor

        return LocalExecutor(workers or available_cores())
    from .dask_cluster import DaskExecutor

    return DaskExecutor(address=address, workers=workers)
