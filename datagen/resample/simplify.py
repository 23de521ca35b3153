"""Bring a mesh to a target face count: quadric edge collapse above it, subdivision then
collapse below it. Backends: ``pymeshlab`` (MeshLab's quadric edge collapse) and ``fast``
(fast-simplification, the same quadric error metric, faster)."""
from __future__ import annotations

import numpy as np
import trimesh

BACKENDS = ("pymeshlab", "fast")


def decimate(vertices: np.ndarray, faces: np.ndarray, target: int, backend: str = "pymeshlab"):
    """Quadric edge collapse of (N, 3), (M, 3) to about ``target`` faces; returns (V', F')."""
    if backend == "pymeshlab":
        import pymeshlab

        ms = pymeshlab.MeshSet()
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(vertices, np.float64), face_matrix=np.asarray(faces, np.int32)))
        ms.meshing_decimation_quadric_edge_collapse(targetfacenum=int(target), preservenormal=True, planarquadric=True,
                                                   autoclean=True)
        m = ms.current_mesh()
        return np.asarray(m.vertex_matrix(), np.float64), np.asarray(m.face_matrix(), np.int64)
    if backend == "fast":
        import fast_simplification

        v, f = fast_simplification.simplify(np.asarray(vertices, np.float32), np.asarray(faces, np.int32),
                                            target_reduction=1.0 - target / len(faces))
        return np.asarray(v, np.float64), np.asarray(f, np.int64)
    raise ValueError(f"backend: expected one of {BACKENDS}, got {backend!r}")


def resample_to(vertices: np.ndarray, faces: np.ndarray, target: int, backend: str = "pymeshlab"):
    """(V', F', subdivisions) with ``target`` faces (within 1% for inputs of at least 500 faces).

    Meshes above the target are decimated; meshes below it are subdivided (each face into four,
    at edge midpoints) until they exceed it, then decimated.
    """
    v, f = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    refined = 0
    while len(f) < target:
        v, f = trimesh.remesh.subdivide(v, f)
        refined += 1
    if len(f) > target:
        v, f = decimate(v, f, target, backend)
    v, f = _drop_unused(v, f)
    return v, f, refined


def _drop_unused(v, f):
    used = np.unique(f)
    remap = np.full(len(v), -1, np.int64)
    remap[used] = np.arange(len(used))
    return v[used], remap[f]
