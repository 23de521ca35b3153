"""NPT (baselines/npt): SPAdaIN against a hand computation, the published decoder's blocks and widths,
the placement, the pose reaching the answer through the unnormalised first block, the constant-code
ablation's switch, the residual start, training steps, the checkpoint round trip, and the shipped
weights' self-transfer."""
import numpy as np
import pytest
import torch

from mimicbench.baselines.npt.placement import box_centre, centred, place
from mimicbench.baselines.npt.spadain import SPAdaIN


def test_spadain_is_instance_norm_scaled_and_shifted_by_convs_of_the_identity_points():
    torch.manual_seed(0)
    layer = SPAdaIN(5)
    x, m = torch.randn(2, 5, 40), torch.randn(2, 3, 40)
    out = layer(x, m).detach().numpy()
    xn, mn = x.numpy().astype(np.float64), m.numpy().astype(np.float64)
    wg, bg = layer.gamma.weight.detach().numpy()[:, :, 0], layer.gamma.bias.detach().numpy()
    wb, bb = layer.beta.weight.detach().numpy()[:, :, 0], layer.beta.bias.detach().numpy()
    for b in range(2):
        for c in range(5):
            row = xn[b, c]
            normed = (row - row.mean()) / np.sqrt(((row - row.mean()) ** 2).mean() + 1e-5)  # biased variance
            for i in range(40):
                gamma = sum(wg[c, j] * mn[b, j, i] for j in range(3)) + bg[c]
                beta = sum(wb[c, j] * mn[b, j, i] for j in range(3)) + bb[c]
                assert out[b, c, i] == pytest.approx(normed[i] * gamma + beta, abs=1e-4)


def test_spadain_without_normalisation_scales_and_shifts_the_raw_features():
    torch.manual_seed(1)
    layer = SPAdaIN(4, normalise=False)
    x, m = torch.randn(2, 4, 30), torch.randn(2, 3, 30)
    out = layer(x, m).detach().numpy().astype(np.float64)
    xn, mn = x.numpy().astype(np.float64), m.numpy().astype(np.float64)
    wg, bg = layer.gamma.weight.detach().numpy()[:, :, 0], layer.gamma.bias.detach().numpy()
    wb, bb = layer.beta.weight.detach().numpy()[:, :, 0], layer.beta.bias.detach().numpy()
    for b in range(2):
        for c in range(4):
            for i in range(30):
                gamma = sum(wg[c, j] * mn[b, j, i] for j in range(3)) + bg[c]
                beta = sum(wb[c, j] * mn[b, j, i] for j in range(3)) + bb[c]
                assert out[b, c, i] == pytest.approx(xn[b, c, i] * gamma + beta, abs=1e-4)


def test_placement_puts_a_centred_answer_back_where_the_target_stands_moved_as_the_source():
    rng = np.random.default_rng(0)
    rest = rng.uniform([-0.3, 0.0, -0.2], [0.3, 1.8, 0.2], (200, 3))
    target = rest * 0.5 + [2.0, 0.0, 1.0]
    shift = np.array([0.4, 0.1, -0.2])
    posed = rest + shift
    np.testing.assert_allclose(centred(posed, rest), (rest - box_centre(rest)) / 1.8 * 1.0, atol=2e-2)
    # the centred target rest mesh, placed: the target rest mesh moved by half the source's shift
    # (the target is half the source's size)
    got = place(centred(target, target), rest, posed, target)
    np.testing.assert_allclose(got, target + shift * 0.5, atol=1e-5)


def test_pose_code_takes_any_vertex_count_and_ignores_vertex_order():
    from mimicbench.baselines.npt.model import NeuralPoseTransfer

    torch.manual_seed(0)
    model = NeuralPoseTransfer((8, 16, 32)).eval()
    pose, identity = torch.randn(1, 300, 3), torch.randn(1, 120, 3)
    out = model(pose, identity)
    assert out.shape == (1, 120, 3) and float(out.detach().abs().max()) <= 2.0
    perm = torch.randperm(300)
    torch.testing.assert_close(model(pose[:, perm], identity), out, atol=1e-5, rtol=0)


