"""A posed mesh read back as a skeleton pose: every bone's world rotation and posed keypoint.

The one read-off shared by every skeleton method (:func:`mimicbench.baselines.posing.source_pose`) and the
protocols (:mod:`mimicbench.benchmark.motion_range`): the joint fit of all bones
(:func:`mimicbench.geometry.transform_estimation.estimate_transforms`), then the bones the mesh does not
determine (:func:`mimicbench.geometry.transform_estimation.weight_support`: no skin weight, or vertices on a
line) completed from the skeleton:

- rotation: when at least two of the bone's children carry skin weight at or below them, are
  determined, and their global rotations agree within :data:`AGREE_DEGREES`, their average
  (weighted by the skin weight at and below each child; children are completed first), since what
  a bone without vertices turns is what hangs below it (a rig's ``Body`` that carries a clip's
  whole-body turn); otherwise its parent's rotation (a root: the identity);
- position: rigid with its parent (``t_k = t_p + R_p (cbar_k - cbar_p)``); a root keeps the fit's
  value (its rest position when it owns no vertices).

Rigs whose every bone is supported (every zoo character) read exactly as the joint fit.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mimicbench.geometry.kinematics import array_to_transforms, subtree_sums, transforms_to_array
from mimicbench.geometry.quaternion import quat_angle, quat_apply
from mimicbench.geometry.rotation_average import weighted_quaternion_average
from mimicbench.geometry.transform_estimation import estimate_transforms
from mimicbench.geometry.validation import check_parents, check_shape
from mimicbench.schemas.weights import as_dense

AGREE_DEGREES = 20.0
"""Children's rotations that agree within this many degrees give an undetermined bone its rotation."""


@dataclass(frozen=True)
class PoseReadOff:
    """A pose read off a mesh.

    Attributes:
        rotations: (K, 4) float64 unit quaternions (w, x, y, z), each bone's world rotation
            relative to rest.
        positions: (K, 3) float64 posed keypoints, metres.
        supported: (K,) bool, the bones the mesh determines; the others were completed from the
            skeleton (module docstring).
    """

    rotations: np.ndarray
    positions: np.ndarray
    supported: np.ndarray

    @property
    def transforms(self) -> np.ndarray:
        """The pose as stored transforms (K, 7) float32."""
        return transforms_to_array(self.rotations, self.positions)


def read_pose(rest_vertices: np.ndarray, rest_keypoints: np.ndarray, parents: np.ndarray, weights,
              posed_vertices: np.ndarray, **fit_options) -> PoseReadOff:
    """Read a posed mesh's pose (module docstring).

    Args:
        rest_vertices: (N, 3) rest vertices, metres.
        rest_keypoints: (K, 3) joint heads at rest, metres.
        parents: (K,) int, -1 for roots, ``parents[k] < k``.
        weights: dense (N, K) or :class:`~mimicbench.schemas.weights.SparseWeights`.
        posed_vertices: (N, 3) the posed mesh, vertex for vertex the rest mesh's.
        **fit_options: ``ridge``, ``iterations``, ``min_weight`` of
            :func:`~mimicbench.geometry.transform_estimation.estimate_transforms`.
    """
    keypoints = check_shape(rest_keypoints, (None, 3), "rest_keypoints").astype(np.float64)
    parents = check_parents(parents, keypoints.shape[0])
    posed = check_shape(posed_vertices, (None, 3), "posed_vertices")
    transforms, supported = estimate_transforms(rest_vertices, posed, weights, keypoints, **fit_options)
    q, t = array_to_transforms(transforms)
    if not supported.all():
        q = _rotations_from_skeleton(q, supported, parents, as_dense(weights, len(parents)).sum(axis=0))
        for k, p in enumerate(parents):
            if not supported[k] and p >= 0:
                t[k] = t[p] + quat_apply(q[p], keypoints[k] - keypoints[p])
    return PoseReadOff(q, t, supported)


def read_rig_pose(rig, posed_vertices: np.ndarray, **fit_options) -> PoseReadOff:
    """:func:`read_pose` of a rig object with ``vertices``, ``keypoints``, ``parents`` and ``weights``
    (a :class:`mimicbench.benchmark.request.Rig` or a character record)."""
    return read_pose(rig.vertices, rig.keypoints, rig.parents, rig.weights, posed_vertices, **fit_options)


def _rotations_from_skeleton(q: np.ndarray, supported: np.ndarray, parents: np.ndarray,
                             weight: np.ndarray) -> np.ndarray:
    """Rotations (K, 4) with the unsupported bones' completed (module docstring) from the read-off
    ``q`` (K, 4) of the others; ``weight`` (K,) each bone's own total skin weight."""
    below = subtree_sums(weight, parents)  # skin weight at and below each bone
    q = np.array(q, dtype=np.float64)
    known, from_children = supported.copy(), np.zeros(len(parents), bool)
    for k in range(len(parents) - 1, -1, -1):
        if supported[k]:
            continue
        kids = np.flatnonzero((parents == k) & known & (below > 0))
        if len(kids) >= 2 and np.degrees(quat_angle(q[kids][:, None], q[kids][None])).max() <= AGREE_DEGREES:
            q[k] = weighted_quaternion_average(q[kids], below[kids][:, None])[0]
            known[k] = from_children[k] = True
    for k, p in enumerate(parents):
        if not supported[k] and not from_children[k]:
            q[k] = q[p] if p >= 0 else np.array([1.0, 0.0, 0.0, 0.0])
    return q
