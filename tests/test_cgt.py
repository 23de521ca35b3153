"""CGT (baselines/cgt): the published block structure (four CGPBlocks interleaved with the SPAdaIN blocks,
widths, one shared encoder), the CGPBlock against a naive loop, the no-attention switch, farthest-point
sampling against a naive loop, capped attention against the dense one and continuous in the target point,
training steps, the checkpoint round trip and the shipped weights' self-transfer."""
import numpy as np
import pytest
import torch

from mimicbench.baselines.cgt.sampling import farthest_points


def gained(model):
    """``model`` with every CGPBlock's gain set to 1 (it starts at 0, where the attention adds nothing)."""
    with torch.no_grad():
        for block in model.cgp:
            block.gain.fill_(1.0)
    return model


@pytest.mark.parametrize("widths,stages", [((64, 128, 1024), (1024, 512, 512, 256)), ((8, 16, 32), (32, 16, 16, 8))])
def test_four_cgp_blocks_sit_before_the_four_spadain_blocks_at_the_published_widths(widths, stages):
    from mimicbench.baselines.cgt.model import Cgt, CGPBlock
    from mimicbench.baselines.npt.spadain import SPAdaINResBlock

    model = Cgt(widths)
    assert [(c.in_channels, c.out_channels) for c in model.convs] == list(zip((widths[-1],) + stages[:-1], stages))
    assert len(model.cgp) == 4 and all(isinstance(b, CGPBlock) for b in model.cgp)
    assert [b.query.in_channels for b in model.cgp] == list(stages)
    assert len(model.blocks) == 4 and all(isinstance(b, SPAdaINResBlock) and b.normalised for b in model.blocks)
    assert [b.conv1.in_channels for b in model.blocks] == list(stages)
    assert (model.out.in_channels, model.out.out_channels) == (stages[-1], 3)
    # single head, no norm, gain starting at zero
    for block in model.cgp:
        assert float(block.gain.detach()) == 0.0 and block.gain.shape == (1,)
        assert not any(isinstance(m, (torch.nn.LayerNorm, torch.nn.InstanceNorm1d, torch.nn.MultiheadAttention))
                       for m in block.modules())
    # one encoder shared by both meshes
    assert [n for n, _ in model.named_children()].count("encoder") == 1
    assert not any("identity_features" in n or "pose_features" in n for n, _ in model.named_modules())


def test_the_attention_sits_between_each_stage_conv_and_its_spadain_block():
    from mimicbench.baselines.cgt.model import Cgt

    torch.manual_seed(0)
    model = gained(Cgt((8, 16, 32)).eval())
    order = []
    for i in range(4):
        model.convs[i].register_forward_hook(lambda *a, i=i: order.append(f"conv{i}"))
        model.cgp[i].register_forward_hook(lambda *a, i=i: order.append(f"cgp{i}"))
        model.blocks[i].register_forward_hook(lambda *a, i=i: order.append(f"block{i}"))
    with torch.no_grad():
        model(torch.randn(1, 50, 3), torch.randn(1, 40, 3))
    expect = []
    for i in range(4):
        expect += [f"conv{i}"] * 3 + [f"cgp{i}", f"block{i}"]  # the shared conv runs on the three streams
    assert order == expect


def test_cgp_block_matches_a_naive_loop():
    # energy[p, q] = query(pose_p) . key(identity_q); each target point q: softmax over p, gather value(pose_p)
    from mimicbench.baselines.cgt.model import CGPBlock

    torch.manual_seed(0)
    block = CGPBlock(5)
    with torch.no_grad():
        block.gain.fill_(0.7)
        x, p, i = torch.randn(1, 5, 7), torch.randn(1, 5, 9), torch.randn(1, 5, 7)
        out = block(x, p, i)[0].double().numpy()
    wq, bq = block.query.weight[:, :, 0].detach().double().numpy(), block.query.bias.detach().double().numpy()
    wk, bk = block.key.weight[:, :, 0].detach().double().numpy(), block.key.bias.detach().double().numpy()
    wv, bv = block.value.weight[:, :, 0].detach().double().numpy(), block.value.bias.detach().double().numpy()
    P, Id, X = p[0].double().numpy(), i[0].double().numpy(), x[0].double().numpy()
    for q in range(7):
        energies = [float((wq @ P[:, a] + bq) @ (wk @ Id[:, q] + bk)) for a in range(9)]
        e = np.exp(np.array(energies) - max(energies))
        weights = e / e.sum()
        gathered = sum(weights[a] * (wv @ P[:, a] + bv) for a in range(9))
        np.testing.assert_allclose(out[:, q], X[:, q] + 0.7 * gathered, atol=1e-5)


def test_no_attention_switch_changes_the_answer_and_zero_gain_is_no_attention():
    from mimicbench.baselines.cgt.model import Cgt

    torch.manual_seed(0)
    model = Cgt((8, 16, 32)).eval()
    pose, identity = torch.randn(1, 60, 3), torch.randn(1, 40, 3)
    with torch.no_grad():
        untrained = model(pose, identity)
        model.attention = False
        torch.testing.assert_close(model(pose, identity), untrained, atol=0, rtol=0)  # gain 0: no effect yet
        gained(model)
        without = model(pose, identity)
        model.attention = True
        with_attention = model(pose, identity)
    assert float((with_attention - without).abs().max()) > 1e-3


