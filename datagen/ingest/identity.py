"""Names ingest derives from a file: character IDs, cache keys and skeleton IDs.

- **Character ID** ``assets/<stem>``; when that ID is already held by a different source file (in
  the dataset or earlier in the same run), ``assets/<stem>-<8 hex>``, the hex being the start of
  the sha256 of the file's absolute path. So two files with one stem never share an ID, and
  re-ingesting a file keeps its ID.
- **Cache key** ``<stem>-<16 hex of the file's content sha256>-<8 hex of the options digest>``:
  a changed file or changed options (e.g. ``--bvh-scale``) is ingested again, and two files with
  one stem never share a cache entry.
- **Skeleton ID** ``skel-<16 hex>`` of the bone names and parents: equal exactly when both are
  equal, so characters rigged on one skeleton form a family (h2h, same-skeleton cases).
"""
from __future__ import annotations

import hashlib
import re
from pathlib import Path

from mimicbench.schemas.fingerprint import digest_of


def file_sha256(path: str | Path, chunk: int = 1 << 20) -> str:
    """Hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(chunk), b""):
            h.update(block)
    return h.hexdigest()


def safe_stem(path: str | Path) -> str:
    """The file stem with characters other than letters, digits, ``-``, ``_`` and ``.`` as ``_``."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", Path(path).stem) or "asset"


def cache_key(path: str | Path, content_sha256: str, options: dict) -> str:
    """``<stem>-<content hash>-<options digest>`` (see the module docstring)."""
    return f"{safe_stem(path)}-{content_sha256[:16]}-{digest_of(options)[:8]}"


def character_id_for(path: str | Path, taken: dict[str, str]) -> str:
    """The character ID of ``path`` given ``taken`` (ID -> source path already using it); the
    caller records the returned ID in ``taken``."""
    source = str(path)
    base = f"assets/{safe_stem(path)}"
    if taken.get(base, source) == source:
        return base
    return f"{base}-{hashlib.sha256(source.encode()).hexdigest()[:8]}"


def skeleton_id(bone_names, parents) -> str:
    """``skel-`` and 16 hex of the digest of (bone names, parent names): equal exactly when the
    names and the parent relation are equal."""
    names = [str(n) for n in bone_names]
    parent_names = [names[int(p)] if int(p) >= 0 else None for p in parents]
    return "skel-" + digest_of({"bones": names, "parents": parent_names})[:16]
