"""Check a dataset folder against its manifest and the schema: ``mimicbench validate DIR``."""
from __future__ import annotations

from pathlib import Path

import pyarrow.parquet as pq

from schemas.manifest import MANIFEST, sha256_of
from schemas.shards import SHARD_RE, DatasetError, check_schema
from schemas.tables import RECORD_TYPES, schema_of
from schemas.version import SCHEMA_VERSION, is_compatible

import json


def validate_dataset(root) -> list[str]:
    """Problems found in a dataset folder, each naming the file and why; empty when valid.

    Checks: manifest present and parseable with a known schema version; every listed shard
    exists, has its sha256, reads as Parquet with the recorded row count, carries a compatible
    schema version and the contract's column types; no shard file on disk is unlisted.
    """
    root = Path(root)
    problems: list[str] = []
    mpath = root / MANIFEST
    if not root.is_dir():
        return [f"{root}: not a folder"]
    if not mpath.exists():
        return [f"{mpath}: missing"]
    try:
        manifest = json.loads(mpath.read_text())
    except json.JSONDecodeError as exc:
        return [f"{mpath}: not valid JSON ({exc})"]
    version = manifest.get("schema_version")
    if not isinstance(version, str) or not is_compatible(version):
        problems.append(f"{mpath}: unknown schema version {version!r}, expected {SCHEMA_VERSION!r}")
    listed = set()
    for table, info in sorted(manifest.get("tables", {}).items()):
        if table not in RECORD_TYPES:
            problems.append(f"{mpath}: unknown table {table!r}")
            continue
        expected = schema_of(table)
        for entry in info.get("shards", []):
            path = root / entry["path"]
            listed.add(path.resolve())
            if not path.exists():
                problems.append(f"{path}: missing (listed in manifest.json)")
                continue
            digest = sha256_of(path)
            if digest != entry.get("sha256"):
                problems.append(f"{path}: checksum mismatch (sha256 {digest[:12]}..., manifest says "
                                f"{str(entry.get('sha256'))[:12]}...): the file changed or is truncated")
            try:
                meta = pq.read_metadata(path)
                schema = pq.read_schema(path)
            except Exception as exc:
                problems.append(f"{path}: not a readable Parquet file ({exc})")
                continue
            try:
                check_schema(path, schema, expected)
            except DatasetError as exc:
                problems.append(str(exc))
            if meta.num_rows != entry.get("rows"):
                problems.append(f"{path}: {meta.num_rows} rows, manifest says {entry.get('rows')}")
    for table in RECORD_TYPES:
        folder = root / table
        if not folder.is_dir():
            continue
        for f in sorted(folder.glob("*.parquet")):
            if SHARD_RE.match(f.name) and f.resolve() not in listed:
                problems.append(f"{f}: shard on disk but not listed in manifest.json")
    return problems
