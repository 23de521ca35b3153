"""MMDMC's body edge term ``edge_stretch`` (the relative stretch ELS measures) by hand on a tiny mesh,
and the mesh-edge subsample the body stage draws for it."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from mimicbench.baselines.mmdmc.losses import edge_stretch
from mimicbench.baselines.mmdmc.training import _mesh_edge_subsample, body_edge_loss
from mimicbench.geometry.mesh import unique_edges

# two triangles sharing the edge 1-2: a unit square cut along its diagonal
SQUARE = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float64)
FACES = np.array([[0, 1, 2], [1, 3, 2]])
EDGES = torch.as_tensor(unique_edges(FACES))


def test_a_stretched_edge_gives_the_hand_value():
    """Moving vertex 3 from (1,1) to (1,2): edge 1-3 goes 1 -> 2 (stretch 1), edge 2-3 goes 1 -> sqrt(2)
    (stretch sqrt(2)-1), the other three are unchanged; the mean over the 5 edges is (1 + sqrt(2)-1)/5."""
    assert len(EDGES) == 5
    pred = SQUARE.copy()
    pred[3] = [1, 2, 0]
    got = float(edge_stretch(torch.as_tensor(pred), torch.as_tensor(SQUARE), EDGES))
    assert got == pytest.approx(np.sqrt(2) / 5, rel=1e-12)
    # shrinking counts like stretching: |0.5 - 1| on edge 0-1 alone
    shrunk = SQUARE.copy()
    shrunk[1] = [0.5, 0, 0]
    one = torch.as_tensor([[0, 1]])
    assert float(edge_stretch(torch.as_tensor(shrunk), torch.as_tensor(SQUARE), one)) == pytest.approx(0.5)


def test_an_unstretched_posed_mesh_gives_zero():
    """A rotated and translated copy keeps every edge length: no stretch, batched or not."""
    c, s = np.cos(0.7), np.sin(0.7)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    posed = SQUARE @ rot.T + [0.3, -2.0, 5.0]
    assert float(edge_stretch(torch.as_tensor(posed), torch.as_tensor(SQUARE), EDGES)) == pytest.approx(0, abs=1e-12)
    batch = torch.as_tensor(np.stack([posed, SQUARE]))
    assert float(edge_stretch(batch, torch.as_tensor(np.stack([SQUARE, SQUARE])), EDGES)) == pytest.approx(0, abs=1e-12)
    assert float(edge_stretch(torch.as_tensor(posed), torch.as_tensor(SQUARE), EDGES[:0])) == pytest.approx(0.0, abs=1e-12)


def test_a_few_steps_lower_the_stretch():
    """Gradient steps on the vertex positions of a stretched mesh bring its stretch down."""
    pred = torch.as_tensor(SQUARE * [1.3, 0.8, 1.0] + np.random.default_rng(0).normal(0, 0.05, SQUARE.shape),
                           dtype=torch.float32).requires_grad_(True)
    truth = torch.as_tensor(SQUARE, dtype=torch.float32)
    opt = torch.optim.Adam([pred], lr=1e-2)
    first = float(edge_stretch(pred, truth, EDGES).detach())
    for _ in range(30):
        loss = edge_stretch(pred, truth, EDGES)
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert float(edge_stretch(pred, truth, EDGES).detach()) < 0.5 * first


def test_mesh_edge_subsample_keeps_real_mesh_edges():
    """The subsample holds both ends of each drawn edge; mapped back, every drawn pair is a mesh edge;
    the subsample is topped up to ``points`` distinct vertices."""
    rng = np.random.default_rng(3)
    # a 12 x 12 grid of vertices, two triangles a cell
    n = 12
    idx = np.arange(n * n).reshape(n, n)
    faces = np.concatenate([np.stack([idx[:-1, :-1], idx[1:, :-1], idx[:-1, 1:]], -1).reshape(-1, 3),
                            np.stack([idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], -1).reshape(-1, 3)])
    edges = unique_edges(faces)
    mesh = {tuple(sorted(e)) for e in edges.tolist()}
    rows, pairs = _mesh_edge_subsample(n * n, edges, 40, rng)
    assert len(rows) == 40 and len(np.unique(rows)) == 40 and np.all(np.diff(rows) > 0)
    assert pairs.shape == (20, 2) and pairs.min() >= 0 and pairs.max() < 40
    assert all(tuple(sorted((rows[a], rows[b]))) in mesh for a, b in pairs)
    assert len({tuple(sorted((rows[a], rows[b]))) for a, b in pairs}) == 20  # drawn without replacement


def test_body_edge_loss_option_is_off_by_default_and_checked():
    assert body_edge_loss({}) == "knn"
    assert body_edge_loss({"body_edge_loss": "mesh_stretch"}) == "mesh_stretch"
    with pytest.raises(ValueError, match="body_edge_loss: expected one of"):
        body_edge_loss({"body_edge_loss": "mesh"})
