"""``h2h``: same-skeleton transfer with ground truth.

Cases: ordered pairs of characters that share one skeleton (equal ``skeleton_id``, hence equal
bone names and parents), of **any** category: a family of humanoids, a dinosaur pack on one rig,
a horse and a zebra. (The name ``h2h``, humanoid to humanoid, is kept for the results it
labels; the docs call the protocol "same-skeleton".)

Ground truth: the target posed by the source's pose carried over bone by bone
(:func:`ground_truth_transforms`): each bone's rotation relative to its parent, and each bone's
translation relative to its parent beyond its rest offset (a body bone a clip moves, feet driven
by IK, pole targets) scaled by the size ratio, as is the root's displacement from rest. Two
characters with identical rest skeletons and meshes therefore get the source's own pose.

Scores: PMD (headline by the target's height, the papers' convention), PMD by largest extent,
aligned PMD, squared PMD and ELS of the prediction against the posed ground truth, and the forward
scores against hidden ground truth (``semantic_deg``, ``out_of_range``).

Placement: the headline ``pmd`` is the PMD after centring prediction and ground truth on their own
centroids (``pmd_aligned``). How far a character's root travels when a pose moves to a character
of another size is a convention (scaled by height, by leg length, by the largest extent, or not
at all) that a method cannot know, and it is not the pose; the placed PMD stays in ``pmd_height``.
"""
from __future__ import annotations

from collections import defaultdict
from typing import Sequence

import numpy as np

from mimicbench.benchmark.normalisation import size_ratio
from mimicbench.benchmark.protocols.base import BenchmarkProtocol, Call, CasePool, EvalData, Outcome, wants_hidden_roles
from mimicbench.benchmark.scoring import score_pose
from mimicbench.geometry.kinematics import array_to_transforms, forward_kinematics, local_from_global, transforms_to_array
from mimicbench.geometry.quaternion import quat_apply, quat_conjugate
from mimicbench.schemas.case import CaseRecord


def local_translations(source_transforms: np.ndarray, rest_keypoints: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Each bone's translation (K, 3) relative to its parent beyond its rest offset, in the
    parent's rest-relative frame: ``R(q_p)^-1 (t_k - t_p) - (cbar_k - cbar_p)``; for a root, its
    displacement from rest ``t_k - cbar_k``. All zero for a pose made of rotations only.

    Args:
        source_transforms: (..., K, 7) poses.
        rest_keypoints: (K, 3) rest joint heads.
        parents: (K,) parents, -1 for roots.

    Returns:
        (..., K, 3) translations, metres.
    """
    q, t = array_to_transforms(source_transforms)
    rest = np.asarray(rest_keypoints, np.float64)
    parents = np.asarray(parents)
    out = t - rest
    child = parents >= 0
    p = parents[child]
    out[..., child, :] = (quat_apply(quat_conjugate(q[..., p, :]), t[..., child, :] - t[..., p, :])
                          - (rest[child] - rest[p]))
    return out


def transforms_from_local(local_rotations: np.ndarray, moved: np.ndarray, rest_keypoints: np.ndarray,
                          parents: np.ndarray) -> np.ndarray:
    """Global transforms (K, 7) from local rotations (K, 4) and local translations (K, 3).

    ``moved`` is what :func:`local_translations` returns: per bone its translation relative to
    its parent beyond the rest offset, in the parent's rest-relative frame (a root's: its
    displacement from rest). Forward kinematics runs on a rest skeleton whose bone offsets
    include them, so every joint lands where the carried-over pose puts it.
    """
    parents = np.asarray(parents)
    rest = np.asarray(rest_keypoints, np.float64)
    moved = np.asarray(moved, np.float64)
    shifted = np.empty_like(rest)
    for k, p in enumerate(parents):
        shifted[k] = rest[k] if p < 0 else shifted[p] + rest[k] - rest[p] + moved[k]
    roots = parents < 0
    root_pos = shifted.copy()
    root_pos[roots] += moved[roots]
    g_rot, g_pos = forward_kinematics(local_rotations, shifted, parents, root_pos)
    return transforms_to_array(g_rot, g_pos)


def ground_truth_transforms(source, target, source_transforms: np.ndarray) -> np.ndarray:
    """Ground-truth target transforms (K, 7) for a source pose (K, 7) on a shared skeleton.

    Local rotations are copied bone by bone; local translations (:func:`local_translations`,
    the roots' displacements included) are scaled by :func:`mimicbench.benchmark.normalisation.size_ratio`
    and added to the target's own rest offsets; positions follow by forward kinematics
    (:func:`transforms_from_local`).

    Args:
        source, target: CharacterRecord-like objects (character_id, keypoints, parents,
            bone_names, vertices) with equal bone names and parents.
        source_transforms: (K, 7) the source's pose.
    """
    if list(source.bone_names) != list(target.bone_names) or not np.array_equal(source.parents, target.parents):
        raise ValueError(f"same-skeleton ground truth: {source.character_id} and {target.character_id} do not "
                         "share a skeleton (expected equal bone names and parents)")
    parents = np.asarray(target.parents)
    q, _ = array_to_transforms(source_transforms)
    ratio = size_ratio(source.vertices, target.vertices)
    moved = local_translations(source_transforms, source.keypoints, parents) * ratio
    return transforms_from_local(local_from_global(q, parents), moved, target.keypoints, parents)


class SameSkeleton(BenchmarkProtocol):
    name = "h2h"
    title = "same-skeleton transfer, scored against ground truth"
    headline = "height"
    headline_column = "pmd_aligned"
    """The leaderboard ranks by the placement-free PMD (see the module docstring), which ``pmd`` also holds."""

    def candidate_pairs(self, pool: CasePool) -> list[tuple]:
        families = defaultdict(list)
        for c in pool.characters:
            if c.skeleton_id:
                families[c.skeleton_id].append(c)
        return [(a, b) for fam in families.values() for a in fam for b in fam if a is not b]

    def ground_truth(self, source, target, source_transforms):
        """The target's ground-truth transforms (K, 7) for a source pose (:func:`ground_truth_transforms`)."""
        return ground_truth_transforms(source, target, source_transforms)

    def make_case(self, source, target, motion, frame: int) -> CaseRecord:
        src_t = motion.transforms[frame]
        return CaseRecord(self.case_id(source, target, motion, frame), self.name, source.character_id,
                          target.character_id, motion.motion_id, frame, src_t,
                          self.ground_truth(source, target, src_t), source.category, target.category)

    def evaluate(self, cases: Sequence[CaseRecord], data: EvalData, call: Call) -> list[Outcome]:
        src = [data.characters[c.source_id] for c in cases]
        tgt = [data.characters[c.target_id] for c in cases]
        hidden = wants_hidden_roles(call)
        posed = [data.posed(s, c.source_transforms) for s, c in zip(src, cases)]
        answers = call([data.request(s, p, t, c.case_id, hidden) for s, p, t, c in zip(src, posed, tgt, cases)])
        out = []
        for c, s, p, t, (pred, err, sec) in zip(cases, src, posed, tgt, answers):
            if err:
                out.append(Outcome(c, "failed", err, sec))
                continue
            truth = data.posed(t, c.target_transforms)
            metrics = score_pose(pred, truth, data.frame(t), self.headline)
            metrics["pmd"] = metrics["pmd_aligned"]
            metrics.update(data.forward_scores(s, p, t, pred))
            out.append(Outcome(c, "ok", None, sec, metrics, {"forward": pred}))
        return out
