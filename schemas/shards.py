"""Write and read a dataset's Parquet shards: ``{table}/{split}-{i:05d}-of-{n:05d}.parquet``.

Each shard is written under a temporary name, fsynced and renamed when complete (with the
user's umask), then the manifest is updated (also atomically); so a killed run leaves no half
shard under a final name and a manifest that still describes the data that was complete before.

Every read checks what the manifest promises before trusting a shard: the path stays inside the
dataset, the size and sha256 match (the hash once per process per file; ``verify=False`` or
``MIMICBENCH_VERIFY=0`` skips the hash), the schema version is known, the row count matches, and
a table derived from other tables of the dataset was made from their current content.
A missing manifest, a table the manifest does not list, or a dataset marked incomplete is an
error (:class:`DatasetError`, naming the file), never an empty result.
"""
from __future__ import annotations

import math
import os
import re
import tempfile
from pathlib import Path
from typing import Any, Sequence

import pyarrow as pa
import pyarrow.parquet as pq

from mimicbench.schemas.columns import records_to_table, table_to_records
from mimicbench.schemas.errors import os_error_at
from mimicbench.schemas.errors import DatasetError
from mimicbench.schemas.fingerprint import stale_inputs
from mimicbench.schemas.integrity import entry_path, verify_shard
from mimicbench.schemas.manifest import (chmod_like_open, fsync_file, incomplete_reason, is_complete, load_manifest,
                              load_manifest_for_write, save_manifest, sha256_of)
from mimicbench.schemas.tables import COLUMN_ENCODING, ROW_GROUP_SIZE, record_type, schema_of
from mimicbench.schemas.version import METADATA_KEY, SCHEMA_VERSION, is_compatible

SHARD_RE = re.compile(r"^(?P<split>[A-Za-z0-9_]+)-(?P<i>\d{5})-of-(?P<n>\d{5})\.parquet$")
SPLITS = ("train", "val", "test")

__all__ = ["DatasetError", "SHARD_RE", "SPLITS", "shard_name", "write_records", "write_table", "read_table",
           "read_records", "shard_entries", "has_table", "splits_of", "check_schema", "remove_split"]


def shard_name(split: str, i: int, n: int) -> str:
    return f"{split}-{i:05d}-of-{n:05d}.parquet"


def write_records(
    root: str | os.PathLike,
    table: str,
    records: Sequence[Any],
    split: str,
    rows_per_shard: int = 1000,
    config: dict | None = None,
) -> list[dict]:
    """Write ``records`` of ``table`` for one split as shards, replacing that split's old shards.

    Args:
        root: dataset folder (created if missing).
        table: table name (``characters``, ``motions``, ``pairs``, ``cases``, ``status``).
        records: records of the table's record type, in the order to store.
        split: split name; shards are named after it.
        rows_per_shard: maximum rows per shard.
        config: the stage configuration that produced the rows, stored in the manifest.

    Returns:
        The manifest entries of the new shards.
    """
    rtype = record_type(table)
    arrow = records_to_table(list(records), rtype, table)
    return write_table(root, table, arrow, split, rows_per_shard=rows_per_shard, config=config)


def write_table(root, table: str, arrow: pa.Table, split: str, rows_per_shard: int = 1000,
                config: dict | None = None) -> list[dict]:
    """Write an Arrow table (already in ``table``'s schema) as shards; see :func:`write_records`."""
    if not re.fullmatch(r"[A-Za-z0-9_]+", split):
        raise ValueError(f"split: expected letters, digits or '_', got {split!r}")
    root = Path(root)
    manifest = load_manifest_for_write(root)  # refuses an unreadable or incompatible manifest before any write
    root.mkdir(parents=True, exist_ok=True)
    folder = entry_path(root, table, where=table)  # the table folder must not be a symlink out of the dataset
    folder.mkdir(parents=True, exist_ok=True)
    if not folder.resolve().is_relative_to(root.resolve()):
        raise DatasetError(f"{folder}: leads outside the dataset folder {root} (a symlink); refusing to write there")
    expected = schema_of(table)
    if not arrow.schema.equals(expected, check_metadata=False):
        raise ValueError(f"{table}: table schema differs from the contract:\n{arrow.schema}\nexpected:\n{expected}")
    arrow = arrow.replace_schema_metadata(expected.metadata)
    n = max(1, math.ceil(arrow.num_rows / max(1, rows_per_shard)))
    # Write every shard under a temporary name first; rename only once all are complete.
    temps: list[tuple[str, Path]] = []
    try:
        for i in range(n):
            part = arrow.slice(i * rows_per_shard, rows_per_shard)
            final = folder / shard_name(split, i, n)
            temps.append((_write_parquet_temp(part, final, ROW_GROUP_SIZE.get(table, 1024),
                                              COLUMN_ENCODING.get(table)), final))
    except BaseException:
        for tmp, _ in temps:
            if os.path.exists(tmp):
                os.unlink(tmp)
        raise
    entries = []
    for tmp, final in temps:
        digest = sha256_of(tmp)
        entry = {"path": f"{table}/{final.name}", "split": split, "rows": pq.read_metadata(tmp).num_rows,
                 "bytes": os.path.getsize(tmp), "sha256": digest}
        os.replace(tmp, final)
        entries.append(entry)
    tinfo = manifest["tables"].setdefault(table, {"shards": []})
    old = [s for s in tinfo["shards"] if s["split"] == split]
    tinfo["shards"] = sorted([s for s in tinfo["shards"] if s["split"] != split] + entries, key=lambda s: s["path"])
    tinfo["rows"] = sum(s["rows"] for s in tinfo["shards"])
    if config is not None:
        manifest.setdefault("configs", {})[table] = config
    save_manifest(root, manifest)
    new_paths = {e["path"] for e in entries}
    _unlink_stale(root, [s for s in old if s["path"] not in new_paths])  # another shard count's layout
    return entries


