"""Write one split of a table shard by shard as rows arrive, holding at most one shard in memory.

:func:`mimicbench.schemas.shards.write_records` needs the whole split at once; a PokeAnimDB-size motions
table (millions of frames) does not fit. :class:`ShardStream` takes rows in their final order,
writes every full shard to a hidden temporary file at once, and on :meth:`ShardStream.close`
renames them to ``{split}-{i:05d}-of-{n:05d}.parquet`` (n is known only then) and lists them in
the manifest, replacing the split's old shards, exactly as ``write_records`` would have written
the same rows with the same ``rows_per_shard`` (the same bytes). A run killed before ``close``
leaves only hidden temporary files (removed by the next stream of that split) and the manifest
as it was.
"""
from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any, Iterable, Iterator

import pyarrow.parquet as pq

from mimicbench.schemas.columns import records_to_table, table_to_records
from mimicbench.schemas.integrity import entry_path, verify_shard
from mimicbench.schemas.manifest import load_manifest_for_write, save_manifest, sha256_of
from mimicbench.schemas.errors import DatasetError
from mimicbench.schemas.shards import (_unlink_stale, _write_parquet_temp, check_schema, read_checked_shard, readable_entries,
                            shard_name)
from mimicbench.schemas.tables import COLUMN_ENCODING, ROW_GROUP_SIZE, record_type, schema_of


class ShardStream:
    """Rows of one ``table`` split, written ``rows_per_shard`` at a time (see the module docstring).

    Use as a context manager, or call :meth:`add` then :meth:`close`; :meth:`abort` drops the
    temporary files. ``config`` is stored in the manifest for the table, as in ``write_records``.
    """

    def __init__(self, root, table: str, split: str, rows_per_shard: int = 1000, config: dict | None = None):
        if not re.fullmatch(r"[A-Za-z0-9_]+", split):
            raise ValueError(f"split: expected letters, digits or '_', got {split!r}")
        if rows_per_shard < 1:
            raise ValueError(f"rows_per_shard: expected >= 1, got {rows_per_shard}")
        self.root, self.table, self.split = Path(root), table, split
        self.rows_per_shard, self.config = rows_per_shard, config
        load_manifest_for_write(self.root)  # refuse an unreadable manifest before writing anything
        self.folder = entry_path(self.root, table, where=table)
        if self.folder.is_dir():
            for old in self.folder.glob(f".{split}-stream-*.tmp"):  # left by a killed run
                old.unlink()
        self.rtype, self.schema = record_type(table), schema_of(table)
        self.buffer: list[Any] = []
        self.temps: list[str] = []
        self.rows = 0

    def add(self, records: Iterable[Any]) -> None:
        """Append records (in their final order); full shards are written at once."""
        for r in records:
            self.buffer.append(r)
            if len(self.buffer) == self.rows_per_shard:
                self._flush()

    def _flush(self) -> None:
        if not self.buffer and self.temps:
            return
        self.folder.mkdir(parents=True, exist_ok=True)
        arrow = records_to_table(self.buffer, self.rtype, self.table).replace_schema_metadata(self.schema.metadata)
        final = self.folder / f"{self.split}-stream-{len(self.temps):05d}"
        tmp = _write_parquet_temp(arrow, final, ROW_GROUP_SIZE.get(self.table, 1024), COLUMN_ENCODING.get(self.table))
        hidden = self.folder / f".{self.split}-stream-{len(self.temps):05d}.tmp"
        os.replace(tmp, hidden)
        self.temps.append(str(hidden))
        self.rows += len(self.buffer)
        self.buffer = []

    def close(self) -> list[dict]:
        """Write the last shard, name every shard, list them in the manifest; return their entries."""
        if self.buffer or not self.temps:
            self._flush()  # an empty split still gets one empty shard, as write_records does
        n = len(self.temps)
        entries = []
        for i, tmp in enumerate(self.temps):
            final = self.folder / shard_name(self.split, i, n)
            entry = {"path": f"{self.table}/{final.name}", "split": self.split, "rows": pq.read_metadata(tmp).num_rows,
                     "bytes": os.path.getsize(tmp), "sha256": sha256_of(tmp)}
            os.replace(tmp, final)
            entries.append(entry)
        self.temps = []
        manifest = load_manifest_for_write(self.root)
        tinfo = manifest["tables"].setdefault(self.table, {"shards": []})
        old = [s for s in tinfo["shards"] if s["split"] == self.split]
        tinfo["shards"] = sorted([s for s in tinfo["shards"] if s["split"] != self.split] + entries,
                                 key=lambda s: s["path"])
        tinfo["rows"] = sum(s["rows"] for s in tinfo["shards"])
        if self.config is not None:
            manifest.setdefault("configs", {})[self.table] = self.config
        save_manifest(self.root, manifest)
        new_paths = {e["path"] for e in entries}
        _unlink_stale(self.root, [s for s in old if s["path"] not in new_paths])
        return entries

    def abort(self) -> None:
        """Drop what was written; the manifest is untouched."""
        for tmp in self.temps:
            if os.path.exists(tmp):
                os.unlink(tmp)
        self.temps, self.buffer = [], []

    def __enter__(self) -> "ShardStream":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


def iter_records(root, table: str, split: str | None = None, *, verify: bool | None = None,
                 allow_incomplete: bool = False) -> Iterator[Any]:
    """The records of ``table`` (one split, or all) one shard at a time, with the checks of
    :func:`mimicbench.schemas.shards.read_table` on each shard; memory holds one shard, not the table."""
    root = Path(root)
    expected, rtype = schema_of(table), record_type(table)
    for e in readable_entries(root, table, split, allow_incomplete):
        yield from table_to_records(read_checked_shard(root, e, expected, verify=verify), rtype)


def checked_parquet_file(root, entry: dict, table: str, verify: bool | None = None) -> pq.ParquetFile:
    """The Parquet file of a manifest ``entry`` of ``table``, after :func:`read_checked_shard`'s
    per-shard checks (path inside the dataset, size/sha256, readable, schema, row count), opened
    for reading row group by row group."""
    root = Path(root)
    path = entry_path(root, entry["path"])
    verify_shard(path, entry, verify)
    try:
        pf = pq.ParquetFile(path)
    except Exception as exc:  # pyarrow raises several types for damaged files
        raise DatasetError(f"{path}: not a readable Parquet file ({exc})") from exc
    check_schema(path, pf.schema_arrow, schema_of(table))
    if pf.metadata.num_rows != entry.get("rows"):
        raise DatasetError(f"{path}: {pf.metadata.num_rows} rows, manifest.json says {entry.get('rows')}")
    return pf


def read_row_group(pf: pq.ParquetFile, i: int, table: str, columns: list[str] | None = None) -> list[Any]:
    """The records of row group ``i`` of a checked file (:func:`checked_parquet_file`)."""
    t = pf.read_row_group(i, columns=columns).replace_schema_metadata(schema_of(table).metadata)
    return table_to_records(t, record_type(table))


def iter_row_groups(root, table: str, split: str | None = None, *, verify: bool | None = None,
                    allow_incomplete: bool = False) -> Iterator[tuple[dict, int, list[Any]]]:
    """``(manifest entry, row group number, its records)`` of ``table`` (one split, or all), in
    stored order, with the checks of :func:`iter_records`. Memory holds one row group (8 rows of
    ``characters``), not a shard: a characters shard of 500 rows of full meshes is gigabytes."""
    for e in readable_entries(Path(root), table, split, allow_incomplete):
        pf = checked_parquet_file(root, e, table, verify)
        for i in range(pf.num_row_groups):
            yield e, i, read_row_group(pf, i, table)
