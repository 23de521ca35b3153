"""Deterministic choice of character pairs within each split.

``--all-pairs`` gives every ordered pair (a, b), a != b, of one split. Otherwise N ordered pairs
are drawn without replacement with a seeded generator, half within a category and half across
categories (``INTRA_FRACTION``), falling back to the other kind when one runs short.
"""
from __future__ import annotations

import itertools

import numpy as np

INTRA_FRACTION = 0.5


def sample_pairs(characters: list, num_pairs: int | None, all_pairs: bool, seed: int = 0) -> list[tuple]:
    """Ordered (source, target) pairs of records from one split, in a deterministic order."""
    chars = sorted(characters, key=lambda c: c.character_id)
    every = [(a, b) for a, b in itertools.permutations(chars, 2)]
    if all_pairs or num_pairs is None or num_pairs >= len(every):
        return every
    rng = np.random.default_rng(seed)
    intra = [p for p in every if p[0].category == p[1].category]
    cross = [p for p in every if p[0].category != p[1].category]
    want_intra = min(len(intra), int(round(num_pairs * INTRA_FRACTION)))
    want_cross = min(len(cross), num_pairs - want_intra)
    want_intra = min(len(intra), num_pairs - want_cross)
    pick = [intra[i] for i in rng.choice(len(intra), want_intra, replace=False)] if want_intra else []
    pick += [cross[i] for i in rng.choice(len(cross), want_cross, replace=False)] if want_cross else []
    return sorted(pick, key=lambda p: (p[0].character_id, p[1].character_id))
