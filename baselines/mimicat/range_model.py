"""Each target bone's range of motion predicted from its shape, and H's refinement of a pose with it.

The evaluator's ``out_of_range`` score (:mod:`mimicbench.benchmark.motion_range`) measures a bone's
local rotation (relative to its nearest supported ancestor) as a swing vector, in the plane
perpendicular to the bone's rest axis, and a twist about that axis, against the hull of swings and
the arc of twists the character's own clips reach. A method never sees the target's clips, so
:class:`RangeModel` predicts those ranges from the target's rest skeleton alone:

- **Fit** (:meth:`RangeModel.fit`): every scored bone of a training zoo, with its shape features
  (:func:`bone_features`) and the ranges its own clips reach: the swing hull's vertices as 3-D
  rotation vectors (radians, world frame at rest; perpendicular to the bone's rest axis) and the
  twist bins reached (1 degree each).
- **Predict** (:meth:`RangeModel.predict`): for each scored bone of a new character, its ``k``
  nearest training bones in feature space; the predicted swing range is the convex hull of their
  hull vertices written in this bone's swing plane, the predicted twist range the smallest arc
  holding every bin any of them reached.

Refining a pose (``scope`` of the model):

- ``free`` (:func:`refine_free`): only the target bones that G's one-to-one M matches to no source
  bone move. They share the turn between their matched neighbours (:func:`interpolate_free`), where
  the structured initialisation gives them their parent's rotation and puts the whole turn on the
  next matched bone, and each is then moved into its predicted range. Matched bones keep their
  world rotations: they are what the return leg of a cycle reads back.
- ``all`` (:func:`project_pose`): every scored bone whose swing lies more than ``slack_deg``
  outside the predicted hull is moved to ``slack_deg`` from it along the shortest way, its twist
  likewise to ``slack_deg`` beyond the predicted arc; a bone below keeps its local rotation
  (``keep="local"``) or its world rotation (``keep="world"``, its local rotation then projected
  in turn); a move of more than ``max_deg`` degrees is not made.
- ``both``: ``free`` then ``all``.

Keypoints keep their offset from their parent in the parent's frame. Features are taken in the
character's normalised rest frame (centre of the rest mesh's bounding box, divided by its height;
Y up, +Z forward as the data contract says), so the predicted ranges depend on the skeleton's
shape only, never on bone names or the target's clips.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mimicbench.benchmark.motion_range import (TWIST_BINS, BoneRanges, _twist_arc, _wrap_degrees, convex_hull_2d,
                                               swing_twist)
from mimicbench.geometry.quaternion import quat_conjugate, quat_multiply

FEATURE_SCALES = {"axis": 2.0, "position": 1.0, "parent_axis": 1.0, "length": 4.0, "children": 0.5, "depth": 0.5}
"""Weight of each feature group in the nearest-neighbour distance (see :func:`bone_features`)."""

FORMAT = "mimicat-range/1"


def bone_features(rig) -> np.ndarray:
    """Shape features (K, 12) of every bone of a character at rest, in its normalised rest frame.

    Columns, each group multiplied by its :data:`FEATURE_SCALES` weight: the bone's unit rest axis
    (3, :func:`mimicbench.benchmark.motion_range.bone_axes`), its keypoint (3, centred on the rest
    mesh's bounding-box centre, divided by its height), its parent's unit axis (3, zero for a root),
    its length (1, keypoint to the mean of its children's, or to its parent's for a leaf, over the
    height), its child count (1, capped at 3, over 3) and its depth in the tree (1, over the
    deepest bone's).

    Args:
        rig: an object with ``vertices`` (N, 3), ``keypoints`` (K, 3), ``parents`` (K,).
    """
    from mimicbench.benchmark.motion_range import bone_axes

    v = np.asarray(rig.vertices, np.float64)
    kp = np.asarray(rig.keypoints, np.float64)
    parents = np.asarray(rig.parents, np.int64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    height = max(float(hi[1] - lo[1]), 1e-9)
    pos = (kp - (lo + hi) / 2) / height
    axes = bone_axes(kp, parents)
    parent_axes = np.where((parents >= 0)[:, None], axes[np.maximum(parents, 0)], 0.0)
    children = np.bincount(parents[parents >= 0], minlength=len(parents))
    length = np.zeros(len(parents))
    depth = np.zeros(len(parents))
    for k, p in enumerate(parents):
        kids = np.flatnonzero(parents == k)
        if len(kids):
            length[k] = np.linalg.norm(kp[kids].mean(axis=0) - kp[k]) / height
        elif p >= 0:
            length[k] = np.linalg.norm(kp[k] - kp[p]) / height
        depth[k] = depth[p] + 1 if p >= 0 else 0
    depth /= max(depth.max(), 1.0)
    s = FEATURE_SCALES
    return np.concatenate([axes * s["axis"], pos * s["position"], parent_axes * s["parent_axis"],
                           length[:, None] * s["length"], np.minimum(children, 3)[:, None] / 3 * s["children"],
                           depth[:, None] * s["depth"]], axis=1)


def bone_frame(rig) -> BoneRanges:
    """The target's bone bookkeeping of the ``out_of_range`` score (reference, scored, axes, swing
    basis) with no frame seen: :meth:`BoneRanges.empty` of the rig."""
    return BoneRanges.empty(rig.character_id, rig.vertices, rig.keypoints, rig.parents, rig.weights)


@dataclass
class PredictedRanges:
    """A character's predicted ranges: ``frame`` its bone bookkeeping, ``hulls`` K arrays (M_k, 2)
    (swing hull vertices in radians, (0, 2) for a bone not predicted), ``arcs`` (K, 2) degrees
    (lo, hi) of the twist arc."""

    frame: BoneRanges
    hulls: list
    arcs: np.ndarray


@dataclass
class RangeModel:
    """Nearest-neighbour ranges over the scored bones of a training zoo.

    Attributes:
        features: (B, 12) float32 :func:`bone_features` rows of the training bones.
        hull_points: (P, 3) float32, every training bone's swing hull vertices as world rotation
            vectors (radians), bone b's rows ``hull_offsets[b]:hull_offsets[b + 1]``.
        hull_offsets: (B + 1,) int64.
        twist: (B, TWIST_BINS) bool, twist bins each training bone reached.
        characters: (B,) str, the character each training bone belongs to.
        k: neighbours per predicted bone.
        slack_deg: how far outside the predicted range :func:`project_pose` leaves a bone.
        parts: what :func:`project_pose` moves: ``both`` (swing and twist), ``swing`` or ``twist``.
        keep: what :func:`project_pose` keeps of a bone below a moved one: ``local`` or ``world``.
        max_deg: :func:`project_pose` leaves a bone whose move would turn it further than this.
        scope: ``all`` (:func:`project_pose` on every bone), ``free`` (:func:`refine_free`: only
            the target bones no source bone is matched to move; matched bones keep their rotation)
            or ``both`` (:func:`refine_free`, then :func:`project_pose` with ``keep`` on every bone).
        source: what the model was fitted on (dataset path and fingerprint).
    """

    features: np.ndarray
    hull_points: np.ndarray
    hull_offsets: np.ndarray
    twist: np.ndarray
    characters: np.ndarray
    k: int = 3
    slack_deg: float = 5.0
    parts: str = "both"
    keep: str = "local"
    scope: str = "all"
    max_deg: float = 180.0
    source: dict = field(default_factory=dict)

    @classmethod
    def fit(cls, rigs: dict, ranges: dict, k: int = 3, slack_deg: float = 5.0, parts: str = "both",
            keep: str = "local", scope: str = "all", max_deg: float = 180.0,
            source: dict | None = None) -> "RangeModel":
        """Fit on characters ``rigs`` ({id: Rig}) and their clip ranges ``ranges`` ({id:
        :class:`BoneRanges`}, :func:`mimicbench.benchmark.motion_range.ranges_for_dataset`); bones
        that are not scored or whose character has no clip frame are left out."""
        feats, points, offsets, twist, chars = [], [], [0], [], []
        for cid, rng in sorted(ranges.items()):
            if cid not in rigs or not rng.frames:
                continue
            f = bone_features(rigs[cid])
            for b in np.flatnonzero(rng.scored):
                p = np.asarray(rng.hulls[b], np.float64) @ rng.basis[b]  # (M, 3) rotation vectors
                feats.append(f[b])
                points.append(p)
                offsets.append(offsets[-1] + len(p))
                twist.append(rng.twist[b])
                chars.append(cid)
        if not feats:
            raise ValueError("RangeModel.fit: no scored bone with clip frames among the characters given")
        return cls(np.asarray(feats, np.float32), np.concatenate(points).astype(np.float32),
                   np.asarray(offsets, np.int64), np.asarray(twist, bool), np.asarray(chars), int(k),
                   float(slack_deg), _check(parts, PARTS), _check(keep, KEEPS), _check(scope, SCOPES),
                   float(max_deg), dict(source or {}))

    def predict(self, rig, exclude: str | None = None) -> PredictedRanges:
        """Predicted ranges of every scored bone of ``rig`` (a Rig); ``exclude`` leaves one
        training character's bones out of the neighbours (leave-one-out checks on the training zoo)."""
        frame = bone_frame(rig)
        feats = bone_features(rig)
        pool = np.flatnonzero(self.characters != exclude) if exclude is not None else np.arange(len(self.features))
        hulls = [np.zeros((0, 2)) for _ in frame.reference]
        arcs = np.zeros((len(frame.reference), 2))
        for b in np.flatnonzero(frame.scored):
            d = np.linalg.norm(self.features[pool] - feats[b], axis=1)
            near = pool[np.argsort(d, kind="stable")[: self.k]]
            pts = np.concatenate([self.hull_points[self.hull_offsets[n]:self.hull_offsets[n + 1]] for n in near])
            hulls[b] = convex_hull_2d(pts.astype(np.float64) @ frame.basis[b].T)
            arcs[b] = _twist_arc(self.twist[near].any(axis=0))
        return PredictedRanges(frame, hulls, arcs)

    def save(self, path) -> None:
        """Write the model as one safetensors file, its settings in the header's metadata."""
        import json

        from safetensors.numpy import save_file

        names = np.asarray(self.characters).astype(str)
        uniq, index = np.unique(names, return_inverse=True)
        meta = {"format": FORMAT, "k": str(self.k), "slack_deg": str(self.slack_deg), "parts": self.parts, "keep": self.keep, "scope": self.scope, "max_deg": str(self.max_deg),
                "feature_scales": json.dumps(FEATURE_SCALES), "characters": json.dumps(uniq.tolist()),
                "source": json.dumps(self.source)}
        save_file({"features": self.features, "hull_points": self.hull_points, "hull_offsets": self.hull_offsets,
                   "twist": np.packbits(self.twist, axis=1), "character_index": index.astype(np.int32)},
                  str(path), metadata=meta)

    @classmethod
    def load(cls, path) -> "RangeModel":
        """Read a model written by :meth:`save`; raises ValueError for another file or feature set."""
        import json

        from safetensors import safe_open

        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"range model {path}: no such file (fit one with analyses/mimicat_range.py fit)")
        with safe_open(str(path), framework="numpy") as f:
            meta = f.metadata() or {}
            if meta.get("format") != FORMAT:
                raise ValueError(f"{path}: expected a range model of format {FORMAT!r}, got {meta.get('format')!r}")
            if json.loads(meta["feature_scales"]) != FEATURE_SCALES:
                raise ValueError(f"{path}: fitted with feature scales {meta['feature_scales']}, this code uses "
                                 f"{FEATURE_SCALES}")
            t = {name: f.get_tensor(name) for name in f.keys()}
        chars = np.asarray(json.loads(meta["characters"]))[t["character_index"]]
        twist = np.unpackbits(t["twist"], axis=1, count=TWIST_BINS).astype(bool)
        return cls(t["features"], t["hull_points"], t["hull_offsets"], twist, chars, int(meta["k"]),
                   float(meta["slack_deg"]), _check(meta["parts"], PARTS), _check(meta["keep"], KEEPS),
                   _check(meta["scope"], SCOPES), float(meta["max_deg"]), json.loads(meta["source"]))


