"""The registered validity probes (see :mod:`mimicbench.baselines.probes`).

Role probes (read the hidden roles; the uncorrupted one is ``probe_role_transfer``,
:mod:`mimicbench.baselines.probes.role_transfer`):

| name | corruption |
|---|---|
| ``probe_mirror`` | left and right exchanged, the driving part's motion reflected |
| ``probe_fore_hind`` | fore limbs driven by the hind limbs and the other way round |
| ``probe_frozen_limb`` | one limb (:func:`~mimicbench.baselines.probes.corruptions.frozen_part`) held at rest relative to its parent |
| ``probe_noise15`` | every bone turned by 15 degrees about a random axis |
| ``probe_half_angle`` | every bone's rotation relative to its parent halved |
| ``probe_rest`` | the target at rest |

Rig probes (read only what a method reads; the uncorrupted one is ``nearest_joint``):
``nearest_joint_mirrored`` (the target's rest joints reflected left-right before the match) and
``nearest_joint_fore_hind`` (reflected between the fore and hind limbs: top-bottom for an upright
humanoid, front-back along the longer horizontal side for the others).
"""
from __future__ import annotations

import abc

import numpy as np
from scipy.spatial.distance import cdist

from mimicbench.baselines.nearest_joint import NearestJoint
from mimicbench.baselines.posing import pose_target
from mimicbench.baselines.probes import corruptions
from mimicbench.baselines.probes.role_transfer import hidden_roles, role_transfer, role_transfer_rotations
from mimicbench.benchmark.method import MethodMetadata, PoseTransferMethod
from mimicbench.benchmark.protocols.base import HIDDEN_ROLES_TAG
from mimicbench.schemas.character import HUMANOID_LIKE
from mimicbench.geometry.hungarian import hungarian_match
from mimicbench.geometry.mesh import normalize_unit_height

PROBE_TAGS = ("probe", HIDDEN_ROLES_TAG)


def _probe_metadata(name: str, description: str, tags=PROBE_TAGS, version: str = "2") -> MethodMetadata:
    return MethodMetadata(name=name, version=version, licence="MIT", description=description, tags=tags,
                          protocols=("h2h", "cct"))


class ProbeRoleTransfer(PoseTransferMethod):
    """The uncorrupted role transfer."""

    metadata = _probe_metadata("probe_role_transfer", "validity probe: the pose carried over through the hidden roles")

    def transfer(self, requests):
        return [role_transfer(r) for r in requests]


class ProbeMirror(PoseTransferMethod):
    metadata = _probe_metadata("probe_mirror", "validity probe: role transfer with left and right exchanged")

    def transfer(self, requests):
        return [role_transfer(r, class_map=corruptions.swap_sides, mirror=True) for r in requests]


class ProbeForeHind(PoseTransferMethod):
    metadata = _probe_metadata("probe_fore_hind", "validity probe: role transfer with fore and hind limbs exchanged")

    def transfer(self, requests):
        return [role_transfer(r, class_map=corruptions.swap_fore_hind) for r in requests]


class _RotationProbe(PoseTransferMethod):
    """Role transfer whose target rotations are edited by :meth:`corrupt`."""

    @abc.abstractmethod
    def corrupt(self, request, rotations: np.ndarray) -> np.ndarray:
        """The target's global rotations (Kt, 4) after the corruption."""

    def transfer(self, requests):
        out = []
        for r in requests:
            q, root = role_transfer_rotations(r)
            out.append(pose_target(r.target, self.corrupt(r, q), root).astype(np.float32))
        return out


class ProbeFrozenLimb(_RotationProbe):
    metadata = _probe_metadata("probe_frozen_limb", "validity probe: role transfer with one limb held at rest")

    def corrupt(self, request, rotations):
        classes = hidden_roles(request)["target_classes"]
        return corruptions.freeze(rotations, request.target.parents, classes, corruptions.frozen_part(classes))


class ProbeNoise15(_RotationProbe):
    metadata = _probe_metadata("probe_noise15", "validity probe: role transfer with 15 degrees of rotation noise")

    def corrupt(self, request, rotations):
        return corruptions.rotation_noise(rotations, request.target.parents, 15.0, request.case_id)


class ProbeHalfAngle(_RotationProbe):
    metadata = _probe_metadata("probe_half_angle", "validity probe: role transfer with every rotation halved")

    def corrupt(self, request, rotations):
        return corruptions.half_angle(rotations, request.target.parents)


class ProbeRest(PoseTransferMethod):
    metadata = _probe_metadata("probe_rest", "validity probe: the target at rest")

    def transfer(self, requests):
        return [np.array(r.target.vertices, np.float32) for r in requests]


def reflected_pairs(source, target, axis: int) -> np.ndarray:
    """(P, 2) nearest-joint pairs with the target's unit-height rest joints reflected along ``axis``
    about their bounding-box centre."""
    ks = normalize_unit_height(source.keypoints, source.vertices)
    kt = np.array(normalize_unit_height(target.keypoints, target.vertices))
    centre = 0.5 * (kt[:, axis].min() + kt[:, axis].max())
    kt[:, axis] = 2 * centre - kt[:, axis]
    pairs, _ = hungarian_match(cdist(ks, kt), maximize=False)
    return pairs


def fore_hind_axis(target) -> int:
    """The axis along which a character's fore limbs and hind limbs lie apart: y for an upright
    humanoid (arms above legs), else the rest mesh's longer horizontal side (x or z)."""
    if target.category in HUMANOID_LIKE:
        return 1
    span = np.ptp(np.asarray(target.vertices), axis=0)
    return 0 if span[0] > span[2] else 2


class NearestJointMirrored(NearestJoint):
    """``nearest_joint`` with the target's rest joints mirrored left-right before the match."""

    metadata = _probe_metadata("nearest_joint_mirrored", "validity probe: nearest_joint matched against the "
                               "target's mirror image", tags=("probe",))

    @staticmethod
    def pairs(source, target):
        return reflected_pairs(source, target, 0)


class NearestJointForeHind(NearestJoint):
    """``nearest_joint`` with the target's rest joints reflected between fore and hind limbs (:func:`fore_hind_axis`)
    before the match."""

    metadata = _probe_metadata("nearest_joint_fore_hind", "validity probe: nearest_joint matched against the "
                               "target reflected between its fore and hind limbs", tags=("probe",), version="2")

    @staticmethod
    def pairs(source, target):
        return reflected_pairs(source, target, fore_hind_axis(target))
