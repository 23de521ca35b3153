"""Apparel deformation from the body's motion history (ours; config ``apparel_model="body_history"``,
the shipped f_d): f_d reads the kinematic history the request carries, not its own past states.

The simulated apparel at frame t is a function of the body's motion before t (the simulation starts
at rest on the body at the clip's first frame, as a request does) and of the apparel's own rest
shape. This module reads that history directly. Each apparel vertex has a *frame*: the rotation R_t
blended from the body bones its skinning weights name (:func:`frame_rotations`: the normalised
weighted sum of their quaternions, so neighbouring vertices have neighbouring frames and a garment's
offsets do not tear where its largest weight changes bone). In that frame it sees

- its rest offset from the weighted rest heads of those bones (3), and gravity's direction
  ``R_t^T up`` (3);
- for each lag l in :data:`LAGS`: where its body state was l frames earlier, ``R_t^T (s_{t-l} - s_t)``
  (3), and how its frame was turned then, the axis times the sine of ``R_t^T R_{t-l}`` (3);
  frames before the request's first repeat its first frame (the apparel at rest, as the simulation
  started),

and an MLP maps those 6 + 6 len(LAGS) numbers to an offset in the frame: the vertex's state is
``s_t + R_t offset``. With ``still_zero`` (config ``history_still_zero``) the offset is the
MLP's answer less its answer for the same rest offset and gravity with the lag inputs zero (the body
still for a second): a body that does not move keeps its skinned apparel. Without it, the sag the MLP
learnt from the training simulator's relaxed chains carried over to a real character whose own
physics barely moves (Gene's ``stand``: PMD_a 2.5 times ``mmdmc_no_apparel``'s). A zero offset is ``mmdmc_no_apparel``; the last layer starts at zero. No
rollout: every frame is one independent prediction, so training needs no backpropagation through
time, and a bad frame cannot derail the next. Training adds the relative stretch of the apparel's
mesh edges to the vertex loss (config ``w_stretch``), the quantity ELS scores.

Why not the paper's recurrence (:mod:`mimicbench.baselines.mmdmc.apparel`): rolled out from rest as a request
starts, its learned displacement removes 0.08% of ``mmdmc_no_apparel``'s PMD_a on a held-out zoo.
On the same data a per-vertex MLP on these inputs, fitted without the stretch term, predicts the
held-out offsets with 37% less error than a zero displacement. The shipped model trains for
positions (``w_stretch`` 0.1) and gives the edges their lengths back after the MLP, by soft ARAP
against the rest apparel (:mod:`mimicbench.baselines.mmdmc.apparel_arap`, config ``history_arap``); the
measurements are in docs/notes/mmdmc.md. The chains' lag, swing and flare in spins are a
function of the body's recent turning and acceleration in the vertex's frame, which one frame's
velocity and acceleration (K = 3 states) do not carry. All positions in the character's unit-height
frame.
"""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

from mimicbench.baselines.mmdmc.apparel_arap import ITERATIONS as ARAP_ITERATIONS
from mimicbench.baselines.mmdmc.nn import mlp
from mimicbench.geometry.skinning_torch import quat_to_matrix_torch

LAGS = (1, 2, 3, 4, 6, 8, 11, 15, 20, 30)
"""Frames back the history looks (30 frames: 1 s at 30 fps)."""
FEATURES = 6 + 6 * len(LAGS)
UP = (0.0, 1.0, 0.0)
"""The dataset frame's up axis (Y up)."""
REST_SCALE = 10.0
"""Rest offsets (unit height, about 0.1) are scaled by this on input."""
POSITION_SCALE = 10.0
"""Past body positions relative to now (unit height, 0.01-0.15 across the lags) are scaled by this."""
ROTATION_SCALE = 3.0
"""sin(angle) * axis of the frame bone's turn since a lag (0.05-0.3) is scaled by this."""
OUTPUT_SCALE = 0.05
"""The decoder's output times this is the offset (unit-height frame)."""


FRAME_BONES = 4
"""Bones (largest weights) a vertex's frame is blended from."""


def frame_bones(weights: np.ndarray, count: int = FRAME_BONES) -> tuple[np.ndarray, np.ndarray]:
    """Each vertex's frame bones and their weights: (A, count) int64 body-bone indices, largest weight
    first, and (A, count) float32 weights renormalised to sum to 1, from weights (A, Kb)."""
    w = np.asarray(weights, np.float64)
    count = min(count, w.shape[1])
    bones = np.argsort(-w, axis=1, kind="stable")[:, :count]
    top = np.take_along_axis(w, bones, 1)
    top = top / np.maximum(top.sum(1, keepdims=True), 1e-12)
    return bones.astype(np.int64), top.astype(np.float32)


def frame_rotations(transforms: torch.Tensor, bones: torch.Tensor, weights: torch.Tensor) -> torch.Tensor:
    """(..., F, A, 3, 3) each vertex's frame: the normalised weighted sum of its frame bones'
    quaternions, each turned to the hemisphere of the first (largest) one's.

    Args:
        transforms: (..., F, Kb, 7) body-bone transforms (q_w, q_x, q_y, q_z, t).
        bones: (A, J) and weights (A, J), as :func:`frame_bones` gives them.
    """
    q = transforms[..., bones, :4]  # (..., F, A, J, 4)
    q = q / q.norm(dim=-1, keepdim=True).clamp_min(1e-12)
    side = torch.where((q * q[..., :1, :]).sum(-1) < 0, -1.0, 1.0).to(q.dtype)
    return quat_to_matrix_torch((q * (side * weights.to(q.dtype))[..., None]).sum(-2))


