"""Soft ARAP restoration of f_d's apparel (baselines/mmdmc/apparel_arap.py), against hand-computed
values, scipy's rotation fit and a naive loop over the energy the module docstring states."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mimicbench.baselines.mmdmc.apparel_arap import edges_among, fit_rotations, laplacian, nearest_rotations, restore


def _strip(n: int = 11, length: float = 1.0, width: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """A straight triangle strip along X: vertices (2n, 3) and its mesh edges (E, 2) (repeats kept,
    as faces give them)."""
    xs = np.linspace(0.0, length, n)
    v = np.concatenate([np.stack([xs, np.zeros(n), np.zeros(n)], 1), np.stack([xs, np.full(n, width), np.zeros(n)], 1)])
    faces = np.array([f for i in range(n - 1) for f in ([i, i + 1, n + i], [i + 1, n + i + 1, n + i])])
    return v, np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])


def unique_edges(edges: np.ndarray) -> np.ndarray:
    """(E', 2) each undirected edge once, as (low, high)."""
    return np.unique(np.sort(edges, axis=1), axis=0)


def _lengths(x: np.ndarray, edges: np.ndarray) -> np.ndarray:
    return np.linalg.norm(x[..., edges[:, 0], :] - x[..., edges[:, 1], :], axis=-1)


def _energy(x: np.ndarray, rest: np.ndarray, edges: np.ndarray, pred: np.ndarray, weight: float) -> float:
    """The docstring's E(X) of one frame by a naive loop, each vertex's rotation fitted by scipy's
    Kabsch (``Rotation.align_vectors``), the minimiser over rotations of the edge term."""
    e = unique_edges(edges)
    total = 2 * weight * float(((x - pred) ** 2).sum())
    for i in range(len(x)):
        nbrs = [b for a, b in e if a == i] + [a for a, b in e if b == i]
        if not nbrs:
            continue
        dx = np.array([x[i] - x[j] for j in nbrs])
        dr = np.array([rest[i] - rest[j] for j in nbrs])
        q = Rotation.align_vectors(dx, dr)[0].as_matrix() if len(nbrs) > 1 else _turn(dr[0], dx[0])
        total += float(((dx - dr @ q.T) ** 2).sum())
    return total


def _turn(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A rotation taking direction a to direction b (one edge fixes no more than that)."""
    return Rotation.align_vectors(b[None], a[None])[0].as_matrix()


def test_laplacian_of_a_triangle_with_a_tail_by_hand():
    lap = laplacian(np.array([[0, 1], [1, 2], [2, 0], [2, 3], [3, 2], [1, 1]]), 5).toarray()
    expected = np.array([[2, -1, -1, 0, 0], [-1, 2, -1, 0, 0], [-1, -1, 3, -1, 0], [0, 0, -1, 1, 0], [0, 0, 0, 0, 0]])
    np.testing.assert_array_equal(lap, expected)


def test_edges_among_keeps_the_edges_inside_and_renumbers_them():
    edges = np.array([[0, 5], [5, 7], [7, 2], [9, 5]])
    np.testing.assert_array_equal(edges_among(edges, np.array([2, 5, 7, 9])), [[1, 2], [2, 0], [3, 1]])


def test_fitted_rotations_match_scipys_kabsch():
    rng = np.random.default_rng(3)
    rest, edges = _strip(6)
    posed = rest @ Rotation.random(random_state=4).as_matrix().T + rng.normal(0, 0.01, rest.shape)
    q = fit_rotations(rest, posed[None], edges)[0]
    np.testing.assert_allclose(np.linalg.det(q), 1.0, atol=1e-9)
    e = unique_edges(edges)
    for i in (0, 3, 7, 11):
        nbrs = [b for a, b in e if a == i] + [a for a, b in e if b == i]
        ref = Rotation.align_vectors(posed[i] - posed[nbrs], rest[i] - rest[nbrs])[0].as_matrix()
        np.testing.assert_allclose(q[i], ref, atol=1e-9)


def test_nearest_rotations_are_the_svds_including_reflections_and_rank_deficient_matrices():
    rng = np.random.default_rng(7)
    m = rng.normal(size=(2000, 3, 3))
    m[:500] = np.eye(3) + 0.2 * rng.normal(size=(500, 3, 3))     # near a rotation (what ARAP sees)
    m[500:510, :, 2] = m[500:510, :, 1]                           # rank 2: collinear-free but flat
    m[510:520] = np.einsum("ni,nj->nij", rng.normal(size=(10, 3)), rng.normal(size=(10, 3)))  # rank 1
    m[520:530] = 0.0
    q = nearest_rotations(m)
    np.testing.assert_allclose(np.einsum("nji,njk->nik", q, q), np.broadcast_to(np.eye(3), q.shape), atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(q), 1.0, atol=1e-9)
    u, _, vt = np.linalg.svd(m[:500])
    np.testing.assert_allclose(q[:500], u @ vt, atol=1e-9)
    # the rotation nearest each matrix: no rotation of a random few is closer (the minimiser of
    # |Q - M|_F over SO(3), by the SVD with the sign of its last column set to make det +1)
    u, _, vt = np.linalg.svd(m[530:])
    u[:, :, 2] *= np.sign(np.linalg.det(u @ vt))[:, None]
    np.testing.assert_allclose(q[530:], u @ vt, atol=1e-8)


def test_a_rigid_motion_of_the_rest_apparel_is_kept_as_it_is():
    rest, edges = _strip()
    turn = Rotation.from_euler("xyz", [30, 40, 50], degrees=True).as_matrix()
    pred = np.stack([rest @ turn.T + 1.0, rest + [0.0, 2.0, 0.0]])
    for weight in (0.01, 1.0):
        np.testing.assert_allclose(restore(pred, rest, edges, weight), pred, atol=1e-9)


def test_a_shrunk_strip_gets_its_lengths_back_and_keeps_its_centroid():
    rest, edges = _strip()
    pred = (rest * [0.7, 1.0, 1.0] + [0.0, 0.0, 0.3])[None]  # the strip at 70% of its length
    was = np.abs(_lengths(pred, edges) / _lengths(rest, edges) - 1).mean()
    out = restore(pred, rest, edges, 0.01, iterations=20)
    stretch = np.abs(_lengths(out, edges) / _lengths(rest, edges) - 1).mean()
    assert was > 0.15 and stretch < 0.02
    # the global step's rows sum to weight * (x - p) = 0 over each component (L's rows sum to 0 and
    # the rotated rest edges cancel in pairs): the centroid is the prediction's
    np.testing.assert_allclose(out.mean(1), pred.mean(1), atol=1e-9)
    # a stronger pull keeps more of the prediction and less of the lengths
    firm = restore(pred, rest, edges, 10.0, iterations=20)
    assert np.abs(firm - pred).max() < np.abs(out - pred).max()
    assert np.abs(_lengths(firm, edges) / _lengths(rest, edges) - 1).mean() > stretch


def test_each_iteration_lowers_the_energy_of_a_naive_loop():
    rng = np.random.default_rng(0)
    rest, edges = _strip(6)
    bent = rest.copy()
    bent[:, 2] = 0.3 * np.sin(2 * rest[:, 0])  # a bend the rest strip does not have
    pred = (bent + rng.normal(0, 0.03, rest.shape))[None]
    energies = [_energy(restore(pred, rest, edges, 0.3, iterations=k)[0], rest, edges, pred[0], 0.3) for k in range(5)]
    assert all(b <= a + 1e-9 for a, b in zip(energies, energies[1:])), energies
    assert energies[-1] < 0.5 * energies[0]


def test_a_vertex_on_no_edge_keeps_its_prediction_and_frames_are_independent():
    rest, edges = _strip(5)
    rest = np.concatenate([rest, [[5.0, 5.0, 5.0]]])  # a loose vertex
    rng = np.random.default_rng(1)
    pred = rest[None] + rng.normal(0, 0.05, (3,) + rest.shape)
    out = restore(pred, rest, edges, 0.2)
    np.testing.assert_allclose(out[:, -1], pred[:, -1], atol=1e-12)
    np.testing.assert_allclose(restore(pred[1:2], rest, edges, 0.2)[0], out[1], atol=1e-12)


def test_the_result_does_not_depend_on_the_length_unit():
    rest, edges = _strip()
    pred = (rest * [0.8, 1.0, 1.0])[None]
    np.testing.assert_allclose(restore(pred * 100, rest * 100, edges, 0.1), 100 * restore(pred, rest, edges, 0.1),
                               rtol=1e-9, atol=1e-9)


def test_bad_arguments_are_refused_with_what_was_expected():
    rest, edges = _strip(3)
    with pytest.raises(ValueError, match="weight"):
        restore(rest[None], rest, edges, 0.0)
    with pytest.raises(ValueError, match=r"\(F, A, 3\)"):
        restore(rest, rest, edges, 0.1)
    with pytest.raises(ValueError, match=r"vertex 9, expected 0\.\.5"):
        restore(rest[None], rest, np.array([[0, 9]]), 0.1)
    with pytest.raises(ValueError, match=r"vertex -1, expected 0\.\.5"):
        restore(rest[None], rest, np.array([[-1, 2]]), 0.1)
