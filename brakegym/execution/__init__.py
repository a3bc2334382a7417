"""Executors: where the chunks of a campaign or a batch of stops run, behind one interface.

:meth:`Executor.map(function, items) <brakegym.execution.base.Executor.map>` calls
``function(item)`` for every item and yields the results in the order of the items as they
complete, so that a caller can write them to disk as they come. Which executor runs them changes
neither a result nor its order: the work must be a function of its item alone (a campaign's chunk
carries its seed and its stops' indices, see :mod:`brakegym.campaigns.chunks`).

- :mod:`.base`: the interface :class:`~.base.Executor`, the error of a failed task
  (:class:`~.base.TaskFailed`), and what a task carries to its worker (the config search path,
  the kernel's thread count).
- :mod:`.local`: :class:`~.local.InlineExecutor`, in this process (the compiled kernel then uses
  every core through its threads), and :class:`~.local.LocalExecutor`, worker processes on this
  machine (forked where the platform allows, inheriting the loaded kernels, one kernel thread each).
- :mod:`.dask_cluster`: :class:`~.dask_cluster.DaskExecutor`, a Dask distributed cluster: an
  existing scheduler's address, or a local cluster of N worker processes (the optional extra
  ``dask``: ``pip install 'brakegym[dask]'``).
- :mod:`.rows`: :class:`~.rows.RowsOnExecutor`, a function of rows (a batch of stops) evaluated on
  an executor in chunks of rows, for the rare-event estimators.
- :mod:`.options`: :func:`~.options.executor_from_options`, an executor from the command line's
  ``--executor``, ``--workers`` and ``--dask-address``.
- :mod:`.blas`: :func:`~.blas.on_one_blas_thread`, the fits' linear algebra on one BLAS thread, so
  that a fit's result does not depend on the machine's cores.

Importing this package loads neither numba nor distributed; the executors load what they run.
"""

from .base import Executor, ExecutorUnavailable, TaskFailed, available_cores
from .dask_cluster import DaskExecutor
from .local import InlineExecutor, LocalExecutor
from .options import EXECUTOR_KINDS, executor_from_options
from .rows import RowsOnExecutor

__all__ = [
    "EXECUTOR_KINDS",
    "DaskExecutor",
    "Executor",
    "ExecutorUnavailable",
    "InlineExecutor",
    "LocalExecutor",
    "RowsOnExecutor",
    "TaskFailed",
    "available_cores",
    "executor_from_options",
]
