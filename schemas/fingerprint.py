"""Fingerprints: short sha256 digests that say which inputs and which parameters made something.

A derived thing (a resampled dataset, correspondences, benchmark cases, benchmark results) records
the fingerprints of the tables it read and of its own configuration; resume reuses earlier work
only when both still match. A table's fingerprint is derived from the sha256 of each of its shards
that ``manifest.json`` lists, so computing it reads only the manifest.
"""
from __future__ import annotations

import hashlib
import json
import os
from typing import Iterable

from schemas.manifest import load_manifest


def digest_of(value) -> str:
    """Hex sha256 of ``value`` as canonical JSON (sorted keys, no spaces); tuples hash like lists.

    Raises:
        TypeError: ``value`` holds something JSON cannot represent (e.g. a numpy array).
    """
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def table_fingerprint(root: str | os.PathLike, table: str, manifest: dict | None = None) -> str:
    """Fingerprint of one table of the dataset at ``root``: its shards' paths, row counts and sha256.

    Raises:
        KeyError: the manifest lists no shard of ``table``.
    """
    manifest = load_manifest(root) if manifest is None else manifest
    shards = manifest.get("tables", {}).get(table, {}).get("shards", [])
    if not shards:
        raise KeyError(f"{root}: manifest.json lists no shard of table {table!r}")
    return digest_of(sorted((s["path"], s["rows"], s["sha256"]) for s in shards))


def tables_fingerprint(root: str | os.PathLike, tables: Iterable[str]) -> dict[str, str]:
    """``{table: fingerprint}`` for each of ``tables`` (see :func:`table_fingerprint`)."""
    manifest = load_manifest(root)
    return {t: table_fingerprint(root, t, manifest) for t in tables}
