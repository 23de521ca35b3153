"""Joint refinement f_j (MMDMC Sec. 4.4): a light MLP on the tiled body and apparel outputs (each
vertex's body state s, its combined state y after the apparel module, their difference, its
apparel probability and rest position) to a per-vertex correction; y' = y + correction."""
from __future__ import annotations

import torch
from torch import nn

from mimicbench.baselines.mmdmc.nn import mlp

OUTPUT_SCALE = 0.02
"""The MLP's output times this is the correction (unit-height frame)."""


class JointRefiner(nn.Module):
    """f_j: (..., N, 3) body, (..., N, 3) combined, (..., N) probability, (..., N, 3) rest -> correction (..., N, 3)."""

    def __init__(self, hidden: int = 32):
        super().__init__()
        self.mlp = mlp([13, hidden, hidden, 3], last_act=False)
        # the last layer starts at zero: an untrained f_j corrects nothing (y' = y)
        nn.init.zeros_(self.mlp[-1].weight)
        nn.init.zeros_(self.mlp[-1].bias)

    def forward(self, body: torch.Tensor, combined: torch.Tensor, prob: torch.Tensor, rest: torch.Tensor) -> torch.Tensor:
        x = torch.cat([body, combined, (combined - body) * 10.0, prob[..., None], rest.expand_as(body)], dim=-1)
        return self.mlp(x) * OUTPUT_SCALE
