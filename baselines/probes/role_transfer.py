"""The probes' uncorrupted transfer: a pose carried over through the hidden roles.

Not a method to compete with (it reads ground truth that methods never receive): the right answer
the validity probes corrupt in known ways (:mod:`mimicbench.baselines.probes.corruptions`).

Each target bone is driven by its role match in the source (:func:`mimicbench.benchmark.role_match.match_by_role`,
through an optional class map, e.g. left <-> right). A torso bone (``root``, ``spine``) takes its
match's global rotation. A part bone (an arm, a wing, a tail) takes its match's rotation relative
to the source's body, carried into the target's rest by the shortest rotation ``A`` from the
source part's rest direction to the target part's (:mod:`mimicbench.benchmark.semantic`):
``R_t = R_body A (R_body^T R_s) A^T``, so a humanoid's arm raised forward raises a dog's foreleg
forward. Unmatched bones stay rigid with their parent; the root moves like the source's root,
scaled by the size ratio; positions follow by forward kinematics and the mesh by LBS.
"""
from __future__ import annotations

import numpy as np

from mimicbench.baselines.posing import pose_target, size_ratio, source_pose
from mimicbench.benchmark.role_match import bone_mass, match_by_role
from mimicbench.benchmark.semantic import FRAME_CLASSES, part_motion, part_regions, rotation_matrix, shortest_rotation
from mimicbench.geometry.quaternion import matrix_to_quat, quat_to_matrix

MIRROR = np.diag([-1.0, 1.0, 1.0])
"""Reflection across the sagittal plane (x -> -x, the dataset frame's left-right axis)."""


def hidden_roles(request) -> dict:
    """The request's ``extras["hidden_roles"]``, or a clear error when the harness did not attach it."""
    roles = request.extras.get("hidden_roles")
    if roles is None or roles.get("source_classes") is None or roles.get("target_classes") is None:
        raise ValueError("probe: this case has no hidden role labels for both characters (probes run only on "
                         "characters with bone_roles, through the benchmark harness)")
    return roles


def role_transfer_rotations(request, class_map=None, mirror: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Target global rotations (Kt, 4) and root displacement (3,) of the role transfer.

    Args:
        request: a :class:`mimicbench.benchmark.request.TransferRequest` with ``extras["hidden_roles"]``.
        class_map: target class -> the source class that drives it; None keeps classes.
        mirror: carry the driving part reflected across the sagittal plane (a mirror image of
            the source's motion, as when left and right are exchanged).
    """
    roles = hidden_roles(request)
    src, tgt = request.source, request.target
    s_cls, t_cls = roles["source_classes"], roles["target_classes"]
    match = match_by_role(roles["source_roles"], s_cls, src.parents, bone_mass(src), roles["target_roles"], t_cls,
                          tgt.parents, bone_mass(tgt), class_map=class_map)
    q_src, t_src = source_pose(request)
    r_src = quat_to_matrix(q_src)
    s_motion = part_motion(src.vertices, request.source_posed, part_regions(src.weights, src.parents, s_cls))
    t_rest = part_motion(tgt.vertices, tgt.vertices, part_regions(tgt.weights, tgt.parents, t_cls))
    body = s_motion.body
    reflect = MIRROR if mirror else np.eye(3)
    r_tgt = np.tile(np.eye(3), (len(tgt.parents), 1, 1))
    for j in range(len(tgt.parents)):
        i, cls, p = int(match[j]), t_cls[j], int(tgt.parents[j])
        if i < 0 or cls is None:
            r_tgt[j] = r_tgt[p] if p >= 0 else np.eye(3)
        elif cls.split("/")[-1] in FRAME_CLASSES:
            r_tgt[j] = r_src[i]
        else:
            relative = reflect @ body.T @ r_src[i] @ reflect
            d_src, d_tgt = s_motion.rest_dirs.get(s_cls[i]), t_rest.rest_dirs.get(cls)
            carry = (rotation_matrix(shortest_rotation(reflect @ d_src, d_tgt))
                     if d_src is not None and d_tgt is not None else np.eye(3))
            r_tgt[j] = body @ carry @ relative @ carry.T
    s_root = int(np.flatnonzero(src.parents < 0)[0])
    root_moved = (t_src[s_root] - src.keypoints[s_root]) * size_ratio(request)
    return matrix_to_quat(r_tgt), root_moved


def role_transfer(request, class_map=None, mirror: bool = False) -> np.ndarray:
    """(Nt, 3) float32 target vertices posed by :func:`role_transfer_rotations`."""
    q, root = role_transfer_rotations(request, class_map, mirror)
    return pose_target(request.target, q, root).astype(np.float32)
