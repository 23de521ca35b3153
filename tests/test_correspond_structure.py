import itertools

import numpy as np
import pytest
import torch

from mimicbench.datagen.correspond.batched import correspondence_batch, feature_penalty, hungarian_pairs
from mimicbench.datagen.correspond.methods import FEATURES, METHODS, get_matcher
from mimicbench.datagen.correspond.roles import role_classes
from mimicbench.datagen.correspond.structure import skeleton_features
from mimicbench.geometry.sinkhorn import sinkhorn_log

# A small humanoid with a tail, facing +Z, left = +X, metres (hand-placed joint heads)
TOY = [  # name, parent, head
    ("hips", -1, (0, 1.0, 0)), ("spine", 0, (0, 1.2, 0)), ("neck", 1, (0, 1.5, 0)), ("head", 2, (0, 1.6, 0)),
    ("jaw", 3, (0, 1.62, 0.05)),
    ("left shoulder", 1, (0.03, 1.45, 0)), ("left upper arm", 5, (0.2, 1.45, 0)), ("left lower arm", 6, (0.45, 1.45, 0)),
    ("left hand", 7, (0.7, 1.45, 0)),
    ("right shoulder", 1, (-0.03, 1.45, 0)), ("right upper arm", 9, (-0.2, 1.45, 0)),
    ("right lower arm", 10, (-0.45, 1.45, 0)), ("right hand", 11, (-0.7, 1.45, 0)),
    ("left upper leg", 0, (0.1, 0.95, 0)), ("left lower leg", 13, (0.1, 0.5, 0)), ("left foot", 14, (0.1, 0.05, 0)),
    ("right upper leg", 0, (-0.1, 0.95, 0)), ("right lower leg", 16, (-0.1, 0.5, 0)),
    ("right foot", 17, (-0.1, 0.05, 0)),
    ("tail 1", 0, (0, 1.0, -0.1)), ("tail 2", 19, (0, 0.95, -0.3)),
]


def toy(order=None):
    order = list(range(len(TOY))) if order is None else list(order)
    where = {old: new for new, old in enumerate(order)}
    names = [TOY[i][0] for i in order]
    parents = [where[TOY[i][1]] if TOY[i][1] >= 0 else -1 for i in order]
    return names, np.array(parents), np.array([TOY[i][2] for i in order], float)


def test_features_of_a_hand_built_skeleton():
    names, parents, kp = toy()
    f = skeleton_features(names, parents, kp)
    i = {n: k for k, n in enumerate(names)}
    assert f.side.tolist() == [0, 0, 0, 0, 0] + [1] * 4 + [-1] * 4 + [1] * 3 + [-1] * 3 + [0, 0]
    # body parts: trunk on the root-head path, neck by name, head and below, tail off the path
    part = {n: "trunk neck head tail".split()[int(np.argmax(f.part[k]))] for n, k in i.items() if f.side[k] == 0}
    assert part == {"hips": "trunk", "spine": "trunk", "neck": "neck", "head": "head", "jaw": "head",
                    "tail 1": "tail", "tail 2": "tail"}
    assert not f.part[i["left hand"]].any()
    # arms attach high (1), legs low (0), whatever the limb bone
    assert f.axial[i["left hand"]] == pytest.approx(1.0) and f.axial[i["right upper arm"]] == pytest.approx(1.0)
    assert f.axial[i["left foot"]] == pytest.approx(0.0)
    # the clavicle runs out from the midline: the arm counts segments from the upper arm
    hop = f.limb_hop * 4
    assert [hop[i[n]] for n in ("left shoulder", "left upper arm", "left lower arm", "left hand")] == [-1, 0, 1, 2]
    assert [hop[i[n]] for n in ("left upper leg", "left lower leg", "left foot")] == [0, 1, 2]
    assert [f.chain_hop[i[n]] * 4 for n in ("hips", "spine", "neck", "head", "jaw", "tail 1", "tail 2")] == [0, 1, 0, 0, 1, 0, 1]
    # along: half hops, half length; the leg's lower leg is half way both ways
    assert f.along[i["left upper leg"]] == 0 and f.along[i["left foot"]] == pytest.approx(1.0)
    assert f.along[i["left lower leg"]] == pytest.approx(0.5)
    # the frame: head along +z, left along +x
    assert f.position[i["head"], 2] > 0 and f.position[i["left hand"], 0] > 0 and f.position[i["right hand"], 0] < 0


