"""Deterministic train/val/test splits from character IDs (or a split file)."""
from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path

DEFAULT_FRACTIONS = {"train": 0.8, "val": 0.1, "test": 0.1}


def split_of(character_id: str, fractions: dict[str, float] | None = None, salt: str = "") -> str:
    """The split of a character: a fixed function of its ID (sha256 bucket), independent of order.

    Args:
        character_id: the stable ID, e.g. ``zoo/quadruped-0007``.
        fractions: split name to fraction, summing to 1; default 80/10/10 train/val/test.
        salt: changes the assignment for all IDs at once (for a reshuffled split).
    """
    fractions = fractions or DEFAULT_FRACTIONS
    total = sum(fractions.values())
    if abs(total - 1.0) > 1e-6:
        raise ValueError(f"fractions: expected values summing to 1, got {total}")
    h = int.from_bytes(hashlib.sha256((salt + character_id).encode()).digest()[:8], "big") / 2**64
    acc = 0.0
    for name, frac in fractions.items():
        acc += frac
        if h < acc:
            return name
    return list(fractions)[-1]


def load_split_file(path: str | Path) -> dict[str, str]:
    """Read a split file: JSON mapping split name to a list of character IDs; returns ID -> split."""
    data = json.loads(Path(path).read_text())
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a JSON object mapping split names to lists of character IDs")
    out: dict[str, str] = {}
    for split, ids in data.items():
        if not re.fullmatch(r"[A-Za-z0-9_]+", split):  # it names shard files: never a path
            raise ValueError(f"{path}: split name {split!r}: expected letters, digits or '_' (it names the shard "
                             f"files {{split}}-00000-of-00001.parquet)")
        if not isinstance(ids, list) or not all(isinstance(c, str) for c in ids):
            raise ValueError(f"{path}: split {split!r}: expected a list of character IDs (strings)")
        for cid in ids:
            if cid in out:
                raise ValueError(f"{path}: character {cid!r} is in both {out[cid]!r} and {split!r}")
            out[cid] = split
    return out


def split_rule(fractions: dict[str, float] | None = None, salt: str = "", split_file: str | Path | None = None) -> dict:
    """A JSON description of how splits are assigned, for a stage's fingerprinted parameters.

    A stage that assigns splits (ingest with :func:`split_of` or a split file) puts this in the
    parameters it passes to :func:`mimicbench.schemas.fingerprint.stage_config`, so output made under another
    split rule, or another split file's content, is not reused on resume.

    Returns:
        ``{"rule": "sha256-bucket", "fractions": ..., "salt": ...}`` or, with ``split_file``,
        ``{"rule": "split-file", "split_file_sha256": <sha256 of the file's bytes>}``.
    """
    if split_file is not None:
        return {"rule": "split-file", "split_file_sha256": hashlib.sha256(Path(split_file).read_bytes()).hexdigest()}
    return {"rule": "sha256-bucket", "fractions": dict(fractions or DEFAULT_FRACTIONS), "salt": salt}
