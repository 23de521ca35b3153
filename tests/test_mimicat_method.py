"""``mimicat`` and its ablations through the benchmark registry, with the shipped checkpoint."""
from __future__ import annotations

import shutil

import numpy as np
import pytest

from mimicbench.baselines.mimicat.method import BUNDLED, Mimicat
from mimicbench.benchmark.registry import available_methods, get_method
from tests.mimicat_toys import request, tube_rig

STAGES = ("shape", "corr", "transfer", "transfer_no_prior")


@pytest.fixture(scope="module")
def requests():
    rigs = [tube_rig("a", 3), tube_rig("b", 5, 1.4), tube_rig("c", 4, 0.7, branch=False)]
    return [request(rigs[0], rigs[1], 0), request(rigs[1], rigs[2], 1), request(rigs[2], rigs[0], 2)]


def test_shipped_checkpoint_is_small_and_complete():
    total = 0
    for stage in STAGES:
        path = BUNDLED / f"{stage}.safetensors"
        assert path.is_file(), f"missing shipped weights {path}"
        total += path.stat().st_size
    assert total < 8 * 2**20  # a few MB, shipped in the package


def test_registered_names_answer_mixed_batches(requests):
    names = ("mimicat", "mimicat_naive_avg", "mimicat_no_prior", "mimicat_init_only")
    assert set(names) <= set(available_methods())
    outputs = {}
    for name in names:
        method = get_method(name)
        assert method.metadata.name == name and set(method.metadata.protocols) == {"h2h", "cct"}
        method.setup("cpu")
        out = method.transfer(requests)
        for r, v in zip(requests, out):
            assert v.shape == (len(r.target.vertices), 3) and v.dtype == np.float32
            assert np.isfinite(v).all()
        outputs[name] = out
    # A2 (H without L_reg) and H left out are different models: some answer differs from the full model's
    for name in ("mimicat_no_prior", "mimicat_init_only"):
        assert max(np.abs(a - b).max() for a, b in zip(outputs[name], outputs["mimicat"])) > 1e-6
    # A1 with the shipped one-to-one M: Eq. 4's average and the normalised plain sum of one
    # quaternion per column are that quaternion, so the answers are the same by construction
    for a, b in zip(outputs["mimicat_naive_avg"], outputs["mimicat"]):
        np.testing.assert_allclose(a, b, atol=1e-5)


def test_batching_does_not_change_answers(requests):
    method = Mimicat(arap=False, batch_size=1)
    one_by_one = method.transfer(requests)
    together = Mimicat(arap=False, batch_size=16).transfer(requests)
    for a, b in zip(one_by_one, together):
        np.testing.assert_allclose(a, b, atol=1e-4)


def test_checkpoint_option_run_layout_and_errors(tmp_path, requests, monkeypatch):
    run = tmp_path / "run"
    for stage in STAGES:
        (run / stage).mkdir(parents=True)
        shutil.copy(BUNDLED / f"{stage}.safetensors", run / stage / "model.safetensors")
    expected = Mimicat(arap=False).transfer(requests[:1])[0]
    np.testing.assert_allclose(Mimicat(run, arap=False).transfer(requests[:1])[0], expected, atol=1e-6)
    monkeypatch.setenv("MIMICAT_CHECKPOINT", str(run))
    assert Mimicat().checkpoint == run
    with pytest.raises(FileNotFoundError, match="no weights for stage 'shape'"):
        Mimicat(tmp_path / "empty").setup("cpu")


