"""The transfer stage's shared caches (G's M per epoch for all ranks, E's rest tokens once per mesh)
give the batches and losses that recomputing everything in the step gives."""
from __future__ import annotations

import numpy as np
import pytest
import torch


@pytest.fixture()
def stage_context(small_zoo):
    import mimicbench.baselines.mimicat.transfer_training as tt
    from mimicbench.baselines.mimicat.method import BUNDLED, checkpoint_path
    from mimicbench.training.checkpoint import load_module, read_header
    from mimicbench.training.registry import trainable
    from mimicbench.training.stage import StageContext

    model = trainable("mimicat")
    config = read_header(checkpoint_path(BUNDLED, "transfer"))["config"]
    config = {**config, "transfer": {**config["transfer"], "examples_per_epoch": 4, "batch_size": 2}}
    ctx = StageContext(small_zoo, torch.device("cpu"), config)
    for need in model.stage("transfer").needs:
        m = load_module(checkpoint_path(BUNDLED, need), lambda cfg, s=model.stage(need): s.build(cfg, ctx), ctx.device)
        for p in m.parameters():
            p.requires_grad_(False)
        ctx.frozen[need] = m.eval()
    saved = dict(tt._CACHE), tt.SHARED_CACHES
    tt._CACHE.clear()
    yield tt, model, config, ctx
    tt._CACHE.clear()
    tt._CACHE.update(saved[0])
    tt.SHARED_CACHES = saved[1]


def _epoch(tt, model, config, ctx, shared: bool):
    """One epoch's batches and their losses (H freshly built with seed 0), caches cleared first."""
    tt._CACHE.clear()
    tt.SHARED_CACHES = shared
    torch.manual_seed(0)
    h = model.stage("transfer").build(config, ctx)
    batches = list(model.stage("transfer").batches(config, ctx, np.random.default_rng(3)))
    cached = dict(tt._CACHE.get(("m", str(ctx.dataset), str(ctx.device)), {}))
    losses = [{k: float(v.detach()) for k, v in tt.transfer_loss(h, b, ctx).items()} for b in batches]
    return batches, cached, losses


def test_shared_caches_give_the_losses_of_recomputation(stage_context):
    tt, model, config, ctx = stage_context
    b_off, m_off, l_off = _epoch(tt, model, config, ctx, shared=False)
    b_on, m_on, l_on = _epoch(tt, model, config, ctx, shared=True)
    assert b_on == b_off and len(b_on) == 2
    assert not m_off  # the per-step path computes M in the step
    pairs = {(s, t) for b in b_on for s, _, _, t in b["examples"]}
    assert set(m_on) == {(a, b, float(config["transfer"]["m_temperature"])) for s, t in pairs for a, b in ((s, t), (t, s))}
    for on, off in zip(l_on, l_off):
        assert on.keys() == off.keys()
        for k in on:
            assert abs(on[k] - off[k]) <= 1e-4 * max(1.0, abs(off[k])), (k, on[k], off[k])


def test_shared_correspondences_match_one_pair_at_a_time(stage_context, monkeypatch):
    """Batched with other pairs (padding, masks) and split over two ranks by hand, G's M equals
    the M of each pair computed alone."""
    import mimicbench.training.distributed as dist
    from mimicbench.baselines.mimicat.transfer import correspondences
    from mimicbench.training.stage import StageContext

    monkeypatch.setattr(dist, "gather_objects", lambda obj, world_size: [obj])  # each rank's own share

    tt, _, config, ctx = stage_context
    c = tt.section(config, "transfer")
    _, _, tensors = tt._characters(ctx.dataset, ctx.device, c["points"], c["split"])
    ids = sorted(tensors)[:4]
    pairs = [(a, b) for a in ids for b in ids if a != b][:6]
    merged = {}
    for rank in (0, 1):  # what each of two ranks computes before the gather
        tt._CACHE.clear()
        tt.shared_correspondences(StageContext(ctx.dataset, ctx.device, config, ctx.frozen, rank, 2), tensors, pairs,
                                  0.1, chunk=2)
        got = tt._m_cache(ctx)
        assert len(got) == len(pairs[rank::2])
        merged.update(got)
    assert {k[:2] for k in merged} == set(pairs)
    for (s, t, temp), m in merged.items():
        alone = correspondences(ctx.frozen["shape"], ctx.frozen["corr"], [tensors[s]], [tensors[t]], {}, temp)[0]
        np.testing.assert_allclose(m.numpy(), alone.numpy(), atol=1e-4)  # Sinkhorn stops within 1e-5 of its marginals


