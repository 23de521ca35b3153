"""SFPT's ``decoder`` stage (baselines/sfpt/decoder_stage.py): its terms against hand values on two rigid
blocks (centred, translations from the Kabsch fit), their invariance to where the target stands, that it
starts from the trained ``sfpt`` weights and changes only the pose decoder's rotations, that the method loads a
run's last stage, that the ``paper`` preset's zero epochs keep the joint weights, and that the shipped decoder
reads the target's encoding and differs from the bare Kabsch fit."""
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


IDENTITY = np.float32([[0, 0, 0, 1, 0, 0, 0]] * 2)


def example(truth: np.ndarray, fit: np.ndarray) -> dict:
    from mimicbench.baselines.sfpt.mesh_graph import mesh_edges

    v, f, w = two_blocks()
    return {"pose": torch.zeros(2, 4), "code": torch.zeros(2, 4), "kabsch": torch.as_tensor(IDENTITY),
            "fit": torch.as_tensor(fit), "rest": torch.as_tensor(v), "truth": torch.as_tensor(truth),
            "weights": torch.as_tensor(w), "edges": torch.as_tensor(mesh_edges(f, 8))}


def terms_of(transforms, it) -> dict:
    from types import SimpleNamespace

    from mimicbench.baselines.sfpt.decoder_stage import decoder_terms

    return {k: float(x) for k, x in decoder_terms(SimpleNamespace(decoder=Fixed(transforms)), it).items()}


def test_decoder_terms_against_hand_values():
    v, _, _ = two_blocks()
    truth = v + np.float32([0.5, 0.0, 0.0])  # the whole target placed 0.5 along x ...
    truth[4:, 0] += 0.3  # ... and its second block moved 0.3 further
    it = example(truth, IDENTITY)
    # the decoder answers no motion and the source's Kabsch fit has zero translations: after centring (means
    # x 2 and 2.65), block one is 0.15 ahead of the truth and block two 0.15 behind, a distance of 0.15 for every
    # vertex; with the ground-truth handle translations (0.5 and 0.8) the deformation is the truth: 0.
    # Uncentred, the plain deformation would be 0.65 away on average (0.5 and 0.8).
    assert terms_of(IDENTITY, it) == pytest.approx({"rec": 0.5 * 0.15, "arap": 0.0, "trans": 0.0}, abs=1e-6)
    # the decoder's own translations are replaced by the Kabsch fit's: answering any of them changes nothing
    moved = IDENTITY.copy()
    moved[:, :3] = [[9.0, -4.0, 2.0], [0.3, 0.0, 0.0]]
    assert terms_of(moved, it) == pytest.approx(terms_of(IDENTITY, it), abs=1e-7)
    # a half turn of block two about z: its quaternion (0, 0, 0, 1) against the fit's (1, 0, 0, 0) differs by
    # 0.5 on average (either sign), block one's by 0: trans = 0.5 * mean(0, 0.5); still rigid, so arap 0
    turned = IDENTITY.copy()
    turned[1, 3:] = [0, 0, 0, 1]
    got = terms_of(turned, it)
    assert got["trans"] == pytest.approx(0.5 * 0.25, abs=1e-6) and got["arap"] == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize("offset", [[0.0, 0.0, 0.0], [1.0, -2.0, 0.5], [-30.0, 7.0, 12.0]])
def test_the_stage_loss_is_invariant_to_a_translation_of_the_target(offset):
    """The same truth placed anywhere, with its Kabsch fit recomputed from the placed truth, gives the same
    terms: placement cannot be learned. Checked against the hand value of the unplaced example."""
    from mimicbench.baselines.sfpt.handles import kabsch_transforms

    v, _, w = two_blocks()
    truth = v.copy()
    truth[4:, 1] += 0.2  # block two 0.2 up: centred, block one is 0.1 above the truth, block two 0.1 below
    truth = truth + np.float32(offset)
    fit = kabsch_transforms(torch.as_tensor(v), torch.as_tensor(truth), torch.as_tensor(w)).numpy()
    turned = IDENTITY.copy()
    turned[1, 3:] = [np.cos(0.3), 0, 0, np.sin(0.3)]
    got = terms_of(turned, example(truth, fit))
    assert got == pytest.approx(terms_of(turned, example(v + np.float32([0, 0.2, 0]) * (np.arange(8) >= 4)[:, None],
                                                          fit)), abs=1e-5)
    assert terms_of(IDENTITY, example(truth, fit))["rec"] == pytest.approx(0.5 * 0.1, abs=1e-6)


def test_decoder_stage_needs_the_trained_sfpt_stage():
    from mimicbench.baselines.sfpt.decoder_stage import build_decoder
    from mimicbench.training.registry import trainable
    from mimicbench.training.stage import StageContext

    with pytest.raises(ValueError, match="train it first"):
        build_decoder(trainable("sfpt").config("cpu"), StageContext("x", torch.device("cpu"), {}))


