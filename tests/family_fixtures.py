"""Test datasets with same-skeleton families of any category, and clips that translate bones."""
from __future__ import annotations

import dataclasses
import shutil

import numpy as np

from mimicbench.schemas.shards import read_records, write_records


def descendants(parents: np.ndarray, k: int) -> list[int]:
    """Bone k and every bone below it (parents[c] < c)."""
    out = [k]
    for c in range(k + 1, len(parents)):
        if parents[c] in out:
            out.append(c)
    return out


def translate_bones(transforms: np.ndarray, parents: np.ndarray, size: float) -> tuple[np.ndarray, list[int]]:
    """A copy of a clip (F, K, 7) in which two non-root bones (a child of the root and the deepest
    bone's parent) and everything below them are also translated, by up to 8% and 5% of ``size``
    (as a body bone and an IK-driven foot would be); frame 0 stays the rest pose."""
    out = np.array(transforms, np.float32)
    f = np.arange(len(out))[:, None] / max(1, len(out) - 1)
    body = int(np.flatnonzero(parents == int(np.flatnonzero(parents < 0)[0]))[0])
    foot = int(parents[len(parents) - 1])
    moved = []
    for k, amp in ((body, [0.02, 0.08, 0.03]), (foot, [0.05, 0.02, -0.04])):
        sub = descendants(parents, k)
        out[1:, sub, 4:] += (np.sin(np.pi * f[1:]) * np.asarray(amp) * size)[:, None, :].astype(np.float32)
        moved.append(k)
    return out, moved


def add_family(zoo_dir, dest, category: str, copies: dict[str, float], shared: bool = False):
    """Copy a zoo to ``dest``; give its first ``category`` character (with ``shared``: the first
    whose skeleton_id another character has) a clip that translates non-root bones, and copies
    of it scaled about the origin by ``copies[new_id]`` (same skeleton_id, same mesh up to scale,
    same split). Returns (dest, base_id, moved bones)."""
    shutil.copytree(zoo_dir, dest)
    chars = read_records(dest, "characters")
    ids = [c.skeleton_id for c in chars]
    base = next(c for c in chars if c.category == category and len(c.faces) and c.skeleton_id
                and (not shared or ids.count(c.skeleton_id) > 1))
    for new_id, s in copies.items():
        chars.append(dataclasses.replace(base, character_id=new_id, vertices=base.vertices * np.float32(s),
                                         keypoints=base.keypoints * np.float32(s)))
    motions = read_records(dest, "motions")
    clip = next(m for m in motions if m.character_id == base.character_id)
    size = float(np.ptp(base.vertices, axis=0).max())
    moved_t, moved = translate_bones(clip.transforms, base.parents, size)
    motions.append(dataclasses.replace(clip, motion_id=clip.motion_id + "-ik", name=clip.name + "-ik",
                                       transforms=moved_t))
    for table, recs in (("characters", chars), ("motions", motions)):
        for split in sorted({r.split for r in recs}):
            write_records(dest, table, [r for r in recs if r.split == split], split=split, config={"test": True})
    return dest, base.character_id, moved
