"""SFPT's ``decoder`` stage (baselines/sfpt/decoder_stage.py): its terms against hand values on two rigid
blocks, that it starts from the trained ``sfpt`` weights and changes only the pose decoder, that the method
loads a run's last stage, and that the ``paper`` preset's zero epochs keep the joint weights."""
import numpy as np
import pytest
import torch


def two_blocks():
    """Two disconnected unit squares (8 vertices (8, 3), triangles (4, 3)) and one-hot weights (8, 2)."""
    v = np.float32([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0],
                    [3, 0, 0], [4, 0, 0], [3, 1, 0], [4, 1, 0]])
    f = np.int64([[0, 1, 2], [1, 3, 2], [4, 5, 6], [5, 7, 6]])
    w = np.zeros((8, 2), np.float32)
    w[:4, 0] = 1
    w[4:, 1] = 1
    return v, f, w


class Fixed(torch.nn.Module):
    """A decoder answering fixed transforms (H, 7) whatever it is given."""

    def __init__(self, transforms):
        super().__init__()
        self.transforms = torch.as_tensor(transforms, dtype=torch.float32)

    def forward(self, pose, code, kabsch):
        return self.transforms


def test_decoder_terms_against_hand_values():
    from types import SimpleNamespace

    from mimicbench.baselines.sfpt.decoder_stage import decoder_terms
    from mimicbench.baselines.sfpt.mesh_graph import mesh_edges

    v, f, w = two_blocks()
    truth = v.copy()
    truth[4:, 0] += 0.3  # the second block moved by 0.3 along x
    identity = np.float32([[0, 0, 0, 1, 0, 0, 0]] * 2)
    exact = identity.copy()
    exact[1, 0] = 0.3
    it = {"pose": torch.zeros(2, 4), "code": torch.zeros(2, 4), "kabsch": torch.as_tensor(identity),
          "fit": torch.as_tensor(exact), "rest": torch.as_tensor(v), "truth": torch.as_tensor(truth),
          "weights": torch.as_tensor(w), "edges": torch.as_tensor(mesh_edges(f, 8))}
    got = decoder_terms(SimpleNamespace(decoder=Fixed(exact)), it)
    assert {k: float(x) for k, x in got.items()} == pytest.approx({"rec": 0.0, "arap": 0.0, "trans": 0.0}, abs=1e-6)
    got = decoder_terms(SimpleNamespace(decoder=Fixed(identity)), it)
    # rec: half of (4 of 8 vertices off by 0.3 in one of 3 coordinates: 0.3 * 4 / 24) + half of 0 (the
    # ground-truth handle translations put the block back); trans: L1 of translations 0.3 / 6; arap: rigid
    assert float(got["rec"]) == pytest.approx(0.5 * 0.3 * 4 / 24, abs=1e-6)
    assert float(got["trans"]) == pytest.approx(0.3 / 6, abs=1e-6)
    assert float(got["arap"]) == pytest.approx(0.0, abs=1e-6)


def test_decoder_stage_needs_the_trained_sfpt_stage():
    from mimicbench.baselines.sfpt.decoder_stage import build_decoder
    from mimicbench.training.registry import trainable
    from mimicbench.training.stage import StageContext

    with pytest.raises(ValueError, match="train it first"):
        build_decoder(trainable("sfpt").config("cpu"), StageContext("x", torch.device("cpu"), {}))


def tiny_decoder_config(epochs: int = 1) -> dict:
    from tests.test_npt import tiny

    cfg = tiny("sfpt")
    cfg["decoder"].update(examples=4, batch_size=2, batches_per_epoch=3, epochs=epochs, lr=1e-2)
    return cfg


def test_decoder_stage_trains_only_the_decoder_and_the_method_loads_it(small_zoo, tmp_path):
    from safetensors.torch import load_file

    from mimicbench.baselines.sfpt.method import Sfpt
    from mimicbench.training.loop import train_model

    cfg = tiny_decoder_config()
    results = train_model("sfpt", "all", small_zoo, tmp_path / "run", cfg, epochs=None, progress=False)
    assert [r.stage for r in results] == ["sfpt", "decoder"]
    joint, tuned = load_file(str(results[0].model_path)), load_file(str(results[1].model_path))
    assert joint.keys() == tuned.keys()
    moved = {name for name in joint if not torch.equal(joint[name], tuned[name])}
    assert moved and all(name.startswith("decoder.") for name in moved), moved  # only the decoder trains
    method = Sfpt(checkpoint=tmp_path / "run")
    assert method.weights_path() == results[1].model_path
    method.setup("cpu")
    for name, value in tuned.items():
        torch.testing.assert_close(method.module.state_dict()[name], value, rtol=0, atol=0)


def test_a_few_decoder_steps_lower_the_reconstruction_term(small_zoo):
    from mimicbench.baselines.sfpt.decoder_stage import batches_decoder, build_decoder, loss_decoder
    from mimicbench.baselines.sfpt.training import build_sfpt
    from mimicbench.training.stage import StageContext

    cfg = tiny_decoder_config()
    torch.manual_seed(0)
    frozen = build_sfpt(cfg).eval()
    ctx = StageContext(small_zoo, torch.device("cpu"), cfg, {"sfpt": frozen})
    module = build_decoder(cfg, ctx)
    batch = next(iter(batches_decoder(cfg, ctx, np.random.default_rng(0))))
    first = {k: float(v.detach()) for k, v in loss_decoder(module, batch, ctx).items()}
    assert set(first) == {"total", "rec", "arap", "trans"}
    opt = torch.optim.Adam([p for p in module.parameters() if p.requires_grad], lr=3e-3)
    for _ in range(12):
        loss = loss_decoder(module, batch, ctx)["rec"]
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert float(loss_decoder(module, batch, ctx)["rec"]) < first["rec"]


def test_zero_decoder_epochs_keep_the_joint_weights(small_zoo, tmp_path):
    from safetensors.torch import load_file

    from mimicbench.training.loop import train_stage

    cfg = tiny_decoder_config(epochs=0)
    joint = train_stage("sfpt", "sfpt", small_zoo, tmp_path, cfg, epochs=1, progress=False)
    kept = train_stage("sfpt", "decoder", small_zoo, tmp_path, cfg, progress=False)
    a, b = load_file(str(joint)), load_file(str(kept))
    assert all(torch.equal(a[k], b[k]) for k in a)
