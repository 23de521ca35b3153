"""Smoothing of f_s's skinning weights along the mesh (ours; the paper asks for smooth weights
through its smoothness loss, Eq. 10, which a small f_s trained for minutes meets only in part).

Two forms: :func:`smooth_weights` counts mesh edges (config ``weight_smoothing``, iterations);
:func:`diffuse_weights` spreads over a distance (config ``weight_smoothing_radius``, a share of the
character's height), so a coarse mesh is smoothed over the same part of its body as a fine one.

Each iteration moves every vertex's weights halfway to the mean of its mesh neighbours' (unique
face edges): w <- (w + mean_{j ~ i} w_j) / 2. Rows stay convex combinations (they keep summing to
1); a vertex in no face keeps its own. The pipeline smooths after the apparel vertices were moved
onto their chains' body bones (:func:`mimicbench.baselines.mmdmc.pipeline.mesh_weights`), so a garment hanging
from two body bones blends between them instead of tearing.

Measurements behind these choices: docs/notes/measurements.md.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def smooth_weights(weights: np.ndarray, edges: np.ndarray, iterations: int) -> np.ndarray:
    """(N, K) float32 weights after ``iterations`` halfway steps to the neighbours' mean.

    Args:
        weights: (N, K) skinning weights, rows summing to 1.
        edges: (E, 2) int unique mesh edges.
        iterations: >= 0 (0 returns the weights unchanged).
    """
    if iterations < 0:
        raise ValueError(f"weight smoothing: expected iterations >= 0, got {iterations}")
    w = np.asarray(weights, np.float64)
    if iterations == 0 or not len(edges):
        return w.astype(np.float32)
    n = len(w)
    e = np.asarray(edges, np.int64)
    adj = sp.coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(n, n)).tocsr()
    degree = np.asarray(adj.sum(axis=1)).ravel()
    lonely = degree == 0
    degree[lonely] = 1.0
    for _ in range(iterations):
        mean = (adj @ w) / degree[:, None]
        mean[lonely] = w[lonely]
        w = 0.5 * (w + mean)
    return w.astype(np.float32)


def diffuse_weights(weights: np.ndarray, vertices: np.ndarray, faces: np.ndarray, radius: float) -> np.ndarray:
    """(N, K) float32 weights after implicit heat diffusion over a distance ``radius``.

    Solves ``(M - t L) w' = M w`` with t = radius^2, L the cotangent Laplacian and M the Voronoi
    mass matrix of the mesh (libigl); on a plane this is close to blurring with a Gaussian of
    standard deviation sqrt(2) * radius, whatever the mesh's resolution. Separate mesh pieces do
    not exchange weight. Rows are clipped at 0 and renormalised to sum to 1 (the cotangent
    Laplacian of obtuse triangles can undershoot); a vertex in no face keeps its own weights.

    Args:
        weights: (N, K) skinning weights, rows summing to 1.
        vertices: (N, 3) rest positions, in the unit of ``radius`` (the unit-height frame).
        faces: (M, 3) int triangles.
        radius: >= 0, same unit as ``vertices`` (0 returns the weights unchanged).
    """
    import igl
    from scipy.sparse.linalg import splu

    if not radius >= 0:
        raise ValueError(f"weight diffusion: expected a radius >= 0, got {radius}")
    w = np.asarray(weights, np.float64)
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    if len(v) != len(w):
        raise ValueError(f"weight diffusion: expected one vertex (N, 3) per weight row, got {v.shape} and {w.shape}")
    if radius == 0 or not len(f):
        return w.astype(np.float32)
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    f = f[area > 1e-12 * max(float(np.ptp(v, axis=0).max()) ** 2, 1e-30)]  # degenerate faces have no cotangents
    n = len(v)
    lap = sp.coo_matrix(igl.cotmatrix(v, f))  # libigl sizes both to the highest vertex a face uses
    lap = sp.csr_matrix((lap.data, (lap.row, lap.col)), shape=(n, n))
    mass = np.zeros(n)
    diag = igl.massmatrix(v, f, igl.MASSMATRIX_TYPE_VORONOI).diagonal()
    mass[:len(diag)] = diag
    lonely = ~(mass > 0)
    mass[lonely] = 1.0
    system = (sp.diags(mass) - radius ** 2 * sp.diags((~lonely).astype(np.float64)) @ lap).tocsc()
    out = splu(system).solve(mass[:, None] * w)
    out = np.clip(out, 0.0, None)
    total = out.sum(axis=1, keepdims=True)
    out = np.where(total > 0, out / np.where(total > 0, total, 1.0), w)
    out[lonely] = w[lonely]
    return out.astype(np.float32)
