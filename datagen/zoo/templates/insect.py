"""Insect or spider template: thorax, abdomen chain, head with antennae, 6 or 8 splayed legs.

Insects (variant even): head, two 3-5 joint antennae, 3 leg pairs of 4 joints. Spiders (odd):
fangs instead of antennae, 4 leg pairs. Legs are numbered front to back: ``left/leg/2/3`` is the
third joint of the second left leg. Stands on Y = 0 facing +Z.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.zoo.skeleton import SIDES, SkeletonBuilder, arc_points


def insect_params(rng: np.random.Generator, variant: int) -> dict:
    spider = variant % 2 == 1
    return {"spider": spider, "size": float(rng.uniform(0.1, 0.6)), "legs": float(rng.uniform(0.8, 1.5)),
            "abdomen": int(rng.integers(1, 5)), "antenna": int(rng.integers(3, 6)), "girth": float(rng.uniform(0.8, 1.3))}


def build_insect(b: SkeletonBuilder, p: dict) -> dict:
    S, g = p["size"], p["girth"]
    ll = 0.45 * S * p["legs"]
    y = 0.35 * ll + 0.1 * S
    r = 0.12 * S * g
    thorax = b.add("thorax", -1, (0, y, 0), (0, y, 0.3 * S), r, 0.9 * r, aspect=(1.0, 0.8), limit=0.2)
    head = b.add("head", thorax, (0, y, 0.3 * S), (0, y, 0.48 * S), 0.8 * r, 0.6 * r, limit=0.4)
    if p["spider"]:
        for side, s in SIDES:
            base = np.array([s * 0.3 * r, y - 0.3 * r, 0.44 * S])
            b.add(f"{side}/fang", head, base, base + np.array([0, -0.6, 0.6]) * 0.12 * S, 0.2 * r, 0.06 * r, limit=0.4)
    else:
        na = p["antenna"]
        for side, s in SIDES:
            base = np.array([s * 0.3 * r, y + 0.4 * r, 0.44 * S])
            apts = arc_points(base, [np.array([s * 0.35, 0.5, 0.8]) * 0.4 * S / na] * na)
            b.chain([f"{side}/antenna/{i + 1}" for i in range(na)], head, apts,
                    list(np.linspace(0.12 * r, 0.05 * r, na + 1)), limit=0.5)
    na = p["abdomen"]
    apts = arc_points((0, y, 0), [np.array([0, 0.05, -1.0]) * 0.7 * S / na] * na)
    radii = 1.3 * r * np.sin(np.linspace(0.35, 2.8, na + 1)) + 0.2 * r
    b.chain([f"abdomen/{i + 1}" for i in range(na)], thorax, apts, list(radii), limit=0.3)
    pairs = 4 if p["spider"] else 3
    for i in range(pairs):
        z = 0.3 * S * (0.85 - i / max(1, pairs - 1) * 0.85)
        fan = np.radians(40 - 80 * i / max(1, pairs - 1))
        for side, s in SIDES:
            d = np.array([s * np.cos(fan), 0, np.sin(fan)])
            top = np.array([s * 0.8 * r, y - 0.2 * r, z])
            steps = [0.25 * ll * d + (0, 0.08 * ll, 0), 0.45 * ll * d + (0, 0.2 * ll, 0),
                     0.25 * ll * d - (0, y + 0.28 * ll - 0.2 * r - 0.01 * S, 0), 0.15 * ll * d - (0, 0, 0)]
            lpts = arc_points(top, steps)
            lpts[-1, 1] = max(lpts[-1, 1], 0.005 * S)
            b.chain([f"{side}/leg/{i + 1}/{j + 1}" for j in range(4)], thorax, lpts,
                    list(np.array([0.22, 0.18, 0.13, 0.08, 0.04]) * r), limit=0.6)
    return {"thorax": thorax}
