"""The registered MMDMC methods with the shipped checkpoint, on a zoo apparel character."""
from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest
import torch

from mimicbench.benchmark.registry import get_method
from mimicbench.benchmark.request import MotionRequest, Rig
from mimicbench.geometry.quaternion import quat_to_matrix
from mimicbench.schemas.weights import SparseWeights

NAMES = ("mmdmc", "mmdmc_body_only", "mmdmc_no_apparel", "mmdmc_gt_mask")


@pytest.fixture(scope="module")
def character(tmp_path_factory):
    """A zoo apparel character's rig, a 6-frame window of its first clip and its record."""
    from mimicbench.datagen.zoo.dataset import build_zoo
    from mimicbench.schemas.shards import read_records

    root = tmp_path_factory.mktemp("mmdmc_zoo")
    build_zoo(root, 1, seed=11, categories=["apparel"], clips_per_character=1, progress=False)
    rec = read_records(root, "characters")[0]
    motion = read_records(root, "motions")[0]
    rig = Rig(rec.character_id, rec.category, rec.vertices, rec.faces, rec.keypoints, rec.parents, rec.weights,
              rec.bone_names)
    k = len(rec.parents)
    window = np.asarray(motion.transforms, np.float32).reshape(-1, k, 7)[10:16]
    return rig, window, rec


def request(rig, window, rec, extras=None):
    return MotionRequest(rig, window, ~np.asarray(rec.apparel_bone_mask, bool), 30.0, "toy", extras or {})


def naive_lbs(rest, keypoints, dense, transforms):
    """v_i = sum_k W_ik (R_k (v_i - c_k) + t_k), a loop over joints (the spec, MimiCAT Eq. 1)."""
    out = np.zeros((len(transforms), len(rest), 3))
    for f, tr in enumerate(transforms):
        for k in range(len(keypoints)):
            r = quat_to_matrix(tr[k, :4].astype(np.float64))
            out[f] += dense[:, k:k + 1] * ((rest - keypoints[k]) @ r.T + tr[k, 4:])
    return out


def test_methods_are_registered_for_the_apparel_protocol():
    for name in NAMES:
        m = get_method(name)
        assert m.metadata.name == name and m.metadata.protocols == ("apparel",) and m.metadata.needs_training
    assert "reads_gt_apparel_mask" in get_method("mmdmc_gt_mask").metadata.tags
    assert not any("reads_gt_apparel_mask" in get_method(n).metadata.tags for n in NAMES[:3])


def test_shipped_checkpoint_answers_and_body_only_is_lbs_of_its_weights(character):
    from mimicbench.baselines.mmdmc.pipeline import apparel_probability, mesh_weights

    rig, window, rec = character
    outs = {}
    for name in NAMES[:2]:
        m = get_method(name)
        m.setup("cpu")
        [out] = m.transfer_motion([request(rig, window, rec)])
        assert out.shape == (len(window), len(rig.vertices), 3) and out.dtype == np.float32
        assert np.isfinite(out).all()
        outs[name] = (m, out)
    m, body = outs["mmdmc_body_only"]
    prep = next(iter(m._prepared.values()))
    w = mesh_weights(m.modules.body, prep, None, smoothing=m.modules.weight_smoothing,
                     radius=m.modules.weight_smoothing_radius).numpy().astype(np.float64)
    assert np.allclose(w.sum(1), 1.0, atol=1e-5) and (w >= 0).all()
    bones = np.flatnonzero(~np.asarray(rec.apparel_bone_mask, bool))
    ref = naive_lbs(np.asarray(rig.vertices, np.float64), np.asarray(rig.keypoints, np.float64)[bones], w,
                    window[:, bones].astype(np.float64))
    np.testing.assert_allclose(body, ref, atol=2e-4)
    # the apparel path moves only the vertices f_c finds apparel and those whose weights its apparel
    # skinning changed (smoothed across a seam); the rest stays the body's
    m2, apparel = outs["mmdmc"]
    moved = np.abs(apparel - body).max(axis=(0, 2)) > 0
    mods, prep2 = m2.modules, next(iter(m2._prepared.values()))
    mask = apparel_probability(mods.seg, prep2, mods.mask_by_piece) > mods.threshold
    reskinned = np.abs(mesh_weights(mods.body, prep2, mask, mods.apparel_skinning, mods.weight_smoothing,
                                     mods.weight_smoothing_radius).numpy()
                       - mesh_weights(mods.body, prep2, None, smoothing=mods.weight_smoothing,
                                     radius=mods.weight_smoothing_radius).numpy()).max(1) > 0
    assert moved.any() and not moved[~(mask | reskinned)].any()


def test_never_reads_the_targets_weights_or_apparel_mask(character):
    rig, window, rec = character
    rng = np.random.default_rng(0)
    scrambled = SparseWeights(rng.integers(0, len(rig.parents), rig.weights.indices.shape).astype(np.int32),
                              np.asarray(rig.weights.values)[rng.permutation(len(rig.vertices))], len(rig.parents))
    other = dataclasses.replace(rig, weights=scrambled)
    m = get_method("mmdmc")
    [a] = m.transfer_motion([request(rig, window, rec)])
    m2 = get_method("mmdmc")  # a fresh instance: nothing cached from the first rig
    [b] = m2.transfer_motion([request(other, window, rec)])
    np.testing.assert_array_equal(a, b)


