"""Input validators shared by the geometry core: messages say what was expected."""
from __future__ import annotations

import numpy as np


def check_last_dim(x, size: int, name: str) -> np.ndarray:
    """Return ``x`` as a float array whose last dimension is ``size``, else raise ValueError."""
    x = np.asarray(x)
    if x.ndim == 0 or x.shape[-1] != size:
        raise ValueError(f"{name}: expected shape (..., {size}), got {x.shape}")
    if not np.issubdtype(x.dtype, np.floating):
        x = x.astype(np.float64)
    return x


def check_shape(x, shape: tuple, name: str) -> np.ndarray:
    """Check ``x`` against ``shape``, where None matches any size; return it as an array."""
    x = np.asarray(x)
    if x.ndim != len(shape) or any(s is not None and s != d for s, d in zip(shape, x.shape)):
        want = "(" + ", ".join("?" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{name}: expected shape {want}, got {x.shape}")
    return x


def check_parents(parents, num_joints: int | None = None) -> np.ndarray:
    """Validate a ``parents`` array (K,) int: -1 for roots and ``parents[k] < k`` otherwise.

    The data contract stores bones in topological order, so a single forward pass over k
    visits every parent before its children.
    """
    p = np.asarray(parents)
    if p.ndim != 1 or not np.issubdtype(p.dtype, np.integer):
        raise ValueError(f"parents: expected a 1-D integer array, got shape {p.shape} dtype {p.dtype}")
    if num_joints is not None and p.shape[0] != num_joints:
        raise ValueError(f"parents: expected {num_joints} entries, got {p.shape[0]}")
    k = np.arange(p.shape[0])
    bad = (p != -1) & ((p < 0) | (p >= k))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"parents: expected -1 or an index below the bone's own (topological order), "
            f"got parents[{i}] = {int(p[i])}"
        )
    return p.astype(np.int64)


def expect(ok: bool, name: str, expected: str, value) -> None:
    """Raise ValueError ``"{name}: expected {expected}, got {value!r}"`` unless ``ok``."""
    if not ok:
        raise ValueError(f"{name}: expected {expected}, got {value!r}")


def is_whole(x) -> bool:
    """True for a Python or numpy integer that is not a bool."""
    return not isinstance(x, bool) and isinstance(x, (int, np.integer))
