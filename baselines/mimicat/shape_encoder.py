"""Shape encoder E: a point cloud -> l_E learned query tokens of width d (a set encoder).

No PyPI package ships a pretrained 3D shape encoder, so E is trained here on the dataset's
meshes as an autoencoder, in the manner of 3DShape2VecSet (Zhang et al. 2023): learned queries
cross-attend to the embedded points, self-attention blocks mix the tokens, and a decoder queried
at 3D points predicts the unsigned distance to the surface from the tokens alone. After the
``shape`` stage E is frozen; ``f(V)`` is ``ShapeAutoencoder(points)``.

Input points are mesh vertices (rest or posed) in the character's rest frame: minus the centre
of the rest mesh's bounding box, divided by its largest side (so the rest mesh fits in the unit
cube around the origin); see :func:`mimicbench.baselines.mimicat.data.rest_frame`.
"""
from __future__ import annotations

import torch
from torch import nn

from mimicbench.baselines.mimicat.attention import CrossAttentionBlock, FourierEmbedding, self_attention_stack


class ShapeEncoder(nn.Module):
    """Points (B, P, 3) -> tokens (B, l_E, d)."""

    def __init__(self, tokens: int = 16, width: int = 64, heads: int = 4, layers: int = 2, mlp: int = 128,
                 fourier: int = 6):
        super().__init__()
        self.embed = FourierEmbedding(width, fourier)
        self.queries = nn.Parameter(torch.randn(tokens, width) * 0.02)
        self.cross = CrossAttentionBlock(width, heads, mlp)
        self.blocks = self_attention_stack(width, heads, mlp, layers)
        self.norm = nn.LayerNorm(width)

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        if points.ndim != 3 or points.shape[-1] != 3:
            raise ValueError(f"points: expected (B, P, 3), got {tuple(points.shape)}")
        x = self.embed(points)
        q = self.queries.expand(points.shape[0], -1, -1)
        return self.norm(self.blocks(self.cross(q, x)))


class DistanceDecoder(nn.Module):
    """Tokens (B, l_E, d) and query points (B, Q, 3) -> unsigned distance to the surface (B, Q)."""

    def __init__(self, width: int = 64, heads: int = 4, layers: int = 1, mlp: int = 128, fourier: int = 6):
        super().__init__()
        self.embed = FourierEmbedding(width, fourier)
        self.cross = nn.ModuleList(CrossAttentionBlock(width, heads, mlp) for _ in range(layers))
        self.head = nn.Sequential(nn.LayerNorm(width), nn.Linear(width, width), nn.GELU(), nn.Linear(width, 1))

    def forward(self, tokens: torch.Tensor, queries: torch.Tensor) -> torch.Tensor:
        x = self.embed(queries)
        for block in self.cross:
            x = block(x, tokens)
        return nn.functional.softplus(self.head(x)[..., 0])


class ShapeAutoencoder(nn.Module):
    """E with its training decoder. ``forward(points)`` = ``encode``: (B, P, 3) -> (B, l_E, d)."""

    def __init__(self, tokens: int = 16, width: int = 64, heads: int = 4, layers: int = 2, mlp: int = 128,
                 decoder_layers: int = 1, fourier: int = 6):
        super().__init__()
        self.encoder = ShapeEncoder(tokens, width, heads, layers, mlp, fourier)
        self.decoder = DistanceDecoder(width, heads, decoder_layers, mlp, fourier)
        self.tokens, self.width = tokens, width

    @classmethod
    def from_config(cls, config: dict) -> "ShapeAutoencoder":
        """From the ``shape`` section of a MimiCAT config."""
        s = config["shape"]
        return cls(s["tokens"], s["width"], s["heads"], s["layers"], s["mlp"], s.get("decoder_layers", 1),
                   s.get("fourier", 6))

    def encode(self, points: torch.Tensor) -> torch.Tensor:
        return self.encoder(points)

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        return self.encoder(points)

    def decode(self, tokens: torch.Tensor, queries: torch.Tensor) -> torch.Tensor:
        return self.decoder(tokens, queries)


def shape_loss(model: ShapeAutoencoder, points: torch.Tensor, queries: torch.Tensor,
               distances: torch.Tensor) -> dict[str, torch.Tensor]:
    """Autoencoder loss: L1 between predicted and true unsigned distances at the queries.

    Args:
        points: (B, P, 3) encoder input; queries: (B, Q, 3); distances: (B, Q) true unsigned
            distances to the surface (rest-frame units: largest side = 1).

    Returns:
        ``total`` (mean L1), ``near`` (mean L1 on queries within 0.02 of the surface).
    """
    pred = model.decode(model.encode(points), queries)
    err = (pred - distances).abs()
    near = distances < 0.02
    out = {"total": err.mean()}
    out["near"] = (err[near].mean() if near.any() else err.new_zeros(())).detach()
    return out
