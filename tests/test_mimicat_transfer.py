"""The initialisation (Eq. 3-4) and the pose-transfer transformer H at toy size."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from mimicbench.baselines.mimicat.initialisation import (forward_kinematics_global, initial_pose, quaternion_average,
                                              structured_pose)
from mimicbench.baselines.mimicat.transfer import PoseTransferTransformer, pose_mesh
from mimicbench.baselines.mimicat.transfer_data import CharacterTensors
from mimicbench.baselines.posing import source_pose
from mimicbench.baselines.text_soft import TextSoft
from mimicbench.geometry.kinematics import forward_kinematics, local_from_global, transforms_to_array
from mimicbench.geometry.quaternion import quat_from_axis_angle
from tests.mimicat_toys import TinyEncoder, bend, posed, request, tube_rig


def _random_m(ks, kt, seed):
    rng = np.random.default_rng(seed)
    m = rng.random((ks, kt)) ** 4
    m[:, -1] = 0  # a target bone no source bone maps to: identity rotation, rigid follow
    return m / m.sum(axis=1, keepdims=True)


def _init_vertices(r, m, average="eq4"):
    q, t = source_pose(r)
    s, g = CharacterTensors.of_rig(r.source, 16), CharacterTensors.of_rig(r.target, 16)
    qb, tb = initial_pose(torch.as_tensor(q), torch.as_tensor(t), s.keypoints, g.keypoints, g.parents,
                          torch.as_tensor(m), r.target.size / r.source.size, average)
    return pose_mesh(g, qb, tb).numpy(), qb, tb, s, g


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_initialisation_equals_text_soft_with_m_sink(seed):
    src, tgt = tube_rig("s", 5, 1.3), tube_rig("t", 4, 0.8)
    m = _random_m(len(src.parents), len(tgt.parents), seed)
    r = request(src, tgt, seed, m)
    expected = TextSoft().transfer([r])[0]
    got, *_ = _init_vertices(r, m)
    np.testing.assert_allclose(got, expected, atol=2e-5)


def test_forward_kinematics_global_matches_the_loop():
    rig = tube_rig("t", 5)
    q = bend(rig, 1.0, 3)[:, :4].astype(np.float64)
    _, expected = forward_kinematics(local_from_global(q, rig.parents), rig.keypoints, rig.parents)
    got = forward_kinematics_global(torch.as_tensor(q), torch.tensor(np.array(rig.keypoints), dtype=torch.float64),
                                    rig.parents)
    np.testing.assert_allclose(got.numpy(), expected, atol=1e-6)


def test_naive_average_by_hand():
    # two rotations about z by 0.2 and 0.6 rad, one stored with the opposite sign, weights 3:1
    q = quat_from_axis_angle(np.array([[0, 0, 1.0], [0, 0, 1.0]]), np.array([0.2, 0.6]))
    q[1] *= -1
    m = np.array([[0.75], [0.25]])
    s = 0.75 * np.array([np.cos(0.1), 0, 0, np.sin(0.1)]) + 0.25 * np.array([np.cos(0.3), 0, 0, np.sin(0.3)])
    got = quaternion_average(torch.as_tensor(q), torch.as_tensor(m), "naive").numpy()[0]
    np.testing.assert_allclose(got, s / np.linalg.norm(s), atol=1e-12)
    eq4 = quaternion_average(torch.as_tensor(q), torch.as_tensor(m), "eq4").numpy()[0]
    assert abs(eq4[3] - got[3]) > 1e-6  # Eq. 4 is not the plain sum
    with pytest.raises(ValueError, match="expected one of"):
        quaternion_average(torch.as_tensor(q), torch.as_tensor(m), "mean")


def _h_inputs(pairs, enc):
    src = [CharacterTensors.of_rig(a.source, 32) for a in pairs]
    tgt = [CharacterTensors.of_rig(a.target, 32) for a in pairs]
    qs, ts, vs, ms = [], [], [], []
    for r in pairs:
        q, t = source_pose(r)
        qs.append(torch.as_tensor(q, dtype=torch.float32))
        ts.append(torch.as_tensor(t, dtype=torch.float32))
        vs.append(torch.as_tensor(np.array(r.source_posed)))
        ms.append(torch.as_tensor(r.extras["m_sink"]))
    f_s = enc(torch.stack([s.normalised(s.vertices) for s in src]))
    f_sp = enc(torch.stack([s.normalised(v) for s, v in zip(src, vs)]))
    f_t = enc(torch.stack([t.normalised(t.vertices) for t in tgt]))
    return src, qs, ts, tgt, ms, f_sp - f_s, f_t


def structured_by_loop(q_src, t_src, src, tgt, m, ratio):
    """The structured initialisation's transforms (Kt, 7) by a loop over target bones, from the
    NumPy rotation average and the h2h ground truth's local translations (a naive reference)."""
    from mimicbench.benchmark.protocols.h2h import local_translations, transforms_from_local
    from mimicbench.geometry.rotation_average import weighted_quaternion_average

    ps, pt = np.asarray(src.parents), np.asarray(tgt.parents)
    local = local_translations(transforms_to_array(q_src, t_src), src.keypoints, ps) * ratio
    roots = [i for i in range(len(ps)) if ps[i] < 0]
    mass = m.sum(axis=0)
    w = np.divide(m, mass, out=np.zeros_like(m), where=mass > 0)
    q, moved = np.zeros((len(pt), 4)), np.zeros((len(pt), 3))
    for j, p in enumerate(pt):  # parents come first
        if mass[j] > 0:
            q[j] = weighted_quaternion_average(q_src, m[:, j:j + 1])[0]
        else:
            q[j] = q[p] if p >= 0 else [1, 0, 0, 0]
        if p < 0:
            on_roots = sum(w[r, j] for r in roots)
            moved[j] = (sum(w[r, j] * local[r] for r in roots) / on_roots) if on_roots > 0 else local[roots[0]]
        else:
            moved[j] = sum(w[i, j] * w[ps[i], p] * local[i] for i in range(len(ps)) if ps[i] >= 0)
    return transforms_from_local(local_from_global(q, pt), moved, tgt.keypoints, pt)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_structured_initialisation_matches_the_loop(seed):
    src, tgt = tube_rig("s", 5, 1.3), tube_rig("t", 4, 0.8)
    m = _random_m(len(src.parents), len(tgt.parents), seed)
    r = request(src, tgt, seed, m)
    q, t = source_pose(r)
    t = t + np.random.default_rng(seed).normal(scale=0.05, size=t.shape)  # bones with local translations too
    ratio = r.target.size / r.source.size
    s, g = CharacterTensors.of_rig(src, 16), CharacterTensors.of_rig(tgt, 16)
    qb, tb = structured_pose(torch.as_tensor(q), torch.as_tensor(t), s.keypoints, s.parents, g.keypoints, g.parents,
                             torch.as_tensor(m), ratio)
    expected = structured_by_loop(q, t, src, tgt, m, ratio)
    np.testing.assert_allclose(np.abs((qb.numpy() * expected[:, :4]).sum(-1)), 1.0, atol=1e-9)
    np.testing.assert_allclose(tb.numpy(), expected[:, 4:], atol=1e-6)


