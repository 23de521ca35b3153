"""The correspondence transformer G (MimiCAT Eq. 2 and 6).

Each character's keypoints pass through a keypoint encoder MLP, its shape tokens (from the frozen
shape encoder E) through a shape projector; a segment embedding says which character a token
belongs to, and transformer blocks attend over all tokens of the pair at once (padding masked,
so characters of different K share a batch). The affinity of source keypoint i and target
keypoint j is ``phi_i^T A phi_j / sqrt(d)`` with a learnable matrix A (Eq. 2); Sinkhorn
normalisation (:func:`mimicbench.geometry.sinkhorn.sinkhorn_log`, per pair on its unpadded block) makes
it a doubly stochastic soft correspondence M (Ks, Kt): rows sum to 1, columns to Ks/Kt.

Our choice, not the paper's: the affinity may also have a geometric term ``-w ||p_i - p_j||^2``
between the two characters' rest keypoints p (K, 3) in the unit-height frame that
``nearest_joint`` matches in (:func:`mimicbench.geometry.mesh.normalize_unit_height`: centred at the rest
mesh's bounding box, divided by its height; ``CharacterTensors.unit_keypoints``), with a
learnable ``w = w0 * softplus(r) / log 2 > 0`` (``r`` starts at 0, so ``w`` starts at
``w0`` = ``corr.geometry_weight``). In G's own box frame (divided by the largest side) the
nearest joints agreed with the dataset's Hungarian matches on 29% of the training zoo's pairs,
against the unit-height frame's; ``geometry_weight=0`` (the default, and what checkpoints
without the setting were trained with) leaves the term out.

Training (Eq. 6) matches M to the dataset's ``pairs/`` table: cross-entropy of M's rows against
M_sink's (renormalised) rows plus the negative log-likelihood of the Hungarian pairs M_hung.
"""
from __future__ import annotations

import math

import torch
from torch import nn

from mimicbench.baselines.mimicat.corr_data import KEYPOINT_FEATURES
from mimicbench.geometry.sinkhorn import sinkhorn_log, sinkhorn_scaling_torch


def mlp(width_in: int, width: int, width_out: int) -> nn.Sequential:
    """Two-layer MLP with GELU."""
    return nn.Sequential(nn.Linear(width_in, width), nn.GELU(), nn.Linear(width, width_out))


def transformer(width: int, layers: int, heads: int, mlp_width: int) -> nn.TransformerEncoder:
    """Pre-norm transformer blocks over (B, T, width) tokens."""
    block = nn.TransformerEncoderLayer(width, heads, mlp_width, dropout=0.0, batch_first=True, norm_first=True,
                                       activation="gelu")
    return nn.TransformerEncoder(block, layers, enable_nested_tensor=False)


