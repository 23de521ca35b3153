"""Apparel deformation f_d (MMDMC Sec. 4.3): a history-conditioned displacement field on the
apparel vertices.

Step t (Eq. 11-13) sees exactly K = 3 earlier apparel states x_{t-1}, x_{t-2}, x_{t-3}: its
per-vertex input is the previous offset from the body u_{t-1} = x_{t-1} - s_{t-1}, where the
vertex would be if it stayed put while the body moved (x_{t-1} - s_t), the velocity
x_{t-1} - x_{t-2}, the acceleration x_{t-1} - 2 x_{t-2} + x_{t-3}, the body's own motion there
(s_t - s_{t-1}) and the rest position, plus a global motion code from the body joints over the
same frames (Eq. 12). EdgeConv blocks then mix features among each vertex's nearest neighbours
*within its connected apparel component* (Eq. 13: a skirt never reads a ponytail), and an MLP
decodes a displacement d_t: x_t = s_t + u_{t-1} + d_t (zero d_t keeps the apparel's offset from
the body). All positions in the character's unit-height frame.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import torch
from scipy.sparse import csgraph
from scipy.spatial import cKDTree
from torch import nn

from mimicbench.baselines.mmdmc.nn import mlp
from mimicbench.geometry.mesh import unique_edges

HISTORY = 3
"""K: the apparel states one step reads."""
DYNAMIC_SCALE = 10.0
"""Velocities and accelerations (unit-height frame, per frame) are small: scaled by this on input."""
OUTPUT_SCALE = 0.05
"""The decoder's output times this is the displacement (unit-height frame)."""


def apparel_components(faces: np.ndarray, apparel: np.ndarray) -> np.ndarray:
    """Component label (A,) int64 of each apparel vertex (``np.flatnonzero(apparel)`` order):
    connected along mesh edges whose both ends are apparel."""
    apparel = np.asarray(apparel, bool)
    idx = np.flatnonzero(apparel)
    local = np.full(len(apparel), -1)
    local[idx] = np.arange(len(idx))
    e = unique_edges(faces) if len(faces) else np.zeros((0, 2), np.int64)
    e = e[apparel[e[:, 0]] & apparel[e[:, 1]]]
    g = sp.coo_matrix((np.ones(len(e)), (local[e[:, 0]], local[e[:, 1]])), shape=(len(idx), len(idx)))
    return csgraph.connected_components(g, directed=False)[1].astype(np.int64)


def component_neighbours(points: np.ndarray, labels: np.ndarray, k: int) -> np.ndarray:
    """(A, k) int64 nearest neighbours (the vertex itself first) of each point (A, 3) among the
    points of its own component; a component of fewer than k points repeats its nearest ones."""
    points = np.asarray(points, np.float64)
    out = np.zeros((len(points), k), np.int64)
    for c in np.unique(labels):
        members = np.flatnonzero(labels == c)
        kk = min(k, len(members))
        _, nn_ = cKDTree(points[members]).query(points[members], k=kk)
        nn_ = np.asarray(nn_).reshape(len(members), kk)
        out[members] = members[nn_[:, np.arange(k) % kk]]
    return out


class EdgeConv(nn.Module):
    """h_i' = max_j MLP([h_i, h_j - h_i]) over the neighbours j of i."""

    def __init__(self, c_in: int, c_out: int):
        super().__init__()
        self.mlp = mlp([2 * c_in, c_out, c_out])

    def forward(self, h: torch.Tensor, neighbours: torch.Tensor) -> torch.Tensor:
        """h (B, A, C), neighbours (A, k) -> (B, A, c_out)."""
        nb = h[:, neighbours]  # (B, A, k, C)
        centre = h[:, :, None, :].expand_as(nb)
        return self.mlp(torch.cat([centre, nb - centre], dim=-1)).max(dim=2).values


