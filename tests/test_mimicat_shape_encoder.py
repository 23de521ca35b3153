"""MimiCAT shape encoder E and the data it trains on (toy sizes)."""
from __future__ import annotations

import csv

import numpy as np
import pytest
import torch
import trimesh

from mimicbench.baselines.mimicat import data
from mimicbench.baselines.mimicat.config import preset
from mimicbench.baselines.mimicat.shape_encoder import ShapeAutoencoder


def tiny_config(**shape):
    cfg = preset("small")
    cfg["lr"] = 3e-3
    cfg["data"].update(split="all", points=64, frames_per_motion=1)
    cfg["shape"].update(tokens=4, width=16, heads=2, layers=1, mlp=32, fourier=4, queries=64, surface_samples=512,
                        batch_size=8)
    cfg["shape"].update(shape)
    cfg["prior"].update(width=16, heads=2, layers=1, mlp=32, fourier=4, max_keypoints=16, batch_size=8)
    return cfg


def test_tokens_shape_and_permutation_invariance():
    torch.manual_seed(0)
    model = ShapeAutoencoder.from_config(tiny_config()).eval()
    pts = torch.rand(3, 50, 3) - 0.5
    tok = model(pts)
    assert tok.shape == (3, 4, 16)
    perm = torch.randperm(50)
    torch.testing.assert_close(model(pts[:, perm]), tok, atol=1e-5, rtol=1e-5)  # a set encoder
    assert model.decode(tok, torch.rand(3, 7, 3)).shape == (3, 7)
    with pytest.raises(ValueError, match=r"\(B, P, 3\)"):
        model(pts[0])


def test_shape_example_distances_against_exact_closest_points(small_zoo):
    chars = data.read_characters(small_zoo, "all")
    ch = next(c for c in chars if c.motions)
    ex = data.shape_example(ch, 0, 5, np.random.default_rng(0), points=128, queries=200, surface_samples=8000)
    assert ex["points"].shape == (128, 3) and ex["queries"].shape == (200, 3) and ex["distances"].shape == (200,)
    posed = ch.normalised(ch.posed_vertices(0, 5))
    tris = posed[ch.faces]                                   # brute force: every query against every triangle
    q = ex["queries"][::4]
    exact = np.array([np.linalg.norm(trimesh.triangles.closest_point(tris, np.repeat(p[None], len(tris), 0)) - p,
                                     axis=1).min() for p in q])
    d = ex["distances"][::4]
    # nearest of the surface samples: never closer than the surface, and within the sample spacing
    assert (d >= exact - 1e-5).all()
    assert np.abs(d - exact).max() < 0.03
    # encoder input: vertices of the posed mesh, in the rest frame (rest mesh spans at most [-0.5, 0.5])
    assert np.isin(ex["points"].round(5), posed.round(5)).all(axis=1).all()
    rest = ch.normalised(ch.vertices)
    np.testing.assert_allclose(np.ptp(rest, axis=0).max(), 1.0, rtol=1e-6)
    np.testing.assert_allclose((rest.max(0) + rest.min(0)) / 2, 0.0, atol=1e-6)
    # deterministic for a generator state
    again = data.shape_example(ch, 0, 5, np.random.default_rng(0), points=128, queries=200, surface_samples=8000)
    assert all(np.array_equal(ex[k], again[k]) for k in ex)


@pytest.mark.slow
def test_shape_stage_lowers_the_loss(small_zoo, tmp_path):
    from mimicbench.training.loop import train_stage

    train_stage("mimicat", "shape", small_zoo, tmp_path, tiny_config(), epochs=4, seed=0, progress=False)
    with open(tmp_path / "shape" / "loss.csv") as f:
        rows = list(csv.DictReader(f))
    by_epoch = [np.mean([float(r["total"]) for r in rows if r["epoch"] == str(e)]) for e in range(4)]
    assert by_epoch[-1] < 0.7 * by_epoch[0], by_epoch
    assert (tmp_path / "shape" / "loss.png").is_file()
