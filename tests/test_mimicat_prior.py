"""MimiCAT pose prior F: data, masks across characters of different K, training lowers the NLL."""
from __future__ import annotations

import csv

import numpy as np
import pytest
import torch

from mimicbench.baselines.mimicat import data
from mimicbench.baselines.mimicat.pose_prior import PosePrior, bone_vectors
from mimicbench.geometry.quaternion import quat_to_matrix
from tests.test_mimicat_shape_encoder import tiny_config


def test_prior_example_rotations_are_the_world_bone_rotations(small_zoo):
    """Rigid clips: R_k maps each rest bone (k -> child) onto the posed bone (Eq. 1), independently of our reader."""
    chars = [c for c in data.read_characters(small_zoo, "all") if c.motions]
    checked = 0
    for ch in chars[:4]:
        for mi, clip in enumerate(ch.motions):
            if ch.scales[mi] is not None:
                continue
            ex = data.prior_example(ch, mi, 3, np.random.default_rng(1), points=32)
            np.testing.assert_allclose(ex["rotations"], quat_to_matrix(clip[3, :, :4].astype(np.float64)), atol=1e-6)
            for k, p in enumerate(ch.parents):
                if p < 0:
                    continue
                rest_bone = ex["rest"][k] - ex["rest"][p]
                posed_bone = ex["posed"][k] - ex["posed"][p]
                np.testing.assert_allclose(ex["rotations"][p] @ rest_bone, posed_bone, atol=2e-4)
                checked += 1
    assert checked > 50


def test_bone_vectors_against_a_loop():
    pts = torch.randn(2, 5, 3)
    parents = torch.tensor([[-1, 0, 1, 1, 3], [-1, 0, 0, -1, -1]])
    got = bone_vectors(pts, parents)
    for b in range(2):
        for k in range(5):
            p = int(parents[b, k])
            want = pts[b, k] - pts[b, p] if p >= 0 else torch.zeros(3)
            torch.testing.assert_close(got[b, k], want)


def test_padding_does_not_change_a_characters_output():
    torch.manual_seed(0)
    model = PosePrior(16, 16, 2, 1, 32, 4).eval()
    torch.nn.init.normal_(model.head.weight, std=0.1)  # a non-zero head, so outputs differ per keypoint
    f = torch.randn(2, 2, 4, 16)
    small = (torch.randn(3, 3), torch.randn(3, 3), torch.tensor([-1, 0, 1]))
    big = (torch.randn(6, 3), torch.randn(6, 3), torch.tensor([-1, 0, 1, 2, 0, 4]))
    rest = torch.zeros(2, 6, 3)
    posed = torch.zeros(2, 6, 3)
    parents = torch.full((2, 6), -1)
    mask = torch.zeros(2, 6, dtype=torch.bool)
    for b, (r, p, par) in enumerate((small, big)):
        rest[b, :len(r)], posed[b, :len(r)], parents[b, :len(r)], mask[b, :len(r)] = r, p, par, True
    batched = model(f[0], f[1], rest, posed, parents, mask)
    alone = model(f[0][:1], f[1][:1], small[0][None], small[1][None], small[2][None])
    torch.testing.assert_close(batched[0, :3], alone[0], atol=1e-5, rtol=1e-5)
    # nll: one character, quaternions or matrices, the same number
    q = torch.nn.functional.normalize(torch.randn(3, 4), dim=-1)
    R = torch.as_tensor(quat_to_matrix(q.double().numpy()), dtype=torch.float32)
    a = model.nll(f[0][0], f[1][0], small[0], small[1], small[2].numpy(), q=q)
    b = model.nll(f[0][0], f[1][0], small[0], small[1], small[2], R=R)
    torch.testing.assert_close(a, b, atol=1e-5, rtol=1e-5)
    assert a.ndim == 0 and torch.isfinite(a)


@pytest.mark.slow
def test_prior_stage_lowers_the_nll(small_zoo, tmp_path):
    from mimicbench.training.loop import train_stage

    cfg = tiny_config()
    cfg["data"]["frames_per_motion"] = 2
    train_stage("mimicat", "shape", small_zoo, tmp_path, cfg, epochs=1, seed=0, progress=False)
    train_stage("mimicat", "prior", small_zoo, tmp_path, cfg, epochs=3, seed=0, progress=False)
    with open(tmp_path / "prior" / "loss.csv") as f:
        rows = list(csv.DictReader(f))
    assert {"total", "nll", "sample_dist", "mode_deg"} <= set(rows[0])
    by_epoch = [np.mean([float(r["nll"]) for r in rows if r["epoch"] == str(e)]) for e in range(3)]
    assert float(rows[0]["nll"]) == pytest.approx(0.0, abs=1e-9)  # F starts at 0: the uniform distribution
    assert by_epoch[-1] < by_epoch[0] - 0.5, by_epoch  # a log-likelihood gain over uniform
    dist = [np.mean([float(r["sample_dist"]) for r in rows if r["epoch"] == str(e)]) for e in range(3)]
    assert dist[-1] < dist[0], dist  # samples from F come closer to the true rotations
