"""Deterministic choice of character pairs within each split.

``--all-pairs`` gives every ordered pair (a, b), a != b, of one split: n (n - 1) pairs for n
characters. With ``--unordered`` each unordered pair comes once, as (a, b) with a's ID before
b's: n (n - 1) / 2 pairs. (PokeAnimDB's 384k pairs equal C(877, 2) = 384,126, the unordered pairs
among 877 characters, 90% of its 975: one split of 90%, one direction a pair. The zoo's 80/10/10
splits give 777, 99 and 99 characters: 622,356 ordered pairs, 311,178 unordered.) Otherwise N pairs
are drawn without replacement with a seeded generator, half within a category and half across
categories (``INTRA_FRACTION``), falling back to the other kind when one runs short.
"""
from __future__ import annotations

import itertools

import numpy as np

INTRA_FRACTION = 0.5


def sample_pairs(characters: list, num_pairs: int | None, all_pairs: bool, seed: int = 0,
                 unordered: bool = False, keep=None) -> list[tuple]:
    """(source, target) pairs of records from one split, in a deterministic order: ordered pairs, or
    with ``unordered`` one (a, b) a pair of characters, a's ID before b's. ``keep(a, b)``, when
    given, chooses the candidate pairs (``--pairs-across-splits``: characters of different splits)."""
    chars = sorted(characters, key=lambda c: c.character_id)
    every = list((itertools.combinations if unordered else itertools.permutations)(chars, 2))
    if keep is not None:
        every = [(a, b) for a, b in every if keep(a, b)]
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
