"""Fish template: body root, spine to the head, tail chain to a tail fin, pectoral and dorsal fins.

The smallest variant has 11 joints. Varies length, depth, spine and tail segments, fin sizes.
Floats at Y = body depth, faces +Z; the body is flattened sideways.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.zoo.skeleton import SIDES, SkeletonBuilder, arc_points


def fish_params(rng: np.random.Generator, variant: int) -> dict:
    small = variant % 3 == 0
    return {"length": float(rng.uniform(0.3, 1.4)), "depth": float(rng.uniform(0.18, 0.32)),
            "spine": 1 if small else int(rng.integers(1, 4)), "tail": 4 if small else int(rng.integers(4, 10)),
            "fin": float(rng.uniform(0.7, 1.4)), "pelvic": not small}


def build_fish(b: SkeletonBuilder, p: dict) -> dict:
    L = p["length"]
    d = p["depth"] * L
    y = d
    front = 0.45 * L
    root = b.add("root", -1, (0, y, 0), (0, y, front / (p["spine"] + 1)), 0.5 * d, 0.5 * d,
                 aspect=(0.55, 1.0), limit=0.3)
    spts = np.linspace([0, y, front / (p["spine"] + 1)], [0, y, front], p["spine"] + 1)
    spine = b.chain([f"spine/{i + 1}" for i in range(p["spine"])], root, spts,
                    list(np.linspace(0.5 * d, 0.42 * d, p["spine"] + 1)), aspect=(0.55, 1.0), limit=0.3)
    b.add("head", spine[-1], spts[-1], spts[-1] + np.array([0, -0.02, 0.2]) * L, 0.42 * d, 0.15 * d,
          aspect=(0.6, 1.0), limit=0.3)
    n = p["tail"]
    tpts = arc_points((0, y, 0), [np.array([0, 0, -0.5 * L / n])] * n)
    tail = b.chain([f"tail/{i + 1}" for i in range(n)], root, tpts, list(np.linspace(0.5 * d, 0.1 * d, n + 1)),
                   aspect=(0.55, 1.0), limit=0.45)
    f = p["fin"]
    b.add("tail_fin", tail[-1], tpts[-1], tpts[-1] + np.array([0, 0, -0.16 * L * f]), 0.1 * d, 0.35 * d * f,
          aspect=(0.25, 1.0), limit=0.5)
    for side, s in SIDES:
        base = spts[0] + np.array([s * 0.22 * d, -0.25 * d, 0])
        b.add(f"{side}/fin", root, base, base + np.array([s * 0.6, -0.3, -0.5]) * 0.25 * L * f, 0.1 * d, 0.03 * d,
              aspect=(2.5, 0.4), side_ref=(0, 0, 1), limit=0.6)
        if p["pelvic"]:
            base = np.array([s * 0.15 * d, y - 0.4 * d, -0.1 * L])
            b.add(f"{side}/pelvic_fin", root, base, base + np.array([s * 0.3, -0.6, -0.5]) * 0.12 * L * f,
                  0.06 * d, 0.02 * d, aspect=(2.0, 0.4), side_ref=(0, 0, 1), limit=0.6)
    base = np.array([0, y + 0.45 * d, 0.05 * L])
    b.add("dorsal_fin", root, base, base + np.array([0, 0.5, -0.6]) * 0.25 * L * f, 0.12 * d, 0.03 * d,
          aspect=(0.3, 1.0), side_ref=(1, 0, 0), limit=0.4)
    return {"root": root}
