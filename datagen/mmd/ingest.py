"""The ``datagen ingest`` path for MMD files, without Blender: a .pmx/.pmd model becomes a character
(``assets/<stem>``, :func:`mimicbench.datagen.ingest.identity.character_id_for`) with its rigid bodies and
joints; which .vmd files play on which model: :func:`motions_for`. A malformed file is a failed
status row naming it; the other files go on.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mimicbench.datagen.mmd import MODEL_SUFFIXES, MOTION_SUFFIXES, read_model
from mimicbench.datagen.mmd.frame import MMD_UNIT_METRES
from mimicbench.datagen.mmd.records import character_from_mmd
from mimicbench.datagen.splits import split_of
from mimicbench.schemas.shards import splits_of
from mimicbench.schemas.status import StatusRecord


@dataclass
class MMDIngest:
    """What :func:`load_model` (or :func:`ingest_mmd`) made: records by table, and one status row per file."""

    characters: list = field(default_factory=list)
    motions: list = field(default_factory=list)
    rigid_bodies: list = field(default_factory=list)
    joints: list = field(default_factory=list)
    statuses: list = field(default_factory=list)


def split_mmd_paths(paths) -> tuple[list[Path], list[Path]]:
    """(other paths, MMD paths) by suffix, order kept."""
    mmd = [Path(p) for p in paths if Path(p).suffix.lower() in MODEL_SUFFIXES + MOTION_SUFFIXES]
    return [Path(p) for p in paths if Path(p) not in mmd], mmd


def clip_name(model: Path, motion: Path) -> str | None:
    """The clip name of ``motion`` if its name ties it to ``model`` (``<stem>.vmd`` -> ``<stem>``,
    ``<stem>_<clip>.vmd`` -> ``<clip>``), else None."""
    if motion.stem == model.stem:
        return motion.stem
    if motion.stem.startswith(model.stem + "_") and len(motion.stem) > len(model.stem) + 1:
        return motion.stem[len(model.stem) + 1:]
    return None


def motions_for(model: Path, models: list[Path], given: list[Path]) -> list[tuple[Path, str]]:
    """(.vmd path, clip name) pairs that play on ``model``: the .vmd files beside it or ``given``
    whose names tie them to it (:func:`clip_name`), and the ``given`` ones (the command line,
    ``--motions DIR``) that no model of ``models`` claims by name: those play on every model."""
    out: dict[Path, str] = {}
    beside = sorted(p for p in model.parent.glob("*") if p.suffix.lower() in MOTION_SUFFIXES)
    for p in beside + list(given):
        name = clip_name(model, p)
        if name is not None:
            out[p.resolve()] = name
    for p in given:
        if not any(clip_name(m, p) for m in models):
            out.setdefault(p.resolve(), p.stem)
    return sorted(out.items(), key=lambda kv: str(kv[0]))


def load_model(item: tuple) -> MMDIngest:
    """One model and the motions that play on it: the MMD loader's per-item function.

    Args:
        item: ``(model path, character ID, split, category, metres per MMD unit, the most frames a
            motion may have (None: the default), ((.vmd path, clip name), ...))``; ``unknown`` as
            the category keeps the MMD guess (``humanoid`` when the standard humanoid bones are present).

    Returns:
        Its records by table and a status row for the model and each motion (a malformed file is
        a failed row naming it, not an exception).
    """
    from mimicbench.datagen.mmd.motion import motion_from_vmd
    from mimicbench.datagen.mmd.physics import physics_records
    from mimicbench.datagen.mmd.vmd import read_vmd

    path, cid, split, category, scale, max_frames, motions = item
    path = Path(path)
    out = MMDIngest()
    start = time.perf_counter()
    try:
        model = read_model(path)
        char = character_from_mmd(model, cid, str(path), split, category, scale)
        new_index = np.empty(len(model.bones), np.int64)
        new_index[char.meta["mmd"]["file_bone_index"]] = np.arange(len(model.bones))
        bodies, joints = physics_records(model, cid, new_index, scale)
    except (ValueError, OSError) as e:  # MMDFormatError is a ValueError
        out.statuses.append(StatusRecord(str(path), "ingest", "failed", _reason(e, path), time.perf_counter() - start))
        return out
    out.characters.append(char)
    out.rigid_bodies += bodies
    out.joints += joints
    out.statuses.append(StatusRecord(str(path), "ingest", "ok", "", time.perf_counter() - start))
    reports = char.meta["mmd"].setdefault("motions", {})
    for vmd_path, name in motions:
        start = time.perf_counter()
        vmd_path = Path(vmd_path)
        try:
            rec, report = motion_from_vmd(read_vmd(vmd_path), model, char, name, str(vmd_path), scale,
                                          max_frames=max_frames)
        except (ValueError, OSError) as e:
            out.statuses.append(StatusRecord(str(vmd_path), "ingest", "failed", _reason(e, vmd_path),
                                             time.perf_counter() - start))
            continue
        out.motions.append(rec)
        reports[name] = report
        note = f"on {cid}: {report['matched']} bones matched, {len(report['unmatched'])} unmatched" \
               + (f" ({', '.join(report['unmatched'][:5])})" if report["unmatched"] else "") \
               + f"; {report['ignored_morph_keys']} morph keys ignored"
        out.statuses.append(StatusRecord(str(vmd_path), "ingest", "ok", note, time.perf_counter() - start))
    return out


def model_items(paths, category_for=None, scale: float = MMD_UNIT_METRES, taken: dict | None = None,
                max_frames: int | None = None, split_for=split_of) -> tuple[list[tuple], list[StatusRecord]]:
    """The :func:`load_model` items of the MMD files ``paths`` (.pmx/.pmd/.vmd), and failed rows
    for .vmd motions given without any model.

    Args:
        category_for: ``Path -> category`` (default ``unknown``).
        taken: character ID -> source path already holding it (the dataset's and this run's other
            formats); updated with the IDs given here, so no two sources share an ID.
        split_for: character ID -> split (default the hashed split).
    """
    from mimicbench.datagen.ingest.identity import character_id_for

    models = [Path(p) for p in paths if Path(p).suffix.lower() in MODEL_SUFFIXES]
    given = [Path(p) for p in paths if Path(p).suffix.lower() in MOTION_SUFFIXES]
    taken = {} if taken is None else taken
    items = []
    for path in models:
        cid = character_id_for(path, taken)
        taken[cid] = str(path)
        items.append((str(path), cid, split_for(cid), category_for(path) if category_for else "unknown", scale,
                      max_frames, tuple((str(v), name) for v, name in motions_for(path, models, given))))
    lone = [] if models else [StatusRecord(str(p), "ingest", "failed",
                                           f"{p}: a .vmd motion needs a .pmx/.pmd model in the same run", 0.0)
                              for p in given]
    return items, lone


def ingest_mmd(paths, category_for=None, scale: float = MMD_UNIT_METRES, taken: dict | None = None,
               max_frames: int | None = None, split_for=split_of) -> MMDIngest:
    """Read MMD models and their motions into records, here (:func:`model_items`, :func:`load_model`);
    ``datagen ingest`` runs the same items through its stage driver."""
    items, lone = model_items(paths, category_for, scale, taken, max_frames, split_for)
    out = MMDIngest()
    for item in items:
        one = load_model(item)
        for name in ("characters", "motions", "rigid_bodies", "joints", "statuses"):
            getattr(out, name).extend(getattr(one, name))
    out.statuses += lone
    return out


def write_physics(run, out: MMDIngest) -> None:
    """Write this run's rigid bodies and joints into ``run``'s folder (after its ``begin()``),
    keeping the rows of characters that earlier runs ingested into the same dataset (ingest merges
    characters across runs)."""
    split = {c.character_id: c.split for c in out.characters}
    for table, rows in (("rigid_bodies", out.rigid_bodies), ("joints", out.joints)):
        earlier = splits_of(run.out_dir, table, allow_incomplete=True) if run.manifest() is not None else []
        by_split = {sp: run.earlier_rows(table, sp, drop=split) for sp in earlier}
        for r in rows:
            by_split.setdefault(split[r.character_id], []).append(r)
        for sp in sorted(set(by_split) | set(split.values())):
            run.write(table, by_split.get(sp, []), sp)


def _reason(e: Exception, path: Path) -> str:
    text = str(e)
    return text if str(path) in text else f"{path}: {text}"
