"""Campaigns at scale (brakegym.campaigns.chunks, .store): the same campaign bit for bit whatever
the executor, the number of workers or the chunk size, a local Dask cluster among them; rows in
Parquet files, resumable after an interruption; the command line's options."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from brakegym import config as cfg
from brakegym.campaigns import CampaignFolderError, dyno_campaign, field_campaign
from brakegym.campaigns.field import field_manifest
from brakegym.campaigns.store import CampaignStore
from brakegym.cli import main
from brakegym.execution import DaskExecutor, Executor, InlineExecutor, LocalExecutor
from brakegym.statistics import pooled_mean_std

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def small_campaign() -> cfg.FieldCampaign:
    """The paper's 88 field applications, 6 repetitions: 528 train stops."""
    return cfg.load("campaigns", "field2022").model_copy(update={"repetitions": 6})


@pytest.fixture(scope="module")
def setup() -> cfg.ScatterSetup:
    return cfg.load("setups", "mcs-75-25")


@pytest.fixture(scope="module")
def reference(small_campaign, setup) -> pd.DataFrame:
    """The small campaign in this process, in one chunk."""
    return field_campaign(small_campaign, setup, seed=3, chunk_size=1000).applications


# ------------------------------------------------------------------------------------------------
# The same campaign bit for bit


@pytest.mark.parametrize(
    ("executor", "chunk_size"),
    [(InlineExecutor(kernel_threads=1), 100), (LocalExecutor(1), 77), (LocalExecutor(2), 200)],
    ids=["inline-100", "local1-77", "local2-200"],
)
def test_same_campaign_whatever_the_executor_and_chunk_size(small_campaign, setup, reference, executor, chunk_size):
    result = field_campaign(small_campaign, setup, seed=3, executor=executor, chunk_size=chunk_size)
    assert result.applications.equals(reference)


def test_dask_local_cluster_of_two_workers_gives_the_local_executors_campaign(small_campaign, setup, reference):
    """The issue's test: a local Dask cluster of two worker processes, bit for bit the local
    executor's campaign."""
    pytest.importorskip("distributed")
    local = field_campaign(small_campaign, setup, seed=3, executor=LocalExecutor(2), chunk_size=150)
    with DaskExecutor(workers=2) as dask:
        result = field_campaign(small_campaign, setup, seed=3, executor=dask, chunk_size=150)
    assert result.applications.equals(local.applications)
    assert local.applications.equals(reference)


def test_dynamometer_campaign_the_same_on_processes_and_in_a_folder(tmp_path):
    rig = cfg.load("rigs", "dynamometer")
    setup = cfg.load("setups", "mcs-100")
    inline = dyno_campaign(rig, setup, seed=2)
    stored = dyno_campaign(rig, setup, seed=2, executor=LocalExecutor(2), out=tmp_path / "dyno")
    assert stored.applications.equals(inline.applications)
    assert list(stored.envelopes) == list(inline.envelopes) == [case.name for case in rig.load_cases]
    for name, envelope in inline.envelopes.items():
        assert stored.envelopes[name].equals(envelope), name
    assert len(list((tmp_path / "dyno" / "envelopes").glob("*.parquet"))) == 12


# ------------------------------------------------------------------------------------------------
# Rows in Parquet, resumed


class _InterruptedAfter(Executor):
    """Runs like the inline executor, then stops the campaign (as Ctrl-C would) after ``chunks``
    chunks; counts the tasks it ran."""

    def __init__(self, chunks: int | None):
        self.chunks, self.ran = chunks, 0

    @property
    def workers(self) -> int:
        return 1

    def map(self, function, items, sizes=None, progress=None):
        for result in InlineExecutor().map(function, items, sizes, progress):
            if self.chunks is not None and self.ran == self.chunks:
                raise KeyboardInterrupt
            self.ran += 1
            yield result


