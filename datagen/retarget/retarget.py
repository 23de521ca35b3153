"""Put a clip of one humanoid skeleton onto another by bone roles.

For each role both skeletons have (:mod:`mimicbench.datagen.retarget.roles`):

1. **Rest alignment**: A_r, the shortest rotation taking the target bone's rest direction (its
   head to the head of the role below it, e.g. upper arm -> forearm) onto the source's. T-pose and
   A-pose skeletons differ here, and A_r absorbs it.
2. **Rotations**: the target bone's world rotation (relative to its rest) is q_src(f) A_r, so its
   posed direction is the source bone's posed direction. Unmapped target bones keep their rest
   pose relative to their parent (their world rotation is the parent's).
3. **Positions** by forward kinematics from the target's rest pose; then the whole skeleton is
   moved so that its hips follow the source's hips, displacement scaled by the ratio of leg
   lengths (thigh + shin, averaged over both sides; the ratio of heights when a skeleton has no
   legs).

All in the dataset frame (metres, Y up, +Z forward), so both skeletons face the same way at rest.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.retarget.roles import direction_children, humanoid_roles
from mimicbench.geometry.kinematics import array_to_transforms, transforms_to_array
from mimicbench.geometry.quaternion import quat_apply, quat_multiply, quat_normalize
from mimicbench.schemas.motion import MotionRecord
from mimicbench.schemas.validate import parents_problem


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Shortest rotation (w, x, y, z) taking direction a (3,) onto direction b (3,); identity when
    either is zero; a half turn about a perpendicular axis when they are opposite."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if na < 1e-9 or nb < 1e-9:
        return np.array([1.0, 0, 0, 0])
    a, b = a / na, b / nb
    c = float(np.dot(a, b))
    if c < -1 + 1e-9:
        perp = np.cross(a, [1.0, 0, 0])
        if np.linalg.norm(perp) < 1e-6:
            perp = np.cross(a, [0, 1.0, 0])
        return np.r_[0.0, perp / np.linalg.norm(perp)]
    q = np.r_[1.0 + c, np.cross(a, b)]
    return q / np.linalg.norm(q)


def leg_length(keypoints: np.ndarray, roles: dict[str, int]) -> float | None:
    """Mean over sides of |hip -> knee| + |knee -> ankle| at rest (metres), or None."""
    out = []
    for side in ("left", "right"):
        try:
            t, s, f = (roles[f"{side}/{r}"] for r in ("thigh", "shin", "foot"))
        except KeyError:
            continue
        out.append(np.linalg.norm(keypoints[s] - keypoints[t]) + np.linalg.norm(keypoints[f] - keypoints[s]))
    return float(np.mean(out)) if out else None


def retarget_clip(source, motion, target, name: str | None = None) -> tuple[MotionRecord, dict]:
    """The clip ``motion`` of character ``source`` on character ``target`` (records), and a
    report: ``mapped`` roles, ``source_unmapped`` / ``target_unmapped`` bone names, ``scale``.

    Raises ValueError when a skeleton is out of the format's order (``parents[k] < k``: a cycle), the
    two skeletons share fewer than 4 roles, or a stored value (transforms, scale) is not finite."""
    for role, rec in (("source", source), ("target", target)):
        cycle = parents_problem(rec.parents)
        if cycle:
            raise ValueError(f"{role} {rec.character_id}: skeleton out of order: {cycle}")
    rs, rt = humanoid_roles(source.bone_names), humanoid_roles(target.bone_names)
    mapped = [r for r in rt if r in rs]
    if len(mapped) < 4:
        raise ValueError(f"{source.character_id} -> {target.character_id}: only {len(mapped)} bone roles in "
                         f"common ({', '.join(mapped) or 'none'}); expected at least 4 (hips, spine, limbs)")
    ks, kt = np.asarray(source.keypoints, np.float64), np.asarray(target.keypoints, np.float64)
    q_src, p_src = array_to_transforms(motion.transforms)  # (F, Ks, 4), (F, Ks, 3)
    f = q_src.shape[0]
    align = {}
    for r in mapped:
        child = next((c for c in direction_children(r) if c in rs and c in rt), None)
        if child is None:
            align[r] = np.array([1.0, 0, 0, 0])
        else:
            align[r] = rotation_between(kt[rt[child]] - kt[rt[r]], ks[rs[child]] - ks[rs[r]])
    role_of_bone = {rt[r]: r for r in mapped}
    parents = np.asarray(target.parents)
    q = np.zeros((f, len(parents), 4))
    p = np.zeros((f, len(parents), 3))
    for k, par in enumerate(parents):
        if k in role_of_bone:
            r = role_of_bone[k]
            q[:, k] = quat_multiply(q_src[:, rs[r]], align[r])
        elif par >= 0:
            q[:, k] = q[:, par]
        else:
            q[:, k] = [1.0, 0, 0, 0]
        if par < 0:
            p[:, k] = kt[k]
        else:
            p[:, k] = p[:, par] + quat_apply(q[:, par], kt[k] - kt[par])
    ls, lt = leg_length(ks, rs), leg_length(kt, rt)
    if ls and lt:
        scale = lt / ls
    else:
        scale = float(np.ptp(kt[:, 1]) / max(np.ptp(ks[:, 1]), 1e-9))
    hs = rs.get("hips", 0)
    ht = rt.get("hips", int(np.flatnonzero(parents < 0)[0]))
    shift = kt[ht] + (p_src[:, hs] - ks[hs]) * scale - p[:, ht]
    p += shift[:, None, :]
    clip = name or f"{source.character_id}/{motion.name}"
    rec = MotionRecord(f"{target.character_id}/{clip}", target.character_id, clip, target.split, motion.fps, f,
                       len(parents), transforms_to_array(quat_normalize(q), p),
                       f"retarget:{motion.motion_id}")
    if not (np.isfinite(scale) and np.all(np.isfinite(rec.transforms))):
        raise ValueError(f"{source.character_id} -> {target.character_id}: the clip's transforms or its scale "
                         f"{scale:g} are not finite (a skeleton with no leg length or height)")
    used_src = {rs[r] for r in mapped}
    report = {"source": source.character_id, "target": target.character_id, "motion": motion.motion_id,
              "mapped": mapped, "scale": scale,
              "source_unmapped": [n for i, n in enumerate(source.bone_names) if i not in used_src],
              "target_unmapped": [n for i, n in enumerate(target.bone_names) if i not in role_of_bone]}
    return rec, report