def test_features_do_not_depend_on_bone_order_or_facing():
    names, parents, kp = toy()
    ref = skeleton_features(names, parents, kp).matrix()
    order = np.random.default_rng(0).permutation(len(TOY))
    n2, p2, k2 = toy(order)
    got = skeleton_features(n2, p2, k2).matrix()
    seq = FEATURES.index("seq_id")  # an identifier: the same sequences, whatever their numbers
    keep = [c for c in range(ref.shape[1]) if c != seq]
    np.testing.assert_allclose(got[:, keep], ref[order][:, keep], atol=1e-5)
    assert len({(a, b) for a, b in zip(got[:, seq], ref[order, seq])}) == len(set(ref[:, seq]))
    turn = np.array([[-1, 0, 0], [0, 1, 0], [0, 0, -1.0]])  # the same rig facing -Z (left at -X)
    np.testing.assert_allclose(skeleton_features(names, parents, kp @ turn.T * 3.0).matrix(), ref, atol=1e-5)


def test_sides_from_the_rest_pose_only_when_no_name_has_one():
    names, parents, kp = toy()
    plain = [n.replace("left ", "").replace("right ", "") for n in names]
    f = skeleton_features(plain, parents, kp)
    assert f.side[plain.index("hand")] == 1 and f.side[len(plain) - 1] == 0
    kp2 = kp.copy()
    kp2[2, 0] = 0.2  # a neck off the middle in a rig with sided names stays a centre bone
    assert skeleton_features(names, parents, kp2).side[2] == 0


def test_cycles_and_bad_parents_are_rejected():
    with pytest.raises(ValueError, match="cycle"):
        skeleton_features(["a", "b"], [1, 0], np.zeros((2, 3)))
    with pytest.raises(ValueError, match="parents"):
        skeleton_features(["a", "b"], [-1, 5], np.zeros((2, 3)))


def test_feature_penalty_equals_a_naive_loop():
    rng = np.random.default_rng(0)
    fa, fb = rng.normal(size=(2, 5, 4)).astype(np.float32), rng.normal(size=(2, 6, 4)).astype(np.float32)
    w = [0.5, 1.0, 0.0, 2.0]
    got = feature_penalty(torch.from_numpy(fa), torch.from_numpy(fb), w).numpy()
    want = np.array([[[sum(w[f] * (fa[b, i, f] - fb[b, j, f]) ** 2 for f in range(4)) for j in range(6)]
                      for i in range(5)] for b in range(2)])
    np.testing.assert_allclose(got, want, atol=1e-4)


def test_no_match_hungarian_is_the_best_partial_matching():
    rng = np.random.default_rng(3)
    for k1, k2 in [(3, 4), (4, 3), (4, 4)]:
        s = rng.uniform(-0.2, 1.0, size=(k1, k2))
        tau = 0.45
        pairs = hungarian_pairs(s, tau)
        assert (s[pairs[:, 0], pairs[:, 1]] > tau).all()
        best = 0.0  # brute force over every partial one-to-one matching
        for r in range(0, min(k1, k2) + 1):
            for rows in itertools.combinations(range(k1), r):
                for cols in itertools.permutations(range(k2), r):
                    best = max(best, sum(s[i, j] - tau for i, j in zip(rows, cols)))
        assert np.isclose(sum(s[i, j] - tau for i, j in pairs), best)


def test_dustbin_sinkhorn_matches_the_core_solver_on_the_augmented_problem():
    rng = np.random.default_rng(1)
    for k1, k2 in [(5, 7), (7, 5), (6, 6)]:
        e1, e2 = rng.normal(size=(k1, 8)), rng.normal(size=(k2, 8))
        e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
        e2 /= np.linalg.norm(e2, axis=1, keepdims=True)
        fa, fb = rng.normal(size=(k1, 3)).astype(np.float32), rng.normal(size=(k2, 3)).astype(np.float32)
        (s, h, m), = correspondence_batch([e1.astype(np.float32)], [e2.astype(np.float32)], 0.1, feat_a=[fa],
                                          feat_b=[fb], feature_weights=[0.1, 0.2, 0.3], no_match=0.2)
        score = s - (0.1 * (fa[:, None, 0] - fb[None, :, 0]) ** 2 + 0.2 * (fa[:, None, 1] - fb[None, :, 1]) ** 2
                     + 0.3 * (fa[:, None, 2] - fb[None, :, 2]) ** 2)
        aug = np.full((k1 + 1, k2 + 1), 0.2)
        aug[:k1, :k2] = score
        rows = np.r_[np.ones(k1), max(k1, k2)]
        cols = np.r_[np.full(k2, max(1.0, k1 / k2)), k1]
        ref = sinkhorn_log(aug, 0.1, rows, cols, num_iters=20000, tol=1e-10)[:k1, :k2]
        np.testing.assert_allclose(m, ref, atol=2e-4)
        assert (m.sum(1) <= 1 + 1e-4).all() and (m.sum(0) <= max(1.0, k1 / k2) + 1e-4).all()
        np.testing.assert_array_equal(h, hungarian_pairs(score, 0.2))


