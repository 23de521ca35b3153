"""Forward kinematics with rest-relative ("delta") rotations.

Convention (the data contract, see ``schemas/FORMAT.md``): a pose gives each keypoint k a
transform T_k = (q_k, t_k): q_k is the world rotation of bone k relative to its rest
orientation and t_k is the posed world position of keypoint k, so a rest point p bound to k maps
to ``R(q_k) (p - cbar_k) + t_k``. Local rotations are relative to the parent:
``q_k = q_parent(k) * l_k``. Bones are stored in topological order (``parents[k] < k``).
"""
from __future__ import annotations

import numpy as np

from mimicbench.geometry.quaternion import quat_apply, quat_conjugate, quat_multiply, quat_normalize
from mimicbench.geometry.validation import check_parents, check_shape


def forward_kinematics(
    local_rotations: np.ndarray,
    rest_keypoints: np.ndarray,
    parents: np.ndarray,
    root_positions: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Global transforms from local rotations.

    Args:
        local_rotations: (..., K, 4) unit quaternions (w, x, y, z), each bone's rotation relative
            to its parent's (the root's is its world rotation), all relative to rest.
        rest_keypoints: (K, 3) joint head positions at rest, metres.
        parents: (K,) int, -1 for roots, ``parents[k] < k``.
        root_positions: (..., K, 3) posed positions, read only at root rows (``parents == -1``);
            None keeps the roots where they are at rest.

    Returns:
        global_rotations (..., K, 4) and positions (..., K, 3): the transforms T_k.
    """
    local_rotations = quat_normalize(np.asarray(local_rotations, dtype=np.float64))
    rest = check_shape(rest_keypoints, (None, 3), "rest_keypoints").astype(np.float64)
    parents = check_parents(parents, rest.shape[0])
    if local_rotations.shape[-2:] != (rest.shape[0], 4):
        raise ValueError(
            f"local_rotations: expected shape (..., {rest.shape[0]}, 4), got {local_rotations.shape}"
        )
    lead = local_rotations.shape[:-2]
    g_rot = np.empty_like(local_rotations)
    g_pos = np.empty(lead + (rest.shape[0], 3))
    for k, p in enumerate(parents):
        if p < 0:
            g_rot[..., k, :] = local_rotations[..., k, :]
            g_pos[..., k, :] = rest[k] if root_positions is None else np.asarray(root_positions)[..., k, :]
        else:
            g_rot[..., k, :] = quat_multiply(g_rot[..., p, :], local_rotations[..., k, :])
            g_pos[..., k, :] = g_pos[..., p, :] + quat_apply(g_rot[..., p, :], rest[k] - rest[p])
    return g_rot, g_pos


def local_from_global(global_rotations: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """Local rotations (..., K, 4) from global ones (..., K, 4): ``l_k = q_parent^-1 * q_k``."""
    g = quat_normalize(np.asarray(global_rotations, dtype=np.float64))
    parents = check_parents(parents, g.shape[-2])
    local = g.copy()
    child = parents >= 0
    if child.any():
        local[..., child, :] = quat_multiply(quat_conjugate(g[..., parents[child], :]), g[..., child, :])
    return local


def transforms_to_array(rotations: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Pack rotations (..., K, 4) and positions (..., K, 3) into the stored (..., K, 7) float32."""
    return np.concatenate([rotations, positions], axis=-1).astype(np.float32)


def array_to_transforms(transforms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split stored transforms (..., K, 7) into unit quaternions (..., K, 4) and positions (..., K, 3)."""
    t = np.asarray(transforms, dtype=np.float64)
    if t.shape[-1] != 7:
        raise ValueError(f"transforms: expected shape (..., K, 7), got {t.shape}")
    return quat_normalize(t[..., :4]), t[..., 4:]


def rest_transforms(rest_keypoints: np.ndarray) -> np.ndarray:
    """The rest pose as stored transforms (K, 7): identity rotations, rest positions."""
    rest = check_shape(rest_keypoints, (None, 3), "rest_keypoints")
    q = np.zeros((rest.shape[0], 4))
    q[:, 0] = 1
    return transforms_to_array(q, rest)


def subtree_sums(values: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """(K,) float64: each bone's ``values`` (K,) plus those of every bone below it. ``parents``
    (K,) in the data contract's topological order (``parents[k] < k``), so one backward pass
    adds every child before its parent is read."""
    out = np.array(values, dtype=np.float64)
    for k in range(len(parents) - 1, -1, -1):
        if parents[k] >= 0:
            out[parents[k]] += out[k]
    return out