def rest_offsets(rest: np.ndarray, heads: np.ndarray, bones: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(A, 3) rest positions (A, 3) less the weighted rest heads (Kb, 3) of their frame bones."""
    return (np.asarray(rest) - np.einsum("aj,ajc->ac", np.asarray(weights, np.float64), np.asarray(heads)[bones]))


def _vee_sin(m: torch.Tensor) -> torch.Tensor:
    """(..., 3): axis * sin(angle) of rotation matrices (..., 3, 3), the vector of their skew part."""
    return 0.5 * torch.stack([m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1)


def history_features(body: torch.Tensor, rotations: torch.Tensor, rest_offset: torch.Tensor) -> torch.Tensor:
    """(B, F, A, FEATURES) inputs of every frame of a request.

    Args:
        body: (B, F, A, 3) body states of the apparel vertices (f_s's LBS), frames 0..F-1 of the
            request, unit-height frame.
        rotations: (B, F, A, 3, 3) each vertex's frame (rest to posed, :func:`frame_rotations`).
        rest_offset: (B, A, 3) :func:`rest_offsets` in the unit-height frame.
    """
    f = body.shape[1]
    local = rotations.transpose(-1, -2)  # (B, F, A, 3, 3): world -> the vertex's frame
    up = torch.as_tensor(UP, dtype=body.dtype, device=body.device)
    parts = [rest_offset[:, None].expand(-1, f, -1, -1) * REST_SCALE, local @ up]
    frames = torch.arange(f, device=body.device)
    past_pos, past_rot = [], []
    for lag in LAGS:
        then = (frames - lag).clamp_min(0)
        past_pos.append((local @ (body[:, then] - body)[..., None])[..., 0] * POSITION_SCALE)
        past_rot.append(_vee_sin(local @ rotations[:, then]) * ROTATION_SCALE)
    return torch.cat(parts + past_pos + past_rot, -1)


class BodyHistoryApparel(nn.Module):
    """f_d as a per-vertex MLP on :func:`history_features`: offsets (B, F, A, 3) in each vertex's frame."""

    model = "body_history"

    def __init__(self, hidden: int = 256, layers: int = 3, smoothing: int = 0, arap: float = 0.0,
                 arap_iterations: int = ARAP_ITERATIONS, still_zero: bool = False):
        super().__init__()
        if smoothing < 0:
            raise ValueError(f"smoothing: expected >= 0 passes, got {smoothing}")
        if arap < 0 or arap_iterations < 0:
            raise ValueError(f"arap: expected a weight >= 0 and iterations >= 0, got {arap} and {arap_iterations}")
        self.smoothing = smoothing  # offset smoothing passes (config ``history_smoothing``), :func:`smooth_offsets`
        # a request's apparel restored by soft ARAP with this pull towards the prediction (config
        # ``history_arap``; 0: not restored), :func:`mimicbench.baselines.mmdmc.apparel_arap.restore`
        self.arap = arap
        self.arap_iterations = arap_iterations
        # the offset is the MLP's answer less its answer for the same vertex and gravity with the
        # body still through every lag (config ``history_still_zero``): a still body keeps its
        # skinned apparel, whatever the MLP learnt of the training simulator's sag
        self.still_zero = still_zero
        self.net = mlp([FEATURES] + [hidden] * layers + [3], last_act=False)
        nn.init.zeros_(self.net[-1].weight)  # untrained: zero offset, mmdmc_no_apparel
        nn.init.zeros_(self.net[-1].bias)

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        return self.net(features) * OUTPUT_SCALE

    def states(self, body: torch.Tensor, rotations: torch.Tensor, rest_offset: torch.Tensor,
               frames: torch.Tensor | None = None,
               neighbours: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """Apparel states and their offsets from the body, each (B, F', A, 3) (unit-height frame), of the
        request frames ``frames`` (F',) (None: all F), from :func:`history_features`' inputs. With the
        module's ``smoothing`` > 0 the offsets are averaged that many times over ``neighbours`` (A, k),
        each vertex's nearest vertices in its own apparel component (:func:`smooth_offsets`)."""
        feats = history_features(body, rotations, rest_offset)
        if frames is not None:
            feats, body, rotations = feats[:, frames], body[:, frames], rotations[:, frames]
        offset = self(feats)
        if self.still_zero:
            still = feats.clone()
            still[..., 6:] = 0.0  # the same vertex and gravity with the body still through the lags
            offset = offset - self(still)
        world = smooth_offsets((rotations @ offset[..., None])[..., 0], neighbours, self.smoothing)
        return body + world, world


def smooth_offsets(offsets: torch.Tensor, neighbours: torch.Tensor | None, passes: int) -> torch.Tensor:
    """(..., A, 3) offsets averaged ``passes`` times over each vertex's ``neighbours`` (A, k) (itself
    among them): a swing's offset varies slowly along a garment, a per-vertex error does not, and the
    difference of two neighbours' offsets is what stretches the edge between them (ELS)."""
    if passes < 0:
        raise ValueError(f"smoothing: expected >= 0 passes, got {passes}")
    if passes and neighbours is None:
        raise ValueError("smoothing: neighbours (A, k) are needed to smooth offsets")
    for _ in range(passes):
        offsets = offsets[..., neighbours, :].mean(-2)
    return offsets