def _rz(deg):
    a = np.radians(deg) / 2
    return np.array([np.cos(a), 0, 0, np.sin(a)])


def test_structured_initialisation_by_hand():
    """A root that walks, a bone with a local translation, an unmatched leaf, size ratio 0.5.

    Source chain 0 (0,0,0) -> 1 (0,1,0) -> 2 (0,2,0). Posed: the root walks by (0.4, 0, 0) and
    turns 90 deg about z; bone 1 turns with it and slides 0.2 along its parent's y beyond its rest
    offset, so t_1 = (0.4,0,0) + Rz90 (0, 1.2, 0) = (-0.8, 0, 0); bone 2 turns -90 deg, t_2 =
    t_1 + Rz90 (0, 1, 0) = (-1.8, 0, 0). Target 0 (0,0,0) -> 1 (0,0.5,0) -> 2 (0,1,0), and a leaf
    3 (0.25,0.5,0) under 1 that nothing maps to. By hand: t_0 = 0.5 (0.4,0,0) = (0.2,0,0);
    t_1 = t_0 + Rz90 (0, 0.5 + 0.5 * 0.2, 0) = (-0.4,0,0); t_2 = t_1 + Rz90 (0,0.5,0) = (-0.9,0,0);
    the leaf takes bone 1's rotation: t_3 = t_1 + Rz90 (0.25,0,0) = (-0.4,0.25,0).
    """
    rest_s = torch.tensor([[0, 0, 0], [0, 1, 0], [0, 2, 0.0]], dtype=torch.float64)
    q_s = torch.as_tensor(np.stack([_rz(90), _rz(90), _rz(-90)]))
    t_s = torch.tensor([[0.4, 0, 0], [-0.8, 0, 0], [-1.8, 0, 0]], dtype=torch.float64)
    rest_t = torch.tensor([[0, 0, 0], [0, 0.5, 0], [0, 1, 0], [0.25, 0.5, 0]], dtype=torch.float64)
    m = torch.zeros(3, 4, dtype=torch.float64)
    m[0, 0] = m[1, 1] = m[2, 2] = 1
    q, t = structured_pose(q_s, t_s, rest_s, np.array([-1, 0, 1]), rest_t, np.array([-1, 0, 1, 1]), m, 0.5)
    np.testing.assert_allclose(t.numpy(), [[0.2, 0, 0], [-0.4, 0, 0], [-0.9, 0, 0], [-0.4, 0.25, 0]], atol=1e-9)
    np.testing.assert_allclose(q.numpy(), np.stack([_rz(90), _rz(90), _rz(-90), _rz(90)]),
                               atol=1e-9)
    # Eq. 3-4 as published instead: the leaf keeps the identity, one shift for the whole skeleton
    q_p, _ = initial_pose(q_s, t_s, rest_s, rest_t, np.array([-1, 0, 1, 1]), m, 0.5)
    np.testing.assert_allclose(q_p[3].numpy(), [1, 0, 0, 0], atol=1e-12)


