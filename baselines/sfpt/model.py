"""The Skeleton-free Pose Transfer networks (Liao et al., ECCV 2022, Sec. 3), re-implemented from the paper
and the authors' public code (read, not copied). One mesh at a time: a mesh is vertices (N, 3) and
per-vertex normals (N, 3) in its unit-height rest frame, and its directed edges (E, 2)
(:func:`mimicbench.baselines.sfpt.mesh_graph.mesh_edges`). Widths scale with ``hidden`` (h; 64 in the paper):

- :class:`MeshEdgeConv`: EdgeConv over the mesh's edges, ``x_i' = MLP(max_j MLP([x_i, x_j - x_i]))``.
- :class:`SkinningPredictor`: handle weights W (N, H) of a rest mesh: EdgeConvs (6 -> h -> 2h -> 4h),
  their concatenation through MLPs (7h -> 4h -> 4h -> 2h) and a linear layer to H logits, softmax.
- :class:`ShapeEncoder`: per-handle codes (H, code) of a mesh (rest or posed) under handle weights W:
  EdgeConvs as above; a per-vertex MLP (7h -> 4h) beside a global max-pooled MLP (7h -> 4h); their
  concatenation averaged per handle with W's normalised columns, a linear layer to ``code``, ReLU.
- :class:`PoseDecoder`: a handle's transform (translation, quaternion wxyz) from the source's pose code
  (posed minus rest encodings), **the target's shape code** and the source handle's Kabsch fit
  (translation, quaternion): an MLP (2 code + 7 -> 4h -> 2h -> 2h -> 7).

The pose is read from the source under the source's handle weights, the shape from the target under
the target's, and the predicted transforms deform the target about its own handle centres
(:func:`mimicbench.baselines.sfpt.handles.deform`).
"""
from __future__ import annotations

import torch
from torch import nn

from mimicbench.baselines.mmdmc.nn import mlp
from mimicbench.baselines.sfpt.handles import handle_centres, kabsch_transforms


def relu_init(module: nn.Module) -> None:
    """He (Kaiming) normal weights for the ReLU layers of every ``nn.Linear`` in ``module``, zero biases.

    PyTorch's default ``nn.Linear`` init shrinks a ReLU network's signal by about 1/sqrt(6) a layer; over
    the dozen layers between a vertex and its handle logits the input is gone and every vertex gets the same
    weights and codes. He init keeps the signal's scale (the published EdgeConv keeps it with batch norm).
    """
    for layer in module.modules():
        if isinstance(layer, nn.Linear):
            nn.init.kaiming_normal_(layer.weight, nonlinearity="relu")
            nn.init.zeros_(layer.bias)


class MeshEdgeConv(nn.Module):
    """x_i' = MLP_out(max over edges (i, j) of MLP_edge([x_i, x_j - x_i])): (N, c_in) -> (N, c_out)."""

    def __init__(self, c_in: int, c_out: int):
        super().__init__()
        self.edge = mlp([2 * c_in, c_out, c_out])
        self.out = mlp([c_out, c_out])

    def forward(self, x: torch.Tensor, edges: torch.Tensor) -> torch.Tensor:
        """x (N, c_in), edges (E, 2) directed (i, j) covering every vertex as an i -> (N, c_out)."""
        xi, xj = x[edges[:, 0]], x[edges[:, 1]]
        msg = self.edge(torch.cat([xi, xj - xi], dim=-1))
        agg = msg.new_full((x.shape[0], msg.shape[1]), float("-inf"))
        agg = agg.scatter_reduce(0, edges[:, :1].expand(-1, msg.shape[1]), msg, reduce="amax", include_self=True)
        return self.out(agg)


class EdgeFeatures(nn.Module):
    """Concatenated outputs (N, 7h) of three :class:`MeshEdgeConv` (c_in -> h -> 2h -> 4h)."""

    def __init__(self, c_in: int, hidden: int):
        super().__init__()
        self.convs = nn.ModuleList([MeshEdgeConv(c_in, hidden), MeshEdgeConv(hidden, 2 * hidden),
                                    MeshEdgeConv(2 * hidden, 4 * hidden)])

    def forward(self, x: torch.Tensor, edges: torch.Tensor) -> torch.Tensor:
        feats = []
        for conv in self.convs:
            x = conv(x, edges)
            feats.append(x)
        return torch.cat(feats, dim=-1)


class SkinningPredictor(nn.Module):
    """Handle weights (N, H), rows summing to 1, of a rest mesh (vertices, normals (N, 3), edges (E, 2))."""

    def __init__(self, hidden: int, handles: int):
        super().__init__()
        self.features = EdgeFeatures(6, hidden)
        self.head = nn.Sequential(mlp([7 * hidden, 4 * hidden, 4 * hidden, 2 * hidden]), nn.Linear(2 * hidden, handles))

    def forward(self, vertices: torch.Tensor, normals: torch.Tensor, edges: torch.Tensor) -> torch.Tensor:
        return torch.softmax(self.head(self.features(torch.cat([vertices, normals], -1), edges)), dim=-1)


