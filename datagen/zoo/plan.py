"""What a zoo holds: characters per category, each one's seed and variant, and its split.

Counts per category follow :data:`SHARES` (largest remainder, at least one character of every
requested category once N allows). Within the humanoid category the first ``ceil(0.75 n)``
characters form the H2H family (one shared skeleton). Every character gets its own random
stream from ``(seed, category number, index)``, so adding characters never changes earlier ones.

Splits (stratified, deterministic): a plain 80/10/10 hash of the ID can leave no H2H family
member in ``test`` in a small zoo, and the benchmark draws its h2h cases from ``test``. So per
stratum (each category, with the H2H family its own stratum) the IDs are sorted by the sha256
of the ID; the first ``max(1, round(0.1 n))`` go to ``test`` (for the H2H family at least
``min(3, n - 1)``, and all of a stratum of one), the next ``round(0.1 n)`` to ``val``, the rest to
``train``. See :func:`assign_splits`.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass

from mimicbench.datagen.zoo.templates import ZOO_CATEGORIES

SHARES = {"humanoid": 0.3, "apparel": 0.15, "quadruped": 0.15, "bird": 0.1, "fish": 0.1, "reptile": 0.1,
          "insect": 0.1}
FAMILY_SHARE = 0.75
FAMILY_MIN_TEST = 3


@dataclass(frozen=True)
class CharacterSpec:
    """One character to build: its ID, category, index within the category and random stream."""

    character_id: str
    category: str
    index: int
    seed: int
    family: bool = False

    @property
    def entropy(self) -> tuple[int, int, int]:
        return (self.seed, ZOO_CATEGORIES.index(self.category), self.index)


def category_counts(n: int, categories: list[str] | None = None) -> dict[str, int]:
    """Characters per category for a zoo of ``n`` (largest remainder of :data:`SHARES`)."""
    cats = list(categories or ZOO_CATEGORIES)
    unknown = [c for c in cats if c not in SHARES]
    if unknown:
        raise ValueError(f"categories: unknown {unknown}; expected some of {list(SHARES)}")
    if n < 0:
        raise ValueError(f"num_characters: expected >= 0, got {n}")
    total = sum(SHARES[c] for c in cats)
    exact = {c: n * SHARES[c] / total for c in cats}
    counts = {c: int(math.floor(v)) for c, v in exact.items()}
    if n >= len(cats):  # every category at least once
        for c in cats:
            if counts[c] == 0:
                counts[c] = 1
    order = sorted(cats, key=lambda c: (-(exact[c] - math.floor(exact[c])), cats.index(c)))
    i = 0
    while sum(counts.values()) < n:
        counts[order[i % len(order)]] += 1
        i += 1
    while sum(counts.values()) > n:  # the minimum-one rule took too many: trim the biggest
        big = max(cats, key=lambda c: (counts[c], -cats.index(c)))
        counts[big] -= 1
    return {c: counts[c] for c in cats}


def plan_zoo(n: int, seed: int = 0, categories: list[str] | None = None) -> list[CharacterSpec]:
    """The characters of a zoo, in category order then index."""
    specs = []
    for cat, count in category_counts(n, categories).items():
        family = math.ceil(FAMILY_SHARE * count) if cat == "humanoid" else 0
        for i in range(count):
            specs.append(CharacterSpec(f"zoo/{cat}-{i:04d}", cat, i, seed, family=i < family))
    return specs


def _sha(cid: str) -> str:
    return hashlib.sha256(cid.encode()).hexdigest()


def assign_splits(specs: list[CharacterSpec]) -> dict[str, str]:
    """Character ID -> ``train``/``val``/``test`` by the stratified rule in the module docstring."""
    strata: dict[str, list[str]] = {}
    for s in specs:
        strata.setdefault("h2h" if s.family else s.category, []).append(s.character_id)
    out = {}
    for name, ids in strata.items():
        ids = sorted(ids, key=_sha)
        n = len(ids)
        n_test = max(1, round(0.1 * n))
        if name == "h2h":
            n_test = max(n_test, min(FAMILY_MIN_TEST, n - 1))
        n_test = min(max(n_test, 1), n)
        n_val = min(round(0.1 * n), n - n_test)
        for i, cid in enumerate(ids):
            out[cid] = "test" if i < n_test else ("val" if i < n_test + n_val else "train")
    return out