def test_stored_campaign_equals_the_in_memory_one(small_campaign, setup, reference, tmp_path):
    stored = field_campaign(small_campaign, setup, seed=3, chunk_size=100, out=tmp_path / "run")
    in_memory = field_campaign(small_campaign, setup, seed=3, chunk_size=100)
    assert stored.applications.equals(reference)
    # Chunks of 100 stops cut field applications of 6 stops apart; the summary joins them.
    assert stored.application_summary().equals(in_memory.application_summary())
    assert in_memory.application_summary().equals(
        field_campaign(small_campaign, setup, seed=3, chunk_size=1000).application_summary()
    )
    csv = tmp_path / "stops.csv"
    stored.write_csv(csv)
    pd.testing.assert_frame_equal(pd.read_csv(csv, dtype={"pad_set": str}), reference, check_exact=False, rtol=1e-15)
    manifest = json.loads((tmp_path / "run" / "manifest.json").read_text())
    assert manifest["seed"] == 3 and manifest["chunk_size"] == 100 and manifest["chunks"] == 6
    assert manifest["configs"]["campaign"]["repetitions"] == 6 and "numba" in manifest["versions"]


def test_an_interrupted_campaign_resumed_equals_an_uninterrupted_one(small_campaign, setup, reference, tmp_path):
    out = tmp_path / "run"
    interrupted = _InterruptedAfter(2)
    with pytest.raises(KeyboardInterrupt):
        field_campaign(small_campaign, setup, seed=3, executor=interrupted, chunk_size=100, out=out)
    assert sorted(p.name for p in (out / "stops").iterdir()) == ["chunk-000000.parquet", "chunk-000001.parquet"]
    (out / "stops" / "chunk-000002.parquet.partial").write_bytes(b"a file cut short by a crash")
    with pytest.raises(CampaignFolderError, match="holds a campaign already: resume it"):
        field_campaign(small_campaign, setup, seed=3, chunk_size=100, out=out)
    told = []
    rest = _InterruptedAfter(None)
    resumed = field_campaign(
        small_campaign, setup, seed=3, executor=rest, chunk_size=100, out=out, resume=True, progress=told.append
    )
    assert rest.ran == 4 and told[0] == 200  # the two finished chunks are not run again
    assert resumed.applications.equals(reference)
    assert not list(out.glob("*/*.partial"))


def test_resume_with_another_campaign_is_refused_naming_the_fields(small_campaign, setup, tmp_path):
    out = tmp_path / "run"
    field_campaign(small_campaign.model_copy(update={"repetitions": 1}), setup, seed=3, chunk_size=50, out=out)
    with pytest.raises(CampaignFolderError) as refusal:
        field_campaign(small_campaign, setup, seed=4, chunk_size=50, out=out, resume=True)
    message = str(refusal.value)
    assert "seed: the folder has 3, this campaign 4" in message
    assert "configs.campaign.repetitions: the folder has 1, this campaign 6" in message
    assert "chunk_size" not in message
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    with pytest.raises(CampaignFolderError, match="not an empty folder and holds no campaign"):
        field_campaign(small_campaign, setup, seed=3, out=tmp_path / "other")


def test_pooled_mean_and_std_of_groups_equal_those_of_the_whole():
    rng = np.random.default_rng(0)
    groups = [rng.normal(3.0, 2.0, size) for size in (1, 5, 40, 7)]
    whole = np.concatenate(groups)
    stds = [g.std(ddof=1) if len(g) > 1 else 0.0 for g in groups]
    mean, std = pooled_mean_std([len(g) for g in groups], [g.mean() for g in groups], stds)
    assert mean == pytest.approx(whole.mean(), rel=1e-13)
    assert std == pytest.approx(whole.std(ddof=1), rel=1e-13)


# ------------------------------------------------------------------------------------------------
# The command line


def _mcs(*extra: str) -> list[str]:
    return ["mcs", "--campaign", "field", "--setup", "mcs-75-25", "--seed", "2", *extra]


