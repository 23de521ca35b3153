"""One correspondence on the fly, from two bone-name lists or two skeletons (as ``pairs/`` stores it)."""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.correspond.batched import DEFAULT_TEMPERATURE, correspondence_batch
from mimicbench.datagen.correspond.canonical import canonicalize_names
from mimicbench.datagen.correspond.encoders import get_encoder
from mimicbench.datagen.correspond.methods import DEFAULT_METHOD, get_matcher, match_batch
from mimicbench.datagen.correspond.structure import skeleton_features


def _embed_cached(enc, texts: list[str]) -> dict[str, np.ndarray]:
    """Embeddings of ``texts`` by ``enc``, remembering every text the encoder has seen."""
    cache = _EMBEDDING_CACHE.setdefault(enc.name, {})
    missing = sorted(set(texts) - cache.keys())
    if missing:
        cache.update(zip(missing, enc.embed(missing)))
    return cache


_EMBEDDING_CACHE: dict[str, dict[str, np.ndarray]] = {}


def correspondence_for_names(names_a, names_b, encoder: str = "minilm", temperature: float = DEFAULT_TEMPERATURE,
                             clip_model: str = "ViT-B-32", clip_pretrained: str | None = None):
    """One pair on the fly from two bone-name lists, by the text-only method (names are all it has).

    Returns S_cos (K1, K2) float32, Hungarian pairs (min(K1, K2), 2) int32 and M_sink (K1, K2)
    float32, as stored in ``pairs/`` by ``--method text``. The encoder and each canonical name's
    embedding are cached, so repeated calls cost only the matrices. With the skeletons at hand,
    :func:`correspondence_for_skeletons` gives the structure-aware default.
    """
    enc = get_encoder(encoder, clip_model, clip_pretrained)
    ca, cb = canonicalize_names(list(names_a)), canonicalize_names(list(names_b))
    if not ca or not cb:
        raise ValueError(f"names_a, names_b: expected non-empty name lists, got {len(ca)} and {len(cb)} names")
    table = _embed_cached(enc, ca + cb)
    return correspondence_batch([np.stack([table[t] for t in ca])], [np.stack([table[t] for t in cb])], temperature)[0]


def correspondence_for_skeletons(names_a, parents_a, keypoints_a, names_b, parents_b, keypoints_b,
                                 method: str = DEFAULT_METHOD, encoder: str = "minilm",
                                 temperature: float | None = None, no_match: float | None = None,
                                 clip_model: str = "ViT-B-32", clip_pretrained: str | None = None):
    """One pair on the fly from two skeletons: names (K,), parents (K,) and rest keypoints (K, 3).

    Returns S_cos (K1, K2), Hungarian pairs (P, 2) int32 and M_sink (K1, K2) as ``pairs/`` stores
    them for ``method`` (``structure`` by default, or ``text``).
    """
    m = get_matcher(method, temperature, no_match)
    enc = get_encoder(encoder, clip_model, clip_pretrained)
    ca, cb = canonicalize_names(list(names_a)), canonicalize_names(list(names_b))
    if not ca or not cb:
        raise ValueError(f"names_a, names_b: expected non-empty name lists, got {len(ca)} and {len(cb)} names")
    table = _embed_cached(enc, ca + cb)
    ea, eb = [np.stack([table[t] for t in ca])], [np.stack([table[t] for t in cb])]
    if not m.uses_structure:
        return match_batch(m, ea, eb)[0]
    fa = skeleton_features(ca, parents_a, keypoints_a).matrix()
    fb = skeleton_features(cb, parents_b, keypoints_b).matrix()
    return match_batch(m, ea, eb, [fa], [fb])[0]