def test_gt_mask_variant_uses_the_mask_it_is_given(character):
    rig, window, rec = character
    m = get_method("mmdmc_gt_mask")
    with pytest.raises(ValueError, match="apparel_vertex_mask"):
        m.transfer_motion([request(rig, window, rec)])
    mask = np.asarray(rec.apparel_vertex_mask, bool)
    [with_gt] = m.transfer_motion([request(rig, window, rec, {"apparel_vertex_mask": mask})])
    [none] = m.transfer_motion([request(rig, window, rec, {"apparel_vertex_mask": np.zeros_like(mask)})])
    assert np.isfinite(with_gt).all() and not np.allclose(with_gt[:, mask], none[:, mask])


def test_no_apparel_is_the_full_model_with_f_d_left_out(character):
    # mmdmc_no_apparel: f_c's mask and f_s's skinning with it (as mmdmc), no displacement from f_d,
    # then f_j; without f_j it is plain LBS of those weights (a loop over joints, the spec)
    from mimicbench.baselines.mmdmc.apparel_history import OUTPUT_SCALE
    from mimicbench.baselines.mmdmc.pipeline import apparel_probability, mesh_weights

    rig, window, rec = character
    m = get_method("mmdmc_no_apparel")
    [out] = m.transfer_motion([request(rig, window, rec)])
    full_method = get_method("mmdmc")
    [full] = full_method.transfer_motion([request(rig, window, rec)])
    mods, prep = m.modules, next(iter(m._prepared.values()))
    mask = apparel_probability(mods.seg, prep, mods.mask_by_piece) > mods.threshold
    assert mask.any()
    moved = np.linalg.norm(full - out, axis=-1).max(axis=0)  # (N,) f_d's effect, through f_j too
    assert moved[~mask].max() < 1e-6 * rec.height  # f_d moves nothing but f_c's mask
    assert moved[mask].max() > 1e-3 * rec.height  # the shipped f_d (version 8) moves the apparel
    # the one f_d is seen through is made plain: a constant offset of OUTPUT_SCALE (unit-height frame)
    # along each vertex's frame bone's X (as it is: not less its still-body answer, not restored)
    pushed = copy.deepcopy(full_method.modules.apparel)
    pushed.still_zero, pushed.arap = False, 0.0
    with torch.no_grad():
        pushed.net[-1].weight.zero_()
        pushed.net[-1].bias[:] = torch.tensor([1.0, 0.0, 0.0])
    full_method.modules = dataclasses.replace(full_method.modules, apparel=pushed)
    [far] = full_method.transfer_motion([request(rig, window, rec)])
    moved = np.linalg.norm(far - out, axis=-1)  # (F, N)
    assert np.median(moved[:, mask]) > OUTPUT_SCALE * rec.height * 0.5
    assert moved[:, ~mask].max() < 1e-6 * rec.height
    w = mesh_weights(mods.body, prep, mask, mods.apparel_skinning, mods.weight_smoothing,
                     mods.weight_smoothing_radius).numpy().astype(np.float64)
    bones = np.flatnonzero(~np.asarray(rec.apparel_bone_mask, bool))
    ref = naive_lbs(np.asarray(rig.vertices, np.float64), np.asarray(rig.keypoints, np.float64)[bones], w,
                    window[:, bones].astype(np.float64))
    np.testing.assert_allclose(out, ref, atol=2e-4)


def test_the_apparel_is_restored_by_soft_arap_as_the_modules_weight_asks(character):
    # f_d's prediction with and without the restoration (baselines/mmdmc/apparel_arap.py): the
    # restored apparel is restore() of the unrestored one in metres (ARAP is the same in any unit and
    # place), nothing else moves, and the apparel's edges come closer to their rest lengths
    from mimicbench.baselines.mmdmc.apparel_arap import edges_among, restore
    from mimicbench.baselines.mmdmc.pipeline import apparel_probability

    rig, window, rec = character
    m = get_method("mmdmc")
    m.transfer_motion([request(rig, window, rec)])  # loads the modules
    mods = m.modules
    outs = {}
    for weight in (0.0, 0.03):
        f_d = copy.deepcopy(mods.apparel)
        f_d.arap = weight
        m.modules = dataclasses.replace(mods, apparel=f_d)
        [outs[weight]] = m.transfer_motion([request(rig, window, rec)])
    prep = next(iter(m._prepared.values()))
    idx = np.flatnonzero(apparel_probability(mods.seg, prep, mods.mask_by_piece) > mods.threshold)
    edges = edges_among(prep.edges, idx)
    rest = np.asarray(rig.vertices, np.float64)[idx]
    expected = restore(outs[0.0][:, idx], rest, edges, 0.03, mods.apparel.arap_iterations)
    np.testing.assert_allclose(outs[0.03][:, idx], expected, atol=1e-5 * rec.height)
    body = np.setdiff1d(np.arange(len(rig.vertices)), idx)
    np.testing.assert_array_equal(outs[0.03][:, body], outs[0.0][:, body])

    def stretch(x):
        ln = np.linalg.norm(x[:, edges[:, 0]] - x[:, edges[:, 1]], axis=-1)
        return np.abs(ln / np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=-1) - 1).mean()

    assert stretch(outs[0.03][:, idx]) < stretch(outs[0.0][:, idx])
