"""Soft as-rigid-as-possible restoration of f_d's apparel (ours; config ``history_arap``, on in
the shipped f_d): the predicted vertices pull the apparel where f_d put it, ARAP keeps its edges' lengths.

The body-history f_d (:mod:`mimicbench.baselines.mmdmc.apparel_history`) predicts each vertex's offset on its
own. Where the simulated strand could swing one way or the other, the best per-vertex guess is the
mean of the two, which lies inside the arc: the strand comes out short, and ELS counts every edge
that shrank. Trained to keep lengths (``w_stretch`` 1.0) f_d gives up most of its offset (-11%
PMD_a); trained for positions (``w_stretch`` 0.1) it removes 29% of PMD_a but costs 0.0115 ELS.

This step takes the position-trained prediction P (F, A, 3) and, frame by frame, finds the apparel X
that minimises the ARAP energy of Sorkine and Alexa (2007) against the rest apparel R, with uniform
("spoke") edge weights, plus a pull towards the prediction:

    E(X) = sum_i sum_{j in N(i)} |(x_i - x_j) - Q_i (r_i - r_j)|^2 + 2 * weight * sum_i |x_i - p_i|^2

over each vertex's rotation Q_i and X, by local-global iterations started from X = P. The local step
is the best rotation per vertex (the polar factor of its edge covariance); the global step solves
``(L + weight I) X = b(Q) + weight P`` with L the graph Laplacian of the apparel's mesh edges
(factorised once; three columns a frame). Lengths and the prediction meet in proportion to
``weight``: at 0 the result is a rigid-as-possible copy of the rest apparel (not unique: the weight
must be > 0), as weight grows it approaches P. A vertex on no edge keeps its prediction. Uniform
weights need no triangle to be well shaped (resampled meshes keep zero-area ones) and read a
triangle strip, a line of edges or a hair card alike. The energy, and so the result, is the same
in any length unit (both terms are squared lengths).

Measurements behind the default weight: docs/notes/mmdmc.md (the ARAP restoration).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

ITERATIONS = 8
"""Default local-global iterations (from the prediction; the energy falls every iteration)."""


def edges_among(edges: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """(E', 2) int64 the mesh edges (E, 2) whose two ends are both among the sorted vertices ``idx``,
    as indices into ``idx``."""
    both = np.isin(edges, idx).all(1)
    return np.searchsorted(idx, edges[both]).astype(np.int64)


def adjacency(edges: np.ndarray, count: int):
    """(count, count) scipy CSR 0/1 adjacency of the undirected ``edges`` (E, 2) (self-loops and
    repeats dropped). The graph Laplacian is ``diag(degree) - adjacency``."""
    from scipy.sparse import coo_matrix

    e = _undirected(edges)
    adj = coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(count, count))
    return adj.tocsr()


def laplacian(edges: np.ndarray, count: int):
    """(count, count) scipy CSR graph Laplacian of the undirected ``edges`` (E, 2): degree on the
    diagonal, -1 per neighbour (each unique edge counted once, self-loops and repeats dropped)."""
    from scipy.sparse import diags

    adj = adjacency(edges, count)
    return (diags(np.asarray(adj.sum(1)).ravel()) - adj).tocsr()


def nearest_rotations(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) the rotation nearest each matrix of ``m`` (..., 3, 3) in the Frobenius norm:
    ``U diag(1, 1, det(U V^T)) V^T`` of its SVD ``U S V^T`` (identity for a zero matrix).

    Found by Higham's scaled Newton iteration for the polar factor (X <- (g X + X^-T / g) / 2, g =
    |det X|^(-1/3)), compiled; a matrix it does not settle (det <= 0, where the rotation needs the
    sign flip, or nearly singular, as at a vertex whose edges are collinear) takes the SVD.
    """
    m = np.ascontiguousarray(m, np.float64)
    flat = m.reshape(-1, 3, 3)
    out = np.empty_like(flat)
    _nearest_rotations(flat, out)
    return out.reshape(m.shape)


def fit_rotations(rest: np.ndarray, posed: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(F, A, 3, 3) each vertex's best rotation Q_i taking its rest edges to its posed ones: the
    rotation nearest to C_i = sum_j (x_i - x_j)(r_i - r_j)^T over its neighbours j.

    Args:
        rest: (A, 3) rest positions; posed: (F, A, 3); edges: (E, 2) mesh edges (repeats and
            self-loops are dropped).
    """
    p = np.ascontiguousarray(posed, np.float64)
    q = np.empty(p.shape + (3,))
    _fit_rotations(np.ascontiguousarray(rest, np.float64), p, _undirected(edges), q)
    return q


def restore(predicted: np.ndarray, rest: np.ndarray, edges: np.ndarray, weight: float,
            iterations: int = ITERATIONS) -> np.ndarray:
    """(F, A, 3) float64 apparel that keeps the rest apparel's edges and stays near ``predicted``
    (the module docstring's E(X), minimised by ``iterations`` local-global steps from the prediction).

    Args:
        predicted: (F, A, 3) f_d's apparel over the frames; rest: (A, 3) the rest apparel (same unit).
        edges: (E, 2) mesh edges among the A vertices (local indices).
        weight: pull towards the prediction, > 0 (per vertex, against each of its edges' weight 1).
        iterations: local-global steps (0: the prediction itself).
    """
    from scipy.sparse import identity
    from scipy.sparse.linalg import factorized

    p = np.asarray(predicted, np.float64)
    r = np.ascontiguousarray(rest, np.float64)
    if p.ndim != 3 or p.shape[2] != 3 or r.shape != p.shape[1:]:
        raise ValueError(f"restore: expected predicted (F, A, 3) and rest (A, 3), got {p.shape} and {r.shape}")
    if not weight > 0:
        raise ValueError(f"restore: weight: expected > 0, got {weight}")
    e = np.asarray(edges, np.int64).reshape(-1, 2)
    outside = e[(e < 0) | (e >= len(r))]
    if len(outside):
        raise ValueError(f"restore: an edge names vertex {int(outside[0])}, expected 0..{len(r) - 1}")
    e = _undirected(e)
    if iterations <= 0 or len(e) == 0:
        return p.copy()
    f, a = p.shape[:2]
    solve = factorized((laplacian(e, a) + weight * identity(a)).tocsc())
    q = np.empty((f, a, 3, 3))
    b = np.empty((f, a, 3))
    x = p
    for _ in range(iterations):
        _fit_rotations(r, np.ascontiguousarray(x), e, q)              # local step: Q (F, A, 3, 3)
        _rotated_rest_edges(r, q, e, b)                               # b_i = sum_j (Q_i + Q_j)(r_i - r_j) / 2
        rhs = (b + weight * p).transpose(1, 0, 2).reshape(a, 3 * f)
        x = solve(rhs).reshape(a, f, 3).transpose(1, 0, 2)            # global step
    return x


def _undirected(edges: np.ndarray) -> np.ndarray:
    """(E', 2) int64 contiguous: each undirected edge of (E, 2) once as (low, high), no self-loops."""
    e = np.sort(np.asarray(edges, np.int64).reshape(-1, 2), axis=1)
    return np.ascontiguousarray(np.unique(e[e[:, 0] != e[:, 1]], axis=0))


@njit(cache=True)
def _nearest_rotation(m: np.ndarray, out: np.ndarray) -> None:
    """The rotation nearest the (3, 3) matrix ``m``, written to ``out`` (see :func:`nearest_rotations`).
    Scalars, not arrays, so that no call allocates."""
    scale = 0.0
    for i in range(3):
        for j in range(3):
            scale += m[i, j] * m[i, j]
    if scale == 0.0:
        for i in range(3):
            for j in range(3):
                out[i, j] = 1.0 if i == j else 0.0
        return
    s = 1.0 / math.sqrt(scale)
    a00, a01, a02 = m[0, 0] * s, m[0, 1] * s, m[0, 2] * s
    a10, a11, a12 = m[1, 0] * s, m[1, 1] * s, m[1, 2] * s
    a20, a21, a22 = m[2, 0] * s, m[2, 1] * s, m[2, 2] * s
    settled = False
    for step in range(30):
        c00, c01, c02 = a11 * a22 - a12 * a21, a12 * a20 - a10 * a22, a10 * a21 - a11 * a20  # det * X^-T
        c10, c11, c12 = a02 * a21 - a01 * a22, a00 * a22 - a02 * a20, a01 * a20 - a00 * a21
        c20, c21, c22 = a01 * a12 - a02 * a11, a02 * a10 - a00 * a12, a00 * a11 - a01 * a10
        det = a00 * c00 + a01 * c01 + a02 * c02
        if not det > (1e-9 if step == 0 else 0.0):  # a reflection or nearly singular: the SVD
            break
        g = det ** (1.0 / 3.0)
        h, k = 0.5 / g, 0.5 * g / det
        n00, n01, n02 = a00 * h + c00 * k, a01 * h + c01 * k, a02 * h + c02 * k
        n10, n11, n12 = a10 * h + c10 * k, a11 * h + c11 * k, a12 * h + c12 * k
        n20, n21, n22 = a20 * h + c20 * k, a21 * h + c21 * k, a22 * h + c22 * k
        change = (abs(n00 - a00) + abs(n01 - a01) + abs(n02 - a02) + abs(n10 - a10) + abs(n11 - a11)
                  + abs(n12 - a12) + abs(n20 - a20) + abs(n21 - a21) + abs(n22 - a22))
        a00, a01, a02, a10, a11, a12, a20, a21, a22 = n00, n01, n02, n10, n11, n12, n20, n21, n22
        if change < 1e-10:  # quadratic convergence: the step just taken left ~1e-20
            settled = True
            break
    if settled:
        out[0, 0], out[0, 1], out[0, 2] = a00, a01, a02
        out[1, 0], out[1, 1], out[1, 2] = a10, a11, a12
        out[2, 0], out[2, 1], out[2, 2] = a20, a21, a22
        return
    u, _, vt = np.linalg.svd(m)
    r = u @ vt
    if _det3(r) < 0.0:
        for i in range(3):
            u[i, 2] = -u[i, 2]
        r = u @ vt
    out[:] = r


@njit(cache=True)
def _nearest_rotations(m: np.ndarray, out: np.ndarray) -> None:
    for k in range(m.shape[0]):
        _nearest_rotation(m[k], out[k])


@njit(cache=True)
def _det3(m: np.ndarray) -> float:
    return (m[0, 0] * (m[1, 1] * m[2, 2] - m[1, 2] * m[2, 1]) - m[0, 1] * (m[1, 0] * m[2, 2] - m[1, 2] * m[2, 0])
            + m[0, 2] * (m[1, 0] * m[2, 1] - m[1, 1] * m[2, 0]))


@njit(cache=True)
def _fit_rotations(rest: np.ndarray, posed: np.ndarray, edges: np.ndarray, q: np.ndarray) -> None:
    """q (F, A, 3, 3) out: per frame and vertex the rotation nearest sum_j (x_i - x_j)(r_i - r_j)^T
    over the unique ``edges`` (E, 2) (each edge adds the same product to both its ends)."""
    f_count, a_count = posed.shape[0], posed.shape[1]
    cov = np.zeros((a_count, 3, 3))
    for f in range(f_count):
        cov[:] = 0.0
        for e in range(edges.shape[0]):
            i, j = edges[e, 0], edges[e, 1]
            for u in range(3):
                dx = posed[f, i, u] - posed[f, j, u]
                for v in range(3):
                    prod = dx * (rest[i, v] - rest[j, v])
                    cov[i, u, v] += prod
                    cov[j, u, v] += prod
        for i in range(a_count):
            _nearest_rotation(cov[i], q[f, i])


@njit(cache=True)
def _rotated_rest_edges(rest: np.ndarray, q: np.ndarray, edges: np.ndarray, b: np.ndarray) -> None:
    """b (F, A, 3) out: b_i = sum_j (Q_i + Q_j)(r_i - r_j) / 2 over the unique ``edges`` (E, 2)."""
    b[:] = 0.0
    for f in range(q.shape[0]):
        for e in range(edges.shape[0]):
            i, j = edges[e, 0], edges[e, 1]
            for u in range(3):
                t = 0.0
                for v in range(3):
                    t += 0.5 * (q[f, i, u, v] + q[f, j, u, v]) * (rest[i, v] - rest[j, v])
                b[f, i, u] += t
                b[f, j, u] -= t
