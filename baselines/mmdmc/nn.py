"""Layers shared by the MMDMC modules."""
from __future__ import annotations

from torch import nn


def mlp(sizes: list[int], last_act: bool = True) -> nn.Sequential:
    """Linear layers of ``sizes`` with ReLU between (and after the last when ``last_act``)."""
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:])):
        layers.append(nn.Linear(a, b))
        if last_act or i < len(sizes) - 2:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)
