import numpy as np
import torch

from benchmark.metrics import els, pmd, pmd_squared
from benchmark.metrics_torch import els_torch, pmd_squared_torch, pmd_torch
from mimicbench.mesh import unique_edges


def test_hand_built_case():
    # a right triangle plus a far vertex: rest height (Y extent) is 2 m
    rest = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 1.0]])
    faces = np.array([[0, 1, 2], [0, 3, 1]])
    edges = unique_edges(faces)  # (0,1) (0,2) (0,3) (1,2) (1,3)
    pred = rest.copy()
    pred[1] += [0.2, 0, 0]  # vertex 1 moves 0.2 m along x
    # PMD: distances 0, 0.2, 0, 0 m -> 0.1 unit heights / 4 vertices * 100 = 2.5
    assert np.isclose(pmd(pred, rest, rest), 2.5)
    # squared: (0.1)^2 / 4 * 100 = 0.25
    assert np.isclose(pmd_squared(pred, rest, rest), 0.25)
    # edges touching vertex 1: (0,1) 1 -> 1.2 (ratio err 0.2); (1,2) sqrt5 -> sqrt(1.44+4);
    # (1,3) sqrt2 -> sqrt(1.44+1)
    errs = [0.2, 0, 0, np.sqrt(5.44) / np.sqrt(5) - 1, np.sqrt(2.44) / np.sqrt(2) - 1]
    assert np.isclose(els(pred, rest, edges), 1 - np.mean(np.abs(errs)))


def test_identity_is_perfect():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(50, 3))
    edges = unique_edges(rng.integers(0, 50, size=(80, 3)))
    assert pmd(v, v, v) == 0.0 and pmd_squared(v, v, v) == 0.0 and els(v, v, edges) == 1.0


def test_torch_twins_match_numpy_batched():
    rng = np.random.default_rng(1)
    rest = rng.normal(size=(4, 60, 3))
    pred = rest + 0.05 * rng.normal(size=rest.shape)
    ref = rest + 0.05 * rng.normal(size=rest.shape)
    faces = rng.integers(0, 60, size=(100, 3))
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
    edges = unique_edges(faces)
    t = lambda a: torch.tensor(a)  # noqa: E731
    np.testing.assert_allclose(pmd_torch(t(pred), t(ref), t(rest)).numpy(), [pmd(p, r, s) for p, r, s in zip(pred, ref, rest)])
    np.testing.assert_allclose(pmd_squared_torch(t(pred), t(ref), t(rest)).numpy(),
                               [pmd_squared(p, r, s) for p, r, s in zip(pred, ref, rest)])
    np.testing.assert_allclose(els_torch(t(pred), t(ref), t(edges)).numpy(), [els(p, r, edges) for p, r in zip(pred, ref)])