@pytest.mark.parametrize("decode", ["soft", "hungarian", "hungarian_sym"])
def test_both_legs_read_the_decoded_m(stage_context, decode):
    """``transfer.m_decode``: H's initialisation in both legs of the cycle reads G's cached soft M
    as it is (``soft``) or its one-to-one decoding (``hungarian``: 0/1, at most one 1 a row and a
    column, min(Ks, Kt) of them, summing to no less of the soft M than its greedy one-to-one
    matching; ``hungarian_sym``: the same of M(s, t) + M(t, s)^T, and the return leg's is the
    forward leg's transpose)."""
    tt, model, config, ctx = stage_context
    config = {**config, "transfer": {**config["transfer"], "init": "structured", "m_decode": decode}}
    ctx.config = config
    tt._CACHE.clear()
    torch.manual_seed(0)
    h = model.stage("transfer").build(config, ctx)
    seen = []
    original = h.initialise
    h.initialise = lambda src, q, t, tgt, m: (seen.append((src.character_id, tgt.character_id, m)),
                                              original(src, q, t, tgt, m))[1]
    batch = next(iter(model.stage("transfer").batches(config, ctx, np.random.default_rng(3))))
    tt.transfer_loss(h, batch, ctx)
    cache = tt._CACHE[("m", str(ctx.dataset), str(ctx.device))]
    temp = float(config["transfer"]["m_temperature"])
    assert len(seen) == 2 * len(batch["examples"])  # forward and return legs
    decoded = {(s, t): m.numpy() for s, t, m in seen}
    for s, t, m in seen:
        soft = cache[(s, t, temp)].numpy()
        if decode == "hungarian_sym":  # one assignment of the pair, read both ways
            soft = soft + cache[(t, s, temp)].numpy().T
            np.testing.assert_array_equal(decoded[(t, s)].T, decoded[(s, t)])
        got = m.numpy()
        if decode == "soft":
            np.testing.assert_allclose(got, soft, atol=0)
            continue
        assert set(np.unique(got)) <= {0.0, 1.0} and got.sum() == min(got.shape)
        assert got.sum(axis=0).max() <= 1 and got.sum(axis=1).max() <= 1
        left, greedy = soft.astype(np.float64), 0.0
        for _ in range(min(got.shape)):
            i, j = np.unravel_index(np.argmax(left), left.shape)
            greedy += float(soft[i, j])
            left[i, :], left[:, j] = -np.inf, -np.inf
        assert float((soft.astype(np.float64) * got).sum()) >= greedy - 1e-6


def test_symmetric_decoding_brings_every_matched_chain_back(stage_context):
    """With ``hungarian_sym`` the cycle through the structured initialisation (H off) returns
    every source bone whose bone and ancestors all go to a target bone and come back to
    themselves with its own rotation and position: the construction undoes itself where the two
    legs agree on the matches (checked by a loop over the bones, on the stage's own draws), and
    every bone matched going out comes back to itself."""
    from mimicbench.baselines.mimicat.transfer import correspondences, decode_correspondence

    tt, model, config, ctx = stage_context
    config = {**config, "transfer": {**config["transfer"], "init": "structured", "m_decode": "hungarian_sym"}}
    c = tt.section(config, "transfer")
    records, motions, tensors = tt._characters(ctx.dataset, ctx.device, c["points"], c["split"])
    torch.manual_seed(0)
    h = model.stage("transfer").build(config, ctx)
    checked = 0
    for s_id, clip, frame, t_id in tt.transfer_examples(records, motions, 6, 0.0, np.random.default_rng(1)):
        s, t = tensors[s_id], tensors[t_id]
        pose = torch.as_tensor(motions[s_id][clip][frame])
        g_st, g_ts = (correspondences(ctx.frozen["shape"], ctx.frozen["corr"], [a], [b], {}, c["m_temperature"])[0]
                      for a, b in ((s, t), (t, s)))
        m_fwd, m_back = decode_correspondence(g_st, "hungarian_sym", g_ts), decode_correspondence(g_ts, "hungarian_sym", g_st)
        with torch.no_grad():
            q1, t1 = h.initialise(s, pose[:, :4], pose[:, 4:], t, m_fwd)[:2]
            q2, t2 = h.initialise(t, q1, t1, s, m_back)[:2]
        fwd, back = m_fwd.numpy(), m_back.numpy()
        home = [bool(fwd[i].sum() > 0 and back[int(fwd[i].argmax()), i] == 1) for i in range(len(s.parents))]
        assert all(home[i] for i in range(len(home)) if fwd[i].sum() > 0)  # no bone comes back to another
        for i in range(len(s.parents)):
            a, chain = i, True
            while a >= 0:
                chain, a = chain and home[a], s.parents[a]
            if not chain:
                continue
            checked += 1
            assert abs(abs(float(q2[i] @ pose[i, :4])) - 1) < 1e-5, (s_id, t_id, i)
            assert float((t2[i] - pose[i, 4:]).norm()) < 1e-4 * s.size, (s_id, t_id, i)
    assert checked >= 10
