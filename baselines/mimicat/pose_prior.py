"""Pose prior F (MimiCAT Appendix A2): per-keypoint matrix-Fisher distributions of rotations.

F reads the shape tokens of the rest and the posed mesh, ``[f(V_rest), f(V_posed)]`` from the
frozen shape encoder E, and one token per keypoint built from its rest and posed positions
``[c_k, t_k]`` (with the bone vectors to its parent, ``c_k - c_parent`` and ``t_k - t_parent``,
which say most about the bone's turn); a transformer mixes the three sets; each keypoint token is
decoded to a matrix-Fisher parameter ``F_k`` (3x3). Trained by the negative log-likelihood of the
dataset's rotations (Eq. A2, :func:`mimicbench.baselines.mimicat.matrix_fisher.negative_log_likelihood`),
it scores how plausible the rotations R_k of a posed character are; the transfer stage uses it,
frozen, as ``L_reg`` (:meth:`PosePrior.nll`).

Positions are in the character's rest frame (see :mod:`mimicbench.baselines.mimicat.data`). R_k is keypoint
k's world rotation relative to rest (the q_k of Eq. 1, as stored in the dataset's clips).

The head is initialised at zero (F = 0: the uniform distribution, NLL 0) and its output is
multiplied by ``output_scale`` so that concentrations of tens to hundreds are reachable in few
steps.
"""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

from mimicbench.baselines.mimicat.attention import FourierEmbedding, self_attention_stack
from mimicbench.baselines.mimicat.matrix_fisher import mode, negative_log_likelihood, sampling_loss


def bone_vectors(points: torch.Tensor, parents: torch.Tensor) -> torch.Tensor:
    """``points[k] - points[parent[k]]`` (B, K, 3), zero for roots (``parents`` (B, K) long, -1 roots)."""
    idx = parents.clamp_min(0)
    par = torch.gather(points, 1, idx[..., None].expand_as(points))
    return torch.where((parents >= 0)[..., None], points - par, torch.zeros_like(points))


