"""Quality of a simulated clip, recorded per clip in the character's ``meta['apparel']``.

All measures are over the apparel vertices (the character's apparel vertex mask) of the mesh
posed by linear blend skinning with the stored transforms:

- ``inside_pct``: share of apparel vertices inside the body (inside any body piece of
  :mod:`mimicbench.datagen.apparel.body_shapes`), mean over frames, percent; ``inside_rest_pct`` the same in
  the rest pose; ``new_inside_pct`` (mean) and ``new_inside_max_pct`` (worst frame) count only
  vertices that are outside the body at rest (authored overlaps such as hair roots in the scalp
  are not penetration).
- ``max_edge_stretch``: largest ``|l / l_rest - 1|`` over apparel edges and frames.
- ``max_accel``: largest vertex acceleration (second difference times fps^2), m/s^2 (jitter);
  ``max_accel_kinematic`` the same for the kinematic clip. ``p99_accel`` and
  ``p99_accel_kinematic``: the 99th percentile of the same accelerations over every apparel
  vertex and frame (one struck vertex moves the max, not the p99).
- ``max_accel_kinematic_body``: the kinematic clip's largest acceleration over the body's vertices
  (every vertex not apparel), m/s^2. A limb that strikes the apparel moves this fast: a thigh
  flexing at a jump's landing struck skirt strips at 2-3 m/s, a physical impact (the same peak at
  2x and 4x the physics rate) that the apparel's own kinematic peak cannot show (the skinned hem
  passes through the thigh), so ``max_accel`` over 3x ``max_accel_kinematic`` alone does not tell
  jitter from a strike (issue 33: seed-711 jumps 54-81 m/s^2 against 16.6 apparel and 105-130 body).
- ``max_accel_kinematic_touching``: the same over the body vertices of the body pieces (each
  vertex's piece is its dominant bone's) that some simulated apparel vertex comes within
  :data:`TOUCH_SHARE` of the height of at some frame: the limbs that can strike the apparel (a hand
  waving far from a skirt does not count), m/s^2; 0 when no piece is touched.
  :func:`over_jitter_bound` compares ``max_accel`` with 3x the larger of this and
  ``max_accel_kinematic``: the jitter test of issue 33.
- ``secondary_motion_pct`` (mean over frames) and ``secondary_motion_max_pct`` (worst frame):
  mean distance of apparel vertices from their kinematic positions, percent of height.

Beside these, :func:`mimicbench.datagen.apparel.setup.simulated_record` records the simulation's counts and
``resettles`` (frames at which chains that escaped the speed bound were put back at rest on
their anchors, :mod:`mimicbench.datagen.apparel.simulate`) and ``resettled_frames`` (those frames' clip
indices; relaxation frames negative, -1 the last).
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.apparel.body_shapes import BodyPiece, points_inside
from mimicbench.datagen.apparel.selection import dominant_bone
from mimicbench.geometry.kinematics import rest_transforms
from mimicbench.geometry.mesh import edge_lengths, unique_edges
from mimicbench.geometry.skinning import linear_blend_skinning


TOUCH_SHARE = 0.02  # an apparel vertex this close to a body piece (share of height) touches it
JITTER_RATIO = 3.0  # issue 33: a clip's peak over this many times its kinematic peak is jitter


def over_jitter_bound(quality: dict) -> bool:
    """True when a clip's ``max_accel`` is above :data:`JITTER_RATIO` times the larger of its
    apparel's kinematic peak and the kinematic peak of the body vertices that touch its apparel
    (a limb's strike is physical; a peak above both is the simulation's own). Qualities recorded
    before ``max_accel_kinematic_touching`` existed are judged by the apparel's peak alone."""
    bound = max(quality["max_accel_kinematic"], quality.get("max_accel_kinematic_touching", 0.0))
    return quality["max_accel"] > JITTER_RATIO * bound


def _touched_bones(pieces: list[BodyPiece], transforms: np.ndarray, points: np.ndarray, reach: float,
                   chunk: int = 32) -> list[int]:
    """The bones of the pieces that any of ``points`` (F, A, 3) comes within ``reach`` metres of
    (or inside) at some frame of the poses ``transforms`` (F, K, 7). Frames are tested ``chunk`` at
    a time and a piece's test stops at its first touch (most touched pieces are touched in the
    first frames; testing every frame of a 1,901-frame clip doubled the cost of its quality)."""
    return [piece.bone for piece in pieces
            if any(points_inside([piece], transforms[s:s + chunk], points[s:s + chunk], tol=-reach).any()
                   for s in range(0, len(points), chunk))]


