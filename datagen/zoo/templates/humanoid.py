"""Humanoid template: hips, spine, neck, head, arms (fingers or not), legs; T-pose or A-pose.

Proportions come from ``params`` (see :func:`humanoid_params`); the H2H family uses one fixed
topology (:data:`H2H_TOPOLOGY`) so that all members share bone names and parents exactly.
The character stands on Y = 0, faces +Z, its left is +X.
"""
from __future__ import annotations

import numpy as np

from mimicbench.datagen.zoo.naming import FINGERS
from mimicbench.datagen.zoo.skeleton import SIDES, SkeletonBuilder

# The family skeleton: 3 spine joints, five three-joint fingers, T-pose, Mixamo names.
H2H_TOPOLOGY = {"spine": 3, "fingers": 5, "pose": "T", "style": "mixamo"}
H2H_SKELETON_ID = "zoo/h2h-humanoid-v1"


def humanoid_params(rng: np.random.Generator, topology: dict | None = None) -> dict:
    """Random proportions (and topology unless given): heights in metres, ratios near 1."""
    p = {
        "height": float(rng.uniform(1.45, 1.95)),
        "leg": float(rng.uniform(0.9, 1.12)),
        "arm": float(rng.uniform(0.88, 1.12)),
        "shoulder": float(rng.uniform(0.85, 1.2)),
        "girth": float(rng.uniform(0.75, 1.35)),
        "head": float(rng.uniform(0.85, 1.3)),
        "belly": float(rng.uniform(0.9, 1.3)),
    }
    if topology is None:
        topology = {"spine": int(rng.integers(2, 5)), "fingers": int(rng.choice([0, 3, 5])),
                    "pose": str(rng.choice(["T", "A"]))}
    p.update({k: v for k, v in topology.items() if k != "style"})
    return p


def build_humanoid(b: SkeletonBuilder, p: dict) -> dict:
    """Add a humanoid to builder ``b``; returns landmark joint indices and sizes for apparel."""
    H = p["height"]
    g = p["girth"]
    hip_y = 0.52 * H * p["leg"] / (0.48 + 0.52 * p["leg"])  # legs longer -> hips higher
    neck_y = 0.83 * H
    head_y = 0.875 * H
    hips = b.add("hips", -1, (0, hip_y, 0), (0, hip_y + 0.07 * H, 0), 0.1 * H * g, 0.095 * H * g,
                 aspect=(1.35, 0.85), limit=0.35)
    spine_pts = np.linspace(hip_y + 0.07 * H, neck_y, p["spine"] + 1)
    radii = 0.085 * H * g * np.interp(np.linspace(0, 1, p["spine"] + 1), [0, 0.4, 1], [p["belly"], 1.05, 1.0])
    spine = b.chain([f"spine/{i + 1}" for i in range(p["spine"])], hips,
                    [(0, y, 0) for y in spine_pts], list(radii), aspect=(1.3, 0.8), limit=0.35)
    chest = spine[-1]
    neck = b.add("neck", chest, (0, neck_y, 0), (0, head_y, 0), 0.032 * H * g, 0.03 * H * g, limit=0.5)
    head_r = 0.062 * H * p["head"]
    head = b.add("head", neck, (0, head_y, 0), (0, head_y + 1.6 * head_r, 0.01 * H), head_r, 0.9 * head_r,
                 aspect=(0.9, 1.0), limit=0.5)
    sh_y = 0.805 * H
    half_sh = 0.12 * H * p["shoulder"]
    ua, fa = 0.17 * H * p["arm"], 0.15 * H * p["arm"]
    hand_len = 0.055 * H
    tilt = 0.0 if p["pose"] == "T" else np.radians(40)
    out = {"hips": hips, "chest": chest, "head": head, "neck": neck, "head_radius": head_r,
           "hip_y": hip_y, "hip_half_width": 0.1 * H * g * 1.35, "chest_depth": 0.085 * H * g * 0.8,
           "height": H}
    for side, s in SIDES:
        arm_dir = np.array([s * np.cos(tilt), -np.sin(tilt), 0.0])
        clav_head = np.array([s * 0.025 * H, sh_y, 0.0])
        sh = clav_head + np.array([s * half_sh, 0, 0])
        shoulder = b.add(f"{side}/shoulder", chest, clav_head, sh, 0.035 * H * g, 0.04 * H * g, limit=0.3)
        elbow = sh + ua * arm_dir
        wrist = elbow + fa * arm_dir
        upper = b.add(f"{side}/upper_arm", shoulder, sh, elbow, 0.042 * H * g, 0.034 * H * g, limit=1.1)
        fore = b.add(f"{side}/forearm", upper, elbow, wrist, 0.032 * H * g, 0.025 * H * g, limit=1.1)
        hand = b.add(f"{side}/hand", fore, wrist, wrist + hand_len * arm_dir, 0.024 * H, 0.022 * H,
                     aspect=(1.0, 0.55), side_ref=(0, 0, 1), limit=0.7)
        nf = p["fingers"]
        knuckle = wrist + hand_len * arm_dir
        down = np.cross(arm_dir, [0, 0, s])  # palm normal (points down in T-pose)
        for f in FINGERS[:nf] if nf == 5 else (("thumb", "index", "middle")[:nf]):
            if f == "thumb":
                base = wrist + 0.3 * hand_len * arm_dir + 0.018 * H * np.array([0, 0, 1])
                d = (0.55 * arm_dir + 0.8 * np.array([0, 0, 1.0]) + 0.2 * down)
                seg = 0.018 * H
            else:
                k = FINGERS.index(f) - 1  # index 0 .. pinky 3
                z = (0.012 - 0.009 * k) * H
                base = knuckle + np.array([0, 0, z])
                d = arm_dir
                seg = (0.02 - 0.002 * abs(k - 1)) * H
            d = d / np.linalg.norm(d)
            pts = [base + i * seg * d for i in range(4)]
            r = 0.0075 * H
            b.chain([f"{side}/{f}/{i}" for i in (1, 2, 3)], hand, pts, [r, 0.95 * r, 0.9 * r, 0.8 * r],
                    limit=0.7)
        hx = s * 0.085 * H * g
        knee_y = 0.28 * H * p["leg"] / (0.48 + 0.52 * p["leg"]) * 1.0
        ankle_y = 0.045 * H
        thigh = b.add(f"{side}/thigh", hips, (hx, hip_y - 0.03 * H, 0), (hx * 0.95, knee_y, 0.005 * H),
                      0.062 * H * g, 0.045 * H * g, limit=1.0)
        shin = b.add(f"{side}/shin", thigh, (hx * 0.95, knee_y, 0.005 * H), (hx * 0.9, ankle_y, -0.01 * H),
                     0.044 * H * g, 0.03 * H * g, limit=1.1)
        foot = b.add(f"{side}/foot", shin, (hx * 0.9, ankle_y, -0.01 * H), (hx * 0.92, 0.02 * H, 0.09 * H),
                     0.03 * H, 0.028 * H, aspect=(1.2, 0.8), limit=0.5)
        b.add(f"{side}/toe", foot, (hx * 0.92, 0.02 * H, 0.09 * H), (hx * 0.93, 0.015 * H, 0.14 * H),
              0.026 * H, 0.02 * H, aspect=(1.3, 0.7), limit=0.4)
        out[f"{side}/upper_arm"] = upper
    return out
