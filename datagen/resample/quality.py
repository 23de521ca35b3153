"""Quality of a resampled character: Hausdorff distance and skinning transfer error, % of height."""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.resample.closest_point import SurfacePoints, closest_points
from mimicbench.geometry.skinning import linear_blend_skinning
from mimicbench.schemas.weights import SparseWeights


def hausdorff_percent(old_v, old_f, new_v, new_f, height: float, new_to_old: SurfacePoints | None = None) -> float:
    """Symmetric Hausdorff distance between the two surfaces, % of height.

    Every vertex of each mesh is measured against the other surface (its exact closest point),
    both ways, and the larger maximum is reported: what MeshLab's Hausdorff filter gives when it
    samples every vertex (the tests compare the two). ``new_to_old``, the closest points of the
    new vertices on the old surface, is reused when given.
    """
    there = closest_points(new_v, new_f, old_v).distances.max()
    back = (new_to_old if new_to_old is not None else closest_points(old_v, old_f, new_v)).distances.max()
    return float(max(there, back) / height * 100.0)


def transfer_error_percent(old_v, old_f, old_weights: SparseWeights, new_v, new_weights: SparseWeights, keypoints,
                           new_to_old: SurfacePoints, frames: np.ndarray, height: float) -> float:
    """Mean distance between the resampled mesh posed by LBS and the original mesh posed with the
    same frames, measured at each new vertex's corresponding point on the original surface.

    Args:
        frames: (F, K, 7) transforms of sampled frames of the character's own motions.
    """
    if len(frames) == 0:
        return 0.0
    posed_old = linear_blend_skinning(old_v, keypoints, old_weights, frames).astype(np.float64)  # (F, N, 3)
    posed_new = linear_blend_skinning(new_v, keypoints, new_weights, frames).astype(np.float64)  # (F, N', 3)
    corners = old_f[new_to_old.faces]  # (N', 3)
    target = np.einsum("qc,fqcd->fqd", new_to_old.barycentric, posed_old[:, corners])
    return float(np.linalg.norm(posed_new - target, axis=-1).mean() / height * 100.0)
