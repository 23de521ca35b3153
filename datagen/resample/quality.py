"""Quality of a resampled character: Hausdorff distance and skinning transfer error, % of height."""
from __future__ import annotations

import numpy as np

from datagen.resample.closest_point import SurfacePoints
from mimicbench.skinning import linear_blend_skinning


def hausdorff_percent(old_v, old_f, new_v, new_f, height: float) -> float:
    """Symmetric Hausdorff distance between the two surfaces, % of height.

    MeshLab's Hausdorff filter (through pymeshlab), sampling every vertex of each mesh against
    the other surface, both ways; the larger maximum is reported.
    """
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(old_v, np.float64), face_matrix=np.asarray(old_f, np.int32)))
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(new_v, np.float64), face_matrix=np.asarray(new_f, np.int32)))
    there = ms.get_hausdorff_distance(sampledmesh=0, targetmesh=1, samplevert=True, samplenum=len(old_v))["max"]
    back = ms.get_hausdorff_distance(sampledmesh=1, targetmesh=0, samplevert=True, samplenum=len(new_v))["max"]
    return float(max(there, back) / height * 100.0)


def transfer_error_percent(old_v, old_f, old_weights, new_v, new_weights, keypoints, new_to_old: SurfacePoints,
                           frames: np.ndarray, height: float) -> float:
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
