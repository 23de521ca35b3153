"""Toy-size pieces for the MimiCAT G/H tests: tube characters of different K and a tiny shape
encoder with the shape encoder's interface (points (B, P, 3) -> tokens (B, l, d))."""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

from mimicbench.benchmark.request import Rig, TransferRequest
from mimicbench.geometry.kinematics import forward_kinematics, transforms_to_array
from mimicbench.geometry.quaternion import quat_from_axis_angle
from mimicbench.geometry.skinning import linear_blend_skinning
from tests.toys import make_tube


class TinyEncoder(nn.Module):
    """Points (B, P, 3) -> (B, tokens, width): learned queries plus a pooled point MLP."""

    def __init__(self, tokens: int = 4, width: int = 16):
        super().__init__()
        self.width = width
        self.queries = nn.Parameter(torch.randn(tokens, width) * 0.1)
        self.point = nn.Sequential(nn.Linear(3, width), nn.GELU(), nn.Linear(width, width))

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        return self.queries + self.point(points).mean(dim=1, keepdim=True)


def tube_rig(name: str, bones: int, height: float = 1.0, branch: bool = True) -> Rig:
    t = make_tube(num_bones=bones, height=height, branch=branch, rings=12, segments=8)
    return Rig(name, "tube", t["vertices"], t["faces"], t["keypoints"], t["parents"], t["weights"],
               tuple(t["bone_names"]))


def bend(rig: Rig, angle: float, seed: int = 0) -> np.ndarray:
    """Transforms (K, 7) bending every bone of a rig about random axes by up to ``angle`` rad."""
    rng = np.random.default_rng(seed)
    k = len(rig.parents)
    axes = rng.normal(size=(k, 3))
    local = quat_from_axis_angle(axes / np.linalg.norm(axes, axis=1, keepdims=True), rng.uniform(0, angle, k))
    q, t = forward_kinematics(local, rig.keypoints, rig.parents)
    return transforms_to_array(q, t)


def posed(rig: Rig, transforms: np.ndarray) -> np.ndarray:
    return linear_blend_skinning(rig.vertices, rig.keypoints, rig.weights, transforms).astype(np.float32)


def request(src: Rig, tgt: Rig, seed: int = 0, m: np.ndarray | None = None) -> TransferRequest:
    extras = {} if m is None else {"m_sink": m}
    return TransferRequest(src, posed(src, bend(src, 0.6, seed)), tgt, f"toy{seed}", extras)