@pytest.mark.parametrize("widths,decoder", [((64, 128, 1024), (1027, 513, 256)), ((8, 16, 32), (35, 17, 8))])
def test_decoder_has_the_published_blocks_and_widths(widths, decoder):
    # the published max-pool decoder: conv b->b, block, conv b->b/2, block, conv b/2->b/4, block, conv->3,
    # b = c3 + 3 (the code and the xyz); only the first block goes without instance norm
    from mimicbench.baselines.npt.model import NeuralPoseTransfer
    from mimicbench.baselines.npt.spadain import SPAdaINResBlock

    model = NeuralPoseTransfer(widths)
    dec = model.decoder
    assert [(c.in_channels, c.out_channels) for c in dec.convs] == [
        (decoder[0], decoder[0]), (decoder[0], decoder[1]), (decoder[1], decoder[2])]
    assert len(dec.blocks) == 3 and all(isinstance(b, SPAdaINResBlock) for b in dec.blocks)
    assert [b.conv1.in_channels for b in dec.blocks] == list(decoder)
    assert [b.normalised for b in dec.blocks] == [False, True, True]
    assert [m.norm is None for m in (dec.blocks[0].norm1, dec.blocks[0].norm2, dec.blocks[0].norm_s)] == [True] * 3
    assert (dec.out.in_channels, dec.out.out_channels) == (decoder[2], 3)
    assert not any(isinstance(m, torch.nn.InstanceNorm1d) for m in dec.blocks[0].modules())


def test_paper_preset_builds_the_published_network():
    from mimicbench.baselines.npt.training import build_npt
    from mimicbench.training.registry import trainable

    cfg = trainable("npt").config("paper")
    model = build_npt(cfg)
    assert cfg["widths"] == [64, 128, 1024] and cfg["residual"] is False and cfg["lr"] == 5e-5
    assert model.decoder.convs[0].in_channels == 1027 and model.decoder.residual is False
    assert [b.normalised for b in model.decoder.blocks] == [False, True, True]


def test_the_answer_follows_the_pose_through_the_unnormalised_first_block():
    # the code is a per-channel constant over the target points: with instance norm in the first block
    # (a network of normalised blocks only) it is subtracted and two poses give one answer
    from mimicbench.baselines.npt.model import NeuralPoseTransfer
    from mimicbench.baselines.npt.spadain import SPAdaINResBlock

    identity = torch.randn(1, 120, 3)
    pose_a, pose_b = torch.randn(1, 300, 3), 0.5 * torch.randn(1, 300, 3)
    torch.manual_seed(0)
    model = NeuralPoseTransfer((8, 16, 32)).eval()
    with torch.no_grad():
        assert float((model(pose_a, identity) - model(pose_b, identity)).abs().max()) > 1e-3
        all_normed = NeuralPoseTransfer((8, 16, 32)).eval()
        all_normed.decoder.blocks[0] = SPAdaINResBlock(35)
        gap = float((all_normed(pose_a, identity) - all_normed(pose_b, identity)).abs().max())
    assert gap < 1e-5, gap


def test_constant_code_switch_changes_the_answer():
    from mimicbench.baselines.npt.model import NeuralPoseTransfer

    torch.manual_seed(0)
    model = NeuralPoseTransfer((8, 16, 32)).eval()
    pose, identity = torch.randn(1, 300, 3), torch.randn(1, 120, 3)
    with torch.no_grad():
        code = model.encoder(pose.transpose(1, 2))
        torch.testing.assert_close(model(pose, identity, code=code), model(pose, identity), atol=0, rtol=0)
        gap = float((model(pose, identity, code=torch.zeros_like(code)) - model(pose, identity)).abs().max())
    assert gap > 1e-3, gap


def test_residual_network_starts_at_the_identity_points_and_keeps_the_range():
    from mimicbench.baselines.npt.model import NeuralPoseTransfer

    torch.manual_seed(0)
    model = NeuralPoseTransfer((8, 16, 32), residual=True).eval()
    identity = torch.rand(1, 90, 3) - 0.5
    with torch.no_grad():
        torch.testing.assert_close(model(torch.randn(1, 200, 3), identity), identity, atol=0, rtol=0)
        model.decoder.out.bias.fill_(100.0)  # a saturated offset is 2 in every coordinate
        torch.testing.assert_close(model(torch.randn(1, 200, 3), identity), identity + 2.0, atol=1e-5, rtol=0)


def tiny(stage):
    from mimicbench.training.registry import trainable

    cfg = trainable(stage).config("cpu")
    cfg.update(batch_size=2, batches_per_epoch=2)
    if stage == "cgt":
        cfg.update(widths=[8, 16, 32], cap=64, points=256)
    elif stage == "npt":
        cfg.update(widths=[8, 16, 32], points=256)
    else:
        cfg.update(hidden=4, handles=8, code=8, batch_size=1)
    return cfg


