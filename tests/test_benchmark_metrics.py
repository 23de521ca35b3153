import numpy as np
import pytest
import torch

from mimicbench.benchmark.metrics import els, pmd, pmd_aligned, pmd_squared
from mimicbench.benchmark.metrics_torch import els_torch, pmd_aligned_torch, pmd_squared_torch, pmd_torch
from mimicbench.benchmark.normalisation import RestFrame, largest_extent, size_ratio
from mimicbench.benchmark.scoring import score_pose
from mimicbench.geometry.mesh import unique_edges

# a rest mesh whose bounding box is 4 m along x, 2 m tall (y) and 1 m deep (z)
REST = np.array([[0, 0, 0], [4, 0, 0], [0, 2, 0], [0, 0, 1.0]])
FACES = np.array([[0, 1, 2], [0, 3, 1]])


def test_rest_frame_by_hand():
    f = RestFrame.of(REST, unique_edges(FACES))
    np.testing.assert_allclose(f.centre, [2, 1, 0.5])
    assert f.height == pytest.approx(2.0) and f.extent == pytest.approx(4.0)
    assert f.scale("height") == pytest.approx(2.0) and f.scale("extent") == pytest.approx(4.0)
    np.testing.assert_allclose(f.normalise([[2, 1, 0.5], [4, 2, 0.5]], "extent"), [[0, 0, 0], [0.5, 0.25, 0]])
    assert largest_extent(REST) == pytest.approx(4.0) and size_ratio(REST, REST * 1.5) == pytest.approx(1.5)
    with pytest.raises(ValueError, match="height or extent|one of height, extent"):
        f.scale("width")
    with pytest.raises(ValueError, match="positive Y extent"):
        RestFrame.of(REST * [1, 0, 1])


def test_three_normalisations_by_hand():
    moved = REST.copy()
    moved[1] += [0.4, 0, 0]  # one of four vertices moves 0.4 m
    # mean distance 0.1 m: 0.1 / 2 m height = 5%; 0.1 / 4 m extent = 2.5%
    assert np.isclose(pmd(moved, REST, REST, "height"), 5.0)
    assert np.isclose(pmd(moved, REST, REST, "extent"), 2.5)
    # aligned: the prediction's centroid moved by 0.1 m along x, so after centring the four
    # vertices are off by 0.1, 0.3, 0.1, 0.1 m: mean 0.15 m = 7.5% of height, 3.75% of extent
    assert np.isclose(pmd_aligned(moved, REST, REST, "height"), 7.5)
    assert np.isclose(pmd_aligned(moved, REST, REST, "extent"), 3.75)
    # squared: (0.4 / 4)^2 / 4 vertices = 0.0025 -> 0.25
    assert np.isclose(pmd_squared(moved, REST, REST, "extent"), 0.25)

    shifted = REST + [1.0, 1.0, 0.0]  # a pure translation of sqrt(2) m
    assert np.isclose(pmd(shifted, REST, REST, "height"), 100 * np.sqrt(2) / 2)
    assert np.isclose(pmd(shifted, REST, REST, "extent"), 100 * np.sqrt(2) / 4)
    assert np.isclose(pmd_aligned(shifted, REST, REST, "height"), 0.0, atol=1e-12)
    # translation plus the moved vertex: aligned PMD sees only the articulation
    assert np.isclose(pmd_aligned(moved + [1.0, 1.0, 0.0], REST, REST, "height"), 7.5)

    frame = RestFrame.of(REST, unique_edges(FACES))
    for headline, main in (("height", 5.0), ("extent", 2.5)):
        s = score_pose(moved, REST, frame, headline)
        assert np.isclose(s["pmd"], main) and np.isclose(s["pmd_height"], 5.0) and np.isclose(s["pmd_extent"], 2.5)
        assert np.isclose(s["pmd_aligned"], 7.5 if headline == "height" else 3.75)
        assert np.isclose(s["els"], els(moved, REST, frame.edges))