def _unlink_stale(root: Path, entries: list[dict]) -> None:
    """Delete the files of manifest entries no longer listed (only those inside the dataset)."""
    for s in entries:
        try:
            path = entry_path(root, s["path"])
        except DatasetError:
            continue  # never delete outside the dataset
        if path.is_file():
            path.unlink()


def remove_split(root, table: str, split: str) -> None:
    """Drop one split of ``table`` from the manifest, then delete its shards (the table goes when empty)."""
    root = Path(root)
    manifest = load_manifest_for_write(root)
    tinfo = manifest["tables"].get(table)
    if not tinfo:
        return
    gone = [s for s in tinfo["shards"] if s["split"] == split]
    tinfo["shards"] = [s for s in tinfo["shards"] if s["split"] != split]
    tinfo["rows"] = sum(s["rows"] for s in tinfo["shards"])
    if not tinfo["shards"]:
        del manifest["tables"][table]
    save_manifest(root, manifest)
    _unlink_stale(root, gone)


def _leaf_paths(schema: pa.Schema) -> list[str]:
    """Parquet leaf column paths of an Arrow schema (``s_cos.list.element`` for a list column)."""
    def walk(name: str, t: pa.DataType) -> list[str]:
        if pa.types.is_list(t) or pa.types.is_large_list(t):
            return walk(f"{name}.list.element", t.value_type)
        if pa.types.is_struct(t):
            return [p for f in t for p in walk(f"{name}.{f.name}", f.type)]
        return [name]
    return [p for f in schema for p in walk(f.name, f.type)]


def _write_parquet_temp(table: pa.Table, final: Path, row_group_size: int,
                        column_encoding: dict | None = None) -> str:
    """Write ``table`` to a temporary file beside ``final``; return its path (removed on error).

    ``column_encoding``: {leaf column path: Parquet encoding} for columns that do better without
    the dictionary encoding (``mimicbench.schemas.tables.COLUMN_ENCODING``); the others keep it.
    """
    fd, tmp = tempfile.mkstemp(prefix=f".{final.name}.", suffix=".tmp", dir=final.parent)
    os.close(fd)
    encoding = {}
    if column_encoding:
        leaves = _leaf_paths(table.schema)
        encoding = {"use_dictionary": [p for p in leaves if p not in column_encoding],
                    "column_encoding": column_encoding}
    try:
        pq.write_table(table, tmp, row_group_size=row_group_size, compression="zstd", **encoding)
        fsync_file(tmp)
        chmod_like_open(tmp)
    except BaseException as exc:
        if os.path.exists(tmp):  # pyarrow may already have removed it: never hide the real error behind that
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise os_error_at(exc, final) from exc
        raise
    return tmp


def reader_manifest(root, allow_incomplete: bool) -> dict:
    """The manifest of ``root`` for reading: DatasetError when missing, or incomplete unless allowed."""
    manifest = load_manifest(root)
    if not allow_incomplete and not is_complete(manifest):
        raise DatasetError(incomplete_reason(root, manifest))
    return manifest


def shard_entries(root, table: str, split: str | None = None, allow_incomplete: bool = False) -> list[dict]:
    """Manifest entries of ``table``'s shards (of one split, or all).

    Raises:
        DatasetError: no readable manifest, or the dataset is marked incomplete (unless
            ``allow_incomplete``: a stage resuming its own output).
    """
    return entries_of(reader_manifest(root, allow_incomplete), table, split)


def entries_of(manifest: dict, table: str, split: str | None = None) -> list[dict]:
    """The entries ``manifest`` lists for ``table``'s shards (of one split, or all); no checks."""
    shards = manifest.get("tables", {}).get(table, {}).get("shards", [])
    return [s for s in shards if split is None or s["split"] == split]


def has_table(root, table: str, split: str | None = None, allow_incomplete: bool = False) -> bool:
    """True when the manifest lists shards of ``table`` (of ``split``); errors as :func:`shard_entries`."""
    return bool(shard_entries(root, table, split, allow_incomplete))


