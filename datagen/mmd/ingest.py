"""The ``datagen ingest`` path for MMD files: no Blender, the bounded readers of this package.

A .pmx/.pmd file becomes a character (``assets/<stem>``); each .vmd given with it becomes a
motion on it. A malformed file becomes a ``failed`` status row naming the file and the problem,
and the other files go on.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from datagen.mmd import MODEL_SUFFIXES, MOTION_SUFFIXES, read_model
from datagen.mmd.frame import MMD_UNIT_METRES
from datagen.mmd.records import character_from_mmd
from datagen.splits import split_of
from schemas.status import StatusRecord


@dataclass
class MMDIngest:
    """What :func:`ingest_mmd` made: records by table, and one status row per file."""

    characters: list = field(default_factory=list)
    motions: list = field(default_factory=list)
    rigid_bodies: list = field(default_factory=list)
    joints: list = field(default_factory=list)
    statuses: list = field(default_factory=list)


def split_mmd_paths(paths) -> tuple[list[Path], list[Path]]:
    """(other paths, MMD paths) by suffix, order kept."""
    mmd = [Path(p) for p in paths if Path(p).suffix.lower() in MODEL_SUFFIXES + MOTION_SUFFIXES]
    return [Path(p) for p in paths if Path(p) not in mmd], mmd


def ingest_mmd(paths, category_for=None, scale: float = MMD_UNIT_METRES, progress: bool = False) -> MMDIngest:
    """Read MMD models (and motions) into records.

    Args:
        paths: .pmx/.pmd/.vmd files.
        category_for: ``Path -> category`` (``unknown`` keeps the MMD guess: ``humanoid`` when the
            standard humanoid bones are present).
        scale: metres per MMD unit (default 0.08).
    """
    from tqdm.auto import tqdm

    out = MMDIngest()
    models = [Path(p) for p in paths if Path(p).suffix.lower() in MODEL_SUFFIXES]
    for path in tqdm(models, desc="ingest mmd", unit="model", disable=not progress):
        start = time.perf_counter()
        cid = f"assets/{path.stem}"
        try:
            model = read_model(path)
            category = category_for(path) if category_for else "unknown"
            char = character_from_mmd(model, cid, str(path), split_of(cid), category, scale)
        except (ValueError, OSError) as e:  # MMDFormatError is a ValueError
            out.statuses.append(StatusRecord(str(path), "ingest", "failed", _reason(e, path), time.perf_counter() - start))
            continue
        out.characters.append(char)
        out.statuses.append(StatusRecord(str(path), "ingest", "ok", "", time.perf_counter() - start))
    for path in (Path(p) for p in paths if Path(p).suffix.lower() in MOTION_SUFFIXES):
        if not models:
            out.statuses.append(StatusRecord(str(path), "ingest", "failed",
                                             "a .vmd motion needs a .pmx/.pmd model in the same run", 0.0))
    return out


def _reason(e: Exception, path: Path) -> str:
    text = str(e)
    return text if str(path) in text else f"{path}: {text}"