def test_els_by_hand():
    rest = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 1.0]])
    edges = unique_edges(FACES)  # (0,1) (0,2) (0,3) (1,2) (1,3)
    pred = rest.copy()
    pred[1] += [0.2, 0, 0]
    # (0,1) 1 -> 1.2; (1,2) sqrt5 -> sqrt(1.44+4); (1,3) sqrt2 -> sqrt(1.44+1)
    errs = [0.2, 0, 0, np.sqrt(5.44) / np.sqrt(5) - 1, np.sqrt(2.44) / np.sqrt(2) - 1]
    assert np.isclose(els(pred, rest, edges), 1 - np.mean(np.abs(errs)))


def test_els_leaves_out_a_zero_length_reference_edge_and_counts_a_near_zero_one_in_full():
    """A zero-length edge has no ratio and is left out of the mean (numpy and torch alike); an edge
    of 1e-9 m is an ordinary edge, so moving one end by 1e-6 m scores it |1e-6 / 1e-9 - 1| = 999
    (why resample welds such edges away rather than the metric guarding them)."""
    rest = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 1.0]])
    edges = unique_edges(FACES)  # (0,1) (0,2) (0,3) (1,2) (1,3)
    pred = rest.copy()
    pred[1] += [0.2, 0, 0]
    errs = [0.2, 0, 0, np.sqrt(5.44) / np.sqrt(5) - 1, np.sqrt(2.44) / np.sqrt(2) - 1]
    zero_rest, zero_pred = np.vstack([rest, rest[2]]), np.vstack([pred, pred[2] + [0, 0, 0.1]])
    with_zero = np.vstack([edges, [2, 4]])  # vertex 4 sits on vertex 2 at rest
    assert np.isclose(els(zero_pred, zero_rest, with_zero), 1 - np.mean(np.abs(errs)))
    t = lambda a: torch.tensor(a)  # noqa: E731
    assert np.isclose(float(els_torch(t(zero_pred[None]), t(zero_rest[None]), t(with_zero))[0]),
                      1 - np.mean(np.abs(errs)))
    near_rest = np.vstack([rest, rest[2] + [1e-9, 0, 0]])
    near_pred = np.vstack([pred, pred[2] + [1e-6, 0, 0]])
    one_ratio = abs(1e-6 / 1e-9 - 1)  # 999, up to the rounding of 2 + 1e-9
    assert np.isclose(els(near_pred, near_rest, with_zero), 1 - np.mean(np.abs(errs + [one_ratio])), rtol=1e-6)


def test_identity_is_perfect():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(50, 3))
    edges = unique_edges(rng.integers(0, 50, size=(80, 3)))
    for by in ("height", "extent"):
        for metric in (pmd, pmd_squared, pmd_aligned):
            assert metric(v, v, v, by) == pytest.approx(0.0, abs=1e-9), metric.__name__
    assert els(v, v, edges) == pytest.approx(1.0)


@pytest.mark.parametrize("by", ["height", "extent"])
def test_torch_twins_match_numpy_batched(by):
    rng = np.random.default_rng(1)
    rest = rng.normal(size=(4, 60, 3)) * [3.0, 1.0, 0.5]
    pred = rest + 0.05 * rng.normal(size=rest.shape) + 0.2
    ref = rest + 0.05 * rng.normal(size=rest.shape)
    faces = rng.integers(0, 60, size=(100, 3))
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
    edges = unique_edges(faces)
    t = lambda a: torch.tensor(a)  # noqa: E731
    for twin, ref_fn in ((pmd_torch, pmd), (pmd_squared_torch, pmd_squared), (pmd_aligned_torch, pmd_aligned)):
        np.testing.assert_allclose(twin(t(pred), t(ref), t(rest), by).numpy(),
                                   [ref_fn(p, r, s, by) for p, r, s in zip(pred, ref, rest)], rtol=1e-10)
    # one rest mesh (N, 3) shared by the batch
    np.testing.assert_allclose(pmd_torch(t(pred), t(ref), t(rest[0]), by).numpy(),
                               [pmd(p, r, rest[0], by) for p, r in zip(pred, ref)], rtol=1e-10)
    np.testing.assert_allclose(els_torch(t(pred), t(ref), t(edges)).numpy(), [els(p, r, edges) for p, r in zip(pred, ref)])