def read_table(root, table: str, split: str | None = None, columns: list[str] | None = None, *,
               verify: bool | None = None, allow_incomplete: bool = False) -> pa.Table:
    """Read ``table`` (one split, or all) from the shards the manifest lists, checking each one.

    Args:
        verify: check each shard's sha256 against the manifest (hashed once per process per
            file); None (default) means yes unless ``MIMICBENCH_VERIFY=0``. Sizes, schema
            versions, column types and row counts are always checked.
        allow_incomplete: read a dataset marked incomplete (a stage resuming its own output).

    Raises:
        DatasetError: naming the file: no manifest; the dataset is incomplete; the manifest lists
            no shard of ``table`` (of ``split``); a shard path leaves the dataset folder; a shard is
            missing, of another size or sha256, unreadable, of another schema version, has wrong
            column types or another row count than the manifest says; ``table`` was derived from
            tables of this dataset that have changed since (e.g. pairs after a new zoo).
    """
    root = Path(root)
    return read_entries(root, table, readable_entries(root, table, split, allow_incomplete), columns, verify)


def read_entries(root: Path, table: str, entries: list[dict], columns: list[str] | None = None,
                 verify: bool | None = None) -> pa.Table:
    """The shards ``entries`` of ``table`` read with the per-shard checks of :func:`read_table`."""
    expected = schema_of(table)
    if columns is not None:
        expected = pa.schema([expected.field(c) for c in columns], metadata=expected.metadata)
    return pa.concat_tables([read_checked_shard(root, e, expected, columns, verify) for e in entries])


def readable_entries(root: Path, table: str, split: str | None, allow_incomplete: bool) -> list[dict]:
    """The manifest's shard entries of ``table`` (of ``split``), after the dataset-level checks of
    :func:`read_table` (manifest present and complete, ``table`` not stale, at least one shard)."""
    return checked_entries(root, reader_manifest(root, allow_incomplete), table, split)


def checked_entries(root: Path, manifest: dict, table: str, split: str | None) -> list[dict]:
    """:func:`readable_entries` with the manifest already read (and its completeness checked)."""
    stale = stale_inputs(root, manifest, table)
    if stale:
        raise DatasetError(stale)
    entries = entries_of(manifest, table, split)
    if not entries:
        what = f"table {table!r}" + (f" split {split!r}" if split is not None else "")
        raise DatasetError(f"{root}/manifest.json lists no shard of {what} (present: "
                           f"{', '.join(sorted(manifest['tables'])) or 'no tables'})")
    return entries


def read_checked_shard(root: Path, entry: dict, expected: pa.Schema, columns: list[str] | None = None,
                       verify: bool | None = None) -> pa.Table:
    """One shard of a manifest ``entry`` with the per-shard checks of :func:`read_table` (path inside
    the dataset, size/sha256, readable Parquet, schema, row count), with ``expected``'s metadata."""
    path = entry_path(root, entry["path"])
    verify_shard(path, entry, verify)
    try:
        t = pq.read_table(path, columns=columns)
    except Exception as exc:  # pyarrow raises several types for damaged files
        raise DatasetError(f"{path}: not a readable Parquet file ({exc})") from exc
    check_schema(path, t.schema, expected)
    if t.num_rows != entry.get("rows"):
        raise DatasetError(f"{path}: {t.num_rows} rows, manifest.json says {entry.get('rows')}")
    return t.replace_schema_metadata(expected.metadata)


def check_schema(path, found: pa.Schema, expected: pa.Schema) -> None:
    """Raise DatasetError naming ``path`` when ``found`` is not ``expected`` (version and types)."""
    meta = found.metadata or {}
    version = meta.get(METADATA_KEY, b"").decode() or None
    if version is None or not is_compatible(version):
        raise DatasetError(f"{path}: schema version {version!r}, expected {SCHEMA_VERSION!r} (same major)")
    for field in expected:
        if field.name not in found.names:
            if field.nullable:
                continue
            raise DatasetError(f"{path}: missing column {field.name!r}")
        got = found.field(field.name).type
        if not got.equals(field.type):
            raise DatasetError(f"{path}: column {field.name!r} has type {got}, expected {field.type}")


def read_records(root, table: str, split: str | None = None, *, verify: bool | None = None,
                 allow_incomplete: bool = False) -> list[Any]:
    """Read ``table`` as records (see :func:`read_table`)."""
    return table_to_records(read_table(root, table, split, verify=verify, allow_incomplete=allow_incomplete),
                            record_type(table))


def splits_of(root, table: str, allow_incomplete: bool = False) -> list[str]:
    """Splits present for ``table``, in train/val/test order first."""
    return ordered_splits(shard_entries(root, table, allow_incomplete=allow_incomplete))


def ordered_splits(entries: list[dict]) -> list[str]:
    """The splits of shard ``entries``, in train/val/test order first."""
    found = {s["split"] for s in entries}
    return [s for s in SPLITS if s in found] + sorted(found - set(SPLITS))
