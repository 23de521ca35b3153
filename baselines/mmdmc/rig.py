"""Walks over an MMDMC character's rig: which body bone each bone hangs from."""
from __future__ import annotations

import numpy as np


def attachment_bones(parents: np.ndarray, body: np.ndarray) -> np.ndarray:
    """(K,) int64: each bone's nearest body ancestor, itself for a body bone; -1 for an apparel bone
    whose chain hangs from no body bone."""
    parents = np.asarray(parents, np.int64)
    body = np.asarray(body, bool)
    if parents.shape != body.shape:
        raise ValueError(f"parents {parents.shape} and body-bone mask {body.shape}: expected one entry per bone each")
    out = np.full(len(parents), -1, np.int64)
    for k in range(len(parents)):
        a, seen = k, 0
        while a >= 0 and not body[a] and seen <= len(parents):
            a, seen = int(parents[a]), seen + 1
        out[k] = a if a >= 0 and body[a] else -1
    return out
