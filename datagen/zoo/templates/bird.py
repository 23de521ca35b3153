"""Bird template: body, spine, neck chain, head and beak, two wings of 3-4 joints, legs with toes, tail.

Varies body size, wing span, neck length and segments, leg length and tail feathers. Wings
spread along +-X at rest (a flight T-pose). Stands on Y = 0 facing +Z.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.zoo.skeleton import SIDES, SkeletonBuilder, arc_points


def bird_params(rng: np.random.Generator, variant: int) -> dict:
    return {"size": float(rng.uniform(0.25, 0.9)), "span": float(rng.uniform(0.8, 1.6)),
            "neck": int(rng.integers(2, 6)), "neck_len": float(rng.uniform(0.6, 1.6)),
            "legs": float(rng.uniform(0.6, 1.5)), "tail": int(rng.integers(1, 4)),
            "wing": 3 + int(variant % 2), "spine": int(rng.integers(1, 3))}


def build_bird(b: SkeletonBuilder, p: dict) -> dict:
    S = p["size"]
    leg_h = 0.35 * S * p["legs"]
    r = 0.16 * S
    body_y = leg_h + r
    hips = b.add("hips", -1, (0, body_y, -0.15 * S), (0, body_y + 0.03 * S, 0.0), r, r,
                 aspect=(0.9, 1.0), limit=0.3)
    pts = np.linspace([0, body_y + 0.03 * S, 0.0], [0, body_y + 0.1 * S, 0.2 * S], p["spine"] + 1)
    spine = b.chain([f"spine/{i + 1}" for i in range(p["spine"])], hips, pts,
                    list(np.linspace(r, 0.8 * r, p["spine"] + 1)), aspect=(0.9, 1.0), limit=0.3)
    chest = spine[-1]
    nl = 0.35 * S * p["neck_len"]
    npts = arc_points(pts[-1], [np.array([0, 0.85, 0.5]) * nl / p["neck"]] * p["neck"])
    neck = b.chain([f"neck/{i + 1}" for i in range(p["neck"])], chest, npts,
                   list(np.linspace(0.06 * S, 0.04 * S, p["neck"] + 1)), limit=0.5)
    hr = 0.07 * S
    head = b.add("head", neck[-1], npts[-1], npts[-1] + np.array([0, 0.1, 1.0]) * 1.5 * hr, hr, 0.8 * hr, limit=0.5)
    tip = npts[-1] + np.array([0, 0.1, 1.0]) * 1.5 * hr
    b.add("beak", head, tip, tip + np.array([0, -0.2, 1.0]) * 1.6 * hr, 0.45 * hr, 0.1 * hr, limit=0.2)
    span = 0.5 * S * p["span"]
    nw = p["wing"]
    lengths = np.array([0.3, 0.35, 0.35] if nw == 3 else [0.25, 0.3, 0.25, 0.2]) * span
    for side, s in SIDES:
        start = pts[-1] + np.array([s * 0.6 * r, 0.02 * S, -0.02 * S])
        wpts = arc_points(start, [np.array([s * L, 0, -0.1 * L]) for L in lengths])
        b.chain([f"{side}/wing/{i + 1}" for i in range(nw)], chest, wpts,
                list(np.linspace(0.06 * S, 0.02 * S, nw + 1)), aspect=(1.0, 0.3), side_ref=(0, 0, 1), limit=1.0)
        x = s * 0.45 * r
        lpts = [(x, body_y - 0.5 * r, -0.08 * S), (x, 0.5 * leg_h, -0.02 * S), (x, 0.06 * S, -0.05 * S),
                (x, 0.02 * S, 0.02 * S), (x, 0.012 * S, 0.12 * S)]
        b.chain([f"{side}/leg/{i + 1}" for i in range(4)], hips, lpts, [0.045 * S, 0.03 * S, 0.018 * S, 0.014 * S,
                                                                        0.01 * S], limit=0.8)
    tpts = arc_points((0, body_y, -0.15 * S - 0.8 * r), [np.array([0, 0.15, -1.0]) * 0.12 * S] * p["tail"])
    b.chain([f"tail/{i + 1}" for i in range(p["tail"])], hips, tpts,
            list(np.linspace(0.06 * S, 0.03 * S, p["tail"] + 1)), aspect=(2.0, 0.3), side_ref=(1, 0, 0), limit=0.4)
    return {"hips": hips}
