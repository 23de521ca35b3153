"""An orthographic camera fitted to a set of points (numpy only; the Blender child uses it).

The view looks at the character's front from the right and a little above (the dataset's
characters face +Z with Y up), so limbs in front of the body and a tail behind it both show.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Direction from the subject to the camera, dataset frame (Y up, +Z forward): front, right, above.
VIEW_DIRECTION = np.array([0.55, 0.35, 1.0])
MARGIN = 1.15  # frame this much wider than the points' extent


@dataclass(frozen=True)
class OrthoCamera:
    """Camera pose and size in the dataset frame.

    Attributes:
        location: (3,) metres.
        right, up, back: (3,) unit axes of the camera (it looks along ``-back``).
        ortho_scale: metres the larger image side spans (Blender's ``ortho_scale``).
        clip_start, clip_end: metres along the view.
    """

    location: np.ndarray
    right: np.ndarray
    up: np.ndarray
    back: np.ndarray
    ortho_scale: float
    clip_start: float
    clip_end: float

    def project(self, points: np.ndarray, width: int, height: int) -> np.ndarray:
        """(P, 2) pixel coordinates (x right, y down) of (P, 3) points on a width x height image."""
        rel = np.asarray(points, np.float64) - self.location
        x, y = rel @ self.right, rel @ self.up
        px_per_m = max(width, height) / self.ortho_scale
        return np.stack([width / 2 + x * px_per_m, height / 2 - y * px_per_m], axis=1)


def fit_camera(points: np.ndarray, width: int, height: int, direction=VIEW_DIRECTION, scale: float | None = None,
               centre: np.ndarray | None = None) -> OrthoCamera:
    """The orthographic camera that frames (P, 3) points on a width x height image.

    Args:
        points: (P, 3) metres, dataset frame; the camera stands in front of all of them.
        direction: from the subject towards the camera (need not be unit length).
        scale: ``ortho_scale`` to use (default: the larger of the points' projected width and
            height, in image proportions, times :data:`MARGIN`).
        centre: (3,) a point the image is centred on (default: the centre of the points'
            projected bounding box).
    """
    pts = np.asarray(points, np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0 or not np.isfinite(pts).all():
        raise ValueError(f"fit_camera: expected finite points of shape (P, 3) with P > 0, got {pts.shape}")
    back = np.asarray(direction, np.float64)
    back = back / np.linalg.norm(back)
    right = np.cross([0.0, 1.0, 0.0], back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    pr, pu, pb = pts @ right, pts @ up, pts @ back
    w, h = float(np.ptp(pr)), float(np.ptp(pu))
    extent = max(w, h, float(np.ptp(pb)), 1e-3)
    if scale is None:
        aspect = width / height
        scale = max(w, h * aspect) if width >= height else max(h, w / aspect)
        scale = max(scale, 1e-3) * MARGIN
    if centre is None:
        cr, cu = (pr.min() + pr.max()) / 2, (pu.min() + pu.max()) / 2
    else:
        c = np.asarray(centre, np.float64)
        cr, cu = float(c @ right), float(c @ up)
    distance = float(pb.max()) + extent  # in front of every point
    location = right * cr + up * cu + back * distance
    depth = distance - float(pb.min())
    return OrthoCamera(location, right, up, back, float(scale), clip_start=extent * 1e-3, clip_end=depth + extent)