def tiny_decoder_config(epochs: int = 1) -> dict:
    from tests.test_npt import tiny

    cfg = tiny("sfpt")
    cfg["decoder"] = {**cfg["decoder"], "examples": 4, "batch_size": 2, "batches_per_epoch": 3, "epochs": epochs,
                      "lr": 1e-2}
    return cfg


def test_decoder_stage_trains_only_the_decoders_rotations_and_the_method_loads_it(small_zoo, tmp_path):
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
    last = max({n.rsplit(".", 1)[0] for n in tuned if n.startswith("decoder.net.")}, key=lambda n: int(n.split(".")[2]))
    assert not tuned[f"{last}.weight"][:3].any() and not tuned[f"{last}.bias"][:3].any()  # translations: Kabsch's
    assert tuned[f"{last}.weight"][3:].abs().sum() > 0
    method = Sfpt(checkpoint=tmp_path / "run")
    assert method.weights_path() == results[1].model_path
    method.setup("cpu")
    for name, value in tuned.items():
        torch.testing.assert_close(method.module.state_dict()[name], value, rtol=0, atol=0)


@pytest.mark.parametrize("term", ["total", "rec"])
def test_the_decoder_stage_loss_falls_along_its_gradient(small_zoo, term):
    from mimicbench.baselines.sfpt.decoder_stage import batches_decoder
    from mimicbench.baselines.sfpt.model import build_sfpt
    from mimicbench.training.registry import trainable
    from mimicbench.training.stage import StageContext
    from tests.test_mmdmc_training import after_descent

    cfg = tiny_decoder_config()
    torch.manual_seed(0)
    frozen = build_sfpt(cfg).eval()
    ctx = StageContext(small_zoo, torch.device("cpu"), cfg, {"sfpt": frozen})
    st = trainable("sfpt").stage("decoder")
    module = st.build(cfg, ctx)
    batch = next(iter(batches_decoder(cfg, ctx, np.random.default_rng(0))))
    assert set(st.loss(module, batch, ctx)) == {"total", "rec", "arap", "trans"}
    before, after, norm, decoder_norm = after_descent(st, module, batch, ctx, term, part="decoder.")
    assert decoder_norm == pytest.approx(norm)  # nothing else trains
    assert after < before - 0.5 * 1e-4 * norm, (before, after, norm)


def test_zero_decoder_epochs_keep_the_joint_weights(small_zoo, tmp_path):
    from safetensors.torch import load_file

    from mimicbench.training.loop import train_stage

    cfg = tiny_decoder_config(epochs=0)
    joint = train_stage("sfpt", "sfpt", small_zoo, tmp_path, cfg, epochs=1, progress=False)
    kept = train_stage("sfpt", "decoder", small_zoo, tmp_path, cfg, progress=False)
    a, b = load_file(str(joint)), load_file(str(kept))
    assert all(torch.equal(a[k], b[k]) for k in a)


def test_shipped_decoder_reads_the_target_and_is_not_the_bare_kabsch_fit(small_zoo):
    """On a zoo character posed by its rig: the shipped decoder's answer keeps the Kabsch translations, turns
    the handles away from the Kabsch rotations (the ``sfpt_kabsch_only`` switch changes the output), and
    changes with the target's shape code."""
    from mimicbench.baselines.pose_pairs import PosePool
    from mimicbench.baselines.sfpt.method import Sfpt
    from mimicbench.baselines.sfpt.frame import unit_frame
    from mimicbench.baselines.sfpt.mesh_graph import vertex_normals

    method = Sfpt()
    method.setup("cpu")
    pool = PosePool.load(small_zoo)
    a, b = pool.ids[0], pool.ids[1]
    r = pool.records[a]
    posed_np = pool.posed(a, pool.draw_pose(a, np.random.default_rng(3)))
    s = method._character(r.vertices, r.faces, (a, len(r.vertices)))
    t = method._character(pool.records[b].vertices, pool.records[b].faces, (b, len(pool.records[b].vertices)))
    posed = torch.as_tensor(unit_frame(posed_np, r.vertices))
    normals = (s["normals"], vertex_normals(posed, s["faces"]))
    with torch.no_grad():
        args = (s["rest"], posed, normals, s["weights"], s["edges"])
        fit = method.module.predict(*args, s["code"], kabsch_only=True)
        own = method.module.predict(*args, s["code"])
        other = method.module.predict(*args, t["code"])
    torch.testing.assert_close(own[:, :3], fit[:, :3], rtol=0, atol=0)
    assert float((own[:, 3:] - fit[:, 3:]).abs().max()) > 1e-3
    assert float((own - other).abs().max()) > 1e-4