def first_batch(stage, dataset, cfg):
    from mimicbench.training.registry import trainable
    from mimicbench.training.stage import StageContext

    st = trainable(stage).stage(stage)
    ctx = StageContext(dataset, torch.device("cpu"), cfg)
    batch = next(iter(st.batches(cfg, ctx, np.random.default_rng(0))))
    batch = {k: torch.as_tensor(v) if isinstance(v, np.ndarray) else v for k, v in batch.items()}
    torch.manual_seed(0)
    return st, st.build(cfg, ctx), batch, ctx


@pytest.mark.parametrize("term", ["total", "mse"])
def test_a_few_steps_lower_the_loss(small_zoo, term):
    from tests.test_mmdmc_training import after_steps

    st, module, batch, ctx = first_batch("npt", small_zoo, tiny("npt"))
    first = {k: float(v.detach()) for k, v in st.loss(module, batch, ctx).items()}
    last = after_steps(st, module, batch, ctx, term=term)
    assert last[term] < first[term], (first, last)


def trained_method(cls, zoo, run):
    """(method, network): a one-epoch training run of ``cls.stage`` at toy size in ``run``, loaded
    through ``cls``, and a network built apart with the weights the run wrote; the method's holds
    exactly those."""
    from safetensors.torch import load_file

    from mimicbench.training.loop import train_stage

    path = train_stage(cls.stage, cls.stage, zoo, run, tiny(cls.stage), epochs=1, progress=False)
    method = cls(checkpoint=run)
    method.setup("cpu")
    trained = first_batch(cls.stage, zoo, tiny(cls.stage))[1]
    trained.load_state_dict(load_file(str(path)))
    for name, value in trained.state_dict().items():
        torch.testing.assert_close(method.module.state_dict()[name], value, rtol=0, atol=0)
    return method, trained


def test_checkpoint_round_trips_through_the_method(small_zoo, tmp_path):
    from mimicbench.baselines.npt.method import Npt
    from mimicbench.benchmark.request import Rig, TransferRequest
    from mimicbench.schemas.shards import read_records

    method, trained = trained_method(Npt, small_zoo, tmp_path / "run")
    rec = next(iter(read_records(small_zoo, "characters")))
    rig = Rig(rec.character_id, rec.category, rec.vertices, rec.faces, rec.keypoints, rec.parents, rec.weights,
              rec.bone_names)
    out = method.transfer([TransferRequest(rig, rec.vertices, rig)])[0]
    # the encoder sees the config's 256 points of the posed source, the draw training makes (seed 0)
    rows = np.sort(np.random.default_rng(0).choice(len(rec.vertices), size=256, replace=False))
    assert len(rec.vertices) > 256 and method.pose_rows(len(rec.vertices)).tolist() == rows.tolist()
    identity = torch.as_tensor(centred(rec.vertices, rec.vertices))[None]
    answer = trained.eval()(identity[:, rows], identity)[0].detach().numpy()
    expect = place(answer, rec.vertices, rec.vertices, rec.vertices)
    np.testing.assert_allclose(out, expect, atol=1e-5)


def self_transfer_pmd(method, zoo) -> tuple[float, float]:
    """Mean over the zoo's first characters of the self-transfer's PMD x100 (by height) against the
    posed source, and identity's (the rest mesh)."""
    from mimicbench.baselines.pose_pairs import PosePool
    from mimicbench.benchmark.request import Rig, TransferRequest

    pool = PosePool.load(zoo)
    got, rest = [], []
    rng = np.random.default_rng(5)
    for cid in pool.ids[:4]:
        r = pool.records[cid]
        rig = Rig(cid, r.category, r.vertices, r.faces, r.keypoints, r.parents, r.weights, r.bone_names)
        posed = pool.posed(cid, pool.draw_pose(cid, rng))
        out = method.transfer([TransferRequest(rig, posed, rig)])[0]
        height = float(np.ptp(r.vertices[:, 1]))
        got.append(np.linalg.norm(out - posed, axis=1).mean() / height * 100)
        rest.append(np.linalg.norm(r.vertices - posed, axis=1).mean() / height * 100)
    return float(np.mean(got)), float(np.mean(rest))


def test_shipped_self_transfer_comes_back_close_to_the_posed_source(small_zoo):
    from mimicbench.baselines.npt.method import Npt

    got, identity = self_transfer_pmd(Npt(), small_zoo)
    assert got < identity, (got, identity)
