"""Write and read a dataset's Parquet shards: ``{table}/{split}-{i:05d}-of-{n:05d}.parquet``.

Each shard is written under a temporary name and renamed when complete, then the manifest is
updated (also atomically); so a killed run leaves no half shard under a final name and a
manifest that still describes the data that was complete before.
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

from schemas.columns import records_to_table, table_to_records
from schemas.manifest import load_manifest, save_manifest, sha256_of
from schemas.tables import ROW_GROUP_SIZE, record_type, schema_of
from schemas.version import METADATA_KEY, SCHEMA_VERSION, is_compatible

SHARD_RE = re.compile(r"^(?P<split>[A-Za-z0-9_]+)-(?P<i>\d{5})-of-(?P<n>\d{5})\.parquet$")
SPLITS = ("train", "val", "test")


class DatasetError(RuntimeError):
    """A dataset folder is not as its manifest and the schema say."""


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
    folder = root / table
    folder.mkdir(parents=True, exist_ok=True)
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
            temps.append((_write_parquet_temp(part, final, ROW_GROUP_SIZE.get(table, 1024)), final))
    except BaseException:
        for tmp, _ in temps:
            if os.path.exists(tmp):
                os.unlink(tmp)
        raise
    entries = []
    for tmp, final in temps:
        os.replace(tmp, final)
        entries.append({"path": f"{table}/{final.name}", "split": split,
                        "rows": pq.read_metadata(final).num_rows, "sha256": sha256_of(final)})
    manifest = load_manifest(root)
    tinfo = manifest["tables"].setdefault(table, {"shards": []})
    old = [s for s in tinfo["shards"] if s["split"] == split]
    tinfo["shards"] = sorted([s for s in tinfo["shards"] if s["split"] != split] + entries, key=lambda s: s["path"])
    tinfo["rows"] = sum(s["rows"] for s in tinfo["shards"])
    manifest["schema_version"] = SCHEMA_VERSION
    if config is not None:
        manifest.setdefault("configs", {})[table] = config
    save_manifest(root, manifest)
    new_paths = {e["path"] for e in entries}
    for s in old:  # shards of an earlier layout (another shard count) are now stale
        if s["path"] not in new_paths and (root / s["path"]).exists():
            (root / s["path"]).unlink()
    return entries


def _write_parquet_temp(table: pa.Table, final: Path, row_group_size: int) -> str:
    """Write ``table`` to a temporary file beside ``final``; return its path (removed on error)."""
    fd, tmp = tempfile.mkstemp(prefix=f".{final.name}.", suffix=".tmp", dir=final.parent)
    os.close(fd)
    try:
        pq.write_table(table, tmp, row_group_size=row_group_size, compression="zstd")
    except BaseException:
        os.unlink(tmp)
        raise
    return tmp


def shard_entries(root, table: str, split: str | None = None) -> list[dict]:
    """Manifest entries of ``table``'s shards (of one split, or all)."""
    manifest = load_manifest(root)
    shards = manifest.get("tables", {}).get(table, {}).get("shards", [])
    return [s for s in shards if split is None or s["split"] == split]


def has_table(root, table: str, split: str | None = None) -> bool:
    return bool(shard_entries(root, table, split))


def read_table(root, table: str, split: str | None = None, columns: list[str] | None = None) -> pa.Table:
    """Read ``table`` (one split, or all) from the shards the manifest lists, checking the schema.

    Raises:
        DatasetError: a listed shard is missing, unreadable, of another schema version, or has
            wrong column types.
    """
    root = Path(root)
    entries = shard_entries(root, table, split)
    expected = schema_of(table)
    if columns is not None:
        expected = pa.schema([expected.field(c) for c in columns], metadata=expected.metadata)
    parts = []
    for e in entries:
        path = root / e["path"]
        if not path.exists():
            raise DatasetError(f"{path}: listed in manifest.json but missing")
        try:
            t = pq.read_table(path, columns=columns)
        except Exception as exc:  # pyarrow raises several types for damaged files
            raise DatasetError(f"{path}: not a readable Parquet file ({exc})") from exc
        check_schema(path, t.schema, expected)
        parts.append(t.replace_schema_metadata(expected.metadata))
    if not parts:
        return expected.empty_table()
    return pa.concat_tables(parts)


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


def read_records(root, table: str, split: str | None = None) -> list[Any]:
    """Read ``table`` as records (see :func:`read_table`)."""
    return table_to_records(read_table(root, table, split), record_type(table))


def splits_of(root, table: str) -> list[str]:
    """Splits present for ``table``, in train/val/test order first."""
    found = {s["split"] for s in shard_entries(root, table)}
    return [s for s in SPLITS if s in found] + sorted(found - set(SPLITS))
