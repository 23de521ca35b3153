"""The Neural Pose Transfer network (Wang et al., CVPR 2020, Fig. 2), re-implemented from the paper.

- Pose encoder: PointNet-style 1x1 convolutions 3 -> c1 -> c2 -> c3 over the posed source's points,
  each followed by instance norm and ReLU; a max over the points gives the pose code (the max-pool
  variant, so source and target vertex counts may differ).
- Decoder: the pose code repeated at every target point, concatenated with the point's identity
  coordinates, a 1x1 conv to c3, then SPAdaIN residual blocks c3 -> c3/2 -> c3/4 conditioned on the
  identity coordinates, and a final SPAdaIN -> 1x1 conv to xyz, squashed by 2 tanh.

Two options of ours (config keys; a config without them is version 1's network):

- ``pose_mix``: the code and the coordinates pass a 1x1 conv, a ReLU and a second 1x1 conv before the
  first SPAdaIN. Without it the pose is lost: the code is the same at every point, so after the one
  linear conv it is a constant per channel, which every SPAdaIN's instance norm (each block and its
  shortcut start with one) subtracts; version 1's answer did not depend on the source's pose
  (changing the pose moved it by 3e-6). Through the ReLU the code decides which points each channel
  is active at, which the norm keeps. (NPT's published max-pool variant needs the same care; its
  per-point variant feeds pose features that differ from point to point.)
- ``residual``: the answer is the identity point plus the 2 tanh output (the last conv starts at
  zero, so an untrained network answers the rest pose), so CPU-scale training spends its steps on
  the pose rather than on reproducing the identity mesh.
- ``pose_cond`` (tried for a version 3, not in the presets: README): the pose code also enters every SPAdaIN's gamma and beta
  (:class:`baselines.npt.spadain.SPAdaIN` with ``code``). ``pose_mix`` alone was not enough: trained,
  version 2's answer still did not follow the pose (its std over 6 poses of one pair 7e-7 against
  the code's 0.3; validation MSE 0.0029 against 0.0021 for the mean pose of the pair): a ReLU of a
  code-dominated input is on or off at every point alike, so the norm removed it again.

Paper widths (c1, c2, c3) = (64, 128, 1024); the ``small`` preset narrows them for CPU training.
Inputs and outputs are in the centred unit-size frames of :mod:`baselines.npt.placement`.
"""
from __future__ import annotations

import torch
from torch import nn

from baselines.npt.spadain import SPAdaIN, SPAdaINResBlock


class PointFeatures(nn.Module):
    """Per-point features (B, c3, N) of points (B, 3, N): 1x1 convs with instance norm and ReLU."""

    def __init__(self, widths: tuple[int, int, int]):
        super().__init__()
        layers, c = [], 3
        for w in widths:
            layers += [nn.Conv1d(c, w, 1), nn.InstanceNorm1d(w), nn.ReLU()]
            c = w
        self.net = nn.Sequential(*layers)

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        return self.net(points)


class PoseEncoder(nn.Module):
    """Pose code (B, c3) of posed points (B, 3, N): a max over :class:`PointFeatures`."""

    def __init__(self, widths: tuple[int, int, int]):
        super().__init__()
        self.features = PointFeatures(widths)

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        return self.features(points).max(dim=2).values


class SPAdaINDecoder(nn.Module):
    """Posed target (B, 3, N) from per-point pose features (B, c_pose, N) and identity points (B, 3, N)."""

    def __init__(self, c_pose: int, width: int, pose_mix: bool = False, residual: bool = False, code: int = 0):
        super().__init__()
        self.inp = nn.Conv1d(c_pose + 3, width, 1)
        self.mix = nn.Conv1d(width, width, 1) if pose_mix else None
        self.residual = bool(residual)
        self.blocks = nn.ModuleList([SPAdaINResBlock(width, width, code=code),
                                     SPAdaINResBlock(width, width // 2, code=code),
                                     SPAdaINResBlock(width // 2, width // 4, code=code)])
        self.out_norm = SPAdaIN(width // 4, code=code)
        self.out = nn.Conv1d(width // 4, 3, 1)
        if self.residual:
            nn.init.zeros_(self.out.weight)
            nn.init.zeros_(self.out.bias)

    def forward(self, pose_features: torch.Tensor, identity: torch.Tensor, code: torch.Tensor | None = None) -> torch.Tensor:
        """pose_features (B, c_pose, N), identity (B, 3, N), code (B, code) when built with one -> (B, 3, N)."""
        h = self.inp(torch.cat([pose_features, identity], dim=1))
        if self.mix is not None:
            h = self.mix(torch.relu(h))
        for block in self.blocks:
            h = block(h, identity, code)
        out = 2.0 * torch.tanh(self.out(torch.relu(self.out_norm(h, identity, code))))
        return identity + out if self.residual else out


class NeuralPoseTransfer(nn.Module):
    """NPT: pose encoder + SPAdaIN decoder.

    Args:
        widths: the pose encoder's (c1, c2, c3); the decoder is c3 wide.
        pose_mix, residual: the decoder's options (module docstring).
    """

    def __init__(self, widths=(64, 128, 1024), pose_mix: bool = False, residual: bool = False,
                 pose_cond: bool = False):
        super().__init__()
        widths = tuple(int(w) for w in widths)
        self.encoder = PoseEncoder(widths)
        self.pose_cond = bool(pose_cond)
        self.decoder = SPAdaINDecoder(widths[-1], widths[-1], pose_mix, residual, widths[-1] if pose_cond else 0)

    def forward(self, posed_source: torch.Tensor, identity: torch.Tensor) -> torch.Tensor:
        """posed_source (B, Ns, 3), identity (B, Nt, 3), centred unit-size frames -> (B, Nt, 3)."""
        code = self.encoder(posed_source.transpose(1, 2))
        nt = identity.shape[1]
        return self.decoder(code[:, :, None].expand(-1, -1, nt), identity.transpose(1, 2),
                            code if self.pose_cond else None).transpose(1, 2)