def _accel(posed: np.ndarray, fps: float) -> np.ndarray:
    """(F - 2, A) acceleration magnitudes (m/s^2) of vertices ``posed`` (F, A, 3) metres at ``fps``."""
    if len(posed) < 3:
        return np.zeros((0, posed.shape[1]))
    return np.linalg.norm((posed[2:] - 2 * posed[1:-1] + posed[:-2]) * fps ** 2, axis=-1)


def _peak_and_p99(acc: np.ndarray) -> tuple[float, float]:
    """The largest and the 99th percentile of accelerations ``acc`` (any shape); 0 for none."""
    if acc.size == 0:
        return 0.0, 0.0
    return float(acc.max()), float(np.percentile(acc, 99.0))


def clip_quality(vertices, faces, keypoints, weights, apparel_mask, pieces: list[BodyPiece], simulated: np.ndarray,
                 kinematic: np.ndarray, fps: float, height: float) -> dict:
    """The measures above for one clip.

    Args:
        vertices: (N, 3) rest vertices; faces: (M, 3); keypoints: (K, 3); weights: skin weights.
        apparel_mask: (N,) bool apparel vertices.
        pieces: body pieces of the character.
        simulated, kinematic: (F, K, 7) the simulated clip and the clip it came from.
        fps: frames per second; height: the character's height, metres.
    """
    mask = np.asarray(apparel_mask, bool)
    sim = linear_blend_skinning(vertices, keypoints, weights, simulated).astype(np.float64)[:, mask]
    kin_all = linear_blend_skinning(vertices, keypoints, weights, kinematic).astype(np.float64)
    kin, kin_body = kin_all[:, mask], kin_all[:, ~mask]
    rest_pose = rest_transforms(keypoints).astype(np.float64)
    inside_rest = points_inside(pieces, rest_pose, np.asarray(vertices, np.float64)[mask])
    inside = points_inside(pieces, np.asarray(simulated, np.float64), sim)  # (F, A)
    new_inside = (inside & ~inside_rest).mean(axis=1) * 100.0
    faces = np.asarray(faces)
    apparel_faces = faces[mask[faces].all(axis=1)]
    remap = np.cumsum(mask) - 1
    edges = remap[unique_edges(apparel_faces)] if len(apparel_faces) else np.zeros((0, 2), int)
    stretch = 0.0
    if len(edges):
        rest_len = edge_lengths(np.asarray(vertices, np.float64)[mask], edges)
        ok = rest_len > 1e-9
        posed_len = np.linalg.norm(sim[:, edges[:, 0]] - sim[:, edges[:, 1]], axis=-1)
        stretch = float(np.abs(posed_len[:, ok] / rest_len[ok] - 1.0).max())
    moved = np.linalg.norm(sim - kin, axis=-1).mean(axis=1) / height * 100.0
    peak, p99 = _peak_and_p99(_accel(sim, fps))
    peak_kinematic, p99_kinematic = _peak_and_p99(_accel(kin, fps))
    acc_body = _accel(kin_body, fps)  # (F - 2, B)
    peak_body = _peak_and_p99(acc_body)[0]
    owner = dominant_bone(weights, len(keypoints))[~mask]
    touching = np.isin(owner, _touched_bones(pieces, np.asarray(simulated, np.float64), sim, TOUCH_SHARE * height))
    peak_touching = _peak_and_p99(acc_body[:, touching])[0]
    return {
        "inside_pct": float(inside.mean() * 100.0), "inside_rest_pct": float(inside_rest.mean() * 100.0),
        "new_inside_pct": float(new_inside.mean()), "new_inside_max_pct": float(new_inside.max()),
        "max_edge_stretch": stretch, "max_accel": peak, "max_accel_kinematic": peak_kinematic,
        "p99_accel": p99, "p99_accel_kinematic": p99_kinematic, "max_accel_kinematic_body": peak_body,
        "max_accel_kinematic_touching": peak_touching,
        "secondary_motion_pct": float(moved.mean()), "secondary_motion_max_pct": float(moved.max()),
    }
