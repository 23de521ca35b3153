"""Deterministic benchmark cases: ``mimicbench bench cases DATASET``.

- ``h2h``: ordered pairs of humanoids that share one skeleton (equal ``skeleton_id``, hence equal
  bone names and parents). The ground truth is the target posed with the source's per-bone
  rotations relative to rest (local rotations, matched by bone name), joint positions by forward
  kinematics on the target's own rest skeleton, and the root's displacement from rest scaled by
  the ratio of heights (target / source).
- ``cct``: cross-category ordered pairs with a humanoid on one side (humanoid -> any other
  category, and any other category -> humanoid; ``apparel`` humanoids count as humanoids). No
  ground truth: scored by cycle consistency.

Poses are frames (not the rest frame 0) of the source's own motions, drawn with a seeded
generator, so the same dataset and options give the same cases.
"""
from __future__ import annotations

import itertools

import numpy as np

from mimicbench.kinematics import array_to_transforms, forward_kinematics, local_from_global, transforms_to_array
from mimicbench.mesh import unit_height_frame
from schemas.case import CaseRecord
from schemas.shards import read_records, write_records

HUMANOID_LIKE = ("humanoid", "apparel")


def h2h_target_transforms(source, target, source_transforms: np.ndarray) -> np.ndarray:
    """Ground-truth target transforms (Kt, 7) for a source pose (Ks, 7) on a shared skeleton.

    Args:
        source, target: CharacterRecord-like objects with keypoints, parents, bone_names, vertices.
        source_transforms: (Ks, 7) the source's pose.
    """
    if list(source.bone_names) != list(target.bone_names) or not np.array_equal(source.parents, target.parents):
        raise ValueError(f"h2h: {source.character_id} and {target.character_id} do not share a skeleton")
    q, t = array_to_transforms(source_transforms)
    local = local_from_global(q, source.parents)
    _, hs = unit_height_frame(source.vertices)
    _, ht = unit_height_frame(target.vertices)
    roots = np.asarray(source.parents) < 0
    root_pos = np.array(target.keypoints, dtype=np.float64)
    root_pos[roots] = target.keypoints[roots] + (t[roots] - source.keypoints[roots]) * (ht / hs)
    g_rot, g_pos = forward_kinematics(local, target.keypoints, target.parents, root_pos)
    return transforms_to_array(g_rot, g_pos)


def _frames_for(rng, motions, n_poses):
    """n_poses (motion, frame) draws from a character's motions, never the rest frame 0."""
    choices = [(m, f) for m in motions for f in range(1, m.num_frames)]
    if not choices:
        return []
    idx = rng.choice(len(choices), size=min(n_poses, len(choices)), replace=False)
    return [choices[i] for i in sorted(idx)]


def build_cases(dataset, split: str = "test", h2h_pairs: int = 100, h2h_poses: int = 20,
                cct_pairs: int = 300, cct_poses: int = 10, seed: int = 0) -> dict[str, list[CaseRecord]]:
    """Cases per protocol from the characters of ``split`` (``all`` for every split)."""
    chars = [c for c in read_records(dataset, "characters") if len(c.faces) and (split == "all" or c.split == split)]
    chars.sort(key=lambda c: c.character_id)
    by_id = {c.character_id: c for c in chars}
    motions: dict[str, list] = {}
    for m in read_records(dataset, "motions"):
        if m.character_id in by_id:
            motions.setdefault(m.character_id, []).append(m)
    for ms in motions.values():
        ms.sort(key=lambda m: m.motion_id)
    rng = np.random.default_rng(seed)

    families: dict[str, list] = {}
    for c in chars:
        if c.skeleton_id and c.category in HUMANOID_LIKE:
            families.setdefault(c.skeleton_id, []).append(c)
    h2h_candidates = [(a, b) for fam in families.values() for a, b in itertools.permutations(fam, 2)
                      if motions.get(a.character_id)]
    cct_candidates = [(a, b) for a, b in itertools.permutations(chars, 2)
                      if (a.category in HUMANOID_LIKE) != (b.category in HUMANOID_LIKE) and motions.get(a.character_id)]

    def pick(cands, n):
        if len(cands) <= n:
            return cands
        return [cands[i] for i in sorted(rng.choice(len(cands), size=n, replace=False))]

    out: dict[str, list[CaseRecord]] = {"h2h": [], "cct": []}
    for a, b in pick(h2h_candidates, h2h_pairs):
        for m, f in _frames_for(rng, motions[a.character_id], h2h_poses):
            src_t = m.transforms[f]
            out["h2h"].append(CaseRecord(
                f"h2h/{a.character_id}->{b.character_id}/{m.name}#{f}", "h2h", a.character_id, b.character_id,
                m.motion_id, f, src_t, h2h_target_transforms(a, b, src_t), a.category, b.category))
    for a, b in pick(cct_candidates, cct_pairs):
        for m, f in _frames_for(rng, motions[a.character_id], cct_poses):
            out["cct"].append(CaseRecord(
                f"cct/{a.character_id}->{b.character_id}/{m.name}#{f}", "cct", a.character_id, b.character_id,
                m.motion_id, f, m.transforms[f], None, a.category, b.category))
    return out


def write_cases(dataset, cases: dict[str, list[CaseRecord]], config: dict) -> dict[str, int]:
    """Write the cases table, one shard group per protocol (split = protocol name)."""
    counts = {}
    for protocol, recs in cases.items():
        write_records(dataset, "cases", recs, split=protocol, rows_per_shard=5000, config=config)
        counts[protocol] = len(recs)
    return counts