PARTS = ("both", "swing", "twist")
KEEPS = ("local", "world")
SCOPES = ("all", "free", "both")


def _check(value: str, allowed: tuple) -> str:
    if value not in allowed:
        raise ValueError(f"range model setting: expected one of {allowed}, got {value!r}")
    return value


def nearest_on_hull_2d(hull: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The point (2,) of the convex polygon ``hull`` (M, 2) (counter-clockwise, or a segment, or a
    point, as :func:`mimicbench.benchmark.motion_range.convex_hull_2d` gives) nearest to ``x`` (2,):
    ``x`` itself inside."""
    h = np.asarray(hull, np.float64)
    x = np.asarray(x, np.float64)
    if len(h) == 1:
        return h[0].copy()
    a, b = (h[:1], h[1:]) if len(h) == 2 else (h, np.roll(h, -1, axis=0))
    ab = b - a
    if len(h) >= 3 and ((ab[:, 0] * (x[1] - a[:, 1]) - ab[:, 1] * (x[0] - a[:, 0])) >= -1e-12).all():
        return x.copy()
    t = np.clip(((x - a) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-300), 0.0, 1.0)
    candidates = a + t[:, None] * ab
    return candidates[np.argmin(np.linalg.norm(candidates - x, axis=1))]


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * np.asarray(axis, np.float64)])


def _rotvec_quat(v: np.ndarray) -> np.ndarray:
    angle = float(np.linalg.norm(v))
    return _axis_angle(v / angle, angle) if angle > 1e-12 else np.array([1.0, 0.0, 0.0, 0.0])


def _clamp_twist(tau_deg: float, lo: float, hi: float, slack: float) -> float:
    """A twist angle (degrees) moved to within ``slack`` of the arc [lo, hi] (degrees) when beyond."""
    mid, half = (lo + hi) / 2, (hi - lo) / 2 + slack
    off = _wrap_degrees(tau_deg - mid)
    return tau_deg if abs(off) <= half else mid + np.sign(off) * half


def _project_local(local: np.ndarray, k: int, ranges: PredictedRanges, slack: float, slack_deg: float,
                   parts: str, max_deg: float = 180.0) -> np.ndarray:
    """Bone k's local rotation (4,) moved to within ``slack`` radians (``slack_deg`` degrees) of
    its predicted swing hull and twist arc (``parts`` as :func:`project_pose`); itself when inside,
    or when the move would turn it by more than ``max_deg`` degrees."""
    frame = ranges.frame
    swing, tau = swing_twist(local[None], frame.axes[k:k + 1], frame.basis[k:k + 1])
    swing, tau = swing[0], float(np.degrees(tau[0]))
    near = nearest_on_hull_2d(ranges.hulls[k], swing)
    gap = 0.0 if parts == "twist" else float(np.linalg.norm(swing - near))
    tau_new = tau if parts == "swing" else _clamp_twist(tau, *ranges.arcs[k], slack_deg)
    if gap <= slack and tau_new == tau:
        return local
    s = swing if gap <= slack else near + (swing - near) * (slack / gap)
    moved = quat_multiply(_rotvec_quat(s @ frame.basis[k]), _axis_angle(frame.axes[k], np.radians(tau_new)))
    turn = 2 * np.degrees(np.arccos(min(abs(float(moved @ local)), 1.0)))
    return moved if turn <= max_deg else local


def project_pose(q: np.ndarray, t: np.ndarray, parents: np.ndarray, ranges: PredictedRanges,
                 slack_deg: float, parts: str = "both", keep: str = "local",
                 max_deg: float = 180.0) -> tuple[np.ndarray, np.ndarray]:
    """A pose with every scored bone's local rotation moved to within ``slack_deg`` of its
    predicted range (see the module docstring).

    Args:
        q: (K, 4) rest-relative world rotations (w, x, y, z); t: (K, 3) posed keypoints, metres.
        parents: (K,) with ``parents[k] < k`` (-1 for roots).
        ranges: the character's :class:`PredictedRanges`.
        slack_deg: degrees outside the predicted range a bone may stay.
        parts: ``both``, ``swing`` (the twist kept) or ``twist`` (the swing kept).
        keep: what a bone below a moved one keeps: ``local``, its local rotation (it turns with
            its reference), or ``world``, its world rotation (its local rotation, read against its
            moved reference, is then projected in turn).
        max_deg: a bone whose move would turn it by more than this many degrees is left as it is.

    Returns:
        q (K, 4) and t (K, 3), float64; bones with their local rotation inside the range and
        unscored bones keep their local rotation (``keep="local"``) or world rotation (``world``).
    """
    _check(parts, PARTS)
    _check(keep, KEEPS)
    q = np.asarray(q, np.float64)
    t = np.asarray(t, np.float64)
    parents = np.asarray(parents, np.int64)
    frame = ranges.frame
    slack = np.radians(slack_deg)
    original_local = frame.local_rotations(q)
    new_q = q.copy()
    for k, r in enumerate(frame.reference):
        if r < 0:
            continue
        local = original_local[k] if keep == "local" else quat_multiply(quat_conjugate(new_q[r]), q[k])
        if frame.scored[k] and len(ranges.hulls[k]):
            local = _project_local(local, k, ranges, slack, slack_deg, parts, max_deg)
        new_q[k] = quat_multiply(new_q[r], local)
    return new_q, _carry_positions(q, t, new_q, parents)


def _slerp(a: np.ndarray, b: np.ndarray, u: float) -> np.ndarray:
    """Spherical interpolation of unit quaternions a, b (4,) at u in [0, 1], the short way."""
    b = b if float(a @ b) >= 0 else -b
    d = min(float(a @ b), 1.0)
    angle = np.arccos(d)
    if angle < 1e-9:
        return a.copy()
    return (np.sin((1 - u) * angle) * a + np.sin(u * angle) * b) / np.sin(angle)


def interpolate_free(q: np.ndarray, parents: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """World rotations (K, 4) where free bones between two fixed ones share the turn between them.

    For each fixed bone d whose path up to its nearest fixed ancestor a runs through free bones
    ``a -> u_1 -> ... -> u_{n-1} -> d``, bone u_i takes ``slerp(q_a, q_d, i / n)``: each of the n
    joints on the path turns by 1/n of the turn from a to d, where the structured initialisation
    gives the free bones a's rotation and puts the whole turn at d. Paths are taken shortest first; a free bone on
    several paths keeps the first; free bones with no fixed ancestor or descendant keep theirs.

    Args:
        q: (K, 4) rest-relative world rotations; parents: (K,) with ``parents[k] < k``;
        fixed: (K,) bool, bones whose rotation stays.
    """
    q = np.asarray(q, np.float64).copy()
    parents = np.asarray(parents, np.int64)
    fixed = np.asarray(fixed, bool)
    paths = []
    for d in np.flatnonzero(fixed):
        path, a = [], parents[d]
        while a >= 0 and not fixed[a]:
            path.append(a)
            a = parents[a]
        if a >= 0 and path:
            paths.append((len(path), d, a, path[::-1]))
    done = np.zeros(len(parents), bool)
    original = q.copy()
    for n, d, a, path in sorted(paths):
        for i, u in enumerate(path, start=1):
            if not done[u]:
                q[u] = _slerp(original[a], original[d], i / (n + 1))
                done[u] = True
    return q


def refine_free(q: np.ndarray, t: np.ndarray, parents: np.ndarray, fixed: np.ndarray, ranges: PredictedRanges | None,
                slack_deg: float, parts: str = "both") -> tuple[np.ndarray, np.ndarray]:
    """A pose whose fixed bones keep their world rotations and whose free bones are refined:
    :func:`interpolate_free`, then each free scored bone's local rotation (against its reference
    as already refined) moved to within ``slack_deg`` of its predicted range (``ranges`` None:
    interpolation only); keypoints keep their offset from their parent in the parent's frame.

    Args:
        q: (K, 4) rest-relative world rotations; t: (K, 3) posed keypoints, metres.
        parents: (K,) with ``parents[k] < k``; fixed: (K,) bool.
        ranges, slack_deg, parts: as :func:`project_pose`.

    Returns:
        q (K, 4), t (K, 3), float64.
    """
    _check(parts, PARTS)
    q = np.asarray(q, np.float64)
    t = np.asarray(t, np.float64)
    parents = np.asarray(parents, np.int64)
    fixed = np.asarray(fixed, bool)
    new_q = interpolate_free(q, parents, fixed)
    if ranges is not None:
        frame = ranges.frame
        slack = np.radians(slack_deg)
        for k, r in enumerate(frame.reference):
            if r < 0 or fixed[k] or not frame.scored[k] or not len(ranges.hulls[k]):
                continue
            local = _project_local(quat_multiply(quat_conjugate(new_q[r]), new_q[k]), k, ranges, slack, slack_deg,
                                   parts)
            new_q[k] = quat_multiply(new_q[r], local)
    return new_q, _carry_positions(q, t, new_q, parents)


def _carry_positions(q: np.ndarray, t: np.ndarray, new_q: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Keypoints (K, 3) under new rotations, each keeping its offset from its parent in the
    parent's frame: ``t'_k = t'_p + R(q'_p) R(q_p)^T (t_k - t_p)``; roots stay."""
    from mimicbench.geometry.quaternion import quat_to_matrix

    rot_old, rot_new = quat_to_matrix(q), quat_to_matrix(new_q)
    new_t = t.copy()
    for k, p in enumerate(parents):
        if p >= 0:
            new_t[k] = new_t[p] + rot_new[p] @ (rot_old[p].T @ (t[k] - t[p]))
    return new_t
