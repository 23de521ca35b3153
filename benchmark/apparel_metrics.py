"""Apparel scores over time and against the body: acceleration error and penetration share.

PMD_a scores each frame on its own, so apparel that shakes frame to frame can score as well as
smooth apparel. Cloth papers report two more figures (HOOD, Grigorev et al., CVPR 2023), and
the ``apparel`` protocol gives both per case:

- :func:`accel_error`: mean over apparel vertices and frames of ``|a_pred - a_gt|``, each
  acceleration the second difference of the vertex's positions times fps^2, in m/s^2 of the
  character scaled to :data:`REFERENCE_HEIGHT_M` (1.70 m) tall.
- :func:`penetration_share`: share (percent) of apparel vertices within :data:`CONTACT_MM`
  millimetres of the body, or inside it (HOOD's 1 mm), the distance scaled with the character
  (1 mm at 1.70 m height). The body is the target's convex body pieces
  (:func:`mimicbench.datagen.apparel.body_shapes.body_pieces`, one a body bone, the shapes the simulation
  collides with), posed by the ground truth's bones; apparel vertices already that close at rest
  (hair roots in the scalp, a collar on the neck: authored, not penetration) are not counted.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.apparel.body_shapes import BodyPiece, body_pieces, points_inside
from mimicbench.datagen.apparel.selection import dominant_bone
from mimicbench.geometry.kinematics import rest_transforms

REFERENCE_HEIGHT_M = 1.70
"""Both scores are stated for the character scaled to this height (MMDMC's 1.70 m)."""
CONTACT_MM = 1.0
"""HOOD's contact distance: an apparel vertex this close to the body (mm at 1.70 m) or inside counts."""


def second_differences(positions: np.ndarray, fps: float) -> np.ndarray:
    """(F - 2, ..., 3) accelerations ``(x[f+1] - 2 x[f] + x[f-1]) * fps^2`` of ``positions`` (F, ..., 3)."""
    x = np.asarray(positions, np.float64)
    if len(x) < 3:
        return np.zeros((0,) + x.shape[1:])
    return (x[2:] - 2.0 * x[1:-1] + x[:-2]) * float(fps) ** 2


def accel_error(pred: np.ndarray, truth: np.ndarray, apparel: np.ndarray, fps: float, height: float) -> float | None:
    """Mean over apparel vertices and frames of ``|a_pred - a_gt|``, m/s^2 at 1.70 m height.

    Args:
        pred, truth: (F, N, 3) posed meshes of consecutive frames, metres.
        apparel: (N,) bool, the vertices scored.
        fps: frames per second of the sequence.
        height: the character's rest height, metres (positions are scaled by 1.70 / height).

    Returns:
        The mean, or None for fewer than 3 frames or no apparel vertex.

    >>> x = np.zeros((4, 1, 3)); x[:, 0, 0] = [0.0, 0.0, 0.01, 0.0]
    >>> accel_error(x, np.zeros((4, 1, 3)), np.array([True]), 10.0, 1.70)  # (|1| + |-2|) / 2 m/s^2
    1.5
    """
    pred, truth = np.asarray(pred, np.float64), np.asarray(truth, np.float64)
    mask = np.asarray(apparel, bool)
    if pred.shape != truth.shape or pred.ndim != 3 or pred.shape[-1] != 3 or mask.shape != pred.shape[1:2]:
        raise ValueError(f"accel_error: expected pred and truth (F, N, 3) of one shape and apparel (N,); got "
                         f"{pred.shape}, {truth.shape} and {mask.shape}")
    if height <= 0 or fps <= 0:
        raise ValueError(f"accel_error: expected height > 0 m and fps > 0, got {height} and {fps}")
    if len(pred) < 3 or not mask.any():
        return None
    diff = second_differences(pred[:, mask], fps) - second_differences(truth[:, mask], fps)
    return float(np.linalg.norm(diff, axis=-1).mean() * REFERENCE_HEIGHT_M / height)


def contact_reach(height: float, mm: float = CONTACT_MM) -> float:
    """The contact distance in the character's metres: ``mm`` millimetres at 1.70 m height."""
    return mm / 1000.0 * float(height) / REFERENCE_HEIGHT_M


def character_body_pieces(vertices, keypoints, weights, apparel_bones) -> list[BodyPiece]:
    """The convex body pieces of a character's body bones (every bone not in ``apparel_bones`` (K,))."""
    keypoints = np.asarray(keypoints, np.float64)
    owner = dominant_bone(weights, len(keypoints))
    return body_pieces(np.asarray(vertices, np.float64), keypoints, owner, ~np.asarray(apparel_bones, bool))


def clear_at_rest(pieces: list[BodyPiece], rest_keypoints, rest_points, reach: float) -> np.ndarray:
    """(A,) bool: rest points (A, 3) farther than ``reach`` metres outside every piece at rest."""
    rest = rest_transforms(np.asarray(rest_keypoints, np.float64)).astype(np.float64)
    return ~points_inside(pieces, rest, np.asarray(rest_points, np.float64), tol=-reach)


def penetration_share(points: np.ndarray, pieces: list[BodyPiece], transforms: np.ndarray, counted: np.ndarray,
                      reach: float) -> float | None:
    """Percent of the ``counted`` points within ``reach`` metres of the body or inside it, mean over frames.

    Args:
        points: (F, A, 3) apparel vertices of each frame, metres.
        pieces: the body's convex pieces; transforms: (F, K, 7) the bones posing them each frame.
        counted: (A,) bool, the points scored (:func:`clear_at_rest`).
        reach: metres (:func:`contact_reach`).

    Returns:
        The percentage, or None when no point is counted.
    """
    points = np.asarray(points, np.float64)
    counted = np.asarray(counted, bool)
    if points.ndim != 3 or points.shape[-1] != 3 or counted.shape != points.shape[1:2]:
        raise ValueError(f"penetration_share: expected points (F, A, 3) and counted (A,); got {points.shape} and "
                         f"{counted.shape}")
    if not counted.any() or not len(points):
        return None
    near = points_inside(pieces, np.asarray(transforms, np.float64), points[:, counted], tol=-float(reach))
    return float(near.mean() * 100.0)
