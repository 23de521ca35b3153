"""NPT's and CGT's cross-category cycle term (baselines/npt/cycle.py)."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from mimicbench.baselines.npt.cycle import box_centred, cross_category_pairs, cycle_batch, cycle_item, cycle_terms


def self_pair(zoo, category: str = "humanoid"):
    """(A rest, A posed) (N, 3) float32 of the first ``category`` character of ``zoo``, posed by a frame of a clip,
    both in the centred unit-size frame of its rest mesh (every vertex)."""
    from mimicbench.baselines.npt.placement import centred
    from mimicbench.baselines.pose_pairs import PosePool

    pool = PosePool.load(zoo)
    cid = next(c for c in pool.ids if pool.records[c].category == category)
    rest = np.asarray(pool.records[cid].vertices, np.float32)
    posed = pool.posed(cid, pool.motions[cid][0][len(pool.motions[cid][0]) // 2])
    return centred(rest, rest), centred(posed, rest)


def naive_edge_ratio(x: np.ndarray, ref: np.ndarray, edges: np.ndarray) -> float:
    """Mean over edges of |l_x^2 / l_ref^2 - 1|, one edge at a time (float64)."""
    x, ref = np.asarray(x, np.float64), np.asarray(ref, np.float64)
    total = 0.0
    for i, j in edges:
        total += abs(float(((x[i] - x[j]) ** 2).sum()) / max(float(((ref[i] - ref[j]) ** 2).sum()), 1e-8) - 1.0)
    return total / len(edges)


def test_cycle_is_zero_for_an_exact_transfer_on_a_self_pair_and_the_edge_term_is_the_hand_one(small_zoo):
    from mimicbench.baselines.pose_pairs import knn_pairs

    rest, posed = self_pair(small_zoo)
    edges = knn_pairs(rest, 6)
    edges = edges[((rest[edges[:, 0]] - rest[edges[:, 1]]) ** 2).sum(1) > 0]  # seam duplicates have no length
    t = {k: torch.as_tensor(v, dtype=torch.float64)[None] for k, v in (("rest", rest), ("posed", posed))}
    # on a self pair (B = A, the same rows) the exact transfer answers the posed source itself
    exact = cycle_terms(lambda pose, identity: pose, t["posed"], t["rest"], t["rest"], torch.as_tensor(edges))
    assert float(exact["cycle"]) < 1e-12
    assert float(exact["cycle_edge"]) == pytest.approx(naive_edge_ratio(posed, rest, edges), rel=1e-9)
    assert float(exact["cycle_edge"]) > 1e-3  # a real pose stretches some neighbour pairs
    # the rest mesh answered (a method that ignores the pose): the cycle is the MSE of rest to posed
    still = cycle_terms(lambda pose, identity: identity, t["posed"], t["rest"], t["rest"], torch.as_tensor(edges))
    assert float(still["cycle"]) == pytest.approx(float(((rest.astype(np.float64) - posed) ** 2).mean()), rel=1e-9)
    assert float(still["cycle_edge"]) == 0.0
    # a rigid rotation of the rest mesh keeps every edge: the edge term is zero
    c, s = np.cos(0.7), np.sin(0.7)
    turned = rest.astype(np.float64) @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]).T
    rigid = cycle_terms(lambda pose, identity: pose, torch.as_tensor(turned)[None], t["rest"], t["rest"],
                        torch.as_tensor(edges))
    assert float(rigid["cycle_edge"]) < 1e-9


def test_the_return_leg_sees_the_forward_answer_recentred_at_its_box_centre():
    seen = []

    def answer(pose, identity):
        seen.append(pose.clone())
        return identity + 5.0  # a forward answer far from the centre

    pose, mid, back = torch.rand(2, 30, 3), torch.rand(2, 20, 3), torch.rand(2, 30, 3)
    cycle_terms(answer, pose, mid, back, torch.zeros(0, 2, dtype=torch.long))
    for b in range(2):
        x = seen[1][b].numpy()
        np.testing.assert_allclose((x.min(0) + x.max(0)) / 2, 0.0, atol=1e-6)
        y = mid[b].numpy() + 5.0
        np.testing.assert_allclose(x, y - (y.min(0) + y.max(0)) / 2, atol=1e-6)
    np.testing.assert_allclose(box_centred(torch.tensor([[[0.0, 1, 2], [2, 5, 4]]])).numpy(),
                               [[[-1, -2, -1], [1, 2, 1]]])


def test_cross_category_pairs_are_the_cct_protocols_pairs(small_zoo):
    import pandas as pd

    from mimicbench.baselines.pose_pairs import PosePool

    pool = PosePool.load(small_zoo)
    chars = pd.concat([pd.read_parquet(f, columns=["character_id", "category"])
                       for f in sorted((small_zoo / "characters").glob("*.parquet"))])
    human = {c: k in ("humanoid", "apparel") for c, k in zip(chars.character_id, chars.category) if c in pool.ids}
    expected = [(a, b) for a in sorted(human) for b in sorted(human) if human[a] != human[b]]
    pairs = cross_category_pairs(pool)
    assert pairs == expected and len(pairs) > 0


def test_cycle_examples_keep_the_rows_of_a_in_step_and_a_dataset_without_pairs_is_a_clear_error(small_zoo):
    from mimicbench.baselines.npt.placement import centred
    from mimicbench.baselines.pose_pairs import PosePool
    from mimicbench.runtime.errors import UserError

    pool = PosePool.load(small_zoo)
    cfg = {"points": 128, "knn": 4, "cycle_batch": 3}
    b = cycle_batch(pool, cross_category_pairs(pool), cfg, np.random.default_rng(1))
    assert b["cycle_pose"].shape == (3, 128, 3) and b["cycle_edges"].shape == (3, 128 * 4, 2)
    # one example: A's rest and posed points are A's vertices at the same rows, B's points B's rest vertices
    a, bb = cross_category_pairs(pool)[0]
    one = cycle_item(pool, a, bb, cfg, np.random.default_rng(5))
    a_rest = centred(pool.records[a].vertices, pool.records[a].vertices)
    b_rest = centred(pool.records[bb].vertices, pool.records[bb].vertices)
    posed = pool.posed(a, pool.draw_pose(a, np.random.default_rng(5)))  # the item's first draw
    both = np.concatenate([a_rest, centred(posed, pool.records[a].vertices)], 1)  # (Na, 6) rest | posed
    item = np.concatenate([one["cycle_back"], one["cycle_pose"]], 1)
    assert max(float(np.min(((both - p) ** 2).sum(1))) for p in item) < 1e-12
    assert all(np.min(((b_rest - p) ** 2).sum(1)) == 0.0 for p in one["cycle_mid"])
    with pytest.raises(UserError, match="cycle_batch=0"):
        cycle_batch(pool, [], cfg, np.random.default_rng(1))


@pytest.mark.parametrize("stage", ["npt", "cgt"])
def test_a_few_steps_lower_the_cycle_term_and_the_term_is_off_without_cycle_batch(small_zoo, stage):
    from tests.test_mmdmc_training import after_steps
    from tests.test_npt import first_batch, tiny

    from mimicbench.baselines.npt.config import CYCLE

    cfg = {**tiny(stage), **CYCLE}  # the cycle term (ours, off in every preset)
    st, module, batch, ctx = first_batch(stage, small_zoo, cfg)
    assert batch["cycle_pose"].shape[0] == cfg["cycle_batch"]
    first = {k: float(v.detach()) for k, v in st.loss(module, batch, ctx).items()}
    last = after_steps(st, module, batch, ctx, term="cycle")
    assert last["cycle"] < first["cycle"], (first, last)
    st, module, batch, ctx = first_batch(stage, small_zoo, tiny(stage))  # cpu preset: no cycle keys, no term
    assert not any(k.startswith("cycle") for k in batch)
    assert "cycle" not in st.loss(module, batch, ctx)


def test_a_detached_forward_leg_gets_no_gradient_from_the_cycle():
    """answer(p, i) = i + a p, one shared scalar a: with the forward answer F = mid + a pose detached,
    dcycle/da is the return leg's alone, 2/n sum (back + a c(F) - pose) c(F) with c the box centring
    (hand formula, float64); without detaching, the forward leg adds its part and the two differ."""
    rng = np.random.default_rng(3)
    pose, mid, back = (rng.normal(size=(2, 25, 3)) for _ in range(3))
    grads = {}
    for detach in (True, False):
        a = torch.tensor(0.7, dtype=torch.float64, requires_grad=True)
        terms = cycle_terms(lambda p, i: i + a * p, torch.as_tensor(pose), torch.as_tensor(mid), torch.as_tensor(back),
                            torch.zeros(0, 2, dtype=torch.long), detach_forward=detach)
        terms["cycle"].backward()
        grads[detach] = float(a.grad)
    f = mid + 0.7 * pose
    c = f - (f.max(1, keepdims=True) + f.min(1, keepdims=True)) / 2
    hand = 2.0 / pose.size * float(((back + 0.7 * c - pose) * c).sum())
    assert grads[True] == pytest.approx(hand, rel=1e-9)
    assert abs(grads[False] - grads[True]) > 1e-3 * abs(hand)
