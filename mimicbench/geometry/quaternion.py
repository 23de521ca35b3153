"""Unit quaternions in (w, x, y, z) order, as NumPy float arrays.

All functions broadcast over leading dimensions: a "quaternion array" has shape (..., 4) and a
"rotation-matrix array" has shape (..., 3, 3). Rotations act on column vectors: ``R @ v``.
A torch twin of the few functions the benchmark needs on tensors lives in
:mod:`mimicbench.quaternion_torch`.
"""
from __future__ import annotations

import numpy as np

from mimicbench.geometry.validation import check_last_dim

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def quat_identity(shape: tuple[int, ...] = (), dtype=np.float64) -> np.ndarray:
    """Identity quaternions of shape ``shape + (4,)``."""
    q = np.zeros(tuple(shape) + (4,), dtype=dtype)
    q[..., 0] = 1.0
    return q


def quat_normalize(q: np.ndarray, eps: float = 1e-12) -> np.ndarray:
    """Scale quaternions (..., 4) to unit length. Zero quaternions become the identity."""
    q = check_last_dim(q, 4, "q")
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    out = np.where(n > eps, q / np.maximum(n, eps), IDENTITY.astype(q.dtype))
    return out


def quat_canonical(q: np.ndarray) -> np.ndarray:
    """Pick the sign of each quaternion (..., 4) so that w >= 0 (q and -q are the same rotation)."""
    q = check_last_dim(q, 4, "q")
    return np.where(q[..., :1] < 0, -q, q)


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` of quaternion arrays (..., 4); rotation ``b`` is applied first."""
    a = check_last_dim(a, 4, "a")
    b = check_last_dim(b, 4, "b")
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """Conjugate (w, -x, -y, -z) of quaternions (..., 4)."""
    q = check_last_dim(q, 4, "q")
    return q * np.array([1.0, -1.0, -1.0, -1.0], dtype=q.dtype)


def quat_inverse(q: np.ndarray) -> np.ndarray:
    """Inverse of (not necessarily unit) quaternions (..., 4)."""
    q = check_last_dim(q, 4, "q")
    return quat_conjugate(q) / np.sum(q * q, axis=-1, keepdims=True)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of quaternions (..., 4); the input is normalised first."""
    q = quat_normalize(np.asarray(q))
    w, x, y, z = np.moveaxis(q, -1, 0)
    m = np.stack(
        [
            1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
        ],
        axis=-1,
    )
    return m.reshape(q.shape[:-1] + (3, 3))


def matrix_to_quat(m: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4) with w >= 0 of rotation matrices (..., 3, 3).

    Uses the numerically stable branch on the largest of (trace, diagonal) per matrix
    (Shepperd's method), so it is accurate for rotations near 180 degrees.
    """
    m = np.asarray(m)
    if m.shape[-2:] != (3, 3):
        raise ValueError(f"m: expected shape (..., 3, 3), got {m.shape}")
    lead = m.shape[:-2]
    m = m.reshape(-1, 3, 3)
    t = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    diag = np.stack([t, m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], axis=-1)
    case = np.argmax(diag, axis=-1)
    q = np.empty((m.shape[0], 4), dtype=np.result_type(m.dtype, np.float32))
    # case 0: trace largest
    s = np.sqrt(np.maximum(1.0 + diag[:, 0], 1e-30)) * 2
    q0 = np.stack([0.25 * s, (m[:, 2, 1] - m[:, 1, 2]) / s, (m[:, 0, 2] - m[:, 2, 0]) / s,
                   (m[:, 1, 0] - m[:, 0, 1]) / s], -1)
    s = np.sqrt(np.maximum(1.0 + m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2], 1e-30)) * 2
    q1 = np.stack([(m[:, 2, 1] - m[:, 1, 2]) / s, 0.25 * s, (m[:, 0, 1] + m[:, 1, 0]) / s,
                   (m[:, 0, 2] + m[:, 2, 0]) / s], -1)
    s = np.sqrt(np.maximum(1.0 + m[:, 1, 1] - m[:, 0, 0] - m[:, 2, 2], 1e-30)) * 2
    q2 = np.stack([(m[:, 0, 2] - m[:, 2, 0]) / s, (m[:, 0, 1] + m[:, 1, 0]) / s, 0.25 * s,
                   (m[:, 1, 2] + m[:, 2, 1]) / s], -1)
    s = np.sqrt(np.maximum(1.0 + m[:, 2, 2] - m[:, 0, 0] - m[:, 1, 1], 1e-30)) * 2
    q3 = np.stack([(m[:, 1, 0] - m[:, 0, 1]) / s, (m[:, 0, 2] + m[:, 2, 0]) / s,
                   (m[:, 1, 2] + m[:, 2, 1]) / s, 0.25 * s], -1)
    for k, qk in enumerate((q0, q1, q2, q3)):
        sel = case == k
        q[sel] = qk[sel]
    return quat_canonical(quat_normalize(q)).reshape(lead + (4,))


def quat_apply(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v (..., 3) by quaternions q (..., 4) (shapes broadcast)."""
    return np.einsum("...ij,...j->...i", quat_to_matrix(q), np.asarray(v))


def quat_from_axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) rotating by ``angle`` (..., radians) about ``axis`` (..., 3)."""
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.maximum(np.linalg.norm(axis, axis=-1, keepdims=True), 1e-12)
    half = 0.5 * np.asarray(angle, dtype=np.float64)[..., None]
    half, axis = np.broadcast_arrays(half, axis)
    return np.concatenate([np.cos(half[..., :1]), np.sin(half) * axis], axis=-1)


def quat_slerp(a: np.ndarray, b: np.ndarray, t: np.ndarray | float) -> np.ndarray:
    """Spherical linear interpolation from unit quaternions ``a`` to ``b`` (..., 4).

    ``t`` in [0, 1] broadcasts against the leading dimensions. Takes the short path (flips ``b``
    when ``a . b < 0``) and falls back to normalised linear interpolation for nearly equal inputs.
    """
    a = quat_normalize(a)
    b = quat_normalize(b)
    t = np.asarray(t, dtype=a.dtype)[..., None]
    dot = np.sum(a * b, axis=-1, keepdims=True)
    b = np.where(dot < 0, -b, b)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_theta = np.sin(theta)
    near = sin_theta < 1e-6
    safe = np.where(near, 1.0, sin_theta)
    wa = np.where(near, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    wb = np.where(near, t, np.sin(t * theta) / safe)
    return quat_normalize(wa * a + wb * b)


def quat_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Geodesic angle (..., radians, in [0, pi]) between the rotations of quaternions a and b."""
    a = quat_normalize(np.asarray(a, dtype=np.float64))
    b = quat_normalize(np.asarray(b, dtype=np.float64))
    r = quat_multiply(quat_conjugate(a), b)  # atan2 form stays accurate for tiny angles
    return 2.0 * np.arctan2(np.linalg.norm(r[..., 1:], axis=-1), np.abs(r[..., 0]))
