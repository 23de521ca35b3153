import itertools

import numpy as np
import pytest
import torch

from datagen.correspond.batched import correspondence_batch, feature_penalty, hungarian_pairs
from datagen.correspond.methods import FEATURES, METHODS, get_method
from datagen.correspond.roles import role_classes
from datagen.correspond.structure import skeleton_features
from mimicbench.sinkhorn import sinkhorn_log

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
    assert get_method("text") == METHODS["text"] and not METHODS["text"].uses_structure
    s = get_method("structure", no_match=0.3, temperature=0.2)
    assert s.no_match == 0.3 and s.temperature == 0.2 and len(s.feature_weights()) == len(FEATURES)
    assert '"no_match": 0.3' in s.params_json() and '"name": "structure"' in s.params_json()
    with pytest.raises(ValueError, match="expected one of"):
        get_method("structur")
    with pytest.raises(ValueError, match="text method"):
        get_method("text", no_match=0.4)


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
