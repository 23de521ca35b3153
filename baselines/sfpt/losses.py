"""SFPT's training terms (Sec. 3.3), on one example in unit-height rest frames.

- reconstruction / cross-transfer: mean Euclidean vertex distance between a deformed mesh and its
  ground truth (the source posed by its own predicted handles; the target posed by the source's).
- skinning: the rig's skin weights G (N, K) and the handle weights W (N, H) index different things
  (K bones, H handles, in no shared order), so the term compares what both say about pairs of
  vertices: W W^T and G G^T (in [0, 1]: how much two vertices move together) compared by binary
  cross entropy over the pairs of a vertex subsample (ours: a permutation-free form of the paper's
  skinning supervision).
- edge: the deformed target's neighbour distances against the rest mesh's (an as-rigid-as-possible
  term: mean squared difference of lengths, MMDMC's :func:`baselines.mmdmc.losses.edge_length`).
"""
from __future__ import annotations

import torch

from baselines.mmdmc.losses import edge_length


def vertex_distance(pred: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """Mean over vertices of the Euclidean distance of (..., N, 3) positions."""
    return (pred - truth).norm(dim=-1).mean()


def co_skinning(weights: torch.Tensor, rig_weights: torch.Tensor) -> torch.Tensor:
    """Binary cross entropy of W W^T against G G^T over all pairs: weights (S, H), rig_weights (S, K)."""
    pred = (weights @ weights.T).clamp(1e-6, 1.0 - 1e-6)
    truth = (rig_weights @ rig_weights.T).clamp(0.0, 1.0)
    return torch.nn.functional.binary_cross_entropy(pred, truth)


def rigid_edges(pred: torch.Tensor, rest: torch.Tensor, edges: torch.Tensor) -> torch.Tensor:
    """Mean squared difference of edge lengths (E, 2) between a deformed mesh and its rest mesh (N, 3)."""
    return edge_length(pred, rest, edges)
