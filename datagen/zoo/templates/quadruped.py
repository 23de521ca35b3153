"""Quadruped template: pelvis, spine and chest along +Z, neck, head, jaw, ears, tail, four legs.

Varies body length, leg length, girth, neck and tail segments, head size and whether legs have a
toe joint. Stands on Y = 0 facing +Z.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.zoo.skeleton import SIDES, SkeletonBuilder, arc_points


def quadruped_params(rng: np.random.Generator, variant: int) -> dict:
    return {"size": float(rng.uniform(0.5, 1.6)), "body": float(rng.uniform(0.8, 1.3)),
            "legs": float(rng.uniform(0.7, 1.3)), "girth": float(rng.uniform(0.8, 1.3)),
            "spine": int(rng.integers(2, 5)), "neck": int(rng.integers(1, 4)), "tail": int(rng.integers(2, 9)),
            "head": float(rng.uniform(0.8, 1.3)), "toes": bool(variant % 2 == 0), "ears": bool(rng.random() < 0.7)}


def build_quadruped(b: SkeletonBuilder, p: dict) -> dict:
    S, g = p["size"], p["girth"]
    leg_h = 0.55 * S * p["legs"]
    body = 0.8 * S * p["body"]
    r_body = 0.17 * S * g
    z0 = -body / 2
    hips = b.add("hips", -1, (0, leg_h, z0), (0, leg_h + 0.02 * S, z0 + body / (p["spine"] + 1)),
                 r_body, r_body, aspect=(0.9, 1.0), limit=0.3)
    pts = np.linspace([0, leg_h + 0.02 * S, z0 + body / (p["spine"] + 1)], [0, leg_h + 0.04 * S, body / 2],
                      p["spine"] + 1)
    spine = b.chain([f"spine/{i + 1}" for i in range(p["spine"])], hips, pts, [r_body] * (p["spine"] + 1),
                    aspect=(0.9, 1.0), limit=0.3)
    chest = spine[-1]
    neck_len = 0.35 * S
    npts = arc_points(pts[-1], [np.array([0, 0.7, 0.7]) * neck_len / p["neck"]] * p["neck"])
    neck = b.chain([f"neck/{i + 1}" for i in range(p["neck"])], chest, npts,
                   list(np.linspace(0.1 * S * g, 0.07 * S * g, p["neck"] + 1)), limit=0.45)
    hr = 0.1 * S * p["head"]
    head_tail = npts[-1] + np.array([0, 0.02, 1.0]) * 2.2 * hr
    head = b.add("head", neck[-1], npts[-1], head_tail, hr, 0.6 * hr, limit=0.5)
    b.add("jaw", head, npts[-1] + np.array([0, -0.4 * hr, 0.2 * hr]), head_tail + np.array([0, -0.5 * hr, 0]),
          0.5 * hr, 0.35 * hr, aspect=(1.0, 0.6), limit=0.3)
    if p["ears"]:
        for side, s in SIDES:
            base = npts[-1] + np.array([s * 0.6 * hr, 0.7 * hr, 0.2 * hr])
            b.add(f"{side}/ear", head, base, base + np.array([s * 0.3, 1.0, -0.2]) * 0.9 * hr, 0.25 * hr, 0.1 * hr,
                  aspect=(1.0, 0.4), side_ref=(0, 0, 1), limit=0.4)
    tail_len = 0.6 * S
    tpts = arc_points((0, leg_h + 0.05 * S, z0 - 0.8 * r_body),
                      [np.array([0, -0.3, -1.0]) / 1.044 * tail_len / p["tail"]] * p["tail"])
    b.chain([f"tail/{i + 1}" for i in range(p["tail"])], hips, tpts,
            list(np.linspace(0.05 * S * g, 0.015 * S, p["tail"] + 1)), limit=0.5)
    nseg = 4 if p["toes"] else 3
    for part, parent, z in (("front_leg", chest, body / 2 - 0.3 * r_body), ("hind_leg", hips, z0 + 0.3 * r_body)):
        for side, s in SIDES:
            x = s * 0.55 * r_body
            top = np.array([x, leg_h, z])
            ys = [leg_h, 0.55 * leg_h, 0.18 * leg_h, 0.03 * S][:nseg] + [0.01 * S]
            zs = [z, z + (0.04 if part == "hind_leg" else -0.03) * S, z - 0.02 * S, z + 0.03 * S][:nseg] + [z + 0.1 * S]
            if not p["toes"]:
                ys = [leg_h, 0.5 * leg_h, 0.06 * S, 0.02 * S]
                zs = [z, z + 0.02 * S, z - 0.01 * S, z + 0.09 * S]
            legpts = [(x, y, zz) for y, zz in zip(ys, zs)]
            legpts[0] = top
            rr = list(np.linspace(0.08 * S * g, 0.035 * S * g, nseg + 1))
            b.chain([f"{side}/{part}/{i + 1}" for i in range(nseg)], parent, legpts, rr, limit=0.8)
    return {"hips": hips}