class ApparelDynamics(nn.Module):
    """f_d: one step from K = 3 states, and the rollout over a window."""

    def __init__(self, hidden: int = 48, code: int = 16):
        super().__init__()
        self.motion = mlp([12, code, code])
        self.encode = mlp([18 + code, hidden, hidden])
        self.conv1 = EdgeConv(hidden, hidden)
        self.conv2 = EdgeConv(hidden, hidden)
        self.decode = mlp([3 * hidden, hidden, 3], last_act=False)
        # the decoder starts at zero: an untrained f_d keeps the apparel's offset from the body, so
        # from a rest start it returns f_s's LBS pose, and training only adds dynamics to it
        nn.init.zeros_(self.decode[-1].weight)
        nn.init.zeros_(self.decode[-1].bias)

    def motion_code(self, joints: torch.Tensor) -> torch.Tensor:
        """(B, code) from body joints (B, 4, J, 3) at t-3..t (unit-height frame)."""
        d = (joints[:, 1:] - joints[:, :-1]) * DYNAMIC_SCALE  # (B, 3, J, 3)
        centred = joints[:, -1] - joints[:, -1].mean(dim=1, keepdim=True)
        x = torch.cat([d.permute(0, 2, 1, 3).flatten(2), centred], dim=-1)  # (B, J, 12)
        return self.motion(x).max(dim=1).values

    def step(self, history: torch.Tensor, body: torch.Tensor, rest: torch.Tensor, joints: torch.Tensor,
             neighbours: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """x_t and d_t, each (B, A, 3).

        Args:
            history: (B, 3, A, 3) apparel states x_{t-3}, x_{t-2}, x_{t-1} (exactly K = 3).
            body: (B, 2, A, 3) body states s_{t-1}, s_t of the apparel vertices (f_s's LBS).
            rest: (B, A, 3) rest positions.
            joints: (B, 4, J, 3) posed body joints at t-3..t.
            neighbours: (A, k) EdgeConv neighbours within each component.
        """
        if history.shape[1] != HISTORY:
            raise ValueError(f"history: expected {HISTORY} states (B, {HISTORY}, A, 3), got {tuple(history.shape)}")
        x3, x2, x1 = history.unbind(1)
        s0, s1 = body.unbind(1)
        u = x1 - s0
        feats = torch.cat([u * DYNAMIC_SCALE, (x1 - s1) * DYNAMIC_SCALE, (x1 - x2) * DYNAMIC_SCALE,
                           (x1 - 2 * x2 + x3) * DYNAMIC_SCALE, (s1 - s0) * DYNAMIC_SCALE, rest], dim=-1)
        code = self.motion_code(joints)
        h0 = self.encode(torch.cat([feats, code[:, None].expand(-1, feats.shape[1], -1)], dim=-1))
        h1 = self.conv1(h0, neighbours)
        h2 = self.conv2(h1, neighbours)
        d = self.decode(torch.cat([h0, h1, h2], dim=-1)) * OUTPUT_SCALE
        return s1 + u + d, d

    def rollout(self, history: torch.Tensor, body: torch.Tensor, rest: torch.Tensor, joints: torch.Tensor,
                neighbours: torch.Tensor, truncate: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
        """Predicted states (B, T, A, 3) and displacements (B, T, A, 3) of frames t0..t0+T-1.

        Args:
            history: (B, 3, A, 3) states of frames t0-3..t0-1 (ground truth in training, or the body's
                state at rest: :func:`mimicbench.baselines.mmdmc.pipeline.rest_start`).
            body: (B, T+1, A, 3) body states of frames t0-1..t0+T-1.
            joints: (B, T+3, J, 3) posed body joints of frames t0-3..t0+T-1.
            truncate: truncated backpropagation through time: at every ``truncate``-th step the states
                it reads are detached, so the values are unchanged and a frame's loss reaches back only
                to the last such step (fewer than ``truncate`` steps). 0: no truncation.
        """
        t = body.shape[1] - 1
        if joints.shape[1] != t + HISTORY:
            raise ValueError(f"joints: expected {t + HISTORY} frames for a {t}-frame rollout, got {joints.shape[1]}")
        if truncate < 0:
            raise ValueError(f"truncate: expected >= 0 steps (0: none), got {truncate}")
        recent, states, disps = list(history.unbind(1)), [], []  # recent: what the next step reads
        for i in range(t):
            if truncate and i and i % truncate == 0:
                recent = [s.detach() for s in recent]
            x, d = self.step(torch.stack(recent[-HISTORY:], 1), body[:, i:i + 2], rest, joints[:, i:i + 4], neighbours)
            recent = recent[-(HISTORY - 1):] + [x]
            states.append(x)
            disps.append(d)
        return torch.stack(states, 1), torch.stack(disps, 1)
