"""The correspondence transformer G at toy size: batches of characters of different K, a doubly
stochastic M, masks that make a pair's answer independent of its batch, and training steps that
lower Eq. 6's losses."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from mimicbench.baselines.mimicat.corr_data import KEYPOINT_FEATURES, keypoint_features
from mimicbench.baselines.mimicat.correspondence import CorrespondenceTransformer, correspondence_loss
from mimicbench.baselines.mimicat.transfer_data import CharacterTensors, pad
from tests.mimicat_toys import TinyEncoder, tube_rig


def _batch(pairs, encoder):
    src = [CharacterTensors.of_rig(a, 32) for a, _ in pairs]
    tgt = [CharacterTensors.of_rig(b, 32) for _, b in pairs]
    kp_s, mask_s = pad([s.features for s in src])
    kp_t, mask_t = pad([t.features for t in tgt])
    tok = encoder(torch.stack([c.normalised(c.vertices) for c in src + tgt]))
    return kp_s, mask_s, kp_t, mask_t, tok[:len(src)], tok[len(src):]


@pytest.fixture
def rigs():
    return [tube_rig("a", 3), tube_rig("b", 5, 1.4), tube_rig("c", 4, 0.7, branch=False)]


def test_keypoint_features_by_hand():
    rig = tube_rig("a", 3, height=2.0, branch=False)
    f = keypoint_features(rig.keypoints, rig.parents, rig.vertices)
    assert f.shape == (3, KEYPOINT_FEATURES)
    # tube of height 2 and radius 0.08: largest side 2, centre at y = 1; joints at y = 0, 2/3, 4/3
    np.testing.assert_allclose(f[:, 1], [-0.5, -1 / 6, 1 / 6], atol=1e-6)
    np.testing.assert_allclose(f[1, 3:6], [0, 4 / 3, 0], atol=1e-6)  # parent offset x4
    np.testing.assert_allclose(f[:, 6], [0, 0.5, 1.0])  # depth / max depth
    np.testing.assert_allclose(f[:, 8], [1, 0, 0])  # root
    np.testing.assert_allclose(f[:, 9], [0, 0, 1])  # leaf


def test_masks_shapes_and_doubly_stochastic(rigs):
    torch.manual_seed(0)
    enc, g = TinyEncoder(), CorrespondenceTransformer(16, width=16, layers=1, heads=2, mlp_width=32)
    pairs = [(rigs[0], rigs[1]), (rigs[1], rigs[2]), (rigs[2], rigs[0])]
    with torch.no_grad():
        ms = g(*_batch(pairs, enc))
    for (a, b), m in zip(pairs, ms):
        ks, kt = len(a.parents), len(b.parents)
        assert m.shape == (ks, kt)
        assert torch.all(m >= 0)
        np.testing.assert_allclose(m.sum(dim=1).numpy(), np.ones(ks), atol=1e-4)
        np.testing.assert_allclose(m.sum(dim=0).numpy(), np.full(kt, ks / kt), atol=1e-4)
    # padding is masked: each pair alone gives the same M as inside the padded batch
    for pair, m in zip(pairs, ms):
        with torch.no_grad():
            alone = g(*_batch([pair], enc))[0]
        np.testing.assert_allclose(alone.numpy(), m.numpy(), atol=1e-5)


def test_training_steps_lower_both_losses(rigs):
    torch.manual_seed(0)
    enc, g = TinyEncoder(), CorrespondenceTransformer(16, width=16, layers=1, heads=2, mlp_width=32)
    pairs = [(rigs[0], rigs[1]), (rigs[1], rigs[0]), (rigs[1], rigs[2])]
    inputs = _batch(pairs, enc)
    inputs = tuple(x.detach() for x in inputs)
    rng = np.random.default_rng(0)
    sinks, hungs = [], []
    for a, b in pairs:  # a target the untrained G cannot already give: a random sharp matching
        ks, kt = len(a.parents), len(b.parents)
        j = rng.integers(kt, size=ks)
        m = np.zeros((ks, kt), np.float32)
        m[np.arange(ks), j] = 1
        sinks.append(torch.as_tensor(m))
        hungs.append(torch.as_tensor(np.stack([np.arange(min(ks, kt)), j[:min(ks, kt)]], 1)))
    opt = torch.optim.AdamW(g.parameters(), lr=3e-3)
    first = None
    for _ in range(30):
        loss = correspondence_loss(g(*inputs), sinks, hungs)
        first = first or {k: float(v.detach()) for k, v in loss.items()}
        opt.zero_grad()
        loss["total"].backward()
        opt.step()
    last = correspondence_loss(g(*inputs), sinks, hungs)
    for key in ("sink", "hung", "total"):
        assert float(last[key]) < 0.8 * first[key], key


def _naive_sinkhorn(scores: np.ndarray, temperature: float, sweeps: int = 5000) -> np.ndarray:
    """Reference: alternate row and column scaling of exp(S / T) to rows 1, columns Ks/Kt."""
    ks, kt = scores.shape
    m = np.exp((scores - scores.max()) / temperature)
    for _ in range(sweeps):
        m /= m.sum(axis=1, keepdims=True)
        m *= (ks / kt) / m.sum(axis=0, keepdims=True)
    return m / m.sum(axis=1, keepdims=True)


def test_temperature_sharpens_m_and_keeps_it_doubly_stochastic(rigs):
    """H's initialisation asks G for M at T < 1: the Sinkhorn balance of exp(S / T) (checked
    against a naive loop), rows 1, columns Ks/Kt, and sharper rows than at T = 1."""
    torch.manual_seed(0)
    enc, g = TinyEncoder(), CorrespondenceTransformer(16, width=16, layers=1, heads=2, mlp_width=32)
    torch.nn.init.normal_(g.affinity, std=10.0)  # scores spread like a trained G's
    pairs = [(rigs[0], rigs[1]), (rigs[1], rigs[2])]
    inputs = _batch(pairs, enc)
    with torch.no_grad():
        scores = g.scores(*inputs).double().numpy()
        flat, sharp = g(*inputs), g(*inputs, temperature=0.1)
    for b, ((a, c), m1, m2) in enumerate(zip(pairs, flat, sharp)):
        ks, kt = len(a.parents), len(c.parents)
        np.testing.assert_allclose(m2.numpy(), _naive_sinkhorn(scores[b, :ks, :kt], 0.1), atol=1e-4)
        np.testing.assert_allclose(m2.sum(dim=1).numpy(), np.ones(ks), atol=1e-4)
        np.testing.assert_allclose(m2.sum(dim=0).numpy(), np.full(kt, ks / kt), atol=1e-4)
        assert float(m2.max(dim=1).values.mean()) > float(m1.max(dim=1).values.mean()) + 0.05
    with pytest.raises(ValueError, match="temperature"):
        g(*inputs, temperature=0.0)


def test_geometric_term_alone_matches_nearest_joints():
    """With the learned (semantic) term zeroed, G's affinity is -w ||p_i - p_j||^2 on the
    unit-height positions and M's row argmax is the nearest-joint match: a target made of the
    source's joints, shuffled and jittered, gives back the shuffle (checked against a naive
    nearest-neighbour loop over the positions). The features' own positions (the box frame) are
    made to disagree, so the test fails if G reads them instead."""
    torch.manual_seed(0)
    rng = np.random.default_rng(3)
    k = 7
    grid = np.stack(np.meshgrid([-0.3, 0.0, 0.3], [-0.3, 0.0, 0.3], [0.0], indexing="ij"), -1).reshape(-1, 3)
    p_s = grid[rng.choice(len(grid), k, replace=False)]  # joints at least 0.3 apart
    shuffle = rng.permutation(k)
    p_t = p_s[shuffle] + rng.uniform(-0.03, 0.03, (k, 3))  # target joint j sits at source joint shuffle[j]
    feats_s = rng.normal(size=(1, k, KEYPOINT_FEATURES))
    feats_t = rng.normal(size=(1, k, KEYPOINT_FEATURES))
    nearest = [min(range(k), key=lambda j: sum((p_s[i][c] - p_t[j][c]) ** 2 for c in range(3))) for i in range(k)]
    assert nearest == list(np.argsort(shuffle))  # the toy's answer, by hand: the inverse shuffle
    g = CorrespondenceTransformer(16, width=16, layers=1, heads=2, mlp_width=32, geometry_weight=50.0)
    f32 = lambda a: torch.as_tensor(a, dtype=torch.float32)  # noqa: E731
    with torch.no_grad():
        g.affinity.zero_()
        ones = torch.ones(1, k, dtype=torch.bool)
        tok = torch.randn(2, 4, 16)
        args = (f32(feats_s), ones, f32(feats_t), ones, tok[:1], tok[1:])
        pos = {"pos_s": f32(p_s)[None], "pos_t": f32(p_t)[None]}
        scores = g.scores(*args, **pos)[0].double().numpy()
        m = g(*args, **pos)[0]
        with pytest.raises(ValueError, match="unit-height"):
            g(*args)
    d2 = ((p_s[:, None, :] - p_t[None, :, :]) ** 2).sum(-1)
    np.testing.assert_allclose(scores, -50.0 * d2, rtol=1e-4, atol=1e-4)  # w starts at w0
    assert m.argmax(dim=1).tolist() == nearest


def test_geometric_weight_stays_positive_and_is_optional():
    """w = w0 softplus(r) / log 2 stays > 0 however far training pushes r; geometry_weight=0 (what
    checkpoints without the setting were trained with) builds G without the term's parameter."""
    g = CorrespondenceTransformer(16, width=16, layers=1, heads=2, mlp_width=32, geometry_weight=10.0)
    assert abs(float(g.geometric_weight()) - 10.0) < 1e-5
    with torch.no_grad():
        g.geometry_raw.fill_(-30.0)
    assert float(g.geometric_weight()) > 0
    plain = CorrespondenceTransformer(16, width=16, layers=1, heads=2, mlp_width=32)
    assert plain.geometric_weight() is None and "geometry_raw" not in plain.state_dict()
    with pytest.raises(ValueError, match="geometry_weight"):
        CorrespondenceTransformer(16, width=16, layers=1, heads=2, mlp_width=32, geometry_weight=-1.0)


def test_unit_keypoints_are_in_nearest_joints_frame(rigs):
    """G's geometric positions: rest keypoints centred at the rest mesh's bounding-box centre and
    divided by its height (Y extent), as ``nearest_joint`` matches them; by hand from the rig."""
    for rig in rigs:
        c = CharacterTensors.of_rig(rig, 16)
        v = np.asarray(rig.vertices, np.float64)
        centre = (v.min(0) + v.max(0)) / 2
        expected = (np.asarray(rig.keypoints, np.float64) - centre) / (v[:, 1].max() - v[:, 1].min())
        np.testing.assert_allclose(c.unit_keypoints.numpy(), expected, rtol=1e-5, atol=1e-6)
