import numpy as np
import torch

from mimicbench.datagen.correspond.encoders import ClipEncoder, get_encoder


def test_minilm_ships_its_weights_and_separates_limbs_from_tails():
    enc = get_encoder("minilm")
    e = enc.embed(["left arm", "left wing", "tail"])
    np.testing.assert_allclose(np.linalg.norm(e, axis=1), 1.0, atol=1e-5)
    assert e[0] @ e[1] > e[0] @ e[2]
    assert "all-MiniLM-L6-v2" in enc.name


def test_clip_runs_open_clip_model_code_with_random_and_local_checkpoint(tmp_path):
    random = ClipEncoder("ViT-B-32", pretrained=None)
    e = random.embed(["left upper arm", "tail 3"])
    assert e.shape == (2, 512) and np.isfinite(e).all()
    ckpt = tmp_path / "clip.pt"
    torch.save(random.model.state_dict(), ckpt)
    loaded = ClipEncoder("ViT-B-32", pretrained=str(ckpt))
    np.testing.assert_allclose(loaded.embed(["left upper arm", "tail 3"]), e, atol=1e-5)
    assert "clip:ViT-B-32" in loaded.name