def test_farthest_points_match_a_naive_loop():
    pts = np.random.default_rng(0).normal(size=(80, 3))
    got = farthest_points(pts, 12)
    chosen = [int(np.argmax(np.linalg.norm(pts - pts.mean(0), axis=1)))]
    while len(chosen) < 12:
        gaps = [min(np.linalg.norm(p - pts[c]) for c in chosen) for p in pts]
        chosen.append(int(np.argmax(gaps)))
    assert got.tolist() == chosen
    assert farthest_points(pts, 80).tolist() == list(range(80)) and farthest_points(pts, 0).tolist() == list(range(80))


def test_capped_answer_moves_a_hair_when_a_target_point_moves_a_hair(tube):
    # a carry of attended features from a few nearest capped points jumps where the nearest change: two
    # points 1e-7 apart (a resampled real mesh's near-zero edge) would be sent far apart. Every target point
    # queries on its own: a smooth function of it.
    from mimicbench.baselines.cgt.model import Cgt
    from mimicbench.baselines.cgt.training import capped_rows
    from mimicbench.baselines.npt.placement import centred

    torch.manual_seed(0)
    model = gained(Cgt((8, 16, 32)).eval())
    v = centred(tube["vertices"], tube["vertices"])
    posed = v.copy()
    posed[v[:, 1] > 0.1] += [0.05, 0.0, 0.0]
    nudged = v + np.random.default_rng(3).normal(scale=1e-7, size=v.shape).astype(np.float32)
    rows = {k: torch.as_tensor(x) for k, x in capped_rows(posed, v, len(v) // 4).items()}
    assert len(rows["pose_rows"]) == len(v) // 4
    with torch.no_grad():
        a = model(torch.as_tensor(posed)[None], torch.as_tensor(v)[None], **rows)
        b = model(torch.as_tensor(posed)[None], torch.as_tensor(nudged)[None], **rows)
    assert float((a - b).abs().max()) < 1e-4
    assert float((a - a[:, :1]).abs().max()) > 1e-2  # and the answer is not one point everywhere


def test_capped_attention_is_the_dense_one_when_the_cap_holds_every_point_or_drops_only_duplicates(tube):
    from mimicbench.baselines.cgt.model import Cgt
    from mimicbench.baselines.cgt.training import capped_rows
    from mimicbench.baselines.npt.placement import centred

    torch.manual_seed(0)
    model = gained(Cgt((8, 16, 32)).eval())
    v = centred(tube["vertices"], tube["vertices"])
    posed = v.copy()
    posed[v[:, 1] > 0.1] += [0.05, 0.0, 0.0]
    p, i = torch.as_tensor(posed)[None], torch.as_tensor(v)[None]
    dense = model(p, i)
    rows = {k: torch.as_tensor(x) for k, x in capped_rows(posed, v, len(v)).items()}
    torch.testing.assert_close(model(p, i, **rows), dense, atol=1e-5, rtol=0)
    # a source of every point twice, capped at N: farthest-point sampling keeps one copy of each, and
    # attending over those is attending over all (a softmax over duplicated keys averages the same values)
    twice = np.concatenate([posed, posed])
    rows = capped_rows(twice, v, len(v))
    assert sorted(rows["pose_rows"] % len(v)) == list(range(len(v)))
    capped = model(torch.as_tensor(twice)[None], i, **{k: torch.as_tensor(x) for k, x in rows.items()})
    torch.testing.assert_close(capped, dense, atol=3e-5, rtol=0)  # float32 sums over twice the keys


def test_a_few_steps_lower_the_loss(small_zoo):
    from tests.test_mmdmc_training import after_steps
    from tests.test_npt import first_batch, tiny

    st, module, batch, ctx = first_batch("cgt", small_zoo, tiny("cgt"))
    assert all(list(r) == ["pose_rows"] and len(r["pose_rows"]) == 64 for r in batch["capped"])
    first = {k: float(v.detach()) for k, v in st.loss(module, batch, ctx).items()}
    last = after_steps(st, module, batch, ctx)
    assert last["total"] < first["total"] and last["mse"] < first["mse"], (first, last)


def test_checkpoint_round_trips_through_the_method(small_zoo, tmp_path):
    from mimicbench.baselines.cgt.method import Cgt
    from tests.test_npt import trained_method

    method = trained_method(Cgt, small_zoo, tmp_path / "run")[0]
    assert method.cap == 64


def test_shipped_self_transfer_comes_back_close_to_the_posed_source(small_zoo):
    from mimicbench.baselines.cgt.method import Cgt
    from tests.test_npt import self_transfer_pmd

    got, identity = self_transfer_pmd(Cgt(), small_zoo)
    assert got < identity, (got, identity)
