"""Building blocks shared by E and F: Fourier point embedding and pre-norm attention blocks.

Self-attention blocks are ``torch.nn.TransformerEncoderLayer`` (pre-norm, batch first); the
cross-attention block below has the same layout with queries and context from different sets.
"""
from __future__ import annotations

import math

import torch
from torch import nn


class FourierEmbedding(nn.Module):
    """Points (..., 3) -> features (..., width): [x, sin(2^i pi x), cos(2^i pi x)] then a linear map."""

    def __init__(self, width: int, frequencies: int = 6, in_dim: int = 3):
        super().__init__()
        self.register_buffer("freqs", (2.0 ** torch.arange(frequencies, dtype=torch.float32)) * math.pi,
                             persistent=False)
        self.proj = nn.Linear(in_dim * (1 + 2 * frequencies), width)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        xf = x[..., None] * self.freqs  # (..., D, F)
        feats = torch.cat([x, xf.sin().flatten(-2), xf.cos().flatten(-2)], dim=-1)
        return self.proj(feats)


class CrossAttentionBlock(nn.Module):
    """Pre-norm cross-attention then MLP: queries (B, Q, d) attend to context (B, C, d)."""

    def __init__(self, width: int, heads: int, mlp: int, context_width: int | None = None):
        super().__init__()
        context_width = context_width or width
        self.norm_q = nn.LayerNorm(width)
        self.norm_c = nn.LayerNorm(context_width)
        self.attn = nn.MultiheadAttention(width, heads, kdim=context_width, vdim=context_width, batch_first=True)
        self.norm_mlp = nn.LayerNorm(width)
        self.mlp = nn.Sequential(nn.Linear(width, mlp), nn.GELU(), nn.Linear(mlp, width))

    def forward(self, queries: torch.Tensor, context: torch.Tensor,
                context_padding: torch.Tensor | None = None) -> torch.Tensor:
        """``context_padding`` (B, C) bool, True where the context entry is padding."""
        c = self.norm_c(context)
        x = queries + self.attn(self.norm_q(queries), c, c, key_padding_mask=context_padding, need_weights=False)[0]
        return x + self.mlp(self.norm_mlp(x))


def self_attention_stack(width: int, heads: int, mlp: int, layers: int) -> nn.TransformerEncoder:
    """``layers`` pre-norm self-attention blocks (GELU MLP of width ``mlp``), batch first."""
    layer = nn.TransformerEncoderLayer(width, heads, mlp, dropout=0.0, activation="gelu", batch_first=True,
                                       norm_first=True)
    return nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)
