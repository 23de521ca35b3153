"""Soft as-rigid-as-possible restoration of f_d's apparel (ours; config ``history_arap``, methods
version 9): the predicted vertices pull the apparel where f_d put it, ARAP keeps its edges' lengths.

The body-history f_d (:mod:`baselines.mmdmc.apparel_history`) predicts each vertex's offset on its
own. Where the simulated strand could swing one way or the other, the best per-vertex guess is the
mean of the two, which lies inside the arc: the strand comes out short, and ELS counts every edge
that shrank. Trained to keep lengths (``w_stretch`` 1.0) f_d gives up most of its offset (version 8,
-11% PMD_a); trained for positions (``w_stretch`` 0.1) it removes 29% of PMD_a but costs 0.0115 ELS.

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

Measurements behind the default weight: README, "Issue 33, round 7".
"""
from __future__ import annotations

import numpy as np

ITERATIONS = 8
"""Default local-global iterations (from the prediction; the energy falls every iteration)."""


def edges_among(edges: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """(E', 2) int64 the mesh edges (E, 2) whose two ends are both among the sorted vertices ``idx``,
    as indices into ``idx``."""
    both = np.isin(edges, idx).all(1)
    return np.searchsorted(idx, edges[both]).astype(np.int64)


def laplacian(edges: np.ndarray, count: int):
    """(count, count) scipy CSR graph Laplacian of the undirected ``edges`` (E, 2) (each unique edge
    counted once, self-loops and repeats dropped): degree on the diagonal, -1 per neighbour."""
    from scipy.sparse import coo_matrix, diags

    e = unique_edges(edges)
    adj = coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])),
                     shape=(count, count)).tocsr()
    return (diags(np.asarray(adj.sum(1)).ravel()) - adj).tocsr()


def unique_edges(edges: np.ndarray) -> np.ndarray:
    """(E', 2) int64 the undirected edges of (E, 2), each once as (low, high), without self-loops."""
    e = np.sort(np.asarray(edges, np.int64).reshape(-1, 2), axis=1)
    return np.unique(e[e[:, 0] != e[:, 1]], axis=0)


def fit_rotations(rest: np.ndarray, posed: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(F, A, 3, 3) each vertex's best rotation Q_i taking its rest edges to its posed ones: the
    rotation nearest (polar factor, det +1) to sum_j (x_i - x_j)(r_i - r_j)^T over its neighbours j.

    Args:
        rest: (A, 3) rest positions; posed: (F, A, 3); edges: (E', 2) unique undirected edges.
    """
    i, j = np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]]
    dr = rest[i] - rest[j]                                  # (2E', 3)
    dx = posed[:, i] - posed[:, j]                          # (F, 2E', 3)
    cov = _sum_at(i, dx[..., :, None] * dr[None, :, None, :], posed.shape[1])  # (F, A, 3, 3)
    u, _, vt = np.linalg.svd(cov)
    d = np.sign(np.linalg.det(u @ vt))
    d[d == 0] = 1.0
    u[..., :, 2] *= d[..., None]
    return u @ vt


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
    r = np.asarray(rest, np.float64)
    if p.ndim != 3 or p.shape[2] != 3 or r.shape != p.shape[1:]:
        raise ValueError(f"restore: expected predicted (F, A, 3) and rest (A, 3), got {p.shape} and {r.shape}")
    if not weight > 0:
        raise ValueError(f"restore: weight: expected > 0, got {weight}")
    e = unique_edges(edges)
    if iterations <= 0 or len(e) == 0:
        return p.copy()
    if e.max() >= len(r):
        raise ValueError(f"restore: an edge names vertex {int(e.max())}, expected < {len(r)}")
    f, a = p.shape[:2]
    solve = factorized((laplacian(e, a) + weight * identity(a)).tocsc())
    i, j = np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]]
    dr = r[i] - r[j]                                        # (2E', 3)
    x = p
    for _ in range(iterations):
        q = fit_rotations(r, x, e)                          # (F, A, 3, 3)
        half = 0.5 * ((q[:, i] + q[:, j]) @ dr[None, :, :, None])[..., 0]  # (F, 2E', 3)
        b = _sum_at(i, half, a)
        rhs = (b + weight * p).transpose(1, 0, 2).reshape(a, 3 * f)
        x = solve(rhs).reshape(a, f, 3).transpose(1, 0, 2)
    return x


def _sum_at(index: np.ndarray, values: np.ndarray, count: int) -> np.ndarray:
    """(F, count, ...) the sums of ``values`` (F, M, ...) over their rows' ``index`` (M,) in 0..count-1
    (a sparse product: ``np.add.at`` is slow on many frames)."""
    from scipy.sparse import csr_matrix

    f, m = values.shape[:2]
    gather = csr_matrix((np.ones(m), (index, np.arange(m))), shape=(count, m))
    flat = values.transpose(1, 0, *range(2, values.ndim)).reshape(m, -1)
    out = np.asarray(gather @ flat).reshape((count, f) + values.shape[2:])
    return out.transpose(1, 0, *range(2, values.ndim))