def test_methods_by_name_and_their_record():
    assert get_matcher("text") == METHODS["text"] and not METHODS["text"].uses_structure
    s = get_matcher("structure", no_match=0.3, temperature=0.2)
    assert s.no_match == pytest.approx(0.3) and s.temperature == pytest.approx(0.2) and len(s.feature_weights()) == len(FEATURES)
    assert '"no_match": 0.3' in s.params_json() and '"name": "structure"' in s.params_json()
    with pytest.raises(ValueError, match="unknown matching method .structur.. Did you mean .structure."):
        get_matcher("structur")
    with pytest.raises(ValueError, match="text method"):
        get_matcher("text", no_match=0.4)


def test_role_map_classes():
    assert role_classes(["left/upper_arm", "left/index/2", "right/thigh", "spine/2", "neck", "apparel/skirt/1/2"],
                        "apparel") == ["left/forelimb", "left/forelimb", "right/hindlimb", "spine", "neck", "apparel"]
    assert role_classes(["left/front_leg/1", "right/hind_leg/3", "tail/2", "jaw", "left/ear"], "quadruped") == [
        "left/forelimb", "right/hindlimb", "tail", "jaw", "left/ear"]
    assert role_classes(["left/wing/2", "left/leg/1", "beak"], "bird") == ["left/forelimb", "left/hindlimb", "jaw"]
    assert role_classes(["left/fin", "right/pelvic_fin", "tail_fin", "dorsal_fin"], "fish") == [
        "left/forelimb", "right/hindlimb", "tail", "dorsal"]
    spider = ["thorax", "left/fang"] + [f"left/leg/{i}/1" for i in (1, 2, 3, 4)] + ["abdomen/1"]
    assert role_classes(spider, "insect") == ["root", "left/jaw", "left/forelimb", "left/midlimb", "left/midlimb",
                                              "left/hindlimb", "tail"]
    with pytest.raises(ValueError, match="role map"):
        role_classes(["left/antler"], "quadruped")


def test_monotone_pairs_is_the_best_order_preserving_matching():
    from mimicbench.datagen.correspond.batched import monotone_pairs

    rng = np.random.default_rng(5)
    for n, m in [(1, 1), (3, 4), (4, 3), (5, 5), (2, 6)]:
        gain = rng.uniform(-0.5, 1.0, size=(n, m))
        got = monotone_pairs(gain)
        assert all(i2 > i1 and j2 > j1 for (i1, j1), (i2, j2) in zip(got, got[1:]))
        assert all(gain[i, j] > 0 for i, j in got)
        best = 0.0  # brute force: every increasing choice of rows and of columns
        for r in range(0, min(n, m) + 1):
            for rows in itertools.combinations(range(n), r):
                for cols in itertools.combinations(range(m), r):
                    best = max(best, sum(max(gain[i, j], 0) for i, j in zip(rows, cols)))
        assert np.isclose(sum(gain[i, j] for i, j in got), best)