def test_structured_initialisation_with_one_to_one_matches_is_nearest_joint():
    """A one-hot M of nearest_joint's own Hungarian pairs: the same posed target as nearest_joint
    (which builds it bone by bone in NumPy)."""
    from mimicbench.baselines.nearest_joint import NearestJoint, nearest_joint_pairs

    for k, (src, tgt) in enumerate([(tube_rig("s", 6, 1.3), tube_rig("t", 4, 0.8)),
                                    (tube_rig("s", 3, 1.0), tube_rig("t", 6, 1.6, branch=False))]):
        r = request(src, tgt, k)
        pairs = nearest_joint_pairs(src, tgt)
        m = np.zeros((len(src.parents), len(tgt.parents)))
        m[pairs[:, 0], pairs[:, 1]] = 1
        q, t = source_pose(r)
        s, g = CharacterTensors.of_rig(src, 16), CharacterTensors.of_rig(tgt, 16)
        qb, tb = structured_pose(torch.as_tensor(q), torch.as_tensor(t), s.keypoints, s.parents, g.keypoints,
                                 g.parents, torch.as_tensor(m), r.target.size / r.source.size)
        np.testing.assert_allclose(pose_mesh(g, qb, tb).numpy(), NearestJoint().transfer([r])[0], atol=2e-5)