def test_initialisation_of_the_shipped_checkpoint_and_of_init_only(requests):
    """The shipped transfer checkpoint's config says ``transfer.init=structured`` and the method
    reads it so. ``mimicat_init_only`` answers the structured initialisation from G's M of both
    directions decoded as one assignment, H left out: the same vertices as that initialisation
    posed by LBS outside the method."""
    import torch

    from mimicbench.baselines.mimicat.initialisation import structured_pose
    from mimicbench.baselines.mimicat.method import MimicatInitOnly
    from mimicbench.baselines.mimicat.transfer import pose_mesh
    from mimicbench.baselines.mimicat.transfer_data import CharacterTensors
    from mimicbench.baselines.posing import source_pose
    from mimicbench.training.checkpoint import read_header

    assert read_header(BUNDLED / "transfer.safetensors")["config"]["transfer"]["init"] == "structured"
    full = Mimicat(arap=False)
    full.setup("cpu")
    assert full._modules["transfer"].init == "structured" and full.decode == "hungarian_sym"
    only = MimicatInitOnly(arap=False)
    only.setup("cpu")
    assert only._modules["transfer"].init == "structured"
    from mimicbench.baselines.mimicat.transfer import correspondences

    for r, got in zip(requests, only.transfer(requests)):
        s, t = CharacterTensors.of_rig(r.source, only.points), CharacterTensors.of_rig(r.target, only.points)
        m = only._correspondences([r], [s], [t])[0]
        # init_only reads G's M of both directions one to one: 0/1, at most one 1 a row and a column,
        # min(Ks, Kt) pairs, and at least the summed G(s, t) + G(t, s)^T of the greedy one-to-one
        # matching of that sum
        soft = sum(x if k == 0 else x.T for k, x in enumerate(
            correspondences(only._modules["shape"], only._modules["corr"], [a], [b], {}, only.m_temperature)[0]
            for a, b in ((s, t), (t, s))))
        mm = m.numpy()
        assert set(np.unique(mm)) <= {0.0, 1.0}
        assert mm.sum(axis=0).max() <= 1 and mm.sum(axis=1).max() <= 1 and mm.sum() == min(mm.shape)
        left, greedy = soft.numpy().copy(), 0.0
        for _ in range(min(mm.shape)):
            i, j = np.unravel_index(np.argmax(left), left.shape)
            greedy += soft.numpy()[i, j]
            left[i, :], left[:, j] = -np.inf, -np.inf
        assert float((soft.numpy().astype(np.float64) * mm).sum()) >= greedy - 1e-6
        q, p = source_pose(r)
        qb, tb = structured_pose(torch.as_tensor(q), torch.as_tensor(p), s.keypoints, s.parents, t.keypoints,
                                 t.parents, m, r.target.size / r.source.size)
        np.testing.assert_allclose(got, pose_mesh(t, qb, tb).numpy(), atol=2e-5)


def test_the_refinement_moves_only_the_bones_g_leaves_unmatched(requests):
    """``mimicat`` refines H's answer on the target bones that G's decoded M matches to no source
    bone; the matched bones' rotations, read back off the returned mesh by the shared joint fit,
    are those of the same model without the refinement."""
    from mimicbench.baselines.mimicat.transfer_data import CharacterTensors
    from mimicbench.geometry.pose_readoff import read_rig_pose
    from mimicbench.geometry.quaternion import quat_angle

    full = Mimicat()
    full.setup("cpu")
    plain = Mimicat()
    plain.use_range = False
    plain.interpolate = False
    plain.setup("cpu")
    moved_free = 0.0
    for r, a, b in zip(requests, full.transfer(requests), plain.transfer(requests)):
        s, t = CharacterTensors.of_rig(r.source, full.points), CharacterTensors.of_rig(r.target, full.points)
        matched = full._correspondences([r], [s], [t])[0].numpy().sum(axis=0) > 0
        qa, qb = read_rig_pose(r.target, a), read_rig_pose(r.target, b)
        ok = matched & qa.supported & qb.supported
        assert np.degrees(quat_angle(qa.rotations[ok], qb.rotations[ok])).max() < 0.05
        free = ~matched & qa.supported & qb.supported
        if free.any():
            moved_free = max(moved_free, float(np.degrees(quat_angle(qa.rotations[free], qb.rotations[free])).max()))
    assert moved_free > 1.0  # some unmatched bone of these pairs does move