class PosePrior(nn.Module):
    """F: shape tokens and keypoints -> a matrix-Fisher parameter per keypoint.

    Args:
        shape_width: d of E's tokens; width, heads, layers, mlp: the transformer's sizes;
        fourier: frequencies of the keypoint embedding; output_scale: factor on the head's output.
    """

    def __init__(self, shape_width: int, width: int = 64, heads: int = 4, layers: int = 2, mlp: int = 128,
                 fourier: int = 6, output_scale: float = 10.0):
        super().__init__()
        self.shape_proj = nn.Linear(shape_width, width)
        self.token_type = nn.Parameter(torch.randn(3, width) * 0.02)  # rest shape, posed shape, keypoint
        self.keypoint_embed = FourierEmbedding(width, fourier, in_dim=12)
        self.blocks = self_attention_stack(width, heads, mlp, layers)
        self.norm = nn.LayerNorm(width)
        self.head = nn.Linear(width, 9)
        nn.init.zeros_(self.head.weight)
        nn.init.zeros_(self.head.bias)
        self.output_scale = float(output_scale)

    @classmethod
    def from_config(cls, config: dict) -> "PosePrior":
        p = config["prior"]
        return cls(int(config["shape"]["width"]), p["width"], p["heads"], p["layers"], p["mlp"], p.get("fourier", 6),
                   p.get("output_scale", 10.0))

    def forward(self, f_rest: torch.Tensor, f_posed: torch.Tensor, rest: torch.Tensor, posed: torch.Tensor,
                parents: torch.Tensor, mask: torch.Tensor | None = None) -> torch.Tensor:
        """Matrix-Fisher parameters.

        Args:
            f_rest, f_posed: (B, l_E, d) shape tokens of the rest and the posed mesh.
            rest, posed: (B, K, 3) rest and posed keypoints (rest frame).
            parents: (B, K) long, -1 for roots (and for padding).
            mask: (B, K) bool, True for real keypoints (None: all).

        Returns:
            F (B, K, 3, 3).
        """
        b, k, _ = rest.shape
        feats = torch.cat([rest, posed, 4 * bone_vectors(rest, parents), 4 * bone_vectors(posed, parents)], -1)
        kp = self.keypoint_embed(feats) + self.token_type[2]
        sr = self.shape_proj(f_rest) + self.token_type[0]
        sp = self.shape_proj(f_posed) + self.token_type[1]
        x = torch.cat([sr, sp, kp], 1)
        padding = None
        if mask is not None:
            shape_ok = torch.ones(b, sr.shape[1] + sp.shape[1], dtype=torch.bool, device=rest.device)
            padding = ~torch.cat([shape_ok, mask], 1)
        x = self.norm(self.blocks(x, src_key_padding_mask=padding))[:, -k:]
        return (self.head(x) * self.output_scale).reshape(b, k, 3, 3)

    def nll(self, f_rest, f_posed, rest, posed, parents, q=None, R=None, mask=None) -> torch.Tensor:
        """Mean negative log-likelihood (Eq. A2) of rotations under F, over the real keypoints.

        Accepts one character (tokens (l_E, d), keypoints (K, 3), parents (K,), q (K, 4)) or a
        batch (a leading B on each). Give rotations as unit quaternions ``q`` (w, x, y, z) or
        matrices ``R`` (..., K, 3, 3). ``parents`` may be a numpy array.
        """
        from mimicbench.geometry.skinning_torch import quat_to_matrix_torch

        if (q is None) == (R is None):
            raise ValueError("nll: give exactly one of q (quaternions) or R (rotation matrices)")
        single = rest.ndim == 2
        parents = torch.as_tensor(np.asarray(parents) if not torch.is_tensor(parents) else parents,
                                  dtype=torch.long, device=rest.device)
        if single:
            f_rest, f_posed, rest, posed, parents = (f_rest[None], f_posed[None], rest[None], posed[None],
                                                     parents[None])
            q = None if q is None else q[None]
            R = None if R is None else R[None]
            mask = None if mask is None else mask[None]
        if R is None:
            R = quat_to_matrix_torch(q / q.norm(dim=-1, keepdim=True))
        F = self(f_rest, f_posed, rest, posed, parents, mask)
        nll = negative_log_likelihood(F, R.to(F.dtype))
        if mask is None:
            return nll.mean()
        return (nll * mask).sum() / mask.sum().clamp_min(1)


def prior_loss(model: PosePrior, f_rest, f_posed, batch: dict, sampling_weight: float = 0.0, samples: int = 4,
               rng: np.random.Generator | None = None) -> dict[str, torch.Tensor]:
    """The ``prior`` stage's loss on a collated batch (see :func:`mimicbench.baselines.mimicat.data.prior_example`).

    Returns ``total`` = ``nll`` (mean over the scored keypoints, Eq. A2) + ``sampling_weight`` x
    the sampling term (A3 as done here: ``samples`` rotations drawn from each F_k, their expected
    distance to R_k minimised through a score-function surrogate, see
    :func:`mimicbench.baselines.mimicat.matrix_fisher.sampling_loss`; ``sample_dist`` logs that distance,
    ||R' - R||^2 / 8), and, for the log only, ``mode_deg``: mean angle (degrees) between the
    mode of each F_k and the true R_k.
    """
    mask = batch["mask"]
    F = model(f_rest, f_posed, batch["rest"], batch["posed"], batch["parents"], mask)
    scored = mask & batch["keep"]
    nll = negative_log_likelihood(F, batch["rotations"].to(F.dtype))
    nll_mean = (nll * scored).sum() / scored.sum().clamp_min(1)
    out = {"nll": nll_mean.detach()}
    total = nll_mean
    if sampling_weight > 0:
        surrogate, dist = sampling_loss(F[scored], batch["rotations"][scored], samples,
                                        rng if rng is not None else np.random.default_rng(0))
        total = total + sampling_weight * surrogate
        out["sample_dist"] = dist.float()
    with torch.no_grad():
        m = mode(F.double())
        cos = (((m * batch["rotations"].double()).sum((-1, -2)) - 1) / 2).clamp(-1, 1)
        angle = torch.rad2deg(torch.arccos(cos))
        mode_deg = (angle * scored).sum() / scored.sum().clamp_min(1)
    return {"total": total, **out, "mode_deg": mode_deg.float()}
