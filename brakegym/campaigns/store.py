"""A campaign's folder: its per-stop rows in Parquet, one file per chunk, and a manifest.

Layout of a folder (``brakegym mcs --out DIR``)::

    DIR/manifest.json                    what the campaign is (see below)
    DIR/<table>/chunk-000000.parquet     the rows of table <table> of chunk 0 ("stops": one row per stop)
    DIR/<table>/chunk-000001.parquet     ...

The manifest holds everything that decides the rows: the campaign's kind and configs (campaign,
set-up, vehicle or rig, material, disc, pneumatics), the seed, the integration step, the chunk size,
the number of stops and chunks, the tables and their columns, and the versions of brakegym, numpy
and numba (other versions may round differently). A chunk's file is written to a temporary name and
renamed when complete, so a file that exists is whole; a chunk is finished when the files of all
its tables exist. Opening a folder to resume a campaign compares the manifest with the campaign's
and refuses it, naming each field that differs, unless they are the same; the finished chunks are
then skipped.

pyarrow reads and writes the files; it is imported when a folder is opened.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

MANIFEST = "manifest.json"
FORMAT = "brakegym campaign folder 1"
_TEMPORARY_SUFFIX = ".partial"


class CampaignFolderError(ValueError):
    """A folder that cannot take or give this campaign: another campaign's, not a campaign's, or
    unreadable."""


def versions() -> dict[str, str]:
    """The versions that decide a campaign's numbers bit for bit."""
    import numba

    from .. import __version__

    return {"brakegym": __version__, "numpy": np.__version__, "numba": numba.__version__}


class CampaignStore:
    """A campaign's folder (see the module documentation). Open it with :meth:`open`."""

    def __init__(self, folder: Path, manifest: dict[str, Any]):
        self.folder = folder
        self.manifest = manifest

    @classmethod
    def open(cls, folder: str | Path, manifest: dict[str, Any], resume: bool) -> CampaignStore:
        """The folder ``folder`` for the campaign ``manifest``: created (it must be empty or
        new), or with ``resume``, a folder of the same campaign whose finished chunks are kept
        (a new or empty folder is started)."""
        folder = Path(folder)
        manifest = {"format": FORMAT, **_plain(manifest)}
        path = folder / MANIFEST
        if path.is_file():
            if not resume:
                raise CampaignFolderError(
                    f"{folder} holds a campaign already: resume it (--resume) or choose another folder"
                )
            try:
                stored = json.loads(path.read_text())
            except (OSError, ValueError) as error:
                raise CampaignFolderError(f"{path}: cannot read the manifest ({error})") from None
            differences = manifest_differences(stored, manifest)
            if differences:
                raise CampaignFolderError(
                    f"{folder} holds another campaign; cannot resume it with this one: " + "; ".join(differences)
                )
            store = cls(folder, stored)
            store._remove_partial_files()
            return store
        if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
            raise CampaignFolderError(f"{folder} is not an empty folder and holds no campaign ({MANIFEST})")
        folder.mkdir(parents=True, exist_ok=True)
        _write_atomically(path, (json.dumps(manifest, indent=2) + "\n").encode())
        return cls(folder, manifest)

    def chunk_path(self, table: str, index: int) -> Path:
        """The file of table ``table`` of chunk ``index``."""
        return self.folder / table / f"chunk-{index:06d}.parquet"

    def finished(self, indices: Sequence[int], tables: Sequence[str]) -> set[int]:
        """Which of the chunks ``indices`` have the files of all ``tables``."""
        present = {table: _listing(self.folder / table) for table in tables}
        return {i for i in indices if all(self.chunk_path(t, i).name in present[t] for t in tables)}

    def write(self, index: int, tables: Mapping[str, Mapping[str, np.ndarray]]) -> None:
        """The rows of chunk ``index``: for each table its columns (1-D arrays of one length)."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        for table, columns in tables.items():
            path = self.chunk_path(table, index)
            path.parent.mkdir(exist_ok=True)
            temporary = path.with_name(path.name + _TEMPORARY_SUFFIX)
            pq.write_table(pa.table({name: np.asarray(values) for name, values in columns.items()}), temporary)
            os.replace(temporary, path)

    def read(self, table: str, index: int, columns: Sequence[str] | None = None) -> dict[str, np.ndarray]:
        """The columns ``columns`` (default: all) of table ``table`` of chunk ``index``."""
        import pyarrow.parquet as pq

        path = self.chunk_path(table, index)
        try:
            data = pq.read_table(path, columns=list(columns) if columns is not None else None)
        except (OSError, ValueError, KeyError) as error:
            raise CampaignFolderError(f"{path}: cannot read the rows of chunk {index} ({error})") from None
        return {name: data.column(name).to_numpy() for name in data.column_names}

    def _remove_partial_files(self) -> None:
        for pattern in (f"*{_TEMPORARY_SUFFIX}", f"*/*{_TEMPORARY_SUFFIX}"):
            for partial in self.folder.glob(pattern):
                partial.unlink()


def manifest_differences(stored: Mapping[str, Any], wanted: Mapping[str, Any], prefix: str = "") -> list[str]:
    """Each field where two manifests differ, as ``"field: the folder has X, this campaign Y"``."""
    out = []
    for key in sorted(set(stored) | set(wanted), key=str):
        name = f"{prefix}{key}"
        if key not in wanted:
            out.append(f"{name}: the folder has {_short(stored[key])}, this campaign none")
        elif key not in stored:
            out.append(f"{name}: the folder has none, this campaign {_short(wanted[key])}")
        elif isinstance(stored[key], Mapping) and isinstance(wanted[key], Mapping):
            out += manifest_differences(stored[key], wanted[key], f"{name}.")
        elif stored[key] != wanted[key]:
            out.append(f"{name}: the folder has {_short(stored[key])}, this campaign {_short(wanted[key])}")
    return out


def _short(value: Any) -> str:
    text = json.dumps(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _plain(value: Any) -> Any:
    """``value`` as JSON has it (tuples as lists, numpy scalars as numbers), so that a manifest
    read back compares equal to the one written."""
    return json.loads(json.dumps(value, default=_json_default))


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    raise TypeError(f"not JSON serialisable in a manifest: {type(value).__name__}")


def _listing(folder: Path) -> set[str]:
    try:
        return set(os.listdir(folder))
    except FileNotFoundError:
        return set()


def _write_atomically(path: Path, data: bytes) -> None:
    temporary = path.with_name(path.name + _TEMPORARY_SUFFIX)
    temporary.write_bytes(data)
    os.replace(temporary, path)