def test_self_transfer_through_the_structured_initialisation(small_zoo):
    """A zoo character posed by its own clips (root walking, every bone) onto itself with M = I:
    PMD x100 below 1e-3 on every frame tried."""
    from mimicbench.benchmark.metrics import pmd
    from mimicbench.schemas.shards import read_records

    chars = {c.character_id: c for c in read_records(small_zoo, "characters")}
    motions = [mo for mo in read_records(small_zoo, "motions")][:6]
    walked = 0.0
    for mo in motions:
        c = CharacterTensors.of_record(chars[mo.character_id], 16)
        eye = torch.eye(c.num_keypoints, dtype=torch.float64)
        root = int(np.flatnonzero(c.parents < 0)[0])
        for f in (1, mo.num_frames // 2, mo.num_frames - 1):
            pose = torch.as_tensor(np.asarray(mo.transforms[f], np.float64))
            truth = pose_mesh(c, pose[:, :4], pose[:, 4:]).numpy()
            q, t = structured_pose(pose[:, :4], pose[:, 4:], c.keypoints, c.parents, c.keypoints, c.parents, eye, 1.0)
            assert pmd(pose_mesh(c, q, t).numpy(), truth, c.vertices.numpy()) < 1e-3, (mo.motion_id, f)
            walked = max(walked, float((pose[root, 4:] - c.keypoints[root].double()).norm()) / c.size)
    assert walked > 0.05  # some root moved by more than 5% of its character's size


@pytest.mark.parametrize("init", ["paper", "structured"])
def test_untrained_h_returns_the_initialisation_for_a_mixed_batch(init):
    torch.manual_seed(0)
    rigs = [tube_rig("a", 3), tube_rig("b", 5, 1.4), tube_rig("c", 4, 0.7, branch=False)]
    pairs = [request(rigs[0], rigs[1], 0, _random_m(4, 6, 0)), request(rigs[1], rigs[2], 1, _random_m(6, 4, 1)),
             request(rigs[2], rigs[0], 2, _random_m(4, 4, 2))]
    enc, h = TinyEncoder(), PoseTransferTransformer(16, width=16, layers=1, heads=2, mlp_width=32, init=init)
    out = h(*_h_inputs(pairs, enc))
    for r, (q, t) in zip(pairs, out):
        kt = len(r.target.parents)
        assert q.shape == (kt, 4) and t.shape == (kt, 3)
        g = CharacterTensors.of_rig(r.target, 32)
        if init == "paper":
            expected = TextSoft().transfer([r])[0]
        else:
            qs, ts = source_pose(r)
            truth = structured_by_loop(qs, ts, r.source, r.target, r.extras["m_sink"], r.target.size / r.source.size)
            expected = pose_mesh(g, torch.as_tensor(truth[:, :4]), torch.as_tensor(truth[:, 4:])).numpy()
        np.testing.assert_allclose(pose_mesh(g, q, t).detach().numpy(), expected, atol=2e-5)


def test_unknown_initialisation_is_refused():
    with pytest.raises(ValueError, match="structured"):
        PoseTransferTransformer(16, width=16, layers=1, heads=2, mlp_width=32, init="eq3")


def test_training_steps_lower_the_cycle_losses():
    """H alone, G replaced by fixed correspondences: a few AdamW steps on the cycle lower L_rec and L_feat."""
    torch.manual_seed(0)
    a, b = tube_rig("a", 4), tube_rig("b", 6, 1.5, branch=False)
    m_ab = _random_m(5, 6, 4)
    m_ba = _random_m(6, 5, 5)
    enc = TinyEncoder()
    for p in enc.parameters():
        p.requires_grad_(False)
    h = PoseTransferTransformer(16, width=16, layers=1, heads=2, mlp_width=32)
    sa, sb = CharacterTensors.of_rig(a, 32), CharacterTensors.of_rig(b, 32)
    poses = [bend(a, 0.8, s) for s in range(3)]

    def losses():
        rec, feat = [], []
        for pose in poses:
            q, t = torch.as_tensor(pose[:, :4]), torch.as_tensor(pose[:, 4:])
            v = torch.as_tensor(posed(a, pose))
            d_fwd = enc(sa.normalised(v)[None]) - enc(sa.normalised(sa.vertices)[None])
            (qt, tt), = h([sa], [q], [t], [sb], [torch.as_tensor(m_ab)], d_fwd, enc(sb.normalised(sb.vertices)[None]))
            vt = pose_mesh(sb, qt, tt)
            d_back = enc(sb.normalised(vt)[None]) - enc(sb.normalised(sb.vertices)[None])
            (qs, ts), = h([sb], [qt], [tt], [sa], [torch.as_tensor(m_ba)], d_back, enc(sa.normalised(sa.vertices)[None]))
            rec.append((pose_mesh(sa, qs, ts) - v).norm(dim=-1).mean() / sa.size)
            feat.append(((d_back - d_fwd) ** 2).mean())
        return torch.stack(rec).mean(), torch.stack(feat).mean()

    rec0, feat0 = (float(x.detach()) for x in losses())
    opt = torch.optim.AdamW(h.parameters(), lr=2e-3)
    for _ in range(25):
        rec, feat = losses()
        opt.zero_grad()
        (rec + feat).backward()
        opt.step()
    rec1, feat1 = (float(x.detach()) for x in losses())
    assert rec1 < 0.8 * rec0
    assert feat1 < 0.8 * feat0


def test_training_steps_lower_the_prior_term():
    """L_reg: the forward leg's rotations under a frozen pose prior F (a random, non-uniform one),
    lowered by a few AdamW steps on H."""
    from mimicbench.baselines.mimicat.pose_prior import PosePrior

    torch.manual_seed(0)
    enc = TinyEncoder()
    prior = PosePrior(16, width=16, heads=2, layers=1, mlp=32)
    torch.nn.init.normal_(prior.head.weight, std=0.5)
    for p in list(enc.parameters()) + list(prior.parameters()):
        p.requires_grad_(False)
    a, b = tube_rig("a", 4), tube_rig("b", 6, 1.5)
    sa, sb = CharacterTensors.of_rig(a, 32), CharacterTensors.of_rig(b, 32)
    m = torch.as_tensor(_random_m(5, 7, 6))
    h = PoseTransferTransformer(16, width=16, layers=1, heads=2, mlp_width=32)
    poses = [bend(a, 0.8, s) for s in range(3)]

    def reg():
        out = []
        for pose in poses:
            v = torch.as_tensor(posed(a, pose))
            d = enc(sa.normalised(v)[None]) - enc(sa.normalised(sa.vertices)[None])
            f_t = enc(sb.normalised(sb.vertices)[None])
            (q, t), = h([sa], [torch.as_tensor(pose[:, :4])], [torch.as_tensor(pose[:, 4:])], [sb], [m], d, f_t)
            f_p = enc(sb.normalised(pose_mesh(sb, q, t))[None])
            out.append(prior.nll(f_t[0], f_p[0], (sb.keypoints - sb.centre) / sb.size, (t - sb.centre) / sb.size,
                                 sb.parents, q=q))
        return torch.stack(out).mean()

    first = float(reg().detach())
    opt = torch.optim.AdamW(h.parameters(), lr=2e-3)
    for _ in range(20):
        loss = reg()
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert float(reg().detach()) < first - 0.1 * abs(first)


def test_hungarian_decoding_is_the_best_one_to_one_assignment():
    """``transfer.m_decode=hungarian``: a 0/1 matrix whose pairs are the one-to-one assignment of
    largest summed M, found here by trying every injection (both orientations, ties excluded by
    random M); ``soft`` returns M untouched; an unknown decoding is refused."""
    import itertools

    from mimicbench.baselines.mimicat.transfer import decode_correspondence

    rng = np.random.default_rng(3)
    for ks, kt in ((3, 5), (5, 3), (4, 4)):
        m = torch.as_tensor(rng.random((ks, kt)))
        got = decode_correspondence(m, "hungarian").numpy()
        best, best_pairs = -1.0, None
        if ks <= kt:
            for cols in itertools.permutations(range(kt), ks):
                total = sum(float(m[i, c]) for i, c in enumerate(cols))
                if total > best:
                    best, best_pairs = total, [(i, c) for i, c in enumerate(cols)]
        else:
            for rows in itertools.permutations(range(ks), kt):
                total = sum(float(m[r, j]) for j, r in enumerate(rows))
                if total > best:
                    best, best_pairs = total, [(r, j) for j, r in enumerate(rows)]
        expected = np.zeros((ks, kt))
        for i, j in best_pairs:
            expected[i, j] = 1
        np.testing.assert_array_equal(got, expected)
        assert got.dtype == np.float64
        assert decode_correspondence(m, "soft") is m
    with pytest.raises(ValueError, match="m_decode"):
        decode_correspondence(m, "sharp")


def test_symmetric_decoding_is_one_assignment_both_ways():
    """``transfer.m_decode=hungarian_sym``: the one-to-one assignment of largest summed
    ``M(s, t) + M(t, s)^T``, found here by trying every injection, and the reversed pair's decoding
    is its transpose (so a cycle's return leg sends each matched bone back to where it came from);
    ``hungarian`` of the two directions apart can disagree on the same matrices. A missing or
    wrongly shaped reversed M is refused."""
    import itertools

    from mimicbench.baselines.mimicat.transfer import decode_correspondence

    rng = np.random.default_rng(5)
    disagreed = 0
    for ks, kt in ((3, 5), (5, 3), (4, 4)):
        for _ in range(20):
            m, r = torch.as_tensor(rng.random((ks, kt))), torch.as_tensor(rng.random((kt, ks)))
            got = decode_correspondence(m, "hungarian_sym", r).numpy()
            joint = m.numpy() + r.numpy().T
            n = min(ks, kt)
            best = max(sum(joint[i, j] for i, j in (zip(range(ks), p) if ks <= kt else zip(p, range(kt))))
                       for p in itertools.permutations(range(max(ks, kt)), n))
            assert got.sum() == n and got.sum(axis=0).max() <= 1 and got.sum(axis=1).max() <= 1
            assert abs(float((joint * got).sum()) - best) < 1e-9
            np.testing.assert_array_equal(decode_correspondence(r, "hungarian_sym", m).numpy(), got.T)
            apart = decode_correspondence(r, "hungarian").numpy().T != decode_correspondence(m, "hungarian").numpy()
            disagreed += int(apart.any())
    assert disagreed > 0  # the independent decodings are not each other's transposes
    m = torch.as_tensor(rng.random((3, 4)))
    with pytest.raises(ValueError, match="reversed pair"):
        decode_correspondence(m, "hungarian_sym")
    with pytest.raises(ValueError, match="reversed pair"):
        decode_correspondence(m, "hungarian_sym", m)


def test_presets_decode_one_to_one_and_old_configs_stay_soft():
    """The presets' structured initialisation reads G's M of both directions as one one-to-one
    assignment; a config without the key (the checkpoints of methods version 4 and before) keeps
    the soft M it was trained with."""
    from mimicbench.baselines.mimicat.config import preset
    from mimicbench.baselines.mimicat.transfer_training import section

    for name in ("small", "paper"):
        assert section(preset(name), "transfer")["m_decode"] == "hungarian_sym"
    assert section({"transfer": {"init": "structured"}}, "transfer")["m_decode"] == "soft"
