"""Each bone's range of motion from a character's own clips, and how much of a predicted pose lies
beyond it (issue 47's forward plausibility, column ``out_of_range``).

**Local rotation.** Bone k's rotation relative to its *reference*, the nearest ancestor whose
rotation the mesh determines (:func:`mimicbench.geometry.transform_estimation.weight_support`; usually the
parent): ``l_k = q_ref^-1 q_k`` with the rest-relative world rotations of the data contract. A
bone without such an ancestor (a root, or a bone under roots without vertices) has no local
rotation and is not scored: a root's rotation is the whole body's heading, not a joint angle.

**Swing and twist.** ``l_k = swing * twist``: the twist turns about the bone's rest axis ``a_k``
(from its keypoint to the mean of its children's, or along its parent's direction for a leaf), by
tau in (-180, 180] degrees; the swing turns about an axis perpendicular to ``a_k``, written as its
rotation vector's two coordinates in a fixed basis of the plane perpendicular to ``a_k`` (radians;
its length is the swing angle, its direction which way the bone leans).

**Range.** Over every frame of the character's kinematic clips (all of its clips in the motions
table except simulated ``@sim`` twins): the convex hull of the swing vectors reached, and the
smallest arc of twist angles holding every twist reached (1-degree bins). A knee that only bends
forward reaches a segment of swing vectors on one side of rest, so bending it backwards lands
outside the hull by the backward angle, and bending it further than the clips do lands beyond the
segment's end: both are caught, where a bound on the rotation angle alone misses the first.

**Excess.** A pose's excess for bone k is ``max(distance of its swing vector to the hull, twist
beyond the arc)`` in degrees, 0 inside. :func:`out_of_range_share` reads a predicted mesh's pose
with the shared joint-fit read-off (:func:`mimicbench.geometry.pose_readoff.read_pose`) and the character's
ground-truth weights and returns the share of scored bones whose excess is over
:data:`MARGIN_DEG`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from mimicbench.geometry.kinematics import local_from_global
from mimicbench.geometry.pose_readoff import read_pose
from mimicbench.geometry.quaternion import quat_conjugate, quat_multiply, quat_normalize
from mimicbench.geometry.transform_estimation import weight_support
from mimicbench.geometry.validation import check_parents, check_shape

MARGIN_DEG = 10.0
"""Degrees beyond the range before a bone counts as out of range. The range is what a few clips
sampled at their frame rate reach (their hull underestimates what the character can do, and a pose
between two clips' extremes is still a pose the character can take), and a predicted mesh that is
not an exact LBS pose carries a read-off error of a few degrees on small bones; 10 degrees is also
the threshold issue 48's figures were stated with. ``docs/notes/issue-47-readoff.md`` gives the
share of the target's own held-out clip frames beyond 0, 5, 10 and 20 degrees."""

TWIST_BINS = 360
"""Twist angles reached are kept in this many bins over the circle (1 degree each)."""


@dataclass
class BoneRanges:
    """One character's range of motion, bone by bone.

    Attributes:
        character_id: the character.
        reference: (K,) int64, the bone each local rotation is relative to, -1 for none.
        scored: (K,) bool, bones with a local rotation and weight support (scored by
            :meth:`excess_degrees`).
        axes: (K, 3) unit rest axis of each bone (world frame at rest).
        basis: (K, 2, 3) two unit vectors spanning the plane perpendicular to each axis.
        hulls: K arrays (M_k, 2): vertices of the convex hull of the swing vectors reached, in
            radians, counter-clockwise (fewer than 3 rows for a point or a segment); (0, 2)
            before any frame.
        twist: (K, TWIST_BINS) bool, the twist bins reached.
        frames: clip frames seen.
    """

    character_id: str
    reference: np.ndarray
    scored: np.ndarray
    axes: np.ndarray
    basis: np.ndarray
    hulls: list
    twist: np.ndarray
    frames: int = 0

    @classmethod
    def empty(cls, character_id: str, rest_vertices: np.ndarray, rest_keypoints: np.ndarray, parents: np.ndarray,
              weights) -> "BoneRanges":
        """Ranges with no frame seen yet for a character at rest (vertices (N, 3), keypoints (K, 3),
        parents (K,), skin weights); :meth:`add_frames` fills them."""
        keypoints = check_shape(rest_keypoints, (None, 3), "rest_keypoints").astype(np.float64)
        parents = check_parents(parents, len(keypoints))
        supported = weight_support(rest_vertices, weights)
        reference = np.full(len(parents), -1, np.int64)
        for k, p in enumerate(parents):
            while p >= 0 and not supported[p]:
                p = parents[p]
            reference[k] = p
        axes = bone_axes(keypoints, parents)
        return cls(character_id, reference, supported & (reference >= 0), axes, _plane_basis(axes),
                   [np.zeros((0, 2)) for _ in parents], np.zeros((len(parents), TWIST_BINS), bool))

    def local_rotations(self, rotations: np.ndarray) -> np.ndarray:
        """Local rotations (..., K, 4) relative to each bone's reference, from rest-relative world
        rotations (..., K, 4); a bone without a reference keeps its world rotation."""
        return local_from_global(rotations, self.reference)

    def add_frames(self, rotations: np.ndarray) -> None:
        """Widen the ranges by clip frames: rest-relative world rotations (F, K, 4)."""
        q = np.asarray(rotations, np.float64)
        if q.ndim != 3 or q.shape[1:] != (len(self.reference), 4):
            raise ValueError(f"rotations: expected shape (F, {len(self.reference)}, 4), got {q.shape}")
        if not len(q):
            return
        swing, tau = swing_twist(self.local_rotations(q), self.axes, self.basis)  # (F, K, 2), (F, K)
        bins = _twist_bin(tau)
        for k in range(len(self.reference)):
            self.hulls[k] = convex_hull_2d(np.concatenate([self.hulls[k], swing[:, k]]))
            self.twist[k, bins[:, k]] = True
        self.frames += len(q)

    def excess_degrees(self, rotations: np.ndarray) -> np.ndarray:
        """Degrees (..., K) by which rest-relative world rotations (..., K, 4) lie beyond the
        ranges (0 inside); NaN for bones that are not scored or before any frame was seen."""
        q = np.asarray(rotations, np.float64)
        swing, tau = swing_twist(self.local_rotations(q), self.axes, self.basis)
        out = np.full(q.shape[:-1], np.nan)
        if not self.frames:
            return out
        for k in np.flatnonzero(self.scored):
            lo, hi = _twist_arc(self.twist[k])
            twist_out = np.maximum(np.abs(_wrap_degrees(np.degrees(tau[..., k]) - (lo + hi) / 2)) - (hi - lo) / 2, 0.0)
            swing_out = np.degrees(distance_to_hull_2d(self.hulls[k], swing[..., k, :]))
            out[..., k] = np.maximum(swing_out, twist_out)
        return out


def bone_axes(rest_keypoints: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Unit rest axis (K, 3) of each bone: from its keypoint to the mean of its children's
    keypoints; a leaf (or a bone whose children sit on its keypoint) continues its parent's
    direction (from the parent's keypoint to its own), and failing that takes +Y."""
    kp = np.asarray(rest_keypoints, np.float64)
    parents = check_parents(parents, len(kp))
    axes = np.zeros_like(kp)
    for k in range(len(kp)):
        kids = np.flatnonzero(parents == k)
        d = kp[kids].mean(axis=0) - kp[k] if len(kids) else np.zeros(3)
        if np.linalg.norm(d) < 1e-9 and parents[k] >= 0:
            d = kp[k] - kp[parents[k]]
        axes[k] = d / np.linalg.norm(d) if np.linalg.norm(d) >= 1e-9 else [0.0, 1.0, 0.0]
    return axes


def _plane_basis(axes: np.ndarray) -> np.ndarray:
    """(K, 2, 3) orthonormal vectors perpendicular to each unit axis (K, 3)."""
    helper = np.where(np.abs(axes[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 0, 1.0]])
    e1 = np.cross(axes, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return np.stack([e1, np.cross(axes, e1)], axis=1)


def swing_twist(local: np.ndarray, axes: np.ndarray, basis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Swing vectors (..., K, 2) in radians and twist angles (..., K) in radians, (-pi, pi], of
    local rotations (..., K, 4) about unit axes (K, 3), with ``local = swing * twist``; the swing
    vector is the swing's rotation vector in ``basis`` (K, 2, 3). A swing of 180 degrees leaves
    the twist undefined: it is taken as 0."""
    q = quat_normalize(np.asarray(local, np.float64))
    along = np.einsum("...ka,ka->...k", q[..., 1:], axes)
    twist = np.concatenate([q[..., :1], along[..., None] * axes], axis=-1)
    norm = np.linalg.norm(twist, axis=-1, keepdims=True)
    twist = np.where(norm > 1e-12, twist / np.maximum(norm, 1e-300), [1.0, 0.0, 0.0, 0.0])
    tau = 2.0 * np.arctan2(np.einsum("...ka,ka->...k", twist[..., 1:], axes), twist[..., 0])
    tau = _wrap_radians(tau)
    swing = quat_multiply(q, quat_conjugate(twist))
    swing = np.where(swing[..., :1] < 0, -swing, swing)
    s = np.linalg.norm(swing[..., 1:], axis=-1)
    angle = 2.0 * np.arctan2(s, swing[..., 0])
    vector = swing[..., 1:] * np.where(s > 1e-12, angle / np.maximum(s, 1e-300), 2.0)[..., None]
    return np.einsum("...ka,kba->...kb", vector, basis), tau


def convex_hull_2d(points: np.ndarray) -> np.ndarray:
    """Vertices (M, 2) of the convex hull of points (P, 2), counter-clockwise; collinear points
    give the segment's two ends, equal points one point, no points (0, 2)."""
    from scipy.spatial import ConvexHull, QhullError

    p = np.unique(np.asarray(points, np.float64).reshape(-1, 2), axis=0)
    if len(p) <= 2:
        return p
    try:
        return p[ConvexHull(p).vertices]
    except QhullError:  # all on one line: its two extreme points
        direction = p[-1] - p[0]
        along = p @ direction
        return p[[int(np.argmin(along)), int(np.argmax(along))]]


def distance_to_hull_2d(hull: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """Euclidean distance (...,) from points (..., 2) to the convex polygon ``hull`` (M, 2)
    (:func:`convex_hull_2d`: counter-clockwise, or a segment, or a point), 0 inside."""
    x = np.asarray(queries, np.float64)
    h = np.asarray(hull, np.float64)
    if not len(h):
        return np.full(x.shape[:-1], np.inf)
    if len(h) == 1:
        return np.linalg.norm(x - h[0], axis=-1)
    a, b = h, np.roll(h, -1, axis=0)
    if len(h) == 2:
        a, b = h[:1], h[1:]
    ab = b - a  # (E, 2)
    ax = x[..., None, :] - a  # (..., E, 2)
    t = np.clip((ax * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-300), 0.0, 1.0)
    dist = np.linalg.norm(ax - t[..., None] * ab, axis=-1).min(axis=-1)
    if len(h) >= 3:
        inside = ((ab[:, 0] * ax[..., 1] - ab[:, 1] * ax[..., 0]) >= -1e-12).all(axis=-1)
        dist = np.where(inside, 0.0, dist)
    return dist


def _wrap_radians(a):
    return np.pi - np.mod(np.pi - a, 2 * np.pi)


def _wrap_degrees(a):
    return 180.0 - np.mod(180.0 - a, 360.0)


def _twist_bin(tau: np.ndarray) -> np.ndarray:
    """Bin (int) of twist angles tau (radians, (-pi, pi]): bin i covers [-180 + i, -179 + i) degrees."""
    return np.clip(np.floor((np.degrees(tau) + 180.0) * TWIST_BINS / 360.0), 0, TWIST_BINS - 1).astype(np.int64)


def _twist_arc(reached: np.ndarray) -> tuple[float, float]:
    """The smallest arc (lo, hi) in degrees, ``lo <= hi``, holding every reached bin (TWIST_BINS,):
    the circle less its longest run of bins not reached. Nothing reached: (0, 0)."""
    if not reached.any():
        return 0.0, 0.0
    if reached.all():
        return -180.0, 180.0
    width = 360.0 / TWIST_BINS
    free = ~np.concatenate([reached, reached])
    best_len, best_start, run = 0, 0, 0
    for i, f in enumerate(free):
        run = run + 1 if f else 0
        if run > best_len:
            best_len, best_start = run, i - run + 1
    best_len = min(best_len, TWIST_BINS - 1)
    start = (best_start + best_len) % TWIST_BINS  # first reached bin after the gap
    lo = -180.0 + start * width
    return lo, lo + (TWIST_BINS - best_len) * width


def out_of_range_bones(predicted_vertices: np.ndarray, rig, ranges: BoneRanges,
                       margin_deg: float = MARGIN_DEG) -> tuple[np.ndarray, np.ndarray]:
    """Which bones of a predicted pose lie beyond the character's ranges by more than ``margin_deg``.

    Args:
        predicted_vertices: (N, 3) the predicted mesh of the character, metres.
        rig: the character at rest with its ground-truth skin weights: any object with
            ``vertices`` (N, 3), ``keypoints`` (K, 3), ``parents`` (K,) and ``weights`` (a
            :class:`mimicbench.benchmark.request.Rig`).
        ranges: the character's :class:`BoneRanges`.
        margin_deg: degrees beyond the range that still count as inside.

    Returns:
        ``beyond`` (K,) bool and ``scored`` (K,) bool (the bones counted; ``beyond`` is False
        elsewhere).
    """
    pose = read_pose(rig.vertices, rig.keypoints, rig.parents, rig.weights, predicted_vertices)
    excess = ranges.excess_degrees(pose.rotations)
    scored = ranges.scored & pose.supported & np.isfinite(excess)
    return scored & (np.nan_to_num(excess) > margin_deg), scored


def out_of_range_share(predicted_vertices: np.ndarray, rig, ranges: BoneRanges,
                       margin_deg: float = MARGIN_DEG) -> float:
    """Share of the scored bones of a predicted pose beyond the character's own range of motion by
    more than ``margin_deg`` degrees (:func:`out_of_range_bones`), in [0, 1]; NaN when no bone is
    scored (no clip frames, or no bone with a local rotation and weight support)."""
    beyond, scored = out_of_range_bones(predicted_vertices, rig, ranges, margin_deg)
    return float(beyond.sum() / scored.sum()) if scored.any() else float("nan")


def ranges_for_clips(character_id: str, rig, clips) -> BoneRanges:
    """A character's ranges from its clips: ``rig`` as in :func:`out_of_range_bones`, ``clips`` an
    iterable of transforms (F, K, 7)."""
    ranges = BoneRanges.empty(character_id, rig.vertices, rig.keypoints, rig.parents, rig.weights)
    for clip in clips:
        ranges.add_frames(np.asarray(clip)[..., :4])
    return ranges


MOTION_COLUMNS = ["character_id", "name", "num_frames", "num_joints", "transforms"]
"""The columns of the motions table :func:`ranges_for_dataset` reads."""


def ranges_for_dataset(dataset, characters: Mapping | None = None) -> dict[str, BoneRanges]:
    """Every character's ranges from its kinematic clips, streaming the motions table.

    Reads only :data:`MOTION_COLUMNS`, one row group (16 clips) at a time (the transforms only of
    row groups holding a kinematic clip of a given character), and keeps per bone only its hull
    and twist bins, so memory does not grow with the table. Simulated clips
    (``<clip>@sim``) are left out: their body pose is their kinematic twin's.

    Args:
        dataset: a :class:`~mimicbench.schemas.dataset.Dataset` or its path.
        characters: ``{character_id: rig}`` (a :class:`mimicbench.benchmark.request.Rig`, or an object with
            a ``rig`` attribute such as :class:`mimicbench.benchmark.rigs.CharacterData`); None loads every
            character with a mesh.

    Returns:
        ``{character_id: BoneRanges}`` for every character given that has at least one kinematic
        clip (a character without clips has no range and is left out).

    Raises:
        DatasetError: a clip's joint count differs from its character's.
    """
    from mimicbench.benchmark.rigs import load_characters
    from mimicbench.schemas.dataset import Dataset
    from mimicbench.schemas.errors import DatasetError
    from mimicbench.schemas.motion import SIM_SUFFIX
    from mimicbench.schemas.shard_stream import checked_parquet_file

    dataset = Dataset.of(dataset)
    chars = load_characters(dataset) if characters is None else characters
    rigs = {cid: getattr(c, "rig", c) for cid, c in chars.items()}
    out: dict[str, BoneRanges] = {}
    if not dataset.has_table("motions"):
        return out
    for entry in dataset.readable_entries("motions"):
        pf = checked_parquet_file(dataset.root, entry, "motions")
        for g in range(pf.num_row_groups):
            t = pf.read_row_group(g, columns=MOTION_COLUMNS[:4])
            ids, names = t.column("character_id").to_pylist(), t.column("name").to_pylist()
            frames, joints = t.column("num_frames").to_pylist(), t.column("num_joints").to_pylist()
            if not any(cid in rigs and not name.endswith(SIM_SUFFIX) for cid, name in zip(ids, names)):
                continue  # the transforms of this row group are never read
            column = pf.read_row_group(g, columns=["transforms"]).column("transforms").combine_chunks()
            offsets = column.offsets.to_numpy()
            values = column.values.flatten().to_numpy(zero_copy_only=False).reshape(-1, 7)
            group: dict[str, list] = {}
            for i, (cid, name, f, k) in enumerate(zip(ids, names, frames, joints)):
                if cid not in rigs or name.endswith(SIM_SUFFIX):
                    continue
                rig = rigs[cid]
                if k != len(rig.parents):
                    raise DatasetError(f"{dataset}: motion {cid}/{name} has {k} joints, its character {len(rig.parents)}")
                group.setdefault(cid, []).append(values[offsets[i]:offsets[i + 1]].reshape(f, k, 7)[..., :4])
            for cid, clips in group.items():  # one hull update per bone and row group
                if cid not in out:
                    rig = rigs[cid]
                    out[cid] = BoneRanges.empty(cid, rig.vertices, rig.keypoints, rig.parents, rig.weights)
                out[cid].add_frames(np.concatenate(clips))
    return out
