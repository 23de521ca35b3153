"""Apparel humanoid: a humanoid plus apparel bone chains (skirt, long hair, cape, coat tails).

Variants (by index, so a zoo always holds the heavy one): 0 = fingers, long hair, skirt and a
short cape (over 200 joints); 1 = cape and short hair; 2 = coat tails, ponytail and a short
skirt; 3 = everything at once (fingers, long hair, skirt, a long cape, coat tails and a long
ponytail: 236-241 joints, PokeAnimDB's largest skeleton has 241). Apparel joints carry roles
``apparel/<kind>/<chain>/<segment>``.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.zoo.skeleton import SkeletonBuilder
from mimicbench.datagen.zoo.templates.humanoid import build_humanoid, humanoid_params

VARIANTS = (
    {"fingers": 5, "hair": (16, 6), "skirt": (12, 4), "cape": (3, 5), "tails": None, "ponytail": None},
    {"fingers": 0, "hair": (6, 3), "skirt": None, "cape": (5, 5), "tails": None, "ponytail": None},
    {"fingers": 3, "hair": None, "skirt": (8, 3), "cape": None, "tails": (2, 5), "ponytail": 6},
    {"fingers": 5, "hair": (16, 6), "skirt": (12, 4), "cape": (5, 5), "tails": (2, 5), "ponytail": 9},
)


def apparel_params(rng: np.random.Generator, variant: int) -> dict:
    v = VARIANTS[variant % len(VARIANTS)]
    p = humanoid_params(rng, {"spine": int(rng.integers(2, 5)), "fingers": v["fingers"],
                              "pose": str(rng.choice(["T", "A"]))})
    p.update({k: v[k] for k in ("hair", "skirt", "cape", "tails", "ponytail")})
    p["variant"] = variant % len(VARIANTS)
    p["flare"] = float(rng.uniform(0.1, 0.45))
    p["hair_len"] = float(rng.uniform(0.18, 0.32))
    return p


def _hang(b: SkeletonBuilder, kind: str, chain: int, parent: int, start, step, n: int, r: float,
          side_ref, aspect=(2.2, 0.45)) -> None:
    pts = [np.asarray(start, float) + i * np.asarray(step, float) for i in range(n + 1)]
    radii = list(np.linspace(r, 0.8 * r, n + 1))
    b.chain([f"apparel/{kind}/{chain}/{i + 1}" for i in range(n)], parent, pts, radii,
            aspect=aspect, side_ref=side_ref, apparel=True, limit=0.6)


def build_apparel(b: SkeletonBuilder, p: dict) -> dict:
    """Add the humanoid and its apparel chains to ``b``."""
    lm = build_humanoid(b, p)
    H = lm["height"]
    if p["skirt"]:
        n, segs = p["skirt"]
        length = 0.22 * H if segs >= 4 else 0.14 * H
        R = lm["hip_half_width"] * 0.95
        for c in range(n):
            a = 2 * np.pi * (c + 0.5) / n
            out = np.array([np.sin(a), 0, np.cos(a)])
            start = np.array([0, lm["hip_y"] + 0.02 * H, 0]) + R * out * np.array([1, 0, 0.75])
            step = (np.array([0, -1.0, 0]) + p["flare"] * out) * length / segs
            _hang(b, "skirt", c + 1, lm["hips"], start, step, segs, 0.018 * H,
                  side_ref=(-out[2], 0, out[0]), aspect=(2.0 * 6 / max(n, 6) * 1.6, 0.4))
    if p["hair"]:
        n, segs = p["hair"]
        hr = lm["head_radius"]
        center = np.array([0, 0.875 * H + 0.8 * hr, 0])
        for c in range(n):
            a = np.pi * (0.15 + 0.7 * c / max(1, n - 1))  # around the back of the head, left to right
            out = np.array([np.cos(a), 0.2, -np.sin(a)])
            out /= np.linalg.norm(out)
            start = center + 0.95 * hr * out
            step = np.array([0.15 * out[0], -1.0, -0.1]) * p["hair_len"] * H / segs
            _hang(b, "hair", c + 1, lm["head"], start, step, segs, 0.011 * H,
                  side_ref=(-out[2], 0, out[0]), aspect=(1.6, 0.5))
    if p["cape"]:
        n, segs = p["cape"]
        for c in range(n):
            x = (c - (n - 1) / 2) * 0.16 * H / max(1, n - 1) * 2
            start = np.array([x, 0.79 * H, -lm["chest_depth"] - 0.01 * H])
            step = np.array([0.15 * x, -1.0, -0.12]) * 0.42 * H / segs
            _hang(b, "cape", c + 1, lm["chest"], start, step, segs, 0.014 * H, side_ref=(1, 0, 0),
                  aspect=(2.6 * 3 / max(n, 3), 0.35))
    if p["tails"]:
        n, segs = p["tails"]
        for c in range(n):
            x = (c - (n - 1) / 2) * 0.1 * H
            start = np.array([x, lm["hip_y"] + 0.03 * H, -0.07 * H])
            step = np.array([0.2 * x, -1.0, -0.15]) * 0.3 * H / segs
            _hang(b, "coat_tail", c + 1, lm["hips"], start, step, segs, 0.016 * H, side_ref=(1, 0, 0),
                  aspect=(2.2, 0.4))
    if p["ponytail"]:
        segs = p["ponytail"]
        hr = lm["head_radius"]
        start = np.array([0, 0.875 * H + 1.2 * hr, -0.9 * hr])
        step = np.array([0, -0.7, -0.5]) * 0.3 * H / segs
        _hang(b, "ponytail", 1, lm["head"], start, step, segs, 0.016 * H, side_ref=(1, 0, 0), aspect=(1.2, 0.9))
    return lm