class CorrespondenceTransformer(nn.Module):
    """G: keypoints and shape tokens of two characters -> soft correspondence M (Ks, Kt).

    Args:
        shape_width: width d of the shape encoder's tokens.
        width, layers, heads, mlp_width: transformer sizes.
        sinkhorn_iters: Sinkhorn sweeps.
        geometry_weight: w0, the starting weight of the geometric term (per squared unit-height
            distance); 0 leaves the term (and its parameter) out.
    """

    def __init__(self, shape_width: int, width: int = 64, layers: int = 2, heads: int = 4, mlp_width: int = 128,
                 sinkhorn_iters: int = 50, geometry_weight: float = 0.0):
        super().__init__()
        self.keypoint_encoder = mlp(KEYPOINT_FEATURES, width, width)
        self.shape_projector = nn.Linear(shape_width, width)
        self.segment = nn.Embedding(4, width)  # source keypoint, target keypoint, source shape, target shape
        self.blocks = transformer(width, layers, heads, mlp_width)
        self.norm = nn.LayerNorm(width)
        self.affinity = nn.Parameter(torch.eye(width))
        self.sinkhorn_iters = sinkhorn_iters
        if not geometry_weight >= 0:
            raise ValueError(f"geometry_weight: expected >= 0, got {geometry_weight}")
        self.geometry_weight = float(geometry_weight)
        if self.geometry_weight > 0:
            self.geometry_raw = nn.Parameter(torch.zeros(()))

    def geometric_weight(self) -> torch.Tensor | None:
        """w > 0, the current weight of the geometric term (scalar), or None without the term."""
        if self.geometry_weight == 0:
            return None
        return self.geometry_weight * nn.functional.softplus(self.geometry_raw) / math.log(2.0)

    def scores(self, kp_s, mask_s, kp_t, mask_t, shape_s, shape_t, pos_s=None, pos_t=None) -> torch.Tensor:
        """Affinity scores (B, Ks, Kt) of padded inputs.

        Args:
            kp_s: (B, Ks, KEYPOINT_FEATURES) source keypoint features; mask_s (B, Ks) bool, True
                where a keypoint exists.
            kp_t, mask_t: the same for the target.
            shape_s, shape_t: (B, l, d) shape tokens of the rest meshes.
            pos_s, pos_t: (B, Ks, 3), (B, Kt, 3) rest keypoints in the unit-height frame (padded
                like kp_s, kp_t); needed only when G has the geometric term.

        The semantic term ``phi_i^T A phi_j / sqrt(d)``, minus ``w ||p_i - p_j||^2`` when G has
        the geometric term.
        """
        b, ks, _ = kp_s.shape
        kt = kp_t.shape[1]
        seg = self.segment.weight
        tokens = torch.cat([self.keypoint_encoder(kp_s) + seg[0], self.keypoint_encoder(kp_t) + seg[1],
                            self.shape_projector(shape_s) + seg[2], self.shape_projector(shape_t) + seg[3]], dim=1)
        valid = torch.cat([mask_s, mask_t, torch.ones(b, shape_s.shape[1] + shape_t.shape[1], dtype=torch.bool,
                                                      device=kp_s.device)], dim=1)
        h = self.norm(self.blocks(tokens, src_key_padding_mask=~valid))
        phi_s, phi_t = h[:, :ks], h[:, ks:ks + kt]
        semantic = torch.einsum("bid,de,bje->bij", phi_s, self.affinity, phi_t) / math.sqrt(h.shape[-1])
        w = self.geometric_weight()
        if w is None:
            return semantic
        if pos_s is None or pos_t is None:
            raise ValueError("G has a geometric term (corr.geometry_weight > 0): expected the unit-height rest "
                             "keypoints pos_s (B, Ks, 3) and pos_t (B, Kt, 3)")
        return semantic - w * (pos_s[:, :, None, :] - pos_t[:, None, :, :]).pow(2).sum(dim=-1)

    def forward(self, kp_s, mask_s, kp_t, mask_t, shape_s, shape_t, temperature: float = 1.0, pos_s=None,
                pos_t=None) -> list[torch.Tensor]:
        """One doubly stochastic M (Ks_b, Kt_b) per pair of the batch (rows 1, columns Ks/Kt).

        ``temperature`` T divides the scores before Sinkhorn: 1 in training (Eq. 6); the
        pose-transfer stage asks for a sharper M (T < 1, see
        :func:`mimicbench.baselines.mimicat.transfer.correspondences`), with proportionally more sweeps.
        ``pos_s``, ``pos_t``: see :meth:`scores`.

        Without gradients (inference, H's frozen G) Sinkhorn runs as matrix scaling
        (:func:`mimicbench.geometry.sinkhorn.sinkhorn_scaling_torch`, the same balanced matrix to within
        the tolerance, about 20 times faster on CPU); G's own training keeps the log-space one.
        """
        if not temperature > 0:
            raise ValueError(f"temperature: expected > 0, got {temperature}")
        s = self.scores(kp_s, mask_s, kp_t, mask_t, shape_s, shape_t, pos_s, pos_t)
        iters = int(round(self.sinkhorn_iters * max(1.0, 1.0 / temperature)))
        out = []
        for b in range(s.shape[0]):
            ks, kt = int(mask_s[b].sum()), int(mask_t[b].sum())
            if torch.is_grad_enabled():
                out.append(sinkhorn_log(s[b, :ks, :kt], temperature=temperature, num_iters=iters, tol=1e-5))
            else:
                out.append(sinkhorn_scaling_torch(s[b, :ks, :kt], temperature=temperature, num_iters=iters, tol=1e-5))
        return out


def correspondence_loss(m_pred: list[torch.Tensor], m_sink: list[torch.Tensor], hungarian: list[torch.Tensor]) -> dict:
    """Eq. 6: mean over pairs of the row cross-entropy against M_sink plus the Hungarian NLL.

    Args:
        m_pred: per pair (Ks, Kt) doubly stochastic M (rows sum to 1).
        m_sink: per pair (Ks, Kt) target rows (summing to 1, or 0 for a source bone without match).
        hungarian: per pair (P, 2) long (source, target) index pairs.

    Returns:
        ``total``, ``sink`` (cross-entropy) and ``hung`` (NLL), scalars.
    """
    sink, hung = [], []
    for m, target, pairs in zip(m_pred, m_sink, hungarian):
        log_m = m.clamp_min(1e-9).log()
        has = target.sum(dim=1) > 0
        sink.append(-(target[has] * log_m[has]).sum(dim=1).mean() if has.any() else log_m.sum() * 0)
        hung.append(-log_m[pairs[:, 0], pairs[:, 1]].mean() if len(pairs) else log_m.sum() * 0)
    sink_t, hung_t = torch.stack(sink).mean(), torch.stack(hung).mean()
    return {"total": sink_t + hung_t, "sink": sink_t, "hung": hung_t}
