"""Ground-truth correspondences between characters' keypoints (MimiCAT Sec. 3, and beyond).

Bone names are canonicalised (:mod:`.canonical`), embedded with a text encoder
(:mod:`.encoders`: MiniLM offline by default, CLIP through open_clip) and compared by cosine
similarity S_cos. The method (:mod:`.methods`) is chosen by name: ``text`` is the paper's
(S_cos, Hungarian M_hung, Sinkhorn M_sink); ``structure`` (the default) adds what the skeleton
says (:mod:`.structure`) and a no-match threshold. Matrices are computed in batches
(:mod:`.batched`) for sampled or all pairs of each split (:mod:`.sampling`), and scored against
the zoo's hidden bone roles (:mod:`.report`) through the cross-category role map (:mod:`.roles`).
"""
from __future__ import annotations

import importlib

_LAZY = {
    "canonicalize_bone_name": "datagen.correspond.canonical",
    "canonicalize_names": "datagen.correspond.canonical",
    "correspond_dataset": "datagen.correspond.stage",
    "correspondence_for_names": "datagen.correspond.pair",
    "correspondence_for_skeletons": "datagen.correspond.pair",
    "get_matcher": "datagen.correspond.methods",
}
__all__ = sorted(_LAZY)


def __getattr__(name: str):
    """Import the public functions on first use, so the CLI starts fast."""
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