class ShapeEncoder(nn.Module):
    """Per-handle codes (H, code) of a mesh (vertices, normals (N, 3), edges (E, 2)) under weights (N, H)."""

    def __init__(self, hidden: int, code: int):
        super().__init__()
        self.features = EdgeFeatures(6, hidden)
        self.local = mlp([7 * hidden, 4 * hidden])
        self.glob = mlp([7 * hidden, 4 * hidden])
        self.out = mlp([8 * hidden, code])

    def forward(self, vertices: torch.Tensor, normals: torch.Tensor, weights: torch.Tensor,
                edges: torch.Tensor) -> torch.Tensor:
        f = self.features(torch.cat([vertices, normals], -1), edges)  # (N, 7h)
        g = self.glob(f.max(dim=0).values)  # (4h,)
        per_vertex = torch.cat([self.local(f), g.expand(f.shape[0], -1)], -1)  # (N, 8h)
        return self.out(handle_centres(per_vertex, weights))  # (H, code)


class PoseDecoder(nn.Module):
    """(H, 7) handle transforms (translation, quaternion wxyz) from the pose code (H, code), the target's
    shape code (H, code) and the Kabsch fit (H, 7).

    With ``residual`` (ours, ``cpu`` preset) the output is added to the Kabsch fit (the published decoder's
    optional ``base``) and the last layer starts at zero, so an untrained decoder answers the fit itself.
    """

    def __init__(self, hidden: int, code: int, residual: bool = False):
        super().__init__()
        self.net = mlp([2 * code + 7, 4 * hidden, 2 * hidden, 2 * hidden, 7], last_act=False)
        relu_init(self.net)
        self.residual = bool(residual)
        if self.residual:
            nn.init.zeros_(self.net[-1].weight)
            nn.init.zeros_(self.net[-1].bias)

    def forward(self, pose: torch.Tensor, shape: torch.Tensor, kabsch: torch.Tensor) -> torch.Tensor:
        out = self.net(torch.cat([pose, shape, kabsch], -1))
        return out + kabsch if self.residual else out


class SkeletonFreePoseTransfer(nn.Module):
    """SFPT: skinning predictor, shape encoder and pose decoder.

    Args:
        hidden: EdgeConv base width h (64 in the paper); code: per-handle code width (128 in the paper);
        handles: H (40 in the paper); residual: the decoder answers corrections to the Kabsch fit.
    """

    def __init__(self, hidden: int = 64, handles: int = 40, code: int = 128, residual: bool = False):
        super().__init__()
        self.skinning = SkinningPredictor(hidden, handles)
        self.encoder = ShapeEncoder(hidden, code)
        relu_init(self.skinning)
        relu_init(self.encoder)
        self.decoder = PoseDecoder(hidden, code, residual)
        self.handles = handles

    def pose_code(self, rest: torch.Tensor, posed: torch.Tensor, normals: tuple, weights: torch.Tensor,
                  edges: torch.Tensor) -> torch.Tensor:
        """(H, code) a mesh's pose code: the encoding of its posed mesh minus that of its rest mesh, both
        under its rest weights (N, H); normals: (rest, posed) normals (N, 3) each; edges (E, 2)."""
        return self.encoder(posed, normals[1], weights, edges) - self.encoder(rest, normals[0], weights, edges)

    def predict(self, source_rest: torch.Tensor, source_posed: torch.Tensor, source_normals: tuple,
                source_weights: torch.Tensor, source_edges: torch.Tensor, target_code: torch.Tensor,
                kabsch_only: bool = False) -> torch.Tensor:
        """(H, 7) transforms (translation, quaternion wxyz) of the target's handles posing it like the source.

        Args:
            source_rest, source_posed: (Ns, 3); source_normals: (rest, posed) normals (Ns, 3) each;
            source_weights: (Ns, H); source_edges: (E, 2); target_code: (H, code) the target's
            :class:`ShapeEncoder` code at rest; kabsch_only: return the source handles' Kabsch fit itself
            (the ``sfpt_kabsch_only`` ablation: no pose decoder).
        """
        kabsch = kabsch_transforms(source_rest, source_posed, source_weights)
        if kabsch_only:
            return kabsch
        pose = self.pose_code(source_rest, source_posed, source_normals, source_weights, source_edges)
        return self.decoder(pose, target_code, kabsch)


def build_sfpt(config: dict, context=None) -> SkeletonFreePoseTransfer:
    """The network of a config (``hidden``, ``handles``, ``code``, ``residual``); ``context`` (a
    training stage's, unused) lets it serve as a stage's builder."""
    return SkeletonFreePoseTransfer(config["hidden"], config["handles"], config["code"],
                                    config.get("residual", False))
