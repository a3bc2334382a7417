"""The executor interface, the error of a failed task, and what a task takes to its worker.

An executor runs ``function(item)`` for a list of items and yields the results in the order of the
items (:meth:`Executor.map`). A task that raises ends the map with :class:`TaskFailed`, which
names the task and its item, keeps the original error (its ``error``) and the traceback where
it ran; the tasks not yet started are cancelled.

A worker process is not the process that made the work: it has its own config search path and its
own kernel thread count. Each task therefore runs inside the :class:`WorkerContext` captured when
the map began: the config folders of this process, and the kernel's thread count where the
executor says (one thread in worker processes, which already share the cores).
"""

from __future__ import annotations

import abc
import os
import pickle
import traceback
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

#: An item of work: a complete description of one task.
Item = TypeVar("Item")
#: What a task gives for its item.
Result = TypeVar("Result")
#: Told the size of each finished item.
Progress = Callable[[int], None]

# How much of an item a failure message shows.
_ITEM_TEXT_LIMIT = 200


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity where the platform tells it)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


class ExecutorUnavailable(Exception):
    """An executor cannot be had: a package is missing, or a cluster cannot be reached."""


class TaskFailed(RuntimeError):
    """A task raised. ``index`` is the task's place among the items, ``item`` the item as text,
    ``error`` the exception it raised (a stand-in of the same message where that one could not be
    sent back from the worker), ``where`` the traceback in the process that ran it."""

    def __init__(self, index: int, item: str, error: BaseException, where: str):
        super().__init__(index, item, error, where)

    @property
    def index(self) -> int:
        return self.args[0]

    @property
    def item(self) -> str:
        return self.args[1]

    @property
    def error(self) -> BaseException:
        return self.args[2]

    @property
    def where(self) -> str:
        return self.args[3]

    @property
    def summary(self) -> str:
        """Which task failed and how, in one line."""
        return f"task {self.index} ({self.item}) failed: {type(self.error).__name__}: {self.error}"

    def __str__(self) -> str:
        return f"{self.summary}\n\nwhere it ran:\n{self.where}" if self.where else self.summary


class Future(Protocol):
    """What :func:`ordered_results` needs of a submitted task (concurrent.futures and
    distributed futures both have it)."""

    def result(self) -> Any: ...

    def cancel(self) -> Any: ...


@dataclass(frozen=True)
class WorkerContext:
    """What a task carries to the process that runs it: the config folders searched before the
    shipped configs (``--config-path`` and ``$BRAKEGYM_CONFIG_PATH``), and the most kernel
    threads the task may use (None: as the process has it)."""

    config_folders: tuple[str, ...]
    kernel_threads: int | None

    @classmethod
    def capture(cls, kernel_threads: int | None) -> WorkerContext:
        """The context of this process now."""
        from .. import config as cfg

        # The last folder of the search path is the shipped configs, which every worker has.
        return cls(tuple(str(folder) for folder in cfg.search_path()[:-1]), kernel_threads)

    @contextmanager
    def applied(self) -> Iterator[None]:
        """This context in the running process, for the duration of a task."""
        from .. import config as cfg

        if self.kernel_threads is None:
            with cfg.config_path(*self.config_folders):
                yield
            return
        from ..simulator import kernel

        before = kernel.kernel_threads()
        kernel.set_kernel_threads(self.kernel_threads)
        try:
            with cfg.config_path(*self.config_folders):
                yield
        finally:
            kernel.set_kernel_threads(before)


def run_task(function: Callable[[Item], Result], index: int, item: Item, context: WorkerContext | None) -> Result:
    """``function(item)`` in ``context`` (None: in the calling process as it is); an error becomes
    :class:`TaskFailed` (picklable, so that it comes back from a worker process or a cluster as it
    is)."""
    try:
        if context is None:
            return function(item)
        with context.applied():
            return function(item)
    except Exception as error:
        where = traceback.format_exc()
        raise TaskFailed(index, _item_text(item), _sendable(error), where) from error


def _item_text(item: object) -> str:
    text = str(item)
    return text if len(text) <= _ITEM_TEXT_LIMIT else text[: _ITEM_TEXT_LIMIT - 3] + "..."


def _sendable(error: Exception) -> BaseException:
    """``error``, or a RuntimeError with its type and message where it does not pickle."""
    try:
        pickle.loads(pickle.dumps(error))
    except Exception:
        return RuntimeError(f"{type(error).__name__}: {error}")
    return error


def ordered_results(
    submit: Callable[[int, Item], Future],
    items: Sequence[Item],
    in_flight: int,
    sizes: Sequence[int] | None,
    progress: Progress | None,
    lost: Callable[[BaseException], str | None] = lambda error: None,
) -> Iterator[Any]:
    """Submit ``items`` (``submit(index, item)``), at most ``in_flight`` at a time, and yield
    their results in item order; ``progress(sizes[i])`` (1 without sizes) as result ``i`` is
    yielded. A task's :class:`TaskFailed` is raised as it is; another error of a future (a worker
    that died, a cluster that went away) is raised as :class:`TaskFailed` of that task, with
    ``lost(error)``'s text where it says what happened. The tasks not yet done are cancelled when
    the caller stops early or a task fails."""
    pending: deque[Future] = deque()
    submitted = 0
    try:
        for index, item in enumerate(items):
            while submitted < len(items) and len(pending) < in_flight:
                pending.append(submit(submitted, items[submitted]))
                submitted += 1
            future = pending.popleft()
            try:
                result = future.result()
            except TaskFailed:
                raise
            except Exception as error:
                reason = lost(error)
                cause = RuntimeError(reason) if reason else _sendable(error)
                raise TaskFailed(index, _item_text(item), cause, "") from error
            if progress is not None:
                progress(sizes[index] if sizes is not None else 1)
            yield result
    finally:
        for future in pending:
            future.cancel()


class Executor(abc.ABC):
    """Runs ``function(item)`` for many items somewhere, the results in item order.

    Use as a context manager (or call :meth:`close`): an executor may hold worker processes or a
    cluster. ``function`` and the items must pickle for executors that run elsewhere (a function
    defined at a module's top level, or an instance of such a class), and the result of a task must
    depend on its item alone."""

    @property
    @abc.abstractmethod
    def workers(self) -> int:
        """How many tasks run at once."""

    @abc.abstractmethod
    def map(
        self,
        function: Callable[[Item], Result],
        items: Sequence[Item],
        sizes: Sequence[int] | None = None,
        progress: Progress | None = None,
    ) -> Iterator[Result]:
        """``function(item)`` for each of ``items``, yielded in item order as they complete.

        Parameters
        ----------
        function
            The work of one item.
        items
            The items, each a complete description of its work.
        sizes
            The amount of work of each item (stops), for ``progress``; 1 each if not given.
        progress
            Called with an item's size as its result is yielded.

        Raises
        ------
        TaskFailed
            When a task raised, or its worker died; the tasks not yet done are cancelled.
        """

    def close(self) -> None:  # noqa: B027 - executors without resources have nothing to close
        """Release what the executor holds (worker processes, a cluster)."""

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
