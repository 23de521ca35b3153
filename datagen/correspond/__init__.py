"""Text-guided ground-truth correspondences between characters' keypoints (MimiCAT Sec. 3).

Bone names are canonicalised (:mod:`.canonical`), embedded with a text encoder
(:mod:`.encoders`: MiniLM offline by default, CLIP through open_clip), compared by cosine
similarity S_cos, matched one-to-one by the Hungarian algorithm (M_hung) and softly by Sinkhorn
(M_sink) in batches (:mod:`.batched`), for sampled or all pairs of each split (:mod:`.sampling`),
and scored against the zoo's hidden bone roles (:mod:`.report`).
"""
from __future__ import annotations

import importlib

_LAZY = {
    "canonicalize_bone_name": "datagen.correspond.canonical",
    "canonicalize_names": "datagen.correspond.canonical",
    "correspond_dataset": "datagen.correspond.stage",
    "correspondence_for_names": "datagen.correspond.stage",
}
__all__ = sorted(_LAZY)


def __getattr__(name: str):
    """Import the public functions on first use, so the CLI starts fast."""
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
