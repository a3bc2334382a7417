"""A campaign cut into chunks of stops, run on an executor, its rows kept in memory or in a folder.

A campaign numbers its stops 0 ... n - 1 in its own order; a chunk is a run of consecutive stops,
its size fixed by the campaign (``brakegym.defaults.DEFAULT_CHUNK_STOPS`` for the field campaign, one
load case for the dynamometer's), never by the number of workers. A chunk's task computes its rows from the
campaign's seed and its stops' numbers alone (the scatter from per-stop random streams,
:meth:`~brakegym.plants.TrainScatter.draw_for_samples`), and a train's result does not depend on
the other trains of its batch, so the rows are the same bit for bit whatever the executor, the
number of workers or the chunk size.

A task returns tables: ``{table: {column: 1-D array}}`` (``"stops"``: one row per stop).
:func:`run_chunks` keeps them in memory, or writes each chunk's to a
:class:`~brakegym.campaigns.store.CampaignStore` as it comes and skips the chunks already there;
:class:`CampaignRows` gives them back chunk by chunk, from either.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..execution import Executor, InlineExecutor
from ..execution.base import Progress
from .store import CampaignStore

ChunkTables = Mapping[str, Mapping[str, np.ndarray]]


@dataclass(frozen=True)
class Chunk:
    """Stops ``start`` ... ``stop - 1`` of a campaign, its chunk number ``index``."""

    index: int
    start: int
    stop: int

    @property
    def size(self) -> int:
        return self.stop - self.start

    def sample_index(self) -> np.ndarray:
        """The stops' numbers, the sample indices of their random streams."""
        return np.arange(self.start, self.stop, dtype=np.int64)

    def __str__(self) -> str:
        return f"chunk {self.index}: stops {self.start} to {self.stop - 1}"


def even_chunks(n_stops: int, chunk_size: int) -> list[Chunk]:
    """``n_stops`` stops in chunks of ``chunk_size`` (the last one shorter)."""
    if chunk_size < 1:
        raise ValueError(f"chunk size {chunk_size}: need at least 1 stop")
    return [
        Chunk(index, start, min(start + chunk_size, n_stops))
        for index, start in enumerate(range(0, n_stops, chunk_size))
    ]


def chunks_between(boundaries: Sequence[int]) -> list[Chunk]:
    """Chunks from each boundary to the next (``[0, 150, 300]``: stops 0-149 and 150-299)."""
    return [Chunk(index, int(a), int(b)) for index, (a, b) in enumerate(zip(boundaries[:-1], boundaries[1:]))]


class CampaignRows:
    """The rows a campaign's chunks gave, chunk by chunk in chunk order: held in memory, or in a
    :class:`~brakegym.campaigns.store.CampaignStore`."""

    def __init__(self, chunks: Sequence[Chunk], held: Sequence[ChunkTables] | None, store: CampaignStore | None):
        if (held is None) == (store is None):
            raise ValueError("rows are either held in memory or in a store")
        if held is not None and len(held) != len(chunks):
            raise ValueError(f"{len(held)} chunks of rows held for {len(chunks)} chunks")
        self.chunks = list(chunks)
        self.store = store
        self._held = held

    def read(self, table: str, columns: Sequence[str] | None = None) -> Iterator[dict[str, np.ndarray]]:
        """The columns ``columns`` (default: all) of ``table``, one chunk at a time."""
        for position, chunk in enumerate(self.chunks):
            if self._held is not None:
                rows = self._held[position][table]
                yield {name: rows[name] for name in (columns if columns is not None else rows)}
            else:
                assert self.store is not None
                yield self.store.read(table, chunk.index, columns)

    def concatenated(self, table: str, columns: Sequence[str] | None = None) -> dict[str, np.ndarray]:
        """The columns of ``table`` of every chunk, joined: all of them in memory at once."""
        parts = list(self.read(table, columns))
        return {name: np.concatenate([part[name] for part in parts]) for name in parts[0]}


def run_chunks(
    task: Callable[[Chunk], ChunkTables],
    chunks: Sequence[Chunk],
    executor: Executor | None = None,
    store: CampaignStore | None = None,
    progress: Progress | None = None,
) -> CampaignRows:
    """``task(chunk)`` for every chunk on ``executor`` (default: this process). Without ``store``
    the results are held in memory; with it, each chunk's tables are written to the store as they
    come, and the chunks already finished there are skipped (``progress`` is told their stops
    first)."""
    executor = executor or InlineExecutor()
    if store is None:
        held = list(executor.map(task, chunks, [chunk.size for chunk in chunks], progress))
        return CampaignRows(chunks, held, None)
    tables = list(store.manifest["tables"])
    finished = store.finished([chunk.index for chunk in chunks], tables)
    if progress is not None and finished:
        progress(sum(chunk.size for chunk in chunks if chunk.index in finished))
    todo = [chunk for chunk in chunks if chunk.index not in finished]
    for chunk, result in zip(todo, executor.map(task, todo, [chunk.size for chunk in todo], progress)):
        missing = set(tables) - set(result)
        if missing:
            raise ValueError(f"{chunk}: the task gave no table {sorted(missing)}")
        store.write(chunk.index, result)
    return CampaignRows(chunks, None, store)
