"""Reptile template: a snake (long spine, head, jaw) or a lizard (four splayed legs, long tail).

Snakes have 12-60 spine joints; lizards 2-4 spine joints, a 5-14 joint tail and 3-4 joint legs.
Lies on Y = 0 facing +Z.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.zoo.skeleton import SIDES, SkeletonBuilder, arc_points


def reptile_params(rng: np.random.Generator, variant: int) -> dict:
    snake = variant % 2 == 0
    return {"snake": snake, "length": float(rng.uniform(0.8, 2.5) if snake else rng.uniform(0.4, 1.2)),
            "girth": float(rng.uniform(0.7, 1.3)),
            "spine": int(rng.integers(12, 61)) if snake else int(rng.integers(2, 5)),
            "tail": 0 if snake else int(rng.integers(5, 15)), "legs": float(rng.uniform(0.7, 1.3))}


def build_reptile(b: SkeletonBuilder, p: dict) -> dict:
    L, g = p["length"], p["girth"]
    if p["snake"]:
        r = 0.025 * L * g
        n = p["spine"]
        root = b.add("root", -1, (0, r, 0), (0, r, 0.04 * L), r, r, limit=0.3)
        b.add("head", root, (0, r, 0.04 * L), (0, r * 1.1, 0.09 * L), 1.2 * r, 0.6 * r, aspect=(1.3, 0.7), limit=0.4)
        b.add("jaw", 1, (0, 0.7 * r, 0.045 * L), (0, 0.6 * r, 0.085 * L), 0.8 * r, 0.4 * r,
              aspect=(1.3, 0.5), limit=0.3)
        pts = arc_points((0, r, 0), [np.array([0, 0, -0.95 * L / n])] * n)
        b.chain([f"spine/{i + 1}" for i in range(n)], root, pts, list(np.linspace(r, 0.25 * r, n + 1)), limit=0.35)
        return {"root": root}
    r = 0.06 * L * g
    leg_h = 0.6 * r + 0.06 * L * p["legs"]
    body = 0.35 * L
    hips = b.add("hips", -1, (0, leg_h, -body / 2), (0, leg_h, -body / 2 + body / (p["spine"] + 1)), r, r,
                 aspect=(1.3, 0.7), limit=0.3)
    pts = np.linspace([0, leg_h, -body / 2 + body / (p["spine"] + 1)], [0, leg_h, body / 2], p["spine"] + 1)
    spine = b.chain([f"spine/{i + 1}" for i in range(p["spine"])], hips, pts, [r] * (p["spine"] + 1),
                    aspect=(1.3, 0.7), limit=0.3)
    neck = b.add("neck", spine[-1], pts[-1], pts[-1] + (0, 0.01 * L, 0.06 * L), 0.8 * r, 0.7 * r, limit=0.4)
    head = b.add("head", neck, pts[-1] + (0, 0.01 * L, 0.06 * L), pts[-1] + (0, 0.01 * L, 0.2 * L), 0.8 * r,
                 0.35 * r, aspect=(1.2, 0.7), limit=0.4)
    b.add("jaw", head, pts[-1] + (0, -0.3 * r, 0.08 * L), pts[-1] + (0, -0.3 * r, 0.19 * L), 0.5 * r, 0.2 * r,
          aspect=(1.2, 0.5), limit=0.3)
    n = p["tail"]
    tpts = arc_points((0, leg_h, -body / 2), [np.array([0, -0.3 * leg_h / n, -0.45 * L / n])] * n)
    b.chain([f"tail/{i + 1}" for i in range(n)], hips, tpts, list(np.linspace(0.9 * r, 0.15 * r, n + 1)), limit=0.45)
    ll = 0.09 * L * p["legs"]
    for part, parent, z in (("front_leg", spine[-1], body / 2 - 0.02 * L), ("hind_leg", hips, -body / 2)):
        for side, s in SIDES:
            top = np.array([s * 0.9 * r, leg_h, z])
            lpts = arc_points(top, [(s * ll, 0, 0), (0.2 * s * ll, -(leg_h - 0.01 * L), 0.1 * ll),
                                    (s * 0.3 * ll, 0, 0.5 * ll)])
            b.chain([f"{side}/{part}/{i + 1}" for i in range(3)], parent, lpts, [0.4 * r, 0.3 * r, 0.22 * r, 0.15 * r,
                                                                              ][:4], limit=0.8)
    return {"hips": hips}
