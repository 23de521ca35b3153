"""manifest.json: schema version, shards with row counts and sha256, and the configs that built them."""
from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path

from schemas.version import SCHEMA_VERSION

MANIFEST = "manifest.json"


def sha256_of(path: str | os.PathLike, chunk: int = 1 << 20) -> str:
    """Hex sha256 of a file."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while True:
            b = f.read(chunk)
            if not b:
                break
            h.update(b)
    return h.hexdigest()


def empty_manifest() -> dict:
    return {"format": "mimicbench-dataset", "schema_version": SCHEMA_VERSION, "tables": {}, "configs": {}}


def load_manifest(root: str | os.PathLike) -> dict:
    """Read ``root/manifest.json``; a missing manifest is an empty one."""
    path = Path(root) / MANIFEST
    if not path.exists():
        return empty_manifest()
    with open(path) as f:
        return json.load(f)


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to a temporary file beside ``path``, then rename it into place."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def save_manifest(root: str | os.PathLike, manifest: dict) -> None:
    """Write the manifest atomically."""
    atomic_write_bytes(Path(root) / MANIFEST, (json.dumps(manifest, indent=2, sort_keys=True) + "\n").encode())