def test_cli_campaign_killed_then_resumed_gives_the_uninterrupted_result(tmp_path):
    out = tmp_path / "run"
    process = subprocess.Popen(
        [sys.executable, "-m", "brakegym", *_mcs("--executor", "inline", "--chunk-size", "400", "--out", str(out))],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    deadline = time.monotonic() + 120
    while len(list((out / "stops").glob("*.parquet"))) < 2 and process.poll() is None:
        assert time.monotonic() < deadline, "the campaign wrote no chunks"
        time.sleep(0.05)
    process.kill()
    process.wait()
    finished = len(list((out / "stops").glob("*.parquet")))
    assert finished < 11, "the campaign ended before it was killed; nothing to resume"
    resumed, whole = tmp_path / "resumed.json", tmp_path / "whole.json"
    assert main(_mcs("--out", str(out), "--resume", "--chunk-size", "400", "--json", str(resumed))) == 0
    assert main(_mcs("--executor", "local", "--workers", "2", "--json", str(whole))) == 0
    assert json.loads(resumed.read_text()) == json.loads(whole.read_text())


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (("--resume",), "--resume needs --out DIR"),
        (("--dask-address", "tcp://127.0.0.1:8786"), "--dask-address is for --executor dask, not inline"),
        (("--executor", "dask", "--dask-address", "tcp://h:1", "--workers", "2"), "has its own workers"),
        (("--chunk-size", "0"), "--chunk-size must be at least 1"),
    ],
)
def test_cli_execution_options_are_checked(extra, message, capsys):
    try:
        status = main(_mcs(*extra))
    except SystemExit as exit_:  # argparse's own errors
        status = exit_.code
    assert status == 2
    assert message in capsys.readouterr().err


def test_cli_resume_of_another_campaign_names_the_field(tmp_path, capsys):
    campaign = cfg.load("campaigns", "field2022")
    vehicle = cfg.load("vehicles", campaign.vehicle)
    manifest = field_manifest(campaign, vehicle, cfg.load("setups", "mcs-75-25"), 1, 0.2, 1000, 5)
    CampaignStore.open(tmp_path / "run", manifest, resume=False)
    assert main(_mcs("--out", str(tmp_path / "run"), "--resume")) == 2
    assert "seed: the folder has 1, this campaign 2" in capsys.readouterr().err
    assert main(["mcs", "--campaign", "dyno", "--chunk-size", "10"]) == 2
    assert "one chunk per load case" in capsys.readouterr().err


def test_cli_field_campaign_of_any_size(tmp_path):
    out = tmp_path / "field.json"
    assert main(_mcs("--repetitions", "2", "--out", str(tmp_path / "run"), "--json", str(out))) == 0
    data = json.loads(out.read_text())
    assert data["applications"] == 176 and {row["n"] for row in data["field_applications"]} == {2}
    assert json.loads((tmp_path / "run" / "manifest.json").read_text())["stops"] == 176


def test_cli_dask_without_distributed_says_how_to_install_it(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed fails
    assert main(_mcs("--executor", "dask")) == 2
    assert "pip install 'brakegym[dask]'" in capsys.readouterr().err


def test_cli_task_error_is_a_message(tmp_path, capsys):
    """A scatter too wide for the model, found in a worker process, ends the command with the
    worker's message and status 2."""
    configs = tmp_path / "configs"
    (configs / "materials").mkdir(parents=True)
    material = (REPO / "configs" / "materials" / "ehret2022.yaml").read_text()
    wide = material.replace("initial_mu_sigma: 0.01", "initial_mu_sigma: 0.2")
    assert wide != material
    (configs / "materials" / "ehret2022.yaml").write_text(wide)
    try:
        status = main(["--config-path", str(configs), *_mcs("--executor", "local", "--workers", "2")])
    finally:
        cfg.set_config_path([])  # main() set it for the rest of the process
    assert status == 2
    error = capsys.readouterr().err
    assert "task 0 (chunk 0: stops 0 to 999) failed: ValueError: a drawn initial mu lies outside" in error
