"""Bring a mesh to a target face count: quadric edge collapse above it, subdivision then
collapse below it. Backends: ``pymeshlab`` (MeshLab's quadric edge collapse) and ``fast``
(fast-simplification, the same quadric error metric, faster).

Both backends say where each output vertex came from: fast-simplification's collapse history
(replayed by ``fast_simplification.replay_simplification``) maps every input vertex to the output
vertex it was collapsed into, and MeshLab keeps each surviving vertex's quality, which carries the
input vertex's index. :func:`resample_to` turns that into the piece of the input mesh each output
vertex lies on; re-skinning reads weights from that piece alone
(:mod:`mimicbench.datagen.resample.pieces`)."""
from __future__ import annotations

import numpy as np
import trimesh

from mimicbench.datagen.resample.clean import weld_short_edges
from mimicbench.geometry.mesh import mesh_pieces

BACKENDS = ("fast", "pymeshlab")

# MeshLab's quadric edge collapse, every parameter spelled out: pymeshlab keeps a filter's last
# parameters for the next call in the same process, so a default left out is not a default.
# ``preservenormal`` (no face flips) stays on: without it, pieces touching at a merged vertex blew
# up (Hausdorff 755% of height on a zoo snake); ``planarquadric`` stays off: on the zoo it doubled
# the Hausdorff distance.
PYMESHLAB_QUADRIC = {"targetperc": 0.0, "qualitythr": 0.3, "preserveboundary": False, "boundaryweight": 1.0, "preservenormal": True,
                     "preservetopology": False, "optimalplacement": True, "planarquadric": False,
                     "planarweight": 0.001, "qualityweight": False, "autoclean": True, "selected": False}

# fast-simplification collapses every edge under a threshold that grows with the iteration
# (its "aggressiveness"); 3 halves the Hausdorff distance of its default 7 on the zoo at the
# same speed, but may stop short of the target, so higher values are tried next.
FAST_AGGRESSIVENESS = (3, 5, 7, 9)

# decimations tried when welding the result removes faces (see :func:`resample_to`); on the shared
# assets the second or third lands within 1% of the target
WELD_RETRIES = 4


def decimate(vertices: np.ndarray, faces: np.ndarray, target: int, backend: str = "fast"):
    """Quadric edge collapse of (N, 3), (M, 3) to about ``target`` faces.

    Returns:
        (V' (N', 3) float64, F' (M', 3) int64, source (N',) int64): ``source`` is, for each output
        vertex, an input vertex collapsed into it (fast: the lowest-index one; pymeshlab: the one
        that survived). Edge collapse joins vertices along edges only, so all of them lie on one
        piece of the input; pymeshlab's clean-up after the collapse also merges vertices on the same
        place, which can be on two pieces (a zoo's touching hair strands).
    """
    if backend == "pymeshlab":
        import pymeshlab

        ms = pymeshlab.MeshSet()
        # the vertex quality carries each vertex's index through the collapse (MeshLab keeps the survivor's)
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(vertices, np.float64),
                                   face_matrix=np.asarray(faces, np.int32),
                                   v_scalar_array=np.arange(len(vertices), dtype=np.float64)))
        ms.meshing_decimation_quadric_edge_collapse(targetfacenum=int(target), **PYMESHLAB_QUADRIC)
        m = ms.current_mesh()
        return (np.asarray(m.vertex_matrix(), np.float64), np.asarray(m.face_matrix(), np.int64),
                np.rint(m.vertex_scalar_array()).astype(np.int64))
    if backend == "fast":
        import fast_simplification

        v32, f32 = np.asarray(vertices, np.float32), np.asarray(faces, np.int32)
        for agg in FAST_AGGRESSIVENESS:
            v, f, collapses = fast_simplification.simplify(v32, f32, target_reduction=1.0 - target / len(faces),
                                                           agg=agg, return_collapses=True)
            if len(f) <= target * 1.01:
                break
        # (N,) the output vertex each input vertex was collapsed into
        _, _, into = fast_simplification.replay_simplification(v32, f32, collapses)
        source = np.full(len(v), len(v32), np.int64)
        np.minimum.at(source, into[into >= 0], np.flatnonzero(into >= 0))
        return np.asarray(v, np.float64), np.asarray(f, np.int64), source
    raise ValueError(f"backend: expected one of {BACKENDS}, got {backend!r}")


def resample_to(vertices: np.ndarray, faces: np.ndarray, target: int, backend: str = "fast",
                report: dict | None = None):
    """(V', F', subdivisions, pieces) with ``target`` faces (within 1% for inputs of at least 500 faces).

    Meshes above the target are decimated; meshes below it are subdivided (each face into four,
    at edge midpoints) until they exceed it, then decimated. The result is welded
    (:func:`mimicbench.datagen.resample.clean.weld_short_edges`): quadric edge collapse sends several
    vertices to one sharp corner of a low-poly mesh and leaves them there, a few 1e-7 of the size
    apart, in zero-area triangles. When welding takes the count more than 1% from ``target``, the
    refined mesh is decimated again, aiming higher by what welding removed (at most
    ``WELD_RETRIES`` decimations; the count nearest ``target`` is kept). A mesh with nothing to weld
    comes out exactly as decimation left it.

    ``pieces`` (N',) int64 is the piece of the input mesh (its :func:`mimicbench.geometry.mesh.mesh_pieces`
    label) each output vertex came from: subdivision, collapse and welding all join vertices along
    edges only.

    Args:
        report: when given, filled with what welding removed (``weld_short_edges``' counts) and
            the face count decimation aimed at (``decimation_target``).
    """
    v, f = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    pieces = mesh_pieces(f, len(v)).astype(np.float64)[:, None]
    refined = 0
    while len(f) < target:
        # a midpoint takes the mean of its edge's two labels, which are one piece's: the label itself
        v, f, carried = trimesh.remesh.subdivide(v, f, vertex_attributes={"piece": pieces})
        pieces = carried["piece"]
        refined += 1
    pieces = np.rint(pieces[:, 0]).astype(np.int64)
    aim, best = target, None
    for _ in range(WELD_RETRIES):
        out_v, out_f, source = decimate(v, f, aim, backend) if len(f) > aim else (v, f, np.arange(len(v)))
        out_v, out_f, used = _drop_unused(out_v, out_f)
        out_v, out_f, kept, welded = weld_short_edges(out_v, out_f)
        if best is None or abs(len(out_f) - target) < abs(len(best[1]) - target):
            best = (out_v, out_f, pieces[source[used[kept]]], dict(welded, decimation_target=int(aim)))
        if abs(len(out_f) - target) <= 0.01 * target or aim >= len(f) \
                or not (welded["welded_vertices"] or welded["zero_area_faces"]):
            break
        aim = min(len(f), aim + target - len(out_f))
    out_v, out_f, out_pieces, welded = best
    if report is not None:
        report.update(welded)
    return out_v, out_f, refined, out_pieces


def _drop_unused(v, f):
    """(V', F', used): the vertices (N, 3) some face (M, 3) uses, and their indices (N',) in v."""
    used = np.unique(f)
    remap = np.full(len(v), -1, np.int64)
    remap[used] = np.arange(len(used))
    return v[used], remap[f], used