def test_chain_scores_equal_a_naive_loop():
    from mimicbench.datagen.correspond.batched import chain_scores

    rng = np.random.default_rng(2)
    k1, k2 = 6, 7
    fa = np.zeros((1, k1, 6), np.float32)
    fb = np.zeros((1, k2, 6), np.float32)
    for f, k in ((fa, k1), (fb, k2)):  # columns -4..-1: seq id, seq pos, chain code, name code
        f[0, :, -4] = rng.choice([-1, 0, 0, 3], size=k)
        f[0, :, -3] = rng.uniform(0, 1, size=k)
        f[0, :, -2] = rng.choice([1, 4, 7], size=k)
        f[0, :, -1] = rng.choice([10, 11, 12, 13], size=k)
    s = rng.uniform(-0.2, 1.0, size=(1, k1, k2)).astype(np.float32)
    got = chain_scores(torch.from_numpy(s), torch.from_numpy(fa), torch.from_numpy(fb), 1.0, 0.55, 0.7).numpy()
    trunks = (fa[0, :, -4] == 0).sum() >= 3 and (fb[0, :, -4] == 0).sum() >= 3
    for i in range(k1):
        for j in range(k2):
            want = s[0, i, j]
            if trunks and fa[0, i, -4] == 0 and fb[0, j, -4] == 0:
                want = max(want, 0.7 - abs(fa[0, i, -3] - fb[0, j, -3]))
            if fa[0, i, -2] != fb[0, j, -2]:
                want -= 1.0
            if fa[0, i, -1] == fb[0, j, -1]:
                want = max(want, 0.55)
            assert got[0, i, j] == pytest.approx(want, abs=1e-6)


def test_name_keys_and_chain_kinds_of_a_hand_built_skeleton():
    from mimicbench.datagen.correspond.structure import CHAIN_KINDS, name_keys

    keys = name_keys(["hips", "pelvis", "body", "chest", "upper spine", "left foot", "right foot", "spine"])
    assert keys[0] == keys[1] == keys[2] and keys[3] == keys[4] and len(set(keys[[0, 3, 5, 6, 7]])) == 5
    names, parents, kp = toy()
    f = skeleton_features(names, parents, kp)
    kind = {n: (CHAIN_KINDS[int(c) // 3], int(c) % 3 - 1) for n, c in zip(names, f.chain)}
    assert kind["spine"] == kind["neck"] == ("trunk", 0) and kind["jaw"] == ("head", 0)
    assert kind["tail 2"] == ("tail", 0)
    assert kind["left hand"] == ("fore", 1) and kind["right shoulder"] == ("fore", -1)
    assert kind["left foot"] == ("hind", 1) and kind["right upper leg"] == ("hind", -1)
    # sequences: the trunk from the pelvis (hips) by arc length, each limb's path in order
    i = {n: k for k, n in enumerate(names)}
    assert f.seq_id[i["hips"]] == f.seq_id[i["spine"]] == 0 and f.seq_id[i["neck"]] == -1
    assert f.seq_pos[i["hips"]] == 0 and 0 < f.seq_pos[i["spine"]] < 1
    arm = [f.seq_pos[i[n]] for n in ("left shoulder", "left upper arm", "left lower arm", "left hand")]
    assert len({f.seq_id[i[n]] for n in ("left shoulder", "left hand")}) == 1 and arm == sorted(arm)


def test_a_detached_ik_foot_joins_its_leg():
    """An IK foot kept as a root of its own (a Quaternius mech's): it continues the leg it sits at,
    or becomes the sibling of the bone whose head it shares; without keypoints, the main root's child."""
    from mimicbench.datagen.correspond.structure import _attach_detached

    names, parents, kp = toy()
    names = names + ["left ik foot", "right ik foot"]
    parents = np.r_[parents, -1, -1]
    kp = np.vstack([kp, [0.1, 0.0, 0.05], kp[names.index("right foot")]])
    main = np.r_[np.ones(len(TOY), bool), False, False]
    out = _attach_detached(parents, main, kp)
    assert names[out[-2]] == "left foot"  # nearest head
    assert names[out[-1]] == "right lower leg"  # at the right foot's head: the foot's sibling
    assert (_attach_detached(parents, main, None)[-2:] == 0).all()
    f = skeleton_features(names, parents, kp)
    assert f.side[-2] == 1 and f.limb_hop[-2] > f.limb_hop[names.index("left foot")]


def test_same_named_bones_left_free_are_paired():
    from mimicbench.datagen.correspond.batched import same_name_pairs

    s = np.array([[0.9, 0.1, 0.2], [0.1, 0.1, 0.3], [0.2, 0.3, 0.1]])
    pairs = np.array([[0, 0]], np.int32)
    got = same_name_pairs(s, pairs, np.array([1.0, 2.0, 2.0]), np.array([1.0, 2.0, 5.0]))
    assert got.tolist() == [[0, 0], [2, 1]]  # bone 2 scores 0.3 against target 1, bone 1 only 0.1
