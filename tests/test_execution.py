"""Executors (brakegym.execution): results in item order whatever runs them, errors that name the
failed task, options checked, the Dask executor on a local cluster."""

from __future__ import annotations

import os
import signal
import sys

import pytest

from brakegym import config as cfg
from brakegym.execution import (
    DaskExecutor,
    ExecutorUnavailable,
    InlineExecutor,
    LocalExecutor,
    TaskFailed,
    executor_from_options,
)


def _square_or_fail(x: int) -> int:
    if x == 5:
        raise ValueError(f"item {x} is refused")
    return x * x


def _die_at_three(x: int) -> int:
    if x == 3:
        os.kill(os.getpid(), signal.SIGKILL)
    return x


def _search_path_and_threads(_: int) -> tuple[list[str], int]:
    from brakegym.simulator import kernel

    return [str(folder) for folder in cfg.search_path()], kernel.kernel_threads()


@pytest.mark.parametrize("executor", [InlineExecutor(), LocalExecutor(1), LocalExecutor(2)], ids=repr)
def test_results_in_item_order_and_progress(executor):
    told = []
    results = list(executor.map(_square_or_fail, [4, 3, 2, 1, 0], sizes=[10, 20, 30, 40, 50], progress=told.append))
    assert results == [16, 9, 4, 1, 0]
    assert told == [10, 20, 30, 40, 50]


@pytest.mark.parametrize("executor", [InlineExecutor(), LocalExecutor(2)], ids=repr)
def test_a_failed_task_names_itself_and_keeps_the_error(executor):
    with pytest.raises(TaskFailed) as failure:
        list(executor.map(_square_or_fail, list(range(8))))
    assert failure.value.index == 5 and failure.value.item == "5"
    assert isinstance(failure.value.error, ValueError)
    assert failure.value.summary == "task 5 (5) failed: ValueError: item 5 is refused"
    assert "_square_or_fail" in failure.value.where  # the traceback where it ran


def test_a_worker_killed_mid_task_is_a_failed_task():
    with pytest.raises(TaskFailed, match="task 3 .* a worker process ended abruptly"):
        list(LocalExecutor(2).map(_die_at_three, list(range(6))))


def test_worker_processes_take_this_process_configs_and_one_kernel_thread(tmp_path):
    with cfg.config_path(tmp_path):
        seen = list(LocalExecutor(2).map(_search_path_and_threads, [0, 1]))
    assert all(path[0] == str(tmp_path) and threads == 1 for path, threads in seen)


def test_executor_options_are_checked():
    with pytest.raises(ValueError, match="executor 'threads': choose one of"):
        executor_from_options("threads")
    with pytest.raises(ValueError, match="a scheduler address .* is for the dask executor, not 'local'"):
        executor_from_options("local", address="tcp://127.0.0.1:8786")
    with pytest.raises(ValueError, match="workers 0"):
        executor_from_options("local", workers=0)
    with pytest.raises(ValueError, match="has its own workers"):
        executor_from_options("dask", workers=2, address="tcp://127.0.0.1:8786")
    assert isinstance(executor_from_options("local", workers=3), LocalExecutor)
    with pytest.raises(ValueError, match="kernel threads 999: need 1"):
        list(executor_from_options("inline", workers=999).map(_square_or_fail, [1]))


def test_dask_without_distributed_says_how_to_install_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed fails
    with pytest.raises(ExecutorUnavailable, match=r"pip install 'brakegym\[dask\]'"):
        DaskExecutor(workers=1)


def test_an_unreachable_scheduler_is_refused_with_its_address():
    pytest.importorskip("distributed")
    with pytest.raises(ExecutorUnavailable, match="cannot reach the Dask scheduler at tcp://127.0.0.1:9"):
        DaskExecutor(address="tcp://127.0.0.1:9", connect_timeout_s=1)


def test_dask_local_cluster_runs_in_order_with_this_process_configs(tmp_path):
    pytest.importorskip("distributed")
    with DaskExecutor(workers=2) as dask:
        assert dask.workers == 2
        assert list(dask.map(_square_or_fail, [4, 3, 2])) == [16, 9, 4]
        with cfg.config_path(tmp_path):
            seen = list(dask.map(_search_path_and_threads, [0, 1]))
        with pytest.raises(TaskFailed, match=r"task 5 \(5\) failed: ValueError: item 5 is refused"):
            list(dask.map(_square_or_fail, list(range(8))))
    assert all(path[0] == str(tmp_path) and threads == 1 for path, threads in seen)
